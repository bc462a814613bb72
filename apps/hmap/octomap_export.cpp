#include "octomap_export.hpp"

#include <octomap/OcTree.h>

#include <fcntl.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <iostream>
#include <sstream>

#include "hmap/core/error.hpp"
#include "hmap/core/format.hpp"
#include "hmap/io/atomic_file.hpp"

namespace hmap::cli {

namespace {

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

std::size_t write_octomap_bt(const std::filesystem::path& path, const HMap& map, const MemoryBudget& budget) {
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
      const bool inside = tree.coordToKeyChecked(xy.x(), xy.y(), v.z_min, k) && tree.coordToKeyChecked(xy.x(), xy.y(), v.z_max, k);
      if (!inside) {
        ++beyond;
        continue;
      }
      leaves_needed += std::floor(v.z_max / res) - std::floor(v.z_min / res) + 1.0;
    }
  });
  if (beyond > 0) {
    throw Error(path.string() + ": " + std::to_string(beyond) + " HVoxels lie beyond OctoMap's key range (+-" +
                format("%g", 32768.0 * res) + " m at " + format("%g", res) +
                " m resolution), which OctoMap would drop; nothing written");
  }
  // About 100 bytes per leaf before pruning: the node, and its share of the inner nodes' child arrays.
  budget.require(leaves_needed * 100.0, path.string() + ": " + format("%.0f", leaves_needed) + " OctoMap leaves");
  std::size_t leaves = 0;
  map.for_each_column([&](const CellKey& key, const ColumnView& column) {
    const Eigen::Vector2d xy = map.cell_center(key);
    for (const HVoxel& v : column) {
      const auto first = static_cast<long>(std::floor(v.z_min / res));  // inside the key range: checked above
      const auto last = static_cast<long>(std::floor(v.z_max / res));
      for (long k = first; k <= last; ++k) {
        const double z = (static_cast<double>(k) + 0.5) * res;
        tree.updateNode(octomap::point3d(static_cast<float>(xy.x()), static_cast<float>(xy.y()), static_cast<float>(z)),
                        tree.getClampingThresMaxLog(), /*lazy_eval=*/true);
        ++leaves;
      }
    }
  });
  tree.updateInnerOccupancy();
  tree.prune();
  write_file_atomic(path, [&](std::ostream& out) {
    // liboctomap reports progress on stderr; keep the terminal to our own one-line messages.
    bool ok = false;
    {
      const QuietStderr quiet;
      ok = tree.writeBinary(out);
    }
    if (!ok) throw Error("OctoMap could not serialise the tree");
  });
  return leaves;
}

}  // namespace hmap::cli
