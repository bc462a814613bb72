// hmap_drive_cost: the cost of the hybrid map as it grows over a long drive (issue 19).
//
// usage: hmap_drive_cost KITTI_DIR [SEGMENT_M]     (default 1000 m)
//
// Maps the scans of KITTI_DIR (velodyne/*.bin and poses.txt, as `hmap simulate` writes them) in
// order with the hybrid map of `hmap map` at its defaults (the preset chosen from the first scan;
// the HMAP, the ground patches and the 2D grid), and after every SEGMENT_M metres of path (and at
// the end) prints one row: the path so far, the scans of the segment, the process CPU time
// (user + sys, getrusage, every thread) per scan of the segment with the scans' reading included,
// the main thread's CPU time inside HybridMapper::integrate (TBB's workers not counted), the map's HVoxels and memory (MapStats), the 2D grid's
// memory, the ground patches and the process's peak RSS so far. One process, one pass: the
// segments' costs are read off the same run instead of differencing runs of N scans.

#include <sys/resource.h>

#include <cstdio>
#include <ctime>
#include <exception>
#include <string>

#include "hmap/io/config.hpp"
#include "hmap/io/kitti.hpp"
#include "hmap/occupancy/hybrid_mapper.hpp"

namespace {

double process_cpu_s() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
         1e-6 * static_cast<double>(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

double thread_cpu_s() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

double peak_rss_mib() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_maxrss) / 1024.0;  // ru_maxrss is in KiB on Linux
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2 || argc > 3) {
    std::fprintf(stderr, "usage: hmap_drive_cost KITTI_DIR [SEGMENT_M]\n");
    return 2;
  }
  try {
    const double segment_m = argc == 3 ? std::stod(argv[2]) : 1000.0;
    if (!(segment_m > 0.0)) throw std::runtime_error("SEGMENT_M must be positive");
    const hmap::KittiSequence seq = hmap::open_kitti_sequence(argv[1]);
    if (!seq.T_map_scan) throw std::runtime_error("the sequence has no poses.txt");
    const hmap::PoseList& poses = *seq.T_map_scan;
    hmap::ParamSources sources;
    sources.preset.clear();  // chosen from the first scan, as hmap map does
    const hmap::PointCloud first = hmap::read_kitti_bin(seq.scan_paths.at(0));
    const hmap::Params params = hmap::resolve_params_for_scan(sources, first).params;
    hmap::HybridMapper hybrid(params);
    std::printf("%zu scans; cell %.3f m, range %.1f-%.1f m\n", seq.scan_paths.size(), params.map.cell_size,
                params.map.min_range, params.map.max_range);
    std::printf("| path [km] | scans | CPU per scan, read + map [ms] | main thread in integrate [ms] | HVoxels | HMAP memory [MiB] | "
                "2D grid [MiB] | ground patches | peak RSS [MiB] |\n| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n");
    double path = 0.0;
    double next_mark = segment_m;
    std::size_t segment_scans = 0;
    double cpu0 = process_cpu_s();
    double map_cpu = 0.0;
    const auto row = [&] {
      const double cpu = process_cpu_s();
      const hmap::MapStats st = hybrid.map().stats();
      std::printf("| %.2f | %zu | %.2f | %.2f | %zu | %.2f | %.2f | %zu | %.1f |\n", path / 1000.0, segment_scans,
                  1000.0 * (cpu - cpu0) / static_cast<double>(segment_scans),
                  1000.0 * map_cpu / static_cast<double>(segment_scans), st.hvoxels,
                  static_cast<double>(st.memory_bytes) / 1048576.0,
                  static_cast<double>(hybrid.grid().memory_bytes()) / 1048576.0, hybrid.ground_patches().size(),
                  peak_rss_mib());
      std::fflush(stdout);
      cpu0 = cpu;
      map_cpu = 0.0;
      segment_scans = 0;
    };
    for (std::size_t k = 0; k < seq.scan_paths.size(); ++k) {
      const hmap::PointCloud cloud = k == 0 ? first : hmap::read_kitti_bin(seq.scan_paths[k]);
      if (k > 0) path += (poses[k].translation() - poses[k - 1].translation()).norm();
      const double t0 = thread_cpu_s();
      (void)hybrid.integrate(cloud, poses[k]);
      map_cpu += thread_cpu_s() - t0;
      ++segment_scans;
      if (path >= next_mark) {
        row();
        next_mark += segment_m;
      }
    }
    if (segment_scans > 0) row();
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "hmap_drive_cost: %s\n", e.what());
    return 2;
  }
}
