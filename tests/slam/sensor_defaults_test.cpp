// Defaults chosen from the first scan (core/sensor_profile.hpp), asserted for simulated VLP-16,
// HDL-64 and OS0-64 scans and a depth camera; here because the scans come from hmap::sim.

#include "hmap/core/sensor_profile.hpp"
#include "hmap/core/format.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>

#include "hmap/sim/builtin_scenes.hpp"
#include "hmap/sim/composites.hpp"
#include "hmap/sim/scene.hpp"
#include "hmap/sim/sensors.hpp"

namespace hmap {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

PointCloud scan_of(const sim::SpinningLidarParams& lidar) {
  const sim::Scene scene = sim::make_parking_scene();
  sim::SpinningLidar sensor(lidar);
  // On the street, among the parked cars and walls (the route's midpoint).
  const auto route = sim::parking_car_route();
  Pose T = Pose::Identity();
  T.translation() = route[route.size() / 2] + Eigen::Vector3d(0.0, 0.0, 1.8);
  return sensor.scan(scene, T, 0.0).points_sensor;
}

TEST(SensorDefaults, Vlp16RingsWidenTheHeightGapWithRange) {
  // 16 rings 2° apart: neighbouring rings hit a wall d · tan 2° apart, 0.87 m at the outdoor
  // preset's 25 m. The gap grows with the cell's distance by 1.1 · tan 2° = 0.0384 per metre; the
  // paper's 0.4 m stays where that is less (within 10.4 m). The range reaches as far as the gap
  // stays within map.ring_gap_max, 3 m: 3 / 0.0384 = 78.1 m (77-78 m for the spacing as read).
  const SensorProfile s = profile_scan(scan_of(sim::SpinningLidarParams::vlp16()));
  EXPECT_GE(s.rings, 12);
  EXPECT_LE(s.rings, 16);
  EXPECT_NEAR(s.ring_spacing, 2.0 * kDeg, 0.05 * kDeg);
  Params p = outdoor_preset();
  const auto chosen = adapt_to_sensor(p, outdoor_preset(), s);
  ASSERT_EQ(chosen.size(), 2U);
  EXPECT_EQ(chosen[0].name, "map.max_range");
  EXPECT_EQ(chosen[1].name, "map.ring_gap_slope");
  EXPECT_NEAR(p.map.ring_gap_slope, 1.1 * std::tan(2.0 * kDeg), 0.001);
  EXPECT_DOUBLE_EQ(p.map.max_range, std::floor(3.0 / p.map.ring_gap_slope));
  EXPECT_GE(p.map.max_range, 77.0);
  EXPECT_LE(p.map.max_range, 78.0);
  EXPECT_NE(chosen[0].reason.find(format("its rings lie map.ring_gap_max = 3 m apart on a wall %.0f m away",
                                         p.map.max_range)),
            std::string::npos)
      << chosen[0].reason;
  EXPECT_NE(chosen[1].reason.find(format("the height gap is 0.40 m near and 3.00 m at %.0f m (3 m at most)",
                                         p.map.max_range)),
            std::string::npos)
      << chosen[1].reason;
  EXPECT_DOUBLE_EQ(p.map.point_distance_threshold, outdoor_preset().map.point_distance_threshold);
  // A range the user named stands (the gap is still chosen, and said at that range).
  Params named = outdoor_preset();
  const auto kept = adapt_to_sensor(named, outdoor_preset(), s, true);
  ASSERT_EQ(kept.size(), 1U);
  EXPECT_DOUBLE_EQ(named.map.max_range, 25.0);
  EXPECT_NE(kept[0].reason.find("the height gap is 0.40 m near and 0.96 m at 25 m"), std::string::npos) << kept[0].reason;
  // A gap or a slope the user set is theirs (the range is still the sensor's).
  Params gap = outdoor_preset();
  gap.map.point_distance_threshold = 0.6;
  const auto range_only = adapt_to_sensor(gap, outdoor_preset(), s);
  ASSERT_EQ(range_only.size(), 1U);
  EXPECT_EQ(range_only[0].name, "map.max_range");
  EXPECT_DOUBLE_EQ(gap.map.max_range, p.map.max_range);
  EXPECT_DOUBLE_EQ(gap.map.ring_gap_slope, 0.0);
  Params slope = outdoor_preset();
  slope.map.ring_gap_slope = 0.02;
  ASSERT_EQ(adapt_to_sensor(slope, outdoor_preset(), s).size(), 1U);
  EXPECT_DOUBLE_EQ(slope.map.ring_gap_slope, 0.02);
}

TEST(SensorDefaults, Hdl64KeepsThePapersGapWithinItsRange) {
  // Rings 1/3°–1/2° apart: 0.15–0.22 m at 25 m, under the paper's 0.4 m, which stays the gap to
  // 50 m and more. 3 m apart only beyond 300 m: the range is the 100 m spinning LiDARs reach.
  const SensorProfile s = profile_scan(scan_of(sim::SpinningLidarParams::hdl64e()));
  EXPECT_GE(s.rings, 30);
  EXPECT_GT(s.ring_spacing, 0.3 * kDeg);
  EXPECT_LT(s.ring_spacing, 0.55 * kDeg);
  Params p = outdoor_preset();
  const auto chosen = adapt_to_sensor(p, outdoor_preset(), s);
  ASSERT_EQ(chosen.size(), 2U);
  EXPECT_DOUBLE_EQ(p.map.max_range, 100.0);
  EXPECT_NE(chosen[0].reason.find("apart on a wall only beyond the 100 m the common spinning LiDARs reach"),
            std::string::npos)
      << chosen[0].reason;
  EXPECT_DOUBLE_EQ(p.map.point_distance_threshold, outdoor_preset().map.point_distance_threshold);
  EXPECT_GT(p.map.ring_gap_slope * 50.0, 0.25);
  EXPECT_LT(p.map.ring_gap_slope * 50.0, outdoor_preset().map.point_distance_threshold);
}

TEST(SensorDefaults, Os0SixtyFourRings) {
  // The simulator's OS0-64: 64 rings over ±45° (1.43° apart): 0.62 m at 25 m, 0.69 with the margin.
  const SensorProfile s = profile_scan(scan_of(sim::SpinningLidarParams::os0_64()));
  EXPECT_NEAR(s.ring_spacing, 90.0 / 63.0 * kDeg, 0.05 * kDeg);
  Params p = outdoor_preset();
  (void)adapt_to_sensor(p, outdoor_preset(), s);
  EXPECT_NEAR(p.map.ring_gap_slope * 25.0, 0.69, 0.02);
  EXPECT_DOUBLE_EQ(p.map.point_distance_threshold, outdoor_preset().map.point_distance_threshold);
  // 3 m apart at 3 / 0.0275 = 109 m: held to 100 m.
  EXPECT_DOUBLE_EQ(p.map.max_range, 100.0);
}

TEST(SensorDefaults, NoRingsNoChange) {
  // Elevations that fill their span (a depth camera, a sweeping laser), too few points, nothing.
  PointCloud dense;
  for (int i = 0; i < 400; ++i) {
    for (int j = 0; j < 100; ++j) {
      const double el = (-20.0 + 40.0 * i / 399.0) * kDeg;
      const double az = (-30.0 + 60.0 * j / 99.0) * kDeg;
      dense.emplace_back(static_cast<float>(8.0 * std::cos(el) * std::cos(az)),
                         static_cast<float>(8.0 * std::cos(el) * std::sin(az)), static_cast<float>(8.0 * std::sin(el)));
    }
  }
  EXPECT_EQ(profile_scan(dense).rings, 0);
  EXPECT_EQ(profile_scan(PointCloud{}).rings, 0);
  EXPECT_EQ(profile_scan(PointCloud(10, Point3f(NAN, 0.0F, 0.0F))).points, 0U);
  Params p = outdoor_preset();
  EXPECT_TRUE(adapt_to_sensor(p, outdoor_preset(), profile_scan(dense)).empty());
}

// A LiDAR in a closed 4 x 3 m room sees nothing beyond 5 m, where the rings are read: they are read
// from 2 m on when the points lie all around. A depth camera in the same room is not read there.
TEST(SensorDefaults, ALidarInAClosedRoomIsFoundByItsRingsNearBy) {
  sim::SceneBuilder b;
  b.add("floor", sim::make_ground({-2.2, -1.7}, {2.2, 1.7}, 0.0));
  b.add("ceiling", sim::make_ceiling({-2.2, -1.7}, {2.2, 1.7}, 2.5));
  b.add("north", sim::make_wall({-2.1, 1.6}, {2.1, 1.6}, 2.5));
  b.add("south", sim::make_wall({-2.1, -1.6}, {2.1, -1.6}, 2.5));
  b.add("east", sim::make_wall({2.1, -1.6}, {2.1, 1.6}, 2.5));
  b.add("west", sim::make_wall({-2.1, -1.6}, {-2.1, 1.6}, 2.5));
  const sim::Scene room = b.build();
  Pose T = Pose::Identity();
  T.translation() = Eigen::Vector3d(0.3, 0.2, 0.8);
  sim::SpinningLidar vlp16(sim::SpinningLidarParams::vlp16());
  const SensorProfile s = profile_scan(vlp16.scan(room, T, 0.0).points_sensor);
  EXPECT_LT(s.range_p95, 3.0);
  EXPECT_GT(s.azimuth_coverage, 0.99);
  EXPECT_GE(s.rings, 12);
  EXPECT_NEAR(s.ring_spacing, 2.0 * kDeg, 0.1 * kDeg);
  EXPECT_TRUE(is_spinning_lidar(s));
  EXPECT_EQ(preset_for_sensor(s), "room");
  Params p = room_preset();
  (void)adapt_to_sensor(p, room_preset(), s);
  EXPECT_GT(p.map.ring_gap_slope, 0.0);
  EXPECT_DOUBLE_EQ(p.map.max_range, 51.2);  // its own reach, 77-78 m, held to 512 cells of 0.1 m
  // The same room seen through a 70 deg depth camera: no rings read near by, the indoor preset.
  sim::DepthCamera kinect(sim::DepthCameraParams::kinect_one());
  const SensorProfile k = profile_scan(kinect.scan(room, T, 0.0).points_sensor);
  EXPECT_LT(k.azimuth_coverage, 0.5);
  EXPECT_EQ(k.rings, 0);
  EXPECT_EQ(preset_for_sensor(k), "indoor");
  // 1500 points all around at 3 m whose elevations spread thinly over ±25 deg (a slow sweeping
  // laser's): a few 0.05 deg bins pass the count by chance, but hold few of the points: no rings.
  std::mt19937 rng(34);
  std::uniform_real_distribution<double> el(-25.0 * kDeg, 25.0 * kDeg);
  std::uniform_real_distribution<double> az(-std::numbers::pi, std::numbers::pi);
  PointCloud thin;
  for (int i = 0; i < 1500; ++i) {
    const double e = el(rng);
    const double a = az(rng);
    thin.emplace_back(static_cast<float>(3.0 * std::cos(e) * std::cos(a)), static_cast<float>(3.0 * std::cos(e) * std::sin(a)),
                      static_cast<float>(3.0 * std::sin(e)));
  }
  const SensorProfile t = profile_scan(thin);
  EXPECT_GT(t.azimuth_coverage, 0.9);
  EXPECT_EQ(t.rings, 0);
}

TEST(SensorDefaults, PresetFromTheSensorsReach) {
  // Spinning LiDARs on the parking street see past the room preset's 10 m: outdoor. A Kinect in
  // the simulated office sees nothing beyond about 4.5 m: indoor. An empty scan: outdoor.
  std::string why;
  EXPECT_EQ(preset_for_sensor(profile_scan(scan_of(sim::SpinningLidarParams::vlp16())), &why), "outdoor");
  EXPECT_NE(why.find("beyond the indoor preset's 5 m range and the room preset's 10 m"), std::string::npos) << why;
  EXPECT_EQ(preset_for_sensor(profile_scan(scan_of(sim::SpinningLidarParams::hdl64e()))), "outdoor");
  const sim::Scene office = sim::make_office_scene();
  sim::DepthCamera kinect(sim::DepthCameraParams::kinect_one());
  Pose T = Pose::Identity();
  T.translation() = Eigen::Vector3d(1.0, 1.0, 0.5);
  const SensorProfile k = profile_scan(kinect.scan(office, T, 0.0).points_sensor);
  EXPECT_LT(k.range_p95, 5.0);
  EXPECT_EQ(preset_for_sensor(k, &why), "indoor");
  EXPECT_NE(why.find("inside the indoor preset's 5 m"), std::string::npos) << why;
  // Its 70.6 deg view is no spinning LiDAR's, even where its rows beyond 5 m read as rings (the
  // office route's first frame showed 4): it stays indoor, its range the preset's.
  EXPECT_GT(k.azimuth_coverage, 0.15);
  EXPECT_LT(k.azimuth_coverage, 0.25);
  SensorProfile rows = k;
  rows.rings = 4;
  rows.ring_spacing = 0.5 * kDeg;
  EXPECT_FALSE(is_spinning_lidar(rows));
  EXPECT_EQ(preset_for_sensor(rows), "indoor");
  Params kinect_params = indoor_preset();
  (void)adapt_to_sensor(kinect_params, indoor_preset(), rows);
  EXPECT_DOUBLE_EQ(kinect_params.map.max_range, 5.0);
  // Spinning LiDARs at the start of the simulated office's route (hmap simulate --scene office): its
  // walls stand 7-10 m away, beyond the indoor preset's 5 m and within the room preset's 10 m.
  for (const auto& lidar : {sim::SpinningLidarParams::vlp16(), sim::SpinningLidarParams::hdl64e(),
                            sim::SpinningLidarParams::os0_64()}) {
    sim::SpinningLidar sensor(lidar);
    Pose start = Pose::Identity();
    const Eigen::Vector2d at = sim::office_robot_route().front();  // (1, 1) in the 10 x 8 m room
    start.translation() = Eigen::Vector3d(at.x(), at.y(), 1.2);
    const SensorProfile l = profile_scan(sensor.scan(office, start, 0.0).points_sensor);
    EXPECT_GT(l.azimuth_coverage, 0.99);  // walls all around
    EXPECT_TRUE(is_spinning_lidar(l));
    EXPECT_GT(l.range_p95, 5.0);
    EXPECT_LT(l.range_p95, 10.0);
    EXPECT_EQ(preset_for_sensor(l, &why), "room");
    EXPECT_NE(why.find("beyond the indoor preset's 5 m range, inside the room preset's 10 m"), std::string::npos) << why;
    // A LiDAR reaches beyond the room: as far as its rings lie within 3 m of each other on a wall
    // (100 m at most, and 512 cells of the scan window each way); the height gap is the preset's 0.4 m near, and grows with the rings' spread beyond.
    Params p = room_preset();
    const auto chosen = adapt_to_sensor(p, room_preset(), l);
    ASSERT_EQ(chosen.size(), 2U);
    EXPECT_EQ(chosen[0].name, "map.max_range");
    EXPECT_EQ(chosen[1].name, "map.ring_gap_slope");
    EXPECT_GT(p.map.ring_gap_slope, 0.0);
    EXPECT_DOUBLE_EQ(p.map.max_range, 51.2);  // 77-100 m, held to 512 cells of 0.1 m
    EXPECT_NE(chosen[0].reason.find("apart on a wall"), std::string::npos) << chosen[0].reason;
    EXPECT_DOUBLE_EQ(p.map.point_distance_threshold, 0.4);
    // Named by the user, the range stands, even at the preset's value.
    Params named = room_preset();
    (void)adapt_to_sensor(named, room_preset(), l, true);
    EXPECT_DOUBLE_EQ(named.map.max_range, 10.0);
  }
  // A LiDAR in a small room (95 % within 5 m) is not a depth camera: the room preset, and its reach.
  PointCloud closet = scan_of(sim::SpinningLidarParams::vlp16());
  SensorProfile small = profile_scan(closet);
  small.range_p95 = 2.8;
  EXPECT_EQ(preset_for_sensor(small, &why), "room");
  EXPECT_NE(why.find(format("but a LiDAR (%d rings): the room preset", small.rings)), std::string::npos) << why;
  {
    // With the outdoor preset's cell, 0.01 m, the reach is held to the scan window's 2048 cells.
    Params fine = room_preset();
    fine.map.cell_size = 0.01;
    Params fine_preset = fine;
    const auto held = adapt_to_sensor(fine, fine_preset, small);
    EXPECT_DOUBLE_EQ(fine.map.max_range, 20.48);
    ASSERT_FALSE(held.empty());
    EXPECT_NE(held[0].reason.find("(held to 2048 cells each way of the scan window)"), std::string::npos)
        << held[0].reason;
    EXPECT_NO_THROW(validate(fine));
  }
  {
    // With the room preset's 0.1 m cells a VLP-16's 78 m is held to 512 cells each way, 51.2 m;
    // with 0.05 m cells 25.6 m (never under the 25 m a LiDAR had before).
    Params room = room_preset();
    const auto held = adapt_to_sensor(room, room_preset(), small);
    EXPECT_DOUBLE_EQ(room.map.max_range, 51.2);
    ASSERT_FALSE(held.empty());
    EXPECT_NE(held[0].reason.find("(held to 512 cells each way of the scan window)"), std::string::npos)
        << held[0].reason;
    Params finer = room_preset();
    finer.map.cell_size = 0.05;
    Params finer_preset = finer;
    (void)adapt_to_sensor(finer, finer_preset, small);
    EXPECT_DOUBLE_EQ(finer.map.max_range, 25.6);
  }
  EXPECT_EQ(preset_for_sensor(profile_scan(PointCloud{}), &why), "outdoor");
  EXPECT_EQ(why, "the first scan has 0 points, too few to tell the sensor");
  // Hand-made: 95 % of 1000 points at 4 m and the rest at 20 m is indoor; 90 % at 4 m is outdoor.
  PointCloud near_far;
  for (int i = 0; i < 1000; ++i) near_far.emplace_back(i < 960 ? 4.0F : 20.0F, 0.0F, 0.0F);
  EXPECT_EQ(preset_for_sensor(profile_scan(near_far)), "indoor");
  for (int i = 860; i < 960; ++i) near_far[static_cast<std::size_t>(i)] = Point3f(20.0F, 0.0F, 0.0F);
  EXPECT_EQ(preset_for_sensor(profile_scan(near_far)), "outdoor");
  // The same at 8 m: 96 % within 10 m is a room, 86 % is not; exactly at the room's 10 m still is.
  for (int i = 0; i < 1000; ++i) near_far[static_cast<std::size_t>(i)] = Point3f(i < 960 ? 8.0F : 20.0F, 0.0F, 0.0F);
  EXPECT_EQ(preset_for_sensor(profile_scan(near_far), &why), "room");
  EXPECT_NE(why.find("within 8.0 m"), std::string::npos) << why;
  for (int i = 0; i < 960; ++i) near_far[static_cast<std::size_t>(i)] = Point3f(0.0F, 10.0F, 0.0F);
  EXPECT_EQ(preset_for_sensor(profile_scan(near_far)), "room");
  for (int i = 860; i < 960; ++i) near_far[static_cast<std::size_t>(i)] = Point3f(20.0F, 0.0F, 0.0F);
  EXPECT_EQ(preset_for_sensor(profile_scan(near_far), &why), "outdoor");
  EXPECT_NE(why.find("beyond the indoor preset's 5 m range and the room preset's 10 m"), std::string::npos) << why;
  // 999 points at 1 m (a pose file read as a scan is one): too few to tell, outdoor.
  EXPECT_EQ(preset_for_sensor(profile_scan(PointCloud(999, Point3f(1.0F, 0.0F, 0.0F)))), "outdoor");
}

}  // namespace
}  // namespace hmap
