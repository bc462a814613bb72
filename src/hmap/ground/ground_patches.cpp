#include "hmap/ground/ground_patches.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <optional>
#include <random>
#include <span>
#include <string>
#include <unordered_set>
#include <utility>

#include <Eigen/QR>
// nanoflann's dynamic index trips GCC 12's -Wmaybe-uninitialized inside the header (root_bbox is
// filled before use); silence that one warning for this file only.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
#include <nanoflann.hpp>

#include "hmap/core/checked.hpp"
#include "hmap/core/error.hpp"

namespace hmap {

// ---------------------------------------------------------------------------------------------
// GroundModel: a nanoflann kd-tree over the (x, y) patch centres.

struct GroundModel::Index {
  /// nanoflann's dataset adaptor: the patch centres seen as 2D points.
  struct Centres {
    const std::vector<GroundPatch>* patches;
    [[nodiscard]] std::size_t kdtree_get_point_count() const { return patches->size(); }
    [[nodiscard]] double kdtree_get_pt(std::size_t i, std::size_t dim) const {
      return (*patches)[i].center[static_cast<Eigen::Index>(dim)];
    }
    template <class Box>
    bool kdtree_get_bbox(Box& /*box*/) const {
      return false;  // let nanoflann compute it
    }
  };
  // The dynamic variant (a forest of static trees of sizes 2^k) takes one patch at a time in
  // amortized O(log² n): Alg. 4 adds a node per accepted candidate and queries in between.
  using Tree = nanoflann::KDTreeSingleIndexDynamicAdaptor<nanoflann::L2_Simple_Adaptor<double, Centres>,
                                                          Centres, 2, std::uint32_t>;

  // The tree keeps references to `centres` and `patches`: an Index never moves (held by pointer).
  explicit Index(std::vector<GroundPatch> p)
      : patches(std::move(p)), centres{&patches},
        tree(2, centres, nanoflann::KDTreeSingleIndexAdaptorParams(10)) {
    for (const GroundPatch& q : patches) max_half = std::max(max_half, q.half_size);
  }
  Index(const Index&) = delete;
  Index& operator=(const Index&) = delete;

