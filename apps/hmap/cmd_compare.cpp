// hmap compare: the paper's comparison, measured. The hybrid HMAP, the 2.5D pipeline of [9] and
// an OctoMap built from the same scans; side-by-side pictures in the manner of the paper's Fig. 5/6
// and, when the truth is known (a simulated sequence), 3D and 2D accuracy tables.

#include <octomap/OcTree.h>

#include <cstdio>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "cli_common.hpp"
#include "hmap/baseline/elevation_mapper.hpp"
#include "hmap/baseline/elevation_occupancy.hpp"
#include "hmap/baseline/octomap_projection.hpp"
#include "hmap/core/error.hpp"
#include "hmap/eval/grid_metrics.hpp"
#include "hmap/core/format.hpp"
#include "hmap/eval/map_metrics.hpp"
#include "hmap/io/atomic_file.hpp"
#include "hmap/io/cloud_reader.hpp"
#include "hmap/io/hmap_file.hpp"
#include "hmap/io/png.hpp"
#include "hmap/occupancy/hybrid_mapper.hpp"
#include "hmap/render/render.hpp"

namespace hmap::cli {

namespace {

struct CompareOptions : InputOptions {
  ParamOptions params;
  std::string truth;
  std::optional<double> robot_height;
  std::optional<double> elevation_ceiling;
  int max_pixels = 900;
  bool skip_octomap = false;
  bool json = false;
  std::string out;
};

/// One system's numbers.
struct SystemResult {
  std::string name;
  double ms_per_scan = 0.0;
  std::size_t memory_bytes = 0;
  std::optional<MapMetrics> metrics;
};

/// The 2.5D map drawn as solid columns from the lowest point seen to the elevation (what a
/// 2.5D map asserts: everything below the surface is filled).
HMap elevation_display(const ElevationMap& elevation) {
  HMap map(elevation.params());
  elevation.for_each_cell([&](const CellKey& key, const ElevationCell& c) {
    if (std::isnan(c.elevation)) return;
    const float low = std::isnan(c.lowest) ? c.elevation : std::min(c.lowest, c.elevation);
    map.column_for_update(key).push_back({low, c.elevation, 1.0F, 1.0F});
  });
  return map;
}

/// The map with everything above `z_cut` left out (HVoxels clipped there): the top views show
/// what lies under the ceiling, as the 2.5D map sees it.
HMap cut_above(const HMap& map, double z_cut) {
  HMap out(map.params());
  const auto cut = static_cast<float>(z_cut);
  map.for_each_column([&](const CellKey& key, const ColumnView& c) {
    bool any = false;
    for (const HVoxel& v : c) any = any || v.z_min <= cut;
    if (!any) return;
    TileColumn column = out.column_for_update(key);
    for (const HVoxel& v : c) {
      if (v.z_min > cut) break;
      HVoxel clipped = v;
      clipped.z_max = std::min(v.z_max, cut);
      column.push_back(clipped);
    }
  });
  return out;
}

nlohmann::json grid_json(const GridScores& s) {
  return {{"cells_compared", s.compared}, {"accuracy", s.accuracy()}, {"blocked_cells", s.blocked},
          {"blocked_recall", s.blocked_recall()}, {"free_cells", s.free}, {"free_recall", s.free_recall()},
          {"overhang_cells", s.overhang}, {"overhang_free", s.overhang_accuracy()}};
}

/// The three maps grow with the area seen: checked against the memory budget after scan `k`.
void check_compare_memory(const ScanSource& src, std::size_t k, const HybridMapper& hybrid, const ElevationMapper& elevation,
                          const octomap::OcTree* octree) {
  double bytes = static_cast<double>(hybrid.map().memory_bytes() + hybrid.grid().memory_bytes() + elevation.map().memory_bytes());
  if (octree != nullptr) {
    // OctoMap's own count walks the tree; a bound from its node count (each node with a children
    // array) is O(1), and the walk is done only when that bound does not fit.
    const double bound = static_cast<double>(octree->size()) * static_cast<double>(octree->memoryUsageNode() + 8 * sizeof(void*));
    const bool bound_fits = bytes + bound <= static_cast<double>(memory_budget().bytes);
    bytes += bound_fits ? bound : static_cast<double>(octree->memoryUsage());
  }
  for_scan(src, k, [&] { memory_budget().require(bytes, "the comparison"); });
}

/// Compares on the scans of `src`, writing the files into `dir`.
void compare_into(const CompareOptions& o, const Params& params, const ScanSource& src, const std::filesystem::path& dir);

void run_compare(const CompareOptions& o) {
  const Params params = o.params.resolve();
  const ScanSource src = o.open_inputs(/*poses_required=*/true);
  if (src.scans.empty()) throw Error("no scans to compare on");
  prepare_output_set(o.out, {"hmap.hmap", "compare_top.png", "compare_oblique.png", "report.md", "report.json"}, "compare");
  // The map, pictures and reports are one set: a kill leaves the old folder or the new one.
  write_folder_atomic(o.out, [&](const std::filesystem::path& dir) { compare_into(o, params, src, dir); });
}

void compare_into(const CompareOptions& o, const Params& params, const ScanSource& src, const std::filesystem::path& dir) {
  const PoseList& poses = *src.T_map_scan;

  // The same scans, once read, into the three systems.
  HybridMapper hybrid(params);
  // Like elevation_mapping's ignore_points_above: without it the 2.5D map of a room is its ceiling.
  ElevationParams elevation_params;
  elevation_params.max_height_above_sensor = o.elevation_ceiling.value_or(params.occupancy.z_plus);
  // The top views leave out what lies above the same cut, at the sensor's median height.
  std::vector<double> sensor_z;
  for (const Pose& T : poses) sensor_z.push_back(T.translation().z());
  std::nth_element(sensor_z.begin(), sensor_z.begin() + static_cast<std::ptrdiff_t>(sensor_z.size() / 2), sensor_z.end());
  const double z_cut = sensor_z[sensor_z.size() / 2] + elevation_params.max_height_above_sensor;
  ElevationMapper elevation(params, elevation_params);
  octomap::OcTree octree(params.map.cell_size);
  SystemResult r_hmap{"HMAP", 0.0, 0, std::nullopt};
  SystemResult r_25d{"2.5D [9]", 0.0, 0, std::nullopt};
  SystemResult r_octo{"OctoMap", 0.0, 0, std::nullopt};
  PointCloud cloud_map;  // every kept point in the map frame, for the point-cloud panel
  CloudReadStats read_stats;
  Progress progress("comparing", src.scans.size());
  const double min2 = params.map.min_range * params.map.min_range;
  const double max2 = params.map.max_range * params.map.max_range;
  for (std::size_t k = 0; k < src.scans.size(); ++k) {
    const PointCloud cloud = src.read(k, read_stats);
    const Pose& T = poses[k];
    auto t0 = Clock::now();
    hybrid.integrate(cloud, T);
    r_hmap.ms_per_scan += ms_since(t0);
    t0 = Clock::now();
    elevation.integrate(cloud, T);
    r_25d.ms_per_scan += ms_since(t0);
    octomap::Pointcloud octo_cloud;
    octo_cloud.reserve(cloud.size());
    for (std::size_t n = 0; n < cloud.size(); ++n) {
      const Point3f& p = cloud[n];
      const double r2 = p.cast<double>().squaredNorm();
      if (!p.allFinite() || r2 < min2 || r2 > max2) continue;
      const Eigen::Vector3d q = T * p.cast<double>();
      octo_cloud.push_back(static_cast<float>(q.x()), static_cast<float>(q.y()), static_cast<float>(q.z()));
      if (n % 4 == 0 && q.z() <= z_cut) cloud_map.push_back(q.cast<float>());
    }
    const Eigen::Vector3d origin = T.translation();
    if (o.skip_octomap) {
      check_compare_memory(src, k, hybrid, elevation, nullptr);
      progress.update(k + 1, r_hmap.ms_per_scan / static_cast<double>(k + 1));
      continue;
    }
    t0 = Clock::now();
    octree.insertPointCloud(octo_cloud, octomap::point3d(static_cast<float>(origin.x()), static_cast<float>(origin.y()),
                                                         static_cast<float>(origin.z())),
                            params.map.max_range);
    r_octo.ms_per_scan += ms_since(t0);
    check_compare_memory(src, k, hybrid, elevation, &octree);
    progress.update(k + 1, r_hmap.ms_per_scan / static_cast<double>(k + 1));
  }
  progress.finish();
  // The 2D grid of [9]: ground patches on the 2.5D map, grown along the same trajectory.
  const auto t_ground = Clock::now();
  const HMap elevation_hmap = as_hmap(elevation.map());
  GroundTracker ground_25d(params.ground);
  for (const Pose& T : poses) ground_25d.update(elevation_hmap, T.translation(), params.map.max_range);
  const OccupancyGrid grid_25d =
      occupancy_from_elevation(elevation.map(), ground_25d.model(), params, params.occupancy.ground_reach);
  r_25d.ms_per_scan += ms_since(t_ground);
  // Beside the grid kept scan by scan (eq. 3-4 along the rays, the paper's), the grid judged from
  // the finished map column by column with the same ground patches, as the 2.5D grid of [9] is:
  // the same question put to both representations.
  const OccupancyGrid grid_final = occupancy_from_map(hybrid.map(), hybrid.ground(), params, params.occupancy.ground_reach);
  // Both together, as a planner would want them: each cell the more occupied of the two.
  const OccupancyGrid grid_fused = more_occupied(hybrid.grid(), grid_final);
  const auto n = static_cast<double>(src.scans.size());
  for (SystemResult* r : {&r_hmap, &r_25d, &r_octo}) r->ms_per_scan /= n;
  r_hmap.memory_bytes = hybrid.map().stats().memory_bytes + hybrid.grid().memory_bytes();
  r_25d.memory_bytes = elevation.map().memory_bytes() + grid_25d.memory_bytes();
  r_octo.memory_bytes = octree.memoryUsage();
  save_hmap(dir / "hmap.hmap", hybrid.map(), hybrid.ground_patches(), &hybrid.grid());

  // Pictures: Fig. 5/6's five columns, top-down and oblique.
  const MapStats st = hybrid.map().stats();
  if (st.hvoxels == 0) throw Error("the HMAP of these scans is empty: nothing to compare");
  const HMap hmap_cut = cut_above(hybrid.map(), z_cut);
  if (hmap_cut.stats().hvoxels == 0) throw Error("nothing of the map lies below the display cut at z = " + std::to_string(z_cut) + " m");
  const render::HeightRange range = render::resolve_range(hmap_cut, {});
  const render::TopViewport vp = render::viewport_over(st.bounds.min().x(), st.bounds.min().y(), st.bounds.max().x(),
                                       st.bounds.max().y(), params.map.cell_size, o.max_pixels);
  const HMap display_25d = elevation_display(elevation.map());
  const GridReading reading = GridReading::for_map(params.occupancy);
  const RgbImage top = render::side_by_side({{"I point cloud", render::render_points_top(cloud_map, range, vp)},
                                     {"II HMAP", render::render_top_in(hmap_cut, range, vp)},
                                     {"III HMAP 2D grid, kept scan by scan", render::render_occupancy(hybrid.grid(), vp, reading)},
                                     {"IIIb HMAP 2D grid judged from the final map", render::render_occupancy(grid_final, vp, reading)},
                                     {"IV 2.5D", render::render_top_in(display_25d, range, vp)},
                                     {"V 2D grid of the 2.5D map", render::render_occupancy(grid_25d, vp, reading)}});
  const auto out = [&](const char* name) { return (dir / name).string(); };
  write_png(out("compare_top.png"), top);
  const int oblique_px = std::max(300, o.max_pixels * 2 / 3);
  write_png(out("compare_oblique.png"), render::side_by_side({{"II HMAP", render::render_oblique(hmap_cut, range, oblique_px)},
                                                      {"IV 2.5D", render::render_oblique(display_25d, range, oblique_px)}}));

  // Accuracy against the truth, when given.
  nlohmann::json report;
  report["scans"] = src.scans.size();
  report["cell_size_m"] = params.map.cell_size;
  const double robot_height = o.robot_height.value_or(params.occupancy.z_plus);
  std::optional<GridScores> g_hmap, g_hmap_final, g_hmap_fused, g_25d, g_octo;
  if (!o.truth.empty()) {
    const std::filesystem::path truth_dir(o.truth);
    const auto seen_path = truth_dir / "truth_seen.ply";
    const auto surface_path = truth_dir / "truth.ply";
    if (!std::filesystem::exists(seen_path) || !std::filesystem::exists(surface_path)) {
      throw Error(o.truth + ": expected truth.ply and truth_seen.ply (as `hmap simulate` writes them)");
    }
    const PointCloud seen = read_cloud(seen_path);
    const PointCloud surface = read_cloud(surface_path);
    // The walkable ground apart (written by `hmap simulate` since 2026-12-02): without it the local
    // ground is the lowest surface point around, which a buried kerb face pulls down.
    const auto ground_path = truth_dir / "truth_ground.ply";
    const PointCloud truth_ground = std::filesystem::exists(ground_path) ? read_cloud(ground_path) : PointCloud{};
    r_hmap.metrics = evaluate_map(hybrid.map(), seen);
    r_25d.metrics = evaluate_map(elevation_hmap, seen);
    if (!o.skip_octomap) r_octo.metrics = evaluate_map(octomap_as_hmap(octree, params), seen);
    TraversabilityTruthParams truth_params;
    truth_params.cell_size = params.map.cell_size;
    truth_params.step = 2.0 * params.occupancy.ground_distance;
    truth_params.robot_height = robot_height;
    truth_params.overhang_cut = z_cut;
    const TrueTraversability truth_2d = true_traversability(surface, truth_ground, truth_params);
    // Scored on the cells both grids decided and the truth knows: the same cells for both.
    const auto both = [&](const CellKey& key) {
      return hybrid.grid().probability_at(key).has_value() && grid_25d.probability_at(key).has_value();
    };
    // Every grid read as export --pgm writes a map: free from p <= K_g, occupied above 0.65.
    const GridReading read_as = GridReading::for_map(params.occupancy);
    g_hmap = score_grid(hybrid.grid(), truth_2d, both, read_as);
    g_hmap_final = score_grid(grid_final, truth_2d, both, read_as);
    g_hmap_fused = score_grid(grid_fused, truth_2d, both, read_as);
    g_25d = score_grid(grid_25d, truth_2d, both, read_as);
    if (!o.skip_octomap) {
      // What a ROS user gets from this OctoMap: octomap_server's projection of the band between
      // the step and the robot's height, over the same local ground as HMAP's grid.
      OctomapProjectionParams band;
      band.min_height = truth_params.step;
      band.max_height = robot_height;
      band.ground_reach = params.occupancy.ground_reach;
      g_octo = score_grid(project_octomap(octree, hybrid.ground(), params.map.cell_size, params.occupancy, band), truth_2d,
                          both, read_as);
    }
  }

  // The report.
  std::ostringstream md;
  md << "# HMAP vs 2.5D vs OctoMap\n\n" << src.scans.size() << " scans, cell " << params.map.cell_size
     << " m, range " << params.map.min_range << "-" << params.map.max_range << " m.\n\n";
  md << "| system | ms per scan | memory | 3D precision (exact / 1 voxel) | 3D recall (exact / 1 voxel) | Chamfer [m] |\n";
  md << "| --- | --- | --- | --- | --- | --- |\n";
  std::vector<const SystemResult*> systems{&r_hmap, &r_25d};
  if (!o.skip_octomap) systems.push_back(&r_octo);
  for (const SystemResult* r : systems) {
    std::string line;
    if (r->metrics) {
      line = format("| %s | %.2f | %s | %.3f / %.3f | %.3f / %.3f | %.3f |\n", r->name.c_str(),
                    r->ms_per_scan, human_bytes(static_cast<double>(r->memory_bytes)).c_str(),
                    r->metrics->exact.precision, r->metrics->tolerant.precision, r->metrics->exact.recall,
                    r->metrics->tolerant.recall, r->metrics->chamfer.chamfer_m);
    } else {
      line = format("| %s | %.2f | %s | - | - | - |\n", r->name.c_str(), r->ms_per_scan,
                    human_bytes(static_cast<double>(r->memory_bytes)).c_str());
    }
    md << line;
    nlohmann::json j{{"ms_per_scan", r->ms_per_scan}, {"memory_bytes", r->memory_bytes}};
    if (r->metrics) {
      j["precision_exact"] = r->metrics->exact.precision;
      j["precision_1voxel"] = r->metrics->tolerant.precision;
      j["recall_exact"] = r->metrics->exact.recall;
      j["recall_1voxel"] = r->metrics->tolerant.recall;
      j["chamfer_m"] = r->metrics->chamfer.chamfer_m;
    }
    report["systems"][r->name] = j;
  }
  md << "\nms per scan of 2.5D includes its ground extraction and 2D grid, run once at the end and divided by the scans; "
        "HMAP's includes its per-scan ground tree and 2D grid update. 3D scores: voxels of the cell size against the "
        "surface the sensor saw (truth_seen.ply); the 2.5D map as one HVoxel per cell at its elevation; OctoMap's "
        "occupied leaves.\n";
  // Every score as one JSON line per system and grid (--json), the same numbers as the tables.
  std::vector<nlohmann::json> lines;
  for (const SystemResult* r : systems) {
    nlohmann::json j = report["systems"][r->name];
    j["system"] = r->name;
    j["grid"] = "3d";
    lines.push_back(std::move(j));
  }
  if (g_hmap && g_hmap_final && g_hmap_fused && g_25d) {
    struct Row {
      const char* system;
      const char* grid;
      const char* label;
      const char* key;  // in report.json
      const GridScores* scores;
    };
    std::vector<Row> rows{{"HMAP", "kept", "HMAP, eq. 3-4 scan by scan", "hmap", &*g_hmap},
                          {"HMAP", "judged", "HMAP, judged from the final map", "hmap_final", &*g_hmap_final},
                          {"HMAP", "both", "HMAP, both (the more occupied; what export --pgm writes)", "hmap_fused",
                           &*g_hmap_fused},
                          {"2.5D [9]", "judged", "2.5D [9], judged from the final map", "elevation_25d", &*g_25d}};
    if (g_octo) {
      rows.push_back({"OctoMap", "projected", "OctoMap, projected as octomap_server does", "octomap_projected", &*g_octo});
    }
    md << "\n## 2D occupancy against the true traversability (robot " << robot_height << " m tall, steps over "
       << 2.0 * params.occupancy.ground_distance << " m block)\n\n";
    md << "| 2D grid | cells compared | accuracy | blocked found | free found | free under overhangs |\n| --- | --- | --- | --- | --- | --- |\n";
    report["grid_2d"] = {{"robot_height_m", robot_height}};
    for (const Row& row : rows) {
      const GridScores& g = *row.scores;
      md << format("| %s | %zu | %.3f | %.3f (%zu) | %.3f (%zu) | %.3f (%zu) |\n", row.label, g.compared,
                   g.accuracy(), g.blocked_recall(), g.blocked, g.free_recall(), g.free, g.overhang_accuracy(),
                   g.overhang);
      nlohmann::json j = grid_json(g);
      report["grid_2d"][row.key] = j;
      j["system"] = row.system;
      j["grid"] = row.grid;
      j["blocked_found"] = g.blocked_recall();
      j["free_found"] = g.free_recall();
      j["overhang_free"] = g.overhang_accuracy();
      lines.push_back(std::move(j));
    }
    md << "\nCells both HMAP's kept grid and the 2.5D grid observed where the truth has a surface, each grid "
          "scored on those it decided as export --pgm writes them (occupied above 0.65, free from p <= K_g). Overhang cells: free "
          "ground under something higher than the robot and below the 2.5D map's cut (table tops, tree crowns, low "
          "ceilings). The OctoMap row: occupied leaves whose centre lies between the step and the robot's height "
          "above the local ground (HMAP's ground patches) make a cell occupied, free leaves there free.\n";
  }
  md << format(
                "\nPictures: compare_top.png (I point cloud, II HMAP, III HMAP 2D scan by scan, IIIb HMAP 2D judged from "
                "the final map, IV 2.5D, V 2.5D 2D; 2D grids as "
                "map_server reads them: free white, occupied black, unknown grey) and compare_oblique.png. The 3D "
                "views leave out what lies above z = %.2f m (the 2.5D map's cut, %.2f m above the sensor's median "
                "height).\n",
                z_cut, elevation_params.max_height_above_sensor);
  report["display_cut_z_m"] = z_cut;
  write_file_atomic(out("report.md"), [&](std::ostream& f) { f << md.str(); });
  write_file_atomic(out("report.json"), [&](std::ostream& f) { f << report.dump(2) << '\n'; });
  if (o.json) {
    for (const nlohmann::json& j : lines) std::printf("%s\n", j.dump().c_str());
  } else {
    std::fputs(md.str().c_str(), stdout);
  }
}

}  // namespace

void add_compare_command(CLI::App& app) {
  auto opts = std::make_shared<CompareOptions>();
  auto* cmd = app.add_subcommand("compare", "Build HMAP, the 2.5D map of [9] and OctoMap from the same scans; pictures and tables");
  opts->add_input_options(*cmd, kKnownPosesHelp);
  cmd->add_option("--truth", opts->truth, "Folder with truth.ply and truth_seen.ply (a `hmap simulate` output)");
  cmd->add_option("--robot-height", opts->robot_height, "[m] for the true traversability (default occupancy.z_plus)");
  cmd->add_option("--elevation-ceiling", opts->elevation_ceiling,
                  "[m] above the sensor: higher points are left out of the 2.5D map (default occupancy.z_plus)");
  cmd->add_option("--max-pixels", opts->max_pixels, "Largest side of each top-view panel")->capture_default_str();
  cmd->add_flag("--skip-octomap", opts->skip_octomap, "Leave OctoMap out (it takes most of the time)");
  cmd->add_flag("--json", opts->json,
                "Print every score as JSON lines (one per system and grid: system, grid, blocked_found, free_found, "
                "overhang_free, accuracy, ...) instead of the report");
  cmd->add_option("--out,-o", opts->out, "Output folder")->required();
  opts->params.add_to(*cmd);
  cmd->callback([opts] { run_compare(*opts); });
}

}  // namespace hmap::cli
