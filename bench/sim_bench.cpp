// Simulation speed: one frame of the built-in `parking` scene along the car route.

#include <benchmark/benchmark.h>

#include "hmap/sim/builtin_scenes.hpp"
#include "hmap/sim/sensors.hpp"
#include "hmap/sim/trajectory.hpp"

namespace {

void BM_SimulateParking(benchmark::State& state) {
  const hmap::sim::Scene scene = hmap::sim::make_scene("parking");
  const auto route = hmap::sim::parking_car_route();
  const hmap::sim::Trajectory path = hmap::sim::car_path(route, hmap::sim::CarPathParams{});
  hmap::sim::SpinningLidar lidar(state.range(0) == 16 ? hmap::sim::SpinningLidarParams::vlp16()
                                                      : hmap::sim::SpinningLidarParams::hdl64e());
  std::size_t k = 0;
  std::size_t points = 0;
  for (auto _ : state) {
    const std::size_t f = (k++ * 10) % path.T_world_sensor.size();  // one frame a second along the path
    const auto scan = lidar.scan(scene, path.T_world_sensor[f], path.times[f]);
    points += scan.points_sensor.size();
  }
  state.counters["points/s"] = benchmark::Counter(static_cast<double>(points), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_SimulateParking)->Arg(16)->Arg(64)->ArgName("rings")->Unit(benchmark::kMillisecond);

}  // namespace
