#include "hmap/maps/scan_hvoxels.hpp"

#include <Eigen/Eigenvalues>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>

#include "hmap/core/checked.hpp"
#include "hmap/core/error.hpp"

namespace hmap {

namespace {
constexpr std::ptrdiff_t kRankSortMax = 8;

/// Cells at or beyond this many in magnitude are never in a scan's window: build() keeps the
/// window's centre within 10^9 cells and the constructor its half width within 2^20 + 1.
constexpr double kFarCells = 1073741824.0;  // 2^30

/// floor(v) for |v| < kFarCells: the truncation corrected by one below zero is the floor exactly
/// (-0.0 and integers included), and costs less than std::floor without SSE4.1 (index_points'
/// per-point hot spot).
inline std::int64_t floor_near(double v) {
  const auto t = static_cast<std::int32_t>(v);
  return t - (v < static_cast<double>(t) ? 1 : 0);
}
}  // namespace

ScanHVoxelizer::ScanHVoxelizer(const MapParams& params) : params_(params) {
  // The ring gap matters only where it passes the threshold within the window (the window's cells
  // lie within max_range + a cell's diagonal of the sensor): for an HDL-64's 0.4 deg rings it
  // never does within 25 m, and every cell keeps the threshold, as without a slope.
  const double window_reach = params_.max_range + params_.cell_size * std::numbers::sqrt2;
  ring_gap_ = params_.ring_gap_slope > 0.0 &&
              std::min(params_.ring_gap_slope * window_reach, params_.ring_gap_max) > params_.point_distance_threshold;
  // validate() keeps max_range / cell_size <= 2048.
  window_.half = checked_count<std::int32_t>(params_.max_range / params_.cell_size, 1 << 20, "the scan window") + 1;
  window_.width = 2 * window_.half + 1;
  cell_of_window_.assign(window_.cells(), 0);
  for (std::size_t n = 0; n < thin_density_.size(); ++n) {
    thin_density_[n] = hvoxel_density(static_cast<double>(n), params_.min_hvoxel_height, params_);
  }
}

void ScanHVoxelizer::build(std::span<const Point3f> points_sensor, const Pose& T_map_sensor,
                           ScanHVoxels& out) {
  build(points_sensor, T_map_sensor, out, {});
}

void ScanHVoxelizer::build(std::span<const Point3f> points_sensor, const Pose& T_map_sensor, ScanHVoxels& out,
                           const std::function<void(const ScanHVoxels&)>& alongside) {
  // Before anything changes: a non-finite pose would make every cell key undefined.
  if (!T_map_sensor.matrix().allFinite()) throw Error("scan pose is not finite");
  index_points(points_sensor, T_map_sensor, out);
  cluster_heights(out);
  out.centroids.clear();
  out.wall_lean = WallLean{};
  if (keep_centroids_ && alongside) {
    // The sums are one pass over the points, on one core: the caller's work fills the other.
    tbb::parallel_invoke([&] { sum_centroids(out); }, [&] { alongside(out); });
  } else {
    if (keep_centroids_) sum_centroids(out);
    if (alongside) alongside(out);
  }
}

void ScanHVoxelizer::index_points(std::span<const Point3f> points_sensor, const Pose& T_map_sensor,
                                  ScanHVoxels& out) {
  for (std::size_t w : used_windows_) cell_of_window_[w] = 0;
  used_windows_.clear();
  out.cells.clear();
  out.hvoxels.clear();
  out.points_in = points_sensor.size();
  out.points_kept = out.dropped_non_finite = out.dropped_range = 0;

  const double cell = params_.cell_size;
  const Eigen::Vector3d origin = T_map_sensor.translation();
  out.origin_map = origin;
  // build() has refused a non-finite pose; negated so that a NaN-free but huge one fails too.
  if (!(std::abs(origin.x() / cell) <= 1e9) || !(std::abs(origin.y() / cell) <= 1e9)) {
    throw Error("scan pose is too far from the map origin (beyond 10^9 cells)");
  }
  window_.center = {checked_floor<std::int32_t>(origin.x() / cell, "the scan origin's cell"),
                    checked_floor<std::int32_t>(origin.y() / cell, "the scan origin's cell")};
  out.window = window_;
  const Eigen::Matrix3d R = T_map_sensor.linear();
  const auto min_r2 = static_cast<float>(params_.min_range * params_.min_range);
  const auto max_r2 = static_cast<float>(params_.max_range * params_.max_range);

  // Convert and bin in parallel: each point gets its window cell (or a drop code) and its height.
  constexpr std::uint32_t kNonFinite = 0xFFFFFFFF;
  constexpr std::uint32_t kOutOfRange = 0xFFFFFFFE;
  const std::size_t n = points_sensor.size();
  point_window_.resize(n);
  point_z_.resize(n);
  const bool keep_xy = keep_centroids_;
  if (keep_xy) point_xy_.resize(n);
  Eigen::Vector2f* const xy_of_point = keep_xy ? point_xy_.data() : nullptr;
  // Everything the loop reads besides the point is held in locals of the task: through the
  // captured references the compiler reloaded the rotation, the origin and the window on every
  // point (it cannot tell that the stores to point_window_ and point_z_ leave them alone).
  const Point3f* const points = points_sensor.data();
  std::uint32_t* const window_of_point = point_window_.data();
  float* const z_of_point = point_z_.data();
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 8192), [=, window = window_](const auto& range) {
    const double r00 = R(0, 0), r01 = R(0, 1), r02 = R(0, 2);
    const double r10 = R(1, 0), r11 = R(1, 1), r12 = R(1, 2);
    const double r20 = R(2, 0), r21 = R(2, 1), r22 = R(2, 2);
    const double ox = origin.x(), oy = origin.y(), oz = origin.z();
    const std::int64_t ci = window.center.i;
    const std::int64_t cj = window.center.j;
    const std::int64_t half = window.half;
    const std::int64_t width = window.width;
    const double cell_size = cell;
    const float r2_min = min_r2;
    const float r2_max = max_r2;
    for (std::size_t k = range.begin(); k != range.end(); ++k) {
      const Point3f& p_sensor = points[k];
      if (!p_sensor.allFinite()) {
        window_of_point[k] = kNonFinite;
        continue;
      }
      const float r2 = p_sensor.squaredNorm();
      if (r2 < r2_min || r2 > r2_max) {
        window_of_point[k] = kOutOfRange;
        continue;
      }
      // 2D indexing in the gravity-aligned map frame (convertToMapIndex, withinMapBounds).
      // p_map = R · p_sensor + origin, summed in the order Eigen's product used (x, y: the
      // columns left to right; z: the first term plus the other two), so that every bit is as before.
      const double px = p_sensor.x();
      const double py = p_sensor.y();
      const double pz = p_sensor.z();
      const double x_map = ((r00 * px + r01 * py) + r02 * pz) + ox;
      const double y_map = ((r10 * px + r11 * py) + r12 * pz) + oy;
      const double u = x_map / cell_size;
      const double w = y_map / cell_size;
      // Outside the window only through float rounding at the range limit, or a pose whose
      // linear part is not a rotation (far out or NaN: the window is within kFarCells).
      if (!(std::abs(u) < kFarCells) || !(std::abs(w) < kFarCells)) {
        window_of_point[k] = kOutOfRange;
        continue;
      }
      const std::int64_t i = floor_near(u);
      const std::int64_t j = floor_near(w);
      if (std::abs(i - ci) > half || std::abs(j - cj) > half) {
        window_of_point[k] = kOutOfRange;
        continue;
      }
      // window.index({i, j}), from the locals.
      window_of_point[k] = static_cast<std::uint32_t>((i - ci + half) * width + (j - cj + half));
      z_of_point[k] = static_cast<float>((r20 * px + (r21 * py + r22 * pz)) + oz);
      if (xy_of_point != nullptr) {
        xy_of_point[k] = Eigen::Vector2f(static_cast<float>(x_map - ox), static_cast<float>(y_map - oy));
      }
    }
  });
  // Number the cells in order of first appearance (serial: it builds the cell list).
  point_cell_.resize(n);
  // The arrays and counters in locals, as above: the stores through point_cell_ and
  // cell_of_window_ made the compiler reload the members on every point.
  const std::uint32_t* const window_in = point_window_.data();
  std::uint32_t* const slot_of_window = cell_of_window_.data();
  std::uint32_t* const cell_out = point_cell_.data();
  std::size_t kept = 0;
  std::size_t non_finite = 0;
  std::size_t out_of_range = 0;
  // The points per cell, counted here for cluster_heights' counting sort: cell_offset_[c + 1]
  // for cell c (a pass over the points fewer; the pointer is taken again when a cell is added).
  cell_offset_.assign(1, 0);
  std::uint32_t* count_of_slot = cell_offset_.data();
  for (std::size_t k = 0; k < n; ++k) {
    const std::uint32_t w = window_in[k];
    if (w >= kOutOfRange) {
      ++(w == kNonFinite ? non_finite : out_of_range);
      continue;
    }
    std::uint32_t& slot = slot_of_window[w];
    if (slot == 0) {
      out.cells.push_back({window_.key_of(w), 0, 0});
      slot = static_cast<std::uint32_t>(out.cells.size());
      used_windows_.push_back(w);
      cell_offset_.push_back(0);
      count_of_slot = cell_offset_.data();
    }
    ++count_of_slot[slot];
    cell_out[kept] = slot - 1;
    z_of_point[kept] = z_of_point[k];
    if (keep_xy) xy_of_point[kept] = xy_of_point[k];
    ++kept;
  }
  out.dropped_non_finite = non_finite;
  out.dropped_range = out_of_range;
  point_cell_.resize(kept);
  point_z_.resize(kept);
  if (keep_xy) point_xy_.resize(kept);
  out.points_kept = kept;
}

