#include "hmap/sim/simulation.hpp"

#include <gtest/gtest.h>

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
