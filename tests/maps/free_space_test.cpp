#include "hmap/maps/free_space.hpp"
#include "hmap/maps/ray_trace.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <limits>
#include <map>
#include <random>
#include <utility>
#include <vector>

namespace hmap {
namespace free_space_test {

MapParams params() {
  MapParams p;
  p.cell_size = 0.2;
  p.min_range = 0.0;
  p.max_range = 12.0;
  p.point_distance_threshold = 0.1;
  p.density_threshold = 0.0;  // every HVoxel casts a ray
  p.free_unite_gap = 0.0;     // exact union, as the brute-force twin computes it
  return p;
}

struct KeyLess {
  bool operator()(const CellKey& a, const CellKey& b) const {
    return a.i != b.i ? a.i < b.i : a.j < b.j;
  }
};

TEST(FreeCellTest, UnitesOverlapsAndCountsRays) {
  FreeCell c;
  c.add(0.0F, 1.0F, 1, 0.0F, 0.1F);
  c.add(2.0F, 3.0F, 1, 0.0F, 0.1F);
  c.add(0.5F, 2.5F, 1, 0.0F, 0.1F);  // bridges both
  ASSERT_EQ(c.n, 1U);
  EXPECT_FLOAT_EQ(c.z_min[0], 0.0F);
  EXPECT_FLOAT_EQ(c.z_max[0], 3.0F);
  EXPECT_FLOAT_EQ(c.rays[0], 3.0F);
  // The freed lane is empty again: nothing can meet it.
  EXPECT_EQ(c.hit_mask(-1e30F, 1e30F, 0.0F), 1U);
}

TEST(FreeCellTest, UnitesBandsWithinTheGap) {
  FreeCell c;
  c.add(0.0F, 1.0F, 1, 0.05F, 0.1F);
  c.add(1.04F, 2.0F, 1, 0.05F, 0.1F);  // 4 cm above: unites
  c.add(2.06F, 3.0F, 1, 0.05F, 0.1F);  // 6 cm above: stays apart
  ASSERT_EQ(c.n, 2U);
  EXPECT_FLOAT_EQ(c.z_max[0], 2.0F);
  EXPECT_FLOAT_EQ(c.rays[0], 2.0F);
}

TEST(FreeCellTest, FullCellJoinsNearestOnlyWhenClose) {
  FreeCell c;
  for (int k = 0; k < FreeCell::kMaxIntervals; ++k) c.add(static_cast<float>(k), static_cast<float>(k) + 0.5F, 1, 0.0F, 0.2F);
  c.add(100.0F, 101.0F, 1, 0.0F, 0.2F);  // far from all: dropped
  EXPECT_EQ(c.n, static_cast<std::uint32_t>(FreeCell::kMaxIntervals));
  float rays = 0;
  std::array<FreeHVoxel, FreeCell::kMaxIntervals> lanes;
  for (const auto& f : c.hvoxels(lanes)) rays += f.rays;
  EXPECT_FLOAT_EQ(rays, static_cast<float>(FreeCell::kMaxIntervals));
  c.add(0.6F, 0.65F, 1, 0.0F, 0.2F);  // 0.1 above [0, 0.5]: joins it
  bool joined = false;
  for (const auto& f : c.hvoxels(lanes)) joined |= f.z_min == 0.0F && f.z_max == 0.65F && f.rays == 2.0F;
  EXPECT_TRUE(joined);
}

// The intervals of a cell, one at a time in a list: the rules FreeCell::add follows lane by lane.
struct IntervalListTwin {
  std::vector<FreeHVoxel> iv;
  void add(float lo, float hi, float r, float unite_gap, float join_gap) {
    std::size_t hit = iv.size();
    for (std::size_t k = 0; k < iv.size(); ++k) {
      if (!(lo <= iv[k].z_max + unite_gap && hi >= iv[k].z_min - unite_gap)) continue;
      if (hit == iv.size()) {
        iv[k].z_min = std::min(iv[k].z_min, lo);
        iv[k].z_max = std::max(iv[k].z_max, hi);
        iv[k].rays += r;
        hit = k;
      } else {  // folded into the first met; the last takes its place
        iv[hit].z_min = std::min(iv[hit].z_min, iv[k].z_min);
        iv[hit].z_max = std::max(iv[hit].z_max, iv[k].z_max);
        iv[hit].rays += iv[k].rays;
        iv[k] = iv.back();
        iv.pop_back();
        --k;
      }
    }
    if (hit != iv.size()) return;
    if (iv.size() < FreeCell::kMaxIntervals) {
      iv.push_back({lo, hi, r});
      return;
    }
    std::size_t nearest = 0;
    float best = std::numeric_limits<float>::infinity();
    for (std::size_t k = 0; k < iv.size(); ++k) {
      const float gap = std::max(iv[k].z_min - hi, lo - iv[k].z_max);
      if (gap < best) {
        best = gap;
        nearest = k;
      }
    }
    if (best <= join_gap) {
      iv[nearest].z_min = std::min(iv[nearest].z_min, lo);
      iv[nearest].z_max = std::max(iv[nearest].z_max, hi);
      iv[nearest].rays += r;
    }
  }
};

TEST(FreeCellTest, AgreesLaneForLaneWithAListOfIntervals) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> z(-2.0F, 6.0F);
  std::uniform_real_distribution<float> len(0.0F, 0.6F);
  std::uniform_int_distribution<int> rays(1, 3);
  for (int trial = 0; trial < 400; ++trial) {
    const float unite_gap = trial % 3 == 0 ? 0.0F : 0.05F;
    const float join_gap = trial % 2 == 0 ? 0.0F : 0.4F;
    FreeCell cell;
    IntervalListTwin twin;
    const int bands = 1 + trial % 40;
    for (int b = 0; b < bands; ++b) {
      // Now and then a band from exactly zero, of either sign: min and max keep the held value on a tie.
      const float lo = b % 5 == 0 ? (b % 2 == 0 ? 0.0F : -0.0F) : z(rng);
      const float hi = b % 5 == 0 ? (b % 3 == 0 ? 0.0F : -0.0F) : lo + len(rng);
      const auto r = static_cast<float>(rays(rng));
      ASSERT_EQ(cell.hit_mask(lo, hi, unite_gap), cell.hit_mask_scalar(lo, hi, unite_gap));
      cell.add(lo, hi, r, unite_gap, join_gap);
      twin.add(lo, hi, r, unite_gap, join_gap);
      ASSERT_EQ(cell.n, twin.iv.size()) << "trial " << trial << " band " << b;
      for (std::uint32_t k = 0; k < cell.n; ++k) {
        // Bit for bit: the same minima, maxima and sums, in the same lanes.
        EXPECT_EQ(std::bit_cast<std::uint32_t>(cell.z_min[k]), std::bit_cast<std::uint32_t>(twin.iv[k].z_min));
        EXPECT_EQ(std::bit_cast<std::uint32_t>(cell.z_max[k]), std::bit_cast<std::uint32_t>(twin.iv[k].z_max));
        EXPECT_EQ(std::bit_cast<std::uint32_t>(cell.rays[k]), std::bit_cast<std::uint32_t>(twin.iv[k].rays));
      }
      for (std::uint32_t k = cell.n; k < FreeCell::kMaxIntervals; ++k) {
        EXPECT_EQ(cell.z_min[k], std::numeric_limits<float>::infinity());
        EXPECT_EQ(cell.z_max[k], -std::numeric_limits<float>::infinity());
        EXPECT_EQ(cell.rays[k], 0.0F);
      }
    }
  }
}

TEST(FreeCellTest, ClearEmptiesEveryLane) {
  FreeCell c;
  c.add(0.0F, 1.0F, 1, 0.0F, 0.0F);
  c.add(2.0F, 3.0F, 1, 0.0F, 0.0F);
  c.clear();
  EXPECT_EQ(c.n, 0U);
  EXPECT_EQ(c.hit_mask(-1e30F, 1e30F, 1.0F), 0U);
  c.add(5.0F, 6.0F, 2, 0.0F, 0.0F);
  ASSERT_EQ(c.n, 1U);
  EXPECT_EQ(c.hvoxel(0).z_min, 5.0F);
  EXPECT_EQ(c.hvoxel(0).rays, 2.0F);
}

// Brute-force twin of Alg. 3: sample each ray's 2D segment finely, and per crossed cell record
// the band between the two line models; the tracer's free intervals must equal the union.
TEST(FreeSpaceTest, MatchesDenseSegmentSampling) {
  const MapParams p = params();
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> xy(-8.0, 8.0);
  std::uniform_real_distribution<float> z(-1.0F, 2.5F);
  for (int trial = 0; trial < 20; ++trial) {
    ScanHVoxels scan;
    scan.origin_map = {0.07, -0.13, 1.2};
    scan.window = {{0, -1}, static_cast<std::int32_t>(std::ceil(p.max_range / p.cell_size)) + 1, 0};
    scan.window.width = 2 * scan.window.half + 1;
    // Three rays, far apart in direction, so no cell gets more bands than a FreeCell holds.
    for (int r = 0; r < 3; ++r) {
      const double angle = 2.0 * M_PI * (r + 0.3 * trial / 20.0) / 3.0;
      const double dist = 2.0 + std::abs(xy(rng)) * 0.7;
      const CellKey key{static_cast<int>(std::floor((scan.origin_map.x() + dist * std::cos(angle)) / p.cell_size)),
                        static_cast<int>(std::floor((scan.origin_map.y() + dist * std::sin(angle)) / p.cell_size))};
      const float a = z(rng);
      const float b = a + std::abs(z(rng)) * 0.5F;
      scan.cells.push_back({key, static_cast<std::uint32_t>(scan.hvoxels.size()), 1});
      scan.hvoxels.push_back({a, b, 10.0F, 1.0F});
    }
    FreeSpaceTracer tracer(p);
    tracer.trace(scan);
    EXPECT_EQ(tracer.rays(), 3U);

    std::map<CellKey, std::vector<std::pair<double, double>>, KeyLess> brute;
    for (const ScanCell& c : scan.cells) {
      const HVoxel& v = scan.hvoxels[c.first];
      const double xt = (c.key.i + 0.5) * p.cell_size;
      const double yt = (c.key.j + 0.5) * p.cell_size;
      std::map<CellKey, std::pair<double, double>, KeyLess> band;
      const int samples = 200000;
      for (int s = 0; s <= samples; ++s) {
        const double t = static_cast<double>(s) / samples;
        const CellKey k{static_cast<int>(std::floor((scan.origin_map.x() + t * (xt - scan.origin_map.x())) / p.cell_size)),
                        static_cast<int>(std::floor((scan.origin_map.y() + t * (yt - scan.origin_map.y())) / p.cell_size))};
        if (k == c.key) break;
        const double zl = scan.origin_map.z() + t * (v.z_min - scan.origin_map.z());
        const double zu = scan.origin_map.z() + t * (v.z_max - scan.origin_map.z());
        auto [it, fresh] = band.try_emplace(k, std::min(zl, zu), std::max(zl, zu));
        if (!fresh) {
          it->second.first = std::min(it->second.first, std::min(zl, zu));
          it->second.second = std::max(it->second.second, std::max(zl, zu));
        }
      }
      for (const auto& [k, b] : band) brute[k].push_back(b);
    }
    // Same cells.
    std::size_t tracer_cells = 0;
    for (const FreeCell* cell : tracer.cells()) {
      const FreeCell& fc = *cell;
      ++tracer_cells;
      ASSERT_TRUE(brute.count(fc.key)) << "trial " << trial << ": extra cell " << fc.key.i << "," << fc.key.j;
    }
    // Cells the sampling touches only within 1e-5 of a corner may be missed by either side.
    EXPECT_NEAR(static_cast<double>(tracer_cells), static_cast<double>(brute.size()), 2.0);
    for (const FreeCell* cell : tracer.cells()) {
      const FreeCell& fc = *cell;
      auto bands = brute[fc.key];
      std::sort(bands.begin(), bands.end());
      std::vector<std::pair<double, double>> united;
      for (const auto& b : bands) {
        if (!united.empty() && b.first <= united.back().second + 1e-4) {
          united.back().second = std::max(united.back().second, b.second);
        } else {
          united.push_back(b);
        }
      }
      std::array<FreeHVoxel, FreeCell::kMaxIntervals> lanes;
      const auto held = fc.hvoxels(lanes);
      auto free = std::vector<FreeHVoxel>(held.begin(), held.end());
      std::sort(free.begin(), free.end(), [](const auto& a, const auto& b) { return a.z_min < b.z_min; });
      ASSERT_EQ(free.size(), united.size()) << "trial " << trial;
      for (std::size_t k = 0; k < free.size(); ++k) {
        const double tol = 2e-4 * 40.0;  // sampling step times the steepest slope
        EXPECT_NEAR(free[k].z_min, united[k].first, tol);
        EXPECT_NEAR(free[k].z_max, united[k].second, tol);
      }
    }
  }
}

TEST(FreeSpaceTest, LowDensityHVoxelsCastNoRay) {
  MapParams p = params();
  p.density_threshold = 0.5;
  ScanHVoxels scan;
  scan.window = {{0, 0}, static_cast<std::int32_t>(std::ceil(p.max_range / p.cell_size)) + 1, 0};
  scan.window.width = 2 * scan.window.half + 1;
  scan.cells.push_back({{20, 0}, 0, 2});
  scan.hvoxels.push_back({0.0F, 0.1F, 1.0F, 0.2F});
  scan.hvoxels.push_back({1.0F, 1.1F, 50.0F, 0.9F});
  FreeSpaceTracer tracer(p);
  tracer.trace(scan);
  EXPECT_EQ(tracer.rays(), 1U);
  EXPECT_EQ(tracer.cells().size(), 20U);  // cells 0..19 on the x axis
  scan.hvoxels[1].density = 0.1F;
  tracer.trace(scan);
  EXPECT_EQ(tracer.rays(), 0U);
  EXPECT_TRUE(tracer.cells().empty());
}

// The four quadrants share the sensor's row and column: rays along them, and shallow rays that
// run along them for a few cells before stepping into the next quadrant, leave cells there in two
// quadrants, which are folded into one. Each cell is listed once, with every ray that crossed it
// (counted by traverse_2d), trace after trace (the quadrants clear themselves).
TEST(FreeSpaceTest, RaysAlongTheSensorsRowAndColumnAreFoldedOnce) {
  const MapParams p = params();
  ScanHVoxels scan;
  scan.origin_map = {0.1, 0.1, 1.0};  // the centre of cell (0, 0)
  scan.window = {{0, 0}, static_cast<std::int32_t>(std::ceil(p.max_range / p.cell_size)) + 1, 0};
  scan.window.width = 2 * scan.window.half + 1;
  std::map<CellKey, float, KeyLess> expected;
  for (const CellKey key : {CellKey{10, 0}, CellKey{-10, 0}, CellKey{0, 10}, CellKey{0, -10}, CellKey{10, -1},
                            CellKey{-10, -1}, CellKey{-1, 10}, CellKey{-1, -10}, CellKey{-8, 1}}) {
    scan.cells.push_back({key, static_cast<std::uint32_t>(scan.hvoxels.size()), 1});
    scan.hvoxels.push_back({0.9F, 1.1F, 10.0F, 1.0F});  // level with the sensor: one band per cell
    traverse_2d(scan.origin_map.x(), scan.origin_map.y(), (key.i + 0.5) * p.cell_size, (key.j + 0.5) * p.cell_size,
                p.cell_size, [&](const CellKey& k, double, double) {
                  if (!(k == key)) expected[k] += 1.0F;  // the HVoxel's own cell is not free
                  return true;
                });
  }
  FreeSpaceTracer tracer(p);
  for (int trace = 0; trace < 2; ++trace) {
    tracer.trace(scan);
    EXPECT_EQ(tracer.rays(), 9U);
    std::map<CellKey, float, KeyLess> rays_of;
    for (const FreeCell* fc : tracer.cells()) {
      ASSERT_EQ(fc->n, 1U) << fc->key.i << "," << fc->key.j;
      ASSERT_TRUE(rays_of.emplace(fc->key, fc->rays[0]).second) << "listed twice: " << fc->key.i << "," << fc->key.j;
    }
    EXPECT_EQ(rays_of, expected);
    EXPECT_EQ(rays_of.at({0, 0}), 9.0F);
    EXPECT_EQ(rays_of.at({-3, 0}), 3.0F);  // the rays to (-10, 0), (-10, -1) and (-8, 1)
  }
}

TEST(FreeSpaceTest, WorkAlongsideRunsOnceAndEveryQuadrantClearsItselfWhateverTheOrder) {
  // Three traces, each with a different quadrant carrying most of the rays, so the quadrants are
  // taken in a different order each time: every trace lists exactly its own rays' cells (none left
  // over from the last trace) and runs the work alongside once.
  const MapParams p = params();
  FreeSpaceTracer tracer(p);
  const std::array<CellKey, 3> heavy{CellKey{12, 9}, CellKey{-12, 7}, CellKey{5, -12}};
  for (std::size_t trace = 0; trace < heavy.size(); ++trace) {
    ScanHVoxels scan;
    scan.origin_map = {0.1, 0.1, 1.0};  // the centre of cell (0, 0)
    scan.window = {{0, 0}, static_cast<std::int32_t>(std::ceil(p.max_range / p.cell_size)) + 1, 0};
    scan.window.width = 2 * scan.window.half + 1;
    std::map<CellKey, float, KeyLess> expected;
    std::vector<std::pair<CellKey, std::uint32_t>> targets{{heavy[trace], 6}, {{3, 2}, 1}, {{-2, 3}, 1}, {{-3, -2}, 1},
                                                           {{2, -3}, 1}};
    for (const auto& target : targets) {
      const CellKey key = target.first;  // not a structured binding: clang cannot capture one
      const std::uint32_t n = target.second;
      scan.cells.push_back({key, static_cast<std::uint32_t>(scan.hvoxels.size()), n});
      for (std::uint32_t k = 0; k < n; ++k) scan.hvoxels.push_back({0.9F, 1.1F, 10.0F, 1.0F});
      traverse_2d(scan.origin_map.x(), scan.origin_map.y(), (key.i + 0.5) * p.cell_size, (key.j + 0.5) * p.cell_size,
                  p.cell_size, [&](const CellKey& c, double, double) {
                    if (!(c == key)) expected[c] += static_cast<float>(n);
                    return true;
                  });
    }
    int alongside = 0;
    tracer.trace(scan, [&] { ++alongside; });
    EXPECT_EQ(alongside, 1);
    EXPECT_EQ(tracer.rays(), 10U);
    std::map<CellKey, float, KeyLess> rays_of;
    for (const FreeCell* fc : tracer.cells()) {
      ASSERT_EQ(fc->n, 1U) << fc->key.i << "," << fc->key.j;
      ASSERT_TRUE(rays_of.emplace(fc->key, fc->rays[0]).second) << "listed twice: " << fc->key.i << "," << fc->key.j;
    }
    EXPECT_EQ(rays_of, expected) << "trace " << trace;
  }
}

}  // namespace free_space_test
}  // namespace hmap
