#pragma once
// Plain types shared by every hmap library: points, poses, grid keys.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <vector>

namespace hmap {

/// A 3D point in metres. Single precision: sensors measure to millimetres, and a map spans kilometres.
using Point3f = Eigen::Vector3f;
/// A point cloud in one frame; the frame is carried by the variable's name (points_sensor, points_map).
using PointCloud = std::vector<Point3f>;
/// A rigid transform; named by its frames, T_map_sensor maps sensor coordinates into the map frame.
using Pose = Eigen::Isometry3d;
using PoseList = std::vector<Pose, Eigen::aligned_allocator<Pose>>;

/// Index of a 2D grid cell: cell (i, j) covers [i·s, (i+1)·s) × [j·s, (j+1)·s) for cell size s.
struct CellKey {
  std::int32_t i = 0;
  std::int32_t j = 0;
  friend bool operator==(const CellKey&, const CellKey&) = default;
};

struct CellKeyHash {
  std::size_t operator()(const CellKey& k) const noexcept {
    // Mix the two 32-bit halves (splitmix64 finaliser): neighbouring keys land far apart.
    std::uint64_t x = (static_cast<std::uint64_t>(static_cast<std::uint32_t>(k.i)) << 32) |
                      static_cast<std::uint32_t>(k.j);
    x ^= x >> 30;
    x *= 0xbf58476d1ce4e5b9ULL;
    x ^= x >> 27;
    x *= 0x94d049bb133111ebULL;
    x ^= x >> 31;
    return static_cast<std::size_t>(x);
  }
};

/// A closed height interval [z_min, z_max] in metres.
struct Interval {
  float z_min = 0.0F;
  float z_max = 0.0F;
  [[nodiscard]] float height() const { return z_max - z_min; }
  [[nodiscard]] bool contains(float z) const { return z >= z_min && z <= z_max; }
  [[nodiscard]] float overlap(const Interval& o) const {
    const float lo = z_min > o.z_min ? z_min : o.z_min;
    const float hi = z_max < o.z_max ? z_max : o.z_max;
    return hi > lo ? hi - lo : 0.0F;
  }
  friend bool operator==(const Interval&, const Interval&) = default;
};

}  // namespace hmap