float ScanHVoxelizer::cell_gap(const ScanHVoxels& out, std::size_t c) const {
  if (!ring_gap_) return static_cast<float>(params_.point_distance_threshold);
  // Two neighbouring rings of a spinning LiDAR hit a wall at a distance d about slope · d apart in
  // height: the gap that keeps the wall one HVoxel, taken at the cell's far corner (its centre's
  // distance plus half its diagonal), never under the threshold, and at most map.ring_gap_max.
  const double cell = params_.cell_size;
  const CellKey& key = out.cells[c].key;
  const double dx = (key.i + 0.5) * cell - out.origin_map.x();
  const double dy = (key.j + 0.5) * cell - out.origin_map.y();
  const double far = std::sqrt(dx * dx + dy * dy) + cell * std::numbers::sqrt2 / 2.0;
  return static_cast<float>(
      std::max(params_.point_distance_threshold, std::min(params_.ring_gap_slope * far, params_.ring_gap_max)));
}

void ScanHVoxelizer::cluster_heights(ScanHVoxels& out) {
  // Counting sort of the kept heights by cell: each cell's heights become one contiguous slice.
  // index_points counted the points per cell into cell_offset_[c + 1].
  const std::size_t n_cells = out.cells.size();
  for (std::size_t c = 0; c < n_cells; ++c) cell_offset_[c + 1] += cell_offset_[c];
  sorted_z_.resize(point_z_.size());
  // cell_offset_[c] is used as the write cursor of cell c, then restored.
  for (std::size_t k = 0; k < point_z_.size(); ++k) sorted_z_[cell_offset_[point_cell_[k]]++] = point_z_[k];
  for (std::size_t c = n_cells; c > 0; --c) cell_offset_[c] = cell_offset_[c - 1];
  cell_offset_[0] = 0;

  // HeightClustering, cells in parallel: sort each slice and count its clusters, then place the
  // HVoxels of every cell at its offset. The gap is map.point_distance_threshold, or with
  // map.ring_gap_slope it grows with the cell's distance from the sensor (cell_gap).
  cluster_count_.resize(n_cells + 1);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n_cells, 1024), [&](const auto& range) {
    for (std::size_t c = range.begin(); c != range.end(); ++c) {
      const float gap = cell_gap(out, c);
      float* z = sorted_z_.data() + cell_offset_[c];
      float* z_end = sorted_z_.data() + cell_offset_[c + 1];
      const std::ptrdiff_t n = z_end - z;
      if (float* lo = std::min_element(z, z_end), *hi = std::max_element(z, z_end); *hi - *lo <= gap) {
        // All heights within the point-distance threshold of each other: one cluster, whatever
        // their order (no sorted difference can exceed the span: rounding is monotonic). Only its
        // ends are placed; the heights between stay unsorted, and their differences, none above
        // the span, split nothing below. Most cells of ground and of short objects are such; a
        // pass for the ends costs less than the rank sort even for a few heights. (Two passes:
        // std::minmax_element's one was slower, 2.33 -> 2.55 ms for BM_HVoxelizeHdl64.)
        std::iter_swap(z, lo);
        if (hi == z) hi = lo;  // the maximum was at the front: swapped to lo's place
        std::iter_swap(z_end - 1, hi);
      } else if (n <= kRankSortMax) {
        // Small cells: each height goes to its rank (the heights below it, ties by position).
        // Branch-free, where insertion sort mispredicts once per inversion.
        std::array<float, kRankSortMax> sorted{};
        for (std::ptrdiff_t i = 0; i < n; ++i) {
          std::ptrdiff_t rank = 0;
          for (std::ptrdiff_t j = 0; j < n; ++j) rank += (z[j] < z[i]) | ((z[j] == z[i]) & (j < i));
          sorted[static_cast<std::size_t>(rank)] = z[i];
        }
        std::copy_n(sorted.begin(), n, z);
      } else {
        // A spinning sensor lists a cell's points ring by ring, often from the top ring down: the
        // heights come nearly in descending order, insertion sort's worst case. Reversed first,
        // they come nearly ascending, its best.
        // Insertion sort costs one move per inversion, and ring order leaves few: it beats
        // std::sort even for hundreds of points, until the moves pass a budget of 8 per point.
        if (z_end - z > 2 && *z > *(z_end - 1)) std::reverse(z, z_end);
        const auto budget = static_cast<std::ptrdiff_t>(8 * (z_end - z));
        std::ptrdiff_t moves = 0;
        for (float* a = z + 1; a < z_end; ++a) {
          const float value = *a;
          float* b = a;
          for (; b > z && *(b - 1) > value; --b) *b = *(b - 1);
          *b = value;
          moves += a - b;
          if (moves > budget) {
            std::sort(z, z_end);
            break;
          }
        }
      }
      std::uint32_t clusters = 1;  // a new segment starts where the gap exceeds the threshold
      for (const float* it = z + 1; it < z_end; ++it) clusters += *it - *(it - 1) > gap ? 1U : 0U;
      cluster_count_[c + 1] = clusters;
    }
  });
  cluster_count_[0] = 0;
  for (std::size_t c = 0; c < n_cells; ++c) cluster_count_[c + 1] += cluster_count_[c];
  out.hvoxels.resize(cluster_count_[n_cells]);
  const double min_height = params_.min_hvoxel_height;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n_cells, 1024), [&](const auto& range) {
    for (std::size_t c = range.begin(); c != range.end(); ++c) {
      const float gap = cell_gap(out, c);
      const float* z = sorted_z_.data() + cell_offset_[c];
      const float* z_end = sorted_z_.data() + cell_offset_[c + 1];
      ScanCell& cell = out.cells[c];
      cell.first = cluster_count_[c];
      cell.count = cluster_count_[c + 1] - cluster_count_[c];
      HVoxel* v_out = out.hvoxels.data() + cell.first;
      const float* segment = z;
      for (const float* it = z + 1; it <= z_end; ++it) {
        if (it == z_end || *it - *(it - 1) > gap) {
          const std::ptrdiff_t points = it - segment;
          HVoxel v{*segment, *(it - 1), static_cast<float>(points), 0.0F};
          // eq. (1); at or under min_hvoxel_height its value depends on the count alone: from the table.
          if (static_cast<double>(v.height()) <= min_height && points < std::ssize(thin_density_)) {
            v.density = thin_density_[static_cast<std::size_t>(points)];
          } else {
            update_density(v, params_);
          }
          *v_out++ = v;
          segment = it;
        }
      }
    }
  });
}

