#pragma once
// Ground extraction by RRT patch exploration (section IV-A, Alg. 4, eq. 2).
//
// The ground is a tree of patches: small local planes fitted by least squares to the HVoxel tops
// of a square window. The tree grows from a start patch found under a hint (the robot) and only
// connects a new patch to a node whose normal and elevation agree with it, so steps higher than
// E_th and table tops are not taken for ground.

#include <memory>
#include <optional>
#include <random>
#include <vector>

#include <Eigen/Core>

#include "hmap/core/params.hpp"
#include "hmap/maps/hmap.hpp"

namespace hmap {

/// A local ground plane: a square of half-size `half_size` centred on `center`.
struct GroundPatch {
  Eigen::Vector3d center;  ///< [m] map frame; z is the plane's height at (x, y)
  Eigen::Vector3d normal;  ///< unit, z > 0
  double half_size;        ///< [m] half the edge of the window the plane was fitted to
  int parent;              ///< index of the node it connects to in the tree, -1 for the root

  /// Height of the patch's plane at (x, y) [m].
  [[nodiscard]] double height_at(double x, double y) const {
    return center.z() - (normal.x() * (x - center.x()) + normal.y() * (y - center.y())) / normal.z();
  }
};

/// What Alg. 4 produced: the tree of patches and how the K iterations went.
struct GroundResult {
  std::vector<GroundPatch> patches;  ///< patches[0] is the root when `seeded`
  int iterations = 0;                ///< iterations run (K, or 0 when not seeded)
  int accepted = 0;                  ///< candidates connected to the tree
  int rejected = 0;                  ///< candidates without a plane or without a valid connection
  int skipped = 0;                   ///< expansions closer than d_n / 2 to a patch already there
  bool seeded = false;               ///< false when no start patch could be found near the hint
};

/// Queries on a set of patches through a kd-tree of their (x, y) centres, which grows as patches
/// are added.
class GroundModel {
 public:
  GroundModel();
  explicit GroundModel(std::vector<GroundPatch> patches);
  GroundModel(const GroundModel& other);
  GroundModel(GroundModel&& other) noexcept;
  GroundModel& operator=(GroundModel other) noexcept;
  ~GroundModel();

  [[nodiscard]] const std::vector<GroundPatch>& patches() const;
  [[nodiscard]] bool empty() const { return index_ == nullptr; }
  [[nodiscard]] std::size_t size() const { return empty() ? 0 : patches().size(); }

  /// The largest half_size [m] of the patches (0 without any), kept as they are added: what a
  /// search near a point needs to know without a pass over every patch.
  [[nodiscard]] double max_half_size() const;
  /// Adds a patch (Alg. 4's addNode); returns its index. Queries stay valid without a rebuild.
  int add(const GroundPatch& patch);

  /// The patch whose centre is nearest to (x, y) in 2D, or nullptr when there is none.
  [[nodiscard]] const GroundPatch* nearest(double x, double y) const;
  /// Index of that patch, or -1 when there is none.
  [[nodiscard]] int nearest_index(double x, double y) const;
  /// Whether some patch centre lies within `radius` [m] of (x, y).
  [[nodiscard]] bool any_within(double x, double y, double radius) const;
  /// Indices of the patches whose centre lies within `radius` [m] of (x, y), nearest first.
  [[nodiscard]] std::vector<int> within(double x, double y, double radius) const;
  /// Height [m] of the nearest patch's plane at (x, y); nullopt when there is no patch.
  [[nodiscard]] std::optional<double> ground_height(double x, double y) const;

 private:
  struct Index;
  std::unique_ptr<Index> index_;  // null when there are no patches
};

/// Alg. 4 from `hint` (e.g. the robot position, z at the sensor height or below) with windows of
/// half-size `window` [m]. Throws hmap::Error for non-finite hints or out-of-domain parameters.
[[nodiscard]] GroundResult extract_ground(const HMap& map, const Eigen::Vector3d& hint,
                                          const GroundParams& params, double window);
/// As above with windows of half-size d_n / 2: neighbouring patches then just touch.
[[nodiscard]] GroundResult extract_ground(const HMap& map, const Eigen::Vector3d& hint,
                                          const GroundParams& params);

/// Alg. 4 kept running while the map grows: the tree persists from scan to scan, and each
/// update() runs K more iterations with x_rand drawn around the robot, so the patches follow the
/// robot at a fixed cost per scan instead of being rebuilt over the whole map. Patches, once
/// accepted, stay (the ground does not move). `GroundResult::patches` stays empty: the tree is
/// `patches()`.
class GroundTracker {
 public:
  /// Windows of half-size `window` [m] (default d_n / 2). Throws hmap::Error for invalid params.
  GroundTracker(const GroundParams& params, double window);
  explicit GroundTracker(const GroundParams& params);
  /// Continues a tree saved earlier.
  GroundTracker(const GroundParams& params, double window, std::vector<GroundPatch> patches);

  /// K iterations sampling the square of half-size `reach` [m] around `hint` (the sensor);
  /// seeds a new root under the hint when no patch lies within `reach` of it.
  GroundResult update(const HMap& map, const Eigen::Vector3d& hint, double reach);

  [[nodiscard]] const GroundModel& model() const { return tree_; }
  [[nodiscard]] const std::vector<GroundPatch>& patches() const { return tree_.patches(); }
  [[nodiscard]] double window() const { return window_; }

 private:
  GroundParams params_;
  double window_;
  std::mt19937_64 rng_;
  GroundModel tree_;
};

}  // namespace hmap
