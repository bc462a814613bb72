// Micro-benchmarks of the mapping pipeline on real scans ($HMAP_DATA_DIR, default ../shared/data).
// The side-by-side comparison with OctoMap is `hmap bench`; these isolate the stages.

#include <benchmark/benchmark.h>

#include <algorithm>

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
  std::size_t k = 0;
  for (auto _ : state) {
    hvoxelizer.build(scans[k++ % scans.size()], hmap::Pose::Identity(), r);
    benchmark::DoNotOptimize(r.hvoxels.data());
  }
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
}
BENCHMARK(BM_FreeSpaceHdl64)->Unit(benchmark::kMillisecond);

}  // namespace
