#include "hmap/io/pcd.hpp"

#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "io/io_test_util.hpp"

namespace hmap {
namespace {

using test::contains;
using test::input_error_of;
using test::put;

class PcdTest : public test::IoTest {};

std::string header(const std::string& fields, const std::string& size, const std::string& type,
                   const std::string& count, std::size_t width, std::size_t height, const std::string& data) {
  return "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS " + fields + "\nSIZE " + size +
         "\nTYPE " + type + "\nCOUNT " + count + "\nWIDTH " + std::to_string(width) + "\nHEIGHT " +
         std::to_string(height) + "\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " + std::to_string(width * height) +
         "\nDATA " + data + "\n";
}

TEST_F(PcdTest, ReadsAscii) {
  const auto path = write("a.pcd", header("x y z rgb", "4 4 4 4", "F F F F", "1 1 1 1", 3, 1, "ascii") +
                                       "1 2 3 4.2e6\n-1.5 0.25 1e2 0\n\n7 8 9 0\n");
  CloudReadStats stats;
  const PointCloud cloud = read_pcd(path, &stats);
  ASSERT_EQ(cloud.size(), 3U);
  EXPECT_EQ(cloud[0], Point3f(1, 2, 3));
  EXPECT_EQ(cloud[1], Point3f(-1.5F, 0.25F, 100.0F));
  EXPECT_EQ(cloud[2], Point3f(7, 8, 9));
  EXPECT_EQ(stats.points_read, 3U);
  EXPECT_EQ(stats.non_finite_dropped, 0U);
}

TEST_F(PcdTest, ReadsAsciiInAnyFieldOrderWithCountsAboveOne) {
  // normal has COUNT 3: its three values sit between z and y on every line.
  const auto path =
      write("a.pcd", header("intensity z x normal y", "4 4 4 4 4", "F F F F F", "1 1 1 3 1", 2, 1, "ascii") +
                         "10 3 1 0 0 1 2\n11 6 4 1 0 0 5\n");
  const PointCloud cloud = read_pcd(path);
  ASSERT_EQ(cloud.size(), 2U);
  EXPECT_EQ(cloud[0], Point3f(1, 2, 3));
  EXPECT_EQ(cloud[1], Point3f(4, 5, 6));
}

TEST_F(PcdTest, ReadsVersion06WithoutVersionCountOrPoints) {
  const auto path = write("old.pcd",
                          "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 2\nHEIGHT 1\nDATA ascii\n"
                          "1 2 3\r\n4 5 6\r\n");
  const PointCloud cloud = read_pcd(path);
  ASSERT_EQ(cloud.size(), 2U);
  EXPECT_EQ(cloud[1], Point3f(4, 5, 6));
}

TEST_F(PcdTest, ReadsBinary) {
  std::string data;
  const std::vector<Point3f> expected = {{1.5F, -2.0F, 3.25F}, {0.0F, 1e-3F, -7.0F}};
  for (const Point3f& p : expected) {
    put<float>(data, p.x());
    put<float>(data, p.y());
    put<float>(data, p.z());
    put<float>(data, 42.0F);  // intensity
  }
  const auto path =
      write("b.pcd", header("x y z intensity", "4 4 4 4", "F F F F", "1 1 1 1", 2, 1, "binary") + data);
  CloudReadStats stats;
  const PointCloud cloud = read_pcd(path, &stats);
  ASSERT_EQ(cloud.size(), 2U);
  EXPECT_EQ(cloud[0], expected[0]);
  EXPECT_EQ(cloud[1], expected[1]);
  EXPECT_EQ(stats.points_read, 2U);
}

TEST_F(PcdTest, ReadsBinaryDoublesIntegersAndWideFieldsInAnyOrder) {
  // Record: uint8 label, float64 z, float32 normal[3], int16 y, float64 x: 1 + 8 + 12 + 2 + 8 = 31 bytes.
  std::string data;
  for (int i = 0; i < 3; ++i) {
    put<std::uint8_t>(data, static_cast<std::uint8_t>(200 + i));
    put<double>(data, 0.5 * i);
    for (int k = 0; k < 3; ++k) put<float>(data, -9.0F);
    put<std::int16_t>(data, static_cast<std::int16_t>(-100 * i));
    put<double>(data, 1.0 + i);
  }
  const auto path = write(
      "b.pcd", header("label z normal y x", "1 8 4 2 8", "U F F I F", "1 1 3 1 1", 3, 1, "binary") + data);
  const PointCloud cloud = read_pcd(path);
  ASSERT_EQ(cloud.size(), 3U);
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(cloud[i], Point3f(1.0F + static_cast<float>(i), -100.0F * static_cast<float>(i),
                                0.5F * static_cast<float>(i)));
  }
}

/// A binary_compressed PCD of an organized 2×2 cloud, fields x rgb y z, with one NaN pixel.
std::string organized_compressed_pcd(const std::string& lzf, std::uint32_t uncompressed) {
  std::string out = header("x rgb y z", "4 4 4 4", "F F F F", "1 1 1 1", 2, 2, "binary_compressed");
  put<std::uint32_t>(out, static_cast<std::uint32_t>(lzf.size()));
  put<std::uint32_t>(out, uncompressed);
  return out + lzf;
}

std::string organized_soa() {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const std::vector<float> x = {1, 2, nan, 4}, rgb = {0, 0, 0, 0}, y = {10, 20, nan, 40},
                           z = {-1, -2, nan, -4};
  std::string soa;
  for (const auto* column : {&x, &rgb, &y, &z}) {
    for (const float v : *column) put<float>(soa, v);
  }
  return soa;
}

TEST_F(PcdTest, ReadsBinaryCompressedOrganizedAndDropsNaN) {
  const std::string soa = organized_soa();
  const auto path = write(
      "c.pcd", organized_compressed_pcd(test::lzf_literals(soa), static_cast<std::uint32_t>(soa.size())));
  CloudReadStats stats;
  const PointCloud cloud = read_pcd(path, &stats);
  EXPECT_EQ(stats.points_read, 4U);
  EXPECT_EQ(stats.non_finite_dropped, 1U);
  ASSERT_EQ(cloud.size(), 3U);
  EXPECT_EQ(cloud[0], Point3f(1, 10, -1));
  EXPECT_EQ(cloud[1], Point3f(2, 20, -2));
  EXPECT_EQ(cloud[2], Point3f(4, 40, -4));
}

TEST_F(PcdTest, ReadsBinaryCompressedWithBackReferencesAndWideFields) {
  // Fields x y z d, d with COUNT 2; two points, all x = 1.0, so x's 8 bytes compress to a literal
  // run of 4 bytes and a back reference repeating them.
  std::string x_column;
  put<float>(x_column, 1.0F);
  std::string lzf;
  lzf.push_back(3);     // literal run of 4 bytes
  lzf += x_column;      // 00 00 80 3F
  lzf.push_back(0x40);  // back reference: length (2 + 2) = 4, offset high bits 0
  lzf.push_back(3);     // offset low byte: copy from 4 bytes back
  std::string rest;
  for (const float v : {2.0F, 3.0F, 5.0F, 6.0F, 0.0F, 0.0F, 0.0F, 0.0F}) put<float>(rest, v);  // y, z, d
  lzf += test::lzf_literals(rest);
  std::string file = header("x y z d", "4 4 4 4", "F F F F", "1 1 1 2", 2, 1, "binary_compressed");
  put<std::uint32_t>(file, static_cast<std::uint32_t>(lzf.size()));
  put<std::uint32_t>(file, 2 * 20);
  const PointCloud cloud = read_pcd(write("c.pcd", file + lzf));
  ASSERT_EQ(cloud.size(), 2U);
  EXPECT_EQ(cloud[0], Point3f(1, 2, 5));
  EXPECT_EQ(cloud[1], Point3f(1, 3, 6));
}

TEST_F(PcdTest, ReadsEmptyCloud) {
  EXPECT_TRUE(read_pcd(write("e.pcd", header("x y z", "4 4 4", "F F F", "1 1 1", 0, 1, "binary"))).empty());
  std::string compressed = header("x y z", "4 4 4", "F F F", "1 1 1", 0, 1, "binary_compressed");
  put<std::uint32_t>(compressed, 0);
  put<std::uint32_t>(compressed, 0);
  EXPECT_TRUE(read_pcd(write("c.pcd", compressed)).empty());
}

TEST_F(PcdTest, RejectsMissingAndEmptyFiles) {
  EXPECT_TRUE(contains(input_error_of([&] { (void)read_pcd(dir_ / "absent.pcd"); }),
                       "absent.pcd: cannot open: No such file or directory"));
  EXPECT_TRUE(contains(input_error_of([&] { (void)read_pcd(dir_); }), "cannot open"));
  EXPECT_TRUE(contains(input_error_of([&] { (void)read_pcd(write("empty.pcd", "")); }), "no DATA line"));
}

TEST_F(PcdTest, RejectsHeaderThatContradictsItself) {
  const auto error = [&](const std::string& text) {
    return input_error_of([&] { (void)read_pcd(write("h.pcd", text)); });
  };
  const std::string xyz = "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n";
  EXPECT_TRUE(contains(error(xyz + "WIDTH 3\nHEIGHT 2\nPOINTS 5\nDATA ascii\n"),
                       "WIDTH 3 × HEIGHT 2 differs from POINTS 5"));
  EXPECT_TRUE(contains(error("FIELDS x y z\nSIZE 4 2 4\nTYPE F F F\nWIDTH 1\nDATA binary\n"),
                       "field 'y' has TYPE F with SIZE 2; expected SIZE 4 or 8"));
  EXPECT_TRUE(contains(error("FIELDS x y z\nSIZE 4 4 3\nTYPE F F I\nWIDTH 1\nDATA binary\n"),
                       "field 'z' has TYPE I with SIZE 3"));
  EXPECT_TRUE(
      contains(error("FIELDS x y z\nSIZE 4 4 4\nTYPE F F Q\nWIDTH 1\nDATA binary\n"), "expected F, I or U"));
  EXPECT_TRUE(contains(error("FIELDS x y z\nSIZE 4 4\nTYPE F F F\nWIDTH 1\nDATA binary\n"),
                       "SIZE has 2 values for 3 FIELDS"));
  EXPECT_TRUE(contains(error("FIELDS x y\nSIZE 4 4\nTYPE F F\nWIDTH 1\nDATA binary\n"), "no field 'z'"));
  EXPECT_TRUE(contains(error("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 2 1 1\nWIDTH 1\nDATA binary\n"),
                       "field 'x' has COUNT 2; expected 1"));
  EXPECT_TRUE(contains(error(xyz + "WIDTH -3\nDATA ascii\n"), "line 5: WIDTH value '-3'"));
  EXPECT_TRUE(contains(error(xyz + "WIDTH 1\nDATA binary_zstd\n"), "line 6: DATA 'binary_zstd'"));
  EXPECT_TRUE(contains(error("ply\nformat ascii 1.0\n"), "line 1: unknown PCD header keyword 'ply'"));
}

TEST_F(PcdTest, RejectsHugePointClaimsQuicklyWithoutAllocating) {
  const auto start = std::chrono::steady_clock::now();
  const std::string huge =
      "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1000000000000\nHEIGHT 1\nPOINTS 1000000000000\n";
  EXPECT_TRUE(contains(
      input_error_of([&] { (void)read_pcd(write("b.pcd", huge + "DATA binary\n" + std::string(24, '\0'))); }),
      "data section holds 24 bytes, too few for POINTS 1000000000000"));
  EXPECT_TRUE(contains(input_error_of([&] { (void)read_pcd(write("a.pcd", huge + "DATA ascii\n1 2 3\n")); }),
                       "too few for POINTS 1000000000000"));
  std::string compressed = huge + "DATA binary_compressed\n";
  put<std::uint32_t>(compressed, 2);
  put<std::uint32_t>(compressed, 0xFFFFFFF0U);
  compressed += "ab";
  EXPECT_TRUE(contains(input_error_of([&] { (void)read_pcd(write("c.pcd", compressed)); }),
                       "uncompressed size 4294967280 differs from POINTS 1000000000000"));
  // Near 2^64 / point size: the bound must not overflow.
  const std::string overflow =
      "FIELDS x y z\nSIZE 8 8 8\nTYPE F F F\nWIDTH 768614336404564651\nDATA binary\n";
  EXPECT_TRUE(
      contains(input_error_of([&] { (void)read_pcd(write("o.pcd", overflow + std::string(48, '\0'))); }),
               "too few for POINTS 768614336404564651"));
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(1));
}

