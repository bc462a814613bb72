// hmap experiment pvox-boxes: the PVOX seed's experiment reproduced in the simulator — the boxes
// enclosure scanned from five stop-move-stop positions, mapped with RBF and with BRF, the edges of
// its Table 1 measured on each map, runtimes per registration, file sizes, pictures.

#include <cmath>
#include <cstdio>
#include <limits>
#include <nlohmann/json.hpp>
#include <sstream>

#include "cli_common.hpp"
#include "hmap/core/format.hpp"
#include "hmap/io/atomic_file.hpp"
#include "hmap/pvox/boxes_experiment.hpp"
#include "hmap/pvox/mapper.hpp"
#include "pvox_output.hpp"

namespace hmap::cli {

namespace {

struct ExperimentOptions {
  std::string name;
  std::string out;
  std::uint64_t seed = 1;
  bool quick = false;
  bool no_free_space = false;
};

struct FilterRun {
  std::string label;
  std::vector<pvox::RegistrationResult> registrations;
  std::vector<double> ms;
  std::vector<pvox::EdgeMeasurement> edges;
  double average = 0.0;
  std::optional<pvox::PvoxMapper> mapper;
  PointCloud raw_points_map;
};

FilterRun run_filter(const pvox::BoxesRecording& rec, pvox::FilterKind kind, const pvox::PvoxParams& base) {
  FilterRun run;
  run.label = kind == pvox::FilterKind::kRecursive ? "rbf" : "brf";
  pvox::PvoxParams params = base;
  params.filter.kind = kind;
  run.mapper.emplace(params);
  for (std::size_t k = 0; k < rec.scans.size(); ++k) {
    const auto t0 = Clock::now();
    run.registrations.push_back(run.mapper->add_scan(rec.scans[k], rec.commands[k]));
    run.ms.push_back(ms_since(t0));
    const Pose& T = run.registrations.back().T_map_sensor;
    for (const Point3f& p : rec.scans[k]) run.raw_points_map.push_back((T * p.cast<double>()).cast<float>());
  }
  run.edges = pvox::measure_boxes_edges(run.mapper->map());
  run.average = pvox::average_accuracy(run.edges);
  return run;
}

std::string mm(const std::optional<double>& metres) {
  if (!metres) return "—";
  return format("%.1f", *metres * 1000.0);
}

nlohmann::json run_json(const FilterRun& run, const pvox::BoxesRecording& rec) {
  nlohmann::json j;
  j["edges"] = nlohmann::json::array();
  for (const auto& e : run.edges) {
    j["edges"].push_back({{"name", e.name},
                          {"true_mm", e.true_length * 1000.0},
                          {"measured_mm", e.measured ? nlohmann::json(*e.measured * 1000.0) : nlohmann::json(nullptr)},
                          {"accuracy", e.accuracy},
                          {"how", e.how},
                          {"faces_m", {e.first ? nlohmann::json(*e.first) : nlohmann::json(nullptr),
                                       e.second ? nlohmann::json(*e.second) : nlohmann::json(nullptr)}}});
  }
  j["average_accuracy"] = run.average;
  j["registrations"] = nlohmann::json::array();
  for (std::size_t k = 0; k < run.registrations.size(); ++k) {
    const auto& r = run.registrations[k];
    const Eigen::Vector2d error = r.T_map_sensor.translation().head<2>() - rec.T_world_true[k].translation().head<2>();
    j["registrations"].push_back({{"position", k + 1},
                                  {"ms", run.ms[k]},
                                  {"points", r.insert.hits},
                                  {"edge_mm", r.edge * 1000.0},
                                  {"prior_variance_mm2", r.prior_variance.maxCoeff() * 1e6},
                                  {"posterior_variance_mm2", r.posterior_variance.maxCoeff() * 1e6},
                                  {"measured_by_alignment", r.measured_by_alignment},
                                  {"alignment_iterations", r.align.iterations},
                                  {"alignment_converged", r.align.converged},
                                  {"position_error_mm", error.norm() * 1000.0}});
  }
  const auto& map = run.mapper->map();
  j["voxels"] = map.voxel_count();
  j["occupied_voxels"] = map.occupied().size();
  j["edge_mm"] = map.edge() * 1000.0;
  return j;
}

/// The experiment, its files written into `dir`.
void pvox_boxes_into(const ExperimentOptions& o, const std::filesystem::path& dir);

void run_pvox_boxes(const ExperimentOptions& o) {
  prepare_output_set(o.out, {"rbf_*", "brf_*", "report.json", "report.md"}, "experiment");
  // The maps, pictures and reports are one set: a kill leaves the old folder or the new one.
  write_folder_atomic(o.out, [&](const std::filesystem::path& dir) { pvox_boxes_into(o, dir); });
}

void pvox_boxes_into(const ExperimentOptions& o, const std::filesystem::path& dir) {
  pvox::BoxesExperimentParams sim;
  sim.seed = o.seed;
  if (o.quick) {
    sim.angular_step_deg = 1.0;
    sim.sweep_steps = 61;
  }
  const auto t_sim = Clock::now();
  const pvox::BoxesRecording rec = pvox::simulate_boxes(sim);
  const double ms_sim = ms_since(t_sim);

  pvox::PvoxParams params;
  params.insert.max_range = 30.0;  // the UTM-30LX as used
  params.insert.min_range = 0.1;
  params.insert.free_space = o.no_free_space ? pvox::FreeSpace::kOff : pvox::FreeSpace::kRays;
  const FilterRun rbf = run_filter(rec, pvox::FilterKind::kRecursive, params);
  const FilterRun brf = run_filter(rec, pvox::FilterKind::kNaive, params);

  const PvoxFileSizes sizes = write_pvox_files(dir, "rbf_", rbf.mapper->map(), &rbf.raw_points_map);
  write_pvox_files(dir, "brf_", brf.mapper->map(), nullptr);
  // Pictures: the ceiling and the walls cut away, as the seed's Figures 12–13 show the inside.
  PvoxView view;
  view.clip = Eigen::AlignedBox3d(Eigen::Vector3d(-0.72, 0.03, -1.2), Eigen::Vector3d(0.72, 2.64, 0.2));
  const auto slice_z = [](const pvox::VoxelMap& m) { return m.centre(m.key_of(Eigen::Vector3d(0.0, 0.0, -0.91))).z(); };
  PvoxView field = view;
  field.clip = Eigen::AlignedBox3d(Eigen::Vector3d(-0.8, -0.05, -1.2), Eigen::Vector3d(0.8, 2.75, 1.2));
  write_pvox_pictures(dir, "rbf_", rbf.mapper->map(), view, std::numeric_limits<double>::quiet_NaN());
  write_pvox_pictures(dir, "brf_", brf.mapper->map(), view, std::numeric_limits<double>::quiet_NaN());
  write_png(dir / "rbf_gradient.png", render_pvox_gradient(rbf.mapper->map(), field, slice_z(rbf.mapper->map())));

  nlohmann::json report;
  report["rbf"] = run_json(rbf, rec);
  report["brf"] = run_json(brf, rec);
  report["sizes_bytes"] = {{"raw_csv", sizes.raw_csv}, {"voxel_csv", sizes.voxel_csv}, {"binary", sizes.binary}};
  report["seed"] = o.seed;
  report["points"] = rbf.raw_points_map.size();
  report["simulation_ms"] = ms_sim;
  report["free_space"] = !o.no_free_space;
  write_file_atomic(dir / "report.json", report.dump(2) + "\n");

  std::ostringstream md;
  md << "# PVOX experiment: the boxes enclosure (seed Table 1, Figures 12–17)\n\n"
     << "Simulated Hokuyo UTM-30LX (σ 10 mm) turning about the vertical, five stop-move-stop positions "
        "(P1 y 0.4, P2 y 1.4, P3 y 2.4 m heading +y; P4 = P3 turned 180°; P5 = P2 heading −y), each move "
        "placed with N(0, 2000 mm²) per axis; seed "
     << o.seed << ", " << rbf.raw_points_map.size() << " points. Filters: motion variance 2000 mm², measurement "
        "variance 100 mm² (the measurement: point-to-plane alignment of the scan to the map); voxel edge 6σ.\n\n";
  md << "| edge | true [mm] | RBF [mm] | RBF accuracy | BRF [mm] | BRF accuracy |\n| --- | --- | --- | --- | --- | --- |\n";
  for (std::size_t i = 0; i < rbf.edges.size(); ++i) {
    const auto& a = rbf.edges[i];
    const auto& b = brf.edges[i];
    md << format("| %s | %.0f | %s | %.3f | %s | %.3f |\n", a.name.c_str(), a.true_length * 1000.0,
                 mm(a.measured).c_str(), a.accuracy, mm(b.measured).c_str(), b.accuracy);
  }
  md << format("| **average** | | | **%.3f** | | **%.3f** |\n\n", rbf.average, brf.average);
  md << "Each length is the difference of two face coordinates measured on the map (planes: count-weighted median "
        "of flat voxels' point means; face ends: outermost voxel's mean ± √3σ), see docs/PVOX.md.\n\n";
  md << "## Registrations\n\n| position | RBF ms | RBF edge [mm] | RBF σ² [mm²] | RBF error [mm] | BRF ms | BRF σ² [mm²] | BRF error [mm] |\n"
        "| --- | --- | --- | --- | --- | --- | --- | --- |\n";
  for (std::size_t k = 0; k < rbf.registrations.size(); ++k) {
    const auto err = [&](const FilterRun& run) {
      return (run.registrations[k].T_map_sensor.translation().head<2>() - rec.T_world_true[k].translation().head<2>()).norm() * 1000.0;
    };
    md << format("| %zu | %.0f | %.2f | %.4f | %.1f | %.0f | %.2f | %.1f |\n", k + 1, rbf.ms[k],
                 rbf.registrations[k].edge * 1000.0, rbf.registrations[k].posterior_variance.maxCoeff() * 1e6, err(rbf),
                 brf.ms[k], brf.registrations[k].posterior_variance.maxCoeff() * 1e6, err(brf));
  }
  md << format(
                "\n## Sizes (RBF map)\n\n| raw points CSV | voxel CSV | binary |\n| --- | --- | --- |\n| %s | %s | %s |\n\n"
                "Raw / binary = %.0f×.\n\n",
                human_bytes(static_cast<double>(sizes.raw_csv)).c_str(), human_bytes(static_cast<double>(sizes.voxel_csv)).c_str(),
                human_bytes(static_cast<double>(sizes.binary)).c_str(),
                static_cast<double>(sizes.raw_csv) / static_cast<double>(std::max<std::uintmax_t>(1, sizes.binary)));
  md << "Pictures: `rbf_top.png`, `rbf_iso.png` (Figure 13), `brf_top.png`, `brf_iso.png` (Figure 12), "
        "`rbf_gradient.png` (p on a slice just above the floor, arrows −∇p: the \"vector field\").\n";
  write_file_atomic(dir / "report.md", md.str());

  std::printf("pvox-boxes: RBF average accuracy %.3f, BRF %.3f; sizes raw %s, voxel CSV %s, binary %s (%.0fx); wrote %s\n",
              rbf.average, brf.average, human_bytes(static_cast<double>(sizes.raw_csv)).c_str(),
              human_bytes(static_cast<double>(sizes.voxel_csv)).c_str(), human_bytes(static_cast<double>(sizes.binary)).c_str(),
              static_cast<double>(sizes.raw_csv) / static_cast<double>(std::max<std::uintmax_t>(1, sizes.binary)),
              (std::filesystem::path(o.out) / "report.md").c_str());
}

}  // namespace

void add_experiment_command(CLI::App& app) {
  auto opts = std::make_shared<ExperimentOptions>();
  auto* cmd = app.add_subcommand("experiment", "Reproduce a seed paper's experiment in the simulator (pvox-boxes)");
  cmd->add_option("name", opts->name, "pvox-boxes")->required()->check(CLI::IsMember({"pvox-boxes"}));
  cmd->add_option("--out,-o", opts->out, "Output folder")->required();
  cmd->add_option("--seed", opts->seed, "Seed of the placement errors and the sensor noise")->check(kCount)->capture_default_str();
  cmd->add_flag("--quick", opts->quick, "Coarser scans (1° beams, 61 sweep steps) for a fast run");
  cmd->add_flag("--no-free-space", opts->no_free_space, "Count hits only (no misses along the rays)");
  cmd->callback([opts] { run_pvox_boxes(*opts); });
}

}  // namespace hmap::cli
