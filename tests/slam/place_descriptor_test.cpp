#include "hmap/slam/place_descriptor.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "hmap/core/error.hpp"
#include "hmap/maps/mapper.hpp"
#include "hmap/sim/composites.hpp"
#include "hmap/sim/scene.hpp"
#include "hmap/sim/sensors.hpp"

namespace hmap::slam {
namespace place_descriptor_test {

/// A yard with nothing symmetric about it.
sim::Scene yard() {
  using sim::Box;
  using sim::Cylinder;
  using sim::SurfaceKind;
  sim::SceneBuilder b;
  b.add("ground", sim::make_ground({-45, -40}, {45, 40}, 0.0));
  b.add("north", sim::make_wall({-40, 30}, {40, 30}, 3.0));
  b.add("south", sim::make_wall({-40, -30}, {12, -30}, 6.0));
  b.add("west", sim::make_wall({-40, -30}, {-40, 30}, 2.5));
  b.add("east", sim::make_wall({40, -8}, {40, 30}, 4.5));
  for (int k = 0; k < 5; ++k) {
    b.add("pillar", {{Cylinder{{-24.0 + 11.0 * k, 8.0 + (k % 2) * 5.0}, 0.0, 2.0 + k, 0.4}, SurfaceKind::kPillar}});
  }
  b.add("box1", {{Box{{8, -12, 0.6}, {1.5, 0.8, 0.6}, 0.4}, SurfaceKind::kBox}});
  b.add("kiosk", {{Box{{20, 6, 1.5}, {3.0, 2.0, 1.5}, 0.0}, SurfaceKind::kWall}});
  b.add("shed", {{Box{{-20, -15, 2.0}, {4.0, 3.0, 2.0}, 0.3}, SurfaceKind::kWall}});
  return b.build();
}

Params params() {
  Params p = outdoor_preset();
  p.map.cell_size = 0.25;
  p.map.max_range = 40.0;
  return p;
}

/// The map of one VLP-16 scan taken at (x, y, yaw), built in the sensor's level frame (the scan's
/// own x, y, yaw at zero), as a key frame's sub-map is.
HMap place_map(const sim::Scene& scene, double x, double y, double yaw, std::uint64_t seed) {
  Pose T = Pose::Identity();
  T.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(x, y, 1.8);
  sim::SpinningLidarParams lp = sim::SpinningLidarParams::vlp16();
  lp.seed = seed;
  const PointCloud pts = sim::SpinningLidar(lp).scan(scene, T, 0.0).points_sensor;
  Mapper mapper(params());
  Pose level = Pose::Identity();
  level.translation().z() = 1.8;
  mapper.integrate(pts, level);
  return std::move(mapper.map());
}

TEST(PlaceDescriptor, TheSamePlaceTurnedGivesItsSectorShift) {
  const sim::Scene scene = yard();
  const HMap a = place_map(scene, 2.0, -3.0, 0.0, 1);
  const PlaceDescriptor da = describe_place(a, {});
  ASSERT_EQ(da.cells.size(), 20u * 60u);
  for (const int sectors_turned : {10, -17, 29}) {
    const double yaw = sectors_turned * 2.0 * std::numbers::pi / 60.0;
    const HMap b = place_map(scene, 2.0, -3.0, yaw, 2);
    const PlaceDescriptor db = describe_place(b, {});
    const PlaceMatch m = compare_places(da, db);
    EXPECT_EQ(m.shift, (sectors_turned + 60) % 60) << sectors_turned;
    EXPECT_NEAR(m.yaw, yaw, 1e-9);
    EXPECT_LT(m.distance, 0.15);
    EXPECT_LT(ring_key_distance(da, db), 0.1);
  }
  // The descriptor of the turned place taken along its own heading is the first one turned.
  const HMap b = place_map(scene, 2.0, -3.0, 0.0, 2);
  const PlaceMatch m = compare_places(da, describe_place(b, {0.0, 0.0, 10 * 2.0 * std::numbers::pi / 60.0}));
  EXPECT_EQ(m.shift, 10);
}

TEST(PlaceDescriptor, DifferentPlacesDiffer) {
  const sim::Scene scene = yard();
  const PlaceDescriptor here = describe_place(place_map(scene, 2.0, -3.0, 0.0, 1), {});
  const PlaceDescriptor again = describe_place(place_map(scene, 2.5, -2.8, 0.4, 3), {});
  const double same = compare_places(here, again).distance;
  for (const auto& [x, y] : {std::pair{-28.0, 20.0}, std::pair{30.0, -20.0}, std::pair{-30.0, -22.0}}) {
    const PlaceDescriptor there = describe_place(place_map(scene, x, y, 0.0, 4), {});
    const PlaceMatch m = compare_places(here, there);
    EXPECT_GT(m.distance, 2.0 * same) << x << ", " << y;
  }
}

TEST(PlaceDescriptor, EmptyMapsAndBadOptions) {
  const HMap empty(params());
  const PlaceDescriptor d = describe_place(empty, {});
  EXPECT_EQ(compare_places(d, d).distance, 1.0);  // nothing in common: no match
  EXPECT_THROW((void)describe_place(empty, {}, {0.0, 20, 60}), Error);
  EXPECT_THROW((void)describe_place(empty, {}, {40.0, 0, 60}), Error);
  EXPECT_THROW((void)describe_place(empty, {}, {40.0, 20, 3}), Error);
  const PlaceDescriptor other = describe_place(empty, {}, {40.0, 10, 60});
  EXPECT_THROW((void)compare_places(d, other), Error);
}

}  // namespace place_descriptor_test
}  // namespace hmap::slam
