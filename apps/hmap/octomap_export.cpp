#include "octomap_export.hpp"

#include <octomap/OcTree.h>

#include <fcntl.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <iostream>
#include <sstream>

#include "hmap/core/error.hpp"
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

std::size_t write_octomap_bt(const std::filesystem::path& path, const HMap& map) {
  const double res = map.cell_size();
  octomap::OcTree tree(res);
  std::size_t leaves = 0;
  map.for_each_column([&](const CellKey& key, const ColumnView& column) {
    const Eigen::Vector2d xy = map.cell_center(key);
    for (const HVoxel& v : column) {
      // Leaves whose vertical extent meets [z_min, z_max]: centres every res from the first one.
      const double first = (std::floor(v.z_min / res) + 0.5) * res;
      for (double z = first; z - 0.5 * res <= v.z_max; z += res) {
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
