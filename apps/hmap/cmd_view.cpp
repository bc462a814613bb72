// hmap view: the map in a browser (three.js), served on a local address.

#include <csignal>
#include <cstdio>
#include <memory>
#include <string>

#include "cli_common.hpp"
#include "hmap/core/error.hpp"
#include "hmap/io/hmap_file.hpp"
#include "hmap/io/poses.hpp"
#include "hmap/serve/view_server.hpp"
#include "live_view.hpp"
#ifdef HMAP_HAVE_PVOX
#include "pvox_output.hpp"
#endif

namespace hmap::cli {

namespace {

namespace fs = std::filesystem;

struct ViewOptions {
  std::string map;
  std::string bind = "127.0.0.1";
  int port = 8080;
  std::string trajectory;
};

}  // namespace

/// The page's folder: installed beside the tool (PREFIX/share/hmap/web), at the configured
/// install prefix, or in the source tree when the tool runs from its build tree.
fs::path view_web_root() {
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  for (const fs::path& dir : {ec ? fs::path() : exe.parent_path() / ".." / "share" / "hmap" / "web",
                              fs::path(HMAP_WEB_INSTALL_DIR), fs::path(HMAP_WEB_SOURCE_DIR)}) {
    if (!dir.empty() && fs::is_regular_file(dir / "index.html", ec)) return dir;
  }
  throw Error("view: the page (web/index.html) is neither installed (" HMAP_WEB_INSTALL_DIR ") nor in the source tree");
}

namespace {

bool is_pvox([[maybe_unused]] const std::string& path) {
#ifdef HMAP_HAVE_PVOX
  return is_pvox_file(path);
#else
  return false;
#endif
}


#ifdef HMAP_HAVE_PVOX
/// The `.pvox` map of `hmap pvox`: its occupied voxels (p > 0.5), coloured by probability.
std::shared_ptr<const view::MapScene> pvox_scene(const std::string& path, std::vector<Eigen::Vector3d> trajectory) {
  const pvox::VoxelMap voxels = load_pvox_file(path);
  std::vector<Eigen::Vector3d> centres;
  std::vector<double> probability;
  for (const pvox::VoxelView& v : voxels.occupied()) {
    centres.push_back(v.centre);
    probability.push_back(v.probability);
  }
  return std::make_shared<const view::MapScene>(view::voxels_as_columns(centres, probability, voxels.edge()),
                                                std::vector<GroundPatch>{}, std::nullopt, std::move(trajectory), "pvox");
}
#endif

/// The map file's layers as the viewer shows them.
std::shared_ptr<const view::MapScene> load_scene(const std::string& path, std::vector<Eigen::Vector3d> trajectory) {
#ifdef HMAP_HAVE_PVOX
  if (is_pvox_file(path)) return pvox_scene(path, std::move(trajectory));
#endif
  MapFile file = load_map_file(path);
  return std::make_shared<const view::MapScene>(std::move(file.map), std::move(file.ground), std::move(file.grid),
                                                std::move(trajectory));
}

void run_view(const ViewOptions& o) {
  std::vector<Eigen::Vector3d> trajectory;
  fs::path poses = o.trajectory;
  // hmap slam --out DIR writes DIR/map.hmap beside DIR/poses.txt: its trajectory is shown too.
  if (poses.empty() && fs::path(o.map).filename() == "map.hmap" && fs::is_regular_file(fs::path(o.map).parent_path() / "poses.txt")) {
    poses = fs::path(o.map).parent_path() / "poses.txt";
  }
  if (!poses.empty()) {
    for (const Pose& T_map_scan : read_poses(poses)) trajectory.push_back(T_map_scan.translation());
  }
  const auto scene = load_scene(o.map, std::move(trajectory));
  serve::ViewServer server(scene, {o.bind, o.port, view_web_root(), HMAP_THREE_DIR});
  server.bind();
  std::printf("hmap view: %s, %zu %s%s%s\n", o.map.c_str(), scene->map().stats().hvoxels,
              is_pvox(o.map) ? "voxels (PVOX)" : "HVoxels", poses.empty() ? "" : ", trajectory ", poses.empty() ? "" : poses.c_str());
  std::printf("open %s in a browser (Ctrl-C stops)\n", server.url().c_str());
  std::fflush(stdout);
  stop_on_signals([&server] { server.stop(); });
  server.run();
  stop_on_signals(nullptr);
}

}  // namespace

void add_view_command(CLI::App& app) {
  auto o = std::make_shared<ViewOptions>();
  auto* cmd = app.add_subcommand("view", "Show a map in a web browser: HVoxels, 2D grid, ground, trajectory; click a cell for its column");
  cmd->add_option("map", o->map, "Map file (.hmap, or the .pvox of hmap pvox)")->required();
  cmd->add_option("--port", o->port, "Port to listen on (0: any free port)")->check(CLI::Range(0, 65535))->capture_default_str();
  cmd->add_option("--bind", o->bind, "Address to listen on (0.0.0.0: every interface)")->capture_default_str();
  cmd->add_option("--trajectory", o->trajectory, "Poses file (KITTI or TUM) drawn as a line; default: poses.txt beside a map.hmap of hmap slam");
  cmd->callback([o] { run_view(*o); });
}

}  // namespace hmap::cli