TEST_F(PcdTest, RejectsTruncatedData) {
  std::string binary = header("x y z", "4 4 4", "F F F", "1 1 1", 3, 1, "binary");
  const std::size_t data_offset = binary.size();
  binary += std::string(3 * 12 - 1, '\0');
  EXPECT_TRUE(contains(input_error_of([&] { (void)read_pcd(write("b.pcd", binary)); }),
                       "byte " + std::to_string(data_offset) + ": data section holds 35 bytes"));

  const std::string ascii =
      header("x y z", "4 4 4", "F F F", "1 1 1", 3, 1, "ascii") + "1 2 3\n4 5 6\n7 8 9 ";
  // The last line is complete enough to pass the size bound but one point short.
  EXPECT_TRUE(contains(input_error_of([&] {
                         (void)read_pcd(
                             write("a.pcd", header("x y z", "4 4 4", "F F F", "1 1 1", 3, 1, "ascii") +
                                                "1 2 3\n4 5 6\n\n\n\n\n\n\n"));
                       }),
                       "line 20: file ends after 2 of 3 points"));
  EXPECT_TRUE(
      contains(input_error_of([&] { (void)read_pcd(write("a2.pcd", ascii.substr(0, ascii.size() - 3))); }),
               "too few for POINTS 3"));
}

