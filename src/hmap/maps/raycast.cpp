#include "hmap/maps/raycast.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "hmap/core/error.hpp"
#include "hmap/core/format.hpp"

namespace hmap {

namespace {

/// The first t in [t0, t1] at which z0 + t·dz lies in one of the column's HVoxels (bounds
/// included), or nullopt. The column is sorted by height with gaps between its HVoxels.
std::optional<std::pair<double, const HVoxel*>> first_in_column(const ColumnView& column, double z0, double dz, double t0,
                                                                double t1) {
  if (column.empty()) return std::nullopt;
  // The ray's height span within the cell, and the HVoxels that overlap it.
  const double za = z0 + t0 * dz;
  const double zb = z0 + t1 * dz;
  const double lo = std::min(za, zb);
  const double hi = std::max(za, zb);
  std::optional<std::pair<double, const HVoxel*>> best;
  for (const HVoxel& v : column.hvoxels()) {
    if (static_cast<double>(v.z_max) < lo || static_cast<double>(v.z_min) > hi) continue;
    double t = t0;  // the ray starts within the HVoxel's heights (or runs level through them)
    if (za < static_cast<double>(v.z_min)) {
      t = (static_cast<double>(v.z_min) - z0) / dz;  // rising into it from below
    } else if (za > static_cast<double>(v.z_max)) {
      t = (static_cast<double>(v.z_max) - z0) / dz;  // falling into it from above
    }
    t = std::clamp(t, t0, t1);
    if (!best || t < best->first) best = std::pair{t, &v};
  }
  return best;
}

}  // namespace

std::optional<RayHit> raycast(const HMap& map, const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                              double max_range) {
  if (!origin.allFinite()) throw Error("raycast: the origin must be finite");
  if (!direction.allFinite() || direction.norm() == 0.0) throw Error("raycast: the direction must be finite and not zero");
  if (!(max_range >= 0.0 && max_range <= 1e6)) throw Error(format("raycast: max_range %g m is outside [0, 1e6]", max_range));
  const Eigen::Vector3d d = direction.normalized();
  const double s = map.cell_size();
  const auto start = map.key_of(origin.x(), origin.y());
  if (!start) throw Error("raycast: the origin lies beyond the map's key range");
  // The walk in the plane: tMax the ray parameter at the next border in x and y, tDelta a cell's.
  CellKey key = *start;
  const int step_i = d.x() > 0.0 ? 1 : (d.x() < 0.0 ? -1 : 0);
  const int step_j = d.y() > 0.0 ? 1 : (d.y() < 0.0 ? -1 : 0);
  const double inf = std::numeric_limits<double>::infinity();
  const auto first_border = [&](double o, int k, int step, double dv) {
    if (step == 0) return inf;
    const double border = (step > 0 ? (k + 1) : k) * s;
    return (border - o) / dv;
  };
  double t_next_i = first_border(origin.x(), key.i, step_i, d.x());
  double t_next_j = first_border(origin.y(), key.j, step_j, d.y());
  const double delta_i = step_i != 0 ? s / std::abs(d.x()) : inf;
  const double delta_j = step_j != 0 ? s / std::abs(d.y()) : inf;
  double t = 0.0;
  // At most this many cells: every cell crossed moves one border on.
  const double cells = 2.0 + max_range / s * (std::abs(d.x()) + std::abs(d.y()));
  for (double visited = 0.0; visited <= cells + 1.0; visited += 1.0) {
    const double t_exit = std::min({t_next_i, t_next_j, max_range});
    if (const auto hit = first_in_column(map.column(key), origin.z(), d.z(), t, t_exit)) {
      RayHit h;
      h.range = hit->first;
      h.point = origin + h.range * d;
      h.cell = key;
      h.hvoxel = *hit->second;
      return h;
    }
    if (t_exit >= max_range) return std::nullopt;
    t = t_exit;
    if (t_next_i <= t_next_j) {
      key.i += step_i;
      t_next_i += delta_i;
      if (t_next_j == t) {  // through a corner: both borders at once
        key.j += step_j;
        t_next_j += delta_j;
      }
    } else {
      key.j += step_j;
      t_next_j += delta_j;
    }
    if (std::abs(static_cast<double>(key.i)) >= HMap::kMaxKey || std::abs(static_cast<double>(key.j)) >= HMap::kMaxKey) {
      return std::nullopt;
    }
  }
  return std::nullopt;
}

}  // namespace hmap
