#include "hmap/slam/pose_graph.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

#include "hmap/core/error.hpp"

namespace hmap::slam {
namespace {

constexpr double kPi = std::numbers::pi;

/// A 40 × 40 m square driven counter-clockwise in 2 m steps (80 nodes), back to its start.
std::vector<GraphPose> square_truth() {
  std::vector<GraphPose> truth;
  GraphPose p;
  for (int side = 0; side < 4; ++side) {
    for (int k = 0; k < 20; ++k) {
      truth.push_back(p);
      p = compose(p, {2.0, 0.0, 0.0, k == 19 ? kPi / 2.0 : 0.0});
    }
  }
  truth.push_back(p);  // node 80: the start again
  return truth;
}

double distance(const GraphPose& a, const GraphPose& b) { return std::hypot(a.x - b.x, a.y - b.y); }

TEST(PoseGraph, RelativeAndComposeAreInverse) {
  const GraphPose a{3.0, -2.0, 0.5, 0.7};
  const GraphPose b{-1.0, 4.0, 1.5, -2.9};
  const GraphPose r = relative(a, b);
  const GraphPose back = compose(a, r);
  EXPECT_NEAR(back.x, b.x, 1e-12);
  EXPECT_NEAR(back.y, b.y, 1e-12);
  EXPECT_NEAR(back.z, b.z, 1e-12);
  EXPECT_NEAR(back.yaw, b.yaw, 1e-12);
  // By hand: b − a = (−4, 6), turned by −0.7.
  EXPECT_NEAR(r.x, -4.0 * std::cos(0.7) + 6.0 * std::sin(0.7), 1e-12);
  EXPECT_NEAR(r.y, 4.0 * std::sin(0.7) + 6.0 * std::cos(0.7), 1e-12);
}

TEST(PoseGraph, ASquareLoopWithDriftedOdometryClosesOnOneLoopEdge) {
  const std::vector<GraphPose> truth = square_truth();
  const std::size_t n = truth.size();
  // Odometry: each true step with a yaw bias and noise (fixed seed): it drifts.
  std::mt19937_64 rng(7);
  std::normal_distribution<double> noise(0.0, 0.02);
  std::vector<GraphEdge> edges;
  std::vector<GraphPose> drifted{truth.front()};
  for (std::size_t k = 1; k < n; ++k) {
    GraphPose step = relative(truth[k - 1], truth[k]);
    step.x += noise(rng);
    step.y += noise(rng);
    step.yaw += 0.004 + 0.1 * noise(rng);  // 0.23° per step of bias
    GraphEdge e{k - 1, k, step};
    e.sigma = {0.05, 0.05, 0.05, 0.005};
    edges.push_back(e);
    drifted.push_back(compose(drifted.back(), step));
  }
  const double drift = distance(drifted.back(), truth.front());
  ASSERT_GT(drift, 3.0);  // the loop does not close on odometry alone
  // The loop edge: the last node is exactly where the first was.
  GraphEdge loop{0, n - 1, relative(truth.front(), truth.back())};
  loop.sigma = {0.02, 0.02, 0.02, 0.002};
  loop.loss = EdgeLoss::kCauchy;
  edges.push_back(loop);

  const PoseGraphResult r = optimize_pose_graph(drifted, edges);
  ASSERT_TRUE(r.ran);
  EXPECT_TRUE(r.converged);
  EXPECT_LT(r.final_cost, r.initial_cost);
  EXPECT_LT(distance(r.poses.back(), r.poses.front()), 0.1);  // end to start
  double worst = 0.0;
  double worst_drifted = 0.0;
  for (std::size_t k = 0; k < n; ++k) {
    worst = std::max(worst, distance(r.poses[k], truth[k]));
    worst_drifted = std::max(worst_drifted, distance(drifted[k], truth[k]));
  }
  EXPECT_LT(worst, 0.35 * worst_drifted);
  // The first node is held.
  EXPECT_EQ(r.poses[0].x, truth[0].x);
  EXPECT_EQ(r.poses[0].yaw, truth[0].yaw);
}

TEST(PoseGraph, ConsistentEdgesLeaveThePosesAsTheyAre) {
  const std::vector<GraphPose> truth = square_truth();
  std::vector<GraphEdge> edges;
  for (std::size_t k = 1; k < truth.size(); ++k) edges.push_back({k - 1, k, relative(truth[k - 1], truth[k])});
  edges.push_back({0, truth.size() - 1, relative(truth.front(), truth.back()), {0.1, 0.1, 0.1, 0.01}, EdgeLoss::kCauchy});
  const PoseGraphResult r = optimize_pose_graph(truth, edges);
  ASSERT_TRUE(r.ran);
  EXPECT_LT(r.initial_cost, 1e-12);
  for (std::size_t k = 0; k < truth.size(); ++k) {
    EXPECT_NEAR(r.poses[k].x, truth[k].x, 1e-9);
    EXPECT_NEAR(r.poses[k].y, truth[k].y, 1e-9);
    EXPECT_NEAR(std::remainder(r.poses[k].yaw - truth[k].yaw, 2.0 * kPi), 0.0, 1e-9);
  }
}

TEST(PoseGraph, DegenerateInputsDoNothing) {
  const std::vector<GraphPose> one{{1.0, 2.0, 3.0, 0.4}};
  PoseGraphResult r = optimize_pose_graph(one, {});
  EXPECT_FALSE(r.ran);
  ASSERT_EQ(r.poses.size(), 1u);
  EXPECT_EQ(r.poses[0].x, 1.0);
  EXPECT_FALSE(optimize_pose_graph({}, {}).ran);
  // Two nodes, no edge: nothing to do either.
  const std::vector<GraphPose> two{{0, 0, 0, 0}, {5, 0, 0, 0}};
  r = optimize_pose_graph(two, {});
  EXPECT_FALSE(r.ran);
  EXPECT_EQ(r.poses[1].x, 5.0);
  // Odometry edges alone, as the nodes were chained: no change.
  const std::vector<GraphEdge> odometry{{0, 1, {5, 0, 0, 0}}};
  r = optimize_pose_graph(two, odometry);
  EXPECT_NEAR(r.poses[1].x, 5.0, 1e-12);
}

TEST(PoseGraph, RefusesEdgesToMissingNodesAndBadSigmas) {
  const std::vector<GraphPose> two{{0, 0, 0, 0}, {5, 0, 0, 0}};
  EXPECT_THROW((void)optimize_pose_graph(two, std::vector<GraphEdge>{{0, 2, {}}}), Error);
  EXPECT_THROW((void)optimize_pose_graph(two, std::vector<GraphEdge>{{1, 1, {}}}), Error);
  GraphEdge bad{0, 1, {}};
  bad.sigma = {0.1, 0.0, 0.1, 0.1};
  EXPECT_THROW((void)optimize_pose_graph(two, std::vector<GraphEdge>{bad}), Error);
}

}  // namespace
}  // namespace hmap::slam
