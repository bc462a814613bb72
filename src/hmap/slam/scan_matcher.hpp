#pragma once
// Gauss-Newton matching of a scan's HVoxels against the HMAP (section IV-C, eq. 5-8).

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "hmap/core/params.hpp"
#include "hmap/maps/hmap.hpp"
#include "hmap/maps/scan_hvoxels.hpp"
#include "hmap/maps/cell_centroids.hpp"
#include "hmap/slam/hvoxel_metric.hpp"

namespace hmap::slam {

/// ξ = (p_x, p_y, φ) of eq. (5): the planar part of T_map_sensor.
struct PlanarPose {
  double x = 0.0;    ///< [m]
  double y = 0.0;    ///< [m]
  double yaw = 0.0;  ///< [rad]
};

/// A Gaussian belief about ξ before the scan is matched (odometry): its mean and information
/// matrix Λ (the inverse covariance, in (m, m, rad)). The match minimises eq. (5) plus s²·ΔᵀΛΔ,
/// Δ = ξ − mean, s² being the recent matches' cost per HVoxel (eq. 5's residual variance): a match
/// built on few HVoxels or along a corridor cannot move the pose farther from the odometry than
/// the odometry's error allows, a match on many HVoxels still does.
struct MotionPrior {
  PlanarPose mean;
  Eigen::Matrix3d information = Eigen::Matrix3d::Identity();

  /// σ [m] in x and y, σ [rad] in yaw, independent.
  [[nodiscard]] static MotionPrior from_sigmas(const PlanarPose& mean, double sigma_translation, double sigma_yaw) {
    MotionPrior prior{mean, Eigen::Matrix3d::Zero()};
    prior.information.diagonal() << 1.0 / (sigma_translation * sigma_translation),
        1.0 / (sigma_translation * sigma_translation), 1.0 / (sigma_yaw * sigma_yaw);
    return prior;
  }
};

/// What one match did. The Hessian and its eigenvalues are reported so that an ill-constrained
/// match (a featureless corridor) is visible, not hidden.
struct MatchResult {
  PlanarPose pose;                 ///< the estimate ξ*
  bool converged = false;          ///< the last step was below the convergence thresholds
  int iterations = 0;              ///< Gauss-Newton steps taken (the coarse search's included)
  double initial_cost = 0.0;       ///< eq. (5) per HVoxel, (1/n) Σ w (1 − M_H)², at the guess
  double final_cost = 0.0;         ///< the same at ξ*
  double score = 0.0;              ///< mean M_H at ξ* [0, 1]: 1 = every HVoxel matches its column
  double prior_cost = 0.0;         ///< the motion prior's term at ξ*, per HVoxel (0 without a prior)
  /// With a prior: the covariance of ξ* (m, m, rad), (H/s² + Λ)⁻¹, H the scan's Hessian (eq. 8)
  /// and s² the residual variance the prior was weighed with. Zero without a prior.
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  std::size_t hvoxels_used = 0;    ///< scan HVoxels selected (density, min_match_height, max_hvoxels)
  Eigen::Matrix3d hessian = Eigen::Matrix3d::Zero();  ///< eq. (8) at ξ*, in (m, m, rad)
  /// Eigenvalues of the Hessian with yaw scaled by the HVoxels' RMS radius (so all three are in
  /// 1/m²), ascending.
  Eigen::Vector3d eigenvalues = Eigen::Vector3d::Zero();
  /// Curvature of eq. (5) per HVoxel along the three eigenvectors (same order), by central
  /// differences one cell wide: the information that survives averaging over the HVoxels.
  Eigen::Vector3d curvature = Eigen::Vector3d::Zero();
  /// The eigenvectors the curvatures are taken along (columns, in (m, m, rad·RMS radius)).
  Eigen::Matrix3d directions = Eigen::Matrix3d::Identity();
  /// x, y, yaw observable: false for an axis that a direction of too little curvature (under
  /// slam.degeneracy_ratio of the largest) mostly points along (a corridor: the axis along it).
  std::array<bool, 3> observable{true, true, true};
  bool degenerate = false;         ///< smallest / largest curvature < slam.degeneracy_ratio
  bool coarse_search = false;      ///< the coarse search ran (Gauss-Newton looked failed)
  /// The coarse search's best still fitted less than ScanMatcher::kLostScoreRatio of the recent
  /// matches' mean M_H: every heading was searched too (within twice slam.coarse_translation).
  bool wide_search = false;
  /// The coarse search found a lower cost elsewhere, but the move there was along a direction the
  /// scan hardly constrains (CoarseSearch::kWhenFailedKeepPrediction): the guess's minimum was kept.
  bool coarse_rejected = false;
  /// Too few HVoxels were tall enough and the thin ones turned the yaw alone (ThinFallback::kHeading):
  /// x and y are the guess's.
  bool heading_only = false;
  /// Fewer than ScanMatcher::kMinHVoxels were selected: no matching, `pose` is the guess
  /// (also flagged degenerate, not converged).
  bool skipped = false;
};

/// When the coarse search runs.
enum class CoarseSearch : std::uint8_t {
  kWhenFailed,  ///< Gauss-Newton did not converge or scored under the trigger (slam.coarse_trigger_ratio)
  kAlways,      ///< also after a converged match: for a guess with no motion prior (the second scan)
  /// As kWhenFailed, for a guess that predicts the motion (constant velocity, no odometry): the
  /// search's pose replaces the minimum found from the guess only when the scan supports the move.
  /// A move of a cell or more (yaw counted at the HVoxels' RMS radius) must lower the cost by at
  /// least slam.degeneracy_ratio times what the cost rises when the pose moves as far along the
  /// scan's best-constrained direction. On a ramp between walls or in
  /// a corridor, minima half a metre apart along it differ by 1-3 %. Of the 40 picks this refused on
  /// the simulated routes, 36 were farther from the truth than the guess's minimum (docs/SLAM.md).
  kWhenFailedKeepPrediction,
};

/// What a scan is matched with when fewer than ScanMatcher::kMinHVoxels of its HVoxels are at
/// least slam.min_match_height tall (a blind stretch: bare ground and kerbs).
enum class ThinFallback : std::uint8_t {
  kNone,     ///< nothing: the guess is kept (MatchResult::skipped)
  kFull,     ///< x, y and yaw from all the HVoxels, floors and kerbs included
  kHeading,  ///< the yaw from all the HVoxels; x and y keep the guess (odometry's)
};

/// Matches scans against a map. Holds its buffers, so that matching allocates nothing once warm.
class ScanMatcher {
 public:
  /// A scan with fewer selected HVoxels is not matched (MatchResult::skipped). Measured on the
  /// simulated parking (VLP-16, map.point_distance_threshold 0.8): long route RPE 0.65 % with
  /// every scan matched, 0.43 / 0.46 / 0.47 / 0.54 % with 10 / 20 / 30 / 50 (docs/SLAM.md).
  static constexpr std::size_t kMinHVoxels = 20;
  /// The coarse search takes at most this many yaw steps each way (its step follows the scan's
  /// radius, two cells at its RMS radius; beyond this many the step widens).
  static constexpr int kCoarseMaxYawSteps = 64;

