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
  pvox::BoxesMeasurement measured;
  pvox::AccuracySummary accuracy;
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
  run.measured = pvox::measure_boxes(run.mapper->map());
  run.accuracy = pvox::summarize_accuracy(run.measured.edges);
  return run;
}

std::string mm(const std::optional<double>& metres) {
  if (!metres) return "—";
  return format("%.1f", *metres * 1000.0);
}

nlohmann::json run_json(const FilterRun& run, const pvox::BoxesRecording& rec) {
  nlohmann::json j;
  j["edges"] = nlohmann::json::array();
  const auto optional_json = [](const std::optional<double>& v, double scale) {
    return v ? nlohmann::json(*v * scale) : nlohmann::json(nullptr);
  };
  for (const auto& e : run.measured.edges) {
    j["edges"].push_back({{"name", e.name},
                          {"true_mm", e.true_length * 1000.0},
                          {"measured_mm", optional_json(e.measured, 1000.0)},
                          {"accuracy", e.measured ? nlohmann::json(e.accuracy) : nlohmann::json(nullptr)},
                          {"missing", e.missing},
                          {"how", e.how},
                          {"faces_m", {optional_json(e.first, 1.0), optional_json(e.second, 1.0)}}});
  }
  j["average_accuracy_measured"] = run.accuracy.mean;
  j["edges_measured"] = run.accuracy.measured;
  j["edges_missing"] = run.accuracy.missing;
  j["faces"] = nlohmann::json::array();
  for (const auto& f : run.measured.faces) {
    nlohmann::json plane = nullptr;
    if (f.plane) {
      const auto& p = run.measured.planes[static_cast<std::size_t>(f.axis)][*f.plane];
      plane = {{"coordinate_m", p.coordinate}, {"flat_voxels", p.flat_voxels}, {"points", p.points}};
    }
    j["faces"].push_back({{"name", f.name}, {"nominal_m", f.nominal}, {"gate_m", f.gate}, {"plane", plane}});
  }
  j["planes_detected"] = {run.measured.planes[0].size(), run.measured.planes[1].size(), run.measured.planes[2].size()};
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

/// One row per filter and edge; an edge not measured has empty length and accuracy, and names its
/// missing faces.
std::string edges_csv(const std::vector<const FilterRun*>& runs) {
  std::ostringstream csv;
  csv << "filter,edge,true_mm,measured_mm,accuracy,status,first_m,second_m,missing\n";
  const auto cell = [](const std::optional<double>& v, const char* f, double scale) { return v ? format(f, *v * scale) : std::string(); };
  for (const FilterRun* run : runs) {
    for (const auto& e : run->measured.edges) {
      csv << run->label << ',' << e.name << ',' << format("%.1f", e.true_length * 1000.0) << ',' << cell(e.measured, "%.2f", 1000.0)
          << ',' << (e.measured ? format("%.4f", e.accuracy) : std::string()) << ',' << (e.measured ? "measured" : "missing")
          << ',' << cell(e.first, "%.5f", 1.0) << ',' << cell(e.second, "%.5f", 1.0) << ",\"" << e.missing << "\"\n";
    }
  }
  return csv.str();
}

/// One row per filter and detected plane, with the scene face it was matched with (if any).
std::string planes_csv(const std::vector<const FilterRun*>& runs) {
  std::ostringstream csv;
  csv << "filter,axis,coordinate_m,flat_voxels,points,voxels,min_x,min_y,min_z,max_x,max_y,max_z,face\n";
  for (const FilterRun* run : runs) {
    for (std::size_t axis = 0; axis < 3; ++axis) {
      const auto& planes = run->measured.planes[axis];
      for (std::size_t p = 0; p < planes.size(); ++p) {
        std::string face;
        for (const auto& f : run->measured.faces) {
          if (static_cast<std::size_t>(f.axis) == axis && f.plane == p) face = f.name;
        }
        const auto& pl = planes[p];
        csv << run->label << ',' << "xyz"[axis] << ',' << format("%.5f", pl.coordinate) << ',' << pl.flat_voxels << ','
            << pl.points << ',' << pl.voxels.size();
        for (int k = 0; k < 3; ++k) csv << ',' << format("%.4f", pl.extent.min()[k]);
        for (int k = 0; k < 3; ++k) csv << ',' << format("%.4f", pl.extent.max()[k]);
        csv << ",\"" << face << "\"\n";
      }
    }
  }
  return csv.str();
}

/// The experiment, its files written into `dir`.
void pvox_boxes_into(const ExperimentOptions& o, const std::filesystem::path& dir);

void run_pvox_boxes(const ExperimentOptions& o) {
  prepare_output_set(o.out, {"rbf_*", "brf_*", "report.json", "report.md", "edges.csv", "planes.csv"}, "experiment");
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
  render::PvoxView view;
  view.clip = Eigen::AlignedBox3d(Eigen::Vector3d(-0.72, 0.03, -1.2), Eigen::Vector3d(0.72, 2.64, 0.2));
  const auto slice_z = [](const pvox::VoxelMap& m) { return m.centre(m.key_of(Eigen::Vector3d(0.0, 0.0, -0.91))).z(); };
  render::PvoxView field = view;
  field.clip = Eigen::AlignedBox3d(Eigen::Vector3d(-0.8, -0.05, -1.2), Eigen::Vector3d(0.8, 2.75, 1.2));
  write_pvox_pictures(dir, "rbf_", rbf.mapper->map(), view, std::numeric_limits<double>::quiet_NaN());
  write_pvox_pictures(dir, "brf_", brf.mapper->map(), view, std::numeric_limits<double>::quiet_NaN());
  write_png(dir / "rbf_gradient.png", render::render_pvox_gradient(rbf.mapper->map(), field, slice_z(rbf.mapper->map())));

  nlohmann::json report;
  report["rbf"] = run_json(rbf, rec);
  report["brf"] = run_json(brf, rec);
  report["sizes_bytes"] = {{"raw_csv", sizes.raw_csv}, {"voxel_csv", sizes.voxel_csv}, {"binary", sizes.binary}};
  report["seed"] = o.seed;
  report["points"] = rbf.raw_points_map.size();
  report["simulation_ms"] = ms_sim;
  report["free_space"] = !o.no_free_space;
  write_file_atomic(dir / "report.json", report.dump(2) + "\n");
  write_file_atomic(dir / "edges.csv", edges_csv({&rbf, &brf}));
  write_file_atomic(dir / "planes.csv", planes_csv({&rbf, &brf}));

  std::ostringstream md;
  md << "# PVOX experiment: the boxes enclosure (seed Table 1, Figures 12–17)\n\n"
     << "Simulated Hokuyo UTM-30LX (σ 10 mm) turning about the vertical, five stop-move-stop positions "
        "(P1 y 0.4, P2 y 1.4, P3 y 2.4 m heading +y; P4 = P3 turned 180°; P5 = P2 heading −y), each move "
        "placed with N(0, 2000 mm²) per axis; seed "
     << o.seed << ", " << rbf.raw_points_map.size() << " points. Filters: motion variance 2000 mm², measurement "
        "variance 100 mm² (the measurement: point-to-plane alignment of the scan to the map); voxel edge 6σ.\n\n";
  md << "| edge | true [mm] | RBF [mm] | RBF accuracy | BRF [mm] | BRF accuracy |\n| --- | --- | --- | --- | --- | --- |\n";
  const auto accuracy = [](const pvox::EdgeMeasurement& e) { return e.measured ? format("%.3f", e.accuracy) : std::string("missing"); };
  for (std::size_t i = 0; i < rbf.measured.edges.size(); ++i) {
    const auto& a = rbf.measured.edges[i];
    const auto& b = brf.measured.edges[i];
    md << format("| %s | %.0f | %s | %s | %s | %s |\n", a.name.c_str(), a.true_length * 1000.0, mm(a.measured).c_str(),
                 accuracy(a).c_str(), mm(b.measured).c_str(), accuracy(b).c_str());
  }
  const auto summary = [](const pvox::AccuracySummary& s) {
    return format("**%.3f** over %zu measured, **%zu missing**", s.mean, s.measured, s.missing);
  };
  md << "| **average** | | | " << summary(rbf.accuracy) << " | | " << summary(brf.accuracy) << " |\n\n";
  md << "The ruler reads the map alone: along each axis the planes are found in the voxels (flat voxels' point "
        "means, weighted, smoothed, one plane per density peak; no face position is given); then each face of the "
        "scene is matched with the nearest plane within half the gap to its nearest neighbouring face, else it is "
        "missing. Each length is the difference of two face coordinates: a plane's, or the end of a plane's voxels "
        "(outermost voxel's mean ± √3σ, median over rows). An edge with a missing face is not measured and the "
        "average is over the measured edges only. Faces, planes: `report.json`, `edges.csv`, `planes.csv`; "
        "method: docs/PVOX.md.\n\n";
  md << "| face | nominal [mm] | gate [mm] | RBF plane [mm] | BRF plane [mm] |\n| --- | --- | --- | --- | --- |\n";
  for (std::size_t i = 0; i < rbf.measured.faces.size(); ++i) {
    const auto plane_mm = [&](const FilterRun& run) {
      const auto& f = run.measured.faces[i];
      if (!f.plane) return std::string("missing");
      return format("%.1f", run.measured.planes[static_cast<std::size_t>(f.axis)][*f.plane].coordinate * 1000.0);
    };
    const auto& f = rbf.measured.faces[i];
    md << format("| %s | %.0f | %.1f | %s | %s |\n", f.name.c_str(), f.nominal * 1000.0, f.gate * 1000.0,
                 plane_mm(rbf).c_str(), plane_mm(brf).c_str());
  }
  md << "\n";
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

  std::printf("pvox-boxes: RBF accuracy %.3f over %zu edges (%zu missing), BRF %.3f over %zu (%zu missing); sizes raw %s, voxel CSV %s, binary %s (%.0fx); wrote %s\n",
              rbf.accuracy.mean, rbf.accuracy.measured, rbf.accuracy.missing, brf.accuracy.mean, brf.accuracy.measured,
              brf.accuracy.missing, human_bytes(static_cast<double>(sizes.raw_csv)).c_str(),
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
