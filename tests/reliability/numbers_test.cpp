// Numbers at the edges: NaN and infinite points are dropped and counted, points and poses at
// ±1e30 never overflow a cell key, absurd parameters are refused with a message naming them.

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

#include "hmap/core/error.hpp"
#include "hmap/core/params.hpp"
#include "hmap/io/hmap_file.hpp"
#include "hmap/maps/mapper.hpp"
#include "common/test_data.hpp"

namespace hmap {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr float kInf = std::numeric_limits<float>::infinity();

Params small_params() {
  Params p = outdoor_preset();
  p.map.cell_size = 0.5;
  p.map.min_range = 0.5;
  p.map.max_range = 20.0;
  return p;
}

/// A flat 8 m × 8 m floor 1.5 m under the sensor, every 0.1 m.
PointCloud floor_scan() {
  PointCloud points;
  for (int a = -40; a < 40; ++a) {
    for (int b = -40; b < 40; ++b) points.emplace_back(0.1f * static_cast<float>(a), 0.1f * static_cast<float>(b), -1.5f);
  }
  return points;
}

Pose at(double x, double y, double z = 0.0) {
  Pose T = Pose::Identity();
  T.translation() = Eigen::Vector3d(x, y, z);
  return T;
}

std::string error_of(const auto& action) {
  try {
    action();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(NumbersTest, NonFiniteAndHugePointsAreDroppedAndCounted) {
  Mapper mapper(small_params());
  PointCloud points = floor_scan();
  const std::size_t good = points.size();
  points.insert(points.end(), {{kNaN, 0, 0}, {0, kInf, 0}, {0, 0, -kInf}, {kNaN, kNaN, kNaN}});
  points.insert(points.end(), {{1e30f, 0, 0}, {-1e30f, 1e30f, 0}, {0, 0, 1e30f}, {3e38f, -3e38f, 3e38f}});
  const ScanStats stats = mapper.integrate(points, at(0, 0, 1.5));
  EXPECT_EQ(stats.points_in, good + 8);
  EXPECT_EQ(stats.dropped_non_finite, 4U);
  EXPECT_EQ(stats.points_kept, good);
  EXPECT_EQ(stats.dropped_range, 4U);  // ±1e30 and 3e38 fall outside max_range
  EXPECT_EQ(stats.points_kept + stats.dropped_non_finite + stats.dropped_range, stats.points_in);
  const auto bounds = mapper.map().stats().bounds;
  EXPECT_LT(bounds.max().cwiseAbs().maxCoeff(), 25.0);
  EXPECT_LT(bounds.min().cwiseAbs().maxCoeff(), 25.0);
}

TEST(NumbersTest, CellKeysOfHugeCoordinatesDoNotOverflow) {
  const HMap map(small_params());
  for (const double v : {1e30, -1e30, 1e300, -1e300, 3e9, -3e9}) {
    EXPECT_FALSE(map.key_of(v, 0.0).has_value()) << v;
    EXPECT_FALSE(map.key_of(0.0, v).has_value()) << v;
    EXPECT_TRUE(map.column(v, v).empty());
    EXPECT_FALSE(map.occupied(v, v, 0.0));
  }
  for (const double v : {std::nan(""), std::numeric_limits<double>::infinity()}) {
    EXPECT_FALSE(map.key_of(v, 0.0).has_value());
    EXPECT_FALSE(map.key_of(0.0, -v).has_value());
  }
  // The last cells on either side of the key range are still cells.
  const double edge = (HMap::kMaxKey - 4.0) * map.cell_size();
  ASSERT_TRUE(map.key_of(edge, -edge).has_value());
  EXPECT_GT(map.key_of(edge, -edge)->i, 0);
  EXPECT_LT(map.key_of(edge, -edge)->j, 0);
}

TEST(NumbersTest, PosesAtHugeOrNonFiniteCoordinatesAreRefused) {
  Mapper mapper(small_params());
  const PointCloud points = floor_scan();
  for (const double v : {1e30, -1e30, 1e12}) {
    const std::string message = error_of([&] { (void)mapper.integrate(points, at(v, 0.0)); });
    EXPECT_NE(message.find("too far from the map origin"), std::string::npos) << v << ": " << message;
    EXPECT_FALSE(error_of([&] { (void)mapper.integrate(points, at(0.0, v)); }).empty()) << v;
  }
  for (const double v : {std::nan(""), std::numeric_limits<double>::infinity()}) {
    EXPECT_FALSE(error_of([&] { (void)mapper.integrate(points, at(v, 0.0)); }).empty()) << v;
    EXPECT_FALSE(error_of([&] { (void)mapper.integrate(points, at(0.0, 0.0, v)); }).empty()) << v;
    Pose rotated = Pose::Identity();
    rotated.linear()(0, 1) = v;
    EXPECT_FALSE(error_of([&] { (void)mapper.integrate(points, rotated); }).empty()) << v;
  }
  EXPECT_TRUE(mapper.map().empty());
}

TEST(NumbersTest, MapsFarFromTheOriginRoundTrip) {
  // A scan 4·10^8 cells out (2·10^8 m): keys, tiles and the file keep it exactly.
  Mapper mapper(small_params());
  const double far = 4e8 * 0.5;
  (void)mapper.integrate(floor_scan(), at(far, -far, 1.5));
  ASSERT_FALSE(mapper.map().empty());
  EXPECT_TRUE(mapper.map().occupied(far + 0.25, -far + 0.25, 0.0));
  const auto dir = test::temp_dir("numbers_far");
  save_hmap(dir / "far.hmap", mapper.map());
  const HMap loaded = load_hmap(dir / "far.hmap");
  EXPECT_EQ(loaded.stats().hvoxels, mapper.map().stats().hvoxels);
  EXPECT_TRUE(loaded.occupied(far + 0.25, -far + 0.25, 0.0));
  std::filesystem::remove_all(dir);
}

TEST(NumbersTest, AbsurdParametersAreRefusedByName) {
  Params p = outdoor_preset();
  p.map.cell_size = 1e-6;
  std::string message = error_of([&] { validate(p); });
  EXPECT_NE(message.find("map.cell_size"), std::string::npos) << message;
  p = outdoor_preset();
  p.map.max_range = 1e9;
  message = error_of([&] { validate(p); });
  EXPECT_NE(message.find("map.max_range"), std::string::npos) << message;
  EXPECT_NE(message.find("(0, 10000] m"), std::string::npos) << message;  // its range first (issue 14)
  p.map.max_range = 1000.0;  // in its range, but 4000 cells of 0.25 m: beyond the scan window
  message = error_of([&] { validate(p); });
  EXPECT_NE(message.find("2048"), std::string::npos) << message;
  p = outdoor_preset();
  p.map.cell_size = std::nan("");
  message = error_of([&] { validate(p); });
  EXPECT_NE(message.find("map.cell_size"), std::string::npos) << message;
}

}  // namespace
}  // namespace hmap
