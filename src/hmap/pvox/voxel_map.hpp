#pragma once
// The probabilistically voxelated grid: a sparse, unbounded 3D grid of cubic voxels of edge e
// (hashed blocks of 4³ voxels allocated on first touch). Each voxel counts the points that fell
// in it (hits n), the rays that crossed it (misses m), and keeps the first and second moments of
// its points so that surfaces can be measured below the voxel size.
//
// Occupancy probability of a voxel, the "relaxed logit" (the seed's eq. (10), made explicit):
//
//   l_hit  = ln(1 + e² / (2 σ_m²))                    evidence of one point
//   L(n,m) = clamp(n · l_hit − m · l_miss, l_min, l_max)
//   p(n,m) = 1 / (1 + exp(−L))
//
// where σ_m² is the measurement variance. l_hit is the logit of p_hit = ½ (1 + h) with
// h = (e/2)² / ((e/2)² + σ_m²): a point is strong evidence when the voxel is wide compared with the
// measurement noise, and none at all (l_hit → 0) when the voxel is much smaller than the noise.
// The clamp "relaxes" the logit so a voxel never becomes certain (p stays in (0, 1)) and can
// change its mind (OctoMap's clamping: l_min = −2, l_max = 3.5, i.e. p in [0.12, 0.97]).
// Unseen space has p = 0.5.

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <unordered_map>
#include <vector>

#include "hmap/core/budget.hpp"
#include "hmap/core/types.hpp"

namespace hmap::pvox {

/// How rays lower the probability of the voxels they cross.
enum class FreeSpace : std::uint8_t {
  kOff,   ///< only hits (the seed)
  kRays,  ///< every voxel a ray crosses before its end point gets a miss (3D DDA)
};

/// The probability function's parameters.
struct ProbabilityModel {
  double measurement_variance = 100e-6;  ///< [m²] σ_m² (seed: 100 mm²)
  double logit_min = -2.0;               ///< [-] clamp of L
  double logit_max = 3.5;                ///< [-]
  double miss_logit = 0.4;               ///< [-] l_miss, evidence of one ray through the voxel

  /// Throws hmap::Error for a non-positive variance, l_min >= 0, l_max <= 0 or a negative l_miss.
  void validate() const;
  /// l_hit for voxels of edge `edge` [m].
  [[nodiscard]] double hit_logit(double edge) const;
  /// L(n, m) for voxels of edge `edge`.
  [[nodiscard]] double logit(double edge, std::uint64_t hits, std::uint64_t misses) const;
  /// p(n, m) for voxels of edge `edge`.
  [[nodiscard]] double probability(double edge, std::uint64_t hits, std::uint64_t misses) const;
};

/// Index of a voxel: voxel (i, j, k) covers [i·e, (i+1)·e) × [j·e, (j+1)·e) × [k·e, (k+1)·e).
struct VoxelKey {
  std::int32_t i = 0;
  std::int32_t j = 0;
  std::int32_t k = 0;
  friend bool operator==(const VoxelKey&, const VoxelKey&) = default;
  friend auto operator<=>(const VoxelKey&, const VoxelKey&) = default;
};

struct VoxelKeyHash {
  std::size_t operator()(const VoxelKey& key) const noexcept;
};

/// What a voxel holds. Moments are of the point offsets from the voxel centre (small numbers,
/// exact enough in float).
struct Voxel {
  std::uint32_t hits = 0;
  std::uint32_t misses = 0;
  std::array<float, 3> sum{};      ///< Σ d            [m]
  std::array<float, 6> sum_sq{};   ///< Σ d dᵀ: xx, xy, xz, yy, yz, zz [m²]
  [[nodiscard]] bool empty() const { return hits == 0 && misses == 0; }
};

/// A voxel's points summarised: mean, covariance, and the plane through them.
struct VoxelMoments {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();        ///< [m], map frame
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();  ///< [m²]
};

/// One voxel as the map shows it to the outside.
struct VoxelView {
  VoxelKey key;
  Eigen::Vector3d centre;  ///< [m]
  double probability = 0.5;
  std::uint32_t hits = 0;
  std::uint32_t misses = 0;
};

/// A probability and its spatial gradient.
struct FieldSample {
  double probability = 0.5;
  Eigen::Vector3d gradient = Eigen::Vector3d::Zero();  ///< [1/m]
};

/// Counts of an insertion.
struct InsertStats {
  std::size_t hits = 0;           ///< points counted
  std::size_t rejected = 0;       ///< NaN, infinite, or outside [min_range, max_range]
  std::size_t misses = 0;         ///< voxel crossings counted by rays
};

struct InsertParams {
  double min_range = 0.0;    ///< [m] from the sensor
  double max_range = 60.0;   ///< [m] (UTM-30LX: 60 m)
  FreeSpace free_space = FreeSpace::kOff;
};

class VoxelMap {
 public:
  static constexpr int kBlockBits = 2;  ///< blocks of 4³ voxels (2.8 KiB): small enough for sparse outdoor scans
  static constexpr int kBlockSide = 1 << kBlockBits;
  static constexpr int kBlockVoxels = kBlockSide * kBlockSide * kBlockSide;

