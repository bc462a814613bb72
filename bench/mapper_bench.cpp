// Micro-benchmarks of the mapping pipeline on real scans ($HMAP_DATA_DIR, default ../shared/data).
// The side-by-side comparison with OctoMap is `hmap bench`; these isolate the stages.

#include <benchmark/benchmark.h>

#include <cstdlib>
#include <filesystem>

#include "hmap/io/kitti.hpp"
#include "hmap/maps/mapper.hpp"

namespace {

std::filesystem::path data_dir() {
  if (const char* env = std::getenv("HMAP_DATA_DIR"); env != nullptr && *env != '\0') return env;
  return HMAP_DEFAULT_DATA_DIR;
}

/// The 16 HDL-64 scans of kitti_hdl64_seq16, read once.
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

hmap::Params hdl64_params(hmap::FreeSpaceMode mode) {
  hmap::Params p = hmap::outdoor_preset();
  p.map.cell_size = 0.2;
  p.map.max_range = 50.0;
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
  for (auto _ : state) {
    tracer.trace(reps[k++ % reps.size()]);
    rays += tracer.rays();
  }
  state.counters["rays/s"] = benchmark::Counter(static_cast<double>(rays), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_FreeSpaceHdl64)->Unit(benchmark::kMillisecond);

}  // namespace