TEST_F(PcdTest, RejectsMalformedAsciiValues) {
  const std::string head = header("x y z", "4 4 4", "F F F", "1 1 1", 2, 1, "ascii");  // 11 lines
  EXPECT_TRUE(contains(input_error_of([&] { (void)read_pcd(write("a.pcd", head + "1 2 3\n4 five 6\n")); }),
                       "a.pcd: line 13: 'five' is not a number"));
  EXPECT_TRUE(contains(input_error_of([&] { (void)read_pcd(write("a.pcd", head + "1 2 3 4\n4 5 6\n")); }),
                       "line 12: expected 3 values as FIELDS and COUNT say, found 4"));
}

TEST_F(PcdTest, RejectsCorruptCompressedData) {
  const std::string soa = organized_soa();
  const auto size = static_cast<std::uint32_t>(soa.size());
  const std::string lzf = test::lzf_literals(soa);
  // Compressed size beyond the end of the file.
  std::string file = header("x rgb y z", "4 4 4 4", "F F F F", "1 1 1 1", 2, 2, "binary_compressed");
  put<std::uint32_t>(file, static_cast<std::uint32_t>(lzf.size() + 100));
  put<std::uint32_t>(file, size);
  EXPECT_TRUE(contains(input_error_of([&] { (void)read_pcd(write("c1.pcd", file + lzf)); }),
                       "exceeds the " + std::to_string(lzf.size()) + " bytes left"));
  // Uncompressed size that is not POINTS × point size.
  EXPECT_TRUE(contains(
      input_error_of([&] { (void)read_pcd(write("c2.pcd", organized_compressed_pcd(lzf, size + 4))); }),
      "uncompressed size 68 differs from POINTS 4 × 16 bytes"));
  // A stream that decodes to fewer bytes than announced.
  EXPECT_TRUE(contains(input_error_of([&] {
                         (void)read_pcd(write("c3.pcd", organized_compressed_pcd(
                                                            test::lzf_literals(soa.substr(0, 60)), size)));
                       }),
                       "corrupt LZF data"));
  // A back reference before the start of the output.
  EXPECT_TRUE(contains(input_error_of([&] {
                         (void)read_pcd(write(
                             "c4.pcd", organized_compressed_pcd(std::string("\x40\x10", 2) + lzf, size)));
                       }),
                       "corrupt LZF data"));
  // A ratio LZF cannot reach: 64 bytes from none.
  EXPECT_TRUE(
      contains(input_error_of([&] { (void)read_pcd(write("c5.pcd", organized_compressed_pcd("", size))); }),
               "cannot come from 0 LZF-compressed bytes"));
  // Size header cut off.
  const std::string cut = header("x y z", "4 4 4", "F F F", "1 1 1", 1, 1, "binary_compressed") + "abc";
  EXPECT_TRUE(contains(input_error_of([&] { (void)read_pcd(write("c6.pcd", cut)); }), "8-byte size header"));
}

