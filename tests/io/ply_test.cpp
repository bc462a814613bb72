#include "hmap/io/ply.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <limits>
#include <string>

#include "io/io_test_util.hpp"

namespace hmap {
namespace {

using test::contains;
using test::input_error_of;
using test::put;

class PlyTest : public test::IoTest {};

TEST_F(PlyTest, ReadsAsciiWithExtraPropertiesAndFacesAfter) {
  const auto path = write("a.ply",
                          "ply\nformat ascii 1.0\ncomment made by hand\nelement vertex 3\nproperty float nx\n"
                          "property float x\nproperty uchar red\nproperty float y\nproperty float z\n"
                          "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
                          "0 1 255 2 3\n0 -4.5 0 5 6e1\n0 7 1 8 9\n3 0 1 2\n");
  CloudReadStats stats;
  const PointCloud cloud = read_ply(path, &stats);
  ASSERT_EQ(cloud.size(), 3U);
  EXPECT_EQ(cloud[0], Point3f(1, 2, 3));
  EXPECT_EQ(cloud[1], Point3f(-4.5F, 5, 60));
  EXPECT_EQ(cloud[2], Point3f(7, 8, 9));
  EXPECT_EQ(stats.points_read, 3U);
}

/// The same small mesh in a binary PLY: x double, y float32, z int16 among other properties, a
/// face element after the vertices.
std::string binary_ply(std::endian order, bool faces_first) {
  const std::string format = order == std::endian::little ? "binary_little_endian" : "binary_big_endian";
  std::string text = "ply\r\nformat " + format + " 1.0\r\n";
  const std::string face_header =
      "element face 2\nproperty list uchar int vertex_indices\nproperty uint8 flags\n";
  if (faces_first) text += face_header;
  text +=
      "element vertex 2\nproperty uchar red\nproperty double x\nproperty float32 y\nproperty int16 z\n"
      "property list uint16 float weights\n";
  if (!faces_first) text += face_header;
  text += "end_header\n";
  std::string faces;
  put<std::uint8_t>(faces, 3, order);
  for (const int i : {0, 1, 0}) put<std::int32_t>(faces, i, order);
  put<std::uint8_t>(faces, 7, order);
  put<std::uint8_t>(faces, 0, order);  // an empty list
  put<std::uint8_t>(faces, 8, order);
  if (faces_first) text += faces;
  put<std::uint8_t>(text, 255, order);
  put<double>(text, 1.25, order);
  put<float>(text, -2.5F, order);
  put<std::int16_t>(text, -300, order);
  put<std::uint16_t>(text, 2, order);
  put<float>(text, 0.5F, order);
  put<float>(text, 0.5F, order);
  put<std::uint8_t>(text, 0, order);
  put<double>(text, 4.0, order);
  put<float>(text, 5.0F, order);
  put<std::int16_t>(text, 6, order);
  put<std::uint16_t>(text, 0, order);
  if (!faces_first) text += faces;
  return text;
}

TEST_F(PlyTest, ReadsBinaryLittleAndBigEndianWithAnyScalarTypes) {
  for (const std::endian order : {std::endian::little, std::endian::big}) {
    for (const bool faces_first : {false, true}) {
      SCOPED_TRACE(std::string(order == std::endian::little ? "little" : "big") +
                   (faces_first ? ", faces first" : ""));
      const PointCloud cloud = read_ply(write("b.ply", binary_ply(order, faces_first)));
      ASSERT_EQ(cloud.size(), 2U);
      EXPECT_EQ(cloud[0], Point3f(1.25F, -2.5F, -300.0F));
      EXPECT_EQ(cloud[1], Point3f(4, 5, 6));
    }
  }
}

TEST_F(PlyTest, ReadsFixedSizeBinaryVertices) {
  std::string text =
      "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float z\nproperty float y\n"
      "property float x\nproperty float intensity\nend_header\n";
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (const float v : {3.0F, 2.0F, 1.0F, 0.0F, nan, 0.0F, 0.0F, 0.0F, 6.0F, 5.0F, 4.0F, 0.0F})
    put<float>(text, v);
  text += "trailing bytes of later elements are not read";
  CloudReadStats stats;
  const PointCloud cloud = read_ply(write("f.ply", text), &stats);
  ASSERT_EQ(cloud.size(), 2U);
  EXPECT_EQ(cloud[0], Point3f(1, 2, 3));
  EXPECT_EQ(cloud[1], Point3f(4, 5, 6));
  EXPECT_EQ(stats.points_read, 3U);
  EXPECT_EQ(stats.non_finite_dropped, 1U);
}

TEST_F(PlyTest, SkipsAsciiElementsBeforeVertices) {
  const auto path = write("a.ply",
                          "ply\nformat ascii 1.0\nelement camera 1\nproperty float f\nelement face 2\n"
                          "property list uchar int vertex_indices\nelement vertex 2\nproperty int8 x\n"
                          "property uint32 y\nproperty float64 z\nend_header\n"
                          "500\n3 0 1 2\n4 0 1 2 3\n-1 2 3.5\n4 5 nan\n");
  CloudReadStats stats;
  const PointCloud cloud = read_ply(path, &stats);
  ASSERT_EQ(cloud.size(), 1U);
  EXPECT_EQ(cloud[0], Point3f(-1, 2, 3.5F));
  EXPECT_EQ(stats.non_finite_dropped, 1U);
}

TEST_F(PlyTest, ReadsAsciiLineByLine) {
  // Issue 14: tokens were read across lines, so a vertex missing its z took the next line's x and
  // shifted every later vertex by one value.
  const std::string head = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                           "property float z\nend_header\n";
  const auto error = [&](const std::string& body) { return input_error_of([&] { (void)read_ply(write("l.ply", head + body)); }); };
  EXPECT_TRUE(contains(error("1 2 3\n4 5\n6 7 8\n9 9 9\n"),
                       "l.ply: line 9: too few values for element 'vertex' record 1 (3 properties, a record per line)"));
  EXPECT_TRUE(contains(error("1 2 3 4\n5 6 7\n8 9 9\n"), "l.ply: line 8: more values than element 'vertex' record 0"));
  // Blank lines between records and trailing spaces or CR are fine.
  const PointCloud cloud = read_ply(write("ok.ply", head + "1 2 3 \r\n\n4 5 6\n7 8 9"));
  ASSERT_EQ(cloud.size(), 3U);
  EXPECT_EQ(cloud[2], Point3f(7, 8, 9));
}

TEST_F(PlyTest, RejectsMalformedHeaders) {
  const auto error = [&](const std::string& text) {
    return input_error_of([&] { (void)read_ply(write("h.ply", text)); });
  };
  EXPECT_TRUE(contains(error(""), "line 1: not a PLY file"));
  EXPECT_TRUE(contains(error("VERSION 0.7\n"), "line 1: not a PLY file"));
  EXPECT_TRUE(
      contains(error("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"), "no end_header"));
  EXPECT_TRUE(contains(error("ply\nformat ascii 1.0\nelement vertex 1\nproperty quad x\nend_header\n"),
                       "line 4: unknown property type 'quad'"));
  EXPECT_TRUE(contains(error("ply\nformat ascii 1.0\nelement face 1\nproperty float x\nend_header\n1\n"),
                       "no 'element vertex'"));
  EXPECT_TRUE(contains(
      error("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n1 2\n"),
      "element vertex has no property 'z'"));
  EXPECT_TRUE(contains(error("ply\nformat binary_middle_endian 1.0\nend_header\n"), "line 2: format"));
  EXPECT_TRUE(contains(error("ply\nformat ascii 1.0\nelement vertex many\nend_header\n"),
                       "line 3: expected 'element"));
  EXPECT_TRUE(
      contains(error("ply\nformat ascii 1.0\nelement face 1\nproperty list float int v\nend_header\n"),
               "line 4: list count type 'float' is not an integer type"));
}

TEST_F(PlyTest, RejectsHugeVertexClaimsQuickly) {
  const auto start = std::chrono::steady_clock::now();
  const std::string head =
      "element vertex 1000000000000\nproperty float x\nproperty float y\nproperty float z\nend_header\n";
  EXPECT_TRUE(contains(input_error_of([&] {
                         (void)read_ply(write("b.ply", "ply\nformat binary_little_endian 1.0\n" + head +
                                                           std::string(24, '\0')));
                       }),
                       "claims 1000000000000 records of at least 12 bytes, but only 24 bytes are left"));
  EXPECT_TRUE(contains(
      input_error_of([&] { (void)read_ply(write("a.ply", "ply\nformat ascii 1.0\n" + head + "1 2 3\n")); }),
      "element vertex claims 1000000000000 records"));
  // A skipped element with lists claiming many records runs out of bytes, fast.
  EXPECT_TRUE(contains(input_error_of([&] {
                         (void)read_ply(
                             write("f.ply",
                                   "ply\nformat binary_little_endian 1.0\nelement face 1000000000000\n"
                                   "property list uchar int v\n" +
                                       head + std::string(100, '\x01')));
                       }),
                       "byte 180: element 'face' claims 1000000000000 records of at least 1 bytes"));
  // ...and so does one whose records fit the bound but whose lists do not.
  EXPECT_TRUE(contains(input_error_of([&] {
                         (void)read_ply(write("g.ply",
                                              "ply\nformat binary_little_endian 1.0\nelement face 50\n"
                                              "property list uchar int v\n" +
                                                  head + std::string(100, '\x01')));
                       }),
                       "file ends inside element 'face' record 20 of 50"));
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(1));
}

TEST_F(PlyTest, RejectsTruncatedData) {
  std::string text = binary_ply(std::endian::little, true);
  const std::size_t header_bytes = text.find("end_header\n") + 11;
  // Cut inside the faces: the list of the first face needs 12 bytes after its count.
  const std::string cut_faces = text.substr(0, header_bytes + 5);
  EXPECT_TRUE(contains(
      input_error_of([&] { (void)read_ply(write("t.ply", cut_faces)); }),
      "byte " + std::to_string(header_bytes + 1) + ": file ends inside element 'face' record 0 of 2"));
  // Cut inside the second vertex.
  EXPECT_TRUE(
      contains(input_error_of([&] { (void)read_ply(write("t.ply", text.substr(0, text.size() - 3))); }),
               "file ends inside element 'vertex' record 1 of 2"));
  // ascii: one value short.
  EXPECT_TRUE(contains(input_error_of([&] {
                         (void)read_ply(
                             write("a.ply",
                                   "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\n"
                                   "property float y\nproperty float z\nend_header\n1.0 2.0 3.0\n4.0 5.0\n"));
                       }),
                       "line 9: file ends inside element 'vertex' record 1 of 2"));
}

TEST_F(PlyTest, RejectsNonNumbers) {
  EXPECT_TRUE(contains(input_error_of([&] {
                         (void)read_ply(
                             write("a.ply",
                                   "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\n"
                                   "property float y\nproperty float z\nend_header\n1 2 3\n4 five 6\n"));
                       }),
                       "a.ply: line 9: 'five' is not a number"));
  EXPECT_TRUE(contains(input_error_of([&] {
                         (void)read_ply(
                             write("a.ply",
                                   "ply\nformat ascii 1.0\nelement face 1\nproperty list uchar int v\n"
                                   "element vertex 1\nproperty float x\nproperty float y\n"
                                   "property float z\nend_header\n-3 1 2 3\n1 2 3\n"));
                       }),
                       "line 10: list length '-3' is not a non-negative integer"));
}

TEST_F(PlyTest, RejectsMissingFile) {
  EXPECT_TRUE(contains(input_error_of([&] { (void)read_ply(dir_ / "none.ply"); }),
                       "none.ply: cannot open: No such file"));
}

}  // namespace
}  // namespace hmap
