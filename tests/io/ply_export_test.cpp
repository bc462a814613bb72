#include "hmap/io/ply_export.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <iterator>
#include <limits>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "common/test_data.hpp"
#include "hmap/core/error.hpp"
#include "hmap/io/ply.hpp"

namespace hmap {
namespace {

std::string read_bytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

/// The header of a PLY file, parsed independently of hmap's reader.
struct PlyHeader {
  std::vector<std::string> lines;  // without "ply" and "end_header"
  std::vector<std::pair<std::string, std::uint64_t>> elements;
  std::size_t bytes = 0;           // header length, "end_header\n" included
};

PlyHeader parse_header(const std::string& file) {
  PlyHeader h;
  const std::size_t end = file.find("end_header\n");
  if (file.rfind("ply\n", 0) != 0 || end == std::string::npos) {
    ADD_FAILURE() << "not a PLY header";
    return h;
  }
  h.bytes = end + std::string("end_header\n").size();
  std::istringstream in(file.substr(4, end - 4));
  for (std::string line; std::getline(in, line);) {
    h.lines.push_back(line);
    std::istringstream words(line);
    std::string keyword;
    std::string name;
    std::uint64_t count = 0;
    if (words >> keyword && keyword == "element" && words >> name >> count) h.elements.emplace_back(name, count);
  }
  return h;
}

struct Vertex {
  float x, y, z;
  std::array<unsigned char, 3> rgb;
};

float get_f32(const std::string& s, std::size_t at) {
  std::uint32_t v = 0;
  for (int k = 3; k >= 0; --k) v = (v << 8) | static_cast<unsigned char>(s[at + k]);
  return std::bit_cast<float>(v);
}

std::int32_t get_i32(const std::string& s, std::size_t at) {
  std::uint32_t v = 0;
  for (int k = 3; k >= 0; --k) v = (v << 8) | static_cast<unsigned char>(s[at + k]);
  return static_cast<std::int32_t>(v);
}

constexpr std::size_t kVertexBytes = 3 * 4 + 3;
constexpr std::size_t kFaceBytes = 1 + 4 * 4;

std::vector<Vertex> vertices_of(const std::string& file, std::size_t at, std::uint64_t count) {
  std::vector<Vertex> v;
  for (std::uint64_t k = 0; k < count; ++k, at += kVertexBytes) {
    v.push_back({get_f32(file, at), get_f32(file, at + 4), get_f32(file, at + 8),
                 {static_cast<unsigned char>(file[at + 12]), static_cast<unsigned char>(file[at + 13]),
                  static_cast<unsigned char>(file[at + 14])}});
  }
  return v;
}

const std::vector<std::string> kVertexProperties = {
    "property float x",   "property float y",     "property float z",
    "property uchar red", "property uchar green", "property uchar blue"};

class PlyExportTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = test::temp_dir(std::string("ply_export_") +
                          ::testing::UnitTest::GetInstance()->current_test_info()->name());
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  std::filesystem::path dir_;
};

HMap box_map() {
  Params p;
  p.map.cell_size = 0.5;
  HMap map(p);
  const auto put = [&map](CellKey key, std::vector<HVoxel> hvoxels) {
    TileColumn c = map.column_for_update(key);
    for (const HVoxel& v : hvoxels) c.push_back(v);
  };
  put({0, 0}, {{0.0F, 1.0F, 10.0F, 0.9F}, {2.0F, 2.0F, 1.0F, 0.1F}});  // the second is flat
  put({-3, 5}, {{-1.0F, -0.5F, 4.0F, 0.5F}});
  put({40, -17}, {{3.0F, 4.5F, 6.0F, 0.7F}});
  return map;
}

struct Extent {
  double x0, y0, z0, x1, y1, z1;
};

TEST_F(PlyExportTest, BoxesHaveTheHVoxelsExtents) {
  const HMap map = box_map();
  const auto path = dir_ / "boxes.ply";
  write_hvoxel_boxes_ply(path, map);
  const std::string file = read_bytes(path);
  const PlyHeader h = parse_header(file);
  ASSERT_GE(h.lines.size(), 10U);
  EXPECT_EQ(h.lines[0], "format binary_little_endian 1.0");
  const std::uint64_t hvoxels = map.stats().hvoxels;
  ASSERT_EQ(hvoxels, 4U);
  ASSERT_EQ(h.elements.size(), 2U);
  EXPECT_EQ(h.elements[0], (std::pair<std::string, std::uint64_t>("vertex", 8 * hvoxels)));
  EXPECT_EQ(h.elements[1], (std::pair<std::string, std::uint64_t>("face", 6 * hvoxels)));
  std::vector<std::string> properties;
  for (const std::string& l : h.lines) {
    if (l.rfind("property", 0) == 0) properties.push_back(l);
  }
  std::vector<std::string> expected_properties = kVertexProperties;
  expected_properties.push_back("property list uchar int vertex_indices");
  EXPECT_EQ(properties, expected_properties);
  ASSERT_EQ(file.size(), h.bytes + 8 * hvoxels * kVertexBytes + 6 * hvoxels * kFaceBytes);

  // The expected box of every HVoxel: the cell's x, y extent, the HVoxel's z range (flat ones
  // 0.1 · cell_size thick, centred).
  std::vector<Extent> expected;
  const double half = 0.5 * map.cell_size();
  map.for_each_column([&](const CellKey& key, const ColumnView& c) {
    const Eigen::Vector2d centre = map.cell_center(key);
    for (const HVoxel& v : c) {
      double z0 = v.z_min;
      double z1 = v.z_max;
      if (z1 - z0 < 0.05) {
        z0 -= 0.025;
        z1 += 0.025;
      }
      expected.push_back({centre.x() - half, centre.y() - half, z0, centre.x() + half, centre.y() + half, z1});
    }
  });

  const std::vector<Vertex> vertices = vertices_of(file, h.bytes, 8 * hvoxels);
  const std::size_t faces_at = h.bytes + 8 * hvoxels * kVertexBytes;
  for (std::uint64_t box = 0; box < hvoxels; ++box) {
    Extent e{1e9, 1e9, 1e9, -1e9, -1e9, -1e9};
    for (std::size_t k = 8 * box; k < 8 * box + 8; ++k) {
      const Vertex& v = vertices[k];
      e = {std::min<double>(e.x0, v.x), std::min<double>(e.y0, v.y), std::min<double>(e.z0, v.z),
           std::max<double>(e.x1, v.x), std::max<double>(e.y1, v.y), std::max<double>(e.z1, v.z)};
    }
    // Every vertex is a corner of the extent, and the 8 corners are distinct.
    std::vector<int> corners;
    for (std::size_t k = 8 * box; k < 8 * box + 8; ++k) {
      const Vertex& v = vertices[k];
      ASSERT_TRUE(v.x == e.x0 || v.x == e.x1);
      ASSERT_TRUE(v.y == e.y0 || v.y == e.y1);
      ASSERT_TRUE(v.z == e.z0 || v.z == e.z1);
      corners.push_back((v.x == e.x1 ? 1 : 0) + (v.y == e.y1 ? 2 : 0) + (v.z == e.z1 ? 4 : 0));
    }
    std::sort(corners.begin(), corners.end());
    EXPECT_EQ(corners, (std::vector<int>{0, 1, 2, 3, 4, 5, 6, 7}));
    const auto match = std::find_if(expected.begin(), expected.end(), [&](const Extent& x) {
      const double tol = 1e-5;
      return std::abs(x.x0 - e.x0) < tol && std::abs(x.y0 - e.y0) < tol && std::abs(x.z0 - e.z0) < tol &&
             std::abs(x.x1 - e.x1) < tol && std::abs(x.y1 - e.y1) < tol && std::abs(x.z1 - e.z1) < tol;
    });
    ASSERT_NE(match, expected.end()) << "box " << box << " matches no HVoxel";
    expected.erase(match);

    // Six quads on the six sides, counter-clockwise seen from outside.
    const Eigen::Vector3d centre(0.5 * (e.x0 + e.x1), 0.5 * (e.y0 + e.y1), 0.5 * (e.z0 + e.z1));
    std::vector<std::string> sides;
    for (std::uint64_t f = 6 * box; f < 6 * box + 6; ++f) {
      const std::size_t at = faces_at + f * kFaceBytes;
      ASSERT_EQ(file[at], 4);
      std::array<Eigen::Vector3d, 4> q;
      for (std::size_t k = 0; k < 4; ++k) {
        const std::int32_t index = get_i32(file, at + 1 + 4 * k);
        ASSERT_GE(index, static_cast<std::int32_t>(8 * box));
        ASSERT_LT(index, static_cast<std::int32_t>(8 * box + 8));
        const Vertex& v = vertices[static_cast<std::size_t>(index)];
        q[k] = Eigen::Vector3d(v.x, v.y, v.z);
      }
      Eigen::Vector3d normal = Eigen::Vector3d::Zero();  // Newell's method
      for (std::size_t k = 0; k < 4; ++k) normal += q[k].cross(q[(k + 1) % 4]);
      const Eigen::Vector3d face_centre = (q[0] + q[1] + q[2] + q[3]) / 4.0;
      const Eigen::Vector3d outward = face_centre - centre;
      EXPECT_GT(normal.normalized().dot(outward.normalized()), 0.999) << "face " << f;
      std::ostringstream side;
      side << outward.normalized().transpose().array().round();
      sides.push_back(side.str());
    }
    std::sort(sides.begin(), sides.end());
    EXPECT_EQ(std::unique(sides.begin(), sides.end()), sides.end()) << "six different sides";
  }
  EXPECT_TRUE(expected.empty());

  // Colours by height: the lowest vertex is blue, the highest red.
  const auto lowest = std::min_element(vertices.begin(), vertices.end(),
                                       [](const Vertex& a, const Vertex& b) { return a.z < b.z; });
  const auto highest = std::max_element(vertices.begin(), vertices.end(),
                                         [](const Vertex& a, const Vertex& b) { return a.z < b.z; });
  EXPECT_EQ(lowest->rgb, (std::array<unsigned char, 3>{0, 0, 255}));
  EXPECT_EQ(highest->rgb, (std::array<unsigned char, 3>{255, 0, 0}));
}

TEST_F(PlyExportTest, EmptyMapGivesAnEmptyValidPly) {
  HMap map(Params{});
  (void)map.column_for_update({3, 3});  // an allocated tile without HVoxels
  const auto path = dir_ / "empty.ply";
  write_hvoxel_boxes_ply(path, map);
  const std::string file = read_bytes(path);
  const PlyHeader h = parse_header(file);
  ASSERT_EQ(h.elements.size(), 2U);
  EXPECT_EQ(h.elements[0].second, 0U);
  EXPECT_EQ(h.elements[1].second, 0U);
  EXPECT_EQ(file.size(), h.bytes);
  EXPECT_TRUE(read_ply(path).empty());
}

TEST_F(PlyExportTest, SameMapSameBytes) {
  const HMap map = box_map();
  write_hvoxel_boxes_ply(dir_ / "a.ply", map);
  write_hvoxel_boxes_ply(dir_ / "b.ply", map);
  EXPECT_EQ(read_bytes(dir_ / "a.ply"), read_bytes(dir_ / "b.ply"));
}

TEST_F(PlyExportTest, PointsRoundTrip) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-50.0F, 50.0F);
  PointCloud points;
  for (int k = 0; k < 5000; ++k) points.emplace_back(u(rng), u(rng), 0.1F * u(rng));
  const auto path = dir_ / "points.ply";
  write_points_ply(path, points);

  const std::string file = read_bytes(path);
  const PlyHeader h = parse_header(file);
  ASSERT_EQ(h.elements.size(), 1U);
  EXPECT_EQ(h.elements[0], (std::pair<std::string, std::uint64_t>("vertex", points.size())));
  EXPECT_EQ(file.size(), h.bytes + points.size() * kVertexBytes);
  const std::vector<Vertex> vertices = vertices_of(file, h.bytes, points.size());
  for (std::size_t k = 0; k < points.size(); ++k) {
    ASSERT_EQ(vertices[k].x, points[k].x());
    ASSERT_EQ(vertices[k].y, points[k].y());
    ASSERT_EQ(vertices[k].z, points[k].z());
  }

  CloudReadStats stats;
  const PointCloud back = read_ply(path, &stats);
  ASSERT_EQ(back.size(), points.size());
  for (std::size_t k = 0; k < points.size(); ++k) ASSERT_EQ(back[k], points[k]) << k;
  EXPECT_EQ(stats.points_read, points.size());
}

