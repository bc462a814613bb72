// hmap render: pictures of a map — top-down or oblique, with trajectories over the top view.

#include <cstdio>

#include "cli_common.hpp"
#include "hmap/core/error.hpp"
#include "hmap/io/hmap_file.hpp"
#include "hmap/io/poses.hpp"
#include "render.hpp"

namespace hmap::cli {

namespace {

struct RenderOptions {
  std::string map;
  std::string out;
  std::string view = "top";
  std::vector<std::string> trajectories;
  HeightRange range;
  int max_pixels = 2000;
};

void run_render(const RenderOptions& o) {
  const HMap map = load_hmap(o.map);
  if (map.stats().hvoxels == 0) throw Error(o.map + ": the map is empty, nothing to render");
  const HeightRange range = resolve_range(map, o.range);
  if (o.view == "oblique") {
    if (!o.trajectories.empty()) throw Error("--trajectory is drawn on the top view only");
    write_png(o.out, render_oblique(map, range, o.max_pixels));
    std::printf("wrote %s: oblique view from the south-west, colour from %.2f m (blue) to %.2f m (red)\n",
                o.out.c_str(), range.z_low, range.z_high);
    return;
  }
  std::vector<PoseList> paths;
  for (const auto& t : o.trajectories) paths.push_back(read_poses(t));
  TopViewport vp;
  RgbImage img = render_top(map, range, o.max_pixels, vp, paths.empty() ? 0.0 : 2.0);
  // First path white (the truth, by convention), then red, magenta, orange.
  const std::uint8_t colours[4][3] = {{255, 255, 255}, {255, 40, 40}, {255, 0, 255}, {255, 160, 0}};
  for (std::size_t k = 0; k < paths.size(); ++k) {
    const auto* c = colours[std::min<std::size_t>(k, 3)];
    draw_path(img, vp, paths[k], c[0], c[1], c[2]);
  }
  write_png(o.out, img);
  std::printf("wrote %s: %dx%d pixels, %.3f m per pixel, colour from %.2f m (blue) to %.2f m (red); "
              "light cells hold several HVoxels%s\n",
              o.out.c_str(), img.width, img.height, vp.m_per_px, range.z_low, range.z_high,
              paths.empty() ? "" : "; paths: first white, then red, magenta, orange");
}

}  // namespace

void add_render_command(CLI::App& app) {
  auto opts = std::make_shared<RenderOptions>();
  auto* cmd = app.add_subcommand("render", "Draw a PNG of a map: top-down (with trajectories) or oblique");
  cmd->add_option("map", opts->map, "Map file (.hmap)")->required();
  cmd->add_option("--out,-o", opts->out, "Output PNG file")->required();
  cmd->add_option("--view", opts->view, "top or oblique")->check(CLI::IsMember({"top", "oblique"}))->capture_default_str();
  cmd->add_option("--trajectory", opts->trajectories, "Poses file (KITTI or TUM) drawn over the top view; repeatable");
  cmd->add_option("--z-low", opts->range.z_low, "Height drawn blue [m] (default: 2nd percentile of the tops)");
  cmd->add_option("--z-high", opts->range.z_high, "Height drawn red [m] (default: 98th percentile of the tops)");
  cmd->add_option("--max-pixels", opts->max_pixels, "Largest picture side")->check(CLI::Range(16, 20000))->capture_default_str();
  cmd->callback([opts] { run_render(*opts); });
}

}  // namespace hmap::cli
