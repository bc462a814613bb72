#pragma once
// The scenes that ship with the simulator, by name, and the routes and landmarks that go with
// them.

#include <Eigen/Core>
#include <map>
#include <string>
#include <string_view>
#include <vector>

#include "hmap/sim/scene.hpp"

namespace hmap::sim {

/// "boxes", "city" (make_city_scene at the default CityParams), "office", "parking".
[[nodiscard]] std::vector<std::string> builtin_scene_names();

/// The built-in scene `name`. Throws hmap::Error listing the known names for any other.
[[nodiscard]] Scene make_scene(std::string_view name);

/// office: a 10 × 8 m room (x in [0, 10], y in [0, 8], floor z = 0, ceiling 2.6 m) with three
/// tables, a cabinet, three chairs and a standing person.
[[nodiscard]] Scene make_office_scene();
/// A loop through the office that keeps at least 0.5 m from the furniture, floor level [m]; for
/// diff_drive_path.
[[nodiscard]] std::vector<Eigen::Vector2d> office_robot_route();

/// parking: an underground garage (x in [−40, 0], |y| <= 12, floor z = −3.5, ceiling 2.7 m above
/// it, pillars, parked cars), a ramp up to street level (x in [0, 20], slope 17.5 %), and a campus
/// street at z = 0 from x = 20 to 170 (road |y| <= 3.2, 30 cm gutters 3 cm lower, 12 cm curbs at
/// |y| = 3.5, sidewalks and lawns, buildings) with a side road leaving north at x = 96.5..103.5
/// (a T intersection). Trees stand on both sidewalks at |y| = 5.5 with crowns 2.8 m in radius that
/// overhang the road, crown bottoms between 2.5 and 4 m. Cars are parked along the south edge;
/// the one called "leaving_car" (at x = 45, y = −2.2) drives off along +x after t = 3 s.
[[nodiscard]] Scene make_parking_scene();
/// Ground-level waypoints [m] of a drive out of the garage, up the ramp, along the street and
/// left into the side road; for car_path.
[[nodiscard]] std::vector<Eigen::Vector3d> parking_car_route();
/// The same route driven on: a U-turn at the north end of the side road, back south, then east
/// along the street to its end, past the start of the side road again (about 313 m; for SLAM
/// figures that need a longer drive).
[[nodiscard]] std::vector<Eigen::Vector3d> parking_long_car_route();

/// boxes: the enclosure of the PVOX experiment, x in [−0.75, 0.75], y in [0, 2.7], z in [−1, 1]
/// (z up, floor at z = −1), with box A (330 × 215 × 120 mm) and box B (370 × 75 × 785 mm) on the
/// floor. See boxes_vertices() for the layout.
[[nodiscard]] Scene make_boxes_scene();

/// The named vertices of the boxes scene [m]; see builtin_scenes.cpp for the layout.
[[nodiscard]] std::map<std::string, Eigen::Vector3d> boxes_vertices();

/// An edge of the boxes scene to measure: between two named vertices, with its nominal length.
struct NamedEdge {
  std::string from;
  std::string to;
  double length = 0.0;  ///< [m]
};
/// AB 330, AE 120, EG 215, GH 900, HC 370, CF 75, FI 370, IJ 785, JK 575 mm.
[[nodiscard]] std::vector<NamedEdge> boxes_edges();

}  // namespace hmap::sim