  std::vector<GroundPatch> patches;
  Centres centres;
  Tree tree;
  double max_half = 0.0;  ///< of the patches' half_size, folded as std::max (a NaN one is passed over)
};

GroundModel::GroundModel() = default;

GroundModel::GroundModel(std::vector<GroundPatch> patches) {
  if (!patches.empty()) index_ = std::make_unique<Index>(std::move(patches));
}

GroundModel::GroundModel(const GroundModel& other)
    : index_(other.index_ ? std::make_unique<Index>(other.index_->patches) : nullptr) {}

GroundModel::GroundModel(GroundModel&& other) noexcept = default;

GroundModel& GroundModel::operator=(GroundModel other) noexcept {
  index_ = std::move(other.index_);
  return *this;
}

GroundModel::~GroundModel() = default;

const std::vector<GroundPatch>& GroundModel::patches() const {
  static const std::vector<GroundPatch> kNone;
  return index_ ? index_->patches : kNone;
}

int GroundModel::add(const GroundPatch& patch) {
  if (!index_) {
    index_ = std::make_unique<Index>(std::vector<GroundPatch>{patch});
    return 0;
  }
  index_->patches.push_back(patch);
  index_->max_half = std::max(index_->max_half, patch.half_size);
  const auto i = static_cast<std::uint32_t>(index_->patches.size() - 1);
  index_->tree.addPoints(i, i);
  return static_cast<int>(i);
}

int GroundModel::nearest_index(double x, double y) const {
  if (!index_) return -1;
  const double query[2] = {x, y};
  std::uint32_t i = 0;
  double distance_sq = 0.0;
  nanoflann::KNNResultSet<double, std::uint32_t> result(1);
  result.init(&i, &distance_sq);
  index_->tree.findNeighbors(result, query, nanoflann::SearchParams());
  return result.size() == 0 ? -1 : static_cast<int>(i);
}

double GroundModel::max_half_size() const { return index_ ? index_->max_half : 0.0; }

const GroundPatch* GroundModel::nearest(double x, double y) const {
  const int i = nearest_index(x, y);
  return i < 0 ? nullptr : &index_->patches[static_cast<std::size_t>(i)];
}

std::vector<int> GroundModel::within(double x, double y, double radius) const {
  std::vector<int> out;
  if (!index_ || !(radius >= 0.0)) return out;
  const double query[2] = {x, y};
  std::vector<std::pair<std::uint32_t, double>> found;
  // L2_Simple works on squared distances.
  nanoflann::RadiusResultSet<double, std::uint32_t> result(radius * radius, found);
  index_->tree.findNeighbors(result, query, nanoflann::SearchParams());
  std::sort(found.begin(), found.end(), [](const auto& a, const auto& b) {
    return a.second < b.second || (a.second == b.second && a.first < b.first);
  });
  out.reserve(found.size());
  for (const auto& [i, distance_sq] : found) out.push_back(static_cast<int>(i));
  return out;
}

bool GroundModel::any_within(double x, double y, double radius) const {
  const int i = nearest_index(x, y);
  if (i < 0) return false;
  const Eigen::Vector2d c = index_->patches[static_cast<std::size_t>(i)].center.head<2>();
  return (c - Eigen::Vector2d(x, y)).squaredNorm() <= radius * radius;
}

std::optional<double> GroundModel::ground_height(double x, double y) const {
  const GroundPatch* patch = nearest(x, y);
  if (patch == nullptr) return std::nullopt;
  return patch->height_at(x, y);
}

// ---------------------------------------------------------------------------------------------
// Alg. 4.

namespace {

/// getHeightPoints keeps HVoxel tops within kBandFactor · E_th of the parent's plane: wide enough
/// for the slopes and steps the tests then judge, narrow enough to leave ceilings and table tops.
constexpr double kBandFactor = 3.0;
/// patchGeneration needs this many height points for a plane...
constexpr std::size_t kMinPoints = 5;
/// ...and at least this share of the window's cells measured (not interpolated): IDW alone would
/// extend the border cells of the data into flat patches hanging beyond the map's edge.
constexpr double kMinMeasuredShare = 0.25;
/// A window whose points leave an RMS residual above E_th · kMaxRmsFactor is not a plane: a step
/// of height h inside a window leaves an RMS of about h / 4, so steps above ~E_th are refused
/// here instead of being smoothed into a slope and climbed.
constexpr double kMaxRmsFactor = 0.25;
/// Expansions closer than kMinSpacing · d_n to a patch already in the tree add nothing.
constexpr double kMinSpacing = 0.5;
/// Start-patch candidates tried after the hint itself (cells of the chosen histogram bin).
constexpr std::size_t kMaxSeedTries = 16;
/// The ground the sensor stands on is the lowest *extensive* surface below it: the start height is
/// the lowest bin covering at least this share of the most extensive bin's cells. Counting cells
/// (area), not HVoxels, keeps a wall's or a car body's stack of tops from outvoting the floor.
constexpr double kMinSeedAreaShare = 0.5;
/// A neighbourhood is used only when its widest bin covers at least this many patch windows of
/// cells: the first few cells around a sensor are its own mount, the car's body or a table edge,
/// not ground. When no neighbourhood has that much, one window will do (the floor of a small
/// enclosure, sim `boxes`: 2 m x 3 m).
constexpr double kMinSeedWindows[] = {2.0, 1.0};
/// The tracker has lost the ground when no patch lies within this many d_n of the sensor (a bit
/// over the blind footprint of a spinning LiDAR at car height: 3.7 m for an HDL-64 at 1.73 m, 8 d_n
/// = 7.2 m outdoors; 3.2 m indoors, where a camera at 1.5 m sees the floor from about 1 m on).
constexpr double kLostRadius = 8.0;
/// Directions tried around a root for a neighbour (see supported()).
constexpr int kSupportDirections = 16;
/// The neighbourhood of the hint doubles up to this many times d_n while it holds no HVoxel.
constexpr double kMaxHistogramRadius = 16.0;

void validate(const Eigen::Vector3d& hint, const GroundParams& p, double window) {
  const auto require = [](bool ok, const std::string& what) {
    if (!ok) throw Error("extract_ground: " + what);
  };
  require(hint.allFinite(), "the hint must be finite");
  require(p.iterations >= 0, "ground.iterations (K) must be >= 0");
  require(std::isfinite(p.normal_threshold) && p.normal_threshold >= 0.0,
          "ground.normal_threshold (N_th) must be finite and >= 0");
  require(std::isfinite(p.elevation_threshold) && p.elevation_threshold > 0.0,
          "ground.elevation_threshold (E_th) must be finite and > 0");
  require(std::isfinite(p.expansion_distance) && p.expansion_distance > 0.0,
          "ground.expansion_distance (d_n) must be finite and > 0");
  require(std::isfinite(window) && window > 0.0, "the window half-size must be finite and > 0");
}

/// A horizontal plane through `center`: the reference of the start patch.
GroundPatch horizontal_patch(const Eigen::Vector3d& center, double half_size) {
  return {center, Eigen::Vector3d::UnitZ(), half_size, -1};
}

/// The points of one window (getHeightPoints) and how many of its cells held data.
struct HeightPoints {
  std::vector<Eigen::Vector3d> points;
  int measured_cells = 0;  ///< cells with a top in the band
  int window_cells = 0;    ///< cells whose centre lies in the window
};

class PatchExplorer {
 public:
  /// Explores `tree` (Alg. 4's G, possibly holding patches of earlier runs) with `rng`.
  PatchExplorer(const HMap& map, const GroundParams& params, double window, GroundModel& tree,
                std::mt19937_64& rng)
      : map_(map), params_(params), window_(window), model_(tree), rng_(rng) {}

