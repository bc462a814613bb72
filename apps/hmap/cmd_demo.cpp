// hmap demo: the whole job on built-in ground truth — simulate, map, evaluate, draw, report.

#include <cstdio>
#include <fstream>
#include <sstream>

#include "cli_common.hpp"
#include "hmap/core/format.hpp"
#include "hmap/eval/map_metrics.hpp"
#include "hmap/io/atomic_file.hpp"
#include "hmap/io/hmap_file.hpp"
#include "hmap/io/ply_export.hpp"
#include "hmap/io/poses.hpp"
#include "hmap/io/sequence_writer.hpp"
#include "hmap/maps/mapper.hpp"
#include "hmap/render/render.hpp"
#include "hmap/sim/simulation.hpp"

namespace hmap::cli {

namespace {

struct DemoOptions {
  std::string out = "out/demo";
  std::string scene = "parking";
  std::string sensor = "vlp16";
  std::uint64_t seed = 1;
  std::size_t frames = 0;
};

/// Runs the demo, writing its files into `dir`; returns the line to print.
std::string run_demo_into(const DemoOptions& o, const std::filesystem::path& dir);

void run_demo(const DemoOptions& o) {
  prepare_output_set(o.out, {"sequence/", "map.hmap", "map_hvoxels.ply", "map_top.png", "map_oblique.png", "report.md"}, "demo");
  // Every file is written into a staging folder that replaces o.out at the end, as one set.
  std::string summary;
  write_folder_atomic(o.out, [&](const std::filesystem::path& dir) { summary = run_demo_into(o, dir); });
  std::fputs(summary.c_str(), stdout);
#ifdef HMAP_HAVE_VIEW
  std::printf("To turn it around in a browser: hmap view %s/map.hmap --trajectory %s/sequence/poses.txt, then open the URL it prints.\n",
              o.out.c_str(), o.out.c_str());
#endif
}

std::string run_demo_into(const DemoOptions& o, const std::filesystem::path& dir) {
  const auto t_start = Clock::now();

  // 1. Simulate: the scene, the sensor along the scripted path, the truth.
  sim::SimulationSpec spec;
  spec.scene = o.scene;
  spec.sensor = o.sensor;
  spec.seed = o.seed;
  spec.frames = o.frames;
  std::optional<Progress> sim_progress;
  const auto t_sim = Clock::now();
  const sim::SimulatedRecording rec = sim::simulate(spec, [&](std::size_t done, std::size_t n, std::size_t) {
    if (!sim_progress) sim_progress.emplace("simulating", n);
    sim_progress->update(done, ms_since(t_sim) / static_cast<double>(done));
  });
  if (sim_progress) sim_progress->finish();
  const double ms_sim = ms_since(t_sim);
  write_simulated_sequence(dir / "sequence", rec.scans, rec.T_world_sensor, rec.times, rec.odometry, rec.truth_surface);
  write_points_ply(dir / "sequence" / "truth_seen.ply", rec.truth_seen);
  write_points_ply(dir / "sequence" / "truth_ground.ply", rec.truth_ground);

  // 2. Map with the true poses.
  const bool outdoor = sim::is_spinning_lidar(o.sensor);
  const Params params = outdoor ? outdoor_preset() : indoor_preset();
  Mapper mapper(params);
  Progress map_progress("mapping", rec.scans.size());
  double ms_map = 0.0;
  std::size_t removed = 0;
  for (std::size_t k = 0; k < rec.scans.size(); ++k) {
    const auto t0 = Clock::now();
    removed += mapper.integrate(rec.scans[k], rec.T_world_sensor[k]).extrusion.removed;
    ms_map += ms_since(t0);
    map_progress.update(k + 1, ms_map / static_cast<double>(k + 1));
  }
  map_progress.finish();
  const HMap& map = mapper.map();
  save_hmap(dir / "map.hmap", map);
  write_hvoxel_boxes_ply(dir / "map_hvoxels.ply", map);

  // 3. Evaluate against what the sensor could see of the final scene.
  const MapMetrics m = evaluate_map(map, rec.truth_seen);

  // 4. Pictures.
  const render::HeightRange range = render::resolve_range(map, {});
  render::TopViewport vp;
  RgbImage top = render::render_top(map, range, 2000, vp, 2.0);
  render::draw_paths_and_legend(top, vp, render::height_legend(range), {{&rec.T_world_sensor, 255, 255, 255, "sensor path (true)"}});
  write_png(dir / "map_top.png", top);
  write_png(dir / "map_oblique.png", render::render_oblique(map, range, 2000));

  // 5. Report.
  const MapStats st = map.stats();
  const double length = sim::path_length(rec.T_world_sensor);
  std::ostringstream r;
  r.setf(std::ios::fixed);
  r.precision(3);
  r << "# hmap demo: scene `" << o.scene << "`, sensor `" << o.sensor << "`, seed " << o.seed << "\n\n"
    << "Simulated " << rec.scans.size() << " frames along " << length << " m (" << rec.points
    << " points) in " << ms_sim / 1000.0 << " s; the recording is in `sequence/` (KITTI layout, true poses, noisy "
    << "odometry, `truth.ply`, `truth_seen.ply`).\n\n"
    << "Mapped with the true poses and the `" << (outdoor ? "outdoor" : "indoor") << "` preset (cell "
    << params.map.cell_size << " m, range " << params.map.min_range << "-" << params.map.max_range << " m): "
    << ms_map / static_cast<double>(rec.scans.size()) << " ms per scan; " << st.cells << " cells, " << st.hvoxels
    << " HVoxels, " << st.memory_bytes << " bytes; free space and extrusion removed " << removed
    << " HVoxels.\n\n"
    << "| against what the sensor could see (`truth_seen.ply`) | value |\n| --- | --- |\n"
    << "| precision, exact voxels | " << m.exact.precision << " |\n"
    << "| recall, exact voxels | " << m.exact.recall << " |\n"
    << "| F-score, exact voxels | " << m.exact.f_score << " |\n"
    << "| precision, within " << m.tolerant.tolerance_voxels << " voxel | " << m.tolerant.precision << " |\n"
    << "| recall, within " << m.tolerant.tolerance_voxels << " voxel | " << m.tolerant.recall << " |\n"
    << "| Chamfer distance [m] | " << m.chamfer.chamfer_m << " |\n"
    << "| accuracy (map to truth) [m] | " << m.chamfer.accuracy_m << " |\n"
    << "| completeness (truth to map) [m] | " << m.chamfer.completeness_m << " |\n\n"
    << "Voxels are " << m.cell_size_m << " x " << m.cell_size_m << " x " << m.voxel_height_m << " m.\n\n"
    << "Files: `map.hmap`, `map_hvoxels.ply` (boxes for MeshLab / CloudCompare), `map_top.png` (top view, the path "
    << "in white), `map_oblique.png`.\n";
  write_file_atomic(dir / "report.md", r.str());
  return format("Demo: simulated %zu %s frames of '%s' (%.0f m), mapped them at %.1f ms per scan into %zu HVoxels; "
              "against the truth: precision %.3f, recall %.3f (within one voxel %.3f / %.3f), Chamfer %.3f m. "
              "Wrote %s/{report.md, map.hmap, map_hvoxels.ply, map_top.png, map_oblique.png, sequence/} in %.1f s.\n",
              rec.scans.size(), o.sensor.c_str(), o.scene.c_str(), length, ms_map / static_cast<double>(rec.scans.size()),
              st.hvoxels, m.exact.precision, m.exact.recall, m.tolerant.precision, m.tolerant.recall, m.chamfer.chamfer_m,
              o.out.c_str(), ms_since(t_start) / 1000.0);
}

}  // namespace

void add_demo_command(CLI::App& app) {
  auto opts = std::make_shared<DemoOptions>();
  auto* cmd = app.add_subcommand("demo", "Simulate a recording, map it, evaluate the map against the truth, draw it");
  cmd->add_option("--out,-o", opts->out, "Output folder")->capture_default_str();
  cmd->add_option("--scene", opts->scene, "office, parking or boxes")->check(CLI::IsMember({"office", "parking", "boxes"}))->capture_default_str();
  cmd->add_option("--sensor", opts->sensor, sim::sensor_names_text())
      ->check(CLI::IsMember(sim::sensor_names()))
      ->capture_default_str();
  cmd->add_option("--seed", opts->seed, "Noise seed")->check(kCount)->capture_default_str();
  cmd->add_option("--frames", opts->frames, "Only the first N frames of the path (default: all)")->check(kCount);
  cmd->callback([opts] { run_demo(*opts); });
}

}  // namespace hmap::cli
