#include "hmap/sim/composites.hpp"

#include <cmath>

#include "hmap/core/error.hpp"

namespace hmap::sim {
namespace {

Box box_from_corners(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  return Box{0.5 * (lo + hi), 0.5 * (hi - lo), 0.0};
}

}  // namespace

Parts make_table(const TableSize& s) {
  Parts parts;
  const double inset = 0.05 + s.leg_radius;
  const double leg_top = s.height - s.top_thickness;
  for (const double sx : {-1.0, 1.0}) {
    for (const double sy : {-1.0, 1.0}) {
      const Eigen::Vector2d at(sx * (0.5 * s.length - inset), sy * (0.5 * s.width - inset));
      parts.push_back({Cylinder{at, 0.0, leg_top, s.leg_radius}, SurfaceKind::kFurniture});
    }
  }
  parts.push_back({box_from_corners({-0.5 * s.length, -0.5 * s.width, leg_top}, {0.5 * s.length, 0.5 * s.width, s.height}),
                   SurfaceKind::kFurniture});
  return parts;
}

Parts make_chair(const ChairSize& s) {
  Parts parts;
  constexpr double kSeatThickness = 0.04;
  constexpr double kBackThickness = 0.04;
  const double half = 0.5 * s.seat;
  const double inset = s.leg_radius + 0.01;
  const double leg_top = s.seat_height - kSeatThickness;
  for (const double sx : {-1.0, 1.0}) {
    for (const double sy : {-1.0, 1.0}) {
      parts.push_back({Cylinder{{sx * (half - inset), sy * (half - inset)}, 0.0, leg_top, s.leg_radius},
                       SurfaceKind::kFurniture});
    }
  }
  parts.push_back({box_from_corners({-half, -half, leg_top}, {half, half, s.seat_height}), SurfaceKind::kFurniture});
  parts.push_back({box_from_corners({-half, -half, s.seat_height}, {-half + kBackThickness, half, s.back_height}),
                   SurfaceKind::kFurniture});
  return parts;
}

Parts make_cabinet(const CabinetSize& s) {
  return {{box_from_corners({-0.5 * s.depth, -0.5 * s.width, 0.0}, {0.5 * s.depth, 0.5 * s.width, s.height}),
           SurfaceKind::kFurniture}};
}

Parts make_tree(const TreeSize& s) {
  const double crown_center = s.crown_bottom + 0.5 * s.crown_height;
  return {
      {Cylinder{{0.0, 0.0}, 0.0, crown_center, s.trunk_radius}, SurfaceKind::kTrunk},
      {Ellipsoid{{0.0, 0.0, crown_center}, {s.crown_radius, s.crown_radius, 0.5 * s.crown_height}, 0.0},
       SurfaceKind::kCrown},
  };
}

Parts make_person(double height) {
  if (!(height > 0.0)) throw Error("make_person: height must be positive");
  const double k = height / 1.75;  // proportions of a 1.75 m adult
  return {
      {Cylinder{{0.0, 0.1 * k}, 0.0, 0.85 * k, 0.07 * k}, SurfaceKind::kPerson},
      {Cylinder{{0.0, -0.1 * k}, 0.0, 0.85 * k, 0.07 * k}, SurfaceKind::kPerson},
      {Cylinder{{0.0, 0.0}, 0.85 * k, 1.50 * k, 0.18 * k}, SurfaceKind::kPerson},
      {Ellipsoid{{0.0, 0.0, 1.62 * k}, Eigen::Vector3d::Constant(0.12 * k), 0.0}, SurfaceKind::kPerson},
  };
}

Parts make_car(const CarSize& s) {
  const double body_top = s.clearance + 0.55 * (s.height - s.clearance);
  const double hl = 0.5 * s.length;
  const double hw = 0.5 * s.width;
  Parts parts{
      {box_from_corners({-hl, -hw, s.clearance}, {hl, hw, body_top}), SurfaceKind::kVehicle},
      // The cabin spans the middle of the car, a little towards the rear.
      {box_from_corners({-0.35 * s.length, -0.45 * s.width, body_top}, {0.2 * s.length, 0.45 * s.width, s.height}),
       SurfaceKind::kVehicle},
  };
  const double wheel_radius = std::max(0.3, s.clearance + 0.05);
  for (const double sx : {-1.0, 1.0}) {
    for (const double sy : {-1.0, 1.0}) {
      const Eigen::Vector3d c(sx * 0.32 * s.length, sy * (hw - 0.12), wheel_radius);
      parts.push_back({Box{c, {wheel_radius, 0.1, wheel_radius}, 0.0}, SurfaceKind::kVehicle});
    }
  }
  return parts;
}

Parts make_wall(const Eigen::Vector2d& from, const Eigen::Vector2d& to, double height, double thickness,
                double z_floor, SurfaceKind kind) {
  const Eigen::Vector2d along = to - from;
  const double length = along.norm();
  if (!(length > 0.0)) throw Error("make_wall: the two ends must differ");
  const Eigen::Vector2d mid = 0.5 * (from + to);
  return {{Box{{mid.x(), mid.y(), z_floor + 0.5 * height},
               {0.5 * length, 0.5 * thickness, 0.5 * height},
               std::atan2(along.y(), along.x())},
           kind}};
}

Parts make_ceiling(const Eigen::Vector2d& min, const Eigen::Vector2d& max, double z_underside, double thickness) {
  return {{box_from_corners({min.x(), min.y(), z_underside}, {max.x(), max.y(), z_underside + thickness}),
           SurfaceKind::kCeiling}};
}

Parts make_ground(const Eigen::Vector2d& min, const Eigen::Vector2d& max, double z_top, SurfaceKind kind,
                  double thickness) {
  const Eigen::Vector2d c = 0.5 * (min + max);
  return {{GroundPatch{{c.x(), c.y(), z_top}, 0.5 * (max - min), 0.0, Eigen::Vector2d::Zero(), thickness}, kind}};
}

}  // namespace hmap::sim
