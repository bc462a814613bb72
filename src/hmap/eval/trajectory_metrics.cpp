#include "hmap/eval/trajectory_metrics.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>

#include <Eigen/Geometry>

#include "hmap/core/error.hpp"

namespace hmap {
namespace {

constexpr double kRadToDeg = 180.0 / std::numbers::pi;
constexpr double kUndefined = std::numeric_limits<double>::quiet_NaN();

void check_inputs(const PoseList& truth, const PoseList& estimate) {
  if (truth.size() != estimate.size()) {
    throw Error("trajectory evaluation: the ground truth has " + std::to_string(truth.size()) +
                " poses but the estimate has " + std::to_string(estimate.size()) +
                "; frame i of one must match frame i of the other");
  }
  if (truth.size() < 2) {
    throw Error("trajectory evaluation: needs at least 2 poses, got " + std::to_string(truth.size()));
  }
  for (std::size_t i = 0; i < truth.size(); ++i) {
    if (!truth[i].matrix().allFinite()) {
      throw Error("trajectory evaluation: ground-truth pose " + std::to_string(i) + " is not finite");
    }
    if (!estimate[i].matrix().allFinite()) {
      throw Error("trajectory evaluation: estimated pose " + std::to_string(i) + " is not finite");
    }
  }
}

struct Stats {
  double rmse = 0.0;
  double mean = 0.0;
  double median = 0.0;
  double max = 0.0;
};

Stats stats_of(std::vector<double> e) {
  Stats s;
  double sum = 0.0;
  double sum_sq = 0.0;
  for (const double v : e) {
    sum += v;
    sum_sq += v * v;
    s.max = std::max(s.max, v);
  }
  const auto n = static_cast<double>(e.size());
  s.rmse = std::sqrt(sum_sq / n);
  s.mean = sum / n;
  const std::size_t mid = e.size() / 2;
  std::nth_element(e.begin(), e.begin() + static_cast<std::ptrdiff_t>(mid), e.end());
  s.median = e[mid];
  if (e.size() % 2 == 0) {  // even count: mean of the two middle values
    s.median = 0.5 * (s.median + *std::max_element(e.begin(), e.begin() + static_cast<std::ptrdiff_t>(mid)));
  }
  return s;
}

/// The relative-pose error ΔT = (T_truth_i⁻¹ T_truth_j)⁻¹ (T_est_i⁻¹ T_est_j), expressed in the
/// frame of segment start i. KITTI's devkit uses the inverse, which has the same norms.
Pose relative_error(const PoseList& truth, const PoseList& estimate, std::size_t i, std::size_t j) {
  const Pose delta_truth = truth[i].inverse(Eigen::Isometry) * truth[j];
  const Pose delta_estimate = estimate[i].inverse(Eigen::Isometry) * estimate[j];
  return delta_truth.inverse(Eigen::Isometry) * delta_estimate;
}

}  // namespace

PoseList from_first_pose(PoseList poses) {
  if (poses.empty()) return poses;
  const Pose first_inverse = poses.front().inverse();
  for (Pose& T : poses) T = first_inverse * T;
  return poses;
}

double rotation_angle(const Eigen::Matrix3d& R) {
  const Eigen::Vector3d axis_sin(R(2, 1) - R(1, 2), R(0, 2) - R(2, 0), R(1, 0) - R(0, 1));
  const double sin_angle = 0.5 * axis_sin.norm();
  const double cos_angle = 0.5 * (R.trace() - 1.0);
  return std::atan2(sin_angle, cos_angle);
}

Pose rigid_alignment(const PoseList& truth, const PoseList& estimate) {
  check_inputs(truth, estimate);
  const auto n = static_cast<Eigen::Index>(truth.size());
  Eigen::Matrix3Xd points_estimate(3, n);
  Eigen::Matrix3Xd points_truth(3, n);
  for (Eigen::Index i = 0; i < n; ++i) {
    points_estimate.col(i) = estimate[static_cast<std::size_t>(i)].translation();
    points_truth.col(i) = truth[static_cast<std::size_t>(i)].translation();
  }
  // Umeyama 1991, eq. (39)-(41) with c = 1: SVD of the cross-covariance, det-corrected.
  Pose T_truth_estimate = Pose::Identity();
  T_truth_estimate.matrix() = Eigen::umeyama(points_estimate, points_truth, /*with_scaling=*/false);
  return T_truth_estimate;
}

TrajectoryMetrics evaluate_trajectory(const PoseList& truth, const PoseList& estimate,
                                      const TrajectoryEvalParams& params) {
  check_inputs(truth, estimate);
  if (params.segment_lengths.empty()) {
    throw Error("trajectory evaluation: segment_lengths is empty");
  }
  for (const double length : params.segment_lengths) {
    if (!(length > 0.0) || !std::isfinite(length)) {
      throw Error("trajectory evaluation: segment length " + std::to_string(length) +
                  " m is not a positive finite number");
    }
  }
  if (params.start_frame_step < 1) {
    throw Error("trajectory evaluation: start_frame_step must be >= 1, got " +
                std::to_string(params.start_frame_step));
  }

  const std::size_t n = truth.size();
  TrajectoryMetrics m;
  m.frames = n;

  // Distance travelled along the ground truth up to each frame (KITTI's trajectoryDistances).
  std::vector<double> distance(n, 0.0);
  for (std::size_t i = 1; i < n; ++i) {
    distance[i] = distance[i - 1] + (truth[i].translation() - truth[i - 1].translation()).norm();
  }
  m.path_length_m = distance.back();

  // ATE, unaligned and aligned.
  m.T_truth_estimate = rigid_alignment(truth, estimate);
  std::vector<double> errors(n);
  std::vector<double> errors_aligned(n);
  for (std::size_t i = 0; i < n; ++i) {
    errors[i] = (truth[i].translation() - estimate[i].translation()).norm();
    errors_aligned[i] = (truth[i].translation() - m.T_truth_estimate * estimate[i].translation()).norm();
  }
  const Stats ate = stats_of(std::move(errors));
  const Stats ate_aligned = stats_of(std::move(errors_aligned));
  m.ate_rmse_m = ate.rmse;
  m.ate_mean_m = ate.mean;
  m.ate_median_m = ate.median;
  m.ate_max_m = ate.max;
  m.ate_rmse_aligned_m = ate_aligned.rmse;
  m.ate_mean_aligned_m = ate_aligned.mean;
  m.ate_median_aligned_m = ate_aligned.median;
  m.ate_max_aligned_m = ate_aligned.max;
  std::vector<double> errors_origin(n);
  const PoseList truth_origin = from_first_pose(truth);
  const PoseList estimate_origin = from_first_pose(estimate);
  for (std::size_t i = 0; i < n; ++i) {
    errors_origin[i] = (truth_origin[i].translation() - estimate_origin[i].translation()).norm();
  }
  if (n > 0) {
    const Eigen::Vector3d end = truth_origin[n - 1].translation() - estimate_origin[n - 1].translation();
    m.end_error_origin_m = end.norm();
    m.end_error_origin_planar_m = end.head<2>().norm();
  }
  const Stats ate_origin = stats_of(std::move(errors_origin));
  m.ate_rmse_origin_m = ate_origin.rmse;
  m.ate_max_origin_m = ate_origin.max;

  // RPE between consecutive frames.
  double trans_sq = 0.0;
  double rot_sq = 0.0;
  for (std::size_t i = 0; i + 1 < n; ++i) {
    const Pose delta = relative_error(truth, estimate, i, i + 1);
    trans_sq += delta.translation().squaredNorm();
    const double angle = rotation_angle(delta.linear());
    rot_sq += angle * angle;
  }
  m.rpe_frame_trans_rmse_m = std::sqrt(trans_sq / static_cast<double>(n - 1));
  m.rpe_frame_rot_rmse_deg = std::sqrt(rot_sq / static_cast<double>(n - 1)) * kRadToDeg;

  // KITTI per-distance drift (devkit's calcSequenceErrors).
  const double shortest = *std::min_element(params.segment_lengths.begin(), params.segment_lengths.end());
  if (m.path_length_m < shortest) {
    m.segment_length_source = SegmentLengthSource::kFractionOfPath;
    for (int tenth = 1; tenth <= 8; ++tenth) {
      m.segment_lengths_m.push_back(static_cast<double>(tenth) * m.path_length_m / 10.0);
    }
  } else {
    m.segment_length_source = SegmentLengthSource::kGiven;
    m.segment_lengths_m = params.segment_lengths;
  }
  double trans_sum = 0.0;  // of |t(ΔT)| / L
  double rot_sum = 0.0;    // of angle(ΔT) / L [rad/m]
  for (const double length : m.segment_lengths_m) {
    SegmentLengthError per{length, 0, 0.0, 0.0};
    double per_trans = 0.0;
    double per_rot = 0.0;
    if (length > 0.0) {  // a path of length 0 has no segment
      for (std::size_t first = 0; first < n; first += static_cast<std::size_t>(params.start_frame_step)) {
        // The first frame farther than `length` from `first` along the path: strictly farther,
        // as the devkit's lastFrameFromSegmentLength does.
        const auto it = std::upper_bound(distance.begin() + static_cast<std::ptrdiff_t>(first), distance.end(),
                                         distance[first] + length);
        if (it == distance.end()) break;  // later start frames have even less path ahead
        const auto last = static_cast<std::size_t>(it - distance.begin());
        const Pose delta = relative_error(truth, estimate, first, last);
        per_trans += delta.translation().norm() / length;
        per_rot += rotation_angle(delta.linear()) / length;
        ++per.segments;
      }
    }
    trans_sum += per_trans;
    rot_sum += per_rot;
    m.rpe_segments += per.segments;
    const auto count = static_cast<double>(per.segments);
    per.trans_pct = per.segments > 0 ? 100.0 * per_trans / count : kUndefined;
    per.rot_deg_per_m = per.segments > 0 ? kRadToDeg * per_rot / count : kUndefined;
    m.per_length.push_back(per);
  }
  const auto segments = static_cast<double>(m.rpe_segments);
  m.rpe_trans_pct = m.rpe_segments > 0 ? 100.0 * trans_sum / segments : kUndefined;
  m.rpe_rot_deg_per_m = m.rpe_segments > 0 ? kRadToDeg * rot_sum / segments : kUndefined;
  return m;
}

}  // namespace hmap
