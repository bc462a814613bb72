#include "hmap/sim/simulation.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>
#include <vector>

#include "hmap/core/error.hpp"
#include "hmap/sim/builtin_scenes.hpp"
#include "hmap/sim/scene_json.hpp"
#include "hmap/sim/trajectory.hpp"

namespace hmap::sim {
namespace {

SimulationSpec small_spec(const std::string& scene, const std::string& sensor) {
  SimulationSpec spec;
  spec.scene = scene;
  spec.sensor = sensor;
  spec.frames = 2;
  spec.truth_spacing = 1.0;
  return spec;
}

TEST(SimulationTest, SameSpecGivesTheSameRecording) {
  const SimulatedRecording a = simulate(small_spec("parking", "vlp16"));
  const SimulatedRecording b = simulate(small_spec("parking", "vlp16"));
  ASSERT_EQ(a.scans.size(), 2U);
  EXPECT_EQ(a.scans, b.scans);
  EXPECT_EQ(a.truth_surface, b.truth_surface);
  EXPECT_GT(a.scans[0].size(), 20000U);
  EXPECT_EQ(a.points, a.scans[0].size() + a.scans[1].size());
  EXPECT_TRUE(a.point_times.empty());
  EXPECT_FALSE(a.truth_ground.empty());
  EXPECT_LE(a.truth_ground.size(), a.truth_surface.size());
  SimulationSpec other = small_spec("parking", "vlp16");
  other.seed = 2;
  EXPECT_NE(simulate(other).scans[0], a.scans[0]);
}

TEST(SimulationTest, FirstFrameIsTheSensorAtThePathsFirstPose) {
  const SimulatedRecording rec = simulate(small_spec("parking", "hdl64"));
  CarPathParams p;  // the car route with the sensor on the roof (1.73 m, the default)
  const Trajectory path = car_path(parking_car_route(), p);
  auto sensor = std::get<SpinningLidar>(make_sensor("hdl64", 1));
  EXPECT_TRUE(rec.T_world_sensor[0].isApprox(path.T_world_sensor[0]));
  EXPECT_EQ(sensor.scan(make_parking_scene(), path.T_world_sensor[0], path.times[0]).points_sensor, rec.scans[0]);
}

TEST(SimulationTest, OwnSceneDrivesTheOfficeRoute) {
  const Scene flat = scene_from_json(R"({"objects": [{"type": "ground", "center": [0, 0, 0], "size": [100, 100]}]})");
  SimulationSpec spec = small_spec("", "kinect");
  const SimulatedRecording rec = simulate(spec, flat);
  DiffDriveParams p;
  p.sensor_height = 0.8;  // the Kinect's
  const Trajectory office = diff_drive_path(office_robot_route(), p);
  ASSERT_EQ(rec.T_world_sensor.size(), 2U);
  EXPECT_TRUE(rec.T_world_sensor[1].isApprox(office.T_world_sensor[1]));
}

TEST(SimulationTest, SweepsCarryPointTimes) {
  SimulationSpec spec = small_spec("parking", "vlp16");
  spec.sweep = true;
  const SimulatedRecording rec = simulate(spec);
  ASSERT_EQ(rec.point_times.size(), 2U);
  ASSERT_EQ(rec.point_times[0].size(), rec.scans[0].size());
  for (float t : rec.point_times[0]) {
    EXPECT_GE(t, 0.0F);
    EXPECT_LT(t, 0.1F);
  }
}

// A lidar mounted turned about its axis: the same path turned in its own frame, the same scene in
// the world (its points land on the unturned scan's surfaces), its scan turned the other way in
// its own frame.
TEST(SimulationTest, MountYawTurnsTheSensorAboutItsAxis) {
  const SimulatedRecording straight = simulate(small_spec("parking", "vlp16"));
  SimulationSpec spec = small_spec("parking", "vlp16");
  spec.mount_yaw = 0.35;
  const SimulatedRecording turned = simulate(spec);
  ASSERT_EQ(turned.T_world_sensor.size(), 2U);
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.35, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  for (std::size_t k = 0; k < 2; ++k) {
    EXPECT_TRUE(turned.T_world_sensor[k].translation().isApprox(straight.T_world_sensor[k].translation(), 1e-12));
    EXPECT_TRUE(turned.T_world_sensor[k].linear().isApprox(straight.T_world_sensor[k].linear() * R, 1e-12));
  }
  EXPECT_EQ(turned.truth_surface, straight.truth_surface);  // the scene
  // The first frame's points in the world: each turned return within a few centimetres of an
  // unturned one (the rings are the same; the azimuths start elsewhere: 0.2° apart, 3.5 cm at 10 m).
  const PointCloud& a = straight.scans[0];
  const PointCloud& b = turned.scans[0];
  ASSERT_GT(b.size(), 20000U);
  EXPECT_NEAR(static_cast<double>(b.size()), static_cast<double>(a.size()), 0.02 * static_cast<double>(a.size()));
  std::vector<Eigen::Vector3d> world_a;
  world_a.reserve(a.size());
  for (const Point3f& p : a) world_a.push_back(straight.T_world_sensor[0] * p.cast<double>());
  std::vector<double> nearest;
  Eigen::Vector3d centroid_a = Eigen::Vector3d::Zero();
  Eigen::Vector3d centroid_b = Eigen::Vector3d::Zero();
  for (const Point3f& p : a) centroid_a += p.cast<double>();
  for (const Point3f& p : b) centroid_b += p.cast<double>();
  centroid_a /= static_cast<double>(a.size());
  centroid_b /= static_cast<double>(b.size());
  for (std::size_t i = 0; i < b.size(); i += 97) {
    const Eigen::Vector3d q = turned.T_world_sensor[0] * b[i].cast<double>();
    double best = std::numeric_limits<double>::infinity();
    for (const Eigen::Vector3d& w : world_a) best = std::min(best, (w - q).squaredNorm());
    nearest.push_back(std::sqrt(best));
  }
  std::nth_element(nearest.begin(), nearest.begin() + static_cast<std::ptrdiff_t>(nearest.size() / 2), nearest.end());
  EXPECT_LT(nearest[nearest.size() / 2], 0.05);
  // In its own frame the turned scan is the straight one turned back: its centroid too.
  EXPECT_LT((centroid_b - R.transpose() * centroid_a).norm(), 0.05 * centroid_a.norm() + 0.05);
  EXPECT_GT((centroid_b - centroid_a).norm(), 0.2 * centroid_a.head<2>().norm());
}

TEST(SimulationTest, RefusesBadSpecs) {
  SimulationSpec spec = small_spec("office", "vlp16");
  spec.stride = 0;
  EXPECT_THROW((void)simulate(spec), Error);
  spec = small_spec("office", "kinect");
  spec.sweep = true;
  EXPECT_THROW((void)simulate(spec), Error);
  spec = small_spec("office", "vlp16");
  spec.truth_spacing = 0.001;
  EXPECT_THROW((void)simulate(spec), Error);
  EXPECT_THROW((void)simulate(small_spec("garage", "vlp16")), Error);  // make_scene lists the names
  // A turned mounting: only a spinning lidar's (a camera would look elsewhere), within ±180°.
  for (const auto& [sensor, yaw] : {std::pair<std::string, double>{"kinect", 0.3}, {"utm30lx-tilt", 0.3},
                                    {"vlp16", 3.2}, {"vlp16", -3.2}, {"vlp16", std::nan("")}}) {
    spec = small_spec("office", sensor);
    spec.mount_yaw = yaw;
    EXPECT_THROW((void)simulate(spec), Error) << sensor << " " << yaw;
  }
  try {
    (void)make_sensor("os1", 1);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("known: vlp16"), std::string::npos) << e.what();
  }
  for (const std::string& name : sensor_names()) EXPECT_NO_THROW((void)make_sensor(name, 1, SensorNoise::kNone)) << name;
}

}  // namespace
}  // namespace hmap::sim
