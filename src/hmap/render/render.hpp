#pragma once
// Pictures of maps for people: top-down and oblique views, trajectories drawn over them.

#include <array>
#include <cmath>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "hmap/ground/ground_patches.hpp"
#include "hmap/io/png.hpp"
#include "hmap/maps/hmap.hpp"
#include "hmap/occupancy/grid_reading.hpp"

namespace hmap::render {

/// Height colouring: z_low is blue, z_high red; NaN means "from the map" (2nd/98th percentile of
/// the column tops).
struct HeightRange {
  double z_low = NAN;
  double z_high = NAN;
};

/// How world x, y map to pixels of a top-down picture (north up, x to the right).
struct TopViewport {
  double x0 = 0.0;        ///< world x at the left edge [m]
  double y1 = 0.0;        ///< world y at the top edge [m]
  double m_per_px = 0.1;  ///< [m]
  int width = 0;
  int height = 0;
  [[nodiscard]] double px(double x) const { return (x - x0) / m_per_px; }
  [[nodiscard]] double py(double y) const { return (y1 - y) / m_per_px; }
};

/// The resolved height range (percentiles of the tops where not given).
[[nodiscard]] HeightRange resolve_range(const HMap& map, HeightRange range);

/// The largest side a picture may be asked for [px]: a picture's `max_pixels` must lie in
/// [1, kMaxPixels]; check_max_pixels throws hmap::Error saying so otherwise.
inline constexpr int kMaxPixels = 20000;
void check_max_pixels(int max_pixels);

/// Top-down: each pixel coloured by the highest HVoxel top below it; columns with several
/// HVoxels (overhangs) drawn lighter; unknown black. `margin_m` widens the picture (for paths).
[[nodiscard]] RgbImage render_top(const HMap& map, const HeightRange& range, int max_pixels,
                                  TopViewport& viewport, double margin_m = 0.0);

/// Oblique: the HVoxels as vertical bars seen from the south-west, 35° above the horizon,
/// height-coloured and shaded by depth, with a z-buffer.
[[nodiscard]] RgbImage render_oblique(const HMap& map, const HeightRange& range, int max_pixels);

/// Draws the x, y path of `poses` over a top view: a 2-pixel line, a dot at the start.
void draw_path(RgbImage& image, const TopViewport& viewport, const PoseList& poses, std::uint8_t r,
               std::uint8_t g, std::uint8_t b);

/// Blue → cyan → green → yellow → red for t in [0, 1].
void height_colour(double t, std::uint8_t& r, std::uint8_t& g, std::uint8_t& b);

}  // namespace hmap::render

namespace hmap {
class OccupancyGrid;
}  // namespace hmap

