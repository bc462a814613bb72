// hmap_peers_bench: hmap beside Bonxai and OctoMap on the same scans and poses, in one process.
//
//   hmap_peers_bench --kitti DIR --cell 0.2 --max-range 50 [--rounds 3] [--octomap-rounds 1]
//
// Each round runs every system once over all scans on a fresh map: hmap (TBB's threads), hmap on
// one thread, Bonxai, OctoMap. Per run: wall time and CPU time (all threads) of the updates alone,
// points per second, memory by the structure's own accounting and measured on the heap. The
// ratios (peer : hmap) are taken within each round, where the load of this shared machine is most
// alike, and summarised by their median and range over the rounds.

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cstdio>
#include <map>
#include <string>
#include <vector>

#include "hmap/core/error.hpp"
#include "hmap/io/kitti.hpp"
#include "side_by_side.hpp"

namespace {

using hmap::bench::RunMeasurement;

struct Range {
  double median = 0.0;
  double lo = 0.0;
  double hi = 0.0;
};

Range range_of(std::vector<double> v) {
  if (v.empty()) return {};
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  const double median = n % 2 == 1 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
  return {median, v.front(), v.back()};
}

/// "median (lo–hi)", the unit after the median; the median alone for one run.
std::string text(const Range& r, const char* format, const char* unit = "") {
  char a[64];
  char b[64];
  char c[64];
  std::snprintf(a, sizeof a, format, r.median);
  if (r.lo == r.hi) return std::string(a) + unit;
  std::snprintf(b, sizeof b, format, r.lo);
  std::snprintf(c, sizeof c, format, r.hi);
  return std::string(a) + unit + " (" + b + "–" + c + ")";
}

double mib(std::size_t bytes) { return static_cast<double>(bytes) / (1024.0 * 1024.0); }

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"hmap beside Bonxai and OctoMap on the same scans and poses, in one process"};
  std::string kitti;
  std::string preset_name = "outdoor";
  double cell = 0.2;
  double max_range = 50.0;
  double min_range = -1.0;
  std::size_t max_scans = 0;
  int rounds = 3;
  int octomap_rounds = 1;
  bool single_thread = true;
  app.add_option("--kitti", kitti, "KITTI-layout folder (velodyne/*.bin, poses.txt; identity poses without it)")->required();
  app.add_option("--preset", preset_name, "hmap's parameter preset")->capture_default_str();
  app.add_option("--cell", cell, "Cell / voxel edge [m], for every system")->capture_default_str();
  app.add_option("--max-range", max_range, "Points farther are dropped for every system [m]")->capture_default_str();
  app.add_option("--min-range", min_range, "Points closer are dropped for every system [m] (default: the preset's)");
  app.add_option("--scans", max_scans, "Use the first N scans (0: all)");
  app.add_option("--rounds", rounds, "Rounds; each runs every system once on a fresh map")->check(CLI::Range(1, 100))->capture_default_str();
  app.add_option("--octomap-rounds", octomap_rounds, "Rounds that include OctoMap (seconds per scan); 0 skips it")
      ->check(CLI::Range(0, 100))
      ->capture_default_str();
  app.add_flag("!--no-single-thread", single_thread, "Skip hmap on one thread");
  CLI11_PARSE(app, argc, argv);

  try {
    hmap::Params params = hmap::preset(preset_name);
    params.map.cell_size = cell;
    params.map.max_range = max_range;
    if (min_range >= 0.0) params.map.min_range = min_range;
    hmap::validate(params);
    const hmap::bench::FeedSettings feed{params.map.cell_size, params.map.min_range, params.map.max_range};

    // Read and feed every scan first: only the updates are timed.
    hmap::KittiSequenceOptions options;
    if (max_scans > 0) options.max_scans = max_scans;
    const hmap::KittiSequence seq = hmap::open_kitti_sequence(kitti, options);
    std::vector<hmap::bench::FedScan> scans(seq.scan_paths.size());
    std::size_t read = 0;
    std::size_t fed = 0;
    for (std::size_t k = 0; k < scans.size(); ++k) {
      const hmap::PointCloud cloud = hmap::read_kitti_bin(seq.scan_paths[k]);
      hmap::bench::feed_scan(cloud, seq.T_map_scan ? (*seq.T_map_scan)[k] : hmap::Pose::Identity(), feed, scans[k]);
      read += scans[k].points_read;
      fed += scans[k].points_sensor.size();
    }
    std::printf("%s: %zu scans, %zu points read, %zu within %.2f-%.2f m fed to every system (%s poses); "
                "cell %.3f m, preset %s\n",
                kitti.c_str(), scans.size(), read, fed, feed.min_range, feed.max_range,
                seq.T_map_scan ? "poses.txt" : "identity", feed.cell_size, preset_name.c_str());

    std::vector<std::unique_ptr<hmap::bench::System>> systems;
    systems.push_back(hmap::bench::make_hmap_system(params, 0));
    if (single_thread) systems.push_back(hmap::bench::make_hmap_system(params, 1));
    if (auto bonxai = hmap::bench::make_bonxai_system(feed)) {
      systems.push_back(std::move(bonxai));
    } else {
      std::printf("Bonxai skipped: %s\n", hmap::bench::bonxai_absent_reason().c_str());
    }
    if (octomap_rounds > 0) systems.push_back(hmap::bench::make_octomap_system(feed));

    // runs[system][round]
    std::map<std::string, std::vector<RunMeasurement>> runs;
    std::vector<std::string> order;
    for (const auto& s : systems) order.push_back(s->name());
    for (int round = 0; round < rounds; ++round) {
      std::printf("round %d:", round + 1);
      for (auto& s : systems) {
        if (s->name() == "OctoMap" && round >= octomap_rounds) continue;
        const RunMeasurement m = hmap::bench::run_system(*s, scans);
        const hmap::bench::Received& r = s->received();
        if (r.points != fed || r.scans != scans.size()) {
          std::printf("\n  warning: %s took %zu of the %zu points fed as hits\n", s->name().c_str(), r.points, fed);
        }
        runs[s->name()].push_back(m);
        std::printf("  %s %.2f ms wall / %.2f ms CPU per scan;", s->name().c_str(), m.wall_ms_per_scan(),
                    m.cpu_ms_per_scan());
        std::fflush(stdout);
      }
      std::printf("\n");
    }

    std::printf("\n| system | runs | wall ms/scan | CPU ms/scan | points/s (M) | structure MiB | heap MiB |\n");
    std::printf("| --- | --- | --- | --- | --- | --- | --- |\n");
    for (const std::string& name : order) {
      const auto& v = runs[name];
      std::vector<double> wall, cpu, pps;
      for (const RunMeasurement& m : v) {
        wall.push_back(m.wall_ms_per_scan());
        cpu.push_back(m.cpu_ms_per_scan());
        pps.push_back(m.points_per_s() * 1e-6);
      }
      std::printf("| %s | %zu | %s | %s | %s | %.2f | %.2f |\n", name.c_str(), v.size(), text(range_of(wall), "%.2f").c_str(),
                  text(range_of(cpu), "%.2f").c_str(), text(range_of(pps), "%.2f").c_str(), mib(v.front().structure_bytes),
                  mib(v.front().heap_bytes));
    }

    // Ratios within each round: how many times the peer's time (memory) is hmap's.
    std::printf("\n| peer : hmap | rounds | wall | CPU | wall, hmap 1 thread | CPU, hmap 1 thread | structure | heap |\n");
    std::printf("| --- | --- | --- | --- | --- | --- | --- | --- |\n");
    const auto& h2 = runs["hmap"];
    const auto& h1 = runs["hmap 1 thread"];
    for (const std::string& peer : order) {
      if (peer.rfind("hmap", 0) == 0) continue;
      const auto& p = runs[peer];
      std::vector<double> wall, cpu, wall1, cpu1;
      for (std::size_t k = 0; k < p.size(); ++k) {
        wall.push_back(p[k].wall_ms / h2[k].wall_ms);
        cpu.push_back(p[k].cpu_ms / h2[k].cpu_ms);
        if (k < h1.size()) {
          wall1.push_back(p[k].wall_ms / h1[k].wall_ms);
          cpu1.push_back(p[k].cpu_ms / h1[k].cpu_ms);
        }
      }
      const double structure = static_cast<double>(p.front().structure_bytes) / static_cast<double>(h2.front().structure_bytes);
      const double heap = static_cast<double>(p.front().heap_bytes) / static_cast<double>(h2.front().heap_bytes);
      std::printf("| %s | %zu | %s | %s | %s | %s | %.1f× | %.1f× |\n", peer.c_str(), p.size(),
                  text(range_of(wall), "%.1f", "×").c_str(), text(range_of(cpu), "%.1f", "×").c_str(),
                  wall1.empty() ? "-" : text(range_of(wall1), "%.1f", "×").c_str(),
                  cpu1.empty() ? "-" : text(range_of(cpu1), "%.1f", "×").c_str(), structure, heap);
    }
    if (!h1.empty()) {
      std::vector<double> wall, cpu;
      for (std::size_t k = 0; k < h1.size(); ++k) {
        wall.push_back(h1[k].wall_ms / h2[k].wall_ms);
        cpu.push_back(h1[k].cpu_ms / h2[k].cpu_ms);
      }
      std::printf("\nhmap on one thread : hmap on TBB's threads, within each round: wall %s, CPU %s\n",
                  text(range_of(wall), "%.2f", "×").c_str(), text(range_of(cpu), "%.2f", "×").c_str());
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "hmap_peers_bench: %s\n", e.what());
    return 2;
  }
  return 0;
}
