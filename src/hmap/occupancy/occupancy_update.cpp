#include "hmap/occupancy/occupancy_update.hpp"

#include <algorithm>
#include <cmath>

#include <limits>

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include "hmap/core/checked.hpp"
#include "hmap/maps/ray_trace.hpp"

namespace hmap {

HVoxelRole hvoxel_role(const HVoxel& v, double ground_z, const OccupancyParams& p) {
  if (v.z_min - ground_z > p.z_plus || v.z_max - ground_z < p.z_minus) return HVoxelRole::kIgnored;
  if (std::abs(v.z_max - ground_z) > p.ground_distance) return HVoxelRole::kObstacle;
  return HVoxelRole::kGround;
}

double inverse_sensor_model(HVoxelRole role, double density, double delta, const OccupancyParams& p) {
  switch (role) {
    case HVoxelRole::kObstacle:
      return std::max(density, 0.5) * std::exp(-(delta * delta) / (2.0 * p.sigma * p.sigma));
    case HVoxelRole::kGround:
      return p.ground_gain + (0.5 - p.ground_gain) / (1.0 + std::exp(-delta / p.ground_distance));
    case HVoxelRole::kIgnored:
      break;
  }
  return 0.5;
}

namespace {
constexpr int kBlockBits = 2;  // ground lookup blocks of 4x4 cells
constexpr double kCutoffEpsilon = 1e-4;
constexpr double kMaxBucketRim = 32.0;  // rings of buckets; patches larger than that: the kd-tree

/// Distance before the target beyond which a term of eq. (4) is within ε of the floor K_g:
/// obstacle: max(ρ, 0.5)·exp(−δ²/2σ²) <= ε ⇐ |δ| >= σ·sqrt(2 ln(1/ε));
/// ground: (0.5 − K_g) / (1 + exp(|δ|/d_pth)) <= ε ⇐ |δ| >= d_pth·ln((0.5 − K_g)/ε).
double obstacle_cutoff(const OccupancyParams& p) { return p.sigma * std::sqrt(2.0 * std::log(1.0 / kCutoffEpsilon)); }
double ground_cutoff(const OccupancyParams& p) {
  return p.ground_distance * std::log(std::max(0.5 - p.ground_gain, kCutoffEpsilon) / kCutoffEpsilon);
}

}  // namespace

std::pair<double, double> below_along(double h_start, double h_end, double limit) {
  constexpr double kNone = std::numeric_limits<double>::infinity();
  const bool start_low = h_start <= limit;
  const bool end_low = h_end <= limit;
  if (start_low && end_low) return {0.0, 1.0};
  if (!start_low && !end_low) return {kNone, -kNone};
  const double t = (limit - h_start) / (h_end - h_start);  // h_start != h_end here
  return end_low ? std::pair{t, 1.0} : std::pair{0.0, t};
}

namespace {
/// Two rays' p for one cell of one scan, as one: a hit outranks a pass (the larger, when either is
/// at least 0.5: an obstacle's own cell, however thin its density); between passes the clearer
/// wins (the smaller). Commutative and associative: over a set, its largest p when that is at
/// least 0.5, else its smallest.
float combine_in_scan(float a, float b) { return a >= 0.5F || b >= 0.5F ? std::max(a, b) : std::min(a, b); }

struct RayBuffer {
  std::vector<float> p;                 // per window cell: max p of this scan, < 0 untouched
  std::vector<std::uint32_t> touched;   // window cells with p >= 0
  std::vector<std::pair<HVoxelRole, double>> judged;  // (role, density) of the current scan cell
  std::size_t rays = 0;
};
}  // namespace

struct OccupancyUpdater::Buffers : tbb::enumerable_thread_specific<RayBuffer> {};

OccupancyUpdater::OccupancyUpdater(const Params& params)
    : params_(params), cutoff_(0.0), obstacle_cutoff_(0.0), buffers_(std::make_unique<Buffers>()) {
  validate(params_);
  obstacle_cutoff_ = obstacle_cutoff(params_.occupancy);
  cutoff_ = std::max(obstacle_cutoff_, ground_cutoff(params_.occupancy));
}

OccupancyUpdater::~OccupancyUpdater() = default;
OccupancyUpdater::OccupancyUpdater(OccupancyUpdater&&) noexcept = default;
OccupancyUpdater& OccupancyUpdater::operator=(OccupancyUpdater&&) noexcept = default;

void OccupancyUpdater::index_patches(const ScanWindow& window, const GroundModel& ground) {
  const std::vector<GroundPatch>& patches = ground.patches();
  const double cell = params_.map.cell_size;
  const double bucket = cell * (1 << kBlockBits);
  // The rim: a patch more than rim buckets from a block's centre is beyond ground_reach of every
  // cell of the block (Chebyshev distance from a cell >= Euclidean from the centre / √2 − 1.5 cells).
  // The largest half size is the model's, kept as patches are added: a pass over every patch here
  // made each scan's cost grow with the map (issue 19, the 10 km drive).
  const double max_half = ground.max_half_size();
  const double rim = std::ceil(std::sqrt(2.0) * (params_.occupancy.ground_reach + max_half + 1.5 * cell) / bucket);
  const std::optional<std::int32_t> rim_buckets = floor_to<std::int32_t>(rim);  // NaN and 1e300 patches: nothing
  bucket_rim_ = rim_buckets && *rim_buckets <= kMaxBucketRim ? *rim_buckets : -1;  // huge patches: the kd-tree
  bucket_rows_ = 0;
  bucket_cols_ = 0;
  if (bucket_rim_ < 0) return;
  // Bucket (a, b) is block (a, b) of the window, extended beyond it; the patches within rim buckets
  // of the blocks are the only candidates.
  const double x0 = static_cast<double>(window.center.i - window.half) * cell;
  const double y0 = static_cast<double>(window.center.j - window.half) * cell;
  const double lo = -bucket_rim_;
  const double hi = static_cast<double>((window.width >> kBlockBits) + 1 + bucket_rim_);
  std::int32_t a_min = std::numeric_limits<std::int32_t>::max(), a_max = std::numeric_limits<std::int32_t>::min();
  std::int32_t b_min = a_min, b_max = a_max;
  // The candidates come from the model's k-d tree: every centre in the buckets [lo, hi)² lies within
  // the square's half diagonal (and a bucket to spare) of its centre. In index order, as a pass over
  // all patches found them.
  const double mid = 0.5 * (lo + hi) * bucket;
  const double radius = (0.5 * (hi - lo) * std::sqrt(2.0) + 1.0) * bucket;
  std::vector<int> near = ground.within(x0 + mid, y0 + mid, radius);
  std::sort(near.begin(), near.end());
  patch_bucket_.clear();
  for (const int k : near) {
    const GroundPatch& patch = patches[static_cast<std::size_t>(k)];
    const std::optional<std::int32_t> fa = floor_to<std::int32_t>((patch.center.x() - x0) / bucket);
    const std::optional<std::int32_t> fb = floor_to<std::int32_t>((patch.center.y() - y0) / bucket);
    if (!fa || !fb || !(*fa >= lo && *fb >= lo && *fa < hi && *fb < hi)) continue;  // NaN and far ones too
    patch_bucket_.push_back({k, *fa, *fb});
    a_min = std::min(a_min, *fa);
    a_max = std::max(a_max, *fa);
    b_min = std::min(b_min, *fb);
    b_max = std::max(b_max, *fb);
  }
  if (a_min > a_max) return;  // no patch near the window
  // The grid: the patches' bounding box and rim buckets around it. A block outside is farther than
  // rim buckets from every candidate.
  bucket_a0_ = a_min - bucket_rim_;
  bucket_b0_ = b_min - bucket_rim_;
  bucket_rows_ = a_max - a_min + 1 + 2 * bucket_rim_;
  bucket_cols_ = b_max - b_min + 1 + 2 * bucket_rim_;
  const auto rows = static_cast<std::size_t>(bucket_rows_);
  const auto cols = static_cast<std::size_t>(bucket_cols_);
  const std::size_t n_buckets = rows * cols;
  const auto bucket_index = [&](const PatchBucket& pb) {
    return static_cast<std::size_t>(pb.a - bucket_a0_) * cols + static_cast<std::size_t>(pb.b - bucket_b0_);
  };
  // Counting sort of the candidates by bucket, in index order within a bucket.
  bucket_begin_.assign(n_buckets + 1, 0);
  for (const PatchBucket& pb : patch_bucket_) ++bucket_begin_[bucket_index(pb) + 1];
  for (std::size_t b = 0; b < n_buckets; ++b) bucket_begin_[b + 1] += bucket_begin_[b];
  bucket_patches_.resize(bucket_begin_[n_buckets]);
  bucket_fill_.assign(bucket_begin_.begin(), bucket_begin_.end() - 1);
  for (const PatchBucket& pb : patch_bucket_) bucket_patches_[bucket_fill_[bucket_index(pb)]++] = pb.patch;
  // Per bucket, the Chebyshev distance (in buckets, at most rim + 1) to the nearest bucket holding a
  // patch, in two passes: the search skips the empty rings, and a block far from every patch costs
  // one read.
  const auto cap = static_cast<std::uint16_t>(bucket_rim_ + 1);
  empty_rings_.resize(n_buckets);
  for (std::size_t b = 0; b < n_buckets; ++b) empty_rings_[b] = bucket_begin_[b + 1] > bucket_begin_[b] ? 0 : cap;
  const auto relax = [&](std::size_t b, std::size_t from) {
    empty_rings_[b] = std::min<std::uint16_t>(empty_rings_[b], static_cast<std::uint16_t>(empty_rings_[from] + 1));
  };
  for (std::size_t i = 0; i < rows; ++i) {
    for (std::size_t j = 0; j < cols; ++j) {
      const std::size_t b = i * cols + j;
      if (j > 0) relax(b, b - 1);
      if (i > 0) {
        relax(b, b - cols);
        if (j > 0) relax(b, b - cols - 1);
        if (j + 1 < cols) relax(b, b - cols + 1);
      }
    }
  }
  for (std::size_t i = rows; i-- > 0;) {
    for (std::size_t j = cols; j-- > 0;) {
      const std::size_t b = i * cols + j;
      if (j + 1 < cols) relax(b, b + 1);
      if (i + 1 < rows) {
        relax(b, b + cols);
        if (j + 1 < cols) relax(b, b + cols + 1);
        if (j > 0) relax(b, b + cols - 1);
      }
    }
  }
}

std::int32_t OccupancyUpdater::nearest_patch(std::int32_t bi, std::int32_t bj, double x, double y,
                                             const std::vector<GroundPatch>& patches) const {
  // (x, y) is the centre of bucket (bi, bj). Every patch in ring r + 1 or beyond lies at least
  // (r + 0.5) buckets away, every patch off the grid more than rim buckets away: the search stops
  // as soon as the best is that near. Within rim buckets it is exact; beyond, no cell of the block
  // is within ground_reach of any patch (index_patches), so none is as good.
  const std::int32_t ci = bi - bucket_a0_;
  const std::int32_t cj = bj - bucket_b0_;
  if (ci < 0 || cj < 0 || ci >= bucket_rows_ || cj >= bucket_cols_) return -1;
  const auto cols = static_cast<std::size_t>(bucket_cols_);
  const std::int32_t first_ring = empty_rings_[static_cast<std::size_t>(ci) * cols + static_cast<std::size_t>(cj)];
  if (first_ring > bucket_rim_) return -1;
  const double bucket = params_.map.cell_size * (1 << kBlockBits);
  std::int32_t best = -1;
  double best_d2 = std::numeric_limits<double>::infinity();
  const auto visit = [&](std::int32_t i, std::int32_t j) {
    if (i < 0 || j < 0 || i >= bucket_rows_ || j >= bucket_cols_) return;
    const std::size_t b = static_cast<std::size_t>(i) * cols + static_cast<std::size_t>(j);
    for (std::uint32_t k = bucket_begin_[b]; k < bucket_begin_[b + 1]; ++k) {
      const std::int32_t p = bucket_patches_[k];
      const double dx = patches[static_cast<std::size_t>(p)].center.x() - x;
      const double dy = patches[static_cast<std::size_t>(p)].center.y() - y;
      const double d2 = dx * dx + dy * dy;
      if (d2 < best_d2 || (d2 == best_d2 && p < best)) {
        best_d2 = d2;
        best = p;
      }
    }
  };
  for (std::int32_t r = first_ring; r <= bucket_rim_; ++r) {
    for (std::int32_t di = -r; di <= r; ++di) {
      if (di == -r || di == r) {
        for (std::int32_t dj = -r; dj <= r; ++dj) visit(ci + di, cj + dj);
      } else {
        visit(ci + di, cj - r);
        visit(ci + di, cj + r);
      }
    }
    const double reach = (r + 0.5) * bucket;
    if (best_d2 <= reach * reach) return best;
  }
  const double exact = bucket_rim_ * bucket;
  return best_d2 <= exact * exact ? best : -1;
}

void OccupancyUpdater::find_ground(const ScanHVoxels& scan, const ScanWindow& window, const GroundModel& ground,
                                   OccupancyUpdateStats& stats) {
  const OccupancyParams& op = params_.occupancy;
  const double cell = params_.map.cell_size;
  if (window_width_ != window.width) {
    window_width_ = window.width;
    const std::size_t blocks_per_side = (static_cast<std::size_t>(window.width) >> kBlockBits) + 1;
    block_patch_.assign(blocks_per_side * blocks_per_side, -1);
    block_stamp_.assign(blocks_per_side * blocks_per_side, 0);
    stamp_ = 0;
  }
  if (++stamp_ == 0) {  // wrapped: forget every cached block
    std::fill(block_stamp_.begin(), block_stamp_.end(), 0U);
    stamp_ = 1;
  }
  const std::size_t blocks_per_side = (static_cast<std::size_t>(window.width) >> kBlockBits) + 1;
  const auto& patches = ground.patches();
  index_patches(window, ground);
  ground_z_.resize(scan.cells.size());
  for (std::size_t c = 0; c < scan.cells.size(); ++c) {
    const CellKey& key = scan.cells[c].key;
    const double xt = (key.i + 0.5) * cell;
    const double yt = (key.j + 0.5) * cell;
    ground_z_[c] = std::numeric_limits<double>::quiet_NaN();
    // The local ground: the patch nearest to the centre of the cell's block.
    const auto bi = static_cast<std::size_t>(key.i - window.center.i + window.half) >> kBlockBits;
    const auto bj = static_cast<std::size_t>(key.j - window.center.j + window.half) >> kBlockBits;
    const std::size_t b = bi * blocks_per_side + bj;
    if (block_stamp_[b] != stamp_) {
      block_stamp_[b] = stamp_;
      const double half_block = 0.5 * cell * (1 << kBlockBits);
      const double xb = (static_cast<double>(bi << kBlockBits) - window.half + window.center.i) * cell + half_block;
      const double yb = (static_cast<double>(bj << kBlockBits) - window.half + window.center.j) * cell + half_block;
      block_patch_[b] = bucket_rim_ >= 0
                            ? nearest_patch(static_cast<std::int32_t>(bi), static_cast<std::int32_t>(bj), xb, yb, patches)
                            : ground.nearest_index(xb, yb);
    }
    const std::int32_t patch_index = block_patch_[b];
    if (patch_index < 0) {
      ++stats.no_ground;
      continue;
    }
    const GroundPatch& patch = patches[static_cast<std::size_t>(patch_index)];
    // Distance from the patch's square, not its centre: a large patch covers its whole extent.
    if ((patch.center.head<2>() - Eigen::Vector2d(xt, yt)).cwiseAbs().maxCoeff() - patch.half_size > op.ground_reach) {
      ++stats.no_ground;
      continue;
    }
    ground_z_[c] = patch.height_at(xt, yt);
  }
}

OccupancyUpdateStats OccupancyUpdater::update(const ScanHVoxels& scan, const GroundModel& ground,
                                              OccupancyGrid& grid) {
  const OccupancyParams& op = params_.occupancy;
  const double cell = params_.map.cell_size;
  const double xs = scan.origin_map.x();
  const double ys = scan.origin_map.y();
  OccupancyUpdateStats stats;
  if (scan.cells.empty()) return stats;
  // The square around the sensor's cell holding every scan cell: each ray lies inside it. Taken
  // from the cells rather than scan.window, so hand-made scans work too.
  ScanWindow window;
  window.center = {checked_floor<std::int32_t>(xs / cell, "the scan origin's cell"),
                   checked_floor<std::int32_t>(ys / cell, "the scan origin's cell")};
  for (const ScanCell& c : scan.cells) {
    window.half = std::max({window.half, std::abs(c.key.i - window.center.i), std::abs(c.key.j - window.center.j)});
  }
  window.width = 2 * window.half + 1;

  find_ground(scan, window, ground, stats);

  // The sensor's height above its own ground (no patch under it: each ray takes its target's).
  double sensor_ground = std::numeric_limits<double>::quiet_NaN();
  if (const GroundPatch* under = ground.nearest(xs, ys);
      under != nullptr &&
      (under->center.head<2>() - Eigen::Vector2d(xs, ys)).cwiseAbs().maxCoeff() - under->half_size <= op.ground_reach) {
    sensor_ground = under->height_at(xs, ys);
  }
  const double zs = scan.origin_map.z();

  // The rays, in parallel: each thread keeps the max p per cell in its own dense buffer.
  const auto floor_p = static_cast<float>(op.ground_gain);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, scan.cells.size(), 256), [&](const auto& range) {
    RayBuffer& buffer = buffers_->local();
    if (buffer.p.size() < window.cells()) buffer.p.resize(window.cells(), -1.0F);
    for (std::size_t c = range.begin(); c != range.end(); ++c) {
      if (std::isnan(ground_z_[c])) continue;
      const ScanCell& target = scan.cells[c];
      buffer.judged.clear();
      double z_low = std::numeric_limits<double>::infinity();
      bool any_ground = false;
      for (const HVoxel& v : scan.hvoxels_of(target)) {
        const HVoxelRole role = hvoxel_role(v, ground_z_[c], op);
        if (role == HVoxelRole::kIgnored) continue;
        buffer.judged.emplace_back(role, v.density);
        z_low = std::min(z_low, static_cast<double>(v.z_min));
        any_ground = any_ground || role == HVoxelRole::kGround;
      }
      if (buffer.judged.empty()) continue;  // only ceilings, crowns or pits here: no evidence
      ++buffer.rays;
      const double xt = (target.key.i + 0.5) * cell;
      const double yt = (target.key.j + 0.5) * cell;
      const double length = std::sqrt((xt - xs) * (xt - xs) + (yt - ys) * (yt - ys));
      // The obstacle term fades within a few σ, the ground term within a few d_pth: a ray to
      // obstacles alone evaluates eq. (4) over a much shorter stretch.
      const double cutoff = any_ground ? cutoff_ : obstacle_cutoff_;
      const double t_cutoff = length > 0.0 ? 1.0 - cutoff / length : 0.0;
      // Where the lowest ray to this cell (to its lowest judged HVoxel) runs at most
      // free_ray_height above the ground, with the ground taken linear from under the sensor to
      // here: only there is a pass evidence that nothing blocking stands in the cell. Higher, an
      // obstacle could stand under the ray (a parked car under the ray to a facade).
      const double g_target = ground_z_[c];
      const double h_start = zs - (std::isnan(sensor_ground) ? g_target : sensor_ground);
      const double h_end = z_low - g_target;
      // Named doubles, not a structured binding: clang 14 cannot capture those in the lambda below.
      const std::pair<double, double> free_span = below_along(h_start, h_end, op.free_ray_height);
      const double t_free_lo = free_span.first;
      const double t_free_hi = free_span.second;
      // Nothing before min(t_free_lo, t_cutoff) is touched: the walk starts at the first cell
      // leaving after it, exactly the cells (and t values) the whole walk has from there on.
      const double t_start = std::min(t_free_lo, t_cutoff);
      traverse_2d_from(xs, ys, xt, yt, cell, t_start, [&](const CellKey& key, double t_in, double t_out) {
        const bool low = t_out >= t_free_lo && t_in <= t_free_hi;
        float p = floor_p;
        if (t_out >= t_cutoff) {
          // |c| − |v|: from the middle of the ray's stretch in this cell to the HVoxel's cell centre.
          const double delta = key == target.key ? 0.0 : (0.5 * (t_in + t_out) - 1.0) * length;
          double q_max = 0.0;
          for (const auto& [role, density] : buffer.judged) {
            q_max = std::max(q_max, inverse_sensor_model(role, density, delta, op));
          }
          if (!low && q_max <= 0.5 && !(key == target.key)) return true;  // a high pass: no evidence
          p = static_cast<float>(std::clamp(q_max, op.ground_gain, op.clamp_max));
        } else if (!low) {
          return true;
        }
        const std::size_t index = window.index(key);
        float& slot = buffer.p[index];
        if (slot < 0.0F) {
          buffer.touched.push_back(static_cast<std::uint32_t>(index));
          slot = p;
        } else {
          slot = combine_in_scan(slot, p);
        }
        return true;
      });
    }
  });

  // eq. (3) once per cell with the largest p any thread saw; the buffers are left untouched (< 0).
  // Most cells take the floor K_g: its log-odds are computed once.
  const float floor_log_odds = log_odds(floor_p);
  for (RayBuffer& buffer : *buffers_) {
    stats.rays += buffer.rays;
    buffer.rays = 0;
    for (const std::uint32_t index : buffer.touched) {
      float p = buffer.p[index];
      if (p < 0.0F) continue;  // merged already from an earlier buffer
      for (RayBuffer& other : *buffers_) {
        if (other.p.size() > index) {
          if (other.p[index] >= 0.0F) p = combine_in_scan(p, other.p[index]);
          other.p[index] = -1.0F;
        }
      }
      grid.update(window.key_of(index), p == floor_p ? floor_log_odds : log_odds(p));
      ++stats.cells;
    }
    buffer.touched.clear();
  }
  return stats;
}

