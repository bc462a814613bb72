#include "hmap/slam/cell_centroids.hpp"

#include <algorithm>
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
  if (!(weight > 0.0) || !std::isfinite(weight) || !std::isfinite(x) || !std::isfinite(y)) return;
  const CellKey key{checked_floor<std::int32_t>(x / cell_, "a centroid's cell"), checked_floor<std::int32_t>(y / cell_, "a centroid's cell")};
  Tile& tile = tiles_.find_or_create(tile_of(key));
  const std::size_t local = local_index(key);
  Eigen::Vector3d& sums = tile.sums[local];
  if (sums.z() == 0.0) ++cells_;
  sums += Eigen::Vector3d(weight * x, weight * y, weight);
  tile.offset[local] = Eigen::Vector2f(static_cast<float>(sums.x() / sums.z() - (key.i + 0.5) * cell_),
                                       static_cast<float>(sums.y() / sums.z() - (key.j + 0.5) * cell_));
}

void CellCentroids::View::reset(const CellCentroids* source, const CellKey& center, std::int32_t half_cells) {
  source_ = source;
  tiles_wide_ = 0;
  tiles_.clear();
  if (source == nullptr) return;
  const CellKey lo = tile_of({center.i - half_cells, center.j - half_cells});
  const CellKey hi = tile_of({center.i + half_cells, center.j + half_cells});
  tile_min_ = lo;
  tiles_wide_ = std::max(hi.i - lo.i, hi.j - lo.j) + 1;
  tiles_.assign(static_cast<std::size_t>(tiles_wide_) * static_cast<std::size_t>(tiles_wide_), nullptr);
  for (std::int32_t ti = 0; ti < tiles_wide_; ++ti) {
    for (std::int32_t tj = 0; tj < tiles_wide_; ++tj) {
      tiles_[static_cast<std::size_t>(ti) * static_cast<std::size_t>(tiles_wide_) + static_cast<std::size_t>(tj)] =
          source->tiles_.find({lo.i + ti, lo.j + tj});
    }
  }
}

}  // namespace hmap::slam