Eigen::Vector2d WallLean::lean() const {
  // Least squares along the directions the walls hold; zero along one they hold a thousand
  // times less (walls facing one way tell a lean along them only by their ends, and that reading
  // was 0.08 for a true 0.006 on one wall 10 m long).
  Eigen::Vector2d out = Eigen::Vector2d::Zero();
  if (walls == 0) return out;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(information);
  const double largest = eig.eigenvalues()(1);
  for (int k = 0; k < 2; ++k) {
    const double l = eig.eigenvalues()(k);
    if (!(l > 1e-3 * largest)) continue;
    const Eigen::Vector2d v = eig.eigenvectors().col(k);
    out += v * (v.dot(weighted) / l);
  }
  return out;
}

double WallLean::weakest() const {
  return walls == 0 ? 0.0 : Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(information, Eigen::EigenvaluesOnly).eigenvalues()(0);
}

void ScanHVoxelizer::sum_wall_lean(ScanHVoxels& out) {
  // From the moments sum_centroids summed per HVoxel (plan from the origin, z as binned): per wall
  // its lean L = cov(xy, z) / S along its normal n (the plan scatter's least direction), weighed
  // by S/σ².
  const std::size_t n = out.hvoxels.size();
  WallLean& w = out.wall_lean;
  w = WallLean{};
  const double min_spread2 = std::pow(WallLean::kMinSpread * params_.cell_size, 2);  // per point [m²]
  for (std::size_t h = 0; h < n; ++h) {
    const HVoxel& v = out.hvoxels[h];
    const double count = centroid_sums_[h].z();
    if (v.height() < WallLean::kMinHeight || count < static_cast<double>(WallLean::kMinPoints)) continue;
    const std::array<double, 9>& m = moments_[h];
    const Eigen::Vector2d mean(m[0] / count, m[1] / count);
    const double z_mean = m[2] / count;
    Eigen::Matrix2d C;  // Σ (p − p̄)(p − p̄)ᵀ in plan
    C(0, 0) = m[3] - count * mean.x() * mean.x();
    C(0, 1) = C(1, 0) = m[4] - count * mean.x() * mean.y();
    C(1, 1) = m[5] - count * mean.y() * mean.y();
    const Eigen::Vector2d c_xz(m[6] - count * mean.x() * z_mean, m[7] - count * mean.y() * z_mean);
    const double S = m[8] - count * z_mean * z_mean;
    if (!(S > 0.0)) continue;
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(C);
    if (!(eig.eigenvalues()(1) >= 4.0 * eig.eigenvalues()(0))) continue;  // no one direction: not a wall
    // At any one height (the lean taken out) the points must spread along the wall over most of
    // the cell. A LiDAR's column of beams at one azimuth is a line whose plan position changes
    // with height only where its wall leans in this frame, and along the ray: taken for a wall
    // whose normal is across the ray, it read no lean where there was one (on the simulated
    // town an OS0-64's columns made the walls read a third of a 1.1 deg tilt).
    const Eigen::Matrix2d C_level = C - c_xz * c_xz.transpose() / S;
    const double spread = Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(C_level, Eigen::EigenvaluesOnly).eigenvalues()(1);
    if (!(spread >= count * min_spread2)) continue;
    const Eigen::Vector2d normal = eig.eigenvectors().col(0);
    const double lean = normal.dot(c_xz / S);
    if (!(std::abs(lean) <= WallLean::kMaxLean)) continue;  // a slope, a windscreen: not a wall
    // The scatter across the wall about the fitted lean, per point (two parameters fitted), no
    // less than a wall's flatness: a wall that a cell's edge cuts keeps only its points on one
    // side, so it scatters less and leans less than it does. Weighed by the scatter alone, those
    // walls read 55-70 % of the tilt on the simulated town (85-95 % with the floor and the spread).
    const double across = normal.dot(C * normal) - lean * lean * S;
    const double sigma2 = std::max(across / (count - 2.0), WallLean::kFlatness * WallLean::kFlatness);
    const double info = S / sigma2;
    w.information += info * normal * normal.transpose();
    w.weighted += info * normal * lean;
    ++w.walls;
  }
}

