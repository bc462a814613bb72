#include "hmap/sim/builtin_scenes.hpp"
#include "hmap/sim/trajectory.hpp"

#include <gtest/gtest.h>

#include <map>
#include <random>

#include "hmap/core/error.hpp"
#include "hmap/sim/sensors.hpp"

namespace hmap::sim {
namespace {

TEST(BuiltinScenes, EachBuildsAndHasSurfaces) {
  for (const auto& name : builtin_scene_names()) {
    SCOPED_TRACE(name);
    const Scene scene = make_scene(name);
    EXPECT_GT(scene.primitive_count(), 5U);
    EXPECT_FALSE(scene.bounds().isEmpty());
    std::mt19937_64 rng(1);
    // A town of 800 × 800 m at 3 m: about a million points, as many as the garage's at 0.5 m.
    const double spacing = name == "city" ? 3.0 : name == "parking" ? 0.5 : 0.05;
    const PointCloud truth = scene.sample_surface(spacing, rng, 0.0);
    EXPECT_GT(truth.size(), 1000U);
    for (const auto& p : truth) ASSERT_TRUE(scene.bounds().contains(p.cast<double>()));
  }
}

TEST(BuiltinScenes, UnknownNameListsTheKnownOnes) {
  try {
    (void)make_scene("garden");
    FAIL() << "expected an error";
  } catch (const Error& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("garden"), std::string::npos);
    for (const auto& name : builtin_scene_names()) EXPECT_NE(message.find(name), std::string::npos) << message;
  }
}

TEST(BuiltinScenes, BoxesEdgesHaveTheirNominalLengthsAndLieOnSurfaces) {
  const auto vertices = boxes_vertices();
  const Scene scene = make_boxes_scene();
  for (const NamedEdge& edge : boxes_edges()) {
    ASSERT_TRUE(vertices.contains(edge.from) && vertices.contains(edge.to));
    EXPECT_NEAR((vertices.at(edge.from) - vertices.at(edge.to)).norm(), edge.length, 1e-12)
        << edge.from << edge.to;
  }
  EXPECT_EQ(boxes_edges().size(), 9U);
  for (const auto& [name, v] : vertices) {
    // Every vertex is on a surface: solid and free space both within 1 mm of it.
    int solid = 0;
    int free = 0;
    for (int dx = -1; dx <= 1; ++dx) {
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dz = -1; dz <= 1; ++dz) {
          (scene.contains(v + 1e-3 * Eigen::Vector3d(dx, dy, dz), 0.0) ? solid : free) += 1;
        }
      }
    }
    EXPECT_GT(solid, 0) << name;
    EXPECT_GT(free, 0) << name;
  }
}

TEST(BuiltinScenes, ParkingVlp16FrameSeesGroundCarsAndCrowns) {
  const Scene scene = make_parking_scene();
  SpinningLidar lidar(SpinningLidarParams::vlp16());
  Pose T_world_sensor = Pose::Identity();
  T_world_sensor.translation() = Eigen::Vector3d(40.0, 1.6, 1.73);
  const SimulatedScan scan = lidar.scan(scene, T_world_sensor, 0.0);
  std::map<SurfaceKind, int> hits;
  for (const SurfaceKind kind : scan.kind) ++hits[kind];
  EXPECT_GT(hits[SurfaceKind::kGround], 3000);
  EXPECT_GT(hits[SurfaceKind::kVehicle], 300);
  EXPECT_GT(hits[SurfaceKind::kCrown], 300);
  EXPECT_GT(hits[SurfaceKind::kCurb], 50);
  EXPECT_GT(hits[SurfaceKind::kTrunk], 10);
  EXPECT_GT(hits[SurfaceKind::kWall], 100);
}

TEST(BuiltinScenes, ParkingCarLeavesAfterThreeSeconds) {
  const Scene scene = make_parking_scene();
  const auto car = scene.find_object("leaving_car");
  ASSERT_TRUE(car.has_value());
  EXPECT_EQ(scene.object_placement(*car, 0.0).position, scene.object_placement(*car, 3.0).position);
  EXPECT_GT((scene.object_placement(*car, 8.0).position - scene.object_placement(*car, 3.0).position).norm(), 10.0);
  // A beam across the car's parking place hits the car before it leaves and the curb behind it after.
  const Eigen::Vector3d origin(45.0, 1.0, 0.5);
  const auto before = scene.intersect(origin, {0, -1, 0}, 1.0, 20.0);
  const auto after = scene.intersect(origin, {0, -1, 0}, 12.0, 20.0);
  ASSERT_TRUE(before && after);
  EXPECT_EQ(before->object, *car);
  EXPECT_NE(after->object, *car);
}

TEST(BuiltinScenes, RoutesStayOutOfSolids) {
  const Scene office = make_office_scene();
  for (const auto& p : office_robot_route()) EXPECT_FALSE(office.contains({p.x(), p.y(), 0.5}, 0.0));
  const Scene parking = make_parking_scene();
  for (const auto& p : parking_car_route()) EXPECT_FALSE(parking.contains(p + Eigen::Vector3d(0, 0, 1.73), 0.0));
  // The long route: every sensor pose of the drive (U-turn included) stays in free space, and
  // the drive is over 300 m.
  const Trajectory long_drive = car_path(parking_long_car_route(), CarPathParams{});
  double length = 0.0;
  for (std::size_t k = 0; k < long_drive.T_world_sensor.size(); ++k) {
    EXPECT_FALSE(parking.contains(long_drive.T_world_sensor[k].translation(), long_drive.times[k])) << "frame " << k;
    if (k > 0) length += (long_drive.T_world_sensor[k].translation() - long_drive.T_world_sensor[k - 1].translation()).norm();
  }
  EXPECT_GT(length, 300.0);
  EXPECT_LT(length, 330.0);
}

}  // namespace
}  // namespace hmap::sim