TEST_F(PlyExportTest, EmptyAndNonFiniteClouds) {
  write_points_ply(dir_ / "none.ply", {});
  const std::string file = read_bytes(dir_ / "none.ply");
  EXPECT_EQ(file.size(), parse_header(file).bytes);
  EXPECT_TRUE(read_ply(dir_ / "none.ply").empty());

  const float nan = std::numeric_limits<float>::quiet_NaN();
  const PointCloud points = {{0, 0, 0}, {nan, 1, 2}, {1, 1, 1}};
  write_points_ply(dir_ / "nan.ply", points);
  const std::string nan_file = read_bytes(dir_ / "nan.ply");
  const std::vector<Vertex> v = vertices_of(nan_file, parse_header(nan_file).bytes, 3);
  EXPECT_TRUE(std::isnan(v[1].x));
  EXPECT_EQ(v[1].rgb, (std::array<unsigned char, 3>{128, 128, 128}));
  EXPECT_EQ(v[0].rgb, (std::array<unsigned char, 3>{0, 0, 255}));
  EXPECT_EQ(v[2].rgb, (std::array<unsigned char, 3>{255, 0, 0}));
}

TEST_F(PlyExportTest, WritesReplaceAtomically) {
  const auto path = dir_ / "map.ply";
  write_hvoxel_boxes_ply(path, box_map());
  write_points_ply(path, {{1, 2, 3}});
  EXPECT_EQ(read_ply(path).size(), 1U);
  std::vector<std::string> names;
  for (const auto& entry : std::filesystem::directory_iterator(dir_)) {
    names.push_back(entry.path().filename().string());
  }
  EXPECT_EQ(names, std::vector<std::string>{"map.ply"});
  EXPECT_THROW(write_points_ply(dir_ / "missing" / "p.ply", {}), Error);
}

}  // namespace
}  // namespace hmap
