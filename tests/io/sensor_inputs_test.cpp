// Depth PNGs, RGB-D folders (7-Scenes, TUM), VTK legacy files, gravity alignment: hand-made files,
// malformed files, and the real recordings of ../shared/data (rgbd_7scenes, sweeping_laser_eth).

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <numbers>
#include <random>

#include "hmap/io/depth_image.hpp"
#include "hmap/io/gravity.hpp"
#include "hmap/io/read_support.hpp"
#include "hmap/io/rgbd.hpp"
#include "hmap/io/vtk.hpp"
#include "hmap/io/xyz.hpp"
#include "io/io_test_util.hpp"

namespace hmap {
namespace {

using test::contains;
using test::input_error_of;

class SensorInputsTest : public test::IoTest {
 protected:
  /// Every prefix and 300 seeded random corruptions of `bytes` read as `name`: a result or an InputError.
  template <typename F>
  void survives(const std::string& name, const std::string& bytes, F read) {
    const auto try_read = [&](const std::string& content, const std::string& what) {
      const auto path = write(name, content);
      try {
        read(path);
      } catch (const InputError&) {
      } catch (const std::exception& e) {
        ADD_FAILURE() << what << ": " << e.what();
      }
    };
    for (std::size_t length = 0; length < bytes.size(); ++length) try_read(bytes.substr(0, length), "prefix " + std::to_string(length));
    std::mt19937 rng(4242);
    std::uniform_int_distribution<std::size_t> position(0, bytes.size() - 1);
    std::uniform_int_distribution<int> byte(0, 255);
    for (int trial = 0; trial < 300; ++trial) {
      std::string damaged = bytes;
      for (int k = 0; k < 1 + trial % 4; ++k) damaged[position(rng)] = static_cast<char>(byte(rng));
      try_read(damaged, "damage trial " + std::to_string(trial));
    }
  }
};

DepthImage small_image() {
  DepthImage image;
  image.width = 4;
  image.height = 3;
  image.pixels = {1000, 0, 2000, 65535, 1500, 1500, 1500, 1500, 7, 8, 9, 60000};
  return image;
}

TEST_F(SensorInputsTest, DepthPngRoundTripAndBackProjection) {
  const auto path = dir_ / "d.png";
  write_depth_png(path, small_image());
  const DepthImage back = read_depth_png(path);
  ASSERT_EQ(back.width, 4);
  ASSERT_EQ(back.height, 3);
  EXPECT_EQ(back.pixels, small_image().pixels);
  DepthCamera camera{2.0, 4.0, 1.0, 1.0, 0.001, 65535};
  PointCloud points;
  CloudReadStats stats;
  depth_to_points(back, camera, points, &stats);
  EXPECT_EQ(stats.points_read, 12U);
  EXPECT_EQ(stats.non_finite_dropped, 2U);  // one 0, one 65535
  ASSERT_EQ(points.size(), 10U);
  // pixel (0,0): d = 1 m, x = (0-1)·1/2, y = (0-1)·1/4
  EXPECT_FLOAT_EQ(points[0].x(), -0.5F);
  EXPECT_FLOAT_EQ(points[0].y(), -0.25F);
  EXPECT_FLOAT_EQ(points[0].z(), 1.0F);
  // pixel (2,0): d = 2 m, x = (2-1)·2/2 = 1
  EXPECT_FLOAT_EQ(points[1].x(), 1.0F);
  EXPECT_FLOAT_EQ(points[1].z(), 2.0F);
}

TEST_F(SensorInputsTest, DepthPngErrors) {
  EXPECT_TRUE(contains(input_error_of([&] { (void)read_depth_png(write("x.png", "not a png at all")); }), "bad signature"));
  const auto path = dir_ / "ok.png";
  write_depth_png(path, small_image());
  const std::string bytes = detail::read_file_bytes(path);
  const std::string cut = input_error_of([&] { (void)read_depth_png(write("cut.png", bytes.substr(0, bytes.size() - 20))); });
  EXPECT_TRUE(contains(cut, "cut.png: byte")) << cut;
  // An 8-bit RGB picture is not a depth image.
  std::string rgb = bytes;
  rgb[24] = 8;  // IHDR bit depth; the CRC is now wrong too, either error names the file
  EXPECT_TRUE(contains(input_error_of([&] { (void)read_depth_png(write("rgb.png", rgb)); }), "rgb.png"));
  survives("m.png", bytes, [](const std::filesystem::path& p) { (void)read_depth_png(p); });
}

TEST_F(SensorInputsTest, IntrinsicsAndMatrixPoses) {
  const DepthCamera a = read_intrinsics(write("k.txt", "585 0 320\n0 586 240\n0 0 1\n"));
  EXPECT_DOUBLE_EQ(a.fx, 585.0);
  EXPECT_DOUBLE_EQ(a.fy, 586.0);
  EXPECT_DOUBLE_EQ(a.cy, 240.0);
  const DepthCamera b = read_intrinsics(write("k4.txt", "525, 526, 319.5, 239.5\n"));
  EXPECT_DOUBLE_EQ(b.cx, 319.5);
  EXPECT_TRUE(contains(input_error_of([&] { (void)read_intrinsics(write("k5.txt", "1 2 3\n")); }), "holds 3 numbers"));
  EXPECT_TRUE(contains(input_error_of([&] { (void)read_intrinsics(write("k6.txt", "1 2 x 4\n")); }), "line 1"));
  const auto pose = read_matrix4_pose(write("p.txt", "0 -1 0 1\n1 0 0 2\n0 0 1 3\n0 0 0 1\n"));
  ASSERT_TRUE(pose.has_value());
  EXPECT_NEAR((*pose * Eigen::Vector3d(1, 0, 0) - Eigen::Vector3d(1, 3, 3)).norm(), 0.0, 1e-12);
  EXPECT_FALSE(read_matrix4_pose(write("inf.txt", "-inf -inf -inf -inf\n0 0 0 0\n0 0 0 0\n0 0 0 1\n")).has_value());
  EXPECT_TRUE(contains(input_error_of([&] { (void)read_matrix4_pose(write("s.txt", "2 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n")); }),
                       "not a rigid transform"));
  survives("pose.txt", "1 0 0 1\n0 1 0 2\n0 0 1 3\n0 0 0 1\n", [](const std::filesystem::path& p) { (void)read_matrix4_pose(p); });
}

TEST_F(SensorInputsTest, VtkAsciiBinaryAndErrors) {
  const std::string ascii =
      "# vtk DataFile Version 3.0\ntitle\nASCII\nDATASET POLYDATA\nPOINTS 3 float\n1 2 3 4\n5 6\nnan 8 9\n"
      "VERTICES 3 6\n1 0\n1 1\n1 2\n";
  CloudReadStats stats;
  const PointCloud cloud = read_vtk(write("a.vtk", ascii), &stats);
  ASSERT_EQ(cloud.size(), 2U);
  EXPECT_EQ(cloud[1], Point3f(4, 5, 6));
  EXPECT_EQ(stats.points_read, 3U);
  EXPECT_EQ(stats.non_finite_dropped, 1U);
  std::string binary = "# vtk DataFile Version 3.0\nt\nBINARY\nDATASET POLYDATA\nPOINTS 2 double\n";
  for (double v : {1.0, 2.0, 3.0, -1.0, -2.0, -3.5}) test::put<double>(binary, v, std::endian::big);
  const PointCloud b = read_vtk(write("b.vtk", binary));
  ASSERT_EQ(b.size(), 2U);
  EXPECT_EQ(b[1], Point3f(-1, -2, -3.5F));
  const std::string huge = input_error_of([&] {
    (void)read_vtk(write("h.vtk", "# vtk DataFile Version 3.0\nt\nASCII\nDATASET POLYDATA\nPOINTS 4000000000 float\n1 2 3\n"));
  });
  EXPECT_TRUE(contains(huge, "h.vtk: line 5: POINTS claims 4000000000 points")) << huge;
  EXPECT_TRUE(contains(input_error_of([&] { (void)read_vtk(write("c.vtk", ascii.substr(0, 60))); }), "c.vtk: line"));
  EXPECT_TRUE(contains(input_error_of([&] { (void)read_vtk(write("g.vtk", "# vtk DataFile Version 3.0\nt\nASCII\nDATASET STRUCTURED_POINTS\n")); }),
                       "line 4: expected DATASET POLYDATA"));
  survives("m.vtk", ascii, [](const std::filesystem::path& p) { (void)read_vtk(p); });
  survives("mb.vtk", binary, [](const std::filesystem::path& p) { (void)read_vtk(p); });
}

TEST_F(SensorInputsTest, GravityFromAxisRotationAndFloor) {
  const Pose T = gravity_rotation(parse_up_axis("-y"));
  EXPECT_NEAR((T.linear() * Eigen::Vector3d(0, -1, 0) - Eigen::Vector3d::UnitZ()).norm(), 0.0, 1e-12);
  EXPECT_THROW((void)parse_up_axis("w"), Error);
  EXPECT_THROW((void)parse_rotation("1 0 0 0 1 0 0 0 2"), Error);
  const Pose R = parse_rotation("1,0,0, 0,0,-1, 0,1,0");
  EXPECT_NEAR((R.linear() * Eigen::Vector3d(0, 0, 1) - Eigen::Vector3d(0, -1, 0)).norm(), 0.0, 1e-12);
  // A floor (normal n) of 2000 points and a wall of 1500: the floor is found within 1°.
  const Eigen::Vector3d n = Eigen::Vector3d(0.1, -1.0, 0.2).normalized();
  const Eigen::Vector3d u = n.unitOrthogonal();
  const Eigen::Vector3d v = n.cross(u);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> s(-2.0, 2.0);
  std::normal_distribution<double> noise(0.0, 0.005);
  PointCloud points;
  for (int i = 0; i < 2000; ++i) points.push_back((s(rng) * u + s(rng) * v + (-1.5 + noise(rng)) * n).cast<float>());
  for (int i = 0; i < 1500; ++i) points.push_back((s(rng) * n + s(rng) * v + (3.0 + noise(rng)) * u).cast<float>());
  const FloorEstimate floor = estimate_floor(points, Eigen::Vector3d(0, -1, 0));
  ASSERT_TRUE(floor.found);
  EXPECT_GT(floor.up_world.dot(n), std::cos(M_PI / 180.0));
  EXPECT_NEAR(floor.height, -1.5, 0.01);
  EXPECT_GE(floor.inliers, 1900U);
  EXPECT_FALSE(estimate_floor({}, Eigen::Vector3d::UnitZ()).found);
}

// office1.pcd: a camera that sees no floor, with a wall 5 m ahead facing it along the prior. The
// wall is no floor: a plane 5 m from the only sensor is refused. With a floor 1.2 m below the
// camera (fewer points than the wall) the floor is found; without the sensors, the wall wins.
TEST(GravityTest, AWallFarAheadIsNotTheFloor) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> s(-2.0, 2.0);
  std::normal_distribution<double> noise(0.0, 0.005);
  PointCloud wall;
  for (int i = 0; i < 4000; ++i) wall.push_back(Eigen::Vector3d(s(rng), s(rng), -5.0 + noise(rng)).cast<float>());
  const std::vector<Eigen::Vector3d> camera{Eigen::Vector3d::Zero()};
  EXPECT_TRUE(estimate_floor(wall, Eigen::Vector3d::UnitZ()).found);  // no sensor given: the wall
  EXPECT_FALSE(estimate_floor(wall, Eigen::Vector3d::UnitZ(), FloorParams{}, camera).found);
  PointCloud both = wall;
  for (int i = 0; i < 1500; ++i) both.push_back(Eigen::Vector3d(s(rng), s(rng), -1.2 + noise(rng)).cast<float>());
  const FloorEstimate floor = estimate_floor(both, Eigen::Vector3d::UnitZ(), FloorParams{}, camera);
  ASSERT_TRUE(floor.found);
  EXPECT_NEAR(floor.height, -1.2, 0.01);
  EXPECT_GE(floor.inliers, 1450U);
  EXPECT_NEAR(estimate_floor(both, Eigen::Vector3d::UnitZ()).height, -5.0, 0.01);
  // 2.9 m below a second sensor: near enough.
  const std::vector<Eigen::Vector3d> two{Eigen::Vector3d::Zero(), Eigen::Vector3d(0.0, 0.0, -2.1)};
  EXPECT_TRUE(estimate_floor(wall, Eigen::Vector3d::UnitZ(), FloorParams{}, two).found);
}

// A camera pitched 45 degrees down at a floor 0.7 m below it, read with a scanner's +z as the prior
// (the kinect_pcd grabber frames): the plane comes out facing away from the camera and is turned.
// A ceiling above a level scanner keeps the prior's side.
TEST(GravityTest, FloorIsTurnedToFaceTheSensorsAboveIt) {
  const double c = std::sqrt(0.5);
  FloorEstimate floor;
  floor.found = true;
  floor.up_world = Eigen::Vector3d(0.0, c, c);  // the floor's normal in the optical frame, wrong side
  floor.height = 0.7;                            // the camera at the origin lies below: -0.7
  const std::vector<Eigen::Vector3d> camera{Eigen::Vector3d::Zero()};
  EXPECT_TRUE(orient_floor_below_sensors(floor, camera, Eigen::Vector3d::UnitZ()));
  EXPECT_NEAR(floor.up_world.y(), -c, 1e-12);
  EXPECT_NEAR(floor.up_world.dot(Eigen::Vector3d::Zero()) - floor.height, 0.7, 1e-12);  // 0.7 m above it
  EXPECT_FALSE(orient_floor_below_sensors(floor, camera, Eigen::Vector3d::UnitZ()));  // now right
  FloorEstimate ceiling;
  ceiling.found = true;
  ceiling.up_world = Eigen::Vector3d::UnitZ();
  ceiling.height = 2.5;
  EXPECT_FALSE(orient_floor_below_sensors(ceiling, camera, Eigen::Vector3d::UnitZ()));
  EXPECT_DOUBLE_EQ(ceiling.up_world.z(), 1.0);
  // One sensor above the plane: a floor, whatever the others.
  floor.up_world = Eigen::Vector3d(0.0, c, c);
  floor.height = 0.7;
  const std::vector<Eigen::Vector3d> two{Eigen::Vector3d::Zero(), Eigen::Vector3d(0.0, 1.0, 1.0)};
  EXPECT_FALSE(orient_floor_below_sensors(floor, two, Eigen::Vector3d::UnitZ()));
}

// One depth frame in its optical frame (z forward, y down): a camera 0.9 m above a floor, pitched
// 25° down and rolled 5°, with a wall 2.5 m ahead holding more points than the floor, and a
// ceiling 1.5 m above it with more points still. The floor under it is found about -y: its normal
// is the camera's up, 0.9 m below the camera; the ceiling, above the camera, is not a floor.
TEST(GravityTest, TheFloorUnderADepthCameraInItsOpticalFrame) {
  const double deg = std::numbers::pi / 180.0;
  // R_opt_level: level (x forward, y left, z up) to optical, then the camera's tilt.
  Eigen::Matrix3d level_to_optical;
  level_to_optical << 0, -1, 0, 0, 0, -1, 1, 0, 0;
  const Eigen::Matrix3d tilt = (Eigen::AngleAxisd(5.0 * deg, Eigen::Vector3d::UnitX()) *
                                Eigen::AngleAxisd(25.0 * deg, Eigen::Vector3d::UnitY()))
                                   .toRotationMatrix();  // pitched down about the level y, rolled about x
  const Eigen::Matrix3d R_opt_level = level_to_optical * tilt.transpose();
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> along(0.5, 3.0);
  std::uniform_real_distribution<double> across(-1.5, 1.5);
  std::uniform_real_distribution<double> up(-0.9, 1.5);
  std::normal_distribution<double> noise(0.0, 0.004);
  PointCloud frame;
  for (int i = 0; i < 3000; ++i) {  // the floor, level frame z = -0.9
    frame.push_back((R_opt_level * Eigen::Vector3d(along(rng), across(rng), -0.9 + noise(rng))).cast<float>());
  }
  for (int i = 0; i < 5000; ++i) {  // the wall ahead, x = 2.5
    frame.push_back((R_opt_level * Eigen::Vector3d(2.5 + noise(rng), across(rng), up(rng))).cast<float>());
  }
  for (int i = 0; i < 6000; ++i) {  // the ceiling, z = 1.5
    frame.push_back((R_opt_level * Eigen::Vector3d(along(rng), across(rng), 1.5 + noise(rng))).cast<float>());
  }
  const std::optional<SensorFloor> floor = floor_under_sensor(frame, -Eigen::Vector3d::UnitY());
  ASSERT_TRUE(floor.has_value());
  const Eigen::Vector3d up_true = R_opt_level * Eigen::Vector3d::UnitZ();
  EXPECT_LT(std::acos(std::min(1.0, floor->up_sensor.dot(up_true))), 0.3 * deg);
  EXPECT_NEAR(floor->sensor_height, 0.9, 0.01);
  EXPECT_GE(floor->inliers, 2900U);
  EXPECT_EQ(floor->points, frame.size());
  // The wall and the ceiling alone: no floor (the wall is 65° from -y, the ceiling above).
  const PointCloud no_floor(frame.begin() + 3000, frame.end());
  EXPECT_FALSE(floor_under_sensor(no_floor, -Eigen::Vector3d::UnitY()).has_value());
  // Without below_sensors the ceiling, a plane as near the camera, wins on its points.
  const std::array<Eigen::Vector3d, 1> camera{Eigen::Vector3d::Zero()};
  const FloorEstimate either = estimate_floor(frame, -Eigen::Vector3d::UnitY(), FloorParams{}, camera);
  ASSERT_TRUE(either.found);
  EXPECT_NEAR(either.height, 1.5, 0.01);
  EXPECT_FALSE(floor_under_sensor({}, -Eigen::Vector3d::UnitY()).has_value());
}

TEST_F(SensorInputsTest, SevenScenesAllFramesLoad) {
  HMAP_REQUIRE_DATA("rgbd_7scenes");
  const RgbdSequence seq = open_rgbd_sequence(test::data_dir() / "rgbd_7scenes");
  EXPECT_EQ(seq.layout, RgbdLayout::k7Scenes);
  ASSERT_EQ(seq.frames.size(), 50U);
  EXPECT_EQ(seq.frames_without_pose, 0U);
  EXPECT_DOUBLE_EQ(seq.camera.fx, 585.0);
  EXPECT_DOUBLE_EQ(seq.frames.front().time, 150.0);
  for (std::size_t k = 0; k < seq.frames.size(); ++k) {
    CloudReadStats stats;
    const PointCloud points = read_rgbd_frame(seq, k, &stats);
    EXPECT_EQ(stats.points_read, 640U * 480U);
    EXPECT_GT(points.size(), 200000U) << "frame " << k;  // a Kinect v1 indoors sees most pixels
    for (std::size_t i = 0; i < points.size(); i += 997) {
      ASSERT_GT(points[i].z(), 0.3F);
      ASSERT_LT(points[i].z(), 8.0F);
    }
  }
}

TEST_F(SensorInputsTest, TumLayoutMatchesSevenScenes) {
  HMAP_REQUIRE_DATA("rgbd_7scenes");
  const auto src = test::data_dir() / "rgbd_7scenes";
  RgbdOptions first3;
  first3.max_frames = 3;
  const RgbdSequence seven = open_rgbd_sequence(src, first3);
  // The same three frames as a TUM folder: depth.txt, groundtruth.txt at 0.1 s spacing and one
  // pose between frames 1 and 2 (interpolated back at frame 2's stamp).
  std::filesystem::create_directories(dir_ / "depth");
  std::string depth_list = "# depth maps\n# file: x\n# timestamp filename\n";
  std::string gt = "# timestamp tx ty tz qx qy qz qw\n";
  for (int k = 0; k < 3; ++k) {
    const std::string name = "depth/" + std::to_string(k) + ".png";
    std::filesystem::copy_file(seven.frames[static_cast<std::size_t>(k)].depth_png, dir_ / name);
    const double t = 10.0 + 0.1 * k;
    depth_list += std::to_string(t) + " " + name + "\n";
    const Pose& P = seven.frames[static_cast<std::size_t>(k)].T_world_cam;
    const Eigen::Quaterniond q(P.linear());
    char line[256];
    std::snprintf(line, sizeof line, "%.6f %.9f %.9f %.9f %.9f %.9f %.9f %.9f\n", t - (k == 2 ? 0.05 : 0.0), P.translation().x(),
                  P.translation().y(), P.translation().z(), q.x(), q.y(), q.z(), q.w());
    gt += line;
    if (k == 2) {
      std::snprintf(line, sizeof line, "%.6f %.9f %.9f %.9f %.9f %.9f %.9f %.9f\n", t + 0.05, P.translation().x(),
                    P.translation().y(), P.translation().z(), q.x(), q.y(), q.z(), q.w());
      gt += line;
    }
  }
  write("depth.txt", depth_list + "12.0 depth/none.png\n");  // beyond the ground truth: no pose
  write("groundtruth.txt", gt);
  RgbdOptions mm;
  mm.depth_scale = 0.001;
  const RgbdSequence tum = open_rgbd_sequence(dir_, mm);
  EXPECT_EQ(tum.layout, RgbdLayout::kTum);
  ASSERT_EQ(tum.frames.size(), 3U);
  EXPECT_EQ(tum.frames_without_pose, 1U);
  for (std::size_t k = 0; k < 3; ++k) {
    EXPECT_NEAR((tum.frames[k].T_world_cam.matrix() - seven.frames[k].T_world_cam.matrix()).cwiseAbs().maxCoeff(), 0.0, 1e-6);
  }
  EXPECT_EQ(read_rgbd_frame(tum, 1).size(), read_rgbd_frame(seven, 1).size());  // fx 525 vs 585, same valid pixels
  write("bad/depth.txt", "1.0 a.png extra\n");
  write("bad/groundtruth.txt", "1.0 0 0 0 0 0 0 1\n");
  EXPECT_TRUE(contains(input_error_of([&] { (void)open_rgbd_sequence(dir_ / "bad"); }), "depth.txt: line 1"));
}

TEST_F(SensorInputsTest, SweepingLaserFilesLoad) {
  HMAP_REQUIRE_DATA("sweeping_laser_eth");
  const auto dir = test::data_dir() / "sweeping_laser_eth";
  const std::pair<const char*, std::size_t> expected[] = {{"cloud.00000.vtk", 24989}, {"cloud.00001.vtk", 25193},
                                                          {"cloud.00002.vtk", 24154}, {"cloud_0.vtk", 36674},
                                                          {"cloud_1.vtk", 36670}};
  for (const auto& [name, count] : expected) {
    CloudReadStats stats;
    EXPECT_EQ(read_vtk(dir / name, &stats).size() + stats.non_finite_dropped, count) << name;
  }
  // The car pair: car_cloud401 moved by carCloudList.csv's true transform lands on car_cloud400.
  const PointCloud a = read_xyz(dir / "car_cloud400.csv");
  const PointCloud b = read_xyz(dir / "car_cloud401.csv");
  EXPECT_EQ(a.size(), 24989U);
  EXPECT_EQ(b.size(), 25193U);
  Eigen::Matrix4d m;
  m << 0.981715, 0.169605, -0.0864239, 0.0614127, -0.152902, 0.973034, 0.172703, 0.191433, 0.113385, -0.15633, 0.981175,
      -0.0338571, 0, 0, 0, 1;
  const auto median_nn = [&](const Eigen::Matrix4d& T) {
    std::vector<double> d;
    for (std::size_t i = 0; i < b.size(); i += 97) {
      const Eigen::Vector3d p = (T * b[i].cast<double>().homogeneous()).head<3>();
      double best = 1e30;
      for (const auto& q : a) best = std::min(best, (q.cast<double>() - p).squaredNorm());
      d.push_back(std::sqrt(best));
    }
    std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2), d.end());
    return d[d.size() / 2];
  };
  const double aligned = median_nn(m);
  const double raw = median_nn(Eigen::Matrix4d::Identity());
  const double inverse = median_nn(m.inverse());
  // Measured: 0.099 m with the true transform (the scans' point spacing), 0.51 m without, 0.69 m inverted.
  EXPECT_LT(aligned, 0.15);
  EXPECT_LT(aligned, 0.3 * raw);
  EXPECT_GT(inverse, raw);
}

}  // namespace
}  // namespace hmap