OccupancyUpdateStats update_occupancy(const ScanHVoxels& scan, const GroundModel& ground, const Params& params,
                                      OccupancyGrid& grid) {
  return OccupancyUpdater(params).update(scan, ground, grid);
}

}  // namespace hmap

namespace hmap {

OccupancyGrid occupancy_from_map(const HMap& map, const GroundModel& ground, const Params& params,
                                 double max_ground_distance) {
  const OccupancyParams& op = params.occupancy;
  OccupancyGrid grid(map.cell_size(), op.clamp_min, op.clamp_max);
  map.for_each_column([&](const CellKey& key, const ColumnView& column) {
    const Eigen::Vector2d xy = map.cell_center(key);
    const GroundPatch* patch = ground.nearest(xy.x(), xy.y());
    if (patch == nullptr) return;
    const double distance = (patch->center.head<2>() - xy).norm();
    const double g = patch->height_at(xy.x(), xy.y());
    if (distance > max_ground_distance) {
      // Beyond the ground's reach: a column whose lowest HVoxel starts on the patch's plane stands
      // on that ground, and is blocked by any obstacle HVoxel over it; never free (the ground
      // around it was not seen), and nothing said of a column that does not reach the plane.
      if (distance > op.obstacle_reach || column.size() == 0) return;
      if (std::abs(static_cast<double>(column.data()[0].z_min) - g) > params.ground.elevation_threshold) return;
      for (const HVoxel& v : column) {
        if (hvoxel_role(v, g, op) == HVoxelRole::kObstacle) {
          grid.update(key, grid.clamp_max_log_odds());
          break;
        }
      }
      return;
    }
    bool obstacle = false;
    bool drivable = false;
    for (const HVoxel& v : column) {
      const HVoxelRole role = hvoxel_role(v, g, op);
      obstacle = obstacle || role == HVoxelRole::kObstacle;
      drivable = drivable || role == HVoxelRole::kGround;
    }
    if (obstacle) {
      grid.update(key, grid.clamp_max_log_odds());
    } else if (drivable) {
      grid.update(key, grid.clamp_min_log_odds());
    }
  });
  return grid;
}

}  // namespace hmap
