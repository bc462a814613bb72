#include "hmap/slam/scan_matcher.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <type_traits>

#include "hmap/core/checked.hpp"

namespace hmap::slam {

namespace {

/// Steps longer than this many cells are shortened: the metric is only informative within a
/// couple of cells of the surfaces, and a long step from a flat Hessian jumps out of the basin.
constexpr double kMaxStepCells = 4.0;
/// The coarse search scores the pose with at most this many HVoxels.
constexpr std::size_t kCoarseHVoxels = 200;
/// The coarse search takes at most this many steps each way in x and y (validate() keeps
/// slam.coarse_translation within 100 cells, 50 steps of two cells); in yaw, ScanMatcher's
/// kCoarseMaxYawSteps.
constexpr int kCoarseMaxSteps = 50;
/// The degeneracy check evaluates the cost with at most this many HVoxels.
constexpr std::size_t kCurvatureHVoxels = 500;
/// Least s² of MotionPrior: a run of near-perfect matches must not make the odometry weightless.
constexpr double kMinPriorWeight = 0.01;

/// A scan HVoxel's position v moved by ξ (eq. 6: S(ξ) = R(φ) v + p), in cell units from the cell
/// centres, which sit at (i + 0.5)·s: (i0, j0) = `base` is the centre below and left of it and
/// (a, b) = (u − fu, w − fw) its place in that square.
struct Projection {
  float u;
  float w;
  float fu;
  float fw;
  CellKey base;
};
[[nodiscard]] inline Projection project(const Eigen::Vector2f& v, float sin_yaw, float cos_yaw, const PlanarPose& pose,
                                        float cell) {
  const float qx = cos_yaw * v.x() - sin_yaw * v.y() + static_cast<float>(pose.x);
  const float qy = sin_yaw * v.x() + cos_yaw * v.y() + static_cast<float>(pose.y);
  Projection p{qx / cell - 0.5F, qy / cell - 0.5F, 0.0F, 0.0F, {}};
  p.fu = std::floor(p.u);
  p.fw = std::floor(p.w);
  p.base = {static_cast<std::int32_t>(p.fu), static_cast<std::int32_t>(p.fw)};
  return p;
}

/// With the map's centroids: the projection moved back by the offset of the cell it lands in, so
/// that the bilinear field, whose values stand at the cells' centres, is read as if they stood at
/// the centroids. Its derivative is left out (the offset is constant within a cell). The offset is
/// looked up only when the cell differs from the one `at` caches (a lookup per HVoxel and
/// iteration cost the SLAM several % of its time). A const candidate's cache is only read
/// (cost_only, whose threads share the candidates).
template <class Candidate>
inline void shift_by_map_centroid(Projection& p, const CellCentroids* centroids, const CellCentroids::View& view, float cell,
                                  Candidate& cand) {
  if (centroids == nullptr) return;
  const CellKey at{static_cast<std::int32_t>(std::floor(p.u + 0.5F)), static_cast<std::int32_t>(std::floor(p.w + 0.5F))};
  Eigen::Vector2f offset = cand.offset;
  if (!(at == cand.at)) {
    const Eigen::Vector2f* found = view.source() == centroids ? view.offset(at) : centroids->offset(at);
    offset = found == nullptr ? Eigen::Vector2f::Zero() : *found;
    if constexpr (!std::is_const_v<Candidate>) {
      cand.at = at;
      cand.offset = offset;
    }
  }
  p.u -= offset.x() / cell;
  p.w -= offset.y() / cell;
  p.fu = std::floor(p.u);
  p.fw = std::floor(p.w);
  p.base = {static_cast<std::int32_t>(p.fu), static_cast<std::int32_t>(p.fw)};
}

}  // namespace

ScanMatcher::ScanMatcher(const Params& params) : params_(params), interpolator_((validate(params), params)) {}

void ScanMatcher::select(const ScanHVoxels& scan_level, float min_match, bool at_centres) {
  // "Height-Voxel Selection": only HVoxels whose density reaches n_th take part.
  candidates_.clear();
  const double s = params_.map.cell_size;
  const auto n_th = static_cast<float>(params_.map.density_threshold);
  const auto min_height = static_cast<float>(params_.slam.min_layer_height);
  std::size_t eligible = 0;
  for (const ScanCell& cell : scan_level.cells) {
    for (const HVoxel& v : scan_level.hvoxels_of(cell)) eligible += v.density >= n_th && v.height() >= min_match ? 1 : 0;
  }
  const auto cap = static_cast<std::size_t>(std::max(0, params_.slam.max_hvoxels));
  // Evenly thinned to the cap: keep candidate k when its running index crosses a multiple of n/cap.
  const double keep_every = cap > 0 && eligible > cap ? static_cast<double>(eligible) / static_cast<double>(cap) : 1.0;
  double next = 0.0;
  std::size_t index = 0;
  double radius_sq = 0.0;
  // v_x, v_y of eq. (6): the HVoxel's points' plan centroid when the scan has them (a surface lies
  // anywhere in its cell; at the cell's centre every HVoxel is up to half a cell off, and the match
  // is pulled toward poses where the scan's grid and the map's coincide), else the cell's centre.
  const bool centroids = !at_centres && scan_level.centroids.size() == scan_level.hvoxels.size();
  for (const ScanCell& cell : scan_level.cells) {
    const Eigen::Vector2f centre{static_cast<float>((cell.key.i + 0.5) * s), static_cast<float>((cell.key.j + 0.5) * s)};
    for (std::uint32_t k = cell.first; k < cell.first + cell.count; ++k) {
      const HVoxel& h = scan_level.hvoxels[k];
      if (h.density < n_th || h.height() < min_match) continue;
      if (static_cast<double>(index++) < next) continue;
      next += keep_every;
      Candidate c;
      c.v = centroids ? scan_level.centroids[k] : centre;
      c.layer = widened(h.interval(), min_height);
      candidates_.push_back(c);
      radius_sq += static_cast<double>(c.v.squaredNorm());
    }
  }
  rms_radius_ = candidates_.empty() ? 1.0 : std::max(s, std::sqrt(radius_sq / static_cast<double>(candidates_.size())));
}

void ScanMatcher::keep_inside_map(const HMap& map, const PlanarPose& guess) {
  const double s = params_.map.cell_size;
  const double c = std::cos(guess.yaw);
  const double sn = std::sin(guess.yaw);
  std::size_t kept = 0;
  double radius_sq = 0.0;
  for (const Candidate& cand : candidates_) {
    const double x = guess.x + c * cand.v.x() - sn * cand.v.y();
    const double y = guess.y + sn * cand.v.x() + c * cand.v.y();
    bool inside = true;
    for (int di = -1; di <= 1 && inside; ++di) {
      for (int dj = -1; dj <= 1 && inside; ++dj) inside = map.column(x + di * s, y + dj * s).size() > 0;
    }
    if (!inside) continue;
    candidates_[kept++] = cand;
    radius_sq += static_cast<double>(cand.v.squaredNorm());
  }
  candidates_.resize(kept);
  rms_radius_ = kept == 0 ? 1.0 : std::max(s, std::sqrt(radius_sq / static_cast<double>(kept)));
}

ScanMatcher::Linearization ScanMatcher::linearize(const PlanarPose& pose, std::size_t stride) {
  Linearization lin;
  const auto s = static_cast<float>(params_.map.cell_size);
  const auto c = static_cast<float>(std::sin(pose.yaw));
  const auto co = static_cast<float>(std::cos(pose.yaw));
  const auto robust = static_cast<float>(params_.slam.robust_scale);
  // The HVoxels are summed in fixed chunks of 1024, then the chunk sums in order (the order the
  // chunks were once summed in parallel in: the same sums bit for bit).
  struct Sums {
    double h00 = 0, h01 = 0, h02 = 0, h11 = 0, h12 = 0, h22 = 0, g0 = 0, g1 = 0, g2 = 0, cost = 0, score = 0;
  };
  constexpr std::size_t kChunk = 1024;
  const std::size_t visited = (candidates_.size() + stride - 1) / stride;
  const std::size_t chunks = (visited + kChunk - 1) / kChunk;
  // First M_H and its gradient per HVoxel, in small blocks on the cores: reading the map (the F
  // values of a candidate whose cells changed) is most of the work, and the sums' chunks of 1024
  // left one core idle for a scan of 1300 HVoxels. Each sample depends on its candidate alone.
  samples_.resize(visited);
  const auto evaluate = [&](std::size_t from, std::size_t to) {
    for (std::size_t n = from; n < to; ++n) {
      Candidate& cand = candidates_[n * stride];
      Projection projected = project(cand.v, c, co, pose, s);
      shift_by_map_centroid(projected, read_centroids_, centroid_view_, s, cand);
      const auto [u, w, fu, fw, base] = projected;
      if (!(base == cand.base)) {
        // The four F values depend only on the layer and the cells: cached until q leaves them.
        cand.F = interpolator_.corner_values(view_, cand.layer, base);
        cand.base = base;
      }
      samples_[n] = bilinear(cand.F, u - fu, w - fw, s);
    }
  };
  constexpr std::size_t kEvaluateBlock = 128;
  if (visited > kEvaluateBlock) {
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, visited, kEvaluateBlock),
                      [&](const auto& range) { evaluate(range.begin(), range.end()); });
  } else {
    evaluate(0, visited);
  }
  std::vector<Sums> chunk_sums(chunks);
  const auto sum_chunk = [&](std::size_t chunk) {
  Sums& sums = chunk_sums[chunk];
  auto& [h00, h01, h02, h11, h12, h22, g0, g1, g2, cost, score] = sums;
  const std::size_t end = std::min(visited, (chunk + 1) * kChunk);
  for (std::size_t n = chunk * kChunk; n < end; ++n) {
    const Candidate& cand = candidates_[n * stride];
    const MetricSample& m = samples_[n];
    const float r = 1.0F - m.value;
    // ∂S/∂φ = (−sin φ v_x − cos φ v_y, cos φ v_x − sin φ v_y).
    const float dx_dyaw = -c * cand.v.x() - co * cand.v.y();
    const float dy_dyaw = co * cand.v.x() - c * cand.v.y();
    const double j0 = m.gradient.x();
    const double j1 = m.gradient.y();
    const double j2 = m.gradient.x() * dx_dyaw + m.gradient.y() * dy_dyaw;
    double wgt = 1.0;
    if (robust > 0.0F) {
      // Cauchy: w = 1 / (1 + (r/c)²), loss c²·ln(1 + (r/c)²).
      const double t = static_cast<double>(r / robust);
      wgt = 1.0 / (1.0 + t * t);
      cost += static_cast<double>(robust * robust) * std::log1p(t * t);
    } else {
      cost += static_cast<double>(r) * r;
    }
    h00 += wgt * j0 * j0;
    h01 += wgt * j0 * j1;
    h02 += wgt * j0 * j2;
    h11 += wgt * j1 * j1;
    h12 += wgt * j1 * j2;
    h22 += wgt * j2 * j2;
    g0 += wgt * r * j0;
    g1 += wgt * r * j1;
    g2 += wgt * r * j2;
    score += m.value;
  }
  };
  // The map was read above: the sums are a few multiplications per HVoxel, one core's work.
  for (std::size_t chunk = 0; chunk < chunks; ++chunk) sum_chunk(chunk);
  Sums t;
  for (const Sums& part : chunk_sums) {
    t.h00 += part.h00; t.h01 += part.h01; t.h02 += part.h02; t.h11 += part.h11; t.h12 += part.h12; t.h22 += part.h22;
    t.g0 += part.g0; t.g1 += part.g1; t.g2 += part.g2; t.cost += part.cost; t.score += part.score;
  }
  lin.H << t.h00, t.h01, t.h02, t.h01, t.h11, t.h12, t.h02, t.h12, t.h22;  // eq. (8)
  lin.g << t.g0, t.g1, t.g2;                                             // the sum of eq. (7)
  lin.cost = t.cost;
  lin.score = t.score;
  return lin;
}

