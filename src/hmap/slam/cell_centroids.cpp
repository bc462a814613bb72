#include "hmap/slam/cell_centroids.hpp"

#include <cmath>

#include "hmap/core/checked.hpp"
#include "hmap/core/error.hpp"
#include "hmap/core/format.hpp"

namespace hmap::slam {

CellCentroids::CellCentroids(double cell_size) : cell_(cell_size) {
  if (!(cell_size > 0.0) || !std::isfinite(cell_size)) throw Error(format("cell centroids: the cell %g m is not positive", cell_size));
}

void CellCentroids::add(const ScanHVoxels& scan, double x, double y, double yaw, float min_height) {
  if (scan.centroids.size() != scan.hvoxels.size()) return;
  const double c = std::cos(yaw);
  const double s = std::sin(yaw);
  for (std::size_t k = 0; k < scan.hvoxels.size(); ++k) {
    const HVoxel& h = scan.hvoxels[k];
    if (h.height() < min_height || !(h.count > 0.0F)) continue;
    const Eigen::Vector2d v = scan.centroids[k].cast<double>();
    add(x + c * v.x() - s * v.y(), y + s * v.x() + c * v.y(), h.count);
  }
}

void CellCentroids::add(double x, double y, double weight) {
  if (!(weight > 0.0) || !std::isfinite(x) || !std::isfinite(y)) return;
  const CellKey key{checked_floor<std::int32_t>(x / cell_, "a centroid's cell"), checked_floor<std::int32_t>(y / cell_, "a centroid's cell")};
  Cell& cell = cells_.try_emplace(key).first->second;
  cell.sums += Eigen::Vector3d(weight * x, weight * y, weight);
  cell.offset = Eigen::Vector2f(static_cast<float>(cell.sums.x() / cell.sums.z() - (key.i + 0.5) * cell_),
                                static_cast<float>(cell.sums.y() / cell.sums.z() - (key.j + 0.5) * cell_));
}

}  // namespace hmap::slam
