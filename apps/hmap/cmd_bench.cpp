// hmap bench: the same scans into the HMAP and into OctoMap, in one process, side by side.

#include <nlohmann/json.hpp>
#include <octomap/OcTree.h>

#include <malloc.h>
#include <sys/resource.h>

#include <algorithm>
#include <cstdio>
#include <limits>
#include <optional>
#include <iostream>

#include "cli_common.hpp"
#include "hmap/maps/mapper.hpp"

namespace hmap::cli {

namespace {

struct BenchOptions : InputOptions {
  ParamOptions params;
  bool json = false;
  bool skip_octomap = false;
  bool octomap_drop_far = false;
  int repeat = 5;
  int octomap_repeat = 1;
};

struct Result {
  std::string system;
  std::size_t scans = 0;
  std::size_t points = 0;
  double ms_total = 0.0;
  double cpu_ms_total = 0.0;     ///< user + system time of all threads around the updates
  std::size_t memory_bytes = 0;  ///< the structure's own accounting
  std::size_t heap_bytes = 0;    ///< measured: allocator bytes in use held by the map (mallinfo2)
  [[nodiscard]] double ms_per_scan() const { return scans ? ms_total / static_cast<double>(scans) : 0.0; }
  [[nodiscard]] double cpu_ms_per_scan() const { return scans ? cpu_ms_total / static_cast<double>(scans) : 0.0; }
  [[nodiscard]] double points_per_s() const { return ms_total > 0 ? static_cast<double>(points) / (ms_total / 1000.0) : 0.0; }
};

/// Bytes the allocator has handed out and not taken back, headers included: uordblks (blocks of
/// the arenas) + hblkhd (blocks glibc serves by mmap, 128 KiB and up, which uordblks leaves out).
/// (Sanitizer builds replace the allocator and report 0.)
std::size_t heap_in_use() {
  const struct mallinfo2 m = mallinfo2();
  return m.uordblks + m.hblkhd;
}
std::size_t heap_since(std::size_t before) {
  const std::size_t now = heap_in_use();
  return now > before ? now - before : 0;
}

/// User + system CPU time of the process, all threads [ms].
double process_cpu_ms() {
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  const auto ms = [](const timeval& t) { return static_cast<double>(t.tv_sec) * 1e3 + static_cast<double>(t.tv_usec) * 1e-3; };
  return ms(ru.ru_utime) + ms(ru.ru_stime);
}

void print(const Result& r, bool json) {
  if (json) {
    nlohmann::json j{{"system", r.system},        {"scans", r.scans},
                     {"points", r.points},        {"ms_per_scan", r.ms_per_scan()},
                     {"cpu_ms_per_scan", r.cpu_ms_per_scan()},
                     {"points_per_s", r.points_per_s()}, {"memory_bytes", r.memory_bytes},
                     {"heap_bytes", r.heap_bytes}};
    std::cout << j.dump() << std::endl;
  } else {
    std::printf("%-8s %6zu scans %12zu points %10.2f ms/scan %10.2f CPU ms/scan %12s points/s %12s (heap %s)\n",
                r.system.c_str(), r.scans, r.points, r.ms_per_scan(), r.cpu_ms_per_scan(),
                human_count(r.points_per_s()).c_str(),
                human_bytes(static_cast<double>(r.memory_bytes)).c_str(),
                human_bytes(static_cast<double>(r.heap_bytes)).c_str());
  }
}

void run_bench(const BenchOptions& o) {
  const Params params = o.params.resolve();
  ScanSource src = o.open_inputs(/*poses_required=*/false);
  if (!src.T_map_scan) src.T_map_scan = PoseList(src.scans.size(), Pose::Identity());  // as OctoMap's side
  // Read everything first: only the map updates are timed.
  std::vector<PointCloud> clouds;
  CloudReadStats read_stats;
  for (std::size_t k = 0; k < src.scans.size(); ++k) clouds.push_back(src.read(k, read_stats));
  const PoseList& poses = *src.T_map_scan;

  // The HMAP side is short (milliseconds per scan): it runs `repeat` times on a fresh map and
  // the median run counts, so one run's warm-up (page faults, caches) does not decide.
  Result h{"hmap"};
  std::vector<double> run_ms;
  std::vector<double> run_cpu_ms;
  for (int run = 0; run < o.repeat; ++run) {
    Result r{"hmap"};
    const std::size_t heap_before = heap_in_use();
    std::optional<HMap> kept;  // the map alone, once the mapper's scan buffers are gone
    {
      Mapper mapper(params);
      Progress progress("hmap", clouds.size());
      for (std::size_t k = 0; k < clouds.size(); ++k) {
        const double cpu0 = process_cpu_ms();
        const auto t0 = Clock::now();
        const ScanStats s = mapper.integrate(clouds[k], poses[k]);
        r.ms_total += ms_since(t0);
        r.cpu_ms_total += process_cpu_ms() - cpu0;
        r.points += s.points_in;
        progress.update(k + 1, r.ms_total / static_cast<double>(k + 1));
      }
      progress.finish();
      r.scans = clouds.size();
      r.memory_bytes = mapper.map().stats().memory_bytes;
      kept.emplace(std::move(mapper.map()));
    }
    r.heap_bytes = heap_since(heap_before);
    run_ms.push_back(r.ms_total);
    run_cpu_ms.push_back(r.cpu_ms_total);
    if (run == 0) h = r;
  }
  std::sort(run_ms.begin(), run_ms.end());
  std::sort(run_cpu_ms.begin(), run_cpu_ms.end());
  h.ms_total = run_ms[run_ms.size() / 2];
  h.cpu_ms_total = run_cpu_ms[run_cpu_ms.size() / 2];
  print(h, o.json);
  if (o.skip_octomap) return;

  // OctoMap takes seconds per run: once by default; --octomap-repeat N runs it N times on a fresh
  // tree and the median run counts, as for the HMAP side.
  Result oc{"octomap"};
  std::vector<double> octomap_ms;
  std::vector<double> octomap_cpu_ms;
  for (int run = 0; run < o.octomap_repeat; ++run) {
    Result r{"octomap"};
    const std::size_t heap_before = heap_in_use();
    octomap::OcTree tree(params.map.cell_size);
    Progress progress("octomap", clouds.size());
    const double min2 = params.map.min_range * params.map.min_range;
    // Points beyond max_range go to OctoMap, which casts their rays to max_range as free space
    // (its insertPointCloud(..., maxrange) semantics), unless --octomap-drop-far drops them as
    // HMAP does.
    const double max2 = o.octomap_drop_far ? params.map.max_range * params.map.max_range
                                           : std::numeric_limits<double>::infinity();
    for (std::size_t k = 0; k < clouds.size(); ++k) {
      // The scan in the map frame: finite points, none closer than min_range (the sensor's own
      // body, which OctoMap has no parameter to drop).
      octomap::Pointcloud cloud_map;
      cloud_map.reserve(clouds[k].size());
      const Pose& T = poses[k];
      for (const Point3f& p : clouds[k]) {
        const double r2 = p.cast<double>().squaredNorm();
        if (!p.allFinite() || r2 < min2 || r2 > max2) continue;
        const Eigen::Vector3d q = T * p.cast<double>();
        cloud_map.push_back(static_cast<float>(q.x()), static_cast<float>(q.y()), static_cast<float>(q.z()));
      }
      const Eigen::Vector3d origin = T.translation();
      const octomap::point3d sensor(static_cast<float>(origin.x()), static_cast<float>(origin.y()),
                                    static_cast<float>(origin.z()));
      const double cpu0 = process_cpu_ms();
      const auto t0 = Clock::now();
      tree.insertPointCloud(cloud_map, sensor, params.map.max_range);
      r.ms_total += ms_since(t0);
      r.cpu_ms_total += process_cpu_ms() - cpu0;
      r.points += clouds[k].size();
      progress.update(k + 1, r.ms_total / static_cast<double>(k + 1));
    }
    progress.finish();
    r.scans = clouds.size();
    r.memory_bytes = tree.memoryUsage();
    r.heap_bytes = heap_since(heap_before);
    octomap_ms.push_back(r.ms_total);
    octomap_cpu_ms.push_back(r.cpu_ms_total);
    if (run == 0) oc = r;
  }
  std::sort(octomap_ms.begin(), octomap_ms.end());
  std::sort(octomap_cpu_ms.begin(), octomap_cpu_ms.end());
  oc.ms_total = octomap_ms[octomap_ms.size() / 2];
  oc.cpu_ms_total = octomap_cpu_ms[octomap_cpu_ms.size() / 2];
  print(oc, o.json);
  if (!o.json) {
    std::printf("hmap is %.1fx faster per scan and uses %.1fx less memory (%.1fx less heap) than OctoMap "
                "(cell %.3f m, range %.1f-%.1f m)\n",
                h.ms_total > 0 ? oc.ms_total / h.ms_total : 0.0,
                h.memory_bytes > 0 ? static_cast<double>(oc.memory_bytes) / static_cast<double>(h.memory_bytes) : 0.0,
                h.heap_bytes > 0 ? static_cast<double>(oc.heap_bytes) / static_cast<double>(h.heap_bytes) : 0.0,
                params.map.cell_size, params.map.min_range, params.map.max_range);
  }
}

}  // namespace

void add_bench_command(CLI::App& app) {
  auto opts = std::make_shared<BenchOptions>();
  auto* cmd = app.add_subcommand("bench", "Integrate the same scans into the HMAP and into OctoMap and compare");
  opts->add_input_options(*cmd, "Poses T_map_scan, KITTI or TUM format, one per scan (identity for every scan when absent)");
  cmd->add_flag("--json", opts->json, "One JSON object per line, one per system");
  cmd->add_flag("--hmap-only", opts->skip_octomap, "Skip the OctoMap side");
  cmd->add_option("--repeat", opts->repeat, "Runs of the HMAP side; the median counts")
      ->check(CLI::Range(1, 1000))
      ->capture_default_str();
  cmd->add_option("--octomap-repeat", opts->octomap_repeat, "Runs of the OctoMap side; the median counts")
      ->check(CLI::Range(1, 100))
      ->capture_default_str();
  cmd->add_flag("--octomap-drop-far", opts->octomap_drop_far,
                "Drop points beyond --max-range before OctoMap (default: OctoMap truncates their rays "
                "at max range and marks them free, its own behaviour)");
  opts->params.add_to(*cmd);
  cmd->callback([opts] { run_bench(*opts); });
}

}  // namespace hmap::cli
