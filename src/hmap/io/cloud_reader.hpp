#pragma once
// One entry point for every point cloud format hmap reads, chosen by file extension.

#include <filesystem>
#include <vector>

#include "hmap/core/budget.hpp"
#include "hmap/core/types.hpp"
#include "hmap/io/cloud_stats.hpp"

namespace hmap {

/// Reads a point cloud by its extension, in any letter case: .pcd (read_pcd), .ply (read_ply),
/// .bin (read_kitti_bin), .xyz .txt .csv .pts (read_xyz), .vtk (read_vtk). Throws InputError for another extension.
/// `times_s` given: each point's time [s] for a PCD with a t / time / timestamp field (read_pcd),
/// empty for every other file. `budget`: what read_pcd checks against it (a compressed PCD's
/// decompressed points); the other formats hold no more points than their files' bytes allow.
[[nodiscard]] PointCloud read_cloud(const std::filesystem::path& path, CloudReadStats* stats = nullptr,
                                    std::vector<float>* times_s = nullptr, const MemoryBudget* budget = nullptr);

}  // namespace hmap
