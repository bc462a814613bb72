// PVOX micro-benchmarks on the simulated boxes experiment: one registration (alignment of a scan
// to the map built from the previous positions, filter update, re-voxelation, insertion), and the
// insertion alone, with and without free-space rays.

#include <benchmark/benchmark.h>

#include "hmap/pvox/boxes_experiment.hpp"
#include "hmap/pvox/mapper.hpp"

namespace {

const hmap::pvox::BoxesRecording& boxes() {
  static const hmap::pvox::BoxesRecording rec = hmap::pvox::simulate_boxes(hmap::pvox::BoxesExperimentParams{});
  return rec;
}

hmap::pvox::PvoxParams params(hmap::pvox::FreeSpace mode) {
  hmap::pvox::PvoxParams p;
  p.insert.min_range = 0.1;
  p.insert.max_range = 30.0;
  p.insert.free_space = mode;
  return p;
}

// Position 5 registered into the map of positions 1–4 (RBF): alignment + update + insertion.
void BM_PvoxRegisterScan(benchmark::State& state) {
  const auto& rec = boxes();
  const auto mode = state.range(0) != 0 ? hmap::pvox::FreeSpace::kRays : hmap::pvox::FreeSpace::kOff;
  hmap::pvox::PvoxMapper base(params(mode));
  for (std::size_t k = 0; k + 1 < rec.scans.size(); ++k) (void)base.add_scan(rec.scans[k], rec.commands[k]);
  for (auto _ : state) {
    state.PauseTiming();
    hmap::pvox::PvoxMapper mapper = base;
    state.ResumeTiming();
    benchmark::DoNotOptimize(mapper.add_scan(rec.scans.back(), rec.commands.back()));
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * rec.scans.back().size()));
}
BENCHMARK(BM_PvoxRegisterScan)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// Insertion of one scan (195k points) into an empty map at the seed's 58.6 mm.
void BM_PvoxInsertScan(benchmark::State& state) {
  const auto& rec = boxes();
  hmap::pvox::InsertParams ip;
  ip.min_range = 0.1;
  ip.max_range = 30.0;
  ip.free_space = state.range(0) != 0 ? hmap::pvox::FreeSpace::kRays : hmap::pvox::FreeSpace::kOff;
  for (auto _ : state) {
    hmap::pvox::VoxelMap map(0.0586);
    benchmark::DoNotOptimize(map.insert(rec.scans[0], rec.T_world_nominal[0], ip));
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * rec.scans[0].size()));
}
BENCHMARK(BM_PvoxInsertScan)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

}  // namespace