  /// Alg. 4 as the paper runs it: a tree seeded under the hint, K iterations, the search square
  /// following the accepted centres.
  GroundResult run(const Eigen::Vector3d& hint) {
    GroundResult result;
    // Alg. 4 lines 1-3.
    if (!seed(hint)) return result;
    result.seeded = true;
    iterate(params_.iterations, /*follow_tree=*/true, result);
    return result;
  }

  /// The same iterations on a tree that persists across scans: x_rand is drawn from the square of
  /// half-size `reach` around the hint (the part of the map the latest scan can have changed),
  /// and a root is seeded under the hint only when no patch lies within d_n of it yet.
  GroundResult grow(const Eigen::Vector3d& hint, double reach) {
    GroundResult result;
    // Recovery: a tree that is far from the sensor (never reached this part of the map, or lost
    // it behind a door or a ramp) gets a new root from the footprint under the sensor.
    const bool lost = !model_.any_within(hint.x(), hint.y(), std::min(reach, kLostRadius * params_.expansion_distance));
    if (lost && seed(hint)) result.seeded = true;
    if (model_.empty()) return result;
    search_center_ = hint.head<2>();
    search_half_extent_ = reach;
    iterate(params_.iterations, /*follow_tree=*/false, result);
    return result;
  }

 private:
  /// Lines 2-3, over neighbourhoods doubling from d_n: the first one whose histogram yields a
  /// root that fits. Around a sensor the nearest neighbourhoods hold only the inner rim of the
  /// range hole, where no plane fits.
  bool seed(const Eigen::Vector3d& hint) {
    for (const double min_windows : kMinSeedWindows) {
      for (double radius = params_.expansion_distance; radius <= kMaxHistogramRadius * params_.expansion_distance;
           radius *= 2.0) {
        const auto start = neighborhood_histogram(hint, radius, min_windows);
        if (start && initialize_tree(*start)) return true;
      }
    }
    return false;
  }

  void iterate(int iterations, bool follow_tree, GroundResult& result) {
    const double d_n = params_.expansion_distance;
    for (int k = 0; k < iterations; ++k) {
      ++result.iterations;
      const Eigen::Vector2d x_rand = sample_random_direction();
      const int near = nearest_node(x_rand);
      const GroundPatch x_near = model_.patches()[static_cast<std::size_t>(near)];
      const Eigen::Vector2d x_expansion = project_to(x_near, x_rand);
      if (model_.any_within(x_expansion.x(), x_expansion.y(), kMinSpacing * d_n)) {
        ++result.skipped;
        continue;
      }
      const auto points = get_height_points(x_expansion, x_near);
      auto p_local = patch_generation(points, x_expansion);
      if (!p_local) {
        ++result.rejected;
        continue;
      }
      // Lines 10-20: connect to x_near, else to the first neighbour within d_n that agrees.
      int parent = connects(*p_local, x_near) ? near : -1;
      if (parent < 0) {
        for (const int node : nearest_nodes(x_expansion)) {
          if (node != near && connects(*p_local, model_.patches()[static_cast<std::size_t>(node)])) {
            parent = node;
            break;
          }
        }
      }
      if (parent < 0) {
        ++result.rejected;
        continue;
      }
      p_local->parent = parent;
      add_node(*p_local);
      if (follow_tree) update_search_space(x_expansion);
      ++result.accepted;
    }
  }

