#include "hmap/slam/attitude.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdint>

namespace hmap::slam {

namespace {

/// Roll and pitch of a rotation R = Rz(yaw)·Ry(pitch)·Rx(roll), and its yaw.
void decompose(const Eigen::Matrix3d& R, double& roll, double& pitch, double& yaw) {
  pitch = std::asin(std::clamp(-R(2, 0), -1.0, 1.0));
  roll = std::atan2(R(2, 1), R(2, 2));
  yaw = std::atan2(R(1, 0), R(0, 0));
}

/// A small deterministic generator (the same floor every run).
struct Lcg {
  std::uint64_t state;
  std::size_t below(std::size_t n) {
    state = state * 6364136223846793005ULL + 1442695040888963407ULL;
    return static_cast<std::size_t>((state >> 33) % n);
  }
};

/// Least-squares plane z = a x + b y + c through the points within `tolerance` of `plane`
/// (n·p = d, n unit with n.z > 0); returns the number of them, updates `plane`.
std::size_t refit_plane(const std::vector<Eigen::Vector3d>& pts, double tolerance, Eigen::Vector3d& n, double& d) {
  Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  std::size_t inliers = 0;
  for (const auto& p : pts) {
    if (std::abs(n.dot(p) - d) > tolerance) continue;
    const Eigen::Vector3d row(p.x(), p.y(), 1.0);
    A += row * row.transpose();
    b += row * p.z();
    ++inliers;
  }
  if (inliers < 3) return inliers;
  const Eigen::Vector3d abc = A.ldlt().solve(b);
  if (!abc.allFinite()) return 0;
  const Eigen::Vector3d raw(-abc.x(), -abc.y(), 1.0);
  const double norm = raw.norm();
  n = raw / norm;
  d = abc.z() / norm;
  return inliers;
}

}  // namespace

Eigen::Matrix3d level_rotation(const Attitude& a) {
  return (Eigen::AngleAxisd(a.pitch, Eigen::Vector3d::UnitY()) * Eigen::AngleAxisd(a.roll, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

Attitude tilt_aligning(const Eigen::Vector3d& n_sensor, const Eigen::Vector3d& target, const Attitude& a) {
  // Two equations (the direction of R·n) for two unknowns (roll, pitch), solved by Gauss-Newton
  // from the minimal rotation's tilt: dropping that rotation's yaw would turn R·n away from target.
  Attitude out = a;
  double yaw = 0.0;
  decompose(Eigen::Quaterniond::FromTwoVectors(n_sensor, target).toRotationMatrix(), out.roll, out.pitch, yaw);
  for (int it = 0; it < 10; ++it) {
    const Eigen::Vector3d r = level_rotation(out) * n_sensor - target;
    if (r.norm() < 1e-12) break;
    constexpr double h = 1e-7;
    Attitude ar = out;
    ar.roll += h;
    Attitude ap = out;
    ap.pitch += h;
    Eigen::Matrix<double, 3, 2> J;
    J.col(0) = (level_rotation(ar) * n_sensor - target - r) / h;
    J.col(1) = (level_rotation(ap) * n_sensor - target - r) / h;
    const Eigen::Vector2d step = (J.transpose() * J).ldlt().solve(-J.transpose() * r);
    if (!step.allFinite()) break;
    out.roll += step(0);
    out.pitch += step(1);
    if (step.norm() < 1e-12) break;
  }
  return out;
}

std::optional<Eigen::Vector3d> floor_normal(const ScanHVoxels& scan_sensor, const Params& params) {
  // Samples: centres of the thin HVoxels below the sensor (floor, road, table tops), one per cell.
  const double s = params.map.cell_size;
  const double thin = params.slam.surface_max_height;
  std::vector<Eigen::Vector3d> pts;
  pts.reserve(scan_sensor.cells.size());
  for (const ScanCell& cell : scan_sensor.cells) {
    for (const HVoxel& v : scan_sensor.hvoxels_of(cell)) {
      const double zc = 0.5 * (static_cast<double>(v.z_min) + v.z_max) - scan_sensor.origin_map.z();
      if (v.height() > thin || zc > -0.2) continue;
      pts.emplace_back((cell.key.i + 0.5) * s - scan_sensor.origin_map.x(), (cell.key.j + 0.5) * s - scan_sensor.origin_map.y(), zc);
      break;  // the lowest thin HVoxel of the cell
    }
  }
  const std::size_t min_inliers = static_cast<std::size_t>(params.slam.attitude_min_surfaces);
  if (pts.size() < std::max<std::size_t>(3, min_inliers)) return std::nullopt;
  // RANSAC over planes within max_floor_tilt of horizontal: the one with the most samples within
  // a tolerance of a cell's rise at that tilt plus the sensor's noise.
  const double tolerance = std::max(0.05, 0.5 * s * std::tan(params.slam.max_floor_tilt));
  const double cos_max = std::cos(params.slam.max_floor_tilt);
  Lcg rng{0x9E3779B97F4A7C15ULL};
  std::size_t best = 0;
  Eigen::Vector3d best_n = Eigen::Vector3d::UnitZ();
  double best_d = 0.0;
  constexpr int kSamples = 300;
  // Hypotheses are scored on at most 1500 samples, evenly thinned; the refit uses them all. The
  // scored ones are kept by coordinate, so that the count runs vectorised, block by block.
  const std::size_t score_stride = std::max<std::size_t>(1, pts.size() / 1500);
  std::vector<double> xs;
  std::vector<double> ys;
  std::vector<double> zs;
  for (std::size_t k = 0; k < pts.size(); k += score_stride) {
    xs.push_back(pts[k].x());
    ys.push_back(pts[k].y());
    zs.push_back(pts[k].z());
  }
  const std::size_t scored = xs.size();
  for (int it = 0; it < kSamples; ++it) {
    const Eigen::Vector3d& a = pts[rng.below(pts.size())];
    const Eigen::Vector3d& b = pts[rng.below(pts.size())];
    const Eigen::Vector3d& c = pts[rng.below(pts.size())];
    Eigen::Vector3d n = (b - a).cross(c - a);
    const double len = n.norm();
    if (!(len > 1e-6)) continue;
    n /= len;
    if (n.z() < 0) n = -n;
    if (n.z() < cos_max) continue;
    const double d = n.dot(a);
    // Counted until even the remaining samples could not bring it to the best (a tie still can
    // win, below): the same plane is kept, at about half the scoring on a scan's bad hypotheses.
    // Checked once per block: a count given up a block later is still short of the best.
    constexpr std::size_t kBlock = 64;
    const double nx = n.x();
    const double ny = n.y();
    const double nz = n.z();
    const double* px = xs.data();
    const double* py = ys.data();
    const double* pz = zs.data();
    std::size_t count = 0;
    for (std::size_t k0 = 0; k0 < scored && count + (scored - k0) >= best; k0 += kBlock) {
      const std::size_t k1 = std::min(scored, k0 + kBlock);
      // Counted in a double (exact below 2^53): GCC vectorises the test with SSE2 then, not with an
      // integer count.
      double in_block = 0.0;
      for (std::size_t k = k0; k < k1; ++k) {
        // n.dot(p) as Eigen sums it, x first.
        in_block += std::abs(nx * px[k] + ny * py[k] + nz * pz[k] - d) <= tolerance ? 1.0 : 0.0;
      }
      count += static_cast<std::size_t>(in_block);
    }
    // Ties go to the lower plane: a floor, not a table top above it.
    if (count > best || (count == best && d < best_d)) {
      best = count;
      best_n = n;
      best_d = d;
    }
  }
  if (best * score_stride < min_inliers) return std::nullopt;
  for (const double tol : {tolerance, 0.5 * tolerance, 0.05}) {
    if (refit_plane(pts, tol, best_n, best_d) < min_inliers) return std::nullopt;
  }
  if (best_n.z() < cos_max) return std::nullopt;
  return best_n;
}

AttitudeRefiner::AttitudeRefiner(const Params& params) : params_(params) {}

AttitudeFit AttitudeRefiner::refine(const ScanHVoxels& scan_level, const HMap& map, double x, double y, double yaw,
                                    const Attitude& guess, const std::optional<Eigen::Vector3d>& floor_level,
                                    const std::optional<Eigen::Vector3d>& gravity_level) {
  AttitudeFit fit;
  fit.ran = true;
  fit.attitude = guess;
  const auto& sp = params_.slam;
  if (sp.attitude_iterations <= 0) return fit;
  // One sample per thin scan HVoxel, in the level frame of the guess (origin at the sensor).
  const double s = params_.map.cell_size;
  const auto thin = static_cast<float>(sp.surface_max_height);
  const Eigen::Vector3d o = scan_level.origin_map;
  samples_.clear();
  for (const ScanCell& cell : scan_level.cells) {
    const double cx = (cell.key.i + 0.5) * s - o.x();
    const double cy = (cell.key.j + 0.5) * s - o.y();
    for (const HVoxel& v : scan_level.hvoxels_of(cell)) {
      if (v.height() > thin) continue;
      samples_.push_back({{cx, cy, 0.5 * (static_cast<double>(v.z_min) + v.z_max) - o.z()}, 1.0});
    }
  }
  const auto min_pairs = static_cast<std::size_t>(sp.attitude_min_surfaces);
  if (samples_.size() < min_pairs) return fit;
  // At most kMaxSamples, evenly thinned: 4000 surfaces hold three parameters with room to spare.
  constexpr std::size_t kMaxSamples = 4000;
  if (samples_.size() > kMaxSamples) {
    const double every = static_cast<double>(samples_.size()) / static_cast<double>(kMaxSamples);
    for (std::size_t k = 0; k < kMaxSamples; ++k) samples_[k] = samples_[static_cast<std::size_t>(static_cast<double>(k) * every)];
    samples_.resize(kMaxSamples);
  }

  const double c = std::cos(yaw);
  const double sn = std::sin(yaw);
  // The samples lie within max_range of (x, y) (the correction turns them by a few degrees at
  // most); cells outside the view are looked up in the map all the same.
  const auto half = static_cast<std::int32_t>(std::ceil(params_.map.max_range / s)) + 2;
  view_.reset(map, map.key_of(x, y).value_or(CellKey{}), half);
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();  // the correction, applied in the level frame
  double dz = 0.0;
  const double lever_sq = sp.attitude_min_lever * sp.attitude_min_lever;
  const double huber = std::max(0.03, 0.25 * s);
  for (int it = 0; it < sp.attitude_iterations; ++it) {
    // The pairing gate shrinks from attitude_gate to a third of it over the first iterations.
    const double gate = sp.attitude_gate * std::max(1.0 / 3.0, std::pow(0.6, it));
    Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
    Eigen::Vector3d g = Eigen::Vector3d::Zero();
    double r2 = 0.0;
    double agreement = 0.0;
    std::size_t pairs = 0;
    // The pairings, the map lookups, on the cores; then summed in the samples' order, so that the
    // sums do not depend on the threads.
    pairings_.resize(samples_.size());
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, samples_.size(), 512), [&](const auto& range) {
      for (std::size_t k = range.begin(); k != range.end(); ++k) {
        Pairing& pr = pairings_[k];
        pr.q = R * samples_[k].p;
        const Eigen::Vector3d& q = pr.q;
        const double mz = o.z() + q.z() + dz;
        const std::optional<CellKey> key = map.key_of(x + c * q.x() - sn * q.y(), y + sn * q.x() + c * q.y());
        const std::span<const HVoxel> col = key ? view_.column(*key) : std::span<const HVoxel>{};
        double best = gate;
        double surface = 0.0;
        pr.found = false;
        for (const HVoxel& v : col) {
          if (v.height() > thin) continue;
          const double mid = 0.5 * (static_cast<double>(v.z_min) + v.z_max);
          const double e = std::abs(mz - mid);
          if (e < best) {
            best = e;
            surface = mid;
            pr.found = true;
          }
        }
        pr.r = mz - surface;
      }
    });
    for (const Pairing& pr : pairings_) {
      if (!pr.found) continue;
      const Eigen::Vector3d& q = pr.q;
      const double r = pr.r;
      const double w = std::abs(r) <= huber ? 1.0 : huber / std::abs(r);
      // d(mz) / d(dz, wx, wy) for a rotation δw applied on the left: δz = wx·q_y − wy·q_x.
      const Eigen::Vector3d J(1.0, q.y(), -q.x());
      H.noalias() += w * J * J.transpose();
      g.noalias() += w * J * r;
      r2 += r * r;
      agreement += std::max(0.0, 1.0 - (r / gate) * (r / gate));
      ++pairs;
    }
    fit.iterations = it + 1;
    fit.surfaces = pairs;
    fit.rms = pairs > 0 ? std::sqrt(r2 / static_cast<double>(pairs)) : 0.0;
    fit.agreement = agreement;
    if (pairs < min_pairs) {
      fit.observable = {false, false, false};
      break;
    }
    fit.information = H.diagonal() / static_cast<double>(pairs);
    fit.observable = {true, fit.information(1) >= lever_sq, fit.information(2) >= lever_sq};
    // A direction n that should be vertical after the correction: v = R·n, residuals v_x, v_y; for
    // a rotation δw on the left, δv = δw × v, so ∂v_x/∂w_y = v_z and ∂v_y/∂w_x = −v_z.
    const auto pull_vertical = [&](const Eigen::Vector3d& n, double lambda) {
      const Eigen::Vector3d v = R * n;
      H(2, 2) += lambda * v.z() * v.z();
      g(2) += lambda * v.z() * v.x();
      H(1, 1) += lambda * v.z() * v.z();
      g(1) += lambda * (-v.z()) * v.y();
    };
    // A floor that the estimate tilts by more than slam.level_max_slope is a slope (a ramp), not a
    // level floor: it is not levelled.
    if (floor_level && sp.level_prior > 0.0 && (R * *floor_level).z() >= std::cos(sp.level_max_slope)) {
      pull_vertical(*floor_level, sp.level_prior * 0.5 * (H(1, 1) + H(2, 2)));
    }
    if (gravity_level) pull_vertical(*gravity_level, sp.imu_tilt_weight * 0.5 * (H(1, 1) + H(2, 2)));
    // Solve for the observable axes only; the others keep their guess.
    Eigen::Vector3d step = Eigen::Vector3d::Zero();
    std::array<int, 3> idx{};
    int m = 0;
    for (int a = 0; a < 3; ++a) {
      if (fit.observable[static_cast<std::size_t>(a)]) idx[static_cast<std::size_t>(m++)] = a;
    }
    Eigen::MatrixXd Hs(m, m);
    Eigen::VectorXd gs(m);
    for (int i = 0; i < m; ++i) {
      gs(i) = g(idx[static_cast<std::size_t>(i)]);
      for (int j = 0; j < m; ++j) Hs(i, j) = H(idx[static_cast<std::size_t>(i)], idx[static_cast<std::size_t>(j)]);
    }
    const Eigen::VectorXd xs = Hs.ldlt().solve(-gs);
    if (!xs.allFinite()) break;
    for (int i = 0; i < m; ++i) step(idx[static_cast<std::size_t>(i)]) = xs(i);
    // A step is at most a tenth of a radian and the gate in height: the linearisation holds.
    step(0) = std::clamp(step(0), -gate, gate);
    step(1) = std::clamp(step(1), -0.1, 0.1);
    step(2) = std::clamp(step(2), -0.1, 0.1);
    dz += step(0);
    const Eigen::Vector3d w(step(1), step(2), 0.0);
    if (w.norm() > 0.0) R = Eigen::AngleAxisd(w.norm(), w.normalized()).toRotationMatrix() * R;
    if (std::abs(step(0)) < 1e-4 && w.norm() < 1e-5 && gate <= sp.attitude_gate / 3.0 + 1e-12) break;
  }
  // The corrected sensor rotation in the map: Rz(yaw)·R·Rlevel(guess) = Rz(yaw + ψ)·Ry(pitch')·Rx(roll').
  const Eigen::Matrix3d full = R * level_rotation(guess);
  decompose(full, fit.attitude.roll, fit.attitude.pitch, fit.yaw_change);
  fit.attitude.z = guess.z + dz;
  return fit;
}

}  // namespace hmap::slam
