#pragma once
// Analytic solids of the simulated scenes, each convex, with exact ray intersection, an inside
// test, a bounding box and a surface sampler. Lengths are in metres, angles in radians.

#include <Eigen/Geometry>
#include <optional>
#include <random>
#include <string>
#include <variant>
#include <vector>

namespace hmap::sim {

/// A box of half-extents `half_size` about `center`, turned by `yaw` about the vertical axis.
struct Box {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();     ///< [m]
  Eigen::Vector3d half_size = Eigen::Vector3d::Constant(0.5);  ///< [m] half the edge lengths
  double yaw = 0.0;                                     ///< [rad] about +z
};

/// A vertical circular cylinder: trunks, table legs, pillars, bodies.
struct Cylinder {
  Eigen::Vector2d center_xy = Eigen::Vector2d::Zero();  ///< [m] axis position
  double z_min = 0.0;                                   ///< [m] bottom face
  double z_max = 1.0;                                   ///< [m] top face
  double radius = 0.1;                                  ///< [m]
};

/// An ellipsoid with semi-axes `radii` along its own x, y, z, turned by `yaw`; a sphere when the
/// radii are equal. Tree crowns, heads.
struct Ellipsoid {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();     ///< [m]
  Eigen::Vector3d radii = Eigen::Vector3d::Constant(0.5);  ///< [m] semi-axes
  double yaw = 0.0;                                     ///< [rad] about +z
};

/// A piece of ground: a rectangle in plan (half-extents `half_size`, turned by `yaw`) whose top
/// surface is the plane through `center` with slopes dz/dx, dz/dy along the patch's own axes, and
/// which is solid `thickness` metres (measured vertically) below that plane. Flat and sloped
/// roads, ramps, a gutter (a patch slightly lower than its neighbours).
struct GroundPatch {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();     ///< [m] top surface point above the centre
  Eigen::Vector2d half_size = Eigen::Vector2d::Constant(5.0);  ///< [m]
  double yaw = 0.0;                                     ///< [rad] about +z
  Eigen::Vector2d slope = Eigen::Vector2d::Zero();      ///< [-] dz/dx and dz/dy in the patch frame
  double thickness = 0.3;                               ///< [m] vertical depth of the solid
};

using Shape = std::variant<Box, Cylinder, Ellipsoid, GroundPatch>;

/// Where a part goes: turned by `yaw` about the vertical axis through the origin, then moved by
/// `position`.
struct Placement {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();   ///< [m]
  double yaw = 0.0;                                     ///< [rad]
};

/// A point on a surface with its outward unit normal.
struct SurfaceSample {
  Eigen::Vector3d point;
  Eigen::Vector3d normal;
};

/// Distance t in (0, t_max] along `origin + t·direction` to the first crossing of the shape's
/// boundary: the entry point for rays starting outside, the exit point for rays starting inside.
/// t is in units of |direction|. Nothing when the ray misses or the crossing is beyond t_max.
[[nodiscard]] std::optional<double> intersect(const Shape& shape, const Eigen::Vector3d& origin,
                                              const Eigen::Vector3d& direction, double t_max);

/// Whether `point` is inside the closed solid.
[[nodiscard]] bool contains(const Shape& shape, const Eigen::Vector3d& point);

/// The axis-aligned box that encloses the solid.
[[nodiscard]] Eigen::AlignedBox3d bounding_box(const Shape& shape);

/// The shape moved by `placement`.
[[nodiscard]] Shape placed(const Shape& shape, const Placement& placement);

/// Appends points on the shape's surface about `spacing` apart (stratified: one random point per
/// spacing × spacing cell of each face), with outward normals. A ground patch is sampled on its
/// top only; its sides and bottom are underground.
void sample_surface(const Shape& shape, double spacing, std::mt19937_64& rng,
                    std::vector<SurfaceSample>& out);

/// Throws hmap::Error naming `what` when a size is not positive or a value is not finite.
void validate(const Shape& shape, const std::string& what);

}  // namespace hmap::sim
