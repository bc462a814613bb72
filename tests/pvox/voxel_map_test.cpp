#include "hmap/pvox/voxel_map.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <set>

#include "hmap/core/error.hpp"
#include "hmap/pvox/mapper.hpp"
#include "hmap/pvox/serialize.hpp"

namespace hmap::pvox {
namespace {

TEST(Probability, MonotoneInTheCountAndInsideZeroOne) {
  const ProbabilityModel m;
  const double e = 0.0586;
  EXPECT_DOUBLE_EQ(m.probability(e, 0, 0), 0.5);
  EXPECT_NEAR(m.hit_logit(e), std::log(1.0 + e * e / (2.0 * 100e-6)), 1e-12);
  double previous = 0.5;
  for (std::uint64_t n = 1; n < 1000; ++n) {
    const double p = m.probability(e, n, 0);
    EXPECT_GE(p, previous);
    EXPECT_GT(p, 0.0);
    EXPECT_LT(p, 1.0);
    previous = p;
  }
  EXPECT_GT(m.probability(e, 1, 0), 0.5);
  EXPECT_NEAR(previous, 1.0 / (1.0 + std::exp(-3.5)), 1e-12);  // clamped at l_max
  // Misses lower it, down to the clamp.
  EXPECT_LT(m.probability(e, 1, 10), m.probability(e, 1, 0));
  EXPECT_NEAR(m.probability(e, 0, 1000000), 1.0 / (1.0 + std::exp(2.0)), 1e-12);
  // A wider voxel (or a smaller measurement variance) makes one point stronger evidence.
  EXPECT_GT(m.hit_logit(0.1), m.hit_logit(0.05));
}

TEST(VoxelMap, KeysAndCentresAcrossZero) {
  VoxelMap map(0.5);
  EXPECT_EQ(map.key_of(Eigen::Vector3d(0.1, -0.1, -0.5)), (VoxelKey{0, -1, -1}));
  EXPECT_EQ(map.centre({-1, 0, 2}), Eigen::Vector3d(-0.25, 0.25, 1.25));
  map.add_hit(Eigen::Vector3d(-3.9, 2.1, -0.01));
  map.add_hit(Eigen::Vector3d(-3.7, 2.3, -0.03));
  ASSERT_NE(map.find({-8, 4, -1}), nullptr);
  EXPECT_EQ(map.find({-8, 4, -1})->hits, 2U);
  const VoxelMoments mo = VoxelMap::moments(*map.find({-8, 4, -1}), map.centre({-8, 4, -1}));
  EXPECT_NEAR(mo.mean.x(), -3.8, 1e-6);
  EXPECT_NEAR(mo.covariance(0, 0), 0.01, 1e-6);
  EXPECT_EQ(map.voxel_count(), 1U);
  EXPECT_EQ(map.occupied().size(), 1U);
  EXPECT_DOUBLE_EQ(map.probability_at(Eigen::Vector3d(10, 10, 10)), 0.5);
  EXPECT_THROW(VoxelMap(0.0), Error);
  EXPECT_THROW(VoxelMap(-1.0), Error);
}

TEST(VoxelMap, ReVoxelationKeepsCountsAndMomentsOfABruteForceTwin) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < 2000; ++i) points.emplace_back(u(rng), u(rng), 0.3 * u(rng));
  VoxelMap map(0.2);
  for (const auto& p : points) map.add_hit(p);
  map.set_edge(0.37);
  std::uint64_t hits = 0;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  map.for_each([&](const VoxelKey& key, const Voxel& v) {
    hits += v.hits;
    sum += VoxelMap::moments(v, map.centre(key)).mean * v.hits;
  });
  EXPECT_EQ(hits, points.size());
  Eigen::Vector3d truth = Eigen::Vector3d::Zero();
  for (const auto& p : points) truth += p;
  EXPECT_LT((sum - truth).norm(), 1e-3);
  EXPECT_DOUBLE_EQ(map.edge(), 0.37);
}