namespace {
Eigen::Vector3d prior_delta(const PlanarPose& pose, const MotionPrior& prior) {
  return {pose.x - prior.mean.x, pose.y - prior.mean.y, std::remainder(pose.yaw - prior.mean.yaw, 2.0 * std::numbers::pi)};
}
}  // namespace

double ScanMatcher::prior_cost_at(const PlanarPose& pose) const {
  if (!prior_) return 0.0;
  const Eigen::Vector3d delta = prior_delta(pose, *prior_);
  return prior_weight_ * delta.dot(prior_->information * delta);
}

void ScanMatcher::add_prior(const PlanarPose& pose, Linearization& lin) const {
  if (!prior_) return;
  // The prior's residuals weighted by s²: Hessian s²·Λ, and the gradient side of eq. (7) −s²·Λ·Δ
  // (g collects r·∂M/∂ξ, M = 1 − r).
  const Eigen::Vector3d delta = prior_delta(pose, *prior_);
  lin.H += prior_weight_ * prior_->information;
  lin.g -= prior_weight_ * (prior_->information * delta);
  lin.cost += prior_cost_at(pose);
}

Eigen::Vector3d ScanMatcher::solve(const Linearization& lin, bool& degenerate, Eigen::Vector3d& eigenvalues) const {
  // eq. (7), Δξ = H⁻¹ g, solved in the eigenbasis of H with yaw scaled to metres at the RMS radius:
  // directions whose eigenvalue is under degeneracy_ratio · λ_max are not moved (the guess, from
  // odometry or constant velocity, is kept along them).
  const Eigen::Vector3d d(1.0, 1.0, 1.0 / rms_radius_);
  const Eigen::Matrix3d Hs = d.asDiagonal() * lin.H * d.asDiagonal();
  const Eigen::Vector3d gs = d.asDiagonal() * lin.g;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(Hs);
  eigenvalues = eig.eigenvalues();
  const double lmax = eigenvalues(2);
  degenerate = !(lmax > 0.0) || eigenvalues(0) < params_.slam.degeneracy_ratio * lmax;
  Eigen::Vector3d step = Eigen::Vector3d::Zero();
  if (!(lmax > 0.0)) return step;
  if (yaw_only_) {
    // A thin fallback's match (ThinFallback::kHeading): eq. (7) along the yaw alone, in the same
    // scaled units as below (the yaw in metres at the RMS radius).
    const double b = 1.0 / rms_radius_;
    const double l = b * lin.H(2, 2) * b;
    if (l > 0.0) step(2) = b * ((b * lin.g(2)) / l);
  } else {
    Eigen::Vector3d step_s = Eigen::Vector3d::Zero();
    for (int k = 0; k < 3; ++k) {
      const double l = eigenvalues(k);
      if (l < params_.slam.degeneracy_ratio * lmax || l <= 0.0) continue;
      const Eigen::Vector3d u = eig.eigenvectors().col(k);
      step_s += (u.dot(gs) / l) * u;
    }
    step = d.asDiagonal() * step_s;
  }
  const double max_step = kMaxStepCells * params_.map.cell_size;
  const double t = std::hypot(step(0), step(1));
  const double r = std::abs(step(2)) * rms_radius_;
  const double longest = std::max(t, r);
  if (longest > max_step) step *= max_step / longest;
  return step;
}