  /// Throws hmap::Error for invalid parameters.
  explicit ScanMatcher(const Params& params);

  /// Selects the HVoxels of `scan_level` with ρ >= n_th ("Height-Voxel Selection") and
  /// minimises eq. (5) from `guess`. `scan_level` is the scan's HVoxel representation in the
  /// gravity-aligned sensor frame (z, roll and pitch applied; x = y = yaw = 0): its cell centres
  /// are the v_x, v_y of eq. (6). Fewer than kMinHVoxels selected: the guess is returned, skipped.
  /// `thin_fallback`: with fewer than kMinHVoxels at least slam.min_match_height tall, match with
  /// all of them (floors and kerbs included) instead of keeping the guess. kFull, for a guess that
  /// is only constant velocity: blind, it drove straight through a U-turn at the empty end of the
  /// parking's side road. kHeading, for odometry's guess: the thin HVoxels turn the yaw only (the
  /// ground rings pull a translation back toward the last scan, not a turn about the sensor), x and
  /// y keep the odometry's; no coarse search then (docs/SLAM.md). Only the thin HVoxels
  /// whose cell and its eight neighbours are in the map (at the guess) take part: on bare ground the
  /// edge of what the map has seen was the only "feature" and held the pose back.
  /// With a sparse ring pattern few are left, and the match is then skipped. The thin HVoxels are
  /// matched at their cells' centres, and the map read at its cells' centres too (the map centroids
  /// are the tall HVoxels'), whatever the scan's centroids and set_map_centroids.
  /// `alternative` (the last pose, when the guess extrapolates a motion): a second centre of the
  /// coarse search. A handheld sensor's turn rate changes sign from one scan to the next, so
  /// constant velocity can be farther off than no motion at all.
  /// `prior` (odometry): the Gauss-Newton steps and the coarse search's scores include it
  /// (MotionPrior); the degeneracy and the Hessian reported are the scan's alone.
  [[nodiscard]] MatchResult match(const ScanHVoxels& scan_level, const HMap& map, const PlanarPose& guess,
                                  CoarseSearch search = CoarseSearch::kWhenFailed,
                                  const std::optional<PlanarPose>& alternative = std::nullopt,
                                  ThinFallback thin_fallback = ThinFallback::kNone,
                                  const std::optional<MotionPrior>& prior = std::nullopt);

  /// Whether a match that still fits the map less than kLostScoreRatio of the recent matches'
  /// mean M_H after its coarse search searches again over every heading (MatchResult::wide_search).
  /// Off by default: a tracker (HmapSlam) turns it on; a matcher scoring poses it chose itself (a
  /// map registration's yaw sectors, whose wrong sectors fit badly by design) keeps it off.
  void search_when_lost(bool on) { lost_search_ = on; }