TEST(VoxelMap, RaysMarkTheVoxelsTheyCross) {
  VoxelMap map(1.0);
  InsertParams ip;
  ip.free_space = FreeSpace::kRays;
  Pose T = Pose::Identity();
  T.translation() = Eigen::Vector3d(0.5, 0.5, 0.5);
  // A ray along +x from voxel 0 to voxel 5: misses in 0..4, the hit in 5.
  const InsertStats s = map.insert(PointCloud{Point3f(5.0F, 0.0F, 0.0F)}, T, ip);
  EXPECT_EQ(s.hits, 1U);
  EXPECT_EQ(s.misses, 5U);
  for (int i = 0; i < 5; ++i) {
    ASSERT_NE(map.find({i, 0, 0}), nullptr);
    EXPECT_EQ(map.find({i, 0, 0})->misses, 1U);
    EXPECT_LT(map.probability({i, 0, 0}), 0.5);
  }
  EXPECT_EQ(map.find({5, 0, 0})->hits, 1U);
  // A diagonal ray: every voxel crossed is one a dense sample of the segment passes through.
  VoxelMap diag(0.3);
  Pose O = Pose::Identity();
  O.translation() = Eigen::Vector3d(0.05, 0.11, -0.02);
  const Eigen::Vector3d end(2.3, -1.7, 0.9);
  diag.insert(PointCloud{(end - O.translation()).cast<float>()}, O, ip);
  std::set<std::tuple<int, int, int>> brute;
  for (int k = 0; k <= 100000; ++k) {
    const VoxelKey key = diag.key_of(O.translation() + (end - O.translation()) * (k / 100000.0));
    if (!(key == diag.key_of(end))) brute.insert({key.i, key.j, key.k});
  }
  std::set<std::tuple<int, int, int>> dda;
  diag.for_each([&](const VoxelKey& key, const Voxel& v) {
    if (v.misses > 0) dda.insert({key.i, key.j, key.k});
  });
  EXPECT_EQ(dda, brute);
}

TEST(VoxelMap, RejectsPointsOutOfRange) {
  VoxelMap map(0.1);
  InsertParams ip;
  ip.min_range = 0.5;
  ip.max_range = 10.0;
  const PointCloud pts = {Point3f(0.1F, 0, 0), Point3f(20.0F, 0, 0), Point3f(NAN, 0, 0), Point3f(1.0F, 0, 0)};
  const InsertStats s = map.insert(pts, Pose::Identity(), ip);
  EXPECT_EQ(s.hits, 1U);
  EXPECT_EQ(s.rejected, 3U);
  EXPECT_EQ(map.insert(PointCloud{}, Pose::Identity(), ip).hits, 0U);
}

TEST(VoxelMap, GradientMatchesFiniteDifferences) {
  VoxelMap map(0.1);
  for (int i = 0; i < 20; ++i) map.add_hit(Eigen::Vector3d(0.55, 0.01 * i, 0.05));
  map.add_miss(map.key_of(Eigen::Vector3d(0.45, 0.05, 0.05)));
  map.add_miss(map.key_of(Eigen::Vector3d(0.35, 0.05, 0.05)));
  const Eigen::Vector3d p(0.47, 0.08, 0.07);
  const FieldSample f = map.field_at(p);
  const double h = 1e-5;
  for (int a = 0; a < 3; ++a) {
    Eigen::Vector3d dp = Eigen::Vector3d::Zero();
    dp[a] = h;
    const double numeric = (map.field_at(p + dp).probability - map.field_at(p - dp).probability) / (2 * h);
    EXPECT_NEAR(f.gradient[a], numeric, 1e-4);
  }
  // Towards the occupied voxel p grows: the gradient points +x.
  EXPECT_GT(f.gradient.x(), 0.0);
  // At a voxel centre the field is the voxel's own probability.
  EXPECT_NEAR(map.field_at(map.centre(map.key_of(Eigen::Vector3d(0.55, 0.05, 0.05)))).probability,
              map.probability_at(Eigen::Vector3d(0.55, 0.05, 0.05)), 1e-12);
}

