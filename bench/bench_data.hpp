#pragma once
// What the benchmarks share: the real scans ($HMAP_DATA_DIR, default ../shared/data) and the
// HDL-64 parameters every per-scan figure of BENCHMARKS.md is measured at.

#include <cstdlib>
#include <filesystem>
#include <vector>

#include "hmap/core/params.hpp"
#include "hmap/io/config.hpp"
#include "hmap/io/kitti.hpp"

namespace hmap::bench {

inline std::filesystem::path data_dir() {
  if (const char* env = std::getenv("HMAP_DATA_DIR"); env != nullptr && *env != '\0') return env;
  return HMAP_DEFAULT_DATA_DIR;
}

/// The 16 HDL-64 scans of kitti_hdl64_seq16, read once; empty when the set is absent.
inline const std::vector<PointCloud>& hdl64_scans() {
  static const std::vector<PointCloud> scans = [] {
    std::vector<PointCloud> out;
    const auto dir = data_dir() / "kitti_hdl64_seq16";
    if (!std::filesystem::exists(dir)) return out;
    const auto seq = open_kitti_sequence(dir);
    for (const auto& p : seq.scan_paths) out.push_back(read_kitti_bin(p));
    return out;
  }();
  return scans;
}

/// The outdoor preset at 0.2 m cells and 50 m range.
inline Params hdl64_params() {
  Params p = outdoor_preset();
  p.map.cell_size = 0.2;
  p.map.max_range = 50.0;
  return p;
}

/// What `hmap slam --cell 0.2` runs with on these scans: the preset and the defaults chosen from
/// the first scan (the outdoor preset's 25 m range, the ring spacing's height gap), at 0.2 m.
inline Params hdl64_defaults_at_0_2() {
  const auto& scans = hdl64_scans();
  if (scans.empty()) return hdl64_params();
  ParamSources sources;
  sources.cell_size = 0.2;
  return resolve_params_for_scan(sources, scans.front()).params;
}

}  // namespace hmap::bench
