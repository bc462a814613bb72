// Micro-benchmarks of SLAM on the HMAP ($HMAP_DATA_DIR, default ../shared/data): matching one
// HDL-64 scan of kitti_hdl64_seq16 against the map of the previous ones, and a whole SLAM step
// (matching plus map update), at 0.2 m cells and 50 m range.

#include <benchmark/benchmark.h>

#include "hmap/io/kitti.hpp"
#include "hmap/slam/hmap_slam.hpp"
#include "bench_data.hpp"

namespace {

// The last scan matched against the map SLAM built from the 15 before it (HVoxelisation of the
// scan in its level frame included, map update not).
void BM_SlamMatchHdl64(benchmark::State& state) {
  const auto& scans = hmap::bench::hdl64_scans();
  if (scans.size() < 2) {
    state.SkipWithError("kitti_hdl64_seq16 is absent: set HMAP_DATA_DIR");
    return;
  }
  const hmap::Params p = hmap::bench::hdl64_params();
  hmap::slam::HmapSlam slam(p);
  for (std::size_t k = 0; k + 1 < scans.size(); ++k) slam.process(scans[k], {});
  const hmap::slam::PlanarPose guess = slam.predict();
  hmap::ScanHVoxelizer level(p.map);
  hmap::ScanHVoxels scan_level;
  hmap::slam::ScanMatcher matcher(p);
  int iterations = 0;
  std::size_t used = 0;
  for (auto _ : state) {
    level.build(scans.back(), hmap::Pose::Identity(), scan_level);
    const auto r = matcher.match(scan_level, slam.map(), guess);
    iterations += r.iterations;
    used = r.hvoxels_used;
  }
  state.counters["iterations"] = static_cast<double>(iterations) / static_cast<double>(state.iterations());
  state.counters["hvoxels"] = static_cast<double>(used);
}
BENCHMARK(BM_SlamMatchHdl64)->Unit(benchmark::kMillisecond);

// Whole SLAM steps over the 16 scans, map rebuilt each pass: matching plus map update per scan.
void BM_SlamStepHdl64(benchmark::State& state) {
  const auto& scans = hmap::bench::hdl64_scans();
  if (scans.empty()) {
    state.SkipWithError("kitti_hdl64_seq16 is absent: set HMAP_DATA_DIR");
    return;
  }
  std::size_t steps = 0;
  for (auto _ : state) {
    hmap::slam::HmapSlam slam(hmap::bench::hdl64_params());
    for (const auto& scan : scans) slam.process(scan, {});
    steps += scans.size();
  }
  state.counters["scans/s"] = benchmark::Counter(static_cast<double>(steps), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_SlamStepHdl64)->Unit(benchmark::kMillisecond);

// The steady state: scans 3..16 of each pass timed, after the first scan (no matching) and the
// second (always searched coarsely: constant velocity knows nothing yet) have set up the map.
/// Scans 3..16 of each pass timed with `p`, the map rebuilt each pass.
void slam_steady(benchmark::State& state, const hmap::Params& p) {
  const auto& scans = hmap::bench::hdl64_scans();
  if (scans.size() < 3) {
    state.SkipWithError("kitti_hdl64_seq16 is absent: set HMAP_DATA_DIR");
    return;
  }
  std::size_t steps = 0;
  for (auto _ : state) {
    state.PauseTiming();
    hmap::slam::HmapSlam slam(p);
    slam.process(scans[0], {});
    slam.process(scans[1], {});
    state.ResumeTiming();
    for (std::size_t k = 2; k < scans.size(); ++k) slam.process(scans[k], {});
    steps += scans.size() - 2;
  }
  state.counters["scans/s"] = benchmark::Counter(static_cast<double>(steps), benchmark::Counter::kIsRate);
}

void BM_SlamSteadyHdl64(benchmark::State& state) { slam_steady(state, hmap::bench::hdl64_params()); }
BENCHMARK(BM_SlamSteadyHdl64)->Unit(benchmark::kMillisecond);

// The same steady state with what `hmap slam --kitti kitti_hdl64_seq16 --cell 0.2` chooses: the
// user's command at issue 16's 0.2 m (the range is the preset's 25 m, not the 50 m above).
void BM_SlamSteadyHdl64Defaults(benchmark::State& state) { slam_steady(state, hmap::bench::hdl64_defaults_at_0_2()); }
BENCHMARK(BM_SlamSteadyHdl64Defaults)->Unit(benchmark::kMillisecond);

}  // namespace
