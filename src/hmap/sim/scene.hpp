#pragma once
// A simulated world: static solids plus rigid groups that move along piecewise-linear paths,
// queried by rays (exact, nearest hit) and sampled densely for a ground-truth point cloud.

#include <Eigen/Geometry>
#include <cstdint>
#include <numbers>
#include <optional>
#include <random>
#include <string>
#include <string_view>
#include <vector>

#include "hmap/core/types.hpp"
#include "hmap/sim/primitives.hpp"

namespace hmap::sim {

/// Degrees to radians: the scene files, the builtin scenes and the sensors give angles in degrees.
inline constexpr double kRadiansPerDegree = std::numbers::pi / 180.0;

/// What a solid stands for; carried into every hit so that tests and experiments can count hits
/// on the ground, on cars, on tree crowns.
enum class SurfaceKind : std::uint8_t {
  kGround, kCurb, kWall, kCeiling, kPillar, kFurniture, kVehicle, kTrunk, kCrown, kPerson, kBox, kOther,
};
[[nodiscard]] std::string_view to_string(SurfaceKind kind);
/// The kind named `name` ("ground", "curb", ...), or nothing.
[[nodiscard]] std::optional<SurfaceKind> surface_kind_from_string(std::string_view name);

/// One solid of a composite object, in the object's frame.
struct Part {
  Shape shape;
  SurfaceKind kind = SurfaceKind::kOther;
};
using Parts = std::vector<Part>;

/// A keyframe of a moving object: where its frame is at `time`.
struct PathKey {
  double time = 0.0;                                  ///< [s]
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  ///< [m]
  double yaw = 0.0;                                   ///< [rad], interpolated as given (not wrapped)
};

/// A piecewise-linear path through keyframes; the object stays at the first key before it and at
/// the last key after it. Throws hmap::Error without keys or with times not strictly increasing.
class MotionPath {
 public:
  explicit MotionPath(std::vector<PathKey> keys);
  [[nodiscard]] Placement at(double t_seconds) const;
  [[nodiscard]] const std::vector<PathKey>& keys() const { return keys_; }

 private:
  std::vector<PathKey> keys_;
};

/// A ray hit: how far along the (unit) direction, and what was hit.
struct Hit {
  double distance = 0.0;        ///< [m]
  std::uint32_t primitive = 0;  ///< id of the solid, in the order parts were added
  std::uint32_t object = 0;     ///< id of the object the solid belongs to
  SurfaceKind kind = SurfaceKind::kOther;
};

class Scene;

/// Collects objects; build() makes the immutable, queryable Scene.
class SceneBuilder {
 public:
  /// Adds a static object made of `parts` (given in the object's frame) placed at `where`;
  /// returns its object id. Throws hmap::Error for an invalid part, naming the object.
  std::uint32_t add(const std::string& name, const Parts& parts, const Placement& where = {});
  /// Adds an object whose frame follows `path`; returns its object id.
  std::uint32_t add_moving(const std::string& name, const Parts& parts, MotionPath path);
  /// The region sample_surface keeps points in; without it, the bounding box of all static parts.
  void set_bounds(const Eigen::AlignedBox3d& bounds) { bounds_ = bounds; }

  [[nodiscard]] Scene build() const;

 private:
  friend class Scene;
  struct Object {
    std::string name;
    std::optional<MotionPath> path;  ///< nothing for static objects
    std::vector<std::uint32_t> primitives;
  };
  std::vector<Part> parts_;  ///< by primitive id; static ones in the world frame, moving ones in theirs
  std::vector<std::uint32_t> object_of_;  ///< by primitive id
  std::vector<Object> objects_;
  std::optional<Eigen::AlignedBox3d> bounds_;
};

/// The queryable scene. Static solids sit in a bounding-volume hierarchy; each moving object is
/// tested by transforming the ray into its frame at the query time.
class Scene {
 public:
  Scene() = default;

  /// The nearest surface along the ray `origin + s·direction` for s in (0, max_range], at time
  /// `t_seconds` (which places the moving objects). `direction` need not be unit length;
  /// Hit::distance is in metres.
  [[nodiscard]] std::optional<Hit> intersect(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                                             double t_seconds, double max_range) const;
  /// The same answer by testing every solid; the twin of intersect() for tests.
  [[nodiscard]] std::optional<Hit> intersect_brute_force(const Eigen::Vector3d& origin,
                                                         const Eigen::Vector3d& direction, double t_seconds,
                                                         double max_range) const;
  /// Whether `point` is inside any solid at time `t_seconds`.
  [[nodiscard]] bool contains(const Eigen::Vector3d& point, double t_seconds) const;

  /// A dense sample of every visible surface at time `t_seconds` (the ground truth): points about
  /// `spacing_m` apart on each solid, without those inside the bounds' complement and those
  /// covered by another solid (a table leg's top inside the table top, a box's face on the floor).
  [[nodiscard]] PointCloud sample_surface(double spacing_m, std::mt19937_64& rng, double t_seconds) const;
  /// The same sample with each point's surface kind (kinds[n] for points[n]): the truth's walkable
  /// ground (SurfaceKind::kGround) apart from the rest.
  struct KindedSample {
    PointCloud points;
    std::vector<SurfaceKind> kinds;
  };
  [[nodiscard]] KindedSample sample_surface_kinds(double spacing_m, std::mt19937_64& rng, double t_seconds) const;

  [[nodiscard]] std::size_t primitive_count() const { return parts_.size(); }
  [[nodiscard]] std::size_t object_count() const { return objects_.size(); }
  [[nodiscard]] const std::string& object_name(std::uint32_t object) const { return objects_.at(object).name; }
  /// The id of the first object called `name`, or nothing.
  [[nodiscard]] std::optional<std::uint32_t> find_object(std::string_view name) const;
  /// The solid `primitive` in the world frame at time `t_seconds`.
  [[nodiscard]] Part part_at(std::uint32_t primitive, double t_seconds) const;
  /// Where a moving object's frame is at `t_seconds`; the identity placement for static objects.
  [[nodiscard]] Placement object_placement(std::uint32_t object, double t_seconds) const;
  [[nodiscard]] const Eigen::AlignedBox3d& bounds() const { return bounds_; }

 private:
  friend class SceneBuilder;
  struct Node {
    Eigen::AlignedBox3d box;
    std::uint32_t first = 0;  ///< leaf: first index into order_; inner: index of the left child
    std::uint32_t count = 0;  ///< leaf: number of primitives; inner: 0 (right child = left + 1)
  };
  struct MovingObject {
    MotionPath path;
    Eigen::AlignedBox3d box_local;
    std::vector<std::uint32_t> primitives;
  };

  void build_bvh(const std::vector<Eigen::AlignedBox3d>& boxes);
  void intersect_static(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double& best,
                        std::optional<std::uint32_t>& best_id) const;
  void intersect_moving(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t_seconds, double& best,
                        std::optional<std::uint32_t>& best_id) const;
  [[nodiscard]] bool covered(const Eigen::Vector3d& point, double t_seconds, std::uint32_t except) const;

  std::vector<Part> parts_;
  std::vector<std::uint32_t> object_of_;
  std::vector<SceneBuilder::Object> objects_;
  std::vector<MovingObject> moving_;
  std::vector<std::uint32_t> order_;  ///< static primitive ids in BVH leaf order
  std::vector<Node> nodes_;
  Eigen::AlignedBox3d bounds_;
};

}  // namespace hmap::sim
