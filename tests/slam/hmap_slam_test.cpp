#include "hmap/slam/hmap_slam.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "hmap/core/error.hpp"
#include "hmap/sim/composites.hpp"
#include "hmap/sim/scene.hpp"
#include "hmap/sim/sensors.hpp"

namespace hmap::slam {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

TEST(HmapSlam, PoseAlgebra) {
  const PlanarPose a{1.0, 2.0, 0.5};
  const PlanarPose b{-0.3, 0.7, -0.2};
  const PlanarPose id = a * inverse(a);
  EXPECT_NEAR(id.x, 0.0, 1e-12);
  EXPECT_NEAR(id.y, 0.0, 1e-12);
  EXPECT_NEAR(id.yaw, 0.0, 1e-12);
  // a ⊕ b agrees with the SE(3) product of the composed poses.
  const Pose T = compose(a, {}) * compose(b, {});
  const PlanarPose ab = a * b;
  EXPECT_NEAR(T.translation().x(), ab.x, 1e-12);
  EXPECT_NEAR(T.translation().y(), ab.y, 1e-12);
  EXPECT_NEAR(planar_of(T).yaw, ab.yaw, 1e-12);
  // compose / attitude_of / planar_of round trip.
  const Attitude att{1.7, 0.05, -0.08};
  const Pose P = compose(a, att);
  const Attitude back = attitude_of(P);
  EXPECT_NEAR(back.z, att.z, 1e-12);
  EXPECT_NEAR(back.roll, att.roll, 1e-12);
  EXPECT_NEAR(back.pitch, att.pitch, 1e-12);
  EXPECT_NEAR(planar_of(P).yaw, a.yaw, 1e-12);
}

TEST(HmapSlam, FollowsASimulatedDrive) {
  // Six HDL-64 scans 8 cm apart (the first step, with no velocity yet, within the basin) along a gentle curve in a walled yard, constant velocity as
  // the only prior: every pose within 3 cm and 0.3° of the truth.
  sim::SceneBuilder b;
  b.add("ground", sim::make_ground({-25, -20}, {25, 20}, 0.0));
  b.add("north", sim::make_wall({-14, 12}, {14, 12}, 3.0));
  b.add("south", sim::make_wall({-14, -12}, {8, -12}, 4.0));
  b.add("west", sim::make_wall({-14, -12}, {-14, 12}, 2.5));
  b.add("east", sim::make_wall({14, -6}, {14, 12}, 3.5));
  b.add("box", {{sim::Box{{4, -5, 0.6}, {1.0, 0.5, 0.6}, 0.4}, sim::SurfaceKind::kBox}});
  b.add("kiosk", {{sim::Box{{-6, 4, 1.5}, {2.0, 1.5, 1.5}, 0.3}, sim::SurfaceKind::kWall}});
  const sim::Scene scene = b.build();
  Params p = outdoor_preset();
  p.map.cell_size = 0.05;
  p.map.max_range = 20.0;
  p.slam.min_layer_height = 0.1;
  HmapSlam slam(p);
  sim::SpinningLidar lidar(sim::SpinningLidarParams::hdl64e());
  const Attitude att{1.8, 0.0, 0.0};
  for (int k = 0; k < 6; ++k) {
    const PlanarPose truth{0.08 * k, 0.005 * k * k, 0.3 * kDeg * k};
    const PointCloud scan = lidar.scan(scene, compose(truth, att), 0.1 * k).points_sensor;
    const SlamStep step = slam.process(scan, std::optional<Attitude>(att));
    EXPECT_EQ(step.matched, k > 0);
    const PlanarPose est = planar_of(step.T_map_sensor);
    EXPECT_NEAR(est.x, truth.x, 0.03) << k;
    EXPECT_NEAR(est.y, truth.y, 0.03) << k;
    EXPECT_NEAR(est.yaw, truth.yaw, 0.3 * kDeg) << k;
    EXPECT_NEAR(step.T_map_sensor.translation().z(), att.z, 1e-12);
    if (k > 0) {
      EXPECT_TRUE(step.match.converged) << k;
      EXPECT_FALSE(step.match.degenerate) << k;
    }
  }
  EXPECT_EQ(slam.scans(), 6U);
  EXPECT_FALSE(slam.map().empty());
}

TEST(HmapSlam, RejectsInvalidParameters) {
  Params p;
  p.slam.interpolation_window = 4;
  EXPECT_THROW(HmapSlam{p}, Error);
  p = Params{};
  p.slam.idw_weight = 1.5;
  EXPECT_THROW(ScanMatcher{p}, Error);
}

}  // namespace
}  // namespace hmap::slam
