#pragma once
// city: a procedurally generated town for long drives (issue 19's 10 km drive). A square grid of
// streets with kerbs between building blocks of varied heights, trees, poles and parked cars, on
// a gently sloping ground plane; and a route through its streets of a given length that turns at
// intersections and comes back over streets it has driven (a random walk on the street grid).
// Everything follows from CityParams::seed: the same seed, the same town and route.

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "hmap/sim/scene.hpp"

namespace hmap::sim {

struct CityParams {
  int blocks = 8;               ///< [-] blocks per side, [1, 40]; streets run at both ends, blocks + 1 each way
  double block_size = 80.0;     ///< [m] kerb to kerb across a block, [20, 300]
  double street_width = 10.0;   ///< [m] kerb to kerb, [6, 30]
  double slope_x = 0.02;        ///< [-] dz/dx of the ground plane, |slope| <= 0.1
  double slope_y = -0.01;       ///< [-] dz/dy of the ground plane, |slope| <= 0.1
  std::uint64_t seed = 1;       ///< of the layout (buildings, trees, cars) and of the route
};

/// Throws hmap::Error naming the first parameter out of its range.
void validate(const CityParams& params);

/// Street pitch [m]: the distance between neighbouring parallel street centre lines.
[[nodiscard]] double city_pitch(const CityParams& params);
/// The road surface height [m] at (x, y): the ground plane through the origin (the corner
/// intersection; street centre lines at x, y = k · pitch, k = 0 .. blocks).
[[nodiscard]] double city_ground_z(const CityParams& params, double x, double y);
/// Whether (x, y) is on a street's carriageway (between its kerbs), `margin` [m] in from them.
[[nodiscard]] bool on_city_street(const CityParams& params, double x, double y, double margin = 0.0);

/// The town: road, kerbs, raised blocks, buildings, trees, poles, parked cars; bounds 40 m beyond
/// the outer streets. Throws hmap::Error for invalid params.
[[nodiscard]] Scene make_city_scene(const CityParams& params = {});

/// Ground waypoints [m] of a drive along the street centre lines: from the intersection nearest
/// the town's centre, east first, then at each intersection straight on or a turn (never back),
/// chosen at random from `params.seed`, until the polyline is `length_m` long plus what car_path's
/// rounded corners (radius `turn_radius` [m]) take off, so the driven path is about `length_m`.
/// Throws hmap::Error for length_m outside (0, 100 km] or invalid params.
[[nodiscard]] std::vector<Eigen::Vector3d> city_car_route(const CityParams& params, double length_m,
                                                          double turn_radius = 6.0);

/// Ground waypoints [m] of a closed drive around a rectangle of blocks: the smallest rectangle
/// (a × b blocks, a >= b >= a − 1) whose perimeter along the street centre lines is at least
/// `length_m`, centred on the town; from its south-west corner east first, counter-clockwise
/// back to the start, then `overlap_m` on along the first street (a loop closure needs the
/// start seen again from the same side). Throws hmap::Error for a length outside (0, 100 km],
/// a rectangle that does not fit in the town, or invalid params.
[[nodiscard]] std::vector<Eigen::Vector3d> city_loop_route(const CityParams& params, double length_m,
                                                           double overlap_m = 40.0);

}  // namespace hmap::sim