// VIEWPOINT is the sensor's pose in the cloud's frame (tx ty tz qw qx qy qz): the points come out
// in that frame. Here 90° about z and a shift: sensor (1, 0, 0) -> (10, 21, 30).
TEST_F(PcdTest, AppliesTheViewpoint) {
  std::string text = header("x y z", "4 4 4", "F F F", "1 1 1", 2, 1, "ascii") + "1 0 0\n0 0 2\n";
  const auto at = text.find("VIEWPOINT 0 0 0 1 0 0 0");
  text.replace(at, 23, "VIEWPOINT 10 20 30 0.70710678 0 0 0.70710678");
  const PointCloud cloud = read_pcd(write("v.pcd", text));
  ASSERT_EQ(cloud.size(), 2U);
  EXPECT_NEAR((cloud[0] - Point3f(10, 21, 30)).norm(), 0.0F, 1e-5F);
  EXPECT_NEAR((cloud[1] - Point3f(10, 20, 32)).norm(), 0.0F, 1e-5F);
  // The Kinect files' 180° about x (qx = 1): y and z change sign.
  text = header("x y z", "4 4 4", "F F F", "1 1 1", 1, 1, "ascii") + "1 2 3\n";
  text.replace(text.find("VIEWPOINT 0 0 0 1 0 0 0"), 23, "VIEWPOINT 0 0 0 0 1 0 0");
  EXPECT_EQ(read_pcd(write("k.pcd", text)).at(0), Point3f(1, -2, -3));
  // Not a rotation, or not seven numbers: refused with the line.
  text.replace(text.find("VIEWPOINT 0 0 0 0 1 0 0"), 23, "VIEWPOINT 0 0 0 0 2 0 0");
  EXPECT_TRUE(contains(input_error_of([&] { (void)read_pcd(write("n.pcd", text)); }), "n.pcd: line 9: VIEWPOINT quaternion"));
  text.replace(text.find("VIEWPOINT 0 0 0 0 2 0 0"), 23, "VIEWPOINT 0 0 0 1 0 0");
  EXPECT_TRUE(contains(input_error_of([&] { (void)read_pcd(write("s.pcd", text)); }), "VIEWPOINT expects 7 numbers"));
}