void ScanMatcher::assess_degeneracy(MatchResult& result) {
  // The Gauss-Newton Hessian Σ JᵀJ also grows with gradients that cancel between HVoxels (the ring
  // pattern on a corridor's walls changes with x, but not on average): it is the curvature of
  // the cost itself, one cell either side along each eigenvector, that tells a corridor.
  const double h = params_.map.cell_size;
  const Eigen::Vector3d d(1.0, 1.0, 1.0 / rms_radius_);
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(d.asDiagonal() * result.hessian * d.asDiagonal());
  const std::size_t stride = curvature_stride();
  std::size_t used = 0;
  for (std::size_t k = 0; k < candidates_.size(); k += stride) ++used;
  // The cost at the pose and one step either way along each eigenvector.
  const PlanarPose& p = result.pose;
  std::array<PlanarPose, 7> probes;
  probes[0] = p;
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector3d step = d.asDiagonal() * (h * eig.eigenvectors().col(k));
    probes[static_cast<std::size_t>(1 + 2 * k)] = {p.x + step(0), p.y + step(1), p.yaw + step(2)};
    probes[static_cast<std::size_t>(2 + 2 * k)] = {p.x - step(0), p.y - step(1), p.yaw - step(2)};
  }
  std::array<double, 7> f{};
  probe_costs(probes, f);
  for (int k = 0; k < 3; ++k) {
    const double fp = f[static_cast<std::size_t>(1 + 2 * k)];
    const double fm = f[static_cast<std::size_t>(2 + 2 * k)];
    result.curvature(k) = (fp + fm - 2.0 * f[0]) / (h * h) / static_cast<double>(used);
  }
  const double cmax = result.curvature.maxCoeff();
  result.degenerate = !(cmax > 0.0) || result.curvature.minCoeff() < params_.slam.degeneracy_ratio * cmax;
  result.directions = eig.eigenvectors();
  result.observable = {true, true, true};
  for (int k = 0; k < 3; ++k) {
    if (cmax > 0.0 && result.curvature(k) >= params_.slam.degeneracy_ratio * cmax) continue;
    // A weak direction: the axes it mostly points along (|component| above 1/√3) are not observable.
    for (int a = 0; a < 3; ++a) {
      if (std::abs(result.directions(a, k)) > 0.577) result.observable[static_cast<std::size_t>(a)] = false;
    }
  }
}

