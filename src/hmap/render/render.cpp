#include "hmap/render/render.hpp"

#include "hmap/core/format.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "hmap/core/checked.hpp"
#include "hmap/core/error.hpp"
#include "hmap/ground/ground_patches.hpp"
#include "hmap/occupancy/occupancy_grid.hpp"
#include "hmap/render/text.hpp"

namespace hmap::render {

void height_colour(double t, std::uint8_t& r, std::uint8_t& g, std::uint8_t& b) {
  t = std::clamp(t, 0.0, 1.0);
  const auto channel = [](double v) { return static_cast<std::uint8_t>(std::lround(255.0 * std::clamp(v, 0.0, 1.0))); };
  r = channel(1.5 - std::abs(4.0 * t - 3.0));
  g = channel(1.5 - std::abs(4.0 * t - 2.0));
  b = channel(1.5 - std::abs(4.0 * t - 1.0));
}

HeightRange resolve_range(const HMap& map, HeightRange range) {
  if (std::isnan(range.z_low) || std::isnan(range.z_high)) {
    std::vector<float> tops;
    map.for_each_column([&](const CellKey&, const ColumnView& c) { tops.push_back(c[c.size() - 1].z_max); });
    if (tops.empty()) return {0.0, 1.0};
    std::sort(tops.begin(), tops.end());
    if (std::isnan(range.z_low)) range.z_low = tops[tops.size() * 2 / 100];
    if (std::isnan(range.z_high)) range.z_high = tops[tops.size() * 98 / 100];
  }
  if (!(range.z_high > range.z_low)) range.z_high = range.z_low + 1.0;
  return range;
}

void check_max_pixels(int max_pixels) {
  if (max_pixels < 1 || max_pixels > kMaxPixels) {
    throw Error(format("max_pixels = %d is out of its range [1, %d]: the picture's largest side in pixels", max_pixels,
                       kMaxPixels));
  }
}

RgbImage render_top(const HMap& map, const HeightRange& range_in, int max_pixels, TopViewport& vp,
                    double margin_m) {
  check_max_pixels(max_pixels);
  const MapStats st = map.stats();
  if (st.hvoxels == 0) throw Error("the map is empty, nothing to draw");
  // One pixel per cell, or coarser for large maps.
  vp = viewport_over(st.bounds.min().x() - margin_m, st.bounds.min().y() - margin_m, st.bounds.max().x() + margin_m,
                     st.bounds.max().y() + margin_m, map.cell_size(), max_pixels);
  return render_top_in(map, range_in, vp);
}

RgbImage render_oblique(const HMap& map, const HeightRange& range_in, int max_pixels) {
  check_max_pixels(max_pixels);
  const MapStats st = map.stats();
  if (st.hvoxels == 0) throw Error("the map is empty, nothing to draw");
  const HeightRange range = resolve_range(map, range_in);
  // View from the south-west (azimuth 225°), 35° above the horizon: screen u along (1, -1)/√2,
  // depth along (1, 1)/√2 horizontally; screen v mixes depth and height.
  const double elev = 35.0 * M_PI / 180.0;
  const double se = std::sin(elev);
  const double ce = std::cos(elev);
  const auto project = [&](double x, double y, double z, double& u, double& v, double& depth) {
    const double a = (x - y) / std::sqrt(2.0);
    const double d = (x + y) / std::sqrt(2.0);
    u = a;
    v = -(z * ce + d * se);  // up on screen is -v
    depth = d * ce - z * se;
  };
  double umin = 1e300, umax = -1e300, vmin = 1e300, vmax = -1e300, dmin = 1e300, dmax = -1e300;
  for (int corner = 0; corner < 8; ++corner) {
    const double x = corner & 1 ? st.bounds.max().x() : st.bounds.min().x();
    const double y = corner & 2 ? st.bounds.max().y() : st.bounds.min().y();
    const double z = std::clamp(corner & 4 ? st.bounds.max().z() : st.bounds.min().z(), range.z_low - 2.0,
                                range.z_high + 2.0);
    double u = 0, v = 0, d = 0;
    project(x, y, z, u, v, d);
    umin = std::min(umin, u);
    umax = std::max(umax, u);
    vmin = std::min(vmin, v);
    vmax = std::max(vmax, v);
    dmin = std::min(dmin, d);
    dmax = std::max(dmax, d);
  }
  const double scale = std::min(max_pixels / std::max(umax - umin, 1e-6), max_pixels / std::max(vmax - vmin, 1e-6));
  const double px_per_m = std::min(scale, 2.0 / map.cell_size() * 4.0);
  const int w = std::max(1, static_cast<int>(std::ceil((umax - umin) * px_per_m)) + 1);
  const int h = std::max(1, static_cast<int>(std::ceil((vmax - vmin) * px_per_m)) + 1);
  RgbImage img(w, h, 255);
  std::vector<float> zbuf(static_cast<std::size_t>(w) * static_cast<std::size_t>(h), std::numeric_limits<float>::infinity());
  const double half = map.cell_size() / 2.0;
  const int bar = std::max(1, static_cast<int>(std::lround(map.cell_size() * px_per_m)));
  map.for_each_column([&](const CellKey& key, const ColumnView& c) {
    const Eigen::Vector2d xy = map.cell_center(key);
    for (const HVoxel& hv : c) {
      // Sample the bar from z_min to z_max at about one pixel per step.
      const double z_lo = std::clamp(static_cast<double>(hv.z_min), range.z_low - 2.0, range.z_high + 2.0);
      const double z_hi = std::clamp(static_cast<double>(hv.z_max), range.z_low - 2.0, range.z_high + 2.0);
      const double step = 1.0 / (px_per_m * ce);
      // Counted, not `z += step`: at z = 1e17 adding a step changes nothing and the loop never
      // ended. The bar is clamped to the drawn heights, so it spans at most the picture's height.
      const std::optional<int> last = floor_to<int>((z_hi - z_lo + 1e-9) / step);
      if (!last || *last > h + 1) throw Error("an oblique bar spans more than the picture's " + std::to_string(h) + " pixels");
      for (int n = 0; n <= *last; ++n) {
        const double z = z_lo + n * step;
        double u = 0, v = 0, d = 0;
        project(xy.x(), xy.y(), z, u, v, d);
        const int x = static_cast<int>((u - umin) * px_per_m);
        const int y = static_cast<int>((v - vmin) * px_per_m);
        std::uint8_t r = 0, g = 0, b = 0;
        height_colour((z - range.z_low) / (range.z_high - range.z_low), r, g, b);
        // Shade by depth so the nearer faces read in front.
        const double shade = 0.55 + 0.45 * std::clamp(1.0 - (d - dmin) / std::max(dmax - dmin, 1e-6), 0.0, 1.0);
        for (int dx = 0; dx < bar; ++dx) {
          const int xx = x + dx - bar / 2;
          if (xx < 0 || xx >= w || y < 0 || y >= h) continue;
          const std::size_t k = static_cast<std::size_t>(y) * static_cast<std::size_t>(w) + static_cast<std::size_t>(xx);
          const auto depth = static_cast<float>(d - half);
          if (depth >= zbuf[k]) continue;
          zbuf[k] = depth;
          const double edge = dx == 0 || dx == bar - 1 ? 0.8 : 1.0;  // a darker rim separates bars
          img.set(xx, y, static_cast<std::uint8_t>(r * shade * edge), static_cast<std::uint8_t>(g * shade * edge),
                  static_cast<std::uint8_t>(b * shade * edge));
        }
      }
    }
  });
  return img;
}

void draw_path(RgbImage& image, const TopViewport& vp, const PoseList& poses, std::uint8_t r, std::uint8_t g,
               std::uint8_t b) {
  const auto plot = [&](int x, int y) {
    for (int dy = 0; dy < 2; ++dy)
      for (int dx = 0; dx < 2; ++dx)
        if (x + dx >= 0 && y + dy >= 0 && x + dx < image.width && y + dy < image.height) image.set(x + dx, y + dy, r, g, b);
  };
  for (std::size_t k = 1; k < poses.size(); ++k) {
    const double xa = vp.px(poses[k - 1].translation().x()), ya = vp.py(poses[k - 1].translation().y());
    const double xb = vp.px(poses[k].translation().x()), yb = vp.py(poses[k].translation().y());
    const int steps = std::max(1, static_cast<int>(std::ceil(std::max(std::abs(xb - xa), std::abs(yb - ya)))));
    for (int s = 0; s <= steps; ++s) {
      const double t = static_cast<double>(s) / steps;
      plot(static_cast<int>(xa + t * (xb - xa)), static_cast<int>(ya + t * (yb - ya)));
    }
  }
  if (!poses.empty()) {
    const int x = static_cast<int>(vp.px(poses[0].translation().x()));
    const int y = static_cast<int>(vp.py(poses[0].translation().y()));
    for (int dy = -3; dy <= 3; ++dy)
      for (int dx = -3; dx <= 3; ++dx)
        if (dx * dx + dy * dy <= 9 && x + dx >= 0 && y + dy >= 0 && x + dx < image.width && y + dy < image.height)
          image.set(x + dx, y + dy, r, g, b);
  }
}

namespace {

void plot_clipped(RgbImage& image, int x, int y, std::uint8_t r, std::uint8_t g, std::uint8_t b) {
  if (x >= 0 && y >= 0 && x < image.width && y < image.height) image.set(x, y, r, g, b);
}

void draw_line(RgbImage& image, double xa, double ya, double xb, double yb, std::uint8_t r, std::uint8_t g,
               std::uint8_t b) {
  const int steps = std::max(1, static_cast<int>(std::ceil(std::max(std::abs(xb - xa), std::abs(yb - ya)))));
  for (int s = 0; s <= steps; ++s) {
    const double t = static_cast<double>(s) / steps;
    plot_clipped(image, static_cast<int>(std::floor(xa + t * (xb - xa))), static_cast<int>(std::floor(ya + t * (yb - ya))), r, g, b);
  }
}

}  // namespace

RgbImage side_by_side(const std::vector<std::pair<std::string, RgbImage>>& panels) {
  constexpr int kGap = 12;
  // Titles fitted to their panels' widths at one common size: the largest in [11, 20] px at which
  // every title fits on one line, else 11 px with the long ones wrapped.
  int size = 20;
  int width = kGap;
  int height = 0;
  for (const auto& [title, img] : panels) {
    size = std::min(size, fit_text(title, img.width, 20, 11).pixel_height);
    width += img.width + kGap;
    height = std::max(height, img.height);
  }
  std::vector<FittedText> titles;
  int title_h = 0;
  for (const auto& [title, img] : panels) {
    titles.push_back(fit_text(title, img.width, size, size));
    title_h = std::max(title_h, titles.back().height());
  }
  const int top = 8 + title_h + 6;
  RgbImage out(width, height + top + kGap, 255);
  int x = kGap;
  for (std::size_t p = 0; p < panels.size(); ++p) {
    const RgbImage& img = panels[p].second;
    draw_fitted(out, x, 8, titles[p], 0, 0, 0);
    for (int y = 0; y < img.height; ++y) {
      for (int xx = 0; xx < img.width; ++xx) {
        const std::size_t k = 3 * (static_cast<std::size_t>(y) * static_cast<std::size_t>(img.width) + static_cast<std::size_t>(xx));
        out.set(x + xx, top + y, img.rgb[k], img.rgb[k + 1], img.rgb[k + 2]);
      }
    }
    x += img.width + kGap;
  }
  return out;
}

TopViewport viewport_over(double x0, double y0, double x1, double y1, double cell, int max_pixels) {
  TopViewport vp;
  vp.m_per_px = std::max(cell, std::max(x1 - x0, y1 - y0) / std::max(max_pixels, 1));
  vp.x0 = x0;
  vp.y1 = y1;
  vp.width = std::max(1, static_cast<int>(std::ceil((x1 - x0) / vp.m_per_px)));
  vp.height = std::max(1, static_cast<int>(std::ceil((y1 - y0) / vp.m_per_px)));
  return vp;
}

RgbImage render_top_in(const HMap& map, const HeightRange& range_in, const TopViewport& vp) {
  const HeightRange range = resolve_range(map, range_in);
  const auto n = static_cast<std::size_t>(vp.width) * static_cast<std::size_t>(vp.height);
  std::vector<float> top(n, -std::numeric_limits<float>::infinity());
  std::vector<std::uint8_t> layers(n, 0);
  map.for_each_column([&](const CellKey& key, const ColumnView& c) {
    if (c.empty()) return;
    const Eigen::Vector2d xy = map.cell_center(key);
    const auto x = static_cast<int>(std::floor(vp.px(xy.x())));
    const auto y = static_cast<int>(std::floor(vp.py(xy.y())));
    if (x < 0 || y < 0 || x >= vp.width || y >= vp.height) return;
    const std::size_t k = static_cast<std::size_t>(y) * static_cast<std::size_t>(vp.width) + static_cast<std::size_t>(x);
    top[k] = std::max(top[k], c[c.size() - 1].z_max);
    layers[k] = static_cast<std::uint8_t>(std::max<std::size_t>(layers[k], std::min<std::size_t>(c.size(), 255)));
  });
  RgbImage img(vp.width, vp.height, 0);
  for (std::size_t k = 0; k < n; ++k) {
    if (!std::isfinite(top[k])) continue;  // unknown: black
    std::uint8_t r = 0, g = 0, b = 0;
    height_colour((top[k] - range.z_low) / (range.z_high - range.z_low), r, g, b);
    if (layers[k] > 1) {  // overhangs (several HVoxels in the column) drawn lighter
      r = static_cast<std::uint8_t>((r + 255) / 2);
      g = static_cast<std::uint8_t>((g + 255) / 2);
      b = static_cast<std::uint8_t>((b + 255) / 2);
    }
    img.rgb[3 * k] = r;
    img.rgb[3 * k + 1] = g;
    img.rgb[3 * k + 2] = b;
  }
  return img;
}

RgbImage render_occupancy(const OccupancyGrid& grid, const TopViewport& vp, const GridReading& reading) {
  RgbImage img(vp.width, vp.height, 205);
  const double cell = grid.cell_size();
  // Cells larger than a pixel cover several; smaller ones share one, the most occupied winning.
  // A cell no larger than a pixel is placed by its centre (its corner would round onto the
  // neighbouring pixel now and then, leaving unpainted lines); a larger one covers `span` pixels.
  const int span = cell <= vp.m_per_px * 1.000001 ? 1 : static_cast<int>(std::ceil(cell / vp.m_per_px));
  std::vector<float> best(static_cast<std::size_t>(vp.width) * static_cast<std::size_t>(vp.height), -1.0F);
  grid.for_each_cell([&](const CellKey& key, float l) {
    const auto p = static_cast<float>(probability(l));
    const double corner = span == 1 ? 0.5 : 0.0;
    const auto x = static_cast<int>(std::floor(vp.px((key.i + corner) * cell)));
    const auto y = static_cast<int>(std::floor(vp.py((key.j + 1 - corner) * cell)));
    for (int dy = 0; dy < span; ++dy) {
      for (int dx = 0; dx < span; ++dx) {
        const int xx = x + dx;
        const int yy = y + dy;
        if (xx < 0 || yy < 0 || xx >= vp.width || yy >= vp.height) continue;
        float& slot = best[static_cast<std::size_t>(yy) * static_cast<std::size_t>(vp.width) + static_cast<std::size_t>(xx)];
        if (p <= slot) continue;
        slot = p;
        // The classes export --pgm writes, as Nav2 will see the map.
        const CellClass c = reading.classify(p);
        const std::uint8_t grey = c == CellClass::kOccupied ? 0 : c == CellClass::kFree ? 255 : 205;
        img.set(xx, yy, grey, grey, grey);
      }
    }
  });
  return img;
}

RgbImage render_points_top(const PointCloud& points, const HeightRange& range, const TopViewport& vp) {
  const auto n = static_cast<std::size_t>(vp.width) * static_cast<std::size_t>(vp.height);
  std::vector<float> top(n, -std::numeric_limits<float>::infinity());
  for (const Point3f& p : points) {
    const auto x = static_cast<int>(std::floor(vp.px(p.x())));
    const auto y = static_cast<int>(std::floor(vp.py(p.y())));
    if (x < 0 || y < 0 || x >= vp.width || y >= vp.height) continue;
    float& t = top[static_cast<std::size_t>(y) * static_cast<std::size_t>(vp.width) + static_cast<std::size_t>(x)];
    t = std::max(t, p.z());
  }
  RgbImage img(vp.width, vp.height, 0);
  for (std::size_t k = 0; k < n; ++k) {
    if (!std::isfinite(top[k])) continue;
    height_colour((top[k] - range.z_low) / (range.z_high - range.z_low), img.rgb[3 * k], img.rgb[3 * k + 1], img.rgb[3 * k + 2]);
  }
  return img;
}

void draw_ground_patches(RgbImage& image, const TopViewport& vp, std::span<const GroundPatch> patches,
                         std::uint8_t r, std::uint8_t g, std::uint8_t b) {
  for (const GroundPatch& p : patches) {
    const double x0 = vp.px(p.center.x() - p.half_size);
    const double x1 = vp.px(p.center.x() + p.half_size);
    const double y0 = vp.py(p.center.y() + p.half_size);
    const double y1 = vp.py(p.center.y() - p.half_size);
    draw_line(image, x0, y0, x1, y0, r, g, b);
    draw_line(image, x1, y0, x1, y1, r, g, b);
    draw_line(image, x1, y1, x0, y1, r, g, b);
    draw_line(image, x0, y1, x0, y0, r, g, b);
    if (p.parent >= 0 && static_cast<std::size_t>(p.parent) < patches.size()) {
      const GroundPatch& q = patches[static_cast<std::size_t>(p.parent)];
      draw_line(image, vp.px(p.center.x()), vp.py(p.center.y()), vp.px(q.center.x()), vp.py(q.center.y()),
                255, 255, 255);
    }
  }
}

double scale_bar_length(double width_m) {
  if (!(width_m > 0.0) || !std::isfinite(width_m)) return 0.0;
  const double target = width_m / 5.0;
  double best = 0.0;
  for (int e = -3; e <= 6; ++e) {
    for (const double m : {1.0, 2.0, 5.0}) {
      const double v = m * std::pow(10.0, e);
      if (v <= target) best = std::max(best, v);
    }
  }
  return best;
}

namespace {
void fill_box(RgbImage& img, int x0, int y0, int x1, int y1, std::uint8_t r, std::uint8_t g, std::uint8_t b) {
  for (int y = std::max(0, y0); y < std::min(img.height, y1); ++y) {
    for (int x = std::max(0, x0); x < std::min(img.width, x1); ++x) img.set(x, y, r, g, b);
  }
}
void framed_box(RgbImage& img, int x0, int y0, int x1, int y1) {
  fill_box(img, x0, y0, x1, y1, 0, 0, 0);
  fill_box(img, x0 + 1, y0 + 1, x1 - 1, y1 - 1, 255, 255, 255);
}
}  // namespace

LegendPanel legend_panel(const TopViewport& viewport, const std::vector<LegendEntry>& legend, int map_width) {
  constexpr int kText = 13;  // [px] font height
  LegendPanel p;
  p.line = std::max(LegendPanel::kSwatch, measure_text("", kText).height) + 3;
  int longest = 0;
  for (const LegendEntry& e : legend) longest = std::max(longest, measure_text(e.label, kText).width);
  p.legend_w = legend.empty() ? 0 : LegendPanel::kMargin * 3 + LegendPanel::kSwatch + longest;
  p.legend_h = legend.empty() ? 0 : LegendPanel::kMargin * 2 + static_cast<int>(legend.size()) * p.line;
  p.bar_m = scale_bar_length(map_width * viewport.m_per_px);
  p.bar_px = static_cast<int>(std::lround(p.bar_m / viewport.m_per_px));
  if (p.bar_px < 10) p.bar_px = 0;  // too short to read: no bar
  p.label = format("%g m", p.bar_m);
  const TextSize label_size = measure_text(p.label, kText);
  p.box_w = p.bar_px > 0 ? std::max(p.bar_px, label_size.width) + 2 * LegendPanel::kMargin : 0;
  p.box_h = p.bar_px > 0 ? label_size.height + 14 : 0;
  const int inner = std::max(p.legend_w, p.box_w);
  p.width = inner > 0 ? inner + 9 : 0;  // a 1 px rule beside the map, 4 px on either side of the boxes
  return p;
}

void draw_legend_and_scale(RgbImage& image, const TopViewport& viewport, const std::vector<LegendEntry>& legend) {
  constexpr int kText = 13;
  constexpr int kMargin = LegendPanel::kMargin;
  constexpr int kSwatch = LegendPanel::kSwatch;
  const LegendPanel p = legend_panel(viewport, legend, image.width);
  if (p.width == 0) return;
  // The panel goes to the right of the map, never over it: on a small map the legend would hide
  // the map and the path it names.
  const int map_w = image.width;
  const int needed_h = (p.legend_h > 0 ? p.legend_h + 8 : 0) + (p.box_h > 0 ? p.box_h + 8 : 0);
  RgbImage out(map_w + p.width, std::max(image.height, needed_h), 255);
  for (int y = 0; y < image.height; ++y) {
    std::copy_n(image.rgb.begin() + static_cast<std::ptrdiff_t>(y) * map_w * 3, static_cast<std::ptrdiff_t>(map_w) * 3,
                out.rgb.begin() + static_cast<std::ptrdiff_t>(y) * out.width * 3);
  }
  fill_box(out, map_w, 0, map_w + 1, out.height, 0, 0, 0);  // the rule between map and panel
  const int x0 = map_w + 5;
  if (p.legend_h > 0) {
    framed_box(out, x0, 4, x0 + p.legend_w, 4 + p.legend_h);
    for (std::size_t k = 0; k < legend.size(); ++k) {
      const int y = 4 + kMargin + static_cast<int>(k) * p.line;
      const LegendEntry& e = legend[k];
      const int sy = y + (p.line - 3 - kSwatch) / 2;
      fill_box(out, x0 + kMargin - 1, sy - 1, x0 + kMargin + kSwatch + 1, sy + kSwatch + 1, 0, 0, 0);
      fill_box(out, x0 + kMargin, sy, x0 + kMargin + kSwatch, sy + kSwatch, e.r, e.g, e.b);
      draw_text(out, x0 + 2 * kMargin + kSwatch, y, e.label, kText, 0, 0, 0);
    }
  }
  if (p.box_h > 0) {
    const int y1 = out.height - 4;
    framed_box(out, x0, y1 - p.box_h, x0 + p.box_w, y1);
    fill_box(out, x0 + kMargin, y1 - 8, x0 + kMargin + p.bar_px, y1 - 5, 0, 0, 0);  // the bar
    fill_box(out, x0 + kMargin, y1 - 11, x0 + kMargin + 1, y1 - 5, 0, 0, 0);        // its ends
    fill_box(out, x0 + kMargin + p.bar_px - 1, y1 - 11, x0 + kMargin + p.bar_px, y1 - 5, 0, 0, 0);
    draw_text(out, x0 + kMargin, y1 - p.box_h + 2, p.label, kText, 0, 0, 0);
  }
  image = std::move(out);
}

std::array<std::uint8_t, 3> path_colour(std::size_t k, bool on_occupancy) {
  static constexpr std::array<std::array<std::uint8_t, 3>, 6> kColours{
      {{255, 255, 255}, {255, 40, 40}, {255, 0, 255}, {255, 160, 0}, {0, 200, 255}, {80, 220, 80}}};
  if (on_occupancy && k == 0) return {0, 90, 255};
  return kColours[std::min<std::size_t>(k, kColours.size() - 1)];
}

std::vector<LegendEntry> height_legend(const HeightRange& range) {
  std::vector<LegendEntry> legend(2);
  height_colour(0.0, legend[0].r, legend[0].g, legend[0].b);
  legend[0].label = format("%.2f m", range.z_low);
  height_colour(1.0, legend[1].r, legend[1].g, legend[1].b);
  legend[1].label = format("%.2f m", range.z_high);
  return legend;
}

void draw_paths_and_legend(RgbImage& image, const TopViewport& viewport, std::vector<LegendEntry> legend,
                           const std::vector<PathLayer>& paths) {
  for (const PathLayer& p : paths) {
    if (p.poses == nullptr) continue;
    draw_path(image, viewport, *p.poses, p.r, p.g, p.b);
    legend.push_back({p.r, p.g, p.b, p.label});
  }
  draw_legend_and_scale(image, viewport, legend);
}

TopPicture render_top_view(const HMap& map, TopLayer layer, const HeightRange& range_in, int max_pixels,
                           const OccupancyGrid* grid, std::span<const GroundPatch> ground,
                           const std::vector<LabelledPath>& paths, bool legend) {
  if (layer == TopLayer::kOccupancy && (grid == nullptr || grid->known_cells() == 0)) {
    throw Error("the map holds no 2D occupancy grid to draw");
  }
  if (layer == TopLayer::kGround && ground.empty()) throw Error("the map holds no ground patches to draw");
  const HeightRange range = resolve_range(map, range_in);
  TopPicture out;
  out.image = render_top(map, range, max_pixels, out.viewport, paths.empty() ? 0.0 : 2.0);
  if (layer == TopLayer::kOccupancy) {
    out.image = render_occupancy(*grid, out.viewport, GridReading::for_map(map.params().occupancy));
  } else if (layer == TopLayer::kGround) {
    draw_ground_patches(out.image, out.viewport, ground, 255, 255, 255);
  }
  const bool on_grid = layer == TopLayer::kOccupancy;
  std::vector<PathLayer> layers;
  for (std::size_t k = 0; k < paths.size(); ++k) {
    if (paths[k].poses == nullptr) continue;
    const auto c = path_colour(k, on_grid);
    layers.push_back({paths[k].poses, c[0], c[1], c[2], paths[k].label});
  }
  if (legend) {
    const std::vector<LegendEntry> entries =
        on_grid ? std::vector<LegendEntry>{{255, 255, 255, "free"}, {0, 0, 0, "occupied"}, {205, 205, 205, "unknown"}}
                : height_legend(range);
    draw_paths_and_legend(out.image, out.viewport, entries, layers);
  } else {
    for (const PathLayer& p : layers) draw_path(out.image, out.viewport, *p.poses, p.r, p.g, p.b);
  }
  return out;
}

TopPicture render_paths(const std::vector<LabelledPath>& paths, int max_pixels) {
  check_max_pixels(max_pixels);
  double x0 = std::numeric_limits<double>::infinity();
  double y0 = x0;
  double x1 = -x0;
  double y1 = -x0;
  for (const LabelledPath& path : paths) {
    if (path.poses == nullptr) continue;
    for (const Pose& T : *path.poses) {
      const Eigen::Vector3d t = T.translation();
      if (!t.allFinite()) throw Error("cannot draw the path '" + path.label + "': a pose is not finite");
      x0 = std::min(x0, t.x());
      y0 = std::min(y0, t.y());
      x1 = std::max(x1, t.x());
      y1 = std::max(y1, t.y());
    }
  }
  if (!(x0 <= x1)) throw Error("there is no pose to draw");
  const double margin = std::max(1.0, 0.1 * std::max(x1 - x0, y1 - y0));
  TopPicture out;
  out.viewport = viewport_over(x0 - margin, y0 - margin, x1 + margin, y1 + margin, 0.0, max_pixels);
  out.image = RgbImage(out.viewport.width, out.viewport.height, 0);
  std::vector<PathLayer> layers;
  for (std::size_t k = 0; k < paths.size(); ++k) {
    if (paths[k].poses == nullptr) continue;
    const auto c = path_colour(k, false);
    layers.push_back({paths[k].poses, c[0], c[1], c[2], paths[k].label});
  }
  draw_paths_and_legend(out.image, out.viewport, {}, layers);
  return out;
}

}  // namespace hmap::render