// A point finite in the file can leave float's range once the viewpoint moves it (the fuzzer's find:
// 3e38 shifted by 1e38, or turned 45° with y = 3e38). It is dropped and counted, never returned as inf,
// and its time goes with it.
TEST_F(PcdTest, APointTheViewpointMovesOutOfFloatRangeIsDroppedWithItsTime) {
  std::string text = header("x y z t", "4 4 4 4", "F F F F", "1 1 1 1", 3, 1, "ascii") +
                     "1 2 3 0.1\n3e38 0 0 0.2\n-3e38 3e38 0 0.3\n";
  text.replace(text.find("VIEWPOINT 0 0 0 1 0 0 0"), 23, "VIEWPOINT 1e38 0 0 1 0 0 0");
  CloudReadStats stats;
  std::vector<float> times;
  PointCloud cloud = read_pcd(write("far.pcd", text), &stats, &times);
  ASSERT_EQ(cloud.size(), 2U);  // 3e38 + 1e38 leaves float's range; 1 + 1e38 and -3e38 + 1e38 do not
  EXPECT_EQ(stats.points_read, 3U);
  EXPECT_EQ(stats.non_finite_dropped, 1U);
  ASSERT_EQ(times.size(), 2U);
  EXPECT_FLOAT_EQ(times[1] - times[0], 0.2F);  // the dropped point's time went with it (0.1, 0.3 kept)
  // 45° about z: (3e38, 3e38) turns to (0, 4.2e38).
  text = header("x y z", "4 4 4", "F F F", "1 1 1", 2, 1, "ascii") + "3e38 3e38 0\n1 0 0\n";
  text.replace(text.find("VIEWPOINT 0 0 0 1 0 0 0"), 23, "VIEWPOINT 0 0 0 0.92387953 0 0 0.38268343");
  stats = {};
  cloud = read_pcd(write("turn.pcd", text), &stats);
  ASSERT_EQ(cloud.size(), 1U);
  EXPECT_EQ(stats.non_finite_dropped, 1U);
  for (const Point3f& p : cloud) EXPECT_TRUE(p.allFinite());
}

// ---- real data ----

