// hmap render: a top-down picture of a map, coloured by height.

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "cli_common.hpp"
#include "hmap/core/error.hpp"
#include "hmap/io/hmap_file.hpp"
#include "hmap/io/png.hpp"

namespace hmap::cli {

namespace {

/// A perceptual rainbow (blue → cyan → green → yellow → red) for t in [0, 1].
void colormap(double t, std::uint8_t& r, std::uint8_t& g, std::uint8_t& b) {
  t = std::clamp(t, 0.0, 1.0);
  const double rr = std::clamp(1.5 - std::abs(4.0 * t - 3.0), 0.0, 1.0);
  const double gg = std::clamp(1.5 - std::abs(4.0 * t - 2.0), 0.0, 1.0);
  const double bb = std::clamp(1.5 - std::abs(4.0 * t - 1.0), 0.0, 1.0);
  r = static_cast<std::uint8_t>(std::lround(255 * rr));
  g = static_cast<std::uint8_t>(std::lround(255 * gg));
  b = static_cast<std::uint8_t>(std::lround(255 * bb));
}

struct RenderOptions {
  std::string map;
  std::string out;
  double z_low = NAN;
  double z_high = NAN;
  int max_pixels = 4000;
};

void run_render(const RenderOptions& o) {
  const HMap map = load_hmap(o.map);
  const MapStats st = map.stats();
  if (st.hvoxels == 0) throw Error(o.map + ": the map is empty, nothing to render");
  const double cell = map.cell_size();
  const auto i0 = static_cast<long>(std::floor(st.bounds.min().x() / cell + 0.5));
  const auto j0 = static_cast<long>(std::floor(st.bounds.min().y() / cell + 0.5));
  const long ni = static_cast<long>(std::lround((st.bounds.max().x() - st.bounds.min().x()) / cell));
  const long nj = static_cast<long>(std::lround((st.bounds.max().y() - st.bounds.min().y()) / cell));
  // One pixel per cell, or several cells per pixel for very large maps.
  const long stride = std::max(1L, (std::max(ni, nj) + o.max_pixels - 1) / o.max_pixels);
  const int w = static_cast<int>((ni + stride - 1) / stride);
  const int h = static_cast<int>((nj + stride - 1) / stride);
  // Height range: the given one, or the 2nd-98th percentile of the HVoxel tops.
  double lo = o.z_low;
  double hi = o.z_high;
  if (std::isnan(lo) || std::isnan(hi)) {
    std::vector<float> tops;
    map.for_each_column([&](const CellKey&, const Column& c) { tops.push_back(c[c.size() - 1].z_max); });
    std::sort(tops.begin(), tops.end());
    if (std::isnan(lo)) lo = tops[tops.size() * 2 / 100];
    if (std::isnan(hi)) hi = tops[tops.size() * 98 / 100];
  }
  if (!(hi > lo)) hi = lo + 1.0;
  RgbImage img(w, h, 0);
  std::vector<float> top(static_cast<std::size_t>(w) * static_cast<std::size_t>(h), -INFINITY);
  std::vector<std::uint8_t> layers(top.size(), 0);
  map.for_each_column([&](const CellKey& key, const Column& c) {
    const long x = (key.i - i0) / stride;
    const long y = (key.j - j0) / stride;
    if (x < 0 || y < 0 || x >= w || y >= h) return;
    const std::size_t k = static_cast<std::size_t>(h - 1 - y) * static_cast<std::size_t>(w) + static_cast<std::size_t>(x);  // north up
    top[k] = std::max(top[k], c[c.size() - 1].z_max);
    layers[k] = static_cast<std::uint8_t>(std::max<std::size_t>(layers[k], std::min<std::size_t>(c.size(), 255)));
  });
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const std::size_t k = static_cast<std::size_t>(y) * static_cast<std::size_t>(w) + static_cast<std::size_t>(x);
      if (!std::isfinite(top[k])) continue;  // unknown: black
      std::uint8_t r = 0, g = 0, b = 0;
      colormap((top[k] - lo) / (hi - lo), r, g, b);
      if (layers[k] > 1) {  // overhangs (several HVoxels in the column) drawn lighter
        r = static_cast<std::uint8_t>((r + 255) / 2);
        g = static_cast<std::uint8_t>((g + 255) / 2);
        b = static_cast<std::uint8_t>((b + 255) / 2);
      }
      img.set(x, y, r, g, b);
    }
  }
  write_png(o.out, img);
  std::printf("wrote %s: %dx%d pixels, %.3f m per pixel, colour from %.2f m (blue) to %.2f m (red); "
              "light cells hold several HVoxels\n", o.out.c_str(), w, h, cell * static_cast<double>(stride), lo, hi);
}

}  // namespace

void add_render_command(CLI::App& app) {
  auto opts = std::make_shared<RenderOptions>();
  auto* cmd = app.add_subcommand("render", "Draw a top-down PNG of a map, coloured by the height of each column's top");
  cmd->add_option("map", opts->map, "Map file (.hmap)")->required();
  cmd->add_option("--out,-o", opts->out, "Output PNG file")->required();
  cmd->add_option("--z-low", opts->z_low, "Height drawn blue [m] (default: 2nd percentile of the tops)");
  cmd->add_option("--z-high", opts->z_high, "Height drawn red [m] (default: 98th percentile of the tops)");
  cmd->add_option("--max-pixels", opts->max_pixels, "Largest picture side; cells are pooled beyond it")->check(CLI::Range(16, 20000));
  cmd->callback([opts] { run_render(*opts); });
}

}  // namespace hmap::cli
