// hmap export: a saved map into formats other tools read.

#include <cstdio>

#include "cli_common.hpp"
#include "hmap/core/error.hpp"
#include "hmap/io/hmap_file.hpp"
#include "hmap/io/ply_export.hpp"
#include "octomap_export.hpp"

namespace hmap::cli {

namespace {

struct ExportOptions {
  std::string map;
  std::string ply;
  std::string bt;
  bool points = false;
  double z_step = 0.0;
};

void run_export(const ExportOptions& o) {
  if (o.ply.empty() && o.bt.empty()) throw Error("nothing to export: give --ply OUT.ply and/or --bt OUT.bt");
  const HMap map = load_hmap(o.map);
  if (!o.bt.empty()) {
    const std::size_t leaves = write_octomap_bt(o.bt, map);
    std::printf("wrote %zu occupied OctoMap leaves (resolution %.3f m) to %s\n", leaves, map.cell_size(), o.bt.c_str());
    if (o.ply.empty()) return;
  }
  if (o.points) {
    const double step = o.z_step > 0.0 ? o.z_step : map.cell_size();
    const PointCloud pts = recover_points(map, step);
    write_points_ply(o.ply, pts);
    std::printf("wrote %zu recovered points (every %.3f m up each HVoxel) to %s\n", pts.size(), step, o.ply.c_str());
  } else {
    write_hvoxel_boxes_ply(o.ply, map);
    std::printf("wrote %zu HVoxel boxes to %s\n", map.stats().hvoxels, o.ply.c_str());
  }
}

}  // namespace

void add_export_command(CLI::App& app) {
  auto opts = std::make_shared<ExportOptions>();
  auto* cmd = app.add_subcommand("export", "Write a map as PLY (HVoxel boxes, or the recovered points) or as an OctoMap .bt");
  cmd->add_option("map", opts->map, "Map file (.hmap)")->required();
  cmd->add_option("--ply", opts->ply, "Output PLY file");
  cmd->add_option("--bt", opts->bt, "Output OctoMap binary tree (.bt), for octovis and the octomap tools");
  cmd->add_flag("--points", opts->points, "Write the height-upsampled point cloud instead of boxes");
  cmd->add_option("--z-step", opts->z_step, "Vertical spacing of recovered points [m] (default: the cell size)");
  cmd->callback([opts] { run_export(*opts); });
}

}  // namespace hmap::cli
