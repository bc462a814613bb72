#pragma once
// Measuring a map the way the seed's experimenter did with a ruler, for axis-aligned faces, from
// the map alone: the planes present along an axis are found in the voxels' point moments (where
// they lie, what supports them, how far they reach), without being told where a face should be.
// Comparing with the truth is a separate step (associate_faces), so a face that is not in the map
// is reported missing rather than looked for until something is found.

#include <Eigen/Geometry>
#include <cstdint>
#include <optional>
#include <vector>

#include "hmap/pvox/voxel_map.hpp"

namespace hmap::pvox {

struct PlaneDetectionParams {
  std::optional<Eigen::AlignedBox3d> region;  ///< [m] voxels whose mean lies outside are ignored; none: all
  std::uint32_t min_points = 3;     ///< voxels with fewer points are ignored
  /// [edges] σ of a flat voxel's points (and its neighbourhood's) along the axis: 10 mm range noise
  /// is 0.17 edge at 58.6 mm; points spread uniformly over a voxel, 0.29.
  double max_spread = 0.25;
  /// In a flat voxel, and in its neighbourhood, the variance along the axis is at most this
  /// fraction of the smaller in-plane variance (a face-on 58.6 mm voxel covered by points: 286 mm²
  /// in the plane vs about 100 mm² of 10 mm range noise; a perpendicular face spreads most along
  /// the axis; a voxel holding one scan line of a face is not flat by itself).
  double max_flatness = 0.5;
  /// [edges] σ of the neighbourhood's points along each in-plane axis, at least: a scan line,
  /// thin across every direction but its own, is no plane.
  double min_width = 0.25;
  double bandwidth = 0.1;           ///< [edges] σ of the Gaussian kernel of the density along the axis
  double bin = 0.001;               ///< [m] step of the density (widened so that at most 10⁶ bins)
  /// Two density peaks are one plane when the density between them stays above this fraction of
  /// the lower peak (a shoulder, not a second plane).
  double merge_valley = 0.5;
  std::size_t min_voxels = 4;       ///< flat voxels a connected piece of a plane needs
  double slab = 0.5;                ///< [edges] half thickness within which a plane takes its neighbours
};

/// An axis-aligned plane found in the map.
struct DetectedPlane {
  int axis = 0;                      ///< its normal: 0 = x, 1 = y, 2 = z
  double coordinate = 0.0;           ///< [m] weighted median of its flat voxels' means on `axis`
  std::size_t flat_voxels = 0;       ///< support: flat voxels in its cluster
  std::uint64_t points = 0;          ///< support: points of those voxels
  std::vector<VoxelKey> voxels;      ///< the flat voxels and the voxels grown from them within the slab
  Eigen::AlignedBox3d extent;        ///< [m] over `voxels`: mean ± √3σ per axis (points uniform)
};

/// The planes normal to `axis` in `map`, sorted by coordinate. Flat voxels (thin along the axis,
/// not a sliver of a face cut by the voxel grid, with a neighbourhood that is two-dimensional in
/// the plane: measure.cpp's flatness) vote with their mean's coordinate,
/// weighted by n / (σ² + (0.05·edge)²) so that flat voxels dominate and edge voxels (which also
/// hold points of a neighbouring face, and have a biased mean) count little; the weighted votes
/// are smoothed with a Gaussian of bandwidth·edge; each peak of that density is a plane, its
/// voxels those up to the valleys on either side that form connected pieces of at least
/// min_voxels spreading in both in-plane directions, its coordinate their weighted median. A plane
/// then takes the neighbours of its flat voxels that are flat along no axis and whose mean lies
/// within slab·edge of it (and nearer to it than to the next plane): the voxels at its borders,
/// which are not flat because they touch other faces, still tell where it ends. Throws hmap::Error for an
/// axis outside 0..2 or non-positive bandwidth or bin.
[[nodiscard]] std::vector<DetectedPlane> detect_planes(const VoxelMap& map, int axis, const PlaneDetectionParams& params = {});

/// Where `plane` ends along `along` (another axis) on the side `side` (−1: low end, +1: high end):
/// per row of its voxels (same key on the third axis), the outermost voxel's points taken as
/// uniform over their extent, so the end is mean ± √3·σ along `along`; the median over rows.
/// Nothing for a plane without voxels; throws hmap::Error for `along` equal to the plane's axis.
[[nodiscard]] std::optional<double> plane_end(const VoxelMap& map, const DetectedPlane& plane, int along, int side);

/// For each nominal coordinate of a face on one axis, the index of the nearest plane (of those
/// given, all on that axis) within its gate, or nothing (the face is missing from the map). The
/// gate of a face is half the distance to the nearest other nominal face (at most max_gate), so
/// no plane can serve two faces.
[[nodiscard]] std::vector<std::optional<std::size_t>> associate_faces(const std::vector<DetectedPlane>& planes,
                                                                      const std::vector<double>& nominal,
                                                                      double max_gate = 0.25);

/// The gate associate_faces uses for `nominal[i]`: [m].
[[nodiscard]] double face_gate(const std::vector<double>& nominal, std::size_t i, double max_gate = 0.25);

}  // namespace hmap::pvox
