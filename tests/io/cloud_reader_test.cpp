#include "hmap/io/cloud_reader.hpp"

#include <gtest/gtest.h>

#include <string>

#include "io/io_test_util.hpp"

namespace hmap {
namespace {

using test::contains;
using test::input_error_of;
using test::put;

class CloudReaderTest : public test::IoTest {};

TEST_F(CloudReaderTest, DispatchesOnExtensionInAnyCase) {
  const std::string xyz = "1 2 3\n";
  const std::string pcd = "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\nDATA ascii\n1 2 3\n";
  const std::string ply =
      "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
      "property float z\nend_header\n1 2 3\n";
  std::string bin;
  for (const float v : {1.0F, 2.0F, 3.0F, 0.0F}) put<float>(bin, v);
  for (const auto& [name, bytes] : std::vector<std::pair<std::string, std::string>>{{"a.pcd", pcd},
                                                                                    {"b.PCD", pcd},
                                                                                    {"c.ply", ply},
                                                                                    {"d.Ply", ply},
                                                                                    {"e.bin", bin},
                                                                                    {"f.BIN", bin},
                                                                                    {"g.xyz", xyz},
                                                                                    {"h.txt", xyz},
                                                                                    {"i.CSV", xyz},
                                                                                    {"j.pts", xyz}}) {
    SCOPED_TRACE(name);
    CloudReadStats stats;
    const PointCloud cloud = read_cloud(write(name, bytes), &stats);
    ASSERT_EQ(cloud.size(), 1U);
    EXPECT_EQ(cloud[0], Point3f(1, 2, 3));
    EXPECT_EQ(stats.points_read, 1U);
  }
}

TEST_F(CloudReaderTest, RejectsUnknownExtensions) {
  EXPECT_TRUE(contains(input_error_of([&] { (void)read_cloud(write("scan.las", "x")); }),
                       "scan.las: unknown point cloud extension '.las'"));
  EXPECT_TRUE(contains(input_error_of([&] { (void)read_cloud(write("scan", "x")); }), "extension (none)"));
}

TEST_F(CloudReaderTest, ReportsMissingFilesOfKnownTypes) {
  EXPECT_TRUE(
      contains(input_error_of([&] { (void)read_cloud(dir_ / "gone.pcd"); }), "gone.pcd: cannot open"));
}

}  // namespace
}  // namespace hmap
