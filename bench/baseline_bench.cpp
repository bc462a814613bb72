// The 2.5D elevation-map baseline of pipeline [9] on real scans ($HMAP_DATA_DIR, default
// ../shared/data): the per-scan cost to set beside BM_IntegrateHdl64 of mapper_bench.cpp.

#include <benchmark/benchmark.h>

#include "hmap/baseline/elevation_mapper.hpp"
#include "hmap/baseline/elevation_occupancy.hpp"
#include "hmap/io/kitti.hpp"
#include "bench_data.hpp"

namespace {

using hmap::bench::hdl64_params;
using hmap::bench::hdl64_scans;

// One scan fused into a map that already holds the previous scans (the steady state).
void BM_ElevationIntegrateHdl64(benchmark::State& state) {
  const auto& scans = hdl64_scans();
  if (scans.empty()) {
    state.SkipWithError("kitti_hdl64_seq16 is absent: set HMAP_DATA_DIR");
    return;
  }
  hmap::ElevationMapper mapper(hdl64_params());
  for (const auto& scan : scans) mapper.integrate(scan, hmap::Pose::Identity());  // warm
  std::size_t k = 0;
  std::size_t points = 0;
  for (auto _ : state) {
    // KITTI scans come without poses here: the sensor stays at the origin, as in mapper_bench.
    const auto s = mapper.integrate(scans[k % scans.size()], hmap::Pose::Identity());
    points += s.points_in;
    ++k;
  }
  state.counters["points/s"] = benchmark::Counter(static_cast<double>(points), benchmark::Counter::kIsRate);
  state.counters["map_MiB"] = static_cast<double>(mapper.map().memory_bytes()) / (1024.0 * 1024.0);
  state.counters["cells"] = static_cast<double>(mapper.map().known_cells());
}
BENCHMARK(BM_ElevationIntegrateHdl64)->Unit(benchmark::kMillisecond);

// The 2D grid of [9] from the finished map: as_hmap, RRT ground, occupancy_from_elevation.
void BM_ElevationOccupancyHdl64(benchmark::State& state) {
  const auto& scans = hdl64_scans();
  if (scans.empty()) {
    state.SkipWithError("kitti_hdl64_seq16 is absent: set HMAP_DATA_DIR");
    return;
  }
  const hmap::Params params = hdl64_params();
  hmap::ElevationMapper mapper(params);
  mapper.integrate(scans.front(), hmap::Pose::Identity());
  for (auto _ : state) {
    const hmap::HMap as_map = hmap::as_hmap(mapper.map());
    const hmap::GroundResult ground = hmap::extract_ground(as_map, {0.0, 0.0, 0.0}, params.ground);
    const hmap::OccupancyGrid grid =
        hmap::occupancy_from_elevation(mapper.map(), hmap::GroundModel(ground.patches), params, 2.0);
    benchmark::DoNotOptimize(grid.known_cells());
  }
}
BENCHMARK(BM_ElevationOccupancyHdl64)->Unit(benchmark::kMillisecond);

}  // namespace