TEST(PcdRealData, ReadsKinectOrganizedCompressedClouds) {
  HMAP_REQUIRE_DATA("kinect_pcd");
  int files = 0;
  for (const auto& entry : std::filesystem::directory_iterator(test::data_dir() / "kinect_pcd")) {
    if (entry.path().extension() != ".pcd") continue;
    ++files;
    CloudReadStats stats;
    const PointCloud cloud = read_pcd(entry.path(), &stats);
    SCOPED_TRACE(entry.path().string());
    EXPECT_EQ(stats.points_read, 640U * 480U);
    EXPECT_EQ(cloud.size() + stats.non_finite_dropped, stats.points_read);
    EXPECT_GT(cloud.size(), 100000U);  // a Kinect sees most pixels of an indoor scene
    EXPECT_GT(stats.non_finite_dropped, 0U);
    for (const Point3f& p : cloud) {
      ASSERT_TRUE(p.allFinite());
      ASSERT_LT(p.cwiseAbs().maxCoeff(), 20.0F);
    }
  }
  EXPECT_EQ(files, 4);
}

TEST(PcdRealData, ReadsHdl32BinaryPair) {
  HMAP_REQUIRE_DATA("hdl32_pair");
  for (const char* name : {"251370668.pcd", "251371071.pcd"}) {
    SCOPED_TRACE(name);
    CloudReadStats stats;
    const PointCloud cloud = read_pcd(test::data_dir() / "hdl32_pair" / name, &stats);
    EXPECT_GT(stats.points_read, 50000U);
    EXPECT_EQ(cloud.size() + stats.non_finite_dropped, stats.points_read);
    for (const Point3f& p : cloud) ASSERT_LT(p.cwiseAbs().maxCoeff(), 150.0F);
  }
  CloudReadStats stats;
  (void)read_pcd(test::data_dir() / "hdl32_pair" / "251370668.pcd", &stats);
  EXPECT_EQ(stats.points_read, 69088U);  // WIDTH of its header
}

}  // namespace
}  // namespace hmap

namespace hmap {
namespace {

using test::put;

class PcdTimeTest : public test::IoTest {};

TEST_F(PcdTimeTest, OusterStyleNanosecondsBesideTheKeptPoints) {
  // Binary, uint32 `t` in ns from the sweep's start (Ouster); the NaN point is dropped with its time.
  std::string data;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float xs[3] = {1.0F, nan, 3.0F};
  const std::uint32_t ts[3] = {0, 50'000'000, 99'000'000};
  for (int i = 0; i < 3; ++i) {
    put<float>(data, xs[i]);
    put<float>(data, 0.0F);
    put<float>(data, 0.5F);
    put<std::uint32_t>(data, ts[i]);
  }
  std::vector<float> times;
  const PointCloud cloud =
      read_pcd(write("t.pcd", header("x y z t", "4 4 4 4", "F F F U", "1 1 1 1", 3, 1, "binary") + data), nullptr, &times);
  ASSERT_EQ(cloud.size(), 2U);
  ASSERT_EQ(times.size(), 2U);
  EXPECT_FLOAT_EQ(times[0], 0.0F);
  EXPECT_FLOAT_EQ(times[1], 0.099F);
}

TEST_F(PcdTimeTest, SecondsMillisecondsAndAbsoluteStamps) {
  const auto read = [&](const std::string& name, const std::string& field, const std::string& values) {
    std::vector<float> times;
    (void)read_pcd(write(name, header("x y z " + field, "4 4 4 8", "F F F F", "1 1 1 1", 2, 1, "ascii") + values),
                   nullptr, &times);
    return times;
  };
  std::vector<float> t = read("s.pcd", "time", "1 0 0 -0.05\n2 0 0 0.05\n");  // Velodyne: s, around the stamp
  ASSERT_EQ(t.size(), 2U);
  EXPECT_FLOAT_EQ(t[0], -0.05F);
  EXPECT_FLOAT_EQ(t[1], 0.05F);
  t = read("ms.pcd", "t", "1 0 0 0\n2 0 0 100\n");  // 100 ms
  EXPECT_FLOAT_EQ(t[1], 0.1F);
  t = read("abs.pcd", "timestamp", "1 0 0 1700000000.25\n2 0 0 1700000000.35\n");  // unix s: from the first point
  EXPECT_FLOAT_EQ(t[0], 0.0F);
  EXPECT_NEAR(t[1], 0.1F, 1e-6);
  // No time field: empty; a non-finite time is refused.
  t = read("none.pcd", "intensity", "1 0 0 7\n2 0 0 8\n");
  EXPECT_TRUE(t.empty());
  EXPECT_TRUE(test::contains(test::input_error_of([&] { (void)read("bad.pcd", "t", "1 0 0 nan\n2 0 0 1\n"); }),
                             "bad.pcd: line 12"));
}

TEST_F(PcdTimeTest, WithoutTheTimeRequestTheCloudIsTheSame) {
  const auto path = write("same.pcd", header("x y z t", "4 4 4 4", "F F F F", "1 1 1 1", 2, 1, "ascii") +
                                          "1 2 3 0\n4 5 6 0.1\n");
  std::vector<float> times;
  EXPECT_EQ(read_pcd(path), read_pcd(path, nullptr, &times));
  EXPECT_EQ(times.size(), 2U);
}

}  // namespace
}  // namespace hmap

