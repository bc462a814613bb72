#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <unordered_map>

#include "hmap/core/error.hpp"
#include "hmap/maps/ray_trace.hpp"
#include "hmap/occupancy/occupancy_update.hpp"

namespace hmap {
namespace occupancy_updater_test {

Params params() {
  Params p = outdoor_preset();
  p.map.cell_size = 0.2;
  return p;
}

/// Which patch is a cell's local ground in the twin.
enum class TwinGround {
  kNearestToCell,   ///< the exact nearest patch to the cell's centre (one patch covering all)
  kNearestToBlock,  ///< the updater's documented shortcut: the patch nearest to the centre of the
                    ///< cell's 4x4 block of the scan's window (linear search, ties to the lowest
                    ///< index), unless the cell is beyond ground_reach of its square
};

/// The brute-force twin: eq. (4) at every cell of every ray, the local patch found by a linear
/// search, the ray's clearance over the ground checked at both ends of every crossed cell, a hash
/// map of maxima; then eq. (3). Returns the scan cells left without ground.
std::size_t twin_update(const ScanHVoxels& scan, const GroundModel& ground, const Params& params, OccupancyGrid& grid,
                        TwinGround rule = TwinGround::kNearestToCell) {
  const OccupancyParams& op = params.occupancy;
  const double cell = params.map.cell_size;
  const double xs = scan.origin_map.x();
  const double ys = scan.origin_map.y();
  const double zs = scan.origin_map.z();
  const GroundPatch* under = ground.nearest(xs, ys);
  // The window the updater lays its blocks on: the sensor's cell and the farthest scan cell.
  const CellKey centre{static_cast<std::int32_t>(std::floor(xs / cell)), static_cast<std::int32_t>(std::floor(ys / cell))};
  std::int32_t half = 0;
  for (const ScanCell& c : scan.cells) half = std::max({half, std::abs(c.key.i - centre.i), std::abs(c.key.j - centre.j)});
  const auto local_patch = [&](const CellKey& key) -> const GroundPatch* {
    const double xt = (key.i + 0.5) * cell;
    const double yt = (key.j + 0.5) * cell;
    if (rule == TwinGround::kNearestToCell) return ground.nearest(xt, yt);
    const int bi = (key.i - centre.i + half) >> 2;
    const int bj = (key.j - centre.j + half) >> 2;
    const double xb = ((bi << 2) - half + centre.i) * cell + 2.0 * cell;
    const double yb = ((bj << 2) - half + centre.j) * cell + 2.0 * cell;
    const GroundPatch* best = nullptr;
    double best_d2 = std::numeric_limits<double>::infinity();
    for (const GroundPatch& p : ground.patches()) {
      const double d2 = std::pow(p.center.x() - xb, 2) + std::pow(p.center.y() - yb, 2);
      if (d2 < best_d2) {
        best_d2 = d2;
        best = &p;
      }
    }
    if (best == nullptr || std::max(std::abs(best->center.x() - xt), std::abs(best->center.y() - yt)) - best->half_size > op.ground_reach) {
      return nullptr;
    }
    return best;
  };
  std::size_t no_ground = 0;
  std::unordered_map<CellKey, double, CellKeyHash> p_of_cell;
  for (const ScanCell& target : scan.cells) {
    const double xt = (target.key.i + 0.5) * cell;
    const double yt = (target.key.j + 0.5) * cell;
    const GroundPatch* patch = local_patch(target.key);
    if (patch == nullptr) {
      ++no_ground;
      continue;
    }
    const double g = patch->height_at(xt, yt);
    const double g_sensor = under != nullptr ? under->height_at(xs, ys) : g;
    std::vector<std::pair<HVoxelRole, double>> judged;
    double z_low = 1e9;
    for (const HVoxel& v : scan.hvoxels_of(target)) {
      const HVoxelRole role = hvoxel_role(v, g, op);
      if (role == HVoxelRole::kIgnored) continue;
      judged.emplace_back(role, v.density);
      z_low = std::min(z_low, static_cast<double>(v.z_min));
    }
    if (judged.empty()) continue;
    const double length = std::hypot(xt - xs, yt - ys);
    // Height of the lowest ray over the ground (linear from under the sensor to the target) at t.
    const auto clearance = [&](double t) { return (zs + t * (z_low - zs)) - (g_sensor + t * (g - g_sensor)); };
    // The whole walk from the sensor (the updater starts it late: RayTraceFromTest shows the tail is
    // the same).
    traverse_2d_from(xs, ys, xt, yt, cell, 0.0, [&](const CellKey& key, double t_in, double t_out) {
      const bool low = std::min(clearance(t_in), clearance(t_out)) <= op.free_ray_height;
      const double delta = key == target.key ? 0.0 : (0.5 * (t_in + t_out) - 1.0) * length;
      double p = 0.0;
      for (const auto& [role, density] : judged) p = std::max(p, inverse_sensor_model(role, density, delta, op));
      if (!low && p <= 0.5 && !(key == target.key)) return true;  // a high pass tells nothing
      p = std::clamp(p, op.ground_gain, op.clamp_max);
      auto [it, fresh] = p_of_cell.try_emplace(key, p);
      // A hit outranks a pass; between passes the clearer wins.
      if (!fresh) it->second = it->second >= 0.5 || p >= 0.5 ? std::max(it->second, p) : std::min(it->second, p);
      return true;
    });
  }
  for (const auto& [key, p] : p_of_cell) grid.update(key, log_odds(p));
  return no_ground;
}

/// A random scan around (x0, y0): ground HVoxels, obstacles, overhangs, several per cell.
ScanHVoxels random_scan(std::uint64_t seed, double x0, double y0) {
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<int> cell(-60, 60);
  std::uniform_int_distribution<int> kind(0, 3);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  ScanHVoxels scan;
  scan.origin_map = {x0, y0, 1.5};
  std::unordered_map<CellKey, int, CellKeyHash> seen;
  for (int n = 0; n < 400; ++n) {
    const CellKey key{static_cast<std::int32_t>(std::floor(x0 / 0.2)) + cell(rng),
                      static_cast<std::int32_t>(std::floor(y0 / 0.2)) + cell(rng)};
    if (!seen.emplace(key, n).second) continue;
    std::vector<HVoxel> vs;
    switch (kind(rng)) {
      case 0: vs = {{-0.02F, 0.02F, 5.0F, 0.9F}}; break;                              // ground
      case 1: vs = {{0.0F, static_cast<float>(0.5 + u(rng)), 9.0F, static_cast<float>(u(rng))}}; break;  // obstacle
      case 2: vs = {{-0.01F, 0.01F, 3.0F, 0.8F}, {3.0F, 4.0F, 9.0F, 0.9F}}; break;   // ground under a crown
      default: vs = {{-0.01F, 0.08F, 3.0F, 0.8F}, {0.7F, 0.75F, 9.0F, 0.9F}}; break;  // low ground + a box top
    }
    scan.cells.push_back({key, static_cast<std::uint32_t>(scan.hvoxels.size()), static_cast<std::uint32_t>(vs.size())});
    scan.hvoxels.insert(scan.hvoxels.end(), vs.begin(), vs.end());
  }
  return scan;
}

TEST(OccupancyUpdaterTest, MatchesTheBruteForceTwinScanAfterScan) {
  const Params p = params();
  // A slightly tilted ground plane, one patch covering everything.
  const GroundModel ground({GroundPatch{{0.0, 0.0, 0.0}, Eigen::Vector3d(0.0, 0.0, 1.0), 1000.0, -1}});
  OccupancyGrid fast(p.map.cell_size, p.occupancy.clamp_min, p.occupancy.clamp_max);
  OccupancyGrid twin(p.map.cell_size, p.occupancy.clamp_min, p.occupancy.clamp_max);
  OccupancyUpdater updater(p);
  std::size_t cells = 0;
  for (std::uint64_t seed = 1; seed <= 6; ++seed) {
    // The sensor moves between scans, so the window and its blocks change too.
    const ScanHVoxels scan = random_scan(seed, 0.37 * static_cast<double>(seed), -0.53 * static_cast<double>(seed));
    const auto stats = updater.update(scan, ground, fast);
    twin_update(scan, ground, p, twin);
    cells += stats.cells;
    EXPECT_EQ(stats.no_ground, 0U);
  }
  EXPECT_EQ(fast.known_cells(), twin.known_cells());
  EXPECT_GT(cells, 1000U);
  std::size_t compared = 0;
  twin.for_each_cell([&](const CellKey& key, float l) {
    const auto f = fast.log_odds_at(key);
    ASSERT_TRUE(f.has_value());
    // The cutoff changes p by at most 1e-4: log-odds by at most 1e-4 / (p (1 − p)) per update.
    EXPECT_NEAR(*f, l, 6 * 2e-3) << "cell " << key.i << ", " << key.j;
    ++compared;
  });
  EXPECT_EQ(compared, twin.known_cells());
}

/// Patches of half-size 0.45 m every 0.9 m (jittered, tilted by up to about 1 degree) over a field
/// of 20 m with holes: a band 7 m wide without ground, and patches dropped at random, as the
/// tracker leaves them.
GroundModel patchy_ground(std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> jitter(-0.2, 0.2);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<GroundPatch> patches;
  for (int a = -11; a <= 11; ++a) {
    for (int b = -11; b <= 11; ++b) {
      if ((a >= 2 && a <= 10) || u(rng) < 0.2) continue;  // a band with no ground; random holes
      const Eigen::Vector3d n = Eigen::Vector3d(0.1 * jitter(rng), 0.1 * jitter(rng), 1.0).normalized();
      patches.push_back({{0.9 * a + jitter(rng), 0.9 * b + jitter(rng), 0.1 * jitter(rng)}, n, 0.45, -1});
    }
  }
  return GroundModel(std::move(patches));
}

// The block lookup through the per-scan buckets finds what a linear search finds, with ground
// missing in bands and holes, and beyond the patches (cells past ground_reach get none).
TEST(OccupancyUpdaterTest, MatchesTheTwinOnPatchyGround) {
  const Params p = params();
  OccupancyGrid fast(p.map.cell_size, p.occupancy.clamp_min, p.occupancy.clamp_max);
  OccupancyGrid twin(p.map.cell_size, p.occupancy.clamp_min, p.occupancy.clamp_max);
  OccupancyUpdater updater(p);
  std::size_t no_ground = 0;
  std::size_t cells = 0;
  for (std::uint64_t seed = 1; seed <= 6; ++seed) {
    const GroundModel ground = patchy_ground(seed);
    const ScanHVoxels scan = random_scan(seed + 10, 1.1 * static_cast<double>(seed) - 3.0, 0.7 * static_cast<double>(seed) - 2.0);
    const auto stats = updater.update(scan, ground, fast);
    const std::size_t twin_no_ground = twin_update(scan, ground, p, twin, TwinGround::kNearestToBlock);
    EXPECT_EQ(stats.no_ground, twin_no_ground) << "seed " << seed;
    no_ground += stats.no_ground;
    cells += stats.cells;
  }
  EXPECT_GT(no_ground, 100U);  // the band and the field's edge
  EXPECT_GT(cells, 1000U);
  EXPECT_EQ(fast.known_cells(), twin.known_cells());
  twin.for_each_cell([&](const CellKey& key, float l) {
    const auto f = fast.log_odds_at(key);
    ASSERT_TRUE(f.has_value());
    EXPECT_NEAR(*f, l, 6 * 2e-3) << "cell " << key.i << ", " << key.j;
  });
}

// Hand-computed: a ground cell 2 m from the sensor is its own ray's target (eq. 4 at delta = 0:
// K_g + (0.5 - K_g) / 2 = 0.4) and lies under the low end of the ray to ground 2.2 m away (far
// before that target: K_g = 0.3). The clearer pass wins: one update with 0.3. An obstacle there
// would outrank both.
TEST(OccupancyUpdaterTest, TheClearerPassWinsAHitOutranksBoth) {
  Params p = params();
  p.occupancy.free_ray_height = 100.0;  // every crossed cell may be freed
  const GroundModel ground({GroundPatch{{0.0, 0.0, 0.0}, Eigen::Vector3d(0.0, 0.0, 1.0), 1000.0, -1}});
  const auto scan_of = [](float z_max_near) {
    ScanHVoxels scan;
    scan.origin_map = {0.1, 0.1, 1.5};  // the centre of cell (0, 0)
    scan.cells = {{{10, 0}, 0, 1}, {{21, 0}, 1, 1}};
    scan.hvoxels = {{-0.01F, z_max_near, 9.0F, 0.9F}, {-0.01F, 0.01F, 9.0F, 0.9F}};
    return scan;
  };
  OccupancyUpdater updater(p);
  OccupancyGrid grid(p.map.cell_size, p.occupancy.clamp_min, p.occupancy.clamp_max);
  updater.update(scan_of(0.01F), ground, grid);
  EXPECT_NEAR(*grid.log_odds_at({10, 0}), log_odds(0.3), 1e-6);
  EXPECT_NEAR(*grid.log_odds_at({21, 0}), log_odds(0.4), 1e-6);
  OccupancyGrid with_box(p.map.cell_size, p.occupancy.clamp_min, p.occupancy.clamp_max);
  updater.update(scan_of(0.8F), ground, with_box);  // a box 0.8 m tall in cell (10, 0)
  EXPECT_NEAR(*with_box.log_odds_at({10, 0}), log_odds(0.9), 1e-6);  // max(rho, 0.5) * exp(0)
}

TEST(OccupancyUpdaterTest, CutoffIsWhereEq4ReachesItsFloor) {
  const Params p = params();
  const OccupancyUpdater updater(p);
  const double d = updater.cutoff();
  const OccupancyParams& op = p.occupancy;
  EXPECT_NEAR(inverse_sensor_model(HVoxelRole::kGround, 0.9, -d, op), op.ground_gain, 1.01e-4);
  EXPECT_LE(inverse_sensor_model(HVoxelRole::kObstacle, 1.0, -d, op), 1.01e-4);
  EXPECT_GT(inverse_sensor_model(HVoxelRole::kGround, 0.9, -0.5 * d, op) - op.ground_gain, 1e-4);
}

TEST(OccupancyUpdaterTest, EmptyScanAndNoGround) {
  const Params p = params();
  OccupancyUpdater updater(p);
  OccupancyGrid grid(p.map.cell_size, 0.12, 0.97);
  EXPECT_EQ(updater.update(ScanHVoxels{}, GroundModel(), grid).cells, 0U);
  const ScanHVoxels scan = random_scan(3, 0.0, 0.0);
  const auto stats = updater.update(scan, GroundModel(), grid);
  EXPECT_EQ(stats.no_ground, scan.cells.size());
  EXPECT_EQ(grid.known_cells(), 0U);
  // A small patch far away is beyond ground_reach: nothing is judged by it.
  const GroundModel far({GroundPatch{{500.0, 500.0, 0.0}, Eigen::Vector3d(0.0, 0.0, 1.0), 0.5, -1}});
  EXPECT_EQ(updater.update(scan, far, grid).no_ground, scan.cells.size());
  Params bad = params();
  bad.occupancy.ground_reach = -1.0;
  EXPECT_THROW(OccupancyUpdater{bad}, Error);
}

}  // namespace occupancy_updater_test
}  // namespace hmap