  /// Throws hmap::Error for a non-positive or non-finite edge, or an invalid model.
  explicit VoxelMap(double edge, const ProbabilityModel& model = {});
  VoxelMap(const VoxelMap& other);  ///< deep copy of the blocks
  VoxelMap& operator=(const VoxelMap& other);
  VoxelMap(VoxelMap&&) noexcept = default;
  VoxelMap& operator=(VoxelMap&&) noexcept = default;
  ~VoxelMap() = default;

  [[nodiscard]] double edge() const { return edge_; }
  [[nodiscard]] const ProbabilityModel& model() const { return model_; }

  /// Re-voxelates the map at a new edge (the seed: the map changes with every pose estimate).
  /// Each voxel moves, with its counts and moments, to the new voxel holding its points' mean;
  /// moments are carried exactly, misses go with them.
  void set_edge(double edge);

  [[nodiscard]] VoxelKey key_of(const Eigen::Vector3d& p_map) const;
  [[nodiscard]] Eigen::Vector3d centre(const VoxelKey& key) const;

  /// Counts `p_map` as a hit in its voxel.
  void add_hit(const Eigen::Vector3d& p_map);
  /// Counts a miss in voxel `key`.
  void add_miss(const VoxelKey& key);
  /// Sets a voxel from its counts and the mean of its points (decoders); the second moment is
  /// that of all points at the mean.
  void set_voxel(const VoxelKey& key, std::uint32_t hits, std::uint32_t misses, const Eigen::Vector3d& mean);

  /// Inserts a scan taken at T_map_sensor: hits at the points, misses along the rays if asked.
  InsertStats insert(const PointCloud& points_sensor, const Pose& T_map_sensor, const InsertParams& params);

  /// The voxel `key`, or nullptr where nothing was counted.
  [[nodiscard]] const Voxel* find(const VoxelKey& key) const;
  /// p of voxel `key`; 0.5 where nothing was counted.
  [[nodiscard]] double probability(const VoxelKey& key) const;
  /// p of the voxel holding `p_map`.
  [[nodiscard]] double probability_at(const Eigen::Vector3d& p_map) const;
  /// The continuous field: p trilinearly interpolated between voxel centres, and its gradient
  /// (the seed's "vector field": −∇p points away from obstacles).
  [[nodiscard]] FieldSample field_at(const Eigen::Vector3d& p_map) const;
  /// Mean and covariance of the points of a voxel (zero covariance for fewer than two points).
  [[nodiscard]] static VoxelMoments moments(const Voxel& voxel, const Eigen::Vector3d& centre);

  /// Calls `visit(key, voxel)` for every voxel holding a count, in no particular order.
  void for_each(const std::function<void(const VoxelKey&, const Voxel&)>& visit) const;
  /// Voxels with p > `threshold`, sorted by key.
  [[nodiscard]] std::vector<VoxelView> occupied(double threshold = 0.5) const;
  /// Every voxel holding a count, sorted by key.
  [[nodiscard]] std::vector<VoxelView> voxels() const;

  [[nodiscard]] std::size_t voxel_count() const { return voxel_count_; }
  [[nodiscard]] std::size_t block_count() const { return blocks_.size(); }
  /// Heap bytes held by the blocks and the hash table (estimate).
  [[nodiscard]] std::size_t memory_bytes() const;
  /// A new block beyond `budget` throws hmap::Error before it is allocated: noisy points each
  /// touch a block of their own (2.8 KiB per point), and a file's voxels are its claim.
  void set_budget(const MemoryBudget& budget) { budget_ = budget; }
  [[nodiscard]] const MemoryBudget& budget() const { return budget_; }

 private:
  struct Block {
    std::array<Voxel, kBlockVoxels> voxels{};
  };
  Voxel& touch(const VoxelKey& key);
  [[nodiscard]] VoxelView view(const VoxelKey& key, const Voxel& voxel) const;

  double edge_;
  double inv_edge_;
  ProbabilityModel model_;
  std::unordered_map<VoxelKey, std::unique_ptr<Block>, VoxelKeyHash> blocks_;
  std::size_t voxel_count_ = 0;
  MemoryBudget budget_;
};

}  // namespace hmap::pvox
