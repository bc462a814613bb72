#include "hmap/eval/trajectory_metrics.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <vector>

#include "hmap/core/error.hpp"

namespace hmap {
namespace {

constexpr double kDeg = 180.0 / std::numbers::pi;

Pose make_pose(const Eigen::Vector3d& axis_angle, const Eigen::Vector3d& t) {
  Pose T = Pose::Identity();
  const double angle = axis_angle.norm();
  if (angle > 0.0) T.linear() = Eigen::AngleAxisd(angle, axis_angle / angle).toRotationMatrix();
  T.translation() = t;
  return T;
}

Pose random_pose(std::mt19937& gen, double max_angle, double max_t) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Eigen::Vector3d axis(u(gen), u(gen), u(gen));
  axis.normalize();
  return make_pose(axis * max_angle * u(gen), Eigen::Vector3d(u(gen), u(gen), u(gen)) * max_t);
}

/// A random walk of `n` poses, steps of about 1 m that turn a little.
PoseList random_walk(std::mt19937& gen, std::size_t n) {
  PoseList poses{Pose::Identity()};
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (std::size_t i = 1; i < n; ++i) {
    const Pose step = make_pose(Eigen::Vector3d(0.05 * u(gen), 0.05 * u(gen), 0.2 * u(gen)),
                                Eigen::Vector3d(1.0 + 0.2 * u(gen), 0.2 * u(gen), 0.1 * u(gen)));
    poses.push_back(poses.back() * step);
  }
  return poses;
}

/// The estimate of `truth` with a small random error added to every step: drift.
PoseList drifting_copy(std::mt19937& gen, const PoseList& truth) {
  PoseList estimate{truth.front()};
  for (std::size_t i = 1; i < truth.size(); ++i) {
    const Pose step = truth[i - 1].inverse(Eigen::Isometry) * truth[i];
    estimate.push_back(estimate.back() * step * random_pose(gen, 0.01, 0.03));
  }
  return estimate;
}

/// A straight line along x, one metre per frame.
PoseList straight_line(std::size_t n, double step_m) {
  PoseList poses;
  for (std::size_t i = 0; i < n; ++i) {
    poses.push_back(make_pose(Eigen::Vector3d::Zero(), Eigen::Vector3d(step_m * static_cast<double>(i), 0, 0)));
  }
  return poses;
}

void expect_pose_near(const Pose& a, const Pose& b, double tol) {
  EXPECT_TRUE(a.matrix().isApprox(b.matrix(), tol)) << a.matrix() << "\nvs\n" << b.matrix();
}

TEST(TrajectoryMetricsTest, IdenticalTrajectoriesGiveZeros) {
  std::mt19937 gen(1);
  const PoseList truth = random_walk(gen, 300);
  const TrajectoryEvalParams params{{10.0, 50.0}, 1};
  const TrajectoryMetrics m = evaluate_trajectory(truth, truth, params);
  EXPECT_EQ(m.frames, 300U);
  EXPECT_EQ(m.ate_rmse_m, 0.0);
  EXPECT_EQ(m.ate_max_m, 0.0);
  EXPECT_NEAR(m.ate_rmse_aligned_m, 0.0, 1e-9);
  EXPECT_NEAR(m.rpe_frame_trans_rmse_m, 0.0, 1e-9);
  EXPECT_NEAR(m.rpe_frame_rot_rmse_deg, 0.0, 1e-9);
  EXPECT_GT(m.rpe_segments, 0U);
  EXPECT_NEAR(m.rpe_trans_pct, 0.0, 1e-9);
  EXPECT_NEAR(m.rpe_rot_deg_per_m, 0.0, 1e-9);
  expect_pose_near(m.T_truth_estimate, Pose::Identity(), 1e-9);
}

TEST(TrajectoryMetricsTest, PureTranslationOffsetGivesItsNormUnalignedAndZeroAligned) {
  std::mt19937 gen(2);
  const PoseList truth = random_walk(gen, 200);
  const Eigen::Vector3d offset(3.0, -4.0, 12.0);  // norm 13
  PoseList estimate;
  for (const Pose& T : truth) estimate.push_back(Eigen::Translation3d(offset) * T);
  const TrajectoryMetrics m = evaluate_trajectory(truth, estimate, {{20.0}, 1});
  EXPECT_NEAR(m.ate_rmse_m, 13.0, 1e-9);
  EXPECT_NEAR(m.ate_mean_m, 13.0, 1e-9);
  EXPECT_NEAR(m.ate_median_m, 13.0, 1e-9);
  EXPECT_NEAR(m.ate_max_m, 13.0, 1e-9);
  EXPECT_NEAR(m.ate_rmse_aligned_m, 0.0, 1e-9);
  EXPECT_NEAR(m.ate_max_aligned_m, 0.0, 1e-9);
  expect_pose_near(m.T_truth_estimate, Pose(Eigen::Translation3d(-offset)), 1e-9);
  // A world-frame offset leaves every relative motion unchanged.
  EXPECT_NEAR(m.rpe_frame_trans_rmse_m, 0.0, 1e-9);
  EXPECT_NEAR(m.rpe_trans_pct, 0.0, 1e-9);
}

TEST(TrajectoryMetricsTest, RigidOffsetIsRemovedByTheAlignment) {
  std::mt19937 gen(3);
  const PoseList truth = random_walk(gen, 150);
  const Pose T_estimate_truth = random_pose(gen, 2.5, 50.0);
  PoseList estimate;
  for (const Pose& T : truth) estimate.push_back(T_estimate_truth * T);
  const TrajectoryMetrics m = evaluate_trajectory(truth, estimate, {{20.0}, 1});
  EXPECT_GT(m.ate_rmse_m, 1.0);
  EXPECT_NEAR(m.ate_rmse_aligned_m, 0.0, 1e-7);
  expect_pose_near(m.T_truth_estimate, T_estimate_truth.inverse(Eigen::Isometry), 1e-9);
  EXPECT_NEAR(m.rpe_frame_rot_rmse_deg, 0.0, 1e-7);
  EXPECT_NEAR(m.rpe_rot_deg_per_m, 0.0, 1e-7);
  // A whole trajectory moved rigidly has the same motion since its start.
  EXPECT_NEAR(m.ate_rmse_origin_m, 0.0, 1e-7);
}

// From the first pose: the estimate's first pose tilted by 2° about x (a levelled frame against
// the first sensor's) and then the true motion, by hand: a straight 10 m along the truth's y seen
// from a frame tilted 2° ends sin(2°)·10 m off in z at most, and every later position is off by
// the turn of its own translation; unaligned the same 2° makes it all an offset too.
TEST(TrajectoryMetricsTest, FromTheFirstPoseTheWorldFramesDifferenceGoes) {
  PoseList truth, estimate;
  const Pose tilt = make_pose(Eigen::Vector3d(2.0 * M_PI / 180.0, 0.0, 0.0), Eigen::Vector3d::Zero());
  for (int i = 0; i <= 10; ++i) {
    const Pose T = make_pose(Eigen::Vector3d::Zero(), Eigen::Vector3d(0.0, 1.0 * i, 0.0));
    truth.push_back(T);
    estimate.push_back(tilt * T);  // the same motion in a world frame turned 2°
  }
  const TrajectoryMetrics same = evaluate_trajectory(truth, estimate, {{5.0}, 1});
  EXPECT_NEAR(same.ate_rmse_origin_m, 0.0, 1e-9);  // the motion since the start is the truth's
  EXPECT_NEAR(same.ate_max_m, 2.0 * 10.0 * std::sin(M_PI / 180.0), 1e-9);  // chord of 2° at 10 m
  // Now the estimate's motion itself turned 2° after its first pose: from the first pose the
  // positions are off by that chord, |e_i| = 2·i·sin(1°).
  PoseList turned{truth[0]};
  for (int i = 1; i <= 10; ++i) turned.push_back(tilt * truth[static_cast<std::size_t>(i)]);
  const TrajectoryMetrics m = evaluate_trajectory(truth, turned, {{5.0}, 1});
  EXPECT_NEAR(m.ate_max_origin_m, 2.0 * 10.0 * std::sin(M_PI / 180.0), 1e-9);
  double sq = 0.0;
  for (int i = 0; i <= 10; ++i) sq += std::pow(2.0 * i * std::sin(M_PI / 180.0), 2);
  EXPECT_NEAR(m.ate_rmse_origin_m, std::sqrt(sq / 11.0), 1e-9);
  // The end point: (0, 10, 0) turned 2° about x is (0, 10 cos 2°, 10 sin 2°); its horizontal
  // part of the error is 10 (1 − cos 2°).
  EXPECT_NEAR(m.end_error_origin_m, 2.0 * 10.0 * std::sin(M_PI / 180.0), 1e-9);
  EXPECT_NEAR(m.end_error_origin_planar_m, 10.0 * (1.0 - std::cos(2.0 * M_PI / 180.0)), 1e-9);
  EXPECT_NEAR(same.end_error_origin_m, 0.0, 1e-9);
}

TEST(TrajectoryMetricsTest, RigidAlignmentRecoversRandomTransforms) {
  std::mt19937 gen(4);
  for (int trial = 0; trial < 20; ++trial) {
    PoseList truth;
    for (int i = 0; i < 10; ++i) truth.push_back(random_pose(gen, 3.0, 20.0));
    const Pose T_estimate_truth = random_pose(gen, 3.0, 100.0);
    PoseList estimate;
    for (const Pose& T : truth) estimate.push_back(T_estimate_truth * T);
    expect_pose_near(rigid_alignment(truth, estimate), T_estimate_truth.inverse(Eigen::Isometry), 1e-9);
  }
}

TEST(TrajectoryMetricsTest, ConstantScaleDriftGivesTheKnownErrors) {
  // Truth moves 1 m per frame along x, the estimate 1.01 m: 1 cm of error per frame.
  const std::size_t n = 1001;  // 1000 m
  const TrajectoryMetrics m = evaluate_trajectory(straight_line(n, 1.0), straight_line(n, 1.01));
  // ATE: e_i = 0.01·i, i = 0..1000.
  double sum_sq = 0.0;
  for (std::size_t i = 0; i < n; ++i) sum_sq += 1e-4 * static_cast<double>(i * i);
  EXPECT_NEAR(m.ate_rmse_m, std::sqrt(sum_sq / static_cast<double>(n)), 1e-9);
  EXPECT_NEAR(m.ate_mean_m, 5.0, 1e-9);
  EXPECT_NEAR(m.ate_median_m, 5.0, 1e-9);
  EXPECT_NEAR(m.ate_max_m, 10.0, 1e-9);
  EXPECT_NEAR(m.rpe_frame_trans_rmse_m, 0.01, 1e-9);
  EXPECT_NEAR(m.rpe_frame_rot_rmse_deg, 0.0, 1e-12);
  // KITTI: the segment of length L from frame i ends at the first frame strictly farther than L,
  // i + L + 1, whose error is 0.01·(L + 1) m; frames i = 0..999−L start one.
  ASSERT_EQ(m.segment_length_source, SegmentLengthSource::kGiven);
  ASSERT_EQ(m.segment_lengths_m.size(), 8U);
  double pct_sum = 0.0;
  std::size_t segments = 0;
  for (int L = 100; L <= 800; L += 100) {
    const auto count = static_cast<std::size_t>(1000 - L);
    pct_sum += static_cast<double>(count) * 100.0 * 0.01 * (L + 1) / L;
    segments += count;
    const SegmentLengthError& per = m.per_length[static_cast<std::size_t>(L / 100 - 1)];
    EXPECT_EQ(per.segments, count);
    EXPECT_NEAR(per.trans_pct, 1.0 * (L + 1) / L, 1e-9);
  }
  EXPECT_EQ(m.rpe_segments, segments);
  EXPECT_NEAR(m.rpe_trans_pct, pct_sum / static_cast<double>(segments), 1e-9);
  EXPECT_NEAR(m.rpe_rot_deg_per_m, 0.0, 1e-12);
}

TEST(TrajectoryMetricsTest, ConstantYawDriftOnAShortPathUsesFractionsOfThePath) {
  // 51 frames, 50 m: shorter than 100 m, so the segments are 5, 10, ..., 40 m.
  const std::size_t n = 51;
  const double delta = 0.002;  // [rad] extra yaw per frame
  const PoseList truth = straight_line(n, 1.0);
  PoseList estimate{Pose::Identity()};
  const Pose step = make_pose(Eigen::Vector3d(0, 0, delta), Eigen::Vector3d(1, 0, 0));
  for (std::size_t i = 1; i < n; ++i) estimate.push_back(estimate.back() * step);

  const TrajectoryMetrics m = evaluate_trajectory(truth, estimate);
  EXPECT_NEAR(m.path_length_m, 50.0, 1e-12);
  EXPECT_NEAR(m.rpe_frame_rot_rmse_deg, delta * kDeg, 1e-9);
  EXPECT_NEAR(m.rpe_frame_trans_rmse_m, 0.0, 1e-12);
  ASSERT_EQ(m.segment_length_source, SegmentLengthSource::kFractionOfPath);
  ASSERT_EQ(m.segment_lengths_m.size(), 8U);
  double rot_sum = 0.0;
  std::size_t segments = 0;
  for (int tenth = 1; tenth <= 8; ++tenth) {
    const int L = 5 * tenth;
    EXPECT_DOUBLE_EQ(m.segment_lengths_m[static_cast<std::size_t>(tenth - 1)], L);
    const auto count = static_cast<std::size_t>(50 - L);  // starts i with i + L + 1 <= 50
    rot_sum += static_cast<double>(count) * (L + 1) * delta / L;
    segments += count;
  }
  EXPECT_EQ(m.rpe_segments, segments);
  EXPECT_NEAR(m.rpe_rot_deg_per_m, kDeg * rot_sum / static_cast<double>(segments), 1e-9);
}

/// KITTI's devkit (evaluate_odometry.cpp, calcSequenceErrors), transcribed loop for loop.
struct TwinResult {
  double t_err = 0.0;  // mean of t/L
  double r_err = 0.0;  // mean of r/L [rad/m]
  std::size_t segments = 0;
};
TwinResult kitti_twin(const PoseList& gt, const PoseList& result, const std::vector<double>& lengths, int step) {
  std::vector<double> dist{0.0};
  for (std::size_t i = 1; i < gt.size(); ++i) {
    dist.push_back(dist.back() + (gt[i].translation() - gt[i - 1].translation()).norm());
  }
  TwinResult out;
  for (std::size_t first = 0; first < gt.size(); first += static_cast<std::size_t>(step)) {
    for (const double len : lengths) {
      long last = -1;
      for (std::size_t i = first; i < dist.size(); ++i) {
        if (dist[i] > dist[first] + len) {
          last = static_cast<long>(i);
          break;
        }
      }
      if (last == -1) continue;
      const auto j = static_cast<std::size_t>(last);
      const Eigen::Matrix4d delta_gt = gt[first].matrix().inverse() * gt[j].matrix();
      const Eigen::Matrix4d delta_result = result[first].matrix().inverse() * result[j].matrix();
      const Eigen::Matrix4d error = delta_result.inverse() * delta_gt;
      const double d = std::clamp(0.5 * (error(0, 0) + error(1, 1) + error(2, 2) - 1.0), -1.0, 1.0);
      out.r_err += std::acos(d) / len;
      out.t_err += error.block<3, 1>(0, 3).norm() / len;
      ++out.segments;
    }
  }
  out.t_err /= static_cast<double>(out.segments);
  out.r_err /= static_cast<double>(out.segments);
  return out;
}

TEST(TrajectoryMetricsTest, KittiSegmentsMatchTheDevkitTwin) {
  std::mt19937 gen(5);
  const PoseList truth = random_walk(gen, 90);
  const PoseList estimate = drifting_copy(gen, truth);
  const std::vector<double> lengths{3.0, 7.5, 15.0, 30.0, 60.0};
  for (const int step : {1, 3, 10}) {
    const TrajectoryMetrics m = evaluate_trajectory(truth, estimate, {lengths, step});
    const TwinResult twin = kitti_twin(truth, estimate, lengths, step);
    ASSERT_GT(twin.segments, 0U);
    EXPECT_EQ(m.rpe_segments, twin.segments) << "step " << step;
    EXPECT_NEAR(m.rpe_trans_pct, 100.0 * twin.t_err, 1e-9) << "step " << step;
    EXPECT_NEAR(m.rpe_rot_deg_per_m, kDeg * twin.r_err, 1e-9) << "step " << step;
    std::size_t per_sum = 0;
    for (const SegmentLengthError& per : m.per_length) per_sum += per.segments;
    EXPECT_EQ(per_sum, m.rpe_segments);
  }
}

TEST(TrajectoryMetricsTest, MedianOfAnEvenCountIsTheMeanOfTheMiddleTwo) {
  const PoseList truth = straight_line(4, 0.0);
  PoseList estimate;
  for (const double e : {4.0, 1.0, 3.0, 2.0}) estimate.push_back(make_pose(Eigen::Vector3d::Zero(), {0, e, 0}));
  const TrajectoryMetrics m = evaluate_trajectory(truth, estimate);
  EXPECT_NEAR(m.ate_median_m, 2.5, 1e-12);
  EXPECT_NEAR(m.ate_mean_m, 2.5, 1e-12);
  EXPECT_NEAR(m.ate_max_m, 4.0, 1e-12);
}

TEST(TrajectoryMetricsTest, StandingStillHasNoSegments) {
  const PoseList still = straight_line(10, 0.0);
  const TrajectoryMetrics m = evaluate_trajectory(still, still);
  EXPECT_EQ(m.segment_length_source, SegmentLengthSource::kFractionOfPath);
  EXPECT_EQ(m.rpe_segments, 0U);
  EXPECT_TRUE(std::isnan(m.rpe_trans_pct));
  EXPECT_TRUE(std::isnan(m.rpe_rot_deg_per_m));
  EXPECT_EQ(m.ate_rmse_m, 0.0);
  EXPECT_EQ(m.ate_rmse_aligned_m, 0.0);  // degenerate alignment: identity, no NaN
  EXPECT_TRUE(m.T_truth_estimate.matrix().allFinite());
}

TEST(TrajectoryMetricsTest, TwoPosesAreEnough) {
  const PoseList truth = straight_line(2, 1.0);
  const PoseList estimate = straight_line(2, 1.5);
  const TrajectoryMetrics m = evaluate_trajectory(truth, estimate);
  EXPECT_NEAR(m.ate_rmse_m, std::sqrt(0.125), 1e-12);      // errors 0 and 0.5
  EXPECT_NEAR(m.ate_rmse_aligned_m, 0.25, 1e-12);          // centred: ±0.25
  EXPECT_NEAR(m.rpe_frame_trans_rmse_m, 0.5, 1e-12);
  EXPECT_EQ(m.segment_length_source, SegmentLengthSource::kFractionOfPath);
  EXPECT_EQ(m.rpe_segments, 8U);                           // one per length, all from frame 0
  EXPECT_NEAR(m.per_length[0].trans_pct, 100.0 * 0.5 / 0.1, 1e-9);
}

TEST(TrajectoryMetricsTest, BadInputsThrow) {
  const PoseList ten = straight_line(10, 1.0);
  const PoseList nine = straight_line(9, 1.0);
  const PoseList one = straight_line(1, 1.0);
  EXPECT_THROW((void)evaluate_trajectory(ten, nine), Error);
  EXPECT_THROW((void)evaluate_trajectory(one, one), Error);
  EXPECT_THROW((void)evaluate_trajectory(PoseList{}, PoseList{}), Error);
  EXPECT_THROW((void)rigid_alignment(ten, nine), Error);
  PoseList bad = ten;
  bad[4].translation().y() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW((void)evaluate_trajectory(ten, bad), Error);
  EXPECT_THROW((void)evaluate_trajectory(bad, ten), Error);
  bad = ten;
  bad[2].linear()(0, 1) = std::numeric_limits<double>::infinity();
  EXPECT_THROW((void)evaluate_trajectory(ten, bad), Error);
  EXPECT_THROW((void)evaluate_trajectory(ten, ten, {{}, 1}), Error);
  EXPECT_THROW((void)evaluate_trajectory(ten, ten, {{10.0, 0.0}, 1}), Error);
  EXPECT_THROW((void)evaluate_trajectory(ten, ten, {{10.0}, 0}), Error);
  try {
    (void)evaluate_trajectory(ten, nine);
    FAIL() << "no exception";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("10"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("9"), std::string::npos) << e.what();
  }
}

TEST(TrajectoryMetricsTest, RotationAngleIsAccurateNearZeroAndPi) {
  for (const double a : {0.0, 1e-9, 1e-4, 0.5, 3.0, std::numbers::pi - 1e-7}) {
    const Eigen::Matrix3d R = Eigen::AngleAxisd(a, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
    EXPECT_NEAR(rotation_angle(R), a, 1e-12) << a;
  }
}

}  // namespace
}  // namespace hmap