std::size_t ScanMatcher::curvature_stride() const {
  return std::max<std::size_t>(1, candidates_.size() / kCurvatureHVoxels);
}

void ScanMatcher::probe_costs(std::span<const PlanarPose> poses, std::span<double> costs) const {
  // Independent sums over the same thinned HVoxels, on the cores. cost_only leaves the cached F
  // values alone, so the sums do not race, and each is the same single-chunk sum linearize would make.
  const std::size_t stride = curvature_stride();
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, poses.size(), 1), [&](const auto& range) {
    for (std::size_t i = range.begin(); i != range.end(); ++i) costs[i] = cost_only(poses[i], stride);
  });
}

bool ScanMatcher::supports_move(const MatchResult& from, MatchResult& to) {
  assess_degeneracy(to);
  // The move in (m, m, rad·RMS radius), the space assess_degeneracy measures curvature in.
  const Eigen::Vector3d move(to.pose.x - from.pose.x, to.pose.y - from.pose.y,
                             std::remainder(to.pose.yaw - from.pose.yaw, 2.0 * std::numbers::pi) * rms_radius_);
  const double length = move.norm();
  // Within a cell both are the same minimum at the grain of the map: the lower cost stands.
  if (!(length >= params_.map.cell_size)) return true;
  // What the cost rises by when the pose moves as far along the scan's best-constrained direction
  // at `to`, against what the move gained: along a direction the scan hardly constrains, a gain
  // of a few percent is the grain of eq. (5), not evidence.
  Eigen::Index strongest = 0;
  to.curvature.maxCoeff(&strongest);
  const Eigen::Vector3d e = length * to.directions.col(strongest);
  const PlanarPose& p = to.pose;
  const std::array<PlanarPose, 4> probes{p, from.pose, PlanarPose{p.x + e(0), p.y + e(1), p.yaw + e(2) / rms_radius_},
                                         PlanarPose{p.x - e(0), p.y - e(1), p.yaw - e(2) / rms_radius_}};
  std::array<double, 4> f{};
  probe_costs(probes, f);
  const double gain = f[1] - f[0];
  const double rise = 0.5 * (f[2] + f[3]) - f[0];
  return gain >= params_.slam.degeneracy_ratio * rise;
}

