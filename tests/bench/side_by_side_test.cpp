// The comparison of bench/peers_main.cpp is fair: the same points, poses, ranges and resolution
// reach hmap, Bonxai and OctoMap (counted by each adapter, and seen in the maps they build).

#include "side_by_side.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <random>

#include "common/test_data.hpp"
#include "hmap/io/kitti.hpp"

namespace hmap::bench {
namespace {

Pose test_pose() {
  Pose T = Pose::Identity();
  T.translate(Eigen::Vector3d(1.3, -0.7, 0.4));
  T.rotate(Eigen::AngleAxisd(0.52, Eigen::Vector3d::UnitZ()));
  return T;
}

Params test_params(const FeedSettings& s) {
  Params p = outdoor_preset();
  p.map.cell_size = s.cell_size;
  p.map.min_range = s.min_range;
  p.map.max_range = s.max_range;
  return p;
}

/// Every system of the comparison; Bonxai when this build has it.
std::vector<std::unique_ptr<System>> all_systems(const FeedSettings& s) {
  std::vector<std::unique_ptr<System>> out;
  out.push_back(make_hmap_system(test_params(s), 0));
  out.push_back(make_hmap_system(test_params(s), 1));
  out.push_back(make_octomap_system(s));
  if (auto bonxai = make_bonxai_system(s)) out.push_back(std::move(bonxai));
  return out;
}

TEST(FeedScan, KeepsThePointsEverySystemKeepsAsHits) {
  const FeedSettings s{0.2, 1.0, 10.0};
  const Pose T = test_pose();
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const PointCloud cloud{{nan, 0, 0},          {0.5F, 0, 0},      {0, 0, 0},         {3, 4, 0},
                         {9.99F, 0, 0},        {10.01F, 0, 0},    {0, 0, 1.0F},      {0, 30, 0},
                         {0, 0, std::numeric_limits<float>::infinity()}};
  FedScan fed;
  feed_scan(cloud, T, s, fed);
  EXPECT_EQ(fed.points_read, cloud.size());
  ASSERT_EQ(fed.points_sensor.size(), 3U);  // (3, 4, 0), (9.99, 0, 0), (0, 0, 1): r = 1 is kept, as by hmap
  ASSERT_EQ(fed.points_map.size(), 3U);
  EXPECT_EQ(fed.points_sensor[0], Point3f(3, 4, 0));
  EXPECT_EQ(fed.points_sensor[1], Point3f(9.99F, 0, 0));
  EXPECT_EQ(fed.points_sensor[2], Point3f(0, 0, 1.0F));
  for (std::size_t k = 0; k < fed.points_map.size(); ++k) {
    EXPECT_TRUE(fed.points_map[k].isApprox(T * fed.points_sensor[k].cast<double>(), 1e-12));
  }
  EXPECT_TRUE(fed.origin_map.isApprox(T.translation()));

  // The empty scan, and buffers reused: nothing of the last scan is left.
  feed_scan({}, T, s, fed);
  EXPECT_EQ(fed.points_read, 0U);
  EXPECT_TRUE(fed.points_sensor.empty());
  EXPECT_TRUE(fed.points_map.empty());
}

TEST(FeedScan, AtTheRangeLimitEverySystemTakesThePointAsAHit) {
  // Points right at max range, in every direction, with a pose that moves and turns: those kept
  // must be hits for Bonxai (closer than max range in double) and OctoMap (in float) as for hmap.
  const FeedSettings s{0.2, 1.0, 10.0};
  const Pose T = test_pose();
  PointCloud cloud;
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> angle(-3.1416F, 3.1416F);
  std::uniform_real_distribution<float> jitter(-2e-5F, 2e-5F);
  for (int k = 0; k < 20000; ++k) {
    const float a = angle(rng);
    const float b = 0.5F * angle(rng);
    const float r = 10.0F + jitter(rng);
    cloud.emplace_back(r * std::cos(b) * std::cos(a), r * std::cos(b) * std::sin(a), r * std::sin(b));
  }
  FedScan fed;
  feed_scan(cloud, T, s, fed);
  ASSERT_GT(fed.points_sensor.size(), 1000U);
  ASSERT_LT(fed.points_sensor.size(), cloud.size());
  for (auto& system : all_systems(s)) {
    const RunMeasurement m = run_system(*system, std::span<const FedScan>(&fed, 1));
    EXPECT_EQ(m.points, fed.points_sensor.size()) << system->name();
    EXPECT_EQ(system->received().points, fed.points_sensor.size()) << system->name();
  }
}

TEST(SideBySide, TheSamePointsPosesRangeAndResolutionReachEverySystem) {
  // Three scans of random points (some NaN, some too close, some too far) at three poses.
  const FeedSettings s{0.25, 1.2, 15.0};
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-20.0F, 20.0F);
  std::vector<FedScan> scans(3);
  std::size_t fed = 0;
  Eigen::Vector3d origin_sum = Eigen::Vector3d::Zero();
  Eigen::Vector3d point_sum = Eigen::Vector3d::Zero();
  for (std::size_t k = 0; k < scans.size(); ++k) {
    PointCloud cloud;
    for (int n = 0; n < 3000; ++n) cloud.emplace_back(u(rng), u(rng), 0.2F * u(rng));
    cloud.emplace_back(std::numeric_limits<float>::quiet_NaN(), 0.0F, 0.0F);
    cloud.emplace_back(0.3F, 0.2F, 0.1F);
    Pose T = test_pose();
    T.pretranslate(Eigen::Vector3d(0.8 * static_cast<double>(k), 0.1, 0.0));
    feed_scan(cloud, T, s, scans[k]);
    ASSERT_LT(scans[k].points_sensor.size(), cloud.size());
    fed += scans[k].points_sensor.size();
    origin_sum += T.translation();
    for (const auto& p : scans[k].points_map) point_sum += p;
  }
  for (auto& system : all_systems(s)) {
    SCOPED_TRACE(system->name());
    const RunMeasurement m = run_system(*system, scans);
    const Received& r = system->received();
    EXPECT_EQ(m.scans, scans.size());
    EXPECT_EQ(m.points, fed);
    EXPECT_EQ(r.scans, scans.size());
    EXPECT_EQ(r.points, fed);
    EXPECT_LT((r.point_sum - point_sum).norm(), 1e-3 * static_cast<double>(fed));  // OctoMap's copy is float
    EXPECT_LT((r.origin_sum - origin_sum).norm(), 1e-5);
    EXPECT_DOUBLE_EQ(r.resolution, s.cell_size);
    EXPECT_DOUBLE_EQ(r.max_range, s.max_range);
    EXPECT_GT(m.structure_bytes, 0U);
  }
}

TEST(SideBySide, EverySystemMarksTheSameVoxelsOccupied) {
  // Isolated points at voxel centres of the map frame, one per column, seen from a moved and
  // turned sensor; plus points every system must be kept from (too close, too far, NaN).
  const FeedSettings s{0.2, 1.0, 12.0};
  const Pose T = test_pose();
  std::vector<VoxelIndex> expected;
  PointCloud cloud;
  for (int a = 0; a < 36; ++a) {
    const double angle = a * 10.0 * 3.141592653589793 / 180.0;
    const double r = 3.0 + 0.2 * a;
    const VoxelIndex v{static_cast<std::int32_t>(std::floor((T.translation().x() + r * std::cos(angle)) / s.cell_size)),
                       static_cast<std::int32_t>(std::floor((T.translation().y() + r * std::sin(angle)) / s.cell_size)),
                       -5 + a % 15};
    expected.push_back(v);
    const Eigen::Vector3d centre_map = (Eigen::Vector3d(v[0], v[1], v[2]) + Eigen::Vector3d::Constant(0.5)) * s.cell_size;
    cloud.push_back((T.inverse() * centre_map).cast<float>());
  }
  cloud.emplace_back(0.4F, 0.3F, 0.0F);    // too close: a peer given it would mark it occupied
  cloud.emplace_back(0.0F, 12.5F, 0.0F);   // too far
  cloud.emplace_back(std::numeric_limits<float>::quiet_NaN(), 1.0F, 1.0F);
  std::sort(expected.begin(), expected.end());
  ASSERT_EQ(std::adjacent_find(expected.begin(), expected.end()), expected.end());

  FedScan fed;
  feed_scan(cloud, T, s, fed);
  ASSERT_EQ(fed.points_sensor.size(), expected.size());
  for (auto& system : all_systems(s)) {
    SCOPED_TRACE(system->name());
    system->reset();
    system->prepare(fed);
    system->insert(fed);
    std::vector<VoxelIndex> occupied = system->occupied_voxels();
    std::sort(occupied.begin(), occupied.end());
    EXPECT_EQ(occupied, expected);
    system->clear();
  }
}

TEST(SideBySide, RealHdl64ScanReachesEverySystemWhole) {
  // The settings of the benchmark's HDL-64 figures, on a real scan: every point fed is a hit for
  // every system, none is dropped or truncated by one system only.
  HMAP_REQUIRE_DATA("kitti_hdl64_seq16");
  const auto dir = test::data_dir() / "kitti_hdl64_seq16";
  const FeedSettings s{0.2, 1.2, 50.0};
  const KittiSequence seq = open_kitti_sequence(dir, {.max_scans = 1});
  FedScan fed;
  feed_scan(read_kitti_bin(seq.scan_paths.front()), Pose::Identity(), s, fed);
  ASSERT_GT(fed.points_sensor.size(), 100000U);
  for (auto& system : all_systems(s)) {
    SCOPED_TRACE(system->name());
    const RunMeasurement m = run_system(*system, std::span<const FedScan>(&fed, 1));
    EXPECT_EQ(system->received().points, fed.points_sensor.size());
    EXPECT_GT(m.heap_bytes, 0U);
  }
}

TEST(SideBySide, BonxaiIsBuiltWhenItsSourceIsThere) {
  // Not a failure when the peers folder is absent: the benchmark then runs hmap and OctoMap.
  if (make_bonxai_system({}) == nullptr) GTEST_SKIP() << bonxai_absent_reason();
  EXPECT_TRUE(bonxai_absent_reason().empty());
}

}  // namespace
}  // namespace hmap::bench
