// Reading a recording against reading the same scans from KITTI files: is the bag path the
// bottleneck? The recording is $HMAP_BENCH_MCAP (any kind --bag takes; skipped when unset), made
// e.g. by `node tests/ros2/make_ros2_recordings.js ../shared/data --full big.mcap 10` (the 80
// balm_os0 scans ten times over, 1.04 GB, /os_cloud and /tf odom -> os_sensor); the KITTI side
// reads balm_os0's 80 .bin files as often, so both read the same points.
#include <benchmark/benchmark.h>

#include <cstdlib>
#include <filesystem>

#include "bench_data.hpp"
#include "hmap/io/kitti.hpp"
#include "hmap/ros/bag_reader.hpp"

namespace {

// Every cloud of the recording decoded to points (index and poses built once, outside the timing
// of the reads: the constructor's cost is reported as its own counter).
void BM_RecordingReadClouds(benchmark::State& state) {
  const char* file = std::getenv("HMAP_BENCH_MCAP");
  if (file == nullptr || *file == '\0') {
    state.SkipWithError("set HMAP_BENCH_MCAP to a recording with /os_cloud (see bench/ros_bench.cpp)");
    return;
  }
  hmap::ros::BagCloudOptions options;
  options.cloud_topic = "/os_cloud";
  options.map_frame = "odom";
  const auto bytes = static_cast<double>(std::filesystem::file_size(file));
  std::size_t points = 0, clouds = 0;
  for (auto _ : state) {
    const hmap::ros::BagCloudReader reader(file, options);
    for (std::size_t k = 0; k < reader.frames().size(); ++k) {
      const hmap::PointCloud cloud = reader.read(k);
      points += cloud.size();
      benchmark::DoNotOptimize(cloud.data());
    }
    clouds += reader.frames().size();
  }
  state.counters["file_MB/s"] = benchmark::Counter(bytes / 1e6 * static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
  state.counters["clouds/s"] = benchmark::Counter(static_cast<double>(clouds), benchmark::Counter::kIsRate);
  state.counters["points/s"] = benchmark::Counter(static_cast<double>(points), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_RecordingReadClouds)->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();

// The same points from balm_os0's KITTI files, read as many times as the recording holds them
// (state.range(0) passes of the 80 scans).
void BM_KittiReadBalm(benchmark::State& state) {
  const auto dir = hmap::bench::data_dir() / "balm_os0";
  if (!std::filesystem::exists(dir)) {
    state.SkipWithError("balm_os0 is absent: set HMAP_DATA_DIR");
    return;
  }
  const auto seq = hmap::open_kitti_sequence(dir);
  std::size_t points = 0, clouds = 0;
  double bytes = 0.0;
  for (auto _ : state) {
    for (std::int64_t pass = 0; pass < state.range(0); ++pass) {
      for (const auto& path : seq.scan_paths) {
        const hmap::PointCloud cloud = hmap::read_kitti_bin(path);
        points += cloud.size();
        bytes += static_cast<double>(std::filesystem::file_size(path));
        benchmark::DoNotOptimize(cloud.data());
      }
      clouds += seq.scan_paths.size();
    }
  }
  state.counters["file_MB/s"] = benchmark::Counter(bytes / 1e6, benchmark::Counter::kIsRate);
  state.counters["clouds/s"] = benchmark::Counter(static_cast<double>(clouds), benchmark::Counter::kIsRate);
  state.counters["points/s"] = benchmark::Counter(static_cast<double>(points), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_KittiReadBalm)->Arg(10)->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();

}  // namespace