MatchResult ScanMatcher::gauss_newton(const PlanarPose& guess) {
  MatchResult result;
  const auto n = static_cast<double>(candidates_.size());
  PlanarPose pose = guess;
  // `lin` is eq. (5) alone (reported), `total` with the motion prior (what is minimised).
  Linearization lin = linearize(pose, 1);
  Linearization total = lin;
  add_prior(pose, total);
  result.initial_cost = lin.cost / n;
  bool degenerate = false;
  Eigen::Vector3d eigenvalues;
  for (int it = 0; it < params_.slam.max_iterations; ++it) {
    Eigen::Vector3d step = solve(total, degenerate, eigenvalues);
    ++result.iterations;
    // The metric is piecewise bilinear: a full step may overshoot, so halve it until the cost drops.
    bool accepted = false;
    PlanarPose next;
    Linearization next_lin;
    Linearization next_total;
    for (int tries = 0; tries < 4 && step.norm() > 0.0; ++tries, step *= 0.5) {
      next = {pose.x + step(0), pose.y + step(1), pose.yaw + step(2)};
      next_lin = linearize(next, 1);
      next_total = next_lin;
      add_prior(next, next_total);
      if (next_total.cost <= total.cost) {
        accepted = true;
        break;
      }
    }
    if (!accepted) {  // no descent along the Gauss-Newton direction: a minimum of eq. (5)
      result.converged = true;
      break;
    }
    pose = next;
    lin = next_lin;
    total = next_total;
    if (std::hypot(step(0), step(1)) < params_.slam.convergence_translation &&
        std::abs(step(2)) < params_.slam.convergence_rotation) {
      result.converged = true;
      break;
    }
  }
  (void)solve(lin, degenerate, eigenvalues);
  result.pose = pose;
  result.final_cost = lin.cost / n;
  result.prior_cost = (total.cost - lin.cost) / n;
  result.score = lin.score / n;
  result.hvoxels_used = candidates_.size();
  result.hessian = lin.H;
  result.eigenvalues = eigenvalues;
  result.degenerate = degenerate;
  return result;
}

