#pragma once
// One map registered onto another (hmap merge --align): the scan matcher of section IV-C with the
// second map's columns in the place of a scan's HVoxels, a coarse search first.

#include <cstddef>

#include "hmap/maps/map_merge.hpp"
#include "hmap/slam/scan_matcher.hpp"

namespace hmap::slam {

/// How far from the guess the alignment looks.
struct MapAlignOptions {
  PlanarShift guess;               ///< where `moving` is believed to lie in `reference`'s frame
  double search_translation = 5.0; ///< [m] half-width of the coarse search in x and y
  double search_rotation = 0.5;    ///< [rad] half-width of the coarse search in yaw
};

/// What align_maps found.
struct MapAlignResult {
  PlanarShift shift;            ///< `moving`'s frame in `reference`'s: x, y, yaw matched, z from the floors
  MatchResult match;            ///< the planar match (score: mean M_H at the result)
  std::size_t columns_used = 0; ///< columns of `moving` that took part (those over `reference`'s area)
  std::size_t floor_pairs = 0;  ///< column pairs the z offset was taken from
  int sectors = 1;              ///< yaw sectors searched (a map far from its frame's origin needs more)
  bool about_origin = false;    ///< turned about the moving frame's origin (else about its columns' centroid)
};

/// Registers `moving` onto `reference` (same cell size): z first, as the median height difference
/// of the lowest surfaces of columns that fall on each other at the guess, then x, y, yaw by
/// Gauss-Newton on eq. (5) after an exhaustive coarse search of the window in `options` (about the
/// moving frame's origin: turning about it when its columns lie near enough that the search's yaw
/// step stays two cells at their RMS radius, as for a scan's map about its sensor; else about their
/// centroid, in yaw sectors narrow enough that this stays within 1 m of turning about the origin,
/// the best-agreeing sector's match winning), then z
/// again at the result. Both maps are taken as gravity-aligned (their z up), as hmap builds them.
/// The columns of `moving` over `reference`'s area (its bounds widened by the search) take part,
/// those within 1024 cells of their centroid. Throws hmap::Error for different cell sizes, a search
/// window out of range (slam.coarse_translation's), or no overlap at all.
[[nodiscard]] MapAlignResult align_maps(const HMap& reference, const HMap& moving, const MapAlignOptions& options);

}  // namespace hmap::slam
