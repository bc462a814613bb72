#include "hmap/slam/hmap_slam.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>

#include "hmap/core/error.hpp"
#include "hmap/core/format.hpp"

namespace hmap::slam {


Attitude attitude_of(const Pose& T) {
  const Eigen::Matrix3d R = T.linear();
  Attitude a;
  a.z = T.translation().z();
  a.pitch = std::asin(std::clamp(-R(2, 0), -1.0, 1.0));
  a.roll = std::atan2(R(2, 1), R(2, 2));
  return a;
}

PlanarPose planar_of(const Pose& T) {
  const Eigen::Matrix3d R = T.linear();
  return {T.translation().x(), T.translation().y(), std::atan2(R(1, 0), R(0, 0))};
}

Pose compose(const PlanarPose& xi, const Attitude& attitude) {
  Pose T = Pose::Identity();
  T.linear() = (Eigen::AngleAxisd(xi.yaw, Eigen::Vector3d::UnitZ()) *
                Eigen::AngleAxisd(attitude.pitch, Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(attitude.roll, Eigen::Vector3d::UnitX()))
                   .toRotationMatrix();
  T.translation() = Eigen::Vector3d(xi.x, xi.y, attitude.z);
  return T;
}

PlanarPose operator*(const PlanarPose& a, const PlanarPose& b) {
  const double c = std::cos(a.yaw);
  const double s = std::sin(a.yaw);
  return {a.x + c * b.x - s * b.y, a.y + s * b.x + c * b.y, a.yaw + b.yaw};
}

PlanarPose inverse(const PlanarPose& a) {
  const double c = std::cos(a.yaw);
  const double s = std::sin(a.yaw);
  return {-(c * a.x + s * a.y), s * a.x - c * a.y, -a.yaw};
}

HmapSlam::HmapSlam(const Params& params)
    : params_(params),
      mapper_(params),
      matcher_(params),
      refiner_(params),
      level_hvoxelizer_(params.map),
      map_centroids_(params.map.cell_size),
      wall_refiner_(params),
      wall_map_(params.map.cell_size, params.slam.wall_band_height),
      wall_scan_(params.map.cell_size, params.slam.wall_band_height) {
  level_hvoxelizer_.keep_centroids(params_.slam.hvoxel_centroids >= 1 || params_.slam.wall_tilt_drift > 0.0);
  level_hvoxelizer_.keep_wall_lean(params_.slam.wall_tilt_drift > 0.0);
  matcher_.search_when_lost(true);
}

namespace {

/// The continued map's own map, ground and occupancy parameters with `params`'s slam section.
Params continued_params(const Params& params, const HMap& map) {
  if (map.empty()) throw Error("continuing a map: the saved map is empty");
  Params p = map.params();
  p.slam = params.slam;
  validate(p);
  return p;
}

}  // namespace

HmapSlam::HmapSlam(const Params& params, HMap map, const ContinueOptions& where, std::optional<CellCentroids> centroids)
    : params_(continued_params(params, map)),
      mapper_(std::move(map)),
      matcher_(params_),
      refiner_(params_),
      level_hvoxelizer_(params_.map),
      map_centroids_(params_.map.cell_size),
      wall_refiner_(params_),
      wall_map_(params_.map.cell_size, params_.slam.wall_band_height),
      wall_scan_(params_.map.cell_size, params_.slam.wall_band_height),
      continuing_(where),
      map_as_given_(false) {
  level_hvoxelizer_.keep_centroids(params_.slam.hvoxel_centroids >= 1 || params_.slam.wall_tilt_drift > 0.0);
  level_hvoxelizer_.keep_wall_lean(params_.slam.wall_tilt_drift > 0.0);
  matcher_.search_when_lost(true);
  const PlanarPose& g = where.guess;
  if (!(std::isfinite(g.x) && std::isfinite(g.y) && std::isfinite(g.yaw))) {
    throw Error("continuing a map: the first scan's guess must be finite");
  }
  if (!(where.search_translation >= 0.0 && where.search_translation <= 20.0)) {
    throw Error(format("continuing a map: the search half-width %g m is outside [0, 20]", where.search_translation));
  }
  if (!(where.search_rotation >= 0.0 && where.search_rotation <= std::numbers::pi)) {
    throw Error(format("continuing a map: the yaw search half-width %g rad is outside [0, pi]", where.search_rotation));
  }
  last_ = previous_ = g;
  if (centroids) {
    if (centroids->cell_size() != params_.map.cell_size) {
      throw Error(format("continuing a map: its cell centroids are for %g m cells, the map's are %g m", centroids->cell_size(),
                         params_.map.cell_size));
    }
    map_centroids_ = std::move(*centroids);
  }
}

void HmapSlam::start_with_up(const Eigen::Vector3d& up_sensor) {
  if (!up_sensor.allFinite() || !(up_sensor.norm() > 0.0)) throw Error("the first scan's up vector must be finite and non-zero");
  const Attitude tilt = tilt_aligning(up_sensor.normalized(), Eigen::Vector3d::UnitZ(), last_attitude_);
  last_attitude_.roll = tilt.roll;
  last_attitude_.pitch = tilt.pitch;
}

PlanarPose HmapSlam::predict() const {
  if (scans_ < 2) return last_;
  return last_ * (inverse(previous_) * last_);
}

Twist HmapSlam::velocity() const {
  if (scans_ < 2) return {};
  const double dt = (stamp_last_ && stamp_previous_ ? *stamp_last_ - *stamp_previous_ : last_sweep_) +
                    merged_at_last_ - merged_at_previous_;
  return velocity_between(dt);
}

Twist HmapSlam::velocity_between(double dt) const { return twist_between(T_previous_, T_last_, dt); }

SlamStep HmapSlam::process(std::span<const Point3f> points_sensor, const std::optional<Attitude>& given,
                           const std::optional<PlanarPose>& guess) {
  ScanInput input;
  input.points_sensor = points_sensor;
  input.attitude = given;
  input.guess = guess;
  return process(input);
}

SlamStep HmapSlam::process(const ScanInput& input) {
  SlamStep step;
  const std::optional<Attitude>& given = input.attitude;
  const std::optional<PlanarPose>& guess = input.guess;
  const std::optional<ImuPrior>& imu = input.imu;
  std::span<const Point3f> points_sensor = input.points_sensor;
  // Deskewing: the sweep's motion is the body velocity from the last estimate to the guess when
  // one is given (odometry), else that of the last two estimates (the gyro's rate for the rotation
  // when there is an IMU), held over the sweep.
  Twist velocity;
  double middle = 0.0;  // the time on the points' clock the scan is moved to, matched and merged at
  bool from_estimates = false;  // the velocity is the last two estimates' (no guess)
  if (!input.times.empty() && params_.slam.deskew >= 1) {
    const auto [lo, hi] = std::minmax_element(input.times.begin(), input.times.end());
    const double sweep = static_cast<double>(*hi) - static_cast<double>(*lo);
    bool known = false;
    if (guess && scans_ >= 1) {
      const double dt = input.stamp && stamp_last_ ? *input.stamp - *stamp_last_ : sweep;
      if (dt > 0.0) {
        velocity = twist_between(T_last_, compose(*guess, given.value_or(last_attitude_)), dt);
        known = true;
      }
    } else if (scans_ >= 2) {
      // The velocity of the last two estimates (the IMU's rate replaces its rotation below). Moved
      // to the sweep's start, a rate error e would skew the scan, the match take about half of the
      // skew, e·T/2, into the pose, and the next rate err by -(e_k - e_k-1)/2 per sweep T: roots
      // 1/2 and -1 of z² + z/2 - 1/2, an oscillation that does not die out (on the parking route
      // without odometry the yaw error flipped sign and grew each scan; docs/SLAM.md). Moved to
      // the sweep's middle, the skew e·(τ - T/2) averages out of the matched pose, and the
      // estimates the next rate comes from are those middle poses: nothing is fed back.
      const double dt = (stamp_last_ && stamp_previous_ ? *stamp_last_ - *stamp_previous_ : last_sweep_) +
                        merged_at_last_ - merged_at_previous_;
      if (dt > 0.0) {
        velocity = velocity_between(dt);
        known = true;
        from_estimates = true;
      }
    }
    if (imu) {
      velocity.angular = imu->angular_velocity_sensor;
      known = true;
    }
    if (known) {
      // To the sweep's middle when the velocity is the estimates' or odometry's (the scan is matched
      // there); with the gyro's rate alone, the second scan stays at the sweep's start, where its
      // prediction is.
      if (from_estimates || guess) middle = 0.5 * (static_cast<double>(*lo) + static_cast<double>(*hi));
      if (from_estimates) {
        // The last two estimates moved to the same time in their sweeps (the first time: from the
        // sweep's start, the first scans' and the map frame's reference, to the middle), so that
        // the prediction and the next velocity are between the middles.
        if (merged_at_last_ != middle || merged_at_previous_ != middle) {
          T_last_ = T_last_ * exp_twist(velocity, middle - merged_at_last_);
          T_previous_ = T_previous_ * exp_twist(velocity, middle - merged_at_previous_);
          last_ = planar_of(T_last_);
          previous_ = planar_of(T_previous_);
          merged_at_last_ = merged_at_previous_ = middle;
        }
      }
      deskew(points_sensor, input.times, velocity, deskewed_, middle);
      points_sensor = deskewed_;
      step.deskewed = true;
      step.sweep_velocity = velocity;
      if (!skewed_.empty() && skewed_.size() == scans_) {
        // The scans so far had no velocity to be deskewed with (the first; without odometry the
        // second as well) and the map is those scans alone: it is built again from them deskewed
        // with this velocity. Else every later, deskewed scan is matched against a skewed map:
        // 0.3 m off at 10 m/s with odometry; without it, 4 m/s, 0.57 m against 0.04 m undeskewed.
        // Their poses are for the reference time (the first defines the map frame there).
        PointCloud fixed;
        mapper_ = Mapper(params_);
        for (const SkewedScan& old : skewed_) {
          deskew(old.points, old.times, velocity, fixed);
          (void)mapper_.integrate(fixed, old.T_map_sensor);
        }
      }
      skewed_.clear();
    }
    last_sweep_ = sweep;
  }
  // With odometry's velocity the scan is matched at the sweep's middle too: the guess (for the
  // stamp) is moved there along that velocity.
  std::optional<PlanarPose> guess_at = guess;
  if (guess && middle != 0.0) {
    guess_at = planar_of(compose(*guess, given.value_or(last_attitude_)) * exp_twist(velocity, middle));
  }
  step.guess = guess_at.value_or(predict());
  if (!guess && imu && imu->has_rotation && scans_ > 0) {
    // The gyro's rotation since the last scan turns the yaw guess (the translation stays constant velocity).
    const Eigen::Matrix3d R = T_last_.linear() * imu->R_previous_current;
    const double turn = std::remainder(std::atan2(R(1, 0), R(0, 0)) - last_.yaw, 2.0 * std::numbers::pi);
    step.guess.yaw = last_.yaw + turn;
  }
  PlanarPose estimate = step.guess;
  Attitude attitude = given.value_or(last_attitude_);
  // With an IMU, no attitude given and slam.imu_tilt_weight > 0, the tilt guess is the IMU's
  // gravity and the attitude fit is pulled toward it; the floor is not needed. Off by default: the
  // filter takes off the turn's acceleration but not the change of speed, so on the simulated
  // parking route (a car that speeds up and brakes) its vertical was up to 8 deg off and the long
  // route's RPE went from 0.97 % to 5.5 % with odometry. The gyro's turn is used either way.
  const bool imu_tilt = !given && imu.has_value() && params_.slam.imu_tilt_weight > 0.0;
  if (imu_tilt) {
    attitude = tilt_aligning(imu->up_sensor, Eigen::Vector3d::UnitZ(), attitude);
    step.imu_used = true;
  }
  const auto gravity_in_level = [&](const Attitude& a) -> std::optional<Eigen::Vector3d> {
    if (!imu_tilt) return std::nullopt;
    return Eigen::Vector3d(level_rotation(a) * imu->up_sensor);
  };
  // A tilt change that moves a point 10 m away by half the IoU layer (slam.min_layer_height), or a
  // height change of as much, changes what the planar match sees: the HVoxels are built again.
  const double layer = 0.5 * params_.slam.min_layer_height;
  const auto moved = [layer](const Attitude& a, const Attitude& b) {
    const double tilt = std::max(std::abs(a.roll - b.roll), std::abs(a.pitch - b.pitch));
    return tilt * 10.0 > layer || std::abs(a.z - b.z) > layer;
  };
  bool built = false;
  std::optional<Attitude> level_at;  // the attitude scan_level_ was last built at for this scan
  std::optional<Eigen::Vector3d> floor_sensor;  // this scan's floor normal in its sensor frame
  if (!given && !imu_tilt) {
    // The tilt that puts this scan's floor normal where the map's floor normal was last seen
    // (the map's z for the first scan), twice: the thin HVoxels the floor is found from are
    // sharper once the scan is nearly level.
    const PlanarPose heading{0.0, 0.0, step.guess.yaw};
    const Eigen::Vector3d target =
        scans_ == 0 ? Eigen::Vector3d::UnitZ()
                    : Eigen::Vector3d(compose(heading, Attitude{}).linear().transpose() * floor_up_);
    for (int pass = 0; pass < 2; ++pass) {
      std::optional<Eigen::Vector3d> n_level;
      level_hvoxelizer_.build(points_sensor, compose(PlanarPose{}, attitude), scan_level_,
                              [&](const ScanHVoxels& level) { n_level = floor_normal(level, params_); });
      level_at = attitude;
      built = true;
      if (!n_level) break;
      const Eigen::Vector3d n_sensor = level_rotation(attitude).transpose() * *n_level;
      floor_sensor = n_sensor;
      const Attitude next = tilt_aligning(n_sensor, target, attitude);
      const bool changed = moved(next, attitude);
      attitude = next;
      built = !changed;
      if (!changed) break;
    }
  }
  const auto floor_in_level = [&](const Attitude& a) -> std::optional<Eigen::Vector3d> {
    if (!floor_sensor) return std::nullopt;
    return Eigen::Vector3d(level_rotation(a) * *floor_sensor);
  };
  // Two tilt hypotheses. The floor prediction takes this scan's dominant floor for the surface the
  // last scan's was; where the ground changes slope (a ramp's foot or top), or another floor
  // dominates (the street ahead seen from the ramp), it turns the scan by the slope: 8 deg on the
  // simulated parking ramp, beyond what the map fit's gate bridges, and the map then keeps that
  // tilt. When the prediction and the last tilt differ, both are fitted to the map at the planar
  // guess and the one whose surfaces agree better with the map's goes on.
  if (!given && !imu_tilt && scans_ > 0 && floor_sensor) {
    // The hypotheses: the floor's prediction, the last tilt, and the tilt that levels this scan's
    // dominant floor (the floor the sensor stands on at a ramp's top, when it dominates).
    std::array<Attitude, 3> hypotheses{attitude, last_attitude_, tilt_aligning(*floor_sensor, Eigen::Vector3d::UnitZ(), attitude)};
    std::size_t count = 1;
    for (std::size_t h = 1; h < hypotheses.size(); ++h) {
      bool distinct = true;
      for (std::size_t j = 0; j < count; ++j) distinct = distinct && moved(hypotheses[h], hypotheses[j]);
      if (distinct) hypotheses[count++] = hypotheses[h];
    }
    if (count > 1) {
      double best = -1.0;
      std::size_t winner = 0;
      for (std::size_t h = 0; h < count; ++h) {
        level_hvoxelizer_.build(points_sensor, compose(PlanarPose{}, hypotheses[h]), scan_level_);
        level_at = hypotheses[h];
        const AttitudeFit fit = refiner_.refine(scan_level_, mapper_.map(), step.guess.x, step.guess.y, step.guess.yaw,
                                                hypotheses[h], floor_in_level(hypotheses[h]), std::nullopt);
        if (fit.agreement > best) {
          best = fit.agreement;
          winner = h;
        }
      }
      step.tilt_hypotheses = static_cast<int>(count);
      step.tilt_from_floor = winner == 0;
      attitude = hypotheses[winner];
      built = winner + 1 == count;  // scan_level_ holds the last hypothesis's HVoxels
    }
  }
  Eigen::Matrix3d predicted = Eigen::Matrix3d::Zero();  // the odometry's prior covariance
  const bool relocalise = scans_ == 0 && continuing_.has_value();
  if (relocalise) {
    // The first scan of a continued map: its levelled HVoxels as a map of their own (the sensor at
    // x = y = yaw = 0, z = 0), registered onto the saved map about the guess; z from the floors.
    Mapper scan_map(params_);
    Attitude level = attitude;
    level.z = 0.0;
    (void)scan_map.integrate(points_sensor, compose(PlanarPose{}, level));
    if (scan_map.map().empty()) throw Error("continuing a map: the first scan has no points in range");
    MapAlignOptions o;
    o.guess = {continuing_->guess.x, continuing_->guess.y, 0.0, continuing_->guess.yaw};
    o.search_translation = continuing_->search_translation;
    o.search_rotation = continuing_->search_rotation;
    step.relocalised = align_maps(mapper_.map(), scan_map.map(), o);
    const PlanarShift& at = step.relocalised->shift;
    estimate = {at.x, at.y, at.yaw};
    if (!given) attitude.z = at.z;  // a given attitude's z is the map's already
    step.guess = estimate;
  }
  if (scans_ > 0 || relocalise) {
    // The second scan has no motion prior (constant velocity predicts standing still): search.
    // Later, without odometry, the guess is constant velocity: a coarse search may move the pose
    // away from it only along what the scan constrains (on a ramp between walls it otherwise took
    // a minimum 0.6 m behind, 1.4 % cheaper; docs/SLAM.md). With odometry its prior decides.
    const CoarseSearch when_failed = guess ? CoarseSearch::kWhenFailed : CoarseSearch::kWhenFailedKeepPrediction;
    const auto search = scans_ == 1 && !guess ? CoarseSearch::kAlways : when_failed;
    // Odometry: its motion since the last scan, trusted to σ = sigma + noise · |motion| per axis,
    // on top of what the last estimate was already unsure of (pose_covariance_, propagated like an
    // EKF's: grown by each motion, shrunk by each match). After a blind stretch (scans with too
    // few HVoxels) the prior is wide, and the map takes back the drift the odometry made there.
    std::optional<MotionPrior> prior;
    if (guess && !relocalise) {
      const SlamParams& sp = params_.slam;
      const PlanarPose motion = inverse(last_) * *guess;
      const double st = sp.odometry_sigma_translation + sp.odometry_noise * std::hypot(motion.x, motion.y);
      const double sy = sp.odometry_sigma_rotation +
                        sp.odometry_noise * std::abs(std::remainder(motion.yaw, 2.0 * std::numbers::pi));
      Eigen::Matrix3d J = Eigen::Matrix3d::Identity();  // ∂guess/∂last: a yaw error swings the step
      J(0, 2) = -(guess_at->y - last_.y);
      J(1, 2) = guess_at->x - last_.x;
      predicted = J * pose_covariance_ * J.transpose();
      predicted.diagonal() += Eigen::Vector3d(st * st, st * st, sy * sy);
      prior = MotionPrior{*guess_at, predicted.inverse()};
    }
    const auto planar_match = [&](CoarseSearch mode) {
      // The scan's HVoxels in the gravity-aligned sensor frame (x = y = yaw = 0), so that eq. (6)
      // moves them in the plane only.
      if (!built) {
        level_hvoxelizer_.build(points_sensor, compose(PlanarPose{}, attitude), scan_level_);
        level_at = attitude;
      }
      built = false;
      matcher_.set_map_centroids(params_.slam.hvoxel_centroids >= 2 ? &map_centroids_ : nullptr);
      // A first pass that was lost and searched every heading says so, though the pass after the
      // attitude fit starts where it ended and needs no search.
      const bool searched_wide = step.planar_passes > 0 && step.match.wide_search;
      step.match = matcher_.match(scan_level_, mapper_.map(), estimate, mode,
                                  scans_ >= 2 && !guess ? std::optional<PlanarPose>(last_) : std::nullopt,
                                  guess ? ThinFallback::kHeading : ThinFallback::kFull, prior);
      step.match.wide_search = step.match.wide_search || searched_wide;
      estimate = step.match.pose;
      ++step.planar_passes;
    };
    planar_match(search);
    step.matched = true;
    if (!given && !step.match.skipped) {
      step.attitude = refiner_.refine(scan_level_, mapper_.map(), estimate.x, estimate.y, estimate.yaw, attitude,
                                      floor_in_level(attitude), gravity_in_level(attitude));
      const bool again_needed = moved(step.attitude.attitude, attitude);
      attitude = step.attitude.attitude;
      estimate.yaw += step.attitude.yaw_change;
      // The planar match saw the scan at the old tilt: re-level the HVoxels and match again.
      if (again_needed) {
        planar_match(when_failed);
        if (!step.match.skipped) {
          const AttitudeFit again = refiner_.refine(scan_level_, mapper_.map(), estimate.x, estimate.y, estimate.yaw,
                                                    attitude, floor_in_level(attitude), gravity_in_level(attitude));
          attitude = again.attitude;
          estimate.yaw += again.yaw_change;
          step.attitude = again;
        }
      }
    }
  }
  if (guess && (scans_ > 0 || relocalise)) {
    // The estimate's uncertainty for the next scan's prior: the match's, or the prediction's when
    // nothing was matched. Capped, so that a long blind stretch stays a finite matrix.
    pose_covariance_ = step.matched && !step.match.skipped ? step.match.covariance : predicted;
    constexpr double kMaxVariance = 1e4;  // (100 m)², (100 rad)²
    for (int k = 0; k < 3; ++k) pose_covariance_(k, k) = std::min(pose_covariance_(k, k), kMaxVariance);
  }
  if (params_.slam.wall_refine != 0) {
    // The walls' points in the level frame (scan_level_'s, whose tilt may be a step behind the
    // final one: a second-order difference in the plane), refined against, then added to the map's.
    if (!level_at) {
      level_hvoxelizer_.build(points_sensor, compose(PlanarPose{}, attitude), scan_level_);
      level_at = attitude;
    }
    wall_refiner_.collect(points_sensor, compose(PlanarPose{}, *level_at), scan_level_,
                          level_hvoxelizer_.cell_of_window(), wall_points_);
    if (step.matched && !step.match.skipped && !step.match.heading_only && !wall_map_.empty()) {
      wall_scan_.clear();
      wall_scan_.add(wall_points_);
      step.walls = wall_refiner_.refine(wall_scan_, wall_map_, estimate);
      if (step.walls.applied) estimate = step.walls.pose;
    }
    wall_map_.add(wall_points_, estimate);
  }
  if (params_.slam.wall_tilt_drift > 0.0 && !given && !imu_tilt && level_at) {
    // The walls' lean, measured in the frame scan_level_ was built in, as the verticals' direction
    // in the sensor frame, then in the present attitude's level frame: its tilt error, δ.
    const WallLean& wl = scan_level_.wall_lean;
    const double drift = params_.slam.wall_tilt_drift;
    tilt_variance_ += Eigen::Matrix2d::Identity() * drift * drift;
    if (wl.walls > 0) {
      const Eigen::Vector2d lean = wl.lean();
      const Eigen::Vector3d up_sensor = level_rotation(*level_at).transpose() * Eigen::Vector3d(lean.x(), lean.y(), 1.0).normalized();
      const Eigen::Vector3d up = level_rotation(attitude) * up_sensor;
      const Eigen::Vector2d delta(up.x() / up.z(), up.y() / up.z());
      // The walls' information, each direction's variance floored at a plumb wall's (0.2 %).
      constexpr double kPlumb = 0.002;
      const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(wl.information);
      Eigen::Matrix2d info = Eigen::Matrix2d::Zero();
      for (int k = 0; k < 2; ++k) {
        const double l = std::max(0.0, eig.eigenvalues()(k));
        info += l / (1.0 + l * kPlumb * kPlumb) * eig.eigenvectors().col(k) * eig.eigenvectors().col(k).transpose();
      }
      const Eigen::Matrix2d posterior = (tilt_variance_.inverse() + info).inverse();
      const Eigen::Vector2d correction = posterior * info * delta;
      tilt_variance_ = posterior;
      step.wall_tilt = std::hypot(correction.x(), correction.y());
      step.wall_tilt_walls = wl.walls;
      const Eigen::Vector3d corrected_up = level_rotation(attitude).transpose() *
                                           Eigen::Vector3d(correction.x(), correction.y(), 1.0).normalized();
      attitude = tilt_aligning(corrected_up, Eigen::Vector3d::UnitZ(), attitude);
    }
  }
  step.T_map_merged = compose(estimate, attitude);
  step.merged_at_s = middle;
  // The pose at the reference time: the sensor's at the middle moved back along the motion from the
  // last scan's middle to this one's (the reference time lies between the two: an interpolation,
  // where the deskewing's velocity, from the two scans before, would extrapolate).
  // With odometry, back along its velocity (the last estimate it was applied to is for the stamp).
  step.T_map_sensor = step.T_map_merged;
  if (middle != 0.0 && from_estimates) {
    const double dt = input.stamp && stamp_last_ ? *input.stamp - *stamp_last_ : last_sweep_;
    const Twist through = dt > 0.0 ? twist_between(T_last_, step.T_map_merged, dt) : velocity;
    step.T_map_sensor = step.T_map_merged * exp_twist(through, -middle);
  } else if (middle != 0.0) {
    step.T_map_sensor = step.T_map_merged * exp_twist(velocity, -middle);
  }
  if (step.matched && !step.match.skipped) {
    step.observable = {step.match.observable[0], step.match.observable[1], step.attitude.observable[0],
                       step.attitude.observable[1], step.attitude.observable[2], step.match.observable[2]};
  }
  // The floor normal in the map as this scan sees it, for the next scan's tilt prediction.
  if (floor_sensor) floor_up_ = (step.T_map_merged.linear() * *floor_sensor).normalized();
  step.mapping = mapper_.integrate(points_sensor, step.T_map_merged);
  if (params_.slam.hvoxel_centroids >= 2 && level_at) {
    // The scan's tall HVoxels' centroids into the map's cells, at the pose it was merged at
    // (scan_level_ was built at level_at, whose tilt may be a step behind the final one: a
    // second-order difference in the plane).
    const PlanarPose merged = planar_of(step.T_map_merged);
    map_centroids_.add(scan_level_, merged.x, merged.y, merged.yaw, static_cast<float>(params_.slam.min_match_height));
  }
  map_as_given_ = map_as_given_ && !step.deskewed && step.T_map_merged.matrix() == step.T_map_sensor.matrix();
  // (Not for a continued map: rebuilt from the first scans alone, it would lose what was saved.)
  if (!input.times.empty() && params_.slam.deskew >= 1 && !step.deskewed && skewed_.size() == scans_ &&
      skewed_.size() < kMaxSkewedScans && !continuing_) {
    skewed_.push_back({PointCloud(input.points_sensor.begin(), input.points_sensor.end()),
                       std::vector<float>(input.times.begin(), input.times.end()), step.T_map_merged});
  }
  // The estimates kept for the prediction and the velocity: at the middle when that velocity is
  // theirs, else at the stamp (odometry's guess is applied to the pose at the stamp).
  const Pose& kept = from_estimates ? step.T_map_merged : step.T_map_sensor;
  const double kept_at = from_estimates ? middle : 0.0;
  PlanarPose kept_planar = estimate;  // unwrapped yaw, and bit for bit when nothing was moved
  if (middle != 0.0 && !from_estimates) {
    const PlanarPose at_stamp = planar_of(step.T_map_sensor);
    kept_planar = {at_stamp.x, at_stamp.y,
                   estimate.yaw + std::remainder(at_stamp.yaw - estimate.yaw, 2.0 * std::numbers::pi)};
  }
  previous_ = scans_ > 0 ? last_ : kept_planar;
  last_ = kept_planar;
  T_previous_ = scans_ > 0 ? T_last_ : kept;
  T_last_ = kept;
  stamp_previous_ = stamp_last_;
  stamp_last_ = input.stamp;
  merged_at_previous_ = scans_ > 0 ? merged_at_last_ : kept_at;
  merged_at_last_ = kept_at;
  last_attitude_ = attitude;
  ++scans_;
  return step;
}

}  // namespace hmap::slam