double ScanMatcher::cost_only(const PlanarPose& pose, std::size_t stride) const {
  const auto s = static_cast<float>(params_.map.cell_size);
  const auto c = static_cast<float>(std::sin(pose.yaw));
  const auto co = static_cast<float>(std::cos(pose.yaw));
  const auto robust = static_cast<float>(params_.slam.robust_scale);
  double cost = 0.0;
  for (std::size_t k = 0; k < candidates_.size(); k += stride) {
    const Candidate& cand = candidates_[k];
    Projection projected = project(cand.v, c, co, pose, s);
    shift_by_map_centroid(projected, read_centroids_, centroid_view_, s, cand);
    const auto [u, w, fu, fw, base] = projected;
    const std::array<float, 4> F = base == cand.base ? cand.F : interpolator_.corner_values(view_, cand.layer, base);
    const float r = 1.0F - bilinear(F, u - fu, w - fw, s).value;
    if (robust > 0.0F) {
      const double t = static_cast<double>(r / robust);
      cost += static_cast<double>(robust * robust) * std::log1p(t * t);
    } else {
      cost += static_cast<double>(r) * r;
    }
  }
  return cost;
}

std::vector<PlanarPose> ScanMatcher::coarse_search(const PlanarPose& guess, double translation, double rotation) {
  // An exhaustive grid around the guess, scored on a thinned set of HVoxels. The steps are two
  // cells, in yaw two cells at the RMS radius: about the basin of Gauss-Newton, which refines.
  const std::size_t stride = std::max<std::size_t>(1, candidates_.size() / kCoarseHVoxels);
  const double cell = params_.map.cell_size;
  const double dt = 2.0 * cell;
  const double dr = std::max(2.0 * cell / rms_radius_, rotation / kCoarseMaxYawSteps);
  // Both counts are bounded before the grid is sized (a cast of 1e12 to int was undefined).
  const int nt = checked_count<int>(translation / dt, kCoarseMaxSteps + 1,  // + 1: rounding
                                    "the coarse search in x and y (slam.coarse_translation)");
  const int nr = rotation > 0.0 ? checked_count<int>(rotation / dr, kCoarseMaxYawSteps,
                                                     "the coarse search in yaw (slam.coarse_rotation)")
                                : 0;
  struct Scored {
    double cost;
    PlanarPose pose;
  };
  // The grid is scored in parallel (yaw rows on the cores), then ranked in grid order.
  const int side = 2 * nt + 1;
  const std::size_t per_yaw = static_cast<std::size_t>(side) * static_cast<std::size_t>(side);
  const auto pose_at = [&](std::size_t index) {
    const int a = static_cast<int>(index / per_yaw) - nr;
    const int i = static_cast<int>(index % per_yaw) / side - nt;
    const int j = static_cast<int>(index % per_yaw) % side - nt;
    return PlanarPose{guess.x + i * dt, guess.y + j * dt, guess.yaw + a * dr};
  };
  std::vector<double> costs(static_cast<std::size_t>(2 * nr + 1) * per_yaw);
  // The prior counts as much against the thinned HVoxels as against all of them.
  const double prior_share = static_cast<double>((candidates_.size() + stride - 1) / stride) /
                             static_cast<double>(candidates_.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, costs.size(), per_yaw), [&](const auto& range) {
    for (std::size_t k = range.begin(); k != range.end(); ++k) {
      const PlanarPose pose = pose_at(k);
      costs[k] = cost_only(pose, stride) + prior_share * prior_cost_at(pose);
    }
  });
  std::array<Scored, kCoarseStarts> best;
  best.fill({std::numeric_limits<double>::infinity(), guess});
  for (std::size_t k = 0; k < costs.size(); ++k) {
    if (costs[k] >= best.back().cost) continue;
    best.back() = {costs[k], pose_at(k)};
    std::sort(best.begin(), best.end(), [](const Scored& x, const Scored& y) { return x.cost < y.cost; });
  }
  std::vector<PlanarPose> starts;
  for (const Scored& b : best) {
    if (std::isfinite(b.cost)) starts.push_back(b.pose);
  }
  return starts;
}