namespace hmap::render {

/// The viewport over [x0, x1] × [y0, y1] [m]: one pixel per `cell`, or coarser so that neither
/// side exceeds `max_pixels`. Pictures drawn in one viewport line up pixel for pixel.
[[nodiscard]] TopViewport viewport_over(double x0, double y0, double x1, double y1, double cell, int max_pixels);

/// Top-down as render_top, in a given viewport.
[[nodiscard]] RgbImage render_top_in(const HMap& map, const HeightRange& range, const TopViewport& viewport);

/// The 2D occupancy grid as `export --pgm` writes it for map_server: occupied black, free white,
/// undecided and never-observed cells grey (205), decided by `reading` (GridReading::for_map).
[[nodiscard]] RgbImage render_occupancy(const OccupancyGrid& grid, const TopViewport& viewport,
                                        const GridReading& reading);

/// Points seen from above, coloured by the highest point per pixel (the raw cloud panel).
[[nodiscard]] RgbImage render_points_top(const PointCloud& points_map, const HeightRange& range,
                                         const TopViewport& viewport);

/// Alg. 4's tree over a top view: each patch's square outlined, each edge to its parent drawn.
void draw_ground_patches(RgbImage& image, const TopViewport& viewport, std::span<const GroundPatch> patches,
                         std::uint8_t r, std::uint8_t g, std::uint8_t b);


/// One entry of a legend: a colour swatch and its label.
struct LegendEntry {
  std::uint8_t r, g, b;
  std::string label;
};

/// Where draw_legend_and_scale puts things, for a map `map_width` pixels wide: a panel `width`
/// pixels wide to the right of the map (a 1 px black rule at x = map_width, the boxes from x =
/// map_width + 5); the legend box at the top (y = 4, `legend_w` × `legend_h`, a line of `line` px
/// per entry, its swatch kSwatch px square kMargin px in); the scale bar's box at the bottom.
struct LegendPanel {
  static constexpr int kMargin = 5;
  static constexpr int kSwatch = 10;
  int line = 0, legend_w = 0, legend_h = 0;
  double bar_m = 0.0;  ///< the scale bar's length [m] (scale_bar_length of the map's width)
  int bar_px = 0;      ///< 0: too short to draw (under 10 px)
  std::string label;
  int box_w = 0, box_h = 0;
  int width = 0;  ///< the panel's width; 0 when there is nothing to draw
};
[[nodiscard]] LegendPanel legend_panel(const TopViewport& viewport, const std::vector<LegendEntry>& legend, int map_width);

/// Widens `image` by a white panel to its right holding a legend box (swatches and labels) at the
/// top and a scale bar (a round length of about a fifth of the map's width: 1, 2 or 5 × 10^k m,
/// labelled) at the bottom, so that neither hides any of the map; the image grows taller too when
/// the map is shorter than the panel needs. The map's pixels keep their place (`viewport` still
/// applies to them).
void draw_legend_and_scale(RgbImage& image, const TopViewport& viewport, const std::vector<LegendEntry>& legend);

/// A path to draw over a top view, in its colour, with its legend label.
struct PathLayer {
  const PoseList* poses = nullptr;
  std::uint8_t r = 255, g = 255, b = 255;
  std::string label;
};

/// The colour of the k-th path of a top view: white on the height view (the truth, by convention),
/// blue (0, 90, 255) on the occupancy layer, where white is free space and black occupied; then red,
/// magenta, orange, cyan and green on both (green again for any further path).
[[nodiscard]] std::array<std::uint8_t, 3> path_colour(std::size_t k, bool on_occupancy);

/// The height colouring's two ends as legend entries ("z_low m" blue, "z_high m" red).
[[nodiscard]] std::vector<LegendEntry> height_legend(const HeightRange& range);

/// Draws each path (draw_path), adds it to `legend` and draws the legend and the scale bar
/// (draw_legend_and_scale): every top view a command writes goes through here.
void draw_paths_and_legend(RgbImage& image, const TopViewport& viewport, std::vector<LegendEntry> legend,
                           const std::vector<PathLayer>& paths);

/// The scale bar's length [m] for a picture `width_m` wide: the largest 1, 2 or 5 × 10^k at most a fifth of it.
[[nodiscard]] double scale_bar_length(double width_m);

/// Panels side by side on white, each with its title above it, fitted to the panel's width at one
/// size for all (text.hpp: smaller, then wrapped).
[[nodiscard]] RgbImage side_by_side(const std::vector<std::pair<std::string, RgbImage>>& panels);


/// What a top view shows under its paths: the HVoxel tops (render_top), the 2D grid as map_server
/// draws it (render_occupancy), or the tops with Alg. 4's patches outlined white.
enum class TopLayer { kHeight, kOccupancy, kGround };

/// A path for render_top_view, named in the legend by `label`.
struct LabelledPath {
  const PoseList* poses = nullptr;
  std::string label;
};

/// A top view and where its map lies: `viewport` applies to the pixels x < viewport.width (a
/// legend panel, when drawn, lies to their right; the picture may be taller than the map).
struct TopPicture {
  RgbImage image;
  TopViewport viewport;
};

/// The top view `hmap render` draws (and `hmap slam`, `hmap demo`): the map's bounds, widened by
/// 2 m on each side when there are paths, at one pixel per cell or coarser so that neither side of
/// the map exceeds `max_pixels`; `layer` under the paths, path k drawn in path_colour(k) with a dot
/// at its start; with `legend`, the legend (the height range's ends, or free / occupied / unknown on
/// the grid, then each path's label) and the scale bar in a panel to the right
/// (draw_paths_and_legend). `grid` is read with GridReading::for_map(map.params().occupancy).
/// Throws hmap::Error for an empty map, max_pixels out of range, kOccupancy without a grid holding
/// a known cell, or kGround without patches.
[[nodiscard]] TopPicture render_top_view(const HMap& map, TopLayer layer, const HeightRange& range, int max_pixels,
                                         const OccupancyGrid* grid, std::span<const GroundPatch> ground,
                                         const std::vector<LabelledPath>& paths, bool legend);

/// Paths alone, seen from above on black (x to the right, y up), each drawn from its poses as
/// given, path k in path_colour(k) with a dot at its start: the viewport over all of them widened
/// by a tenth of the larger extent (at least 1 m) on each side, at most `max_pixels` on its longer
/// side, with the legend (each label) and the scale bar in a panel to the right. For trajectories
/// without a map (`hmap eval traj --plot`). Throws hmap::Error when no path holds a pose, a pose
/// is not finite, or max_pixels is out of range.
[[nodiscard]] TopPicture render_paths(const std::vector<LabelledPath>& paths, int max_pixels);

}  // namespace hmap::render
