// hmap pvox: build a probabilistically voxelated grid map (PVOX) from scans, registering each
// with the recursive Bayesian filter, and write the map, pictures and a summary.

#include <algorithm>
#include <array>
#include <string_view>
#include <cmath>
#include <cstdio>
#include <limits>
#include <nlohmann/json.hpp>

#include "cli_common.hpp"
#include "hmap/core/error.hpp"
#include "hmap/io/atomic_file.hpp"
#include "hmap/io/poses.hpp"
#include "hmap/pvox/mapper.hpp"
#include "pvox_output.hpp"

namespace hmap::cli {

namespace {

struct PvoxOptions : InputOptions {
  std::string odometry;
  std::string filter = "rbf";
  std::string measure = "auto";
  std::optional<double> edge;
  double k = 6.0;
  double min_range = 0.1;
  double max_range = 60.0;
  double motion_variance_mm2 = 2000.0;
  double measurement_variance_mm2 = 100.0;
  bool free_space = false;
  bool raw_csv = false;
  std::string out;
};

/// What a pvox run writes into its folder: the folder is replaced as a whole, so one that holds
/// anything else is refused before the work instead of losing it.
/// Maps the scans of `src` with `mapper` and writes the folder's files into `dir`.
void write_pvox_run(const PvoxOptions& o, const ScanSource& src, pvox::PvoxMapper& mapper, const PoseList* command_source,
                    bool use_poses, const std::filesystem::path& dir);

void run_pvox(const PvoxOptions& o) {
  // The folder's files are one set (the map, its CSV, pictures and summary): written into a
  // staging folder and swapped in at the end, so that a kill leaves the old set or the new one.
  prepare_output_set(o.out, {"map.pvox", "voxels.csv", "points.csv", "summary.json", "map_top.png", "map_iso.png", "map_gradient.png"},
                     "pvox");  // before the work
  const ScanSource src = o.open_inputs(/*poses_required=*/false);
  std::optional<PoseList> odometry;
  if (!o.odometry.empty()) {
    odometry = read_poses(o.odometry);
    if (odometry->size() < src.scans.size()) {
      throw InputError(o.odometry, "", "holds " + std::to_string(odometry->size()) + " poses for " +
                                           std::to_string(src.scans.size()) + " scans");
    }
  }
  const bool use_poses = o.measure == "poses" || (o.measure == "auto" && src.T_map_scan.has_value());
  if (use_poses && !src.T_map_scan) throw Error("--measure poses needs --poses FILE or a KITTI folder with poses.txt");

  pvox::PvoxParams params;
  params.filter.kind = o.filter == "brf" ? pvox::FilterKind::kNaive : pvox::FilterKind::kRecursive;
  params.filter.motion_variance = o.motion_variance_mm2 * 1e-6;
  params.filter.initial_variance = o.motion_variance_mm2 * 1e-6;
  params.filter.measurement_variance = o.measurement_variance_mm2 * 1e-6;
  params.probability.measurement_variance = o.measurement_variance_mm2 * 1e-6;
  params.k_sigma = o.k;
  params.fixed_edge = o.edge.value_or(0.0);
  params.insert.min_range = o.min_range;
  params.insert.max_range = o.max_range;
  params.insert.free_space = o.free_space ? pvox::FreeSpace::kRays : pvox::FreeSpace::kOff;
  params.budget = memory_budget();
  pvox::PvoxMapper mapper(params);

  // Commands: the odometry's relative motions, else those of the given poses, else standing still.
  const PoseList* command_source = odometry ? &*odometry : src.T_map_scan ? &*src.T_map_scan : nullptr;
  write_folder_atomic(o.out, [&](const std::filesystem::path& dir) {
    write_pvox_run(o, src, mapper, command_source, use_poses, dir);
  });
}

void write_pvox_run(const PvoxOptions& o, const ScanSource& src, pvox::PvoxMapper& mapper, const PoseList* command_source,
                    bool use_poses, const std::filesystem::path& dir) {
  PointCloud raw_points;
  std::vector<double> ms;
  std::vector<pvox::RegistrationResult> results;
  Progress progress("pvox", src.scans.size());
  std::size_t points = 0;
  for (std::size_t k = 0; k < src.scans.size(); ++k) {
    CloudReadStats stats;
    const PointCloud cloud = src.read(k, stats);
    Pose command = Pose::Identity();
    if (command_source != nullptr) {
      command = k == 0 ? (*command_source)[0] : (*command_source)[k - 1].inverse() * (*command_source)[k];
    }
    std::optional<Eigen::Vector2d> measured;
    if (use_poses) measured = (*src.T_map_scan)[k].translation().head<2>();
    const auto t0 = Clock::now();
    results.push_back(for_scan(src, k, [&] { return mapper.add_scan(cloud, command, measured); }));
    ms.push_back(ms_since(t0));
    points += cloud.size();
    if (o.raw_csv) {
      for (const Point3f& p : cloud) raw_points.push_back((results.back().T_map_sensor * p.cast<double>()).cast<float>());
    }
    progress.update(k + 1, ms.back());
  }
  progress.finish();
  const auto& map = mapper.map();
  const PvoxFileSizes sizes = write_pvox_files(dir, "", map, o.raw_csv ? &raw_points : nullptr);
  const render::PvoxView view = render::bulk_view(map);
  // The gradient slice: 1 m above the lowest tenth of the occupied voxels (about the ground).
  const auto occupied = map.occupied();
  double slice = std::numeric_limits<double>::quiet_NaN();
  if (!occupied.empty()) {
    std::vector<double> z;
    for (const auto& v : occupied) z.push_back(v.centre.z());
    std::nth_element(z.begin(), z.begin() + static_cast<std::ptrdiff_t>(z.size() / 10), z.end());
    slice = map.centre(map.key_of(Eigen::Vector3d(0.0, 0.0, z[z.size() / 10] + 1.0))).z();
  }
  write_pvox_pictures(dir, "map_", map, view, slice);

  nlohmann::json summary;
  summary["scans"] = src.scans.size();
  summary["points"] = points;
  summary["filter"] = o.filter;
  summary["measurement"] = use_poses ? "poses" : "alignment";
  summary["edge_m"] = map.edge();
  summary["voxels"] = map.voxel_count();
  summary["occupied_voxels"] = occupied.size();
  summary["memory_bytes"] = map.memory_bytes();
  summary["sizes_bytes"] = {{"raw_csv", sizes.raw_csv}, {"voxel_csv", sizes.voxel_csv}, {"binary", sizes.binary}};
  summary["registrations"] = nlohmann::json::array();
  for (std::size_t k = 0; k < results.size(); ++k) {
    const auto& r = results[k];
    const Eigen::Vector3d t = r.T_map_sensor.translation();
    summary["registrations"].push_back({{"scan", k},
                                        {"ms", ms[k]},
                                        {"x", t.x()},
                                        {"y", t.y()},
                                        {"posterior_variance_m2", r.posterior_variance.maxCoeff()},
                                        {"edge_m", r.edge},
                                        {"measured_by_alignment", r.measured_by_alignment},
                                        {"alignment_valid", r.align.valid},
                                        {"alignment_iterations", r.align.iterations}});
  }
  write_file_atomic(dir / "summary.json", summary.dump(2) + "\n");
  double total_ms = 0.0;
  for (const double m : ms) total_ms += m;
  // Told with the result, not before the work: an error stays the one line of its run.
  if (!src.description.empty()) std::printf("input: %s\n", src.description.c_str());
  std::printf("pvox: %zu scans, %s points, edge %.1f mm, %zu voxels (%zu occupied), %.0f ms per scan; "
              "map.pvox %s, voxels.csv %s%s; wrote %s\n",
              src.scans.size(), human_count(static_cast<double>(points)).c_str(), map.edge() * 1000.0, map.voxel_count(),
              occupied.size(), ms.empty() ? 0.0 : total_ms / static_cast<double>(ms.size()),
              human_bytes(static_cast<double>(sizes.binary)).c_str(), human_bytes(static_cast<double>(sizes.voxel_csv)).c_str(),
              o.raw_csv ? (", points.csv " + human_bytes(static_cast<double>(sizes.raw_csv))).c_str() : "", o.out.c_str());
}

}  // namespace

void add_pvox_command(CLI::App& app) {
  auto o = std::make_shared<PvoxOptions>();
  auto* cmd = app.add_subcommand("pvox", "Build a probabilistically voxelated 3D grid map (PVOX) with Kalman-filter registration");
  o->add_input_options(*cmd, "Measured poses (KITTI or TUM), one per scan: the filter's measurements");
  // The name it had before the input options were shared; --scans is the common one.
  cmd->add_option("--max-scans", o->scans, "The same as --scans")->check(kCount);
  cmd->add_option("--odometry", o->odometry, "Odometry poses (KITTI or TUM): their relative motions are the commands");
  cmd->add_option("--filter", o->filter, "rbf (recursive) or brf (naive, first variance kept)")
      ->check(CLI::IsMember({"rbf", "brf"}))->capture_default_str();
  cmd->add_option("--measure", o->measure, "auto, poses (x, y of the given poses) or align (scan-to-map alignment)")
      ->check(CLI::IsMember({"auto", "poses", "align"}))->capture_default_str();
  auto* edge = cmd->add_option("--edge", o->edge, "Fixed voxel edge [m]");
  cmd->add_option("--k", o->k, "Voxel edge = k · σ of the posterior position")->excludes(edge)->capture_default_str();
  cmd->add_option("--min-range", o->min_range, "[m]")->capture_default_str();
  cmd->add_option("--max-range", o->max_range, "[m]")->capture_default_str();
  cmd->add_option("--motion-variance", o->motion_variance_mm2, "[mm²] of each commanded move")->capture_default_str();
  cmd->add_option("--measurement-variance", o->measurement_variance_mm2, "[mm²] of a measured position")->capture_default_str();
  cmd->add_flag("--free-space", o->free_space, "Lower the probability of voxels that rays cross (3D DDA)");
  cmd->add_flag("--raw-csv", o->raw_csv, "Also write the registered points as points.csv (to compare sizes)");
  cmd->add_option("--out,-o", o->out, "Output folder")->required();
  cmd->callback([o] { run_pvox(*o); });
}

}  // namespace hmap::cli