MatchResult ScanMatcher::match(const ScanHVoxels& scan_level, const HMap& map, const PlanarPose& guess,
                               CoarseSearch search, const std::optional<PlanarPose>& alternative,
                               ThinFallback thin_fallback, const std::optional<MotionPrior>& prior) {
  prior_.reset();
  yaw_only_ = false;
  read_centroids_ = map_centroids_;
  // slam.hvoxel_centroids 0 is eq. (6) as the paper has it, at the cells' centres, though the scan
  // may carry centroids for another reader (the walls' lean, slam.wall_tilt_drift).
  select(scan_level, static_cast<float>(params_.slam.min_match_height), params_.slam.hvoxel_centroids == 0);
  if (candidates_.size() < kMinHVoxels && thin_fallback != ThinFallback::kNone && params_.slam.min_match_height > 0.0) {
    // At the cells' centres, scan and map alike: the map keeps centroids for the tall HVoxels
    // only, and ground rings at their points' centroids against cells at their centres ran away
    // forward through the parking route's blind stretch without odometry (1.0-1.7 m per scan where
    // the car made 0.2-0.5, the constant velocity feeding it on: 20 m too far on seed 3; at the
    // centres 4.6 m short). docs/SLAM.md, session 30.
    read_centroids_ = nullptr;
    select(scan_level, 0.0F, true);
    // Only where the map is known all around (at the guess): flat ground is the same everywhere, so
    // its HVoxels tell the pose only by the edge of what the map has seen, and that edge pulled the
    // scan back onto it (the parking side road's empty end: 6 m behind, 9° of yaw in the U-turn).
    // Inside, ground rings match anywhere (no gradient: the guess stands) and kerbs and steps match
    // where they are.
    keep_inside_map(map, guess);
    // Bare ground carries the pattern of the rings that laid it into the map, and a scan's rings
    // match the last scan's best where that scan was: translated, the thin HVoxels pull the pose
    // back toward the last one (0.25-0.35 m per scan at the parking side road's empty end, where
    // the car moved 0.14-0.46 m). The rings are circles about the sensor, so a turn about it
    // leaves that pattern nearly where it is: the yaw is told by the kerbs. With odometry's guess
    // (kHeading) only the yaw moves. Without odometry the position must come from somewhere, and
    // constant velocity along the road was worse than this pull (docs/SLAM.md).
    yaw_only_ = thin_fallback == ThinFallback::kHeading;
  }
  if (candidates_.size() < kMinHVoxels) {
    // Too few to hold three degrees of freedom: a kerb or a pedestrian alone snaps the pose by
    // degrees. The guess (odometry or constant velocity) is kept.
    MatchResult none;
    none.pose = guess;
    none.hvoxels_used = candidates_.size();
    none.degenerate = true;
    none.skipped = true;
    return none;
  }
  const auto center = map.key_of(guess.x, guess.y).value_or(CellKey{});
  const double reach = params_.map.max_range + params_.slam.coarse_translation + 2.0 * params_.map.cell_size;
  const auto half = static_cast<std::int32_t>(std::ceil(reach / params_.map.cell_size)) +
                    params_.slam.interpolation_window;
  view_.reset(map, center, half);
  centroid_view_.reset(read_centroids_, center, half);
  if (prior) {
    // s²: eq. (5)'s residual variance per HVoxel, from the recent matches (this one's at the guess
    // for the first), so that the prior weighs against the scan as σ_r² : σ_odometry².
    const double n = static_cast<double>(candidates_.size());
    prior_weight_ = std::max(kMinPriorWeight, reference_cost_ > 0.0 ? reference_cost_ : cost_only(guess, 1) / n);
    prior_ = prior;
  }

  MatchResult result = gauss_newton(guess);
  bool assessed = false;  // result's degeneracy already assessed
  // Failure: Gauss-Newton ran out of iterations, or the match is much worse than the recent ones.
  const double ratio = params_.slam.coarse_trigger_ratio;
  const bool failed = search == CoarseSearch::kAlways || !result.converged ||
                      (reference_score_ > 0.0 && result.score < ratio * reference_score_);
  // A yaw-only match is not searched: the grid would move the pose where the thin HVoxels may not.
  if (failed && ratio > 0.0 && !yaw_only_) {
    const int iterations = result.iterations;
    const double initial_cost = result.initial_cost;
    const MatchResult from_guess = result;
    const auto search_from = [&](double translation, double rotation) {
      std::vector<PlanarPose> starts = coarse_search(guess, translation, rotation);
      if (alternative) {
        for (const PlanarPose& start : coarse_search(*alternative, translation, rotation)) starts.push_back(start);
      }
      for (const PlanarPose& start : starts) {
        MatchResult retry = gauss_newton(start);
        if (retry.final_cost + retry.prior_cost < result.final_cost + result.prior_cost) result = retry;
      }
    };
    search_from(params_.slam.coarse_translation, params_.slam.coarse_rotation);
    // Still lost: the best pose of the search fits the map less than half as well as the recent
    // matches did. The sensor moved farther than the prediction's window (a jerk, a dropped
    // scan: balm_os0 at every third scan turns up to 81 degrees between them), so every heading
    // is searched, within twice the translation.
    const bool lost = lost_search_ && reference_score_ > 0.0 && result.score < kLostScoreRatio * reference_score_;
    if (lost) {
      const MatchResult searched = result;
      // Within the grid's kCoarseMaxSteps of two cells, however wide slam.coarse_translation is.
      const double wide = std::min(2.0 * params_.slam.coarse_translation, kCoarseMaxSteps * 2.0 * params_.map.cell_size);
      search_from(wide, std::numbers::pi);
      // Taken only where it fits as the recent matches did: a lower cost among thousands of poses
      // that still fits badly is the grain of eq. (5) (24 HVoxels after the parking's blind
      // stretch: 1.11 -> 1.78 % RPE on one seed).
      if (!(result.score >= kLostScoreRatio * reference_score_)) result = searched;
    }
    if (search == CoarseSearch::kWhenFailedKeepPrediction) {
      assessed = true;  // supports_move assesses the pick
      if (!supports_move(from_guess, result)) {
        assessed = false;
        const int searched = result.iterations;  // the pick's steps, counted though it is not taken
        result = from_guess;
        result.iterations = searched;
        result.coarse_rejected = true;
      }
    }
    result.iterations = iterations + result.iterations;
    result.initial_cost = initial_cost;
    result.coarse_search = true;
    result.wide_search = lost;
  }
  if (!assessed) assess_degeneracy(result);
  Eigen::Matrix3d scan_information = result.hessian;
  if (yaw_only_) {
    // What the scan told is its information along the basis only; the rest is the guess's.
    scan_information = Eigen::Matrix3d::Zero();
    scan_information(2, 2) = result.hessian(2, 2);
    result.heading_only = true;
    result.degenerate = true;
    result.observable[0] = false;
    result.observable[1] = false;
  }
  if (prior_) {
    const Eigen::Matrix3d information = scan_information / prior_weight_ + prior_->information;
    result.covariance = information.inverse();
  }
  reference_score_ = reference_score_ > 0.0 ? 0.8 * reference_score_ + 0.2 * result.score : result.score;
  reference_cost_ = reference_cost_ > 0.0 ? 0.8 * reference_cost_ + 0.2 * result.final_cost : result.final_cost;
  prior_.reset();
  return result;
}

double ScanMatcher::cost_at(const PlanarPose& pose) {
  if (candidates_.empty()) return 0.0;
  return linearize(pose, 1).cost / static_cast<double>(candidates_.size());
}

}  // namespace hmap::slam