  struct Start {
    Eigen::Vector3d p0;                      ///< hint (x, y) at the height of the chosen bin
    std::vector<Eigen::Vector2d> fallbacks;  ///< cells of that bin, nearest to the hint first
  };

  /// Line 2: histogram of the HVoxel tops below the hint in the cells within `radius`, in bins of
  /// E_th; the lowest bin covering half the widest bin's cells gives the start height; none when
  /// the widest bin covers fewer than `min_windows` patch windows of cells.
  std::optional<Start> neighborhood_histogram(const Eigen::Vector3d& hint, double radius, double min_windows) const {
    struct Bin {
      int count = 0;
      double sum = 0.0;
      std::vector<Eigen::Vector2d> cells;
    };
    const double bin_size = params_.elevation_threshold;
    {
      std::map<long long, Bin> bins;
      for_each_cell(hint.head<2>(), radius, [&](const Eigen::Vector2d& xy, const ColumnView& column) {
        if ((xy - hint.head<2>()).norm() > radius) return;
        for (const HVoxel& v : column.hvoxels()) {
          if (v.z_max > hint.z()) continue;
          // Checked: an HVoxel at 3e38 m, or ground.elevation_threshold = 0, made the cast undefined.
          const std::optional<long long> index = floor_to<long long>(v.z_max / bin_size);
          if (!index) continue;
          Bin& bin = bins[*index];
          ++bin.count;
          bin.sum += v.z_max;
          if (bin.cells.empty() || bin.cells.back() != xy) bin.cells.push_back(xy);
        }
      });
      if (bins.empty()) return std::nullopt;
      std::size_t widest = 0;
      for (const auto& [index, bin] : bins) widest = std::max(widest, bin.cells.size());
      const double s_cell = map_.cell_size();
      const double window_cells = std::pow(2.0 * window_ / s_cell, 2.0);
      if (static_cast<double>(widest) < min_windows * window_cells) return std::nullopt;
      const Bin* best = nullptr;
      for (const auto& [index, bin] : bins) {  // ascending heights: the lowest extensive bin
        if (static_cast<double>(bin.cells.size()) >= kMinSeedAreaShare * static_cast<double>(widest)) {
          best = &bin;
          break;
        }
      }
      Start start{{hint.x(), hint.y(), best->sum / best->count}, best->cells};
      // Fallback roots: the bin's cells whose window holds most cells of the bin, nearest first
      // among equals. The cells nearest to a sensor-mounted hint lie on the innermost scan ring
      // (a thin arc no plane can be fitted to); the best-covered ones make a root that fits.
      const double s = map_.cell_size();
      // The bin's cells are cells of the map: HMap::key_of holds them (its keys lie within ±2^30).
      const auto key_of = [&](const Eigen::Vector2d& xy) {
        const std::optional<CellKey> key = map_.key_of(xy.x(), xy.y());
        if (!key) throw Error("ground patches: a seed cell lies beyond the map's key range");
        return *key;
      };
      std::unordered_set<CellKey, CellKeyHash> in_bin;
      for (const Eigen::Vector2d& xy : best->cells) in_bin.insert(key_of(xy));
      // window_ is ground.window_size, ranged; floor(window / cell) a few cells.
      const auto reach = checked_count<std::int32_t>(std::floor(window_ / s), 1 << 10, "the ground seed's window");
      std::vector<std::pair<int, double>> score(best->cells.size());  // (cells of the bin around, distance²)
      for (std::size_t c = 0; c < best->cells.size(); ++c) {
        const CellKey k = key_of(best->cells[c]);
        int around = 0;
        for (std::int32_t di = -reach; di <= reach; ++di) {
          for (std::int32_t dj = -reach; dj <= reach; ++dj) around += in_bin.count({k.i + di, k.j + dj}) > 0 ? 1 : 0;
        }
        score[c] = {around, (best->cells[c] - hint.head<2>()).squaredNorm()};
      }
      std::vector<std::size_t> order(best->cells.size());
      for (std::size_t c = 0; c < order.size(); ++c) order[c] = c;
      std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
        return score[a].first != score[b].first ? score[a].first > score[b].first : score[a].second < score[b].second;
      });
      start.fallbacks.clear();
      for (std::size_t c = 0; c < order.size() && c < kMaxSeedTries; ++c) start.fallbacks.push_back(best->cells[order[c]]);
      return start;
    }
    return std::nullopt;
  }

