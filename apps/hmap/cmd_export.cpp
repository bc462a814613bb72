// hmap export: a saved map into formats other tools read.

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "cli_common.hpp"
#include "mcap_output.hpp"
#include "hmap/core/format.hpp"
#include "hmap/io/atomic_file.hpp"
#include "hmap/core/error.hpp"
#include "hmap/io/hmap_file.hpp"
#include "hmap/io/poses.hpp"
#include "hmap/ground/ground_patches.hpp"
#include "hmap/io/geotiff.hpp"
#include "hmap/io/pgm_export.hpp"
#include "hmap/io/ply_export.hpp"
#include "hmap/occupancy/exported_grid.hpp"
#include "hmap/occupancy/occupancy_update.hpp"
#include "hmap/io/octomap_export.hpp"

namespace hmap::cli {

namespace {

struct ExportOptions {
  std::string map;
  std::string ply;
  std::string bt;
  std::string pgm;
  std::string costmap;
  std::string geotiff;
  std::string mcap;
  std::string trajectory;
  TraversabilityParams traversability;
  std::vector<double> ground_hint;
  int ground_iterations = 0;
  bool points = false;
  bool rederive = false;
  std::string grid = "both";
  double z_step = 0.0;
};

/// Occupied and free cells as the written PGM holds them (the pixels 0 and 254), by the reading
/// that wrote them; cells in between are unknown in the file.
std::pair<std::size_t, std::size_t> count_classes(const OccupancyGrid& grid, const PgmExportParams& pgm) {
  std::size_t occupied = 0, free_cells = 0;
  grid.for_each_cell([&](const CellKey&, float l) {
    const CellClass c = pgm.reading.classify(probability(l));
    occupied += c == CellClass::kOccupied ? 1 : 0;
    free_cells += c == CellClass::kFree ? 1 : 0;
  });
  return {occupied, free_cells};
}

/// The grid to export (hmap/occupancy/exported_grid.hpp) with the map's name in its errors, and a
/// derived grid's search time in its sentence.
using GridChoice = ExportedGrid;
GridChoice choose_grid(MapFile& file, const ExportOptions& o) {
  if (file.map.stats().hvoxels == 0) throw Error(o.map + ": the map is empty, nothing to export");
  ExportGridParams p;
  p.source = *parse_grid_source(o.grid);  // CLI::IsMember checked it
  p.rederive = o.rederive;
  if (o.ground_hint.size() == 3) p.ground_hint = Eigen::Vector3d(o.ground_hint[0], o.ground_hint[1], o.ground_hint[2]);
  p.ground_iterations = o.ground_iterations;
  const auto t0 = Clock::now();
  GridChoice choice = export_grid(file.map, file.ground, file.grid ? &*file.grid : nullptr, p);
  if (!choice.ground_found) {
    throw Error(o.map + ": no ground found near the hint (" + std::to_string(choice.hint.x()) + ", " +
                std::to_string(choice.hint.y()) + ", " + std::to_string(choice.hint.z()) + "); give --ground-hint X Y Z near the floor");
  }
  if (choice.derived) choice.what += format(" (ground search and judging %.1f s)", ms_since(t0) / 1000.0);
  return choice;
}

/// --costmap and --geotiff: the traversability layers of the chosen grid.
/// The grid is read as --pgm writes it (`reading`: GridReading::for_map), so lethal and free agree.
void export_traversability(const GridChoice& choice, const ExportOptions& o, const GridReading& reading) {
  TraversabilityParams tp = o.traversability;
  tp.reading = reading;
  const TraversabilityLayers layers = traversability(choice.grid, GroundModel(choice.ground), tp);
  if (!o.costmap.empty()) {
    write_costmap_pgm(o.costmap, layers);
    std::size_t lethal = 0, free_cells = 0, unknown = 0;
    for (const std::uint8_t c : layers.cost) {
      lethal += c == 100 ? 1 : 0;
      free_cells += c == 0 ? 1 : 0;
      unknown += c == TraversabilityLayers::kUnknown ? 1 : 0;
    }
    std::printf("wrote %s.pgm + .yaml (Nav2 scale mode): %zu lethal, %zu free, %zu between, %zu unknown (written lethal) "
                "cells of %.3f m; lethal from p > %.2f, a step of %.2f m or a slope of %.1f deg, no grid cost from "
                "p <= %.3g, inflation %.2f m\n",
                std::filesystem::path(o.costmap).replace_extension().string().c_str(), lethal, free_cells,
                layers.cost.size() - lethal - free_cells - unknown, unknown, layers.cell_size, tp.reading.occupied_above, tp.max_step,
                tp.max_slope_deg, tp.reading.free_at_most, tp.inflation_radius);
  }
  if (!o.geotiff.empty()) {
    std::size_t with_ground = 0;
    for (const float z : layers.ground_z) with_ground += std::isnan(z) ? 0 : 1;
    if (with_ground == 0) throw Error(o.map + ": the map has no ground patch, no ground height to write to " + o.geotiff);
    write_ground_geotiff(o.geotiff, layers);
    std::printf("wrote %s: ground height of %zu cells (%d x %d pixels of %.3f m, NaN elsewhere)\n", o.geotiff.c_str(),
                with_ground, layers.width, layers.height, layers.cell_size);
  }
}

void run_export(const ExportOptions& o) {
  if (o.ply.empty() && o.bt.empty() && o.pgm.empty() && o.costmap.empty() && o.geotiff.empty() && o.mcap.empty()) {
    throw Error("nothing to export: give --ply OUT.ply, --bt OUT.bt, --pgm OUT, --costmap OUT, --geotiff OUT.tif and/or --mcap OUT.mcap");
  }
  validate(o.traversability);
  if (o.z_step != 0.0 && !(o.z_step >= 1e-3 && o.z_step <= 100.0)) {
    throw Error(format("--z-step = %g m is out of its range [0.001, 100] m", o.z_step));
  }
  if (o.ground_iterations != 0 && !(o.ground_iterations > 0 && o.ground_iterations <= 100000)) {
    throw Error("--ground-iterations = " + std::to_string(o.ground_iterations) + " is out of its range [1, 100000]");
  }
  // Every output checked before the map is read and the work done.
  if (!o.ply.empty()) check_output_extension(o.ply, {".ply"}, "--ply writes a PLY file");
  if (!o.bt.empty()) check_output_extension(o.bt, {".bt"}, "--bt writes an OctoMap binary tree");
  if (!o.geotiff.empty()) check_output_extension(o.geotiff, {".tif", ".tiff"}, "--geotiff writes a GeoTIFF");
  if (!o.ply.empty()) check_output_file(o.ply);
  if (!o.bt.empty()) check_output_file(o.bt);
  if (!o.pgm.empty()) {
    for (const char* ext : {".pgm", ".yaml"}) check_output_file(pgm_stem(o.pgm).concat(ext));
  }
  if (!o.costmap.empty()) {
    for (const char* ext : {".pgm", ".yaml"}) check_output_file(pgm_stem(o.costmap).concat(ext));
  }
  if (!o.geotiff.empty()) check_output_file(o.geotiff);
  if (!o.mcap.empty()) check_mcap_output(o.mcap);
  if (!o.trajectory.empty() && o.mcap.empty()) throw Error("--trajectory goes with --mcap (the poses as /trajectory)");
  // Stamps from a TUM file, or from times.txt beside a KITTI file (KITTI's layout); else none.
  const PoseFile trajectory = o.trajectory.empty() ? PoseFile{} : read_stamped_pose_file(o.trajectory);
  if (!o.mcap.empty()) check_mcap_stamps(trajectory.times, o.trajectory);
  MapFile file = load_map_file(o.map);
  const HMap& map = file.map;
  // The .bt's free leaves come from the exported grid when the map holds one and its ground.
  const bool bt_free = !o.bt.empty() && file.grid && file.grid->known_cells() > 0 && !file.ground.empty();
  std::optional<GridChoice> chosen;
  if (!o.pgm.empty() || !o.costmap.empty() || !o.geotiff.empty() || !o.mcap.empty() || bt_free) chosen = choose_grid(file, o);
  if (!o.mcap.empty()) write_map_mcap(o.mcap, map, &chosen->grid, trajectory.poses, trajectory.times);
  if (!o.pgm.empty() || !o.costmap.empty() || !o.geotiff.empty()) {
    const GridChoice& choice = *chosen;
    // Free from one clear ground pass on (p <= K_g), occupied above 0.65: the PGM, its counts and
    // the costmap all read the grid so.
    const GridReading reading = GridReading::for_map(map.params().occupancy);
    if (!o.pgm.empty()) {
      PgmExportParams pgm;
      pgm.reading = reading;
      write_pgm_map(o.pgm, choice.grid, pgm);
      const auto [occupied, free_cells] = count_classes(choice.grid, pgm);
      std::printf("wrote %s.pgm + .yaml: %zu occupied (p > %.2f) and %zu free (p <= %.3g) cells of %.3f m, %s\n",
                  std::filesystem::path(o.pgm).replace_extension().string().c_str(), occupied, pgm.reading.occupied_above,
                  free_cells, pgm.reading.free_at_most, map.cell_size(), choice.what.c_str());
    }
    if (!o.costmap.empty() || !o.geotiff.empty()) export_traversability(choice, o, reading);
  }
  if (o.ply.empty() && o.bt.empty()) return;
  if (!o.bt.empty()) {
    const std::vector<FreeBand> free = chosen ? free_bands(chosen->grid, chosen->ground, map.params().occupancy.z_plus) : std::vector<FreeBand>{};
    const OctomapExportStats bt = write_octomap_bt(o.bt, map, free, memory_budget());
    std::printf("wrote %zu occupied and %zu free voxels of %.3f m to %s: %zu OctoMap leaves after pruning%s\n",
                bt.occupied_voxels, bt.free_voxels, map.cell_size(), o.bt.c_str(), bt.leaves,
                chosen ? format("; free: the 2D grid's free cells from the ground up to %.2f m (occupancy.z_plus)",
                                map.params().occupancy.z_plus)
                             .c_str()
                       : "; no free leaves: the map holds no 2D grid and ground patches (built with --hvoxels-only)");
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
  auto* cmd = app.add_subcommand("export", "Write a map as PLY (HVoxel boxes, or the recovered points), an OctoMap .bt, a 2D grid, a costmap, a ground GeoTIFF or an MCAP for Foxglove");
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
  cmd->add_option("--costmap", opts->costmap,
                  "Output traversability cost (occupancy, ground step and slope) as a Nav2 costmap-style PGM + YAML "
                  "(mode: scale; OUT.pgm, OUT.yaml)");
  cmd->add_option("--geotiff", opts->geotiff, "Output ground height as a GeoTIFF (Float32, NaN without ground) for QGIS / grid_map");
  cmd->add_option("--max-step", opts->traversability.max_step, "[m] with --costmap: a ground step this high is lethal")
      ->capture_default_str();
  cmd->add_option("--max-slope", opts->traversability.max_slope_deg, "[deg] with --costmap: ground this steep is lethal")
      ->capture_default_str();
  cmd->add_option("--inflation", opts->traversability.inflation_radius,
                  "[m] with --costmap: lethal cells raise the cost within this radius (99 exp(-3 d))")
      ->capture_default_str();
  cmd->add_option("--mcap", opts->mcap,
                  "Output MCAP recording for Foxglove (OUT.mcap): /map nav_msgs/OccupancyGrid (the --pgm grid), /grid "
                  "foxglove.Grid, /tf, /hvoxels foxglove.SceneUpdate cubes coloured by height, /points foxglove.PointCloud; "
                  "stamped with --trajectory's times (else 0)");
  cmd->add_option("--trajectory", opts->trajectory,
                  "With --mcap: poses file (KITTI or TUM, in the map frame, as render draws them) written as /trajectory "
                  "foxglove.PosesInFrame and as one /tf (map -> sensor) per pose at its stamp, for playing the drive back. "
                  "Stamps: a TUM file's own; for a KITTI file, times.txt in the same folder (one line per pose) when "
                  "there is one, else all 0. The map's messages take the latest stamp");
  cmd->add_option("--bt", opts->bt, "Output OctoMap binary tree (.bt), for octovis and the octomap tools");
  cmd->add_flag("--points", opts->points, "Write the height-upsampled point cloud instead of boxes");
  cmd->add_option("--z-step", opts->z_step, "Vertical spacing of recovered points [m] (default: the cell size)");
  cmd->callback([opts] { run_export(*opts); });
}

}  // namespace hmap::cli