namespace hmap {
namespace {

/// `n` zero bytes as LZF: one literal byte, then back references of 264 bytes at distance 1
/// (3 bytes each: the most a reference holds), and a shorter one for the rest.
std::string lzf_zeros(std::size_t n) {
  std::string out;
  if (n == 0) return out;
  out.push_back('\0');  // a literal run of one byte
  out.push_back('\0');
  std::size_t done = 1;
  while (done < n) {
    const std::size_t len = std::min<std::size_t>(264, n - done);
    if (len < 3) {  // a reference copies at least 3 bytes: the rest as literals
      out.push_back(static_cast<char>(len - 1));
      out.append(len, '\0');
      break;
    }
    if (len - 2 < 7) {
      out.push_back(static_cast<char>((len - 2) << 5));
    } else {
      out.push_back(static_cast<char>(7 << 5));
      out.push_back(static_cast<char>(len - 2 - 7));
    }
    out.push_back('\0');  // distance 1
    done += len;
  }
  return out;
}

// A compressed PCD decompresses to up to 88 times its size: the points it would make are checked
// against the memory budget before anything is allocated (issue 14: "a compressed PCD's
// decompressed points are not budgeted").
namespace fs = std::filesystem;

TEST(PcdBudgetTest, CompressedPointsBeyondTheBudgetAreRefusedBeforeTheyAreDecompressed) {
  const fs::path dir = fs::temp_directory_path() / ("hmap_pcd_budget_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  constexpr std::uint32_t kPoints = 1'000'000;
  const std::uint32_t raw = kPoints * 12;
  const std::string lzf = lzf_zeros(raw);
  ASSERT_LT(lzf.size() * 80, raw) << "the file is small: the size check before reading does not catch it";
  std::string file = "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH " + std::to_string(kPoints) +
                     "\nHEIGHT 1\nPOINTS " + std::to_string(kPoints) + "\nDATA binary_compressed\n";
  const auto put32 = [&](std::uint32_t v) { file.append(reinterpret_cast<const char*>(&v), 4); };
  put32(static_cast<std::uint32_t>(lzf.size()));
  put32(raw);
  file += lzf;
  const fs::path path = dir / "zeros.pcd";
  {
    std::ofstream out(path, std::ios::binary);
    out << file;
  }
  MemoryBudget small;
  small.bytes = std::size_t{16} << 20;  // 16 MiB: less than the 12 MB decompressed + 12 MB of points
  try {
    (void)read_pcd(path, nullptr, nullptr, &small);
    ADD_FAILURE() << "read within a budget it exceeds";
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("zeros.pcd: the decompressed points of its binary_compressed data needs 23 MiB"), std::string::npos)
        << what;
    EXPECT_NE(what.find("--max-memory"), std::string::npos) << what;
  }
  MemoryBudget enough;
  enough.bytes = std::size_t{32} << 20;
  const PointCloud cloud = read_pcd(path, nullptr, nullptr, &enough);
  ASSERT_EQ(cloud.size(), kPoints);
  EXPECT_EQ(cloud.front(), Point3f(0, 0, 0));
  EXPECT_EQ(cloud.back(), Point3f(0, 0, 0));
  EXPECT_EQ(read_pcd(path).size(), kPoints) << "no budget given: read";
  fs::remove_all(dir);
}

}  // namespace
}  // namespace hmap
