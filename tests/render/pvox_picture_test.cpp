// The PVOX pictures carry a scale bar (issue 15: "pictures have no legend or scale bar"): drawn
// where draw_legend_and_scale puts it (a panel to the right of the map), as long as the length it names.

#include <gtest/gtest.h>

#include "hmap/pvox/voxel_map.hpp"
#include "hmap/render/pvox_render.hpp"
#include "hmap/render/render.hpp"

namespace hmap::render {
namespace {

/// Black pixels of row `y` of `img` in [x0, x1).
int black_in_row(const RgbImage& img, int y, int x0, int x1) {
  int n = 0;
  for (int x = x0; x < x1; ++x) {
    const std::size_t k = (static_cast<std::size_t>(y) * static_cast<std::size_t>(img.width) + static_cast<std::size_t>(x)) * 3;
    n += img.rgb[k] == 0 && img.rgb[k + 1] == 0 && img.rgb[k + 2] == 0 ? 1 : 0;
  }
  return n;
}

TEST(PvoxPicture, TopViewHasAScaleBarOfTheLengthItNames) {
  // A floor of 10 m x 10 m of 0.1 m voxels, each hit 5 times: occupied.
  pvox::VoxelMap map(0.1);
  for (int i = 0; i < 100; ++i) {
    for (int j = 0; j < 100; ++j) {
      for (int n = 0; n < 5; ++n) map.add_hit(Eigen::Vector3d(i * 0.1 + 0.05, j * 0.1 + 0.05, 0.05));
    }
  }
  PvoxView view;
  view.max_pixels = 500;  // 10 m on 500 px: 0.02 m per pixel
  const RgbImage top = render_pvox_top(map, view);
  // The map is 500 px square; the scale bar's panel is to its right (draw_legend_and_scale).
  const LegendPanel panel = legend_panel(TopViewport{0.0, 0.0, 0.02, 500, 500}, {}, 500);
  ASSERT_GT(panel.width, 0);
  ASSERT_EQ(top.width, 500 + panel.width);
  ASSERT_EQ(top.height, 500);
  // 10 m wide: the bar is 2 m (the largest 1, 2, 5 x 10^k within a fifth), 100 px, from x = 500 + 10,
  // in rows height - 12 .. height - 9 (4 px margin, 5 px inside the box).
  ASSERT_DOUBLE_EQ(scale_bar_length(10.0), 2.0);
  EXPECT_EQ(panel.bar_px, 100);
  const int row = top.height - 10;
  EXPECT_EQ(black_in_row(top, row, 510, 610), 100);
  EXPECT_EQ(black_in_row(top, row, 611, 613), 0) << "the box is white beside the bar";
  // The map's own pixels are not covered: no bar across the floor's bottom rows.
  EXPECT_LT(black_in_row(top, row, 9, 109), 10);
  // The gradient view of the same map: the same bar.
  const RgbImage field = render_pvox_gradient(map, view, 0.05);
  ASSERT_EQ(field.width, 500 + panel.width);
  EXPECT_EQ(black_in_row(field, field.height - 10, 510, 610), 100);
}

}  // namespace
}  // namespace hmap::render
