#include "hmap/maps/extrusion.hpp"

#include <algorithm>

namespace hmap {

namespace {

template <typename EditableColumn>
void apply_rules(EditableColumn& column, const FreeHVoxel& f, const MapParams& p, ExtrusionCounts& counts) {
  const auto n_th = static_cast<float>(p.density_threshold);
  std::size_t i = column.lower_bound(f.z_min);
  float free_density = -1.0F;  // eq. (1) for the free HVoxel, computed once it overlaps something
  while (i < column.size() && column[i].z_min <= f.z_max) {
    HVoxel v = column[i];
    const float h = v.height();
    const float overlap = std::min(v.z_max, f.z_max) - std::max(v.z_min, f.z_min);
    if (h > 0.0F && overlap <= 0.0F) {  // touching at one height only: rule 1
      ++i;
      continue;
    }
    const float d = h > 0.0F ? overlap / h : 1.0F;  // overlapped fraction of v's height
    if (free_density < 0.0F) free_density = hvoxel_density(f.rays, f.z_max - f.z_min, p);
    const bool inside = f.z_min > v.z_min && f.z_max < v.z_max;
    if (inside) {
      if (free_density < v.density) {  // rule 4: subdivide around the free HVoxel
        HVoxel lower{v.z_min, f.z_min, v.count * (f.z_min - v.z_min) / h, 0.0F};
        HVoxel upper{f.z_max, v.z_max, v.count * (v.z_max - f.z_max) / h, 0.0F};
        update_density(lower, p);
        update_density(upper, p);
        column[i] = lower;
        column.insert(i + 1, upper);
        ++counts.subdivided;
        i += 2;
      } else {  // rule 4: update
        v.count = std::max(0.0F, v.count - d * f.rays);
        update_density(v, p);
        column[i] = v;
        ++counts.updated;
        ++i;
      }
      continue;
    }
    bool remove_overlap = free_density >= v.density;  // rule 3
    if (!remove_overlap) {                              // rule 2
      v.count = std::max(0.0F, v.count - d * f.rays);
      update_density(v, p);
      ++counts.updated;
      remove_overlap = v.density < n_th;
    }
    if (remove_overlap) {
      if (f.z_min <= v.z_min && f.z_max >= v.z_max) {  // wholly covered
        column.erase(i, i + 1);
        ++counts.removed;
        continue;
      }
      v.count *= 1.0F - d;
      if (f.z_min <= v.z_min) {
        v.z_min = f.z_max;  // the bottom was free: keep the top
      } else {
        v.z_max = f.z_min;  // the top was free: keep the bottom
      }
      update_density(v, p);
      ++counts.trimmed;
    }
    column[i] = v;
    ++i;
  }
}

}  // namespace

template <typename EditableColumn>
void extrude(EditableColumn& column, std::span<const FreeHVoxel> free, const MapParams& p,
             ExtrusionCounts& counts) {
  if (column.empty() || free.empty()) return;
  for (const FreeHVoxel& f : free) apply_rules(column, f, p, counts);
  // After the rules: the HVoxels the free space reached that are now under n_th go.
  const auto n_th = static_cast<float>(p.density_threshold);
  for (std::size_t i = 0; i < column.size();) {
    const HVoxel v = column[i];
    const bool reached = std::any_of(free.begin(), free.end(), [&](const FreeHVoxel& f) {
      return v.z_min <= f.z_max && v.z_max >= f.z_min;
    });
    if (reached && v.density < n_th) {
      column.erase(i, i + 1);
      ++counts.removed;
    } else {
      ++i;
    }
  }
}

template void extrude(TileColumn&, std::span<const FreeHVoxel>, const MapParams&, ExtrusionCounts&);
template void extrude(Column&, std::span<const FreeHVoxel>, const MapParams&, ExtrusionCounts&);

}  // namespace hmap
