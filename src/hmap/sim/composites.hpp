#pragma once
// Furniture, trees, people, cars and building parts made of primitives. Each maker returns the
// parts in the object's own frame: origin on the floor under the object's centre, x forward,
// z up; place them with SceneBuilder::add(name, parts, Placement{...}).

#include <Eigen/Core>

#include "hmap/sim/scene.hpp"

namespace hmap::sim {

struct TableSize {
  double length = 1.6;          ///< [m] along x
  double width = 0.8;           ///< [m] along y
  double height = 0.75;         ///< [m] floor to top surface
  double top_thickness = 0.04;  ///< [m]
  double leg_radius = 0.03;     ///< [m]
};
/// Four cylinder legs set 5 cm in from the corners, and a box top.
[[nodiscard]] Parts make_table(const TableSize& size = {});

struct ChairSize {
  double seat = 0.45;         ///< [m] seat edge (square)
  double seat_height = 0.45;  ///< [m] floor to seat top
  double back_height = 0.9;   ///< [m] floor to backrest top
  double leg_radius = 0.015;  ///< [m]
};
/// Four legs, a seat and a backrest on the −x side (the chair faces +x).
[[nodiscard]] Parts make_chair(const ChairSize& size = {});

struct CabinetSize {
  double width = 1.0;   ///< [m] along y
  double depth = 0.45;  ///< [m] along x
  double height = 1.9;  ///< [m]
};
[[nodiscard]] Parts make_cabinet(const CabinetSize& size = {});

struct TreeSize {
  double trunk_radius = 0.15;  ///< [m]
  double crown_bottom = 2.5;   ///< [m] above the ground; the trunk reaches the crown's centre
  double crown_height = 3.0;   ///< [m] vertical extent of the crown
  double crown_radius = 2.5;   ///< [m] horizontal semi-axis of the crown
};
/// A cylinder trunk under an ellipsoid crown centred over it.
[[nodiscard]] Parts make_tree(const TreeSize& size = {});

/// Two leg cylinders, a body cylinder and a head sphere, scaled to `height` [m].
[[nodiscard]] Parts make_person(double height = 1.75);

struct CarSize {
  double length = 4.5;     ///< [m] along x
  double width = 1.8;      ///< [m] along y
  double height = 1.5;     ///< [m] ground to roof
  double clearance = 0.2;  ///< [m] ground to the body's underside
};
/// A body box, a cabin box set back from the bonnet, and four wheel boxes.
[[nodiscard]] Parts make_car(const CarSize& size = {});

/// A wall along the floor line from `from` to `to` [m] (centre line), standing on `z_floor`.
[[nodiscard]] Parts make_wall(const Eigen::Vector2d& from, const Eigen::Vector2d& to, double height,
                              double thickness = 0.2, double z_floor = 0.0, SurfaceKind kind = SurfaceKind::kWall);

/// A ceiling slab over [min, max] in plan whose underside is at `z_underside` [m].
[[nodiscard]] Parts make_ceiling(const Eigen::Vector2d& min, const Eigen::Vector2d& max, double z_underside,
                                 double thickness = 0.3);

/// A flat ground rectangle [min, max] in plan with its top at `z_top` [m].
[[nodiscard]] Parts make_ground(const Eigen::Vector2d& min, const Eigen::Vector2d& max, double z_top,
                                SurfaceKind kind = SurfaceKind::kGround, double thickness = 0.3);

}  // namespace hmap::sim
