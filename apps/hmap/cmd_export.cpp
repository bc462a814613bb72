// hmap export: a saved map into formats other tools read.

#include <algorithm>
#include <cstdio>

#include "cli_common.hpp"
#include "hmap/core/format.hpp"
#include "hmap/io/atomic_file.hpp"
#include "hmap/core/error.hpp"
#include "hmap/io/hmap_file.hpp"
#include "hmap/ground/ground_patches.hpp"
#include "hmap/io/pgm_export.hpp"
#include "hmap/io/ply_export.hpp"
#include "hmap/occupancy/occupancy_update.hpp"
#include "octomap_export.hpp"

namespace hmap::cli {

namespace {

struct ExportOptions {
  std::string map;
  std::string ply;
  std::string bt;
  std::string pgm;
  std::vector<double> ground_hint;
  int ground_iterations = 0;
  bool points = false;
  bool rederive = false;
  std::string grid = "both";
  double z_step = 0.0;
};

/// Occupied and free cells as the written PGM holds them: with the file's own thresholds
/// (map_server's 0.65 / 0.196), not at p = 0.5; cells in between are unknown in the file.
std::pair<std::size_t, std::size_t> count_classes(const OccupancyGrid& grid, const PgmExportParams& pgm = {}) {
  std::size_t occupied = 0, free_cells = 0;
  grid.for_each_cell([&](const CellKey&, float l) {
    const double p = probability(l);
    if (p > pgm.occupied_thresh) ++occupied;
    if (p < pgm.free_thresh) ++free_cells;
  });
  return {occupied, free_cells};
}

/// The 2D occupancy of a saved map as map_server PGM + YAML: ground patches by Alg. 4 from a hint
/// (given, or the middle of the map at a low height), then each column judged by eq. (4)'s cases.
void export_pgm(const HMap& map, const ExportOptions& o) {
  const MapStats st = map.stats();
  if (st.hvoxels == 0) throw Error(o.map + ": the map is empty, nothing to export");
  Params params = map.params();
  Eigen::Vector3d hint;
  if (o.ground_hint.size() == 3) {
    hint = {o.ground_hint[0], o.ground_hint[1], o.ground_hint[2]};
  } else {
    std::vector<float> tops;
    map.for_each_column([&](const CellKey&, const ColumnView& c) { tops.push_back(c[0].z_max); });
    std::sort(tops.begin(), tops.end());
    const Eigen::Vector3d mid = st.bounds.center();
    hint = {mid.x(), mid.y(), tops[tops.size() / 5] + 0.5};  // above the low fifth of the lowest tops
  }
  // K of the paper (400) explores a few hundred square metres; grow it with the map's area.
  const double d_n = params.ground.expansion_distance;
  const double area = st.bounds.sizes().x() * st.bounds.sizes().y();
  params.ground.iterations = o.ground_iterations > 0
                                 ? o.ground_iterations
                                 : std::clamp(static_cast<int>(2.0 * area / (d_n * d_n)), params.ground.iterations, 4000);
  const auto t0 = Clock::now();
  const GroundResult ground = extract_ground(map, hint, params.ground);
  if (!ground.seeded) {
    throw Error(o.map + ": no ground found near the hint (" + std::to_string(hint.x()) + ", " + std::to_string(hint.y()) +
                ", " + std::to_string(hint.z()) + "); give --ground-hint X Y Z near the floor");
  }
  const GroundModel model(ground.patches);
  const OccupancyGrid grid = occupancy_from_map(map, model, params, 2.0 * d_n);
  write_pgm_map(o.pgm, grid);
  const auto [occupied, free_cells] = count_classes(grid);
  std::printf("wrote %s.pgm + .yaml: %zu occupied and %zu free cells (map_server thresholds 0.65 / 0.196) of %.3f m, derived from %zu ground patches "
              "(%d RRT iterations, %.1f s); cells without a ground patch within %.2f m are unknown\n",
              std::filesystem::path(o.pgm).replace_extension().string().c_str(), occupied, free_cells, map.cell_size(),
              ground.patches.size(), params.ground.iterations, ms_since(t0) / 1000.0, 2.0 * d_n);
}

void run_export(const ExportOptions& o) {
  if (o.ply.empty() && o.bt.empty() && o.pgm.empty()) {
    throw Error("nothing to export: give --ply OUT.ply, --bt OUT.bt and/or --pgm OUT");
  }
  if (o.z_step != 0.0 && !(o.z_step >= 1e-3 && o.z_step <= 100.0)) {
    throw Error(format("--z-step = %g m is out of its range [0.001, 100] m", o.z_step));
  }
  if (o.ground_iterations != 0 && !(o.ground_iterations > 0 && o.ground_iterations <= 100000)) {
    throw Error("--ground-iterations = " + std::to_string(o.ground_iterations) + " is out of its range [1, 100000]");
  }
  // Every output checked before the map is read and the work done.
  if (!o.ply.empty()) check_output_file(o.ply);
  if (!o.bt.empty()) check_output_file(o.bt);
  if (!o.pgm.empty()) {
    for (const char* ext : {".pgm", ".yaml"}) check_output_file(pgm_stem(o.pgm).concat(ext));
  }
  MapFile file = load_map_file(o.map);
  const HMap& map = file.map;
  if (!o.pgm.empty()) {
    // The grid kept scan by scan (eq. 3-4 with every ray) is the better map; a map saved without it
    // (hmap map --hvoxels-only, or older files) gets one derived from its columns.
    if (file.grid && file.grid->known_cells() > 0 && !o.rederive) {
      // "both" (default): each cell the more occupied of the grid kept scan by scan and the
      // columns of the final map judged by eq. (4) on the same ground patches. The kept grid
      // alone misses thin or sparsely hit obstacles outdoors (few points per cell give densities
      // barely over 0.5 against the free passes of every ray); the judged one misses what later
      // scans carved; docs/COMPARE.md has the figures.
      const Params& params = map.params();
      std::optional<OccupancyGrid> judged;
      if (o.grid != "kept" && !file.ground.empty()) {
        judged = occupancy_from_map(map, GroundModel(file.ground), params, params.occupancy.ground_reach);
      }
      const OccupancyGrid* out = &*file.grid;
      std::optional<OccupancyGrid> fused;
      if (judged && o.grid == "both") {
        fused = more_occupied(*file.grid, *judged);
        out = &*fused;
      } else if (judged && o.grid == "judged") {
        out = &*judged;
      }
      write_pgm_map(o.pgm, *out);
      const auto [occupied, free_cells] = count_classes(*out);
      const char* what = out == &*file.grid ? "the map's own 2D grid (kept scan by scan)"
                         : fused            ? "the map's own 2D grid and its columns judged, the more occupied per cell"
                                            : "the map's columns judged by eq. (4) on its ground patches";
      std::printf("wrote %s.pgm + .yaml: %s, %zu occupied and %zu free cells (map_server thresholds 0.65 / 0.196) of %.3f m\n",
                  std::filesystem::path(o.pgm).replace_extension().string().c_str(), what, occupied, free_cells,
                  map.cell_size());
    } else {
      export_pgm(map, o);
    }
  }
  if (o.ply.empty() && o.bt.empty()) return;
  if (!o.bt.empty()) {
    const std::size_t leaves = write_octomap_bt(o.bt, map, memory_budget());
    std::printf("wrote %zu occupied OctoMap leaves (resolution %.3f m) to %s\n", leaves, map.cell_size(), o.bt.c_str());
    if (o.ply.empty()) return;
  }
  if (o.points) {
    const double step = o.z_step > 0.0 ? o.z_step : map.cell_size();
    const PointCloud pts = recover_points(map, step, memory_budget());
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
  cmd->add_option("--pgm", opts->pgm, "Output 2D occupancy as ROS map_server PGM + YAML (OUT.pgm, OUT.yaml)");
  cmd->add_option("--grid", opts->grid,
                  "With --pgm, for a map that holds its 2D grid: kept (the grid updated scan by scan), judged (the "
                  "final map's columns by eq. 4) or both (the more occupied of the two per cell)")
      ->check(CLI::IsMember({"kept", "judged", "both"}))
      ->capture_default_str();
  cmd->add_flag("--rederive", opts->rederive,
                "Derive the 2D grid from the HVoxels even when the map file holds one kept scan by scan");
  cmd->add_option("--ground-hint", opts->ground_hint, "A point near the floor, X Y Z [m], to start the ground search")
      ->expected(3);
  cmd->add_option("--ground-iterations", opts->ground_iterations, "RRT iterations K (default: grows with the map area)");
  cmd->add_option("--bt", opts->bt, "Output OctoMap binary tree (.bt), for octovis and the octomap tools");
  cmd->add_flag("--points", opts->points, "Write the height-upsampled point cloud instead of boxes");
  cmd->add_option("--z-step", opts->z_step, "Vertical spacing of recovered points [m] (default: the cell size)");
  cmd->callback([opts] { run_export(*opts); });
}

}  // namespace hmap::cli
