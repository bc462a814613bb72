#pragma once
// The memory an input may make hmap allocate. What a file or a parameter asks for (a map that
// spans 100 km exported as points, a noisy scan that touches a new voxel block per point) is
// estimated before it is allocated, or counted while it grows, and refused with a message when it
// exceeds the budget: a clear error instead of the kernel's OOM killer or std::bad_alloc.

#include <cmath>
#include <cstddef>
#include <string>

#include "hmap/core/error.hpp"
#include "hmap/core/format.hpp"

namespace hmap {

struct MemoryBudget {
  /// 2 GiB: a hundred times what mapping 3200 real scans holds (docs/RELIABILITY.md), below the
  /// memory of a small robot computer. The CLI sets it with `hmap --max-memory MIB`.
  static constexpr std::size_t kDefaultBytes = std::size_t{2} << 30;
  std::size_t bytes = kDefaultBytes;

  /// Throws hmap::Error when `needed` bytes (an estimate; NaN and infinity refused too) exceed
  /// the budget; `what` says what asked for them ("the points of export --points").
  void require(double needed, const std::string& what) const {
    if (needed <= static_cast<double>(bytes)) return;
    throw Error(what + " needs " + (std::isfinite(needed) ? format("%.0f MiB", std::ceil(needed / 1048576.0)) : "unbounded memory") +
                ", more than the memory budget of " + format("%.0f MiB", static_cast<double>(bytes) / 1048576.0) +
                " (hmap --max-memory MIB)");
  }
};

}  // namespace hmap
