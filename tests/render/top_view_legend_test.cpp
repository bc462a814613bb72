// Every top view a command writes (render, slam's trajectory.png, the demo's map_top.png) draws its
// paths in a colour that stands out from what is under them, and names each colour in a legend
// beside a scale bar (issue 17: "pictures of the occupancy layer show the trajectory in a colour
// that stands out, with a legend and a scale bar").

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstdlib>
#include <limits>

#include "hmap/core/error.hpp"
#include "hmap/render/render.hpp"
#include "hmap/render/text.hpp"

namespace hmap::render {
namespace top_view_legend_test {

std::array<std::uint8_t, 3> pixel(const RgbImage& img, int x, int y) {
  const std::size_t k = (static_cast<std::size_t>(y) * static_cast<std::size_t>(img.width) + static_cast<std::size_t>(x)) * 3;
  return {img.rgb[k], img.rgb[k + 1], img.rgb[k + 2]};
}

int black_in_row(const RgbImage& img, int y, int x0, int x1) {
  int n = 0;
  for (int x = x0; x < x1; ++x) n += pixel(img, x, y) == std::array<std::uint8_t, 3>{0, 0, 0} ? 1 : 0;
  return n;
}

/// The largest difference in one channel: how far a path colour stands from a background.
int contrast(const std::array<std::uint8_t, 3>& a, const std::array<std::uint8_t, 3>& b) {
  int d = 0;
  for (int c = 0; c < 3; ++c) d = std::max(d, std::abs(static_cast<int>(a[static_cast<std::size_t>(c)]) - b[static_cast<std::size_t>(c)]));
  return d;
}

PoseList straight_path(double x0, double x1, double y) {
  PoseList poses;
  for (double x = x0; x <= x1 + 1e-9; x += 1.0) {
    Pose T = Pose::Identity();
    T.translation() = Eigen::Vector3d(x, y, 0.0);
    poses.push_back(T);
  }
  return poses;
}

TEST(TopViewLegend, OccupancyPathStandsOutAndIsNamedBesideAScaleBar) {
  // 50 m x 40 m at 0.1 m per pixel, all unknown (map_server's grey), a path along y = 20 m.
  const TopViewport vp = viewport_over(0.0, 0.0, 50.0, 40.0, 0.1, 1000);
  ASSERT_EQ(vp.width, 500);
  ASSERT_EQ(vp.height, 400);
  RgbImage img(vp.width, vp.height, 205);
  const PoseList path = straight_path(10.0, 40.0, 20.0);
  const auto c = path_colour(0, /*on_occupancy=*/true);
  // The occupancy layer is white (free), black (occupied) and grey (unknown): the path is none of them.
  for (const std::array<std::uint8_t, 3> background : {std::array<std::uint8_t, 3>{255, 255, 255},
                                                       std::array<std::uint8_t, 3>{0, 0, 0},
                                                       std::array<std::uint8_t, 3>{205, 205, 205}}) {
    EXPECT_GE(contrast(c, background), 150);
  }
  const std::vector<LegendEntry> layer{{255, 255, 255, "free"}, {0, 0, 0, "occupied"}, {205, 205, 205, "unknown"}};
  const LegendPanel panel = legend_panel(vp, {layer[0], layer[1], layer[2], {c[0], c[1], c[2], "path poses.txt"}}, vp.width);
  draw_paths_and_legend(img, vp, layer, {{&path, c[0], c[1], c[2], "path poses.txt"}});
  // The legend is beside the map, not over it: the picture grew by the panel, the map kept its pixels.
  ASSERT_EQ(img.width, 500 + panel.width);
  ASSERT_EQ(img.height, 400);
  for (int x = 0; x < 500; x += 7) {
    for (int y = 0; y < 400; y += 7) {
      if (y >= 197 && y <= 203) continue;  // the path's row
      ASSERT_EQ(pixel(img, x, y), (std::array<std::uint8_t, 3>{205, 205, 205})) << x << ", " << y;
    }
  }
  for (int y = 0; y < 400; ++y) ASSERT_EQ(pixel(img, 500, y), (std::array<std::uint8_t, 3>{0, 0, 0})) << "the rule";

  // On the path (x = 25 m, y = 20 m: pixel 250, 200), in its colour.
  EXPECT_EQ(pixel(img, 250, 200), c);
  EXPECT_EQ(pixel(img, 250, 150), (std::array<std::uint8_t, 3>{205, 205, 205})) << "away from the path: untouched";

  // The legend (draw_legend_and_scale: a box at (505, 4), 5 px margin, a 10 px swatch per line):
  // the three layer colours, then the path's, in that order.
  const int line = std::max(10, measure_text("", 13).height) + 3;
  EXPECT_EQ(panel.line, line);
  const int x0 = 505;
  const std::array<std::array<std::uint8_t, 3>, 4> expected{
      {{255, 255, 255}, {0, 0, 0}, {205, 205, 205}, {c[0], c[1], c[2]}}};
  for (int k = 0; k < 4; ++k) {
    const int sy = 4 + 5 + k * line + (line - 3 - 10) / 2;
    EXPECT_EQ(pixel(img, x0 + 5 + 5, sy + 5), expected[static_cast<std::size_t>(k)]) << "legend line " << k;
    EXPECT_EQ(pixel(img, x0 + 5 - 1, sy + 5), (std::array<std::uint8_t, 3>{0, 0, 0})) << "swatch " << k << " framed";
  }
  // The fifth line does not exist: below the box's frame the panel's white.
  const int box_bottom = 4 + 2 * 5 + 4 * line;
  EXPECT_EQ(panel.legend_h, 2 * 5 + 4 * line);
  EXPECT_EQ(pixel(img, x0 + 10, box_bottom + 3), (std::array<std::uint8_t, 3>{255, 255, 255}));

  // The scale bar: 50 m wide -> 10 m, 100 px, in the row 10 px above the bottom, from x = 510.
  ASSERT_DOUBLE_EQ(scale_bar_length(50.0), 10.0);
  EXPECT_EQ(black_in_row(img, img.height - 10, 510, 610), 100);
  EXPECT_EQ(black_in_row(img, img.height - 10, 611, 613), 0);
}

TEST(TopViewLegend, HeightViewPathsAreWhiteThenRedAndTheHeightEndsAreNamed) {
  const TopViewport vp = viewport_over(0.0, 0.0, 30.0, 30.0, 0.1, 1000);
  RgbImage img(vp.width, vp.height, 0);
  const PoseList truth = straight_path(5.0, 25.0, 10.0);
  const PoseList estimate = straight_path(5.0, 25.0, 20.0);
  const auto first = path_colour(0, false);
  const auto second = path_colour(1, false);
  EXPECT_EQ(first, (std::array<std::uint8_t, 3>{255, 255, 255}));
  EXPECT_GE(contrast(first, second), 150);
  HeightRange range{-1.0, 3.0};
  const std::vector<LegendEntry> legend = height_legend(range);
  ASSERT_EQ(legend.size(), 2U);
  EXPECT_EQ(legend[0].label, "-1.00 m");
  EXPECT_EQ(legend[1].label, "3.00 m");
  std::uint8_t r = 0, g = 0, b = 0;
  height_colour(1.0, r, g, b);
  EXPECT_EQ((std::array<std::uint8_t, 3>{legend[1].r, legend[1].g, legend[1].b}), (std::array<std::uint8_t, 3>{r, g, b}));
  draw_paths_and_legend(img, vp, legend,
                        {{&truth, first[0], first[1], first[2], "truth"}, {&estimate, second[0], second[1], second[2], "estimate"}});
  EXPECT_EQ(pixel(img, 150, 200), first);   // y = 10 m
  EXPECT_EQ(pixel(img, 150, 100), second);  // y = 20 m
  const int line = std::max(10, measure_text("", 13).height) + 3;
  for (int k = 0; k < 4; ++k) {
    const std::array<std::uint8_t, 3> want = k < 2 ? std::array<std::uint8_t, 3>{legend[static_cast<std::size_t>(k)].r,
                                                                                  legend[static_cast<std::size_t>(k)].g,
                                                                                  legend[static_cast<std::size_t>(k)].b}
                                                   : (k == 2 ? first : second);
    EXPECT_EQ(pixel(img, vp.width + 15, 4 + 5 + k * line + (line - 3 - 10) / 2 + 5), want) << "legend line " << k;
  }
  // A null path is skipped, not drawn and not named: the panel holds the scale bar alone.
  RgbImage empty(vp.width, vp.height, 0);
  draw_paths_and_legend(empty, vp, {}, {{nullptr, 255, 0, 0, "nothing"}});
  ASSERT_EQ(empty.width, vp.width + legend_panel(vp, {}, vp.width).width);
  EXPECT_EQ(pixel(empty, vp.width + 15, 4 + 5 + (line - 3 - 10) / 2 + 5), (std::array<std::uint8_t, 3>{255, 255, 255}))
      << "no legend box without entries";
  // A map a few pixels wide still gets its legend: the picture grows to hold it.
  const TopViewport tiny = viewport_over(0.0, 0.0, 1.0, 0.5, 0.1, 1000);
  RgbImage small(tiny.width, tiny.height, 0);
  draw_paths_and_legend(small, tiny, legend, {});
  EXPECT_GT(small.width, 2 * tiny.width);
  EXPECT_GE(small.height, legend_panel(tiny, legend, tiny.width).legend_h + 8);
  EXPECT_EQ(pixel(small, tiny.width + 15, 4 + 5 + (line - 3 - 10) / 2 + 5),
            (std::array<std::uint8_t, 3>{legend[0].r, legend[0].g, legend[0].b}));
}

/// Whether `colour` is within one pixel of (x, y).
bool near_colour(const RgbImage& img, int x, int y, const std::array<std::uint8_t, 3>& colour) {
  for (int dy = -1; dy <= 1; ++dy) {
    for (int dx = -1; dx <= 1; ++dx) {
      if (pixel(img, x + dx, y + dy) == colour) return true;
    }
  }
  return false;
}

TEST(TopViewLegend, PathsAloneFillTheirViewportBesideALegend) {
  // Two paths 10 m long, 4 m apart: widened by a tenth of 10 m (1 m) each side, 12 m x 6 m at
  // 600 px on the longer side, 0.02 m per pixel.
  const PoseList a = straight_path(0.0, 10.0, 0.0);
  const PoseList b = straight_path(0.0, 10.0, 4.0);
  const TopPicture picture = render_paths({{&a, "first"}, {&b, "second"}}, 600);
  ASSERT_EQ(picture.viewport.width, 600);
  ASSERT_EQ(picture.viewport.height, 300);
  EXPECT_NEAR(picture.viewport.m_per_px, 0.02, 1e-12);
  EXPECT_GT(picture.image.width, 600);  // the legend and scale panel, to the right of the paths
  // Path k in path_colour(k), where its poses fall; black where no path runs.
  EXPECT_TRUE(near_colour(picture.image, 300, 250, path_colour(0, false)));  // (5, 0)
  EXPECT_TRUE(near_colour(picture.image, 300, 50, path_colour(1, false)));   // (5, 4)
  EXPECT_EQ(pixel(picture.image, 300, 150), (std::array<std::uint8_t, 3>{0, 0, 0}));
  // Nothing to draw, a pose that is not finite, an absurd size: one clear error each.
  EXPECT_THROW((void)render_paths({}, 600), Error);
  EXPECT_THROW((void)render_paths({{nullptr, "none"}}, 600), Error);
  PoseList bad = a;
  bad[3].translation().y() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW((void)render_paths({{&bad, "bad"}}, 600), Error);
  EXPECT_THROW((void)render_paths({{&a, "first"}}, 0), Error);
  // One pose: a square of 2 m around it, still drawn.
  const PoseList one(1, Pose::Identity());
  const TopPicture dot = render_paths({{&one, "still"}}, 100);
  EXPECT_EQ(dot.viewport.width, 100);
  EXPECT_TRUE(near_colour(dot.image, 50, 50, path_colour(0, false)));
}

}  // namespace top_view_legend_test
}  // namespace hmap::render