  /// Line 3: the root patch at p0, fitted against the horizontal plane at the start height; when
  /// the hint's own window holds too few points, the nearest cells of the chosen bin are tried.
  bool initialize_tree(const Start& start) {
    std::vector<Eigen::Vector2d> candidates{start.p0.head<2>()};
    candidates.insert(candidates.end(), start.fallbacks.begin(), start.fallbacks.end());
    for (const Eigen::Vector2d& xy : candidates) {
      const GroundPatch reference = horizontal_patch({xy.x(), xy.y(), start.p0.z()}, window_);
      if (model_.any_within(xy.x(), xy.y(), kMinSpacing * params_.expansion_distance)) continue;
      auto root = patch_generation(get_height_points(xy, reference), xy);
      if (root && std::abs(root->center.z() - start.p0.z()) <= params_.elevation_threshold && supported(*root)) {
        add_node(*root);
        search_center_ = xy;
        search_half_extent_ = 2.0 * params_.expansion_distance;
        return true;
      }
    }
    return false;
  }

  /// Line 5: x_rand uniform in the search square.
  Eigen::Vector2d sample_random_direction() {
    std::uniform_real_distribution<double> u(-search_half_extent_, search_half_extent_);
    const double dx = u(rng_);
    const double dy = u(rng_);
    return search_center_ + Eigen::Vector2d(dx, dy);
  }

  /// Line 6: the tree node nearest to x_rand.
  int nearest_node(const Eigen::Vector2d& x_rand) const {
    return model_.nearest_index(x_rand.x(), x_rand.y());
  }

  /// Line 7, eq. (2): one step of d_n from x_near toward x_rand.
  Eigen::Vector2d project_to(const GroundPatch& x_near, const Eigen::Vector2d& x_rand) const {
    const Eigen::Vector2d from = x_near.center.head<2>();
    const double angle = std::atan2(x_rand.y() - from.y(), x_rand.x() - from.x());
    return from + params_.expansion_distance * Eigen::Vector2d(std::cos(angle), std::sin(angle));
  }

  /// Line 8: one height per window cell. Tops within the band of the reference plane are kept
  /// (all of them when a cell holds several); a cell with none takes the IDW (power 2) of its 8
  /// neighbours' tops in the band, when there are any. Each column of the window and its one-cell
  /// rim is read at most once (an empty cell's IDW reads up to 8 neighbours, shared by the next).
  HeightPoints get_height_points(const Eigen::Vector2d& center,
                                 const GroundPatch& reference) const {
    HeightPoints out;
    std::vector<Eigen::Vector3d>& points = out.points;
    const double band = kBandFactor * params_.elevation_threshold;
    const double s = map_.cell_size();
    const auto first = map_.key_of(center.x() - window_, center.y() - window_);
    const auto last = map_.key_of(center.x() + window_, center.y() + window_);
    if (!first || !last) return out;
    // The rim's cells: (i, j) is at (i − first.i + 1) · rim_width + (j − first.j + 1).
    const std::int32_t rim_width = last->j - first->j + 3;
    cell_tops_.assign(static_cast<std::size_t>(last->i - first->i + 3) * static_cast<std::size_t>(rim_width), {-1, 0});
    tops_.clear();
    const auto tops_of = [&](std::int32_t i, std::int32_t j) {
      std::pair<int, int>& slot = cell_tops_[static_cast<std::size_t>((i - first->i + 1) * rim_width + (j - first->j + 1))];
      if (slot.first < 0) {
        slot.first = static_cast<int>(tops_.size());
        tops_in_band({i, j}, reference, band, tops_);
        slot.second = static_cast<int>(tops_.size());
      }
      return std::span<const double>(tops_.data() + slot.first, tops_.data() + slot.second);
    };
    for (std::int32_t i = first->i; i <= last->i; ++i) {
      for (std::int32_t j = first->j; j <= last->j; ++j) {
        const Eigen::Vector2d xy((i + 0.5) * s, (j + 0.5) * s);  // HMap::cell_center
        if ((xy - center).cwiseAbs().maxCoeff() > window_ + 1e-9) continue;
        ++out.window_cells;
        const auto tops = tops_of(i, j);
        for (const double z : tops) points.emplace_back(xy.x(), xy.y(), z);
        if (!tops.empty()) {
          ++out.measured_cells;
          continue;
        }
        double weighted = 0.0;
        double weights = 0.0;
        for (std::int32_t di = -1; di <= 1; ++di) {
          for (std::int32_t dj = -1; dj <= 1; ++dj) {
            if (di == 0 && dj == 0) continue;
            const double w = 1.0 / (s * s * (di * di + dj * dj));  // 1 / d^2
            for (const double z : tops_of(i + di, j + dj)) {
              weighted += w * z;
              weights += w;
            }
          }
        }
        if (weights > 0.0) points.emplace_back(xy.x(), xy.y(), weighted / weights);
      }
    }
    return out;
  }

