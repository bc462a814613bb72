// Micro-benchmarks of the mapping pipeline on real scans ($HMAP_DATA_DIR, default ../shared/data).
// The side-by-side comparison with OctoMap is `hmap bench`; these isolate the stages.

#include <benchmark/benchmark.h>

#include <algorithm>
#include <cstdlib>

#include "hmap/io/kitti.hpp"
#include "hmap/maps/mapper.hpp"
#include "bench_data.hpp"

namespace {

using hmap::bench::hdl64_scans;

hmap::Params hdl64_params(hmap::FreeSpaceMode mode) {
  hmap::Params p = hmap::bench::hdl64_params();
  p.map.free_space = mode;
  return p;
}

// One scan integrated into a map that already holds the previous scans (the steady state).
void BM_IntegrateHdl64(benchmark::State& state) {
  const auto& scans = hdl64_scans();
  if (scans.empty()) {
    state.SkipWithError("kitti_hdl64_seq16 is absent: set HMAP_DATA_DIR");
    return;
  }
  const auto mode = static_cast<hmap::FreeSpaceMode>(state.range(0));
  hmap::Mapper mapper(hdl64_params(mode));
  std::size_t k = 0;
  std::size_t points = 0;
  for (auto _ : state) {
    // KITTI scans come without poses here: the sensor stays at the origin, as in `hmap bench`.
    const auto s = mapper.integrate(scans[k % scans.size()], hmap::Pose::Identity());
    points += s.points_in;
    ++k;
  }
  state.counters["points/s"] = benchmark::Counter(static_cast<double>(points), benchmark::Counter::kIsRate);
  state.counters["map_MiB"] = static_cast<double>(mapper.map().stats().memory_bytes) / (1024.0 * 1024.0);
}
BENCHMARK(BM_IntegrateHdl64)->Arg(0)->Arg(1)->ArgName("free_space_mode")->Unit(benchmark::kMillisecond);

void BM_HVoxelizeHdl64(benchmark::State& state) {
  const auto& scans = hdl64_scans();
  if (scans.empty()) {
    state.SkipWithError("kitti_hdl64_seq16 is absent: set HMAP_DATA_DIR");
    return;
  }
  const auto params = hdl64_params(hmap::FreeSpaceMode::kNone);
  hmap::ScanHVoxelizer hvoxelizer(params.map);
  hmap::ScanHVoxels r;
  // The work per scan, for BENCHMARKS.md's estimate of the least an HDL-64 scan needs: points read
  // and kept, the cells they fall in, the HVoxels made.
  double points_in = 0.0;
  double points_kept = 0.0;
  double cells = 0.0;
  double hvoxels = 0.0;
  for (const auto& scan : scans) {
    hvoxelizer.build(scan, hmap::Pose::Identity(), r);
    points_in += static_cast<double>(r.points_in);
    points_kept += static_cast<double>(r.points_kept);
    cells += static_cast<double>(r.cells.size());
    hvoxels += static_cast<double>(r.hvoxels.size());
  }
  const auto n = static_cast<double>(scans.size());
  std::size_t k = 0;
  for (auto _ : state) {
    hvoxelizer.build(scans[k++ % scans.size()], hmap::Pose::Identity(), r);
    benchmark::DoNotOptimize(r.hvoxels.data());
  }
  state.counters["points_in"] = points_in / n;
  state.counters["points_kept"] = points_kept / n;
  state.counters["cells"] = cells / n;
  state.counters["hvoxels"] = hvoxels / n;
}
BENCHMARK(BM_HVoxelizeHdl64)->Unit(benchmark::kMillisecond);

void BM_FreeSpaceHdl64(benchmark::State& state) {
  const auto& scans = hdl64_scans();
  if (scans.empty()) {
    state.SkipWithError("kitti_hdl64_seq16 is absent: set HMAP_DATA_DIR");
    return;
  }
  const auto params = hdl64_params(hmap::FreeSpaceMode::kRayTracing);
  hmap::ScanHVoxelizer hvoxelizer(params.map);
  hmap::FreeSpaceTracer tracer(params.map);
  std::vector<hmap::ScanHVoxels> reps(scans.size());
  for (std::size_t k = 0; k < scans.size(); ++k) hvoxelizer.build(scans[k], hmap::Pose::Identity(), reps[k]);
  // Ray-cell visits per scan: a ray visits the cells from the sensor's to its HVoxel's, that one
  // excluded: |di| + |dj| of them (a cell touched only at a corner is skipped: rarely).
  double ray_cells = 0.0;
  for (const auto& rep : reps) {
    for (const hmap::ScanCell& cell : rep.cells) {
      std::size_t dense = 0;
      for (const hmap::HVoxel& v : rep.hvoxels_of(cell)) dense += v.density >= params.map.density_threshold ? 1 : 0;
      ray_cells += static_cast<double>(dense) *
                   static_cast<double>(std::abs(cell.key.i - rep.window.center.i) + std::abs(cell.key.j - rep.window.center.j));
    }
  }
  std::size_t k = 0;
  std::size_t rays = 0;
  std::size_t free_cells = 0;
  std::size_t iterations = 0;
  for (auto _ : state) {
    tracer.trace(reps[k++ % reps.size()]);
    rays += tracer.rays();
    free_cells += tracer.cells().size();
    ++iterations;
  }
  state.counters["rays/s"] = benchmark::Counter(static_cast<double>(rays), benchmark::Counter::kIsRate);
  state.counters["rays"] = static_cast<double>(rays) / static_cast<double>(std::max<std::size_t>(iterations, 1));
  state.counters["free_cells"] = static_cast<double>(free_cells) / static_cast<double>(std::max<std::size_t>(iterations, 1));
  state.counters["ray_cells"] = ray_cells / static_cast<double>(reps.size());
}
BENCHMARK(BM_FreeSpaceHdl64)->Unit(benchmark::kMillisecond);

}  // namespace
