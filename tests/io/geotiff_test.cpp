#include "hmap/io/geotiff.hpp"

#include <gdal.h>
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <sstream>

#include "common/test_data.hpp"
#include "hmap/core/error.hpp"
#include "hmap/io/pgm_export.hpp"

namespace hmap {
namespace {

/// 3 x 2 cells of 0.5 m from key (-2, 4): heights by hand, one cell without ground.
TraversabilityLayers layers() {
  TraversabilityLayers l;
  l.i_min = -2;
  l.j_min = 4;
  l.width = 3;
  l.height = 2;
  l.cell_size = 0.5;
  // row 0 (south), then row 1 (north)
  l.ground_z = {0.1F, 0.2F, 0.3F, 1.0F, std::nanf(""), 1.5F};
  l.slope_deg.assign(6, 0.0F);
  l.step.assign(6, 0.0F);
  l.cost = {0, 50, 100, 1, TraversabilityLayers::kUnknown, 99};
  return l;
}

// GDAL reads back the heights, north up, with the geotransform of the map frame and NaN no-data.
TEST(GeotiffTest, GdalReadsBackTheGroundHeight) {
  const auto dir = test::temp_dir("geotiff");
  write_ground_geotiff(dir / "g.tif", layers());
  GDALAllRegister();
  GDALDatasetH ds = GDALOpen((dir / "g.tif").c_str(), GA_ReadOnly);
  ASSERT_NE(ds, nullptr);
  EXPECT_EQ(GDALGetRasterXSize(ds), 3);
  EXPECT_EQ(GDALGetRasterYSize(ds), 2);
  double t[6];
  ASSERT_EQ(GDALGetGeoTransform(ds, t), CE_None);
  EXPECT_DOUBLE_EQ(t[0], -1.0);  // i_min * cell
  EXPECT_DOUBLE_EQ(t[1], 0.5);
  EXPECT_DOUBLE_EQ(t[3], 3.0);   // (j_min + height) * cell: the north edge
  EXPECT_DOUBLE_EQ(t[5], -0.5);
  GDALRasterBandH band = GDALGetRasterBand(ds, 1);
  float px[6];
  ASSERT_EQ(GDALRasterIO(band, GF_Read, 0, 0, 3, 2, px, 3, 2, GDT_Float32, 0, 0), CE_None);
  EXPECT_FLOAT_EQ(px[0], 1.0F);  // raster row 0 is the north row
  EXPECT_TRUE(std::isnan(px[1]));
  EXPECT_FLOAT_EQ(px[2], 1.5F);
  EXPECT_FLOAT_EQ(px[3], 0.1F);
  EXPECT_FLOAT_EQ(px[5], 0.3F);
  int has_nodata = 0;
  EXPECT_TRUE(std::isnan(GDALGetRasterNoDataValue(band, &has_nodata)));
  EXPECT_TRUE(has_nodata);
  GDALClose(ds);
  TraversabilityLayers empty;
  EXPECT_THROW(write_ground_geotiff(dir / "e.tif", empty), Error);
  EXPECT_FALSE(std::filesystem::exists(dir / "e.tif"));
}

// The costmap PGM by hand: pixel 255 - round(2.55 c), unknown lethal, north row first; map_server's
// scale mode (occupied 0.995, free 0.005) gives each cost back within one unit.
TEST(CostmapPgmTest, PixelsAndScaleModeRoundTrip) {
  const auto dir = test::temp_dir("costmap");
  write_costmap_pgm(dir / "c", layers());
  std::ifstream in(dir / "c.pgm", std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), {});
  const std::string pixels = bytes.substr(bytes.size() - 6);
  // north: 1, unknown, 99; south: 0, 50, 100 (2.55 * 50 is 127.4999... in binary: 127)
  const unsigned char expected[6] = {255 - 3, 0, 255 - 252, 255, 255 - 127, 0};
  const int costs[6] = {1, 100, 99, 0, 50, 100};
  for (int k = 0; k < 6; ++k) {
    const auto v = static_cast<unsigned char>(pixels[static_cast<std::size_t>(k)]);
    EXPECT_EQ(v, expected[k]) << k;
    // nav2_map_server, mode scale, negate 0.
    const double occ = (255.0 - v) / 255.0;
    const double value = occ > 0.995 ? 100 : occ < 0.005 ? 0 : 1 + 98 * (occ - 0.005) / (0.995 - 0.005);
    EXPECT_NEAR(value, costs[k], 1.0) << k;
  }
  std::ifstream y(dir / "c.yaml");
  const std::string yaml((std::istreambuf_iterator<char>(y)), {});
  EXPECT_NE(yaml.find("mode: scale"), std::string::npos);
  EXPECT_NE(yaml.find("origin: [-1, 2, 0.0]"), std::string::npos) << yaml;
  EXPECT_NE(yaml.find("resolution: 0.5"), std::string::npos);
}

}  // namespace
}  // namespace hmap