  /// Line 9: least-squares plane z = a x + b y + c through the points (coordinates taken
  /// relative to the window centre); none for too few points or measured cells, collinear
  /// points or a large RMS.
  std::optional<GroundPatch> patch_generation(const HeightPoints& height_points,
                                              const Eigen::Vector2d& center) const {
    const std::vector<Eigen::Vector3d>& points = height_points.points;
    if (points.size() < kMinPoints ||
        height_points.measured_cells < kMinMeasuredShare * height_points.window_cells) {
      return std::nullopt;
    }
    const auto n = static_cast<Eigen::Index>(points.size());
    Eigen::MatrixX3d A(n, 3);
    Eigen::VectorXd z(n);
    for (Eigen::Index r = 0; r < n; ++r) {
      const Eigen::Vector3d& p = points[static_cast<std::size_t>(r)];
      A.row(r) << p.x() - center.x(), p.y() - center.y(), 1.0;
      z(r) = p.z();
    }
    const Eigen::ColPivHouseholderQR<Eigen::MatrixX3d> qr(A);
    if (qr.rank() < 3) return std::nullopt;
    const Eigen::Vector3d abc = qr.solve(z);
    const double rms = std::sqrt((A * abc - z).squaredNorm() / static_cast<double>(n));
    // The tops' own noise adds in quadrature to what a step leaves: without it a floor seen by a
    // depth camera (σ of 1-2 cm at 2-3 m) fails the indoor E_th / 4 = 12.5 mm test.
    const double step_rms = kMaxRmsFactor * params_.elevation_threshold;
    if (!(rms <= std::hypot(step_rms, params_.top_noise))) return std::nullopt;
    const Eigen::Vector3d normal = Eigen::Vector3d(-abc.x(), -abc.y(), 1.0).normalized();
    return GroundPatch{{center.x(), center.y(), abc.z()}, normal, window_, -1};
  }

  /// Lines 10-11 (and 17-18): normals within N_th, read as 1 − |n1·n2| <= N_th, and the new
  /// centre within E_th of the node's plane evaluated at that centre.
  bool connects(const GroundPatch& p_local, const GroundPatch& node) const {
    const double normal_gap = 1.0 - std::abs(p_local.normal.dot(node.normal));
    const double elevation_gap =
        std::abs(p_local.center.z() - node.height_at(p_local.center.x(), p_local.center.y()));
    return normal_gap <= params_.normal_threshold && elevation_gap <= params_.elevation_threshold;
  }

  /// A root must be part of an extensive surface: one of the patches a step d_n away (in
  /// kSupportDirections directions) fits and connects to it, as Alg. 4's first expansion would.
  /// A table top or a car roof smaller than d_n has no such neighbour; a scan ring on the ground
  /// has one along its tangent (hence the fine angular steps: the rings of a VLP-16 lie > d_n apart).
  bool supported(const GroundPatch& root) const {
    const double d_n = params_.expansion_distance;
    for (int k = 0; k < kSupportDirections; ++k) {
      const double angle = 2.0 * M_PI * k / kSupportDirections;
      const Eigen::Vector2d xy = root.center.head<2>() + d_n * Eigen::Vector2d(std::cos(angle), std::sin(angle));
      const auto neighbour = patch_generation(get_height_points(xy, root), xy);
      if (neighbour && connects(*neighbour, root)) return true;
    }
    return false;
  }

  /// Line 15: the nodes within d_n of x_expansion, nearest first.
  std::vector<int> nearest_nodes(const Eigen::Vector2d& x_expansion) const {
    return model_.within(x_expansion.x(), x_expansion.y(), params_.expansion_distance);
  }

