// hmap render: pictures of a map — top-down or oblique, with trajectories over the top view.

#include <cctype>
#include <cmath>
#include <cstdio>

#include "cli_common.hpp"
#include "hmap/core/format.hpp"
#include "hmap/io/atomic_file.hpp"
#include "hmap/core/error.hpp"
#include "hmap/io/hmap_file.hpp"
#include "hmap/io/poses.hpp"
#include "hmap/occupancy/occupancy_grid.hpp"
#include "hmap/render/render.hpp"
#ifdef HMAP_HAVE_PVOX
#include "pvox_output.hpp"
#endif

namespace hmap::cli {

namespace {

struct RenderOptions {
  std::string map;
  std::string out;
  std::string view = "top";
  std::string layer = "height";
  std::vector<std::string> trajectories;
  render::HeightRange range;
  int max_pixels = 2000;
};

#ifdef HMAP_HAVE_PVOX
/// The `.pvox` map of `hmap pvox`, drawn as that command draws it: the top view or the isometric one.
void render_pvox(const RenderOptions& o) {
  if (o.layer != "height") throw Error("--layer " + o.layer + ": " + o.map + " is a PVOX map, which has heights only");
  if (!o.trajectories.empty()) throw Error("--trajectory: " + o.map + " is a PVOX map; paths are drawn over .hmap maps only");
  if (!std::isnan(o.range.z_low) || !std::isnan(o.range.z_high)) {
    throw Error("--z-low / --z-high: " + o.map + " is a PVOX map, coloured by its own height range");
  }
  const pvox::VoxelMap map = load_pvox_file(o.map);
  if (map.occupied().empty()) throw Error(o.map + ": the map has no occupied voxel, nothing to render");
  render::PvoxView view = render::bulk_view(map);
  view.max_pixels = o.max_pixels;
  const RgbImage img = o.view == "oblique" ? render::render_pvox_iso(map, view) : render::render_pvox_top(map, view);
  write_png(o.out, img);
  std::printf("wrote %s: %dx%d pixels, %s view of the PVOX map (%zu occupied voxels of %.1f mm)\n", o.out.c_str(),
              img.width, img.height, o.view == "oblique" ? "isometric" : "top", map.occupied().size(), map.edge() * 1000.0);
}
#endif

void run_render(const RenderOptions& o) {
  for (const double z : {o.range.z_low, o.range.z_high}) {
    // NaN: not given. Beyond ±100 km no map has heights, and adding a step to 1e17 changes nothing.
    if (!std::isnan(z) && !(std::abs(z) <= 1e5)) {
      throw Error(format("--z-low / --z-high = %g m is out of its range [-100000, 100000] m", z));
    }
  }
  check_output_extension(o.out, {".png"}, "hmap render writes a PNG picture");
  check_output_file(o.out);
#ifdef HMAP_HAVE_PVOX
  if (is_pvox_file(o.map)) return render_pvox(o);
#endif
  const MapFile file = load_map_file(o.map);
  const HMap& map = file.map;
  if (map.stats().hvoxels == 0) throw Error(o.map + ": the map is empty, nothing to render");
  const render::HeightRange range = render::resolve_range(map, o.range);
  if (o.layer != "height" && o.view == "oblique") throw Error("--layer " + o.layer + " is drawn on the top view only");
  if (o.layer == "occupancy" && (!file.grid || file.grid->known_cells() == 0)) {
    throw Error(o.map + ": the map holds no 2D occupancy (built with --hvoxels-only, or no ground patch was found "
                "while mapping); `hmap export --pgm` derives a grid from the HVoxels");
  }
  if (o.layer == "ground" && file.ground.empty()) {
    throw Error(o.map + ": the map holds no ground patches (built with --hvoxels-only, or no ground was found)");
  }
  if (o.view == "oblique") {
    if (!o.trajectories.empty()) throw Error("--trajectory is drawn on the top view only");
    write_png(o.out, render::render_oblique(map, range, o.max_pixels));
    std::printf("wrote %s: oblique view from the south-west, colour from %.2f m (blue) to %.2f m (red)\n",
                o.out.c_str(), range.z_low, range.z_high);
    return;
  }
  std::vector<PoseList> paths;
  for (const auto& t : o.trajectories) paths.push_back(read_poses(t));
  std::vector<render::LabelledPath> labelled;
  for (std::size_t k = 0; k < paths.size(); ++k) {
    labelled.push_back({&paths[k], "path " + std::filesystem::path(o.trajectories[k]).filename().string()});
  }
  const render::TopLayer layer = o.layer == "occupancy" ? render::TopLayer::kOccupancy
                                 : o.layer == "ground"  ? render::TopLayer::kGround
                                                        : render::TopLayer::kHeight;
  const render::TopPicture picture = render::render_top_view(
      map, layer, range, o.max_pixels, file.grid ? &*file.grid : nullptr, file.ground, labelled, true);
  const RgbImage& img = picture.image;
  const render::TopViewport& vp = picture.viewport;
  write_png(o.out, img);
  if (o.layer == "occupancy") {
    std::printf("wrote %s: %dx%d pixels, %.3f m per pixel; 2D occupancy (free white, occupied black, unknown grey) "
                "%s\n",
                o.out.c_str(), img.width, img.height, vp.m_per_px,
                paths.empty() ? "" : "; paths: first blue, then red, magenta, orange");
  } else {
    std::printf("wrote %s: %dx%d pixels, %.3f m per pixel, colour from %.2f m (blue) to %.2f m (red); "
                "light cells hold several HVoxels%s%s\n",
                o.out.c_str(), img.width, img.height, vp.m_per_px, range.z_low, range.z_high,
                o.layer == "ground" ? "; ground patches outlined white" : "",
                paths.empty() ? "" : "; paths: first white, then red, magenta, orange");
  }
}

}  // namespace

void add_render_command(CLI::App& app) {
  auto opts = std::make_shared<RenderOptions>();
  auto* cmd = app.add_subcommand("render", "Draw a PNG of a map: top-down (with trajectories) or oblique");
  cmd->add_option("map", opts->map, "Map file (.hmap, or the .pvox of hmap pvox)")->required();
  cmd->add_option("--out,-o", opts->out, "Output PNG file")->required();
  cmd->add_option("--view", opts->view, "top or oblique")->check(CLI::IsMember({"top", "oblique"}))->capture_default_str();
  cmd->add_option("--layer", opts->layer,
                  "height (HVoxel tops), occupancy (the 2D grid kept with the map) or ground (Alg. 4 patches "
                  "over the heights)")
      ->check(CLI::IsMember({"height", "occupancy", "ground"}))
      ->capture_default_str();
  cmd->add_option("--trajectory", opts->trajectories, "Poses file (KITTI or TUM) drawn over the top view; repeatable");
  cmd->add_option("--z-low", opts->range.z_low, "Height drawn blue [m] (default: 2nd percentile of the tops)");
  cmd->add_option("--z-high", opts->range.z_high, "Height drawn red [m] (default: 98th percentile of the tops)");
  cmd->add_option("--max-pixels", opts->max_pixels, "Largest picture side")->check(CLI::Range(16, 20000))->capture_default_str();
  cmd->callback([opts] { run_render(*opts); });
}

}  // namespace hmap::cli
