// The hybrid part of section IV per HDL-64 scan: Alg. 4's ground tree growing around the sensor
// and the eq. (3)-(4) update of the 2D grid ($HMAP_DATA_DIR, default ../shared/data).

#include <benchmark/benchmark.h>

#include "hmap/io/kitti.hpp"
#include "hmap/occupancy/hybrid_mapper.hpp"
#include "bench_data.hpp"

namespace {

using hmap::bench::hdl64_params;
using hmap::bench::hdl64_scans;

// Ground tree update + 2D grid update of one scan, after its HMAP update (not timed). The
// sequence has no poses: every scan is taken at the origin, as in BM_IntegrateHdl64.
void BM_GroundAndOccupancyHdl64(benchmark::State& state) {
  const auto& scans = hdl64_scans();
  if (scans.empty()) {
    state.SkipWithError("kitti_hdl64_seq16 is absent: set HMAP_DATA_DIR");
    return;
  }
  const hmap::Params params = hdl64_params();
  hmap::Mapper mapper(params);
  hmap::GroundTracker ground(params.ground);
  hmap::OccupancyGrid grid(params.map.cell_size, params.occupancy.clamp_min, params.occupancy.clamp_max);
  hmap::OccupancyUpdater updater(params);
  std::size_t k = 0;
  std::size_t patches_added = 0;
  std::size_t cells = 0;
  for (auto _ : state) {
    state.PauseTiming();
    mapper.integrate(scans[k % scans.size()], hmap::Pose::Identity());
    state.ResumeTiming();
    const auto g = ground.update(mapper.map(), Eigen::Vector3d::Zero(), params.map.max_range);
    const auto o = updater.update(mapper.last_scan(), ground.model(), grid);
    patches_added += static_cast<std::size_t>(g.accepted);
    cells += o.cells;
    ++k;
  }
  state.counters["patches"] = static_cast<double>(ground.patches().size());
  state.counters["cells/scan"] = static_cast<double>(cells) / static_cast<double>(k);
}
BENCHMARK(BM_GroundAndOccupancyHdl64)->Unit(benchmark::kMillisecond);

// The two parts alone, on a map of all 16 scans.
struct Built {
  hmap::Params params = hdl64_params();
  hmap::Mapper mapper{params};
  hmap::GroundTracker ground{params.ground};
  Built() {
    for (const auto& s : hdl64_scans()) {
      mapper.integrate(s, hmap::Pose::Identity());
      ground.update(mapper.map(), Eigen::Vector3d::Zero(), params.map.max_range);
    }
  }
};

void BM_OccupancyUpdateHdl64(benchmark::State& state) {
  if (hdl64_scans().empty()) {
    state.SkipWithError("kitti_hdl64_seq16 is absent: set HMAP_DATA_DIR");
    return;
  }
  static const Built built;
  hmap::OccupancyGrid grid(built.params.map.cell_size, 0.12, 0.97);
  hmap::OccupancyUpdater updater(built.params);
  std::size_t rays = 0;
  for (auto _ : state) rays += updater.update(built.mapper.last_scan(), built.ground.model(), grid).rays;
  state.counters["rays/scan"] = static_cast<double>(rays) / static_cast<double>(state.iterations());
}
BENCHMARK(BM_OccupancyUpdateHdl64)->Unit(benchmark::kMillisecond);

void BM_GroundUpdateHdl64(benchmark::State& state) {
  if (hdl64_scans().empty()) {
    state.SkipWithError("kitti_hdl64_seq16 is absent: set HMAP_DATA_DIR");
    return;
  }
  static const Built built;
  hmap::GroundTracker ground = built.ground;
  for (auto _ : state) ground.update(built.mapper.map(), Eigen::Vector3d::Zero(), built.params.map.max_range);
}
BENCHMARK(BM_GroundUpdateHdl64)->Unit(benchmark::kMillisecond);

}  // namespace