void ScanHVoxelizer::sum_centroids(ScanHVoxels& out) {
  // Each kept point is in exactly one HVoxel of its cell: the cluster whose bounds hold its height
  // (the bounds are the extreme heights themselves, the same floats). The sums are relative to the
  // origin, in double, so that a cell far out keeps its sub-millimetre centroid.
  // With keep_wall_lean_, the same pass sums each HVoxel's moments for the walls' lean, in the
  // cells whose HVoxels span a wall's height.
  const std::size_t n = out.hvoxels.size();
  std::vector<Eigen::Vector3d>& sums = centroid_sums_;
  sums.assign(n, Eigen::Vector3d::Zero());
  if (keep_wall_lean_) moments_.assign(n, std::array<double, 9>{});
  for (std::size_t k = 0; k < point_cell_.size(); ++k) {
    const ScanCell& cell = out.cells[point_cell_[k]];
    const float z = point_z_[k];
    std::uint32_t h = cell.first;
    const std::uint32_t last = cell.first + cell.count - 1;
    while (h < last && z > out.hvoxels[h].z_max) ++h;
    sums[h] += Eigen::Vector3d(point_xy_[k].x(), point_xy_[k].y(), 1.0);
    if (keep_wall_lean_ && !(out.hvoxels[last].z_max - out.hvoxels[cell.first].z_min < WallLean::kMinHeight)) {
      const double x = point_xy_[k].x();
      const double y = point_xy_[k].y();
      const double zd = z;
      std::array<double, 9>& m = moments_[h];
      m[0] += x;
      m[1] += y;
      m[2] += zd;
      m[3] += x * x;
      m[4] += x * y;
      m[5] += y * y;
      m[6] += x * zd;
      m[7] += y * zd;
      m[8] += zd * zd;
    }
  }
  if (keep_wall_lean_) sum_wall_lean(out);
  out.centroids.resize(n);
  const Eigen::Vector2d origin = out.origin_map.head<2>();
  for (std::size_t h = 0; h < n; ++h) {
    const Eigen::Vector3d& m = sums[h];
    const Eigen::Vector2d mean = m.z() > 0.0 ? Eigen::Vector2d(origin + m.head<2>() / m.z()) : origin;
    out.centroids[h] = mean.cast<float>();
  }
}

}  // namespace hmap