  /// Lines 13 and 20: the search square moves to the mean of the accepted centres and grows to
  /// keep two expansion steps of margin around x_expansion.
  void update_search_space(const Eigen::Vector2d& x_expansion) {
    center_sum_ += x_expansion;
    search_center_ = center_sum_ / static_cast<double>(added_);
    search_half_extent_ =
        std::max(search_half_extent_, (x_expansion - search_center_).cwiseAbs().maxCoeff() +
                                          2.0 * params_.expansion_distance);
  }

  /// Adds a node to the tree and its kd-tree.
  void add_node(const GroundPatch& patch) {
    if (added_ == 0) center_sum_ = patch.center.head<2>();
    ++added_;
    model_.add(patch);
  }

  void tops_in_band(const CellKey& key, const GroundPatch& reference, double band,
                    std::vector<double>& out) const {
    const ColumnView column = map_.column(key);
    if (column.empty()) return;
    const double s = map_.cell_size();
    const double z_ref = reference.height_at((key.i + 0.5) * s, (key.j + 0.5) * s);  // at HMap::cell_center
    for (const HVoxel& v : column.hvoxels()) {
      if (std::abs(v.z_max - z_ref) < band) out.push_back(v.z_max);
    }
  }

  /// Calls f(cell centre, column) for the non-empty columns of the square of half-size
  /// `radius` around `center`.
  template <typename F>
  void for_each_cell(const Eigen::Vector2d& center, double radius, F&& f) const {
    const auto first = map_.key_of(center.x() - radius, center.y() - radius);
    const auto last = map_.key_of(center.x() + radius, center.y() + radius);
    if (!first || !last) return;
    for (std::int32_t i = first->i; i <= last->i; ++i) {
      for (std::int32_t j = first->j; j <= last->j; ++j) {
        const ColumnView column = map_.column(CellKey{i, j});
        if (!column.empty()) f(map_.cell_center({i, j}), column);
      }
    }
  }

  const HMap& map_;
  const GroundParams& params_;
  double window_;
  GroundModel& model_;    // the tree G with its kd-tree
  std::mt19937_64& rng_;
  int added_ = 0;         // patches this explorer added
  Eigen::Vector2d center_sum_ = Eigen::Vector2d::Zero();
  Eigen::Vector2d search_center_ = Eigen::Vector2d::Zero();
  double search_half_extent_ = 0.0;
  // Scratch of get_height_points: the tops read so far, and per rim cell its [begin, end) in them
  // (begin −1: not read yet).
  mutable std::vector<double> tops_;
  mutable std::vector<std::pair<int, int>> cell_tops_;
};

}  // namespace

GroundResult extract_ground(const HMap& map, const Eigen::Vector3d& hint,
                            const GroundParams& params, double window) {
  validate(hint, params, window);
  GroundModel tree;
  std::mt19937_64 rng(params.seed);
  GroundResult result = PatchExplorer(map, params, window, tree, rng).run(hint);
  result.patches = tree.patches();
  return result;
}

GroundResult extract_ground(const HMap& map, const Eigen::Vector3d& hint,
                            const GroundParams& params) {
  return extract_ground(map, hint, params, params.expansion_distance / 2.0);
}

GroundTracker::GroundTracker(const GroundParams& params, double window)
    : params_(params), window_(window), rng_(params.seed) {
  validate(Eigen::Vector3d::Zero(), params_, window_);
}

GroundTracker::GroundTracker(const GroundParams& params) : GroundTracker(params, params.expansion_distance / 2.0) {}

GroundTracker::GroundTracker(const GroundParams& params, double window, std::vector<GroundPatch> patches)
    : GroundTracker(params, window) {
  for (const GroundPatch& p : patches) tree_.add(p);
}

GroundResult GroundTracker::update(const HMap& map, const Eigen::Vector3d& hint, double reach) {
  validate(hint, params_, window_);
  if (!(std::isfinite(reach) && reach > 0.0)) throw Error("GroundTracker: the reach must be finite and > 0");
  // The random stream restarts from the seed and the tree's size: what an update grows is a
  // function of the map, the tree and the scan alone, so a map continued from its saved layers
  // (hmap map --continue) grows the same patches as one built in a single run.
  std::uint64_t z = params_.seed + 0x9E3779B97F4A7C15ULL * (static_cast<std::uint64_t>(tree_.patches().size()) + 1);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;  // splitmix64's finaliser: nearby sizes, unrelated streams
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  rng_.seed(z ^ (z >> 31));
  return PatchExplorer(map, params_, window_, tree_, rng_).grow(hint, reach);
}

}  // namespace hmap
