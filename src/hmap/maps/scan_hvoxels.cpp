#include "hmap/maps/scan_hvoxels.hpp"

#include <algorithm>
#include <cmath>

#include "hmap/core/error.hpp"

namespace hmap {

ScanHVoxelizer::ScanHVoxelizer(const MapParams& params) : params_(params) {
  window_.half = static_cast<std::int32_t>(std::ceil(params_.max_range / params_.cell_size)) + 1;
  window_.width = 2 * window_.half + 1;
  cell_of_window_.assign(window_.cells(), 0);
}

void ScanHVoxelizer::build(std::span<const Point3f> points_sensor, const Pose& T_map_sensor,
                           ScanHVoxels& out) {
  if (!T_map_sensor.matrix().allFinite()) throw Error("scan pose is not finite");
  index_points(points_sensor, T_map_sensor, out);
  cluster_heights(out);
}

void ScanHVoxelizer::index_points(std::span<const Point3f> points_sensor, const Pose& T_map_sensor,
                                  ScanHVoxels& out) {
  for (std::size_t w : used_windows_) cell_of_window_[w] = 0;
  used_windows_.clear();
  out.cells.clear();
  out.hvoxels.clear();
  out.points_in = points_sensor.size();
  out.points_kept = out.dropped_non_finite = out.dropped_range = 0;
  point_cell_.clear();
  point_z_.clear();

  const double cell = params_.cell_size;
  const Eigen::Vector3d origin = T_map_sensor.translation();
  out.origin_map = origin;
  if (std::abs(origin.x() / cell) > 1e9 || std::abs(origin.y() / cell) > 1e9) {
    throw Error("scan pose is too far from the map origin (beyond 10^9 cells)");
  }
  window_.center = {static_cast<std::int32_t>(std::floor(origin.x() / cell)),
                    static_cast<std::int32_t>(std::floor(origin.y() / cell))};
  out.window = window_;
  const Eigen::Matrix3d R = T_map_sensor.linear();
  const auto min_r2 = static_cast<float>(params_.min_range * params_.min_range);
  const auto max_r2 = static_cast<float>(params_.max_range * params_.max_range);

  for (const Point3f& p_sensor : points_sensor) {
    if (!p_sensor.allFinite()) {
      ++out.dropped_non_finite;
      continue;
    }
    const float r2 = p_sensor.squaredNorm();
    if (r2 < min_r2 || r2 > max_r2) {
      ++out.dropped_range;
      continue;
    }
    // 2D indexing in the gravity-aligned map frame (convertToMapIndex, withinMapBounds).
    const Eigen::Vector3d p_map = R * p_sensor.cast<double>() + origin;
    const CellKey key{static_cast<std::int32_t>(std::floor(p_map.x() / cell)),
                      static_cast<std::int32_t>(std::floor(p_map.y() / cell))};
    if (!window_.contains(key)) {  // only float rounding at the range limit can get here
      ++out.dropped_range;
      continue;
    }
    const std::size_t w = window_.index(key);
    std::uint32_t& slot = cell_of_window_[w];
    if (slot == 0) {
      out.cells.push_back({key, 0, 0});
      slot = static_cast<std::uint32_t>(out.cells.size());
      used_windows_.push_back(w);
    }
    point_cell_.push_back(slot - 1);
    point_z_.push_back(static_cast<float>(p_map.z()));
  }
  out.points_kept = point_z_.size();
}

void ScanHVoxelizer::cluster_heights(ScanHVoxels& out) {
  // Counting sort of the kept heights by cell: each cell's heights become one contiguous slice.
  const std::size_t n_cells = out.cells.size();
  cell_offset_.assign(n_cells + 1, 0);
  for (std::uint32_t c : point_cell_) ++cell_offset_[c + 1];
  for (std::size_t c = 0; c < n_cells; ++c) cell_offset_[c + 1] += cell_offset_[c];
  sorted_z_.resize(point_z_.size());
  {
    // cell_offset_[c] is used as the write cursor of cell c, then restored.
    for (std::size_t k = 0; k < point_z_.size(); ++k) {
      sorted_z_[cell_offset_[point_cell_[k]]++] = point_z_[k];
    }
    for (std::size_t c = n_cells; c > 0; --c) cell_offset_[c] = cell_offset_[c - 1];
    cell_offset_[0] = 0;
  }

  const auto gap = static_cast<float>(params_.point_distance_threshold);
  for (std::size_t c = 0; c < n_cells; ++c) {
    float* z = sorted_z_.data() + cell_offset_[c];
    float* z_end = sorted_z_.data() + cell_offset_[c + 1];
    if (z_end - z <= 16) {  // most cells hold a few points: insertion sort wins
      for (float* a = z + 1; a < z_end; ++a) {
        const float value = *a;
        float* b = a;
        for (; b > z && *(b - 1) > value; --b) *b = *(b - 1);
        *b = value;
      }
    } else {
      std::sort(z, z_end);
    }
    ScanCell& cell = out.cells[c];
    cell.first = static_cast<std::uint32_t>(out.hvoxels.size());
    // HeightClustering: a new segment starts where the gap exceeds the threshold.
    float* segment = z;
    for (float* it = z + 1; it <= z_end; ++it) {
      if (it == z_end || *it - *(it - 1) > gap) {
        HVoxel v{*segment, *(it - 1), static_cast<float>(it - segment), 0.0F};
        update_density(v, params_);  // eq. (1)
        out.hvoxels.push_back(v);
        segment = it;
      }
    }
    cell.count = static_cast<std::uint32_t>(out.hvoxels.size()) - cell.first;
  }
}

}  // namespace hmap