  /// Where in its cell the map's surface lies (slam.hvoxel_centroids 2), for the matches that
  /// follow; nullptr (the default): at the cells' centres. A scan HVoxel that lands in a cell with a
  /// centroid is looked up that far the other way, so that the map's value sits at its centroid
  /// (the offset of the cell it lands in, held while it stays there). Must outlive those matches.
  void set_map_centroids(const CellCentroids* centroids) {
    map_centroids_ = centroids;
    centroid_view_.reset(nullptr, {}, 0);  // match() makes it over its window
    for (Candidate& c : candidates_) c.at = CellKey{INT32_MIN, INT32_MIN};  // cached offsets were of the old ones
  }

  /// eq. (5) per HVoxel at ξ for the HVoxels selected by the last match() (for tests and tools).
  [[nodiscard]] double cost_at(const PlanarPose& pose);

 private:
  struct Candidate {
    Eigen::Vector2f v;                 // v_x, v_y of eq. (6) [m]
    Interval layer;                    // widened to slam.min_layer_height
    CellKey base{INT32_MIN, INT32_MIN};  // cached: the cell (i0, j0) the F values belong to
    std::array<float, 4> F{};
    CellKey at{INT32_MIN, INT32_MIN};  // cached: the map cell whose centroid offset is `offset`
    Eigen::Vector2f offset = Eigen::Vector2f::Zero();  // [m] zero for a cell without a centroid
  };
  /// Drops the candidates whose cell and its eight neighbours (at `guess`) are not all in the map.
  void keep_inside_map(const HMap& map, const PlanarPose& guess);
  struct Linearization {
    Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
    Eigen::Vector3d g = Eigen::Vector3d::Zero();
    double cost = 0.0;   // Σ w r²
    double score = 0.0;  // Σ M_H
  };

  /// `at_centres`: every candidate at its cell's centre, though the scan has centroids.
  void select(const ScanHVoxels& scan_level, float min_match, bool at_centres = false);
  /// Whether eq. (5) supports moving from `from` (Gauss-Newton from the guess) to `to` (the coarse
  /// search's pick): a move under a cell always; else the gain is at least slam.degeneracy_ratio of
  /// the rise over as long a move along `to`'s best-constrained direction. Assesses `to`'s
  /// degeneracy (assess_degeneracy) on the way.
  bool supports_move(const MatchResult& from, MatchResult& to);
  /// Every how many selected HVoxels the curvature probes sum (at most kCurvatureHVoxels of them).
  [[nodiscard]] std::size_t curvature_stride() const;
  /// cost_only at each pose over the probes' thinned HVoxels, the poses on the cores.
  void probe_costs(std::span<const PlanarPose> poses, std::span<double> costs) const;
  Linearization linearize(const PlanarPose& pose, std::size_t stride);
  /// The cost of linearize(pose, stride) (same terms, same order), without touching the cached
  /// F values: poses can be scored in parallel.
  [[nodiscard]] double cost_only(const PlanarPose& pose, std::size_t stride) const;
  /// The prior's term of the cost at ξ, its gradient side and Hessian added to `lin` (no-op without one).
  void add_prior(const PlanarPose& pose, Linearization& lin) const;
  [[nodiscard]] double prior_cost_at(const PlanarPose& pose) const;
  [[nodiscard]] Eigen::Vector3d solve(const Linearization& lin, bool& degenerate, Eigen::Vector3d& eigenvalues) const;
  void assess_degeneracy(MatchResult& result);
  MatchResult gauss_newton(const PlanarPose& guess);
  /// The kCoarseStarts best poses of a grid around the guess, best first: within `translation`
  /// [m] in x and y and `rotation` [rad] in yaw.
  std::vector<PlanarPose> coarse_search(const PlanarPose& guess, double translation, double rotation);
  /// A match whose coarse search still ends below this fraction of the recent matches' mean M_H
  /// is lost: searched again over every heading.
  static constexpr double kLostScoreRatio = 0.5;
  static constexpr std::size_t kCoarseStarts = 3;

  Params params_;
  LayerInterpolator interpolator_;
  LocalMapView view_;
  std::vector<Candidate> candidates_;
  std::vector<MetricSample> samples_;  // linearize's M_H and gradient per visited candidate
  double rms_radius_ = 1.0;
  double reference_score_ = 0.0;  // running mean of the scores of the last matches
  double reference_cost_ = 0.0;   // running mean of the final costs per HVoxel of the last matches
  std::optional<MotionPrior> prior_;  // of the match under way
  double prior_weight_ = 0.0;         // s² of MotionPrior for it
  bool yaw_only_ = false;  // the match under way moves the yaw alone (ThinFallback::kHeading)
  bool lost_search_ = false;  // search_when_lost
  const CellCentroids* map_centroids_ = nullptr;   // set_map_centroids
  const CellCentroids* read_centroids_ = nullptr;  // what the match under way reads: map_centroids_, none in a thin fallback
  CellCentroids::View centroid_view_;              // read_centroids_' tiles in view_'s window
};

}  // namespace hmap::slam
