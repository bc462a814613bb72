#include "hmap/maps/cell_centroids.hpp"

#include <cmath>
#include <vector>

#include "hmap/core/checked.hpp"
#include "hmap/core/error.hpp"
#include "hmap/core/format.hpp"

namespace hmap {

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

void CellCentroids::add(const CellCentroids& other, double x, double y, double yaw) {
  if (other.cell_ != cell_) {
    throw Error(format("cell centroids: adding %g m cells' centroids to %g m ones", other.cell_, cell_));
  }
  // Read whole before the first add: `other` may be this.
  std::vector<Eigen::Vector3d> points;
  points.reserve(other.size());
  other.for_each([&](const CellKey& k, const Eigen::Vector2f& offset, double weight) {
    points.emplace_back((k.i + 0.5) * other.cell_ + static_cast<double>(offset.x()),
                        (k.j + 0.5) * other.cell_ + static_cast<double>(offset.y()), weight);
  });
  const double c = std::cos(yaw);
  const double s = std::sin(yaw);
  for (const Eigen::Vector3d& p : points) add(x + c * p.x() - s * p.y(), y + s * p.x() + c * p.y(), p.z());
}

void CellCentroids::restore(const CellKey& cell, const Eigen::Vector2f& offset, double weight) {
  const float half = static_cast<float>(0.5 * cell_);
  if (!offset.allFinite() || std::abs(offset.x()) > half || std::abs(offset.y()) > half) {
    throw Error(format("cell centroids: cell (%d, %d)'s offset (%g, %g) m is not within half a cell (%g m)", cell.i, cell.j,
                       static_cast<double>(offset.x()), static_cast<double>(offset.y()), static_cast<double>(half)));
  }
  if (!(weight > 0.0) || !std::isfinite(weight)) {
    throw Error(format("cell centroids: cell (%d, %d)'s weight %g is not positive and finite", cell.i, cell.j, weight));
  }
  Tile& tile = tiles_.find_or_create(tile_of(cell));
  const std::size_t local = local_index(cell);
  if (in(tile, local) != nullptr) throw Error(format("cell centroids: cell (%d, %d) has a centroid already", cell.i, cell.j));
  ++cells_;
  // The sums a centroid at the offset would have; the offset itself as given, so that it reads
  // back exactly.
  tile.sums[local] = Eigen::Vector3d(weight * ((cell.i + 0.5) * cell_ + static_cast<double>(offset.x())),
                                     weight * ((cell.j + 0.5) * cell_ + static_cast<double>(offset.y())), weight);
  tile.offset[local] = offset;
}

void CellCentroids::View::reset(const CellCentroids* source, const CellKey& center, std::int32_t half_cells) {
  source_ = source;
  tiles_wide_ = 0;
  tiles_.clear();
  if (source == nullptr) return;
  tile_window<Tile>(center, half_cells, kTileBits, [source](const CellKey& t) { return source->tiles_.find(t); }, tile_min_,
                    tiles_wide_, tiles_);
}

}  // namespace hmap
