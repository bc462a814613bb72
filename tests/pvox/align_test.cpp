#include "hmap/pvox/align.hpp"

#include <gtest/gtest.h>

#include "hmap/pvox/boxes_experiment.hpp"
#include "hmap/sim/builtin_scenes.hpp"
#include "hmap/sim/sensors.hpp"

namespace hmap::pvox {
namespace {

PointCloud scan_boxes(const Pose& T_world_sensor, std::uint64_t seed) {
  sim::LineScannerParams p = sim::LineScannerParams::utm30lx_yawing();
  p.angular_step_deg = 0.5;
  p.sweep_steps = 91;
  p.seed = seed;
  sim::LineScanner scanner(p);
  return scanner.scan(sim::make_boxes_scene(), T_world_sensor, 0.0).points_sensor;
}

Pose at(double x, double y, double yaw) {
  Pose T = Pose::Identity();
  T.translation() = Eigen::Vector3d(x, y, 0.0);
  T.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return T;
}

// A map of the boxes scene from one position; a scan from another, given a guess off by a known
// offset: the alignment finds the offset back to a few millimetres.
TEST(Align, RecoversAKnownOffset) {
  VoxelMap map(0.0586);
  const Pose T1 = at(0.3, 0.4, 0.0);
  map.insert(scan_boxes(T1, 1), T1, InsertParams{});
  const Pose T2 = at(0.3, 1.4, 0.0);
  const PointCloud scan2 = scan_boxes(T2, 2);
  for (const Eigen::Vector2d& offset : {Eigen::Vector2d(0.04, -0.03), Eigen::Vector2d(-0.06, 0.05), Eigen::Vector2d(0.0, 0.0)}) {
    Pose guess = T2;
    guess.translation().head<2>() -= offset;
    const AlignResult r = align_xy(map, scan2, guess);
    ASSERT_TRUE(r.valid);
    EXPECT_TRUE(r.converged);
    EXPECT_NEAR(r.offset.x(), offset.x(), 0.004) << r.offset.transpose();
    EXPECT_NEAR(r.offset.y(), offset.y(), 0.004) << r.offset.transpose();
    EXPECT_GT(r.correspondences, 100U);
  }
}

TEST(Align, EmptyMapIsNotValid) {
  const VoxelMap map(0.05);
  const AlignResult r = align_xy(map, PointCloud{Point3f(1, 0, 0)}, Pose::Identity());
  EXPECT_FALSE(r.valid);
  EXPECT_EQ(r.offset, Eigen::Vector2d::Zero());
}

}  // namespace
}  // namespace hmap::pvox
