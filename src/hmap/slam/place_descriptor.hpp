#pragma once
// Place recognition on the HMAP: a polar grid of column heights around a place (rings × sectors,
// Scan Context's layout with the HMAP's columns as its cells), compared under every sector shift
// so that the same place seen with another heading matches, the best shift giving the yaw between.

#include <cstddef>
#include <vector>

#include "hmap/maps/hmap.hpp"
#include "hmap/slam/scan_matcher.hpp"

namespace hmap::slam {

/// The grid's size.
struct PlaceDescriptorOptions {
  double radius = 40.0;  ///< [m] columns up to this far from the place take part
  int rings = 20;        ///< [-] radial bins, each radius / rings wide
  int sectors = 60;      ///< [-] angular bins, 2π / sectors each; the yaw guess's resolution
};

/// The descriptor of one place.
struct PlaceDescriptor {
  int rings = 0;
  int sectors = 0;
  /// [m] per bin (ring-major: cells[ring * sectors + sector]): the tallest column's height above
  /// the lowest HVoxel in the bin (0: empty bin); sector 0 starts at the place's heading.
  std::vector<float> cells;
  /// Per ring, the mean of its bins: does not change when the place is seen turned (a first,
  /// cheap test before the shifts are tried).
  std::vector<float> ring_key;

  [[nodiscard]] bool empty() const { return cells.empty(); }
  [[nodiscard]] float at(int ring, int sector) const { return cells[static_cast<std::size_t>(ring * sectors + sector)]; }
};

/// The descriptor of `map` around `place` (x, y, and the heading sector 0 starts at). Throws
/// hmap::Error for options out of range (radius in (0, 500] m, rings in [1, 200], sectors in
/// [4, 720]).
[[nodiscard]] PlaceDescriptor describe_place(const HMap& map, const PlanarPose& place,
                                             const PlaceDescriptorOptions& options = {});

/// How two descriptors compare.
struct PlaceMatch {
  double distance = 1.0;  ///< [0, 1]: mean over the sectors of 1 − cosine similarity; 0 = the same
  int shift = 0;          ///< sectors: b's sector s is a's sector s + shift
  double yaw = 0.0;       ///< [rad] b's heading in a's frame, shift · 2π / sectors, in (−π, π]
};

/// Mean absolute difference of the ring keys [m] (rotation invariant).
[[nodiscard]] double ring_key_distance(const PlaceDescriptor& a, const PlaceDescriptor& b);

/// The best sector shift of `b` against `a` and its distance (sectors empty in both count for
/// nothing; 1 when no sector is occupied in both). Throws hmap::Error for descriptors of
/// different sizes.
[[nodiscard]] PlaceMatch compare_places(const PlaceDescriptor& a, const PlaceDescriptor& b);

}  // namespace hmap::slam