TEST(Mapper, EdgeFollowsKSigmaOfThePosterior) {
  PvoxParams p;
  PvoxMapper mapper(p);
  const PointCloud scan = {Point3f(1.0F, 0.0F, 0.0F), Point3f(0.0F, 1.0F, 0.5F)};
  for (int k = 0; k < 4; ++k) {
    const auto r = mapper.add_scan(scan, Pose::Identity(), Eigen::Vector2d::Zero());
    EXPECT_DOUBLE_EQ(r.edge, 6.0 * mapper.filter()->sigma());
    EXPECT_DOUBLE_EQ(mapper.map().edge(), r.edge);
  }
  EXPECT_NEAR(mapper.map().edge() * 1000.0, 58.62, 0.01);
  // k = 3: half the edge.
  p.k_sigma = 3.0;
  PvoxMapper half(p);
  const double half_edge = half.add_scan(scan, Pose::Identity()).edge;
  EXPECT_DOUBLE_EQ(half_edge, 3.0 * half.filter()->sigma());
  // A fixed edge does not move.
  p.fixed_edge = 0.1;
  PvoxMapper fixed(p);
  EXPECT_DOUBLE_EQ(fixed.add_scan(scan, Pose::Identity()).edge, 0.1);
  p.k_sigma = -1.0;
  EXPECT_THROW(PvoxMapper{p}, Error);
}

TEST(VoxelMapBudget, ANewBlockBeyondTheBudgetIsRefusedBeforeItIsAllocated) {
  // A block of 4^3 voxels of 44 bytes (two counts, three sums, six second moments) is 2816 bytes,
  // counted with its key (12) and five pointers of the hash table (40): 2868 bytes. 1 MiB holds
  // 1048576 / 2868 = 365.6 of them: noisy points 1 m apart each take a block of their own.
  VoxelMap map(0.05);
  map.set_budget(MemoryBudget{std::size_t{1} << 20});
  for (int k = 0; k < 365; ++k) map.add_hit(Eigen::Vector3d(k, 0.0, 0.0));
  EXPECT_EQ(map.block_count(), 365U);
  map.add_hit(Eigen::Vector3d(0.01, 0.0, 0.0));  // an existing block costs nothing
  try {
    map.add_hit(Eigen::Vector3d(365.0, 0.0, 0.0));
    ADD_FAILURE() << "block 366 allocated";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "the voxel map (366 blocks of 4^3 voxels of 0.05 m) needs 2 MiB, more than the memory budget "
                           "of 1 MiB (hmap --max-memory MIB)");
  }
  EXPECT_EQ(map.block_count(), 365U);
  // The budget goes with a re-voxelation.
  map.set_edge(0.1);
  EXPECT_EQ(map.budget().bytes, std::size_t{1} << 20);
}

TEST(VoxelMapBudget, ADecodedFileGrowsNoFurtherThanTheBudget) {
  VoxelMap map(0.05);
  for (int k = 0; k < 400; ++k) map.add_hit(Eigen::Vector3d(k, 0.0, 0.0));
  const auto bytes = encode_binary(map);
  EXPECT_EQ(decode_binary(bytes, "m.pvox").voxel_count(), 400U);
  try {
    (void)decode_binary(bytes, "m.pvox", MemoryBudget{std::size_t{1} << 20});
    ADD_FAILURE() << "decoded beyond the budget";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("m.pvox: voxel 365 of 400: the voxel map (366 blocks"), std::string::npos) << e.what();
  }
}

TEST(PvoxParamsRanges, EdgesRangesAndPosesBeyondTheKeysAreRefused) {
  PvoxParams p;
  p.fixed_edge = 1e-300;  // before: every point beyond the key range, an empty map with exit 0
  try {
    p.validate();
    ADD_FAILURE();
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "pvox: voxel edge = 1e-300 m is out of its range [0.0001, 100]");
  }
  p.fixed_edge = 0.05;
  EXPECT_NO_THROW(p.validate());
  p.insert.max_range = 1e6;  // before: 4 GB of ray voxels from a 160-byte scan
  EXPECT_THROW(p.validate(), Error);
  p.insert.max_range = 60.0;
  p.fixed_edge = 1e200;
  EXPECT_THROW(p.validate(), Error);
  VoxelMap map(0.05);
  Pose far = Pose::Identity();
  far.translation() = Eigen::Vector3d(1e30, 0.0, 0.0);
  const PointCloud one = {Point3f(1.0F, 0.0F, 0.0F)};
  try {
    (void)map.insert(one, far, InsertParams{});
    ADD_FAILURE() << "a pose 1e30 m away accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("beyond the voxel key range of +-1e+08 m at edge 0.05 m"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace hmap::pvox
