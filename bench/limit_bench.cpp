// The least work an HDL-64 scan needs (issue 19, BENCHMARKS.md "The limit"): the stages of hmap's
// integration done in their barest form, one thread, on the same 16 scans at the same 0.2 m cells
// and 50 m range as BM_HVoxelizeHdl64 and BM_FreeSpaceHdl64. Each kernel does the work its stage
// must do and nothing it may leave out: no second pose, no drop statistics, no density function,
// one free interval per cell instead of four, no thread hand-over. They are floors to measure hmap
// against, not maps: nothing here is used by the library. The work they do is counted by
// BM_HVoxelizeHdl64's and BM_FreeSpaceHdl64's counters.

#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "hmap/maps/scan_hvoxels.hpp"
#include "bench_data.hpp"

namespace {

using hmap::bench::hdl64_scans;

// The window of BM_HVoxelizeHdl64: the cells within 50 m of the sensor's cell at 0.2 m.
struct Grid {
  double cell = 0.2;
  double max_range = 50.0;
  double min_range = 1.2;
  std::int32_t half = static_cast<std::int32_t>(50.0 / 0.2) + 1;
  std::int32_t width = 2 * half + 1;
  [[nodiscard]] std::size_t cells() const { return static_cast<std::size_t>(width) * static_cast<std::size_t>(width); }
};

/// Points binned by cell: the heights of cell c are z[start[c] .. start[c + 1]).
struct Binned {
  std::vector<std::uint32_t> window_of_cell;  // the window cell of each used cell
  std::vector<std::uint32_t> start;
  std::vector<float> z;
};

/// Transform (a rotation and translation read at run time, so the multiplies stay), range test,
/// cell, and a counting sort of the heights by cell over the cells used (first-come numbering).
class Binner {
 public:
  explicit Binner(const Grid& g) : g_(g), slot_(g.cells(), 0) {}
  void bin(const hmap::PointCloud& points, const float (&R)[9], const float (&t)[3], Binned& out) {
    const auto inv = static_cast<float>(1.0 / g_.cell);
    const auto r2_min = static_cast<float>(g_.min_range * g_.min_range);
    const auto r2_max = static_cast<float>(g_.max_range * g_.max_range);
    const float half = static_cast<float>(g_.half);
    cell_of_point_.resize(points.size());
    z_of_point_.resize(points.size());
    out.window_of_cell.clear();
    count_.clear();
    for (std::size_t k = 0; k < points.size(); ++k) {
      const hmap::Point3f& p = points[k];
      const float r2 = p.squaredNorm();
      if (!(r2 >= r2_min && r2 <= r2_max)) {  // NaN fails too
        cell_of_point_[k] = kDropped;
        continue;
      }
      const float x = R[0] * p.x() + R[1] * p.y() + R[2] * p.z() + t[0];
      const float y = R[3] * p.x() + R[4] * p.y() + R[5] * p.z() + t[1];
      const auto i = static_cast<std::int32_t>(std::floor(x * inv) + half);
      const auto j = static_cast<std::int32_t>(std::floor(y * inv) + half);
      const auto w = static_cast<std::uint32_t>(i * g_.width + j);
      std::uint32_t& s = slot_[w];  // the cell's number + 1, 0 while unused
      if (s == 0) {
        out.window_of_cell.push_back(w);
        count_.push_back(0);
        s = static_cast<std::uint32_t>(out.window_of_cell.size());
      }
      ++count_[s - 1];
      cell_of_point_[k] = s;
      z_of_point_[k] = R[6] * p.x() + R[7] * p.y() + R[8] * p.z() + t[2];
    }
    const std::size_t n = out.window_of_cell.size();
    out.start.assign(n + 1, 0);
    for (std::size_t c = 0; c < n; ++c) {
      out.start[c + 1] = out.start[c] + count_[c];
      slot_[out.window_of_cell[c]] = 0;  // the window is clean for the next scan
    }
    out.z.resize(out.start[n]);
    cursor_.assign(out.start.begin(), out.start.end() - 1);
    for (std::size_t k = 0; k < points.size(); ++k) {
      if (cell_of_point_[k] == kDropped) continue;
      out.z[cursor_[cell_of_point_[k] - 1]++] = z_of_point_[k];
    }
  }

