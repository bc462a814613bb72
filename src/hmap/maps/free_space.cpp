#include "hmap/maps/free_space.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <functional>
#include <limits>

#include <tbb/parallel_invoke.h>

#include "hmap/core/checked.hpp"
#include "hmap/maps/ray_trace.hpp"

namespace hmap {

void FreeCell::add_slow(float lo, float hi, float r, float unite_gap, float join_gap) {
  // Unite with every interval it overlaps or comes within unite_gap of (they are kept farther
  // apart than that, so the union cannot reach one that [lo, hi] did not).
  std::uint32_t hit = n;
  for (std::uint32_t k = 0; k < n; ++k) {
    if (lo <= z_max[k] + unite_gap && hi >= z_min[k] - unite_gap) {
      if (hit == n && lo >= z_min[k] && hi <= z_max[k]) {  // inside one: it overlaps no other
        rays[k] += r;
        return;
      }
      if (hit == n) {
        z_min[k] = std::min(z_min[k], lo);
        z_max[k] = std::max(z_max[k], hi);
        rays[k] += r;
        hit = k;
      } else {  // a second overlapped interval: fold it into the first one, the last into its lane
        z_min[hit] = std::min(z_min[hit], z_min[k]);
        z_max[hit] = std::max(z_max[hit], z_max[k]);
        rays[hit] += rays[k];
        --n;
        z_min[k] = z_min[n];
        z_max[k] = z_max[n];
        rays[k] = rays[n];
        z_min[n] = std::numeric_limits<float>::infinity();
        z_max[n] = -std::numeric_limits<float>::infinity();
        rays[n] = 0.0F;
        --k;
      }
    }
  }
  if (hit != n) return;
  if (n < kMaxIntervals) {
    z_min[n] = lo;
    z_max[n] = hi;
    rays[n] = r;
    ++n;
    return;
  }
  std::uint32_t nearest = 0;
  float best = std::numeric_limits<float>::infinity();
  for (std::uint32_t k = 0; k < n; ++k) {
    const float gap = std::max(z_min[k] - hi, lo - z_max[k]);
    if (gap < best) {
      best = gap;
      nearest = k;
    }
  }
  if (best <= join_gap) {
    z_min[nearest] = std::min(z_min[nearest], lo);
    z_max[nearest] = std::max(z_max[nearest], hi);
    rays[nearest] += r;
  }
}

FreeSpaceTracer::FreeSpaceTracer(const MapParams& params) : params_(params) {
  // validate() keeps max_range / cell_size <= 2048; the same window as ScanHVoxelizer's.
  const auto half = checked_count<std::int32_t>(params_.max_range / params_.cell_size, 1 << 20, "the scan window") + 1;
  for (auto& q : quadrants_) q.slot_of_window.assign(static_cast<std::size_t>(2 * half + 1) * (2 * half + 1), 0);
}

std::size_t FreeSpaceTracer::rays() const {
  std::size_t n = 0;
  for (const auto& q : quadrants_) n += q.rays;
  return n;
}

void FreeSpaceTracer::Accumulator::reset() {
  for (std::size_t w : used_windows) slot_of_window[w] = 0;
  used_windows.clear();
  used_cells = 0;
  rays = 0;
}

FreeCell& FreeSpaceTracer::Accumulator::new_cell(std::size_t w, const CellKey& key) {
  if (used_cells == cells.size()) cells.resize(std::max<std::size_t>(4096, 2 * cells.size()));
  FreeCell& cell = cells[used_cells++];
  cell.key = key;
  cell.clear();
  slot_of_window[w] = static_cast<std::uint32_t>(used_cells);
  used_windows.push_back(w);
  return cell;
}

void FreeSpaceTracer::trace(const ScanHVoxels& scan, const std::function<void()>& alongside) {
  // A ray's cells are monotonic in i and in j, so rays to the quadrant (i >= ci, j >= cj) of the
  // sensor's cell (ci, cj) stay in it, and so on: the quadrants share only the sensor's row and
  // column of cells.
  for (auto& q : quadrants_) q.targets.clear();
  std::array<std::uint64_t, 4> work{};  // HVoxels × cells from the sensor: each quadrant's cost to trace
  const CellKey c = scan.window.center;
  for (std::uint32_t k = 0; k < scan.cells.size(); ++k) {
    const ScanCell& cell = scan.cells[k];
    const std::size_t q = (cell.key.i >= c.i ? 0 : 1) + (cell.key.j >= c.j ? 0 : 2);
    quadrants_[q].targets.push_back(k);
    // A ray visits |di| + |dj| + 1 cells.
    work[q] += std::uint64_t{cell.count} *
              (1 + std::abs(std::int64_t{cell.key.i} - c.i) + std::abs(std::int64_t{cell.key.j} - c.j));
  }
  // Five independent jobs: the map work alongside and the four quadrants, which differ up to
  // threefold in cost (a wall on one side). They are taken in a fixed order from a shared counter
  // by as many workers as there are threads, the work alongside first and then the quadrants
  // longest first (by HVoxels × cells from the sensor), so that on two cores the
  // short ones fill in behind the long ones. The order changes only which thread runs a job: each
  // job's result is the same.
  std::array<std::size_t, 4> order{0, 1, 2, 3};
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return work[a] > work[b]; });
  std::atomic<std::size_t> next_job{0};
  const auto worker = [&] {
    for (std::size_t job = next_job++; job < 5; job = next_job++) {
      if (job == 0) {
        if (alongside) alongside();
      } else {
        quadrants_[order[job - 1]].trace(scan, params_);  // clears what the last trace left in it
      }
    }
  };
  tbb::parallel_invoke(worker, worker, worker, worker, worker);
  // Fold the shared row and column into the first quadrant. Their cells are found through the
  // window, not by reading every free cell (two passes over megabytes), and folded in each
  // quadrant's order of making them, as a pass over its cells would.
  const auto join_gap = static_cast<float>(params_.point_distance_threshold);
  const auto unite_gap = static_cast<float>(params_.free_unite_gap);
  Accumulator& first = quadrants_[0];
  const std::int32_t half = scan.window.half;
  for (std::size_t q = 1; q < quadrants_.size(); ++q) {
    Accumulator& quadrant = quadrants_[q];
    std::vector<std::uint32_t>& shared = quadrant.shared_slots;
    shared.clear();
    const auto take = [&](std::size_t w) {
      if (const std::uint32_t slot = quadrant.slot_of_window[w]; slot != 0) shared.push_back(slot - 1);
    };
    for (std::int32_t d = -half; d <= half; ++d) {
      take(scan.window.index({c.i, c.j + d}));                 // the sensor's row
      if (d != 0) take(scan.window.index({c.i + d, c.j}));     // its column (its cell once)
    }
    std::sort(shared.begin(), shared.end());
    for (const std::uint32_t slot : shared) {
      FreeCell& fc = quadrant.cells[slot];
      FreeCell& into = first.cell_at(scan.window.index(fc.key), fc.key);
      for (std::uint32_t k = 0; k < fc.n; ++k) into.add(fc.z_min[k], fc.z_max[k], fc.rays[k], unite_gap, join_gap);
      fc.n = 0;  // folded
    }
  }
  // Every cell of every quadrant holds at least one interval, but the folded ones.
  cells_.clear();
  for (const FreeCell& fc : first.used()) cells_.push_back(&fc);
  for (std::size_t q = 1; q < quadrants_.size(); ++q) {
    const Accumulator& quadrant = quadrants_[q];
    std::size_t next = 0;  // quadrant.shared_slots is sorted
    for (std::size_t slot = 0; slot < quadrant.used_cells; ++slot) {
      if (next < quadrant.shared_slots.size() && quadrant.shared_slots[next] == slot) {
        ++next;
        continue;
      }
      cells_.push_back(&quadrant.cells[slot]);
    }
  }
}

