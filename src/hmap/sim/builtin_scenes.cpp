#include "hmap/sim/builtin_scenes.hpp"

#include <cmath>
#include <numbers>

#include "hmap/core/error.hpp"
#include "hmap/sim/city.hpp"
#include "hmap/sim/composites.hpp"

namespace hmap::sim {
namespace {

Parts box_part(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, SurfaceKind kind) {
  return {{Box{0.5 * (lo + hi), 0.5 * (hi - lo), 0.0}, kind}};
}

/// Four walls of thickness `t` around the interior [lo, hi] in plan, from z0 to z1.
void add_room_walls(SceneBuilder& b, const Eigen::Vector2d& lo, const Eigen::Vector2d& hi, double z0, double z1,
                    double t) {
  b.add("wall_south", box_part({lo.x() - t, lo.y() - t, z0}, {hi.x() + t, lo.y(), z1}, SurfaceKind::kWall));
  b.add("wall_north", box_part({lo.x() - t, hi.y(), z0}, {hi.x() + t, hi.y() + t, z1}, SurfaceKind::kWall));
  b.add("wall_west", box_part({lo.x() - t, lo.y(), z0}, {lo.x(), hi.y(), z1}, SurfaceKind::kWall));
  b.add("wall_east", box_part({hi.x(), lo.y(), z0}, {hi.x() + t, hi.y(), z1}, SurfaceKind::kWall));
}

}  // namespace

std::vector<std::string> builtin_scene_names() { return {"boxes", "city", "office", "parking"}; }

Scene make_scene(std::string_view name) {
  if (name == "boxes") return make_boxes_scene();
  if (name == "office") return make_office_scene();
  if (name == "parking") return make_parking_scene();
  if (name == "city") return make_city_scene();
  std::string known;
  for (const auto& n : builtin_scene_names()) known += (known.empty() ? "" : ", ") + n;
  throw Error("unknown scene '" + std::string(name) + "'; known scenes: " + known);
}

// ---------------------------------------------------------------------------------------------
// office

Scene make_office_scene() {
  SceneBuilder b;
  constexpr double kHeight = 2.6;
  constexpr double kWall = 0.2;
  b.add("floor", make_ground({-kWall, -kWall}, {10.0 + kWall, 8.0 + kWall}, 0.0));
  b.add("ceiling", make_ceiling({-kWall, -kWall}, {10.0 + kWall, 8.0 + kWall}, kHeight));
  add_room_walls(b, {0.0, 0.0}, {10.0, 8.0}, 0.0, kHeight, kWall);
  b.add("table_1", make_table(), {{3.0, 2.0, 0.0}, 0.0});
  b.add("table_2", make_table(), {{3.0, 5.5, 0.0}, 0.0});
  b.add("table_3", make_table(), {{7.0, 4.0, 0.0}, 90.0 * kRadiansPerDegree});
  b.add("chair_1", make_chair(), {{3.0, 2.85, 0.0}, -90.0 * kRadiansPerDegree});
  b.add("chair_2", make_chair(), {{3.0, 4.65, 0.0}, 90.0 * kRadiansPerDegree});
  b.add("chair_3", make_chair(), {{7.85, 4.0, 0.0}, 180.0 * kRadiansPerDegree});
  b.add("cabinet", make_cabinet(), {{9.7, 7.0, 0.0}, 0.0});
  b.add("person", make_person(1.75), {{5.5, 7.4, 0.0}, -90.0 * kRadiansPerDegree});
  // The room's inside, a little beyond its faces: the truth holds no outer wall faces.
  b.set_bounds(Eigen::AlignedBox3d(Eigen::Vector3d(-0.05, -0.05, -0.05), Eigen::Vector3d(10.05, 8.05, 2.65)));
  return b.build();
}

std::vector<Eigen::Vector2d> office_robot_route() {
  return {{1.0, 1.0}, {8.8, 1.0}, {8.8, 6.7}, {1.2, 6.7}, {1.2, 3.8}, {5.0, 3.8}};
}

// ---------------------------------------------------------------------------------------------
// parking

Scene make_parking_scene() {
  SceneBuilder b;
  // Underground garage: floor z = -3.5, ceiling slab underside -0.8 (2.7 m clear), top at street level.
  constexpr double kFloor = -3.5;
  constexpr double kCeiling = -0.8;
  b.add("garage_floor", make_ground({-40.0, -12.0}, {0.0, 12.0}, kFloor));
  b.add("garage_ceiling", make_ceiling({-40.2, -12.2}, {0.0, 12.2}, kCeiling, -kCeiling));
  b.add("garage_wall_back", make_wall({-40.1, -12.2}, {-40.1, 12.2}, kCeiling - kFloor, 0.2, kFloor));
  b.add("garage_wall_south", make_wall({-40.0, -12.1}, {0.0, -12.1}, kCeiling - kFloor, 0.2, kFloor));
  b.add("garage_wall_north", make_wall({-40.0, 12.1}, {0.0, 12.1}, kCeiling - kFloor, 0.2, kFloor));
  b.add("garage_front_south", box_part({-0.2, -12.2, kFloor}, {0.0, -3.7, kCeiling}, SurfaceKind::kWall));
  b.add("garage_front_north", box_part({-0.2, 3.7, kFloor}, {0.0, 12.2, kCeiling}, SurfaceKind::kWall));
  for (const double x : {-8.0, -16.0, -24.0, -32.0}) {
    for (const double y : {-6.0, 6.0}) {
      b.add("pillar", box_part({x - 0.3, y - 0.3, kFloor}, {x + 0.3, y + 0.3, kCeiling}, SurfaceKind::kPillar));
    }
  }
  for (const double x : {-12.0, -20.0, -28.0}) {
    b.add("garage_car", make_car(), {{x, 9.0, kFloor}, 90.0 * kRadiansPerDegree});
    b.add("garage_car", make_car(), {{x + 1.0, -9.0, kFloor}, -90.0 * kRadiansPerDegree});
  }
  b.add("garage_person", make_person(1.7), {{-36.0, 3.0, kFloor}, 0.0});

  // Ramp from the garage floor up to the street, between retaining walls that rise 1 m above it.
  constexpr double kRampSlope = -kFloor / 20.0;
  b.add("ramp", {{GroundPatch{{10.0, 0.0, 0.5 * kFloor}, {10.0, 3.7}, 0.0, {kRampSlope, 0.0}, 0.5},
                  SurfaceKind::kGround}});
  b.add("ramp_wall", box_part({0.0, -3.9, kFloor - 0.5}, {20.0, -3.7, 1.0}, SurfaceKind::kWall));
  b.add("ramp_wall", box_part({0.0, 3.7, kFloor - 0.5}, {20.0, 3.9, 1.0}, SurfaceKind::kWall));
  // Ground over the garage and beside the ramp, at street level.
  b.add("yard", make_ground({-40.2, 12.2}, {20.0, 30.0}, 0.0));
  b.add("yard", make_ground({-40.2, -30.0}, {20.0, -12.2}, 0.0));
  b.add("yard", make_ground({0.0, 3.9}, {20.0, 12.2}, 0.0));
  b.add("yard", make_ground({0.0, -12.2}, {20.0, -3.9}, 0.0));

  // The street: road, gutters (3 cm lower), 12 cm curbs, sidewalks and lawns at +0.12.
  constexpr double kX0 = 20.0;
  constexpr double kX1 = 170.0;
  constexpr double kSideWest = 96.5;
  constexpr double kSideEast = 103.5;
  constexpr double kKerb = 0.12;
  b.add("road", make_ground({kX0, -3.2}, {kX1, 3.2}, 0.0));
  b.add("side_road", make_ground({kSideWest, 3.2}, {kSideEast, 60.0}, 0.0));
  b.add("gutter", make_ground({kX0, -3.5}, {kX1, -3.2}, -0.03));
  b.add("gutter", make_ground({kX0, 3.2}, {kSideWest, 3.5}, -0.03));
  b.add("gutter", make_ground({kSideEast, 3.2}, {kX1, 3.5}, -0.03));
  b.add("curb", box_part({kX0, -3.7, -0.2}, {kX1, -3.5, kKerb}, SurfaceKind::kCurb));
  b.add("curb", box_part({kX0, 3.5, -0.2}, {kSideWest, 3.7, kKerb}, SurfaceKind::kCurb));
  b.add("curb", box_part({kSideEast, 3.5, -0.2}, {kX1, 3.7, kKerb}, SurfaceKind::kCurb));
  b.add("curb", box_part({kSideWest - 0.2, 3.5, -0.2}, {kSideWest, 60.0, kKerb}, SurfaceKind::kCurb));
  b.add("curb", box_part({kSideEast, 3.5, -0.2}, {kSideEast + 0.2, 60.0, kKerb}, SurfaceKind::kCurb));
  b.add("sidewalk", make_ground({kX0, -30.0}, {kX1, -3.7}, kKerb));
  b.add("sidewalk", make_ground({kX0, 3.7}, {kSideWest - 0.2, 60.0}, kKerb));
  b.add("sidewalk", make_ground({kSideEast + 0.2, 3.7}, {kX1, 60.0}, kKerb));
  // A step up to a building entrance on the south side.
  b.add("step", box_part({60.0, -12.0, 0.0}, {66.0, -11.0, 0.3}, SurfaceKind::kCurb));

  // Buildings set back from the street, with a gap at the side road.
  struct Block {
    double x0, x1, y0, y1, height;
  };
  for (const Block& k : {Block{25.0, 55.0, 16.0, 28.0, 9.0}, Block{62.0, 92.0, 14.0, 26.0, 12.0},
                         Block{108.0, 140.0, 15.0, 27.0, 8.0}, Block{146.0, 168.0, 16.0, 30.0, 10.0},
                         Block{24.0, 58.0, -27.0, -13.0, 11.0}, Block{70.0, 120.0, -28.0, -15.0, 9.0},
                         Block{128.0, 166.0, -26.0, -14.0, 12.0}}) {
    b.add("building", box_part({k.x0, k.y0, 0.0}, {k.x1, k.y1, k.height}, SurfaceKind::kWall));
  }

  // Trees on both sidewalks; crowns reach 0.8 m over the road, their bottoms stepping 2.5..4 m.
  int tree = 0;
  for (double x = 26.0; x < kX1 - 2.0; x += 12.0, ++tree) {
    const double crown_bottom = 2.5 + 0.5 * (tree % 4);
    const TreeSize size{0.15, crown_bottom, 3.0, 2.8};
    if (x < kSideWest - 4.0 || x > kSideEast + 4.0) b.add("tree", make_tree(size), {{x, 5.5, kKerb}, 0.0});
    b.add("tree", make_tree(size), {{x + 6.0, -5.5, kKerb}, 0.0});
  }

  // Cars parked along the south edge of the road, and one that leaves.
  for (const double x : {30.0, 36.0, 55.0, 61.0, 67.0, 120.0, 126.0, 140.0}) {
    b.add("parked_car", make_car(), {{x, -2.2, 0.0}, 0.0});
  }
  // Stands until t = 3 s, accelerates at about 1 m/s² to 6 m/s, then cruises off the street.
  std::vector<PathKey> keys{{0.0, {45.0, -2.2, 0.0}, 0.0}, {3.0, {45.0, -2.2, 0.0}, 0.0}};
  for (int k = 1; k <= 6; ++k) {
    const double t = 3.0 + k;
    keys.push_back({t, {45.0 + 0.5 * k * k, -2.2, 0.0}, 0.0});
  }
  keys.push_back({30.0, {63.0 + 6.0 * 21.0, -2.2, 0.0}, 0.0});
  b.add_moving("leaving_car", make_car(), MotionPath(std::move(keys)));
  b.add("pedestrian", make_person(1.8), {{70.0, 5.0, kKerb}, 0.0});
  b.add("pedestrian", make_person(1.6), {{101.0, 30.0, 0.0}, 0.0});

  b.set_bounds(Eigen::AlignedBox3d(Eigen::Vector3d(-40.0, -30.0, -3.6), Eigen::Vector3d(170.0, 60.0, 15.0)));
  return b.build();
}

std::vector<Eigen::Vector3d> parking_car_route() {
  return {{-34.0, 0.0, -3.5}, {0.0, 0.0, -3.5}, {20.0, 0.0, 0.0},
          {30.0, 1.6, 0.0},   {101.75, 1.6, 0.0}, {101.75, 55.0, 0.0}};
}

std::vector<Eigen::Vector3d> parking_long_car_route() {
  std::vector<Eigen::Vector3d> route = parking_car_route();
  // The side road is 7 m wide (x 96.5..103.5): turn within it, come back in the other lane and
  // turn east into the street's northern lane (the parked cars stand in the southern one).
  for (const Eigen::Vector3d& p : {Eigen::Vector3d(100.0, 58.0, 0.0), Eigen::Vector3d(98.25, 55.0, 0.0),
                                   Eigen::Vector3d(98.25, 1.6, 0.0), Eigen::Vector3d(165.0, 1.6, 0.0)}) {
    route.push_back(p);
  }
  return route;
}

// ---------------------------------------------------------------------------------------------
// boxes
//
// The PVOX enclosure: interior x in [-0.75, 0.75], y in [0, 2.7], z in [-1, 1] (z up). The paper
// gives edge lengths only; this layout puts both boxes against the x = -0.45 line, one behind the
// other along +y, so every edge is axis-aligned and lies on a face a sensor near the origin sees:
//
//   box A: x in [-0.45, -0.12] (330), y in [0.935, 1.15] (215), z in [-1.0, -0.88] (120)
//   box B: x in [-0.45, -0.08] (370), y in [2.05, 2.125] (75),  z in [-1.0, -0.215] (785)
//
//   A = (-0.45, 0.935, -0.88)   top front left of box A
//   B = (-0.12, 0.935, -0.88)   top front right of box A          AB = 330 mm along x
//   E = (-0.45, 0.935, -1.00)   bottom front left of box A        AE = 120 mm along z
//   G = (-0.45, 1.150, -1.00)   bottom back left of box A         EG = 215 mm along y
//   H = (-0.45, 2.050, -1.00)   bottom front left of box B        GH = 900 mm along y (floor gap)
//   C = (-0.08, 2.050, -1.00)   bottom front right of box B       HC = 370 mm along x
//   F = (-0.08, 2.125, -1.00)   bottom back right of box B        CF =  75 mm along y
//   I = (-0.45, 2.125, -1.00)   bottom back left of box B         FI = 370 mm along x
//   J = (-0.45, 2.125, -0.215)  top back left of box B            IJ = 785 mm along z
//   K = (-0.45, 2.700, -0.215)  on the back wall, level with J    JK = 575 mm along y

std::map<std::string, Eigen::Vector3d> boxes_vertices() {
  return {
      {"A", {-0.45, 0.935, -0.88}}, {"B", {-0.12, 0.935, -0.88}}, {"E", {-0.45, 0.935, -1.0}},
      {"G", {-0.45, 1.15, -1.0}},   {"H", {-0.45, 2.05, -1.0}},   {"C", {-0.08, 2.05, -1.0}},
      {"F", {-0.08, 2.125, -1.0}},  {"I", {-0.45, 2.125, -1.0}},  {"J", {-0.45, 2.125, -0.215}},
      {"K", {-0.45, 2.7, -0.215}},
  };
}

std::vector<NamedEdge> boxes_edges() {
  return {{"A", "B", 0.330}, {"A", "E", 0.120}, {"E", "G", 0.215}, {"G", "H", 0.900}, {"H", "C", 0.370},
          {"C", "F", 0.075}, {"F", "I", 0.370}, {"I", "J", 0.785}, {"J", "K", 0.575}};
}

Scene make_boxes_scene() {
  SceneBuilder b;
  const Eigen::Vector2d lo(-0.75, 0.0);
  const Eigen::Vector2d hi(0.75, 2.7);
  constexpr double kWall = 0.1;
  b.add("floor", make_ground(lo - Eigen::Vector2d::Constant(kWall), hi + Eigen::Vector2d::Constant(kWall), -1.0));
  b.add("ceiling", make_ceiling(lo - Eigen::Vector2d::Constant(kWall), hi + Eigen::Vector2d::Constant(kWall), 1.0,
                                kWall));
  add_room_walls(b, lo, hi, -1.0, 1.0, kWall);
  b.add("box_A", box_part({-0.45, 0.935, -1.0}, {-0.12, 1.15, -0.88}, SurfaceKind::kBox));
  b.add("box_B", box_part({-0.45, 2.05, -1.0}, {-0.08, 2.125, -0.215}, SurfaceKind::kBox));
  b.set_bounds(Eigen::AlignedBox3d(Eigen::Vector3d(-0.76, -0.01, -1.01), Eigen::Vector3d(0.76, 2.71, 1.01)));
  return b.build();
}

}  // namespace hmap::sim
