#include "hmap/io/cloud_reader.hpp"

#include <algorithm>
#include <cctype>
#include <string>

#include "hmap/core/error.hpp"
#include "hmap/io/kitti.hpp"
#include "hmap/io/pcd.hpp"
#include "hmap/io/ply.hpp"
#include "hmap/io/vtk.hpp"
#include "hmap/io/xyz.hpp"

namespace hmap {

PointCloud read_cloud(const std::filesystem::path& path, CloudReadStats* stats, std::vector<float>* times_s,
                      const MemoryBudget* budget) {
  if (times_s != nullptr) times_s->clear();
  std::string extension = path.extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (extension == ".pcd") return read_pcd(path, stats, times_s, budget);
  if (extension == ".ply") return read_ply(path, stats);
  if (extension == ".bin") return read_kitti_bin(path, stats);
  if (extension == ".vtk") return read_vtk(path, stats);
  if (extension == ".xyz" || extension == ".txt" || extension == ".csv" || extension == ".pts") {
    return read_xyz(path, stats);
  }
  throw InputError(path.string(), "",
                   "unknown point cloud extension " +
                       (extension.empty() ? std::string("(none)") : "'" + extension + "'") +
                       "; expected .pcd, .ply, .bin, .xyz, .txt, .csv, .pts or .vtk");
}

}  // namespace hmap