 private:
  static constexpr std::uint32_t kDropped = 0;
  Grid g_;
  std::vector<std::uint32_t> slot_;
  std::vector<std::uint32_t> cell_of_point_;
  std::vector<float> z_of_point_;
  std::vector<std::uint32_t> count_;
  std::vector<std::uint32_t> cursor_;
};

/// The identity pose, read through volatile copies: the compiler must not fold it away.
struct RuntimePose {
  float R[9];
  float t[3];
  RuntimePose() {
    static const float kIdentity[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    for (int k = 0; k < 9; ++k) R[k] = *static_cast<const volatile float*>(&kIdentity[k]);
    for (float& v : t) v = *static_cast<const volatile float*>(&kZero);
  }
  static constexpr float kZero = 0.0F;
};

void BM_LimitBinHdl64(benchmark::State& state) {
  const auto& scans = hdl64_scans();
  if (scans.empty()) {
    state.SkipWithError("kitti_hdl64_seq16 is absent: set HMAP_DATA_DIR");
    return;
  }
  const Grid g;
  Binner binner(g);
  Binned out;
  const RuntimePose pose;
  std::size_t k = 0;
  for (auto _ : state) {
    binner.bin(scans[k++ % scans.size()], pose.R, pose.t, out);
    benchmark::DoNotOptimize(out.z.data());
  }
}
BENCHMARK(BM_LimitBinHdl64)->Unit(benchmark::kMillisecond);

/// Each cell's heights sorted and split where neighbours are more than `gap` apart: [min, max] and
/// the count per cluster (hmap's Alg. 2 without eq. (1)'s density).
std::size_t cluster(Binned& b, float gap, std::vector<hmap::HVoxel>& out) {
  out.clear();
  for (std::size_t c = 0; c + 1 < b.start.size(); ++c) {
    float* first = b.z.data() + b.start[c];
    float* last = b.z.data() + b.start[c + 1];
    const auto [min_it, max_it] = std::minmax_element(first, last);
    if (*max_it - *min_it <= gap) {  // no gap can exceed the span: one cluster, nothing sorted
      out.push_back({*min_it, *max_it, static_cast<float>(last - first), 0.0F});
      continue;
    }
    if (last - first <= 16) {  // insertion sort: the usual small cell
      for (float* z = first + 1; z != last; ++z) {
        const float v = *z;
        float* q = z;
        for (; q != first && *(q - 1) > v; --q) *q = *(q - 1);
        *q = v;
      }
    } else {
      std::sort(first, last);
    }
    float lo = *first;
    float prev = *first;
    std::uint32_t count = 1;
    for (const float* z = first + 1; z != last; ++z) {
      if (*z - prev > gap) {
        out.push_back({lo, prev, static_cast<float>(count), 0.0F});
        lo = *z;
        count = 0;
      }
      prev = *z;
      ++count;
    }
    out.push_back({lo, prev, static_cast<float>(count), 0.0F});
  }
  return out.size();
}

void BM_LimitClusterHdl64(benchmark::State& state) {
  const auto& scans = hdl64_scans();
  if (scans.empty()) {
    state.SkipWithError("kitti_hdl64_seq16 is absent: set HMAP_DATA_DIR");
    return;
  }
  const Grid g;
  Binner binner(g);
  std::vector<Binned> binned(scans.size());
  const RuntimePose pose;
  for (std::size_t k = 0; k < scans.size(); ++k) binner.bin(scans[k], pose.R, pose.t, binned[k]);
  const auto gap = static_cast<float>(hmap::bench::hdl64_params().map.point_distance_threshold);
  std::vector<hmap::HVoxel> hvoxels;
  Binned work;
  std::size_t k = 0;
  for (auto _ : state) {
    state.PauseTiming();
    work = binned[k++ % binned.size()];  // sorting in place: each round gets the unsorted heights
    state.ResumeTiming();
    benchmark::DoNotOptimize(cluster(work, gap, hvoxels));
    benchmark::DoNotOptimize(hvoxels.data());
  }
}
BENCHMARK(BM_LimitClusterHdl64)->Unit(benchmark::kMillisecond);

// The free-space walks: hmap's own scan HVoxels (ScanHVoxelizer, as BM_FreeSpaceHdl64), one ray per
// HVoxel with density >= n_th to its cell, the same exact traversal in double, one walk per target
// cell for all its rays, each crossed cell's one free interval widened by the rays' band. The
// intervals are 8 bytes per window cell (2 MB, as hmap's free cells are 64 bytes for about 32 k
// cells), reset after each scan over the cells used.
void BM_LimitWalkHdl64(benchmark::State& state) {
  const auto& scans = hdl64_scans();
  if (scans.empty()) {
    state.SkipWithError("kitti_hdl64_seq16 is absent: set HMAP_DATA_DIR");
    return;
  }
  const hmap::Params params = hmap::bench::hdl64_params();
  hmap::ScanHVoxelizer hvoxelizer(params.map);
  std::vector<hmap::ScanHVoxels> reps(scans.size());
  for (std::size_t k = 0; k < scans.size(); ++k) hvoxelizer.build(scans[k], hmap::Pose::Identity(), reps[k]);
  const auto n_th = static_cast<float>(params.map.density_threshold);
  const std::size_t cells = reps.front().window.width * static_cast<std::size_t>(reps.front().window.width);
  constexpr float kInfF = std::numeric_limits<float>::infinity();
  struct Band {
    float lo;
    float hi;
  };
  std::vector<Band> band(cells, Band{kInfF, -kInfF});
  std::vector<std::uint32_t> used;
  std::vector<float> dz_lo;
  std::vector<float> dz_hi;
  std::size_t k = 0;
  for (auto _ : state) {
    const hmap::ScanHVoxels& scan = reps[k++ % reps.size()];
    const double cell = params.map.cell_size;
    const double gx0 = scan.origin_map.x() / cell;
    const double gy0 = scan.origin_map.y() / cell;
    const auto zs = static_cast<float>(scan.origin_map.z());
    const hmap::CellKey start = scan.window.center;
    used.clear();
    for (const hmap::ScanCell& target : scan.cells) {
      dz_lo.clear();
      dz_hi.clear();
      for (const hmap::HVoxel& v : scan.hvoxels_of(target)) {
        if (v.density < n_th) continue;
        dz_lo.push_back(v.z_min - zs);
        dz_hi.push_back(v.z_max - zs);
      }
      if (dz_lo.empty()) continue;
      const float dlo = *std::min_element(dz_lo.begin(), dz_lo.end());
      const float dhi = *std::max_element(dz_hi.begin(), dz_hi.end());
      const double dx = target.key.i + 0.5 - gx0;
      const double dy = target.key.j + 0.5 - gy0;
      constexpr double kInf = std::numeric_limits<double>::infinity();
      const long step_i = dx > 0 ? 1 : -1;
      const long step_j = dy > 0 ? 1 : -1;
      const double t_delta_i = dx != 0.0 ? std::abs(1.0 / dx) : kInf;
      const double t_delta_j = dy != 0.0 ? std::abs(1.0 / dy) : kInf;
      long rem_i = std::labs(static_cast<long>(target.key.i) - start.i);
      long rem_j = std::labs(static_cast<long>(target.key.j) - start.j);
      double t_max_i = rem_i == 0 ? kInf : dx > 0 ? (start.i + 1 - gx0) / dx : (start.i - gx0) / dx;
      double t_max_j = rem_j == 0 ? kInf : dy > 0 ? (start.j + 1 - gy0) / dy : (start.j - gy0) / dy;
      std::size_t w = scan.window.index(start);
      const long w_step_i = step_i * scan.window.width;
      double t_in = 0.0;
      while (rem_i + rem_j > 0) {
        const bool along_i = t_max_i < t_max_j;
        const double t_out = std::min(std::min(t_max_i, t_max_j), 1.0);
        // The band of every ray to this target at once: the lowest line's low end, the highest's top.
        const float a = static_cast<float>(t_in);
        const float b = static_cast<float>(t_out);
        Band& f = band[w];
        if (f.lo == kInfF) used.push_back(static_cast<std::uint32_t>(w));
        f.lo = std::min(f.lo, zs + std::min(a * dlo, b * dlo));
        f.hi = std::max(f.hi, zs + std::max(a * dhi, b * dhi));
        t_in = t_out;
        w += static_cast<std::size_t>(along_i ? w_step_i : step_j);
        rem_i -= along_i ? 1 : 0;
        rem_j -= along_i ? 0 : 1;
        t_max_i = rem_i == 0 ? kInf : t_max_i + (along_i ? t_delta_i : 0.0);
        t_max_j = rem_j == 0 ? kInf : t_max_j + (along_i ? 0.0 : t_delta_j);
      }
    }
    benchmark::DoNotOptimize(band.data());
    for (const std::uint32_t u : used) band[u] = Band{kInfF, -kInfF};
  }
}
BENCHMARK(BM_LimitWalkHdl64)->Unit(benchmark::kMillisecond);

}  // namespace
