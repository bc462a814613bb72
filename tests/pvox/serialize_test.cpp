#include "hmap/pvox/serialize.hpp"

#include <gtest/gtest.h>

#include <random>

#include "hmap/core/error.hpp"

namespace hmap::pvox {
namespace {

VoxelMap sample_map(int points, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1.5, 1.5);
  VoxelMap map(0.0586);
  for (int i = 0; i < points; ++i) map.add_hit(Eigen::Vector3d(u(rng), u(rng), 0.2 * u(rng)));
  map.add_miss(map.key_of(Eigen::Vector3d(3.0, 3.0, 3.0)));  // a free voxel, no points
  return map;
}

TEST(Serialize, BinaryRoundTrip) {
  const VoxelMap map = sample_map(3000, 1);
  const auto bytes = encode_binary(map);
  const VoxelMap back = decode_binary(bytes, "mem.pvox");
  EXPECT_DOUBLE_EQ(back.edge(), map.edge());
  EXPECT_EQ(back.voxel_count(), map.voxel_count());
  map.for_each([&](const VoxelKey& key, const Voxel& v) {
    const Voxel* w = back.find(key);
    ASSERT_NE(w, nullptr);
    EXPECT_EQ(w->hits, v.hits);
    EXPECT_EQ(w->misses, v.misses);
    EXPECT_DOUBLE_EQ(back.probability(key), map.probability(key));
    const auto a = VoxelMap::moments(v, map.centre(key)).mean;
    const auto b = VoxelMap::moments(*w, back.centre(key)).mean;
    EXPECT_LT((a - b).cwiseAbs().maxCoeff(), 0.5 / 255.0 * map.edge() + 1e-6);
  });
  // Deterministic: the same map gives the same bytes.
  EXPECT_EQ(encode_binary(back), bytes);
  // The empty map too.
  const VoxelMap empty(0.1);
  EXPECT_EQ(decode_binary(encode_binary(empty), "e").voxel_count(), 0U);
}

TEST(Serialize, CorruptBinariesAreRejected) {
  const auto bytes = encode_binary(sample_map(40, 2));
  ASSERT_LT(bytes.size(), 2000U);
  // Every truncation.
  for (std::size_t n = 0; n < bytes.size(); ++n) {
    const std::vector<std::uint8_t> cut(bytes.begin(), bytes.begin() + static_cast<std::ptrdiff_t>(n));
    EXPECT_THROW((void)decode_binary(cut, "cut.pvox"), InputError) << "truncated to " << n;
  }
  // Every single-byte flip.
  for (std::size_t i = 0; i < bytes.size(); ++i) {
    auto bad = bytes;
    bad[i] ^= 0x5A;
    EXPECT_THROW((void)decode_binary(bad, "flip.pvox"), InputError) << "byte " << i;
  }
  // Messages say what is wrong and where.
  auto bad = bytes;
  bad[1] = 'Q';
  try {
    (void)decode_binary(bad, "x.pvox");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("x.pvox: byte 0: not a PVOX file"), std::string::npos) << e.what();
  }
  bad = bytes;
  bad[100] ^= 1;
  try {
    (void)decode_binary(bad, "x.pvox");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("checksum"), std::string::npos) << e.what();
  }
  auto longer = bytes;
  longer.push_back(0);
  EXPECT_THROW((void)decode_binary(longer, "long.pvox"), InputError);
}

TEST(Serialize, VoxelCsvRoundTrip) {
  const VoxelMap map = sample_map(500, 3);
  const std::string csv = voxels_csv(map);
  const auto records = parse_voxels_csv(csv, "v.csv");
  auto voxels = map.voxels();
  const std::size_t all = voxels.size();
  std::erase_if(voxels, [](const VoxelView& v) { return v.hits == 0; });  // free-only voxels are not written
  EXPECT_EQ(voxels.size() + 1, all);
  ASSERT_EQ(records.size(), voxels.size());
  for (std::size_t i = 0; i < records.size(); ++i) {
    EXPECT_LT((records[i].centre - voxels[i].centre).cwiseAbs().maxCoeff(), 1e-5);
    EXPECT_EQ(map.key_of(records[i].centre), voxels[i].key);
    EXPECT_NEAR(records[i].edge, map.edge(), 1e-6);
    EXPECT_NEAR(records[i].probability, voxels[i].probability, 1e-5);
  }
  EXPECT_TRUE(parse_voxels_csv("x,y,z,edge,probability\n", "h.csv").empty());
  EXPECT_THROW((void)parse_voxels_csv("", "e.csv"), InputError);
  EXPECT_THROW((void)parse_voxels_csv("x,y,z\n1,2,3\n", "e.csv"), InputError);
  EXPECT_THROW((void)parse_voxels_csv("x,y,z,edge,probability\n1,2,3,0.1\n", "e.csv"), InputError);
  EXPECT_THROW((void)parse_voxels_csv("x,y,z,edge,probability\n1,2,3,0.1,1.5\n", "e.csv"), InputError);
  try {
    (void)parse_voxels_csv("x,y,z,edge,probability\n1,2,3,0.1,0.5\n1,2,a,0.1,0.5\n", "e.csv");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("e.csv: line 3"), std::string::npos) << e.what();
  }
}

TEST(Serialize, PointsCsv) {
  EXPECT_EQ(points_csv({Point3f(1.0F, -2.5F, 0.125F)}), "x,y,z\n1.0000,-2.5000,0.1250\n");
  EXPECT_EQ(points_csv({}), "x,y,z\n");
}

TEST(Serialize, CsvLinesOfHugeNumbersAreWhole) {
  // 1e30f is 1000000015047466219876688855040 exactly: 36 characters with "%.4f", three of them
  // overflowed the writer's 96-byte line buffer (issue 14; ASan: stack-buffer-overflow).
  const std::string x = "1000000015047466219876688855040.0000";
  EXPECT_EQ(points_csv({Point3f(1e30F, -1e30F, 1e30F), Point3f(1.0F, 2.0F, 3.0F)}),
            "x,y,z\n" + x + ",-" + x + "," + x + "\n1.0000,2.0000,3.0000\n");
}

}  // namespace
}  // namespace hmap::pvox
