#include "hmap/io/octomap_export.hpp"

#include <octomap/OcTree.h>

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <cstdio>
#include <iostream>
#include <sstream>

#include "hmap/core/error.hpp"
#include "hmap/core/format.hpp"
#include "hmap/io/atomic_file.hpp"
#include "hmap/occupancy/traversability.hpp"

namespace hmap {

namespace {

/// OctoMap's coordToKeyChecked casts the scaled coordinate to int before it checks the range:
/// undefined for a coordinate beyond ±2^31 cells (an HVoxel at 1e39 m, clang's UBSan). The key
/// range (±32768 cells) is checked here first, NaN included.
bool key_checked(const octomap::OcTree& tree, double x, double y, double z, octomap::OcTreeKey& key) {
  const double limit = 32768.0 * tree.getResolution();
  if (!(std::abs(x) < limit && std::abs(y) < limit && std::abs(z) < limit)) return false;
  return tree.coordToKeyChecked(x, y, z, key);
}

/// Sends file descriptor 2 to /dev/null for its lifetime (liboctomap prints with fprintf too).
class QuietStderr {
 public:
  QuietStderr() : saved_(::dup(STDERR_FILENO)) {
    std::fflush(stderr);
    std::cerr.flush();
    const int null = ::open("/dev/null", O_WRONLY);
    if (null >= 0) {
      ::dup2(null, STDERR_FILENO);
      ::close(null);
    }
  }
  ~QuietStderr() {
    std::fflush(stderr);
    std::cerr.flush();
    if (saved_ >= 0) {
      ::dup2(saved_, STDERR_FILENO);
      ::close(saved_);
    }
  }
  QuietStderr(const QuietStderr&) = delete;
  QuietStderr& operator=(const QuietStderr&) = delete;