void FreeSpaceTracer::Accumulator::trace(const ScanHVoxels& scan, const MapParams& params) {
  reset();
  const double cell = params.cell_size;
  const auto n_th = static_cast<float>(params.density_threshold);
  const auto join_gap = static_cast<float>(params.point_distance_threshold);
  const auto unite_gap = static_cast<float>(params.free_unite_gap);
  const double xs = scan.origin_map.x();
  const double ys = scan.origin_map.y();
  const auto zs = static_cast<float>(scan.origin_map.z());

  for (std::uint32_t target_index : targets) {
    const ScanCell& target = scan.cells[target_index];
    ray_dz.clear();
    for (const HVoxel& v : scan.hvoxels_of(target)) {
      if (v.density >= n_th) ray_dz.emplace_back(v.z_min - zs, v.z_max - zs);  // line models
    }
    if (ray_dz.empty()) continue;
    rays += ray_dz.size();
    // ProjectLineTo2D: the exact traversal of traverse_2d (ray_trace.hpp), written out here so
    // the window index moves by a step instead of being recomputed, and the axis choice is a
    // select rather than a branch (diagonal rays make it unpredictable).
    const double gx0 = xs / cell;
    const double gy0 = ys / cell;
    const double dx = target.key.i + 0.5 - gx0;
    const double dy = target.key.j + 0.5 - gy0;
    const CellKey start = scan.window.center;  // floor(gx0), floor(gy0): cast once per scan, checked
    const double length_cells = std::sqrt(dx * dx + dy * dy);
    constexpr double kInf = std::numeric_limits<double>::infinity();
    const long step_i = dx > 0 ? 1 : -1;
    const long step_j = dy > 0 ? 1 : -1;
    const double t_delta_i = dx != 0.0 ? std::abs(1.0 / dx) : kInf;
    const double t_delta_j = dy != 0.0 ? std::abs(1.0 / dy) : kInf;
    double t_max_i = dx > 0 ? (start.i + 1 - gx0) / dx : dx < 0 ? (start.i - gx0) / dx : kInf;
    double t_max_j = dy > 0 ? (start.j + 1 - gy0) / dy : dy < 0 ? (start.j - gy0) / dy : kInf;
    long rem_i = std::labs(static_cast<long>(target.key.i) - start.i);
    long rem_j = std::labs(static_cast<long>(target.key.j) - start.j);
    CellKey key = start;
    std::size_t w = scan.window.index(start);
    const long w_step_i = step_i * scan.window.width;
    double t_in = 0.0;
    // An axis with no step left never wins the comparison: its next crossing is put at infinity,
    // so choosing the axis is one comparison, without branches.
    if (rem_i == 0) t_max_i = kInf;
    if (rem_j == 0) t_max_j = kInf;
    // Lines are linear in t: their extremes over [t_in, t_out] of a cell are at the ends.
    const auto add_band = [&](FreeCell& free_cell, const Eigen::Vector2f& dz, float a, float b) {
      const float lo = zs + std::min(a * dz.x(), b * dz.x());
      const float hi = zs + std::max(a * dz.y(), b * dz.y());
      free_cell.add(lo, hi, 1.0F, unite_gap, join_gap);
    };
    // Every cell before the target's: the HVoxel's own cell is not free.
    const auto walk = [&](const auto& visit) {
    while (rem_i + rem_j > 0) {
      const bool along_i = t_max_i < t_max_j;
      const double t_out = std::min(std::min(t_max_i, t_max_j), 1.0);
      if ((t_out - t_in) * length_cells >= 1e-6) {  // a cell touched only at a corner is not crossed
        visit(cell_at(w, key), static_cast<float>(t_in), static_cast<float>(t_out));
      }
      t_in = t_out;
      key.i += static_cast<std::int32_t>(along_i ? step_i : 0);
      key.j += static_cast<std::int32_t>(along_i ? 0 : step_j);
      w += static_cast<std::size_t>(along_i ? w_step_i : step_j);
      rem_i -= along_i ? 1 : 0;
      rem_j -= along_i ? 0 : 1;
      t_max_i = rem_i == 0 ? kInf : t_max_i + (along_i ? t_delta_i : 0.0);
      t_max_j = rem_j == 0 ? kInf : t_max_j + (along_i ? 0.0 : t_delta_j);
    }
    };
    // Most targets cast one ray: that walk has no loop over the rays inside.
    if (ray_dz.size() == 1) {
      const Eigen::Vector2f dz = ray_dz.front();
      walk([&](FreeCell& free_cell, float a, float b) { add_band(free_cell, dz, a, b); });
    } else {
      walk([&](FreeCell& free_cell, float a, float b) {
        for (const Eigen::Vector2f& dz : ray_dz) add_band(free_cell, dz, a, b);
      });
    }
  }
}

}  // namespace hmap
