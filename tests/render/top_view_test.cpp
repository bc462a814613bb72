// The top view (src/hmap/render/render.hpp) of a map built here, every pixel worked out by hand:
// where a column lands, its colour from its top, unknown black, paths and the legend's panel, and
// the arguments it refuses.

#include <gtest/gtest.h>

#include <array>

#include "hmap/core/error.hpp"
#include "hmap/occupancy/occupancy_grid.hpp"
#include "hmap/render/render.hpp"

namespace hmap::render {
namespace top_view_test {

std::array<std::uint8_t, 3> pixel(const RgbImage& img, int x, int y) {
  const std::size_t k = (static_cast<std::size_t>(y) * static_cast<std::size_t>(img.width) + static_cast<std::size_t>(x)) * 3;
  return {img.rgb[k], img.rgb[k + 1], img.rgb[k + 2]};
}

/// Cell size 0.5 m. Cell (0, 0): one HVoxel [0, 1]; cell (2, 0): a floor [0, 0.5] under a shelf
/// [1.5, 2]. The map spans x in [0, 1.5], y in [0, 0.5]: three pixels by one at 0.5 m per pixel.
HMap two_columns() {
  Params p;
  p.map.cell_size = 0.5;
  HMap map(p);
  map.column_for_update({0, 0}).push_back({0.0F, 1.0F, 10.0F, 1.0F});
  auto c = map.column_for_update({2, 0});
  c.push_back({0.0F, 0.5F, 10.0F, 1.0F});
  c.push_back({1.5F, 2.0F, 10.0F, 1.0F});
  return map;
}

TEST(TopView, EachColumnIsOnePixelColouredByItsTopUnknownBlack) {
  const HMap map = two_columns();
  const TopPicture pic = render_top_view(map, TopLayer::kHeight, {0.0, 2.0}, 2000, nullptr, {}, {}, false);
  EXPECT_DOUBLE_EQ(pic.viewport.m_per_px, 0.5);
  EXPECT_DOUBLE_EQ(pic.viewport.x0, 0.0);
  EXPECT_DOUBLE_EQ(pic.viewport.y1, 0.5);
  ASSERT_EQ(pic.image.width, 3);
  ASSERT_EQ(pic.image.height, 1);
  // Top 1.0 of [0, 2]: t = 0.5, green with half red and half blue (127.5 rounds up).
  EXPECT_EQ(pixel(pic.image, 0, 0), (std::array<std::uint8_t, 3>{128, 255, 128}));
  EXPECT_EQ(pixel(pic.image, 1, 0), (std::array<std::uint8_t, 3>{0, 0, 0}));  // no column: unknown
  // Top 2.0: t = 1, (128, 0, 0); two HVoxels, so halfway to white: (383 / 2, 255 / 2, 255 / 2).
  EXPECT_EQ(pixel(pic.image, 2, 0), (std::array<std::uint8_t, 3>{191, 127, 127}));
}

TEST(TopView, PathsWidenTheViewBy2mAndTheLegendLiesRightOfTheMap) {
  const HMap map = two_columns();
  PoseList path(2, Pose::Identity());
  path[0].translation() = Eigen::Vector3d(0.25, 0.25, 0.0);
  path[1].translation() = Eigen::Vector3d(1.25, 0.25, 0.0);
  const TopPicture bare = render_top_view(map, TopLayer::kHeight, {0.0, 2.0}, 2000, nullptr, {}, {{&path, "p"}}, false);
  // [-2, 3.5] x [-2, 2.5] at 0.5 m: 11 x 9 pixels; the path's start (0.25, 0.25) at pixel (4, 4).
  EXPECT_DOUBLE_EQ(bare.viewport.x0, -2.0);
  EXPECT_DOUBLE_EQ(bare.viewport.y1, 2.5);
  ASSERT_EQ(bare.image.width, 11);
  ASSERT_EQ(bare.image.height, 9);
  for (int x = 4; x <= 6; ++x) EXPECT_EQ(pixel(bare.image, x, 4), (std::array<std::uint8_t, 3>{255, 255, 255})) << x;
  EXPECT_EQ(pixel(bare.image, 0, 0), (std::array<std::uint8_t, 3>{0, 0, 0}));

  const TopPicture legend = render_top_view(map, TopLayer::kHeight, {0.0, 2.0}, 2000, nullptr, {}, {{&path, "p"}}, true);
  EXPECT_EQ(legend.viewport.width, bare.viewport.width);
  EXPECT_GT(legend.image.width, bare.image.width);  // the panel
  for (int y = 0; y < bare.image.height; ++y) {
    for (int x = 0; x < bare.image.width; ++x) EXPECT_EQ(pixel(legend.image, x, y), pixel(bare.image, x, y));
  }
}

TEST(TopView, RefusesWhatItCannotDraw) {
  const HMap map = two_columns();
  EXPECT_THROW((void)render_top_view(map, TopLayer::kHeight, {}, 0, nullptr, {}, {}, false), Error);
  EXPECT_THROW((void)render_top_view(map, TopLayer::kHeight, {}, kMaxPixels + 1, nullptr, {}, {}, false), Error);
  EXPECT_THROW((void)render_oblique(map, {}, -5), Error);
  EXPECT_THROW((void)render_top_view(map, TopLayer::kOccupancy, {}, 100, nullptr, {}, {}, false), Error);
  const OccupancyGrid empty_grid(0.5, 0.12, 0.97);
  EXPECT_THROW((void)render_top_view(map, TopLayer::kOccupancy, {}, 100, &empty_grid, {}, {}, false), Error);
  EXPECT_THROW((void)render_top_view(map, TopLayer::kGround, {}, 100, nullptr, {}, {}, false), Error);
  EXPECT_THROW((void)render_top_view(HMap(Params{}), TopLayer::kHeight, {}, 100, nullptr, {}, {}, false), Error);
}

TEST(TopView, OccupancyLayerIsTheGridAsMapServerDrawsIt) {
  const HMap map = two_columns();
  OccupancyGrid grid(0.5, 0.12, 0.97);
  grid.set({0, 0}, log_odds(0.97));  // occupied: black
  grid.set({1, 0}, log_odds(0.12));  // free: white
  const TopPicture pic = render_top_view(map, TopLayer::kOccupancy, {}, 2000, &grid, {}, {}, false);
  ASSERT_EQ(pic.image.width, 3);
  EXPECT_EQ(pixel(pic.image, 0, 0), (std::array<std::uint8_t, 3>{0, 0, 0}));
  EXPECT_EQ(pixel(pic.image, 1, 0), (std::array<std::uint8_t, 3>{255, 255, 255}));
  EXPECT_EQ(pixel(pic.image, 2, 0), (std::array<std::uint8_t, 3>{205, 205, 205}));  // never observed
}

}  // namespace top_view_test
}  // namespace hmap::render