 private:
  int saved_;
};

}  // namespace

OctomapExportStats write_octomap_bt(const std::filesystem::path& path, const HMap& map, std::span<const FreeBand> free,
                                    const MemoryBudget& budget) {
  const double res = map.cell_size();
  octomap::OcTree tree(res);
  // Leaves whose vertical extent meets [z_min, z_max]: keys floor(z_min / res) .. floor(z_max / res).
  // Counted first, in doubles: an HVoxel at 3e38 m made `z += res` loop forever, and a small map
  // spanning 100 km asked for gigabytes of leaves.
  double leaves_needed = 0.0;
  std::size_t beyond = 0;
  map.for_each_column([&](const CellKey& key, const ColumnView& column) {
    const Eigen::Vector2d xy = map.cell_center(key);
    for (const HVoxel& v : column) {
      octomap::OcTreeKey k;
      const bool inside = key_checked(tree, xy.x(), xy.y(), v.z_min, k) && key_checked(tree, xy.x(), xy.y(), v.z_max, k);
      if (!inside) {
        ++beyond;
        continue;
      }
      leaves_needed += std::floor(v.z_max / res) - std::floor(v.z_min / res) + 1.0;
    }
  });
  for (const FreeBand& band : free) {
    const Eigen::Vector2d xy = map.cell_center(band.key);
    octomap::OcTreeKey k;
    if (!(band.z_high > band.z_low) || !key_checked(tree, xy.x(), xy.y(), band.z_low, k) ||
        !key_checked(tree, xy.x(), xy.y(), band.z_high, k)) {
      continue;  // free space beyond the key range is left unknown, not refused: it is not the map
    }
    leaves_needed += std::floor(band.z_high / res) - std::floor(band.z_low / res);
  }
  if (beyond > 0) {
    throw Error(path.string() + ": " + std::to_string(beyond) + " HVoxels lie beyond OctoMap's key range (+-" +
                format("%g", 32768.0 * res) + " m at " + format("%g", res) +
                " m resolution), which OctoMap would drop; nothing written");
  }
  // About 100 bytes per leaf before pruning: the node, and its share of the inner nodes' child arrays.
  budget.require(leaves_needed * 100.0, path.string() + ": " + format("%.0f", leaves_needed) + " OctoMap leaves");
  OctomapExportStats stats;
  // Free first, occupied after: a leaf of both is occupied. Values are set, not added, so equal
  // siblings prune.
  const float free_value = tree.getClampingThresMinLog();
  for (const FreeBand& band : free) {
    const Eigen::Vector2d xy = map.cell_center(band.key);
    octomap::OcTreeKey k;
    if (!(band.z_high > band.z_low) || !key_checked(tree, xy.x(), xy.y(), band.z_low, k) ||
        !key_checked(tree, xy.x(), xy.y(), band.z_high, k)) {
      continue;
    }
    const auto first = static_cast<long>(std::floor(band.z_low / res)) + 1;  // (z_low, z_high]
    const auto last = static_cast<long>(std::floor(band.z_high / res));
    for (long z = first; z <= last; ++z) {
      const double zc = (static_cast<double>(z) + 0.5) * res;
      tree.setNodeValue(octomap::point3d(static_cast<float>(xy.x()), static_cast<float>(xy.y()), static_cast<float>(zc)),
                        free_value, /*lazy_eval=*/true);
    }
  }
  map.for_each_column([&](const CellKey& key, const ColumnView& column) {
    const Eigen::Vector2d xy = map.cell_center(key);
    // Two HVoxels of a column may reach into the same leaf: counted once (they are sorted upwards).
    long written_up_to = std::numeric_limits<long>::min();
    for (const HVoxel& v : column) {
      const auto first = static_cast<long>(std::floor(v.z_min / res));  // inside the key range: checked above
      const auto last = static_cast<long>(std::floor(v.z_max / res));
      for (long k = first; k <= last; ++k) {
        const double z = (static_cast<double>(k) + 0.5) * res;
        tree.setNodeValue(octomap::point3d(static_cast<float>(xy.x()), static_cast<float>(xy.y()), static_cast<float>(z)),
                          tree.getClampingThresMaxLog(), /*lazy_eval=*/true);
        if (k > written_up_to) ++stats.occupied_voxels;
        written_up_to = std::max(written_up_to, k);
      }
    }
  });
  tree.updateInnerOccupancy();
  tree.prune();
  stats.leaves = tree.getNumLeafNodes();
  // Free voxels as written: the free leaves' volume in voxels of the map's cell.
  double free_volume = 0.0;
  for (auto it = tree.begin_leafs(); it != tree.end_leafs(); ++it) {
    if (!tree.isNodeOccupied(*it)) free_volume += std::pow(it.getSize() / res, 3.0);
  }
  stats.free_voxels = static_cast<std::size_t>(std::llround(free_volume));
  write_file_atomic(path, [&](std::ostream& out) {
    // liboctomap reports progress on stderr; keep the terminal to our own one-line messages.
    bool ok = false;
    {
      const QuietStderr quiet;
      ok = tree.writeBinary(out);
    }
    if (!ok) throw Error("OctoMap could not serialise the tree");
  });
  return stats;
}

std::vector<FreeBand> free_bands(const OccupancyGrid& grid, std::span<const GroundPatch> ground, double z_plus) {
  std::vector<FreeBand> bands;
  if (ground.empty()) return bands;
  const TraversabilityLayers layers =
      traversability(grid, GroundModel(std::vector<GroundPatch>(ground.begin(), ground.end())), TraversabilityParams{});
  grid.for_each_cell([&](const CellKey& key, float l) {
    if (!(l < 0.0F)) return;
    const std::int64_t col = static_cast<std::int64_t>(key.i) - layers.i_min;
    const std::int64_t row = static_cast<std::int64_t>(key.j) - layers.j_min;
    if (col < 0 || row < 0 || col >= layers.width || row >= layers.height) return;
    const float z = layers.ground_z[layers.index(static_cast<std::int32_t>(col), static_cast<std::int32_t>(row))];
    if (std::isnan(z)) return;
    bands.push_back({key, static_cast<double>(z), static_cast<double>(z) + z_plus});
  });
  return bands;
}

}  // namespace hmap
