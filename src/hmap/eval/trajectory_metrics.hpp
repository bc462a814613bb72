#pragma once
// Trajectory accuracy of an estimate against ground truth: ATE (with and without the rigid
// alignment of Umeyama / Horn), RPE between consecutive frames, and the KITTI odometry benchmark's
// per-distance drift. Pure: poses in, numbers out (the apps write them).

#include <cstddef>
#include <cstdint>
#include <vector>

#include "hmap/core/types.hpp"

namespace hmap {

/// Settings of the trajectory evaluation.
struct TrajectoryEvalParams {
  /// [m] KITTI segment lengths. If the ground-truth path is shorter than the shortest of them,
  /// 10 %, 20 %, ..., 80 % of the path length are used instead (see `segment_length_source`).
  std::vector<double> segment_lengths = {100.0, 200.0, 300.0, 400.0, 500.0, 600.0, 700.0, 800.0};
  /// [frames] stride between KITTI segment start frames; 1 = every frame. KITTI's devkit uses 10
  /// (one second at 10 Hz); with 1 all segments count.
  int start_frame_step = 1;
};

/// Where the KITTI segment lengths came from.
enum class SegmentLengthSource : std::uint8_t {
  kGiven = 0,           ///< TrajectoryEvalParams::segment_lengths
  kFractionOfPath = 1,  ///< 10 %..80 % of the path length: the path was shorter than the given lengths
};

/// KITTI drift averaged over the segments of one length.
struct SegmentLengthError {
  double length_m = 0.0;
  std::size_t segments = 0;           ///< start frames with a segment of this length
  double trans_pct = 0.0;             ///< mean of 100·|t(ΔT)| / L [%]; NaN when segments == 0
  double rot_deg_per_m = 0.0;         ///< mean of angle(ΔT) / L [deg/m]; NaN when segments == 0
};

/// Every number of one trajectory evaluation. Distances in metres, angles in degrees.
struct TrajectoryMetrics {
  std::size_t frames = 0;
  double path_length_m = 0.0;          ///< of the ground truth, sum of consecutive translations

  // ATE: e_i = |t_truth_i − t_estimate_i|.
  double ate_rmse_m = 0.0;             ///< no alignment
  double ate_mean_m = 0.0;
  double ate_median_m = 0.0;
  double ate_max_m = 0.0;
  // ATE after aligning the estimate with T_truth_estimate: e_i = |t_truth_i − T_truth_estimate·t_estimate_i|.
  double ate_rmse_aligned_m = 0.0;
  double ate_mean_aligned_m = 0.0;
  double ate_median_aligned_m = 0.0;
  double ate_max_aligned_m = 0.0;
  // ATE from the first pose: both trajectories re-expressed in their first frame (T_0⁻¹ T_i, evo's
  // --align_origin), e_i = |t(T_truth_0⁻¹ T_truth_i) − t(T_est_0⁻¹ T_est_i)|: for an estimate whose
  // world frame is not the truth's (a gravity-levelled map against a reference in the first
  // sensor's frame) the error of the motion since the start, the first pose's own error included
  // in every later one.
  double ate_rmse_origin_m = 0.0;
  double ate_max_origin_m = 0.0;
  /// The last frame's e_i from the first pose: on a route that comes back to its start, the
  /// end-to-start error (what a loop closure removes); and its horizontal part (x, y of the first frame).
  double end_error_origin_m = 0.0;
  double end_error_origin_planar_m = 0.0;
  /// Least-squares rigid transform (no scale) from the estimate's world frame to the truth's.
  Pose T_truth_estimate = Pose::Identity();

  // RPE between consecutive frames i, i+1 with ΔT = (T_truth_i⁻¹ T_truth_i+1)⁻¹ (T_est_i⁻¹ T_est_i+1).
  double rpe_frame_trans_rmse_m = 0.0;  ///< RMSE of |t(ΔT)| [m]
  double rpe_frame_rot_rmse_deg = 0.0;  ///< RMSE of angle(ΔT) [deg]

  // KITTI per-distance drift (devkit's calcSequenceErrors), averaged over every (start frame i,
  // length L) segment of all lengths: the segment ends at the first frame j whose distance along
  // the true path from i is strictly greater than L (the devkit's test; none: no segment), and
  // ΔT = (T_truth_i⁻¹ T_truth_j)⁻¹ (T_est_i⁻¹ T_est_j) gives 100·|t(ΔT)| / L and angle(ΔT) / L.
  double rpe_trans_pct = 0.0;           ///< [%]; NaN when no segment exists
  double rpe_rot_deg_per_m = 0.0;       ///< [deg/m]; NaN when no segment exists
  std::size_t rpe_segments = 0;         ///< segments averaged
  SegmentLengthSource segment_length_source = SegmentLengthSource::kGiven;
  std::vector<double> segment_lengths_m;       ///< lengths actually used
  std::vector<SegmentLengthError> per_length;  ///< one per entry of segment_lengths_m
};

/// Evaluates `estimate` against `truth` (both T_world_frame, frame i of one matches frame i of the
/// other). Throws hmap::Error for lists of different lengths, fewer than 2 poses, a non-finite
/// pose, or bad parameters.
[[nodiscard]] TrajectoryMetrics evaluate_trajectory(const PoseList& truth, const PoseList& estimate,
                                                    const TrajectoryEvalParams& params = {});

/// The rigid transform T minimising Σ |t_truth_i − T·t_estimate_i|² over the poses' positions
/// (Umeyama 1991, without scale; Horn's closed form). Same input checks as evaluate_trajectory.
[[nodiscard]] Pose rigid_alignment(const PoseList& truth, const PoseList& estimate);

/// `poses` re-expressed from their first pose (T0⁻¹·Tk): trajectories in different frames start
/// together at the identity, as the ATE "from the first pose" compares them. Empty stays empty.
[[nodiscard]] PoseList from_first_pose(PoseList poses);

/// Rotation angle of a rotation matrix [rad], accurate near 0 and π (atan2 of sine and cosine).
[[nodiscard]] double rotation_angle(const Eigen::Matrix3d& R);

}  // namespace hmap
