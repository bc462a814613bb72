// The 2.5D elevation-map baseline of pipeline [9] on real scans ($HMAP_DATA_DIR, default
// ../shared/data): the per-scan cost to set beside BM_IntegrateHdl64 of mapper_bench.cpp.

#include <benchmark/benchmark.h>

#include <cstdlib>
#include <filesystem>

#include "hmap/baseline/elevation_mapper.hpp"
#include "hmap/baseline/elevation_occupancy.hpp"
#include "hmap/io/kitti.hpp"

namespace {

std::filesystem::path data_dir() {
  if (const char* env = std::getenv("HMAP_DATA_DIR"); env != nullptr && *env != '\0') return env;
  return HMAP_DEFAULT_DATA_DIR;
}

/// The HDL-64 scans of kitti_hdl64_seq16, read once.
const std::vector<hmap::PointCloud>& hdl64_scans() {
  static const std::vector<hmap::PointCloud> scans = [] {
    std::vector<hmap::PointCloud> out;
    const auto dir = data_dir() / "kitti_hdl64_seq16";
    if (!std::filesystem::exists(dir)) return out;
    const auto seq = hmap::open_kitti_sequence(dir);
    for (const auto& p : seq.scan_paths) out.push_back(hmap::read_kitti_bin(p));
    return out;
  }();
  return scans;
}

/// The parameters of mapper_bench.cpp: 0.2 m cells, 50 m range.
hmap::Params hdl64_params() {
  hmap::Params p = hmap::outdoor_preset();
  p.map.cell_size = 0.2;
  p.map.max_range = 50.0;
  return p;
}

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
