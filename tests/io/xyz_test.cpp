#include "hmap/io/xyz.hpp"

#include <gtest/gtest.h>

#include <string>

#include "io/io_test_util.hpp"

namespace hmap {
namespace {

using test::contains;
using test::input_error_of;

class XyzTest : public test::IoTest {};

TEST_F(XyzTest, ReadsWhitespaceSeparatedWithCommentsAndBlankLines) {
  const auto path =
      write("p.xyz", "# scanner output\n\n1 2 3\n\t-4.5\t5e-1   +6 255 0 0\r\n   \n# 7 8 9\n1e3 0 -0\n");
  CloudReadStats stats;
  const PointCloud cloud = read_xyz(path, &stats);
  ASSERT_EQ(cloud.size(), 3U);
  EXPECT_EQ(cloud[0], Point3f(1, 2, 3));
  EXPECT_EQ(cloud[1], Point3f(-4.5F, 0.5F, 6));
  EXPECT_EQ(cloud[2], Point3f(1000, 0, 0));
  EXPECT_EQ(stats.points_read, 3U);
}

TEST_F(XyzTest, ReadsCommasAndSemicolonsWithSpacesAround) {
  const PointCloud cloud = read_xyz(write("p.csv", "1,2,3\n4 , 5 , 6,\n7;8;9;label\n"));
  ASSERT_EQ(cloud.size(), 3U);
  EXPECT_EQ(cloud[1], Point3f(4, 5, 6));
  EXPECT_EQ(cloud[2], Point3f(7, 8, 9));
}

TEST_F(XyzTest, UsesColumnsNamedInTheHeader) {
  const PointCloud cloud = read_xyz(write("p.csv", "id,\"Z\",intensity,x,Y\n0,3,0.5,1,2\n1,6,0.5,4,5\n"));
  ASSERT_EQ(cloud.size(), 2U);
  EXPECT_EQ(cloud[0], Point3f(1, 2, 3));
  EXPECT_EQ(cloud[1], Point3f(4, 5, 6));

  const PointCloud compare = read_xyz(write("cc.txt", "//X Y Z R G B\n1 2 3 0 0 0\n"));
  ASSERT_EQ(compare.size(), 1U);
  EXPECT_EQ(compare[0], Point3f(1, 2, 3));
}

TEST_F(XyzTest, ReadsAPtsCountAndRefusesAHeaderWithoutNames) {
  const PointCloud pts = read_xyz(write("p.pts", "2\n1 2 3 -1200 10 20 30\n4 5 6 -1100 10 20 30\n"));
  ASSERT_EQ(pts.size(), 2U);
  EXPECT_EQ(pts[1], Point3f(4, 5, 6));
  EXPECT_TRUE(contains(input_error_of([&] { (void)read_xyz(write("p.pts", "3\n1 2 3\n4 5 6\n")); }),
                       "p.pts: line 1: the point count 3 does not match the 2 points that follow"));
  // Issue 14: the columns are not guessed as 0-2 when the header does not name x, y and z.
  EXPECT_TRUE(contains(input_error_of([&] { (void)read_xyz(write("p.txt", "easting northing height\n1 2 3\n")); }),
                       "p.txt: line 1: a header must name the columns x, y and z, found 'easting northing height'"));
  // An intrinsics or a pose file is not a cloud: its words are not a header naming x, y, z.
  EXPECT_TRUE(contains(input_error_of([&] { (void)read_xyz(write("k.txt", "fx fy cx cy\n525 525 319.5 239.5\n")); }),
                       "k.txt: line 1: a header must name the columns x, y and z"));
}

TEST_F(XyzTest, StrictLinesBomAndDecimalCommas) {
  // A line of two numbers was taken for a header and skipped: "1 2" then "3 4 5 6" mapped (3, 4, 5).
  EXPECT_TRUE(contains(input_error_of([&] { (void)read_xyz(write("two.xyz", "1 2\n3 4 5 6\n")); }),
                       "two.xyz: line 1: expected at least 3 values, found 2"));
  // A UTF-8 byte order mark before the header no longer hides the x column.
  const PointCloud bom = read_xyz(write("bom.csv", "\xEF\xBB\xBFx,y,z\n1,2,3\n"));
  ASSERT_EQ(bom.size(), 1U);
  EXPECT_EQ(bom[0], Point3f(1, 2, 3));
  const PointCloud bom_data = read_xyz(write("bom.xyz", "\xEF\xBB\xBF" "1 2 3\n"));
  ASSERT_EQ(bom_data.size(), 1U);
  // Decimal commas were read as (1, 5, 2).
  EXPECT_TRUE(contains(input_error_of([&] { (void)read_xyz(write("dc.csv", "1,5;2,5;3,5\n")); }),
                       "dc.csv: line 1: '1,5' is not a number (a decimal comma? write 1.5, not 1,5)"));
}

TEST_F(XyzTest, DropsNonFinitePoints) {
  CloudReadStats stats;
  const PointCloud cloud = read_xyz(write("p.xyz", "1 2 3\nnan 0 0\n0 inf 0\n0 0 1e39\n"), &stats);
  EXPECT_EQ(cloud.size(), 1U);
  EXPECT_EQ(stats.points_read, 4U);
  EXPECT_EQ(stats.non_finite_dropped, 3U);
}

TEST_F(XyzTest, ReadsEmptyFilesAsEmptyClouds) {
  EXPECT_TRUE(read_xyz(write("e.xyz", "")).empty());
  EXPECT_TRUE(read_xyz(write("c.xyz", "# nothing\n\n")).empty());
  EXPECT_TRUE(read_xyz(write("h.csv", "x,y,z\n")).empty());
}

TEST_F(XyzTest, RejectsMalformedLinesByLineNumber) {
  EXPECT_TRUE(contains(input_error_of([&] { (void)read_xyz(write("p.xyz", "1 2 3\n# c\n4 abc 6\n")); }),
                       "p.xyz: line 3: 'abc' is not a number"));
  EXPECT_TRUE(contains(input_error_of([&] { (void)read_xyz(write("p.xyz", "1 2 3\n4 5\n")); }),
                       "line 2: expected at least 3 values, found 2"));
  EXPECT_TRUE(contains(input_error_of([&] { (void)read_xyz(write("p.csv", "1,2,3\n4,,6\n")); }),
                       "line 2: empty value in column 2"));
  EXPECT_TRUE(contains(input_error_of([&] { (void)read_xyz(write("p.csv", "a,x,y,z\n0,1,2,3\n0,1,2\n")); }),
                       "line 3: expected at least 4 values, found 3"));
  EXPECT_TRUE(contains(input_error_of([&] { (void)read_xyz(write("p.xyz", "1 2 3\n1 2 3x\n")); }),
                       "line 2: '3x' is not a number"));
  EXPECT_TRUE(
      contains(input_error_of([&] { (void)read_xyz(dir_ / "absent.xyz"); }), "absent.xyz: cannot open"));
}

TEST(XyzRealData, ReadsEthCarCloudCsv) {
  HMAP_REQUIRE_DATA("sweeping_laser_eth");
  CloudReadStats stats;
  const PointCloud cloud = read_xyz(test::data_dir() / "sweeping_laser_eth" / "car_cloud400.csv", &stats);
  EXPECT_GT(cloud.size(), 1000U);
  EXPECT_EQ(stats.non_finite_dropped, 0U);
  EXPECT_EQ(cloud.front(), Point3f(-3.5376F, 0.639553F, -1.37678F));
}

}  // namespace
}  // namespace hmap
