// hmap eval: a map against the true geometry, a trajectory against the true poses.

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include "cli_common.hpp"
#include "hmap/core/error.hpp"
#include "hmap/eval/map_metrics.hpp"
#include "hmap/eval/trajectory_metrics.hpp"
#include "hmap/io/hmap_file.hpp"
#include "hmap/io/ply.hpp"
#include "hmap/io/png.hpp"
#include "hmap/io/poses.hpp"
#include "hmap/render/render.hpp"

namespace hmap::cli {

namespace {

/// JSON has no NaN: unmeasurable values are written as null.
nlohmann::json number(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

struct EvalMapOptions {
  std::string map;
  std::string truth;
  bool json = false;
  MapEvalParams params;
};

nlohmann::json scores_json(const OccupancyScores& s) {
  return {{"tolerance_voxels", s.tolerance_voxels}, {"truth_voxels", s.truth_voxels},
          {"truth_voxels_recalled", s.truth_voxels_recalled}, {"map_voxels", s.map_voxels},
          {"map_voxels_matched", s.map_voxels_matched}, {"precision", number(s.precision)},
          {"recall", number(s.recall)}, {"f_score", number(s.f_score)}};
}

void run_eval_map(const EvalMapOptions& o) {
  const HMap map = load_hmap(o.map);
  std::filesystem::path truth_path = o.truth;
  // A simulated folder: what the sensor could see (truth_seen.ply) when there, else every surface.
  if (std::filesystem::is_directory(truth_path)) {
    truth_path = std::filesystem::exists(truth_path / "truth_seen.ply") ? truth_path / "truth_seen.ply" : truth_path / "truth.ply";
  }
  const PointCloud truth = read_ply(truth_path);
  const MapMetrics m = evaluate_map(map, truth, o.params);
  if (o.json) {
    nlohmann::json j{{"map", o.map},
                     {"truth", truth_path.string()},
                     {"cell_size_m", m.cell_size_m},
                     {"voxel_height_m", m.voxel_height_m},
                     {"precision", number(m.exact.precision)},
                     {"recall", number(m.exact.recall)},
                     {"f_score", number(m.exact.f_score)},
                     {"exact", scores_json(m.exact)},
                     {"tolerant", scores_json(m.tolerant)},
                     {"chamfer_m", number(m.chamfer.chamfer_m)},
                     {"accuracy_m", number(m.chamfer.accuracy_m)},
                     {"completeness_m", number(m.chamfer.completeness_m)},
                     {"accuracy_within", number(m.chamfer.accuracy_within)},
                     {"completeness_within", number(m.chamfer.completeness_within)},
                     {"threshold_m", m.chamfer.threshold_m},
                     {"map_points", m.chamfer.map_points},
                     {"truth_points", m.chamfer.truth_points}};
    std::cout << j.dump() << "\n";
    return;
  }
  std::printf("map %s against %s (%zu true points), voxels %.3f x %.3f x %.3f m\n", o.map.c_str(),
              truth_path.string().c_str(), truth.size(), m.cell_size_m, m.cell_size_m, m.voxel_height_m);
  std::printf("  exact:        precision %.3f  recall %.3f  F %.3f\n", m.exact.precision, m.exact.recall, m.exact.f_score);
  std::printf("  within %d voxel: precision %.3f  recall %.3f  F %.3f\n", m.tolerant.tolerance_voxels, m.tolerant.precision,
              m.tolerant.recall, m.tolerant.f_score);
  std::printf("  Chamfer %.3f m (accuracy %.3f m, completeness %.3f m; %.1f%% / %.1f%% within %.2f m)\n",
              m.chamfer.chamfer_m, m.chamfer.accuracy_m, m.chamfer.completeness_m, 100.0 * m.chamfer.accuracy_within,
              100.0 * m.chamfer.completeness_within, m.chamfer.threshold_m);
}

struct EvalTrajOptions {
  std::string gt;
  std::string est;
  bool json = false;
  std::string plot;                     ///< a PNG of the paths, when given
  std::vector<std::string> plot_paths;  ///< more trajectories for the picture, FILE or FILE=LABEL
};

/// The picture of --plot: the truth, the estimate and each --plot-path, from their first poses.
void plot_trajectories(const EvalTrajOptions& o, const PoseList& gt, const PoseList& est) {
  std::vector<PoseList> extra;
  std::vector<std::string> labels;
  for (const std::string& spec : o.plot_paths) {
    const auto eq = spec.find('=');
    const std::string file = eq == std::string::npos ? spec : spec.substr(0, eq);
    const std::string label = eq == std::string::npos ? std::filesystem::path(file).stem().string() : spec.substr(eq + 1);
    if (file.empty() || label.empty()) {
      throw Error("--plot-path '" + spec + "': expected FILE or FILE=LABEL, both non-empty");
    }
    extra.push_back(from_first_pose(read_poses(file)));
    labels.push_back(label);
  }
  const PoseList truth = from_first_pose(gt);
  const PoseList estimate = from_first_pose(est);
  std::vector<render::LabelledPath> paths{{&truth, "truth (--gt)"}, {&estimate, "estimate (--est)"}};
  for (std::size_t k = 0; k < extra.size(); ++k) paths.push_back({&extra[k], labels[k]});
  const render::TopPicture picture = render::render_paths(paths, 1200);
  write_png(o.plot, picture.image);
}

void run_eval_traj(const EvalTrajOptions& o) {
  if (!o.plot.empty()) check_output_extension(o.plot, {".png"}, "--plot writes a PNG picture");
  const PoseList gt = read_poses(o.gt);
  const PoseList est = read_poses(o.est);
  if (gt.size() != est.size()) {
    throw InputError(o.est, "", "holds " + std::to_string(est.size()) + " poses, " + o.gt + " holds " +
                                    std::to_string(gt.size()));
  }
  const TrajectoryMetrics m = evaluate_trajectory(gt, est);
  if (!o.plot.empty()) plot_trajectories(o, gt, est);
  const bool fraction = m.segment_length_source == SegmentLengthSource::kFractionOfPath;
  if (o.json) {
    nlohmann::json lengths = nlohmann::json::array();
    for (const auto& l : m.per_length) {
      lengths.push_back({{"length_m", l.length_m}, {"segments", l.segments}, {"trans_pct", number(l.trans_pct)},
                         {"rot_deg_per_m", number(l.rot_deg_per_m)}});
    }
    nlohmann::json j{{"frames", m.frames},
                     {"path_length_m", m.path_length_m},
                     {"ate_rmse_m", m.ate_rmse_m},
                     {"ate_mean_m", m.ate_mean_m},
                     {"ate_max_m", m.ate_max_m},
                     {"ate_rmse_aligned_m", m.ate_rmse_aligned_m},
                     {"ate_max_aligned_m", m.ate_max_aligned_m},
                     {"ate_rmse_origin_m", m.ate_rmse_origin_m},
                     {"ate_max_origin_m", m.ate_max_origin_m},
                     {"end_error_origin_m", m.end_error_origin_m},
                     {"end_error_origin_planar_m", m.end_error_origin_planar_m},
                     {"rpe_frame_trans_rmse_m", m.rpe_frame_trans_rmse_m},
                     {"rpe_frame_rot_rmse_deg", m.rpe_frame_rot_rmse_deg},
                     {"rpe_trans_pct", number(m.rpe_trans_pct)},
                     {"rpe_rot_deg_per_m", number(m.rpe_rot_deg_per_m)},
                     {"rpe_segments", m.rpe_segments},
                     {"segment_lengths", fraction ? "fraction_of_path" : "kitti"},
                     {"per_length", lengths}};
    std::cout << j.dump() << "\n";
    return;
  }
  std::printf("%zu frames, %.1f m of true path\n", m.frames, m.path_length_m);
  std::printf("  ATE RMSE %.4f m (max %.4f m); after SE(3) alignment %.4f m (max %.4f m); from the first pose %.4f m (max %.4f m)\n",
              m.ate_rmse_m, m.ate_max_m, m.ate_rmse_aligned_m, m.ate_max_aligned_m, m.ate_rmse_origin_m, m.ate_max_origin_m);
  std::printf("  End point from the first pose: %.4f m (horizontal %.4f m)\n", m.end_error_origin_m, m.end_error_origin_planar_m);
  std::printf("  RPE per frame: %.4f m, %.4f deg (RMSE)\n", m.rpe_frame_trans_rmse_m, m.rpe_frame_rot_rmse_deg);
  std::printf("  RPE per distance (%s, %zu segments): %.3f %% translation, %.5f deg/m rotation\n",
              fraction ? "10-80 % of the path, shorter than KITTI's 100 m" : "KITTI's 100-800 m", m.rpe_segments,
              m.rpe_trans_pct, m.rpe_rot_deg_per_m);
}

}  // namespace

void add_eval_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("eval", "Measure a map against the true geometry, or a trajectory against the truth");
  cmd->require_subcommand(1);
  auto map_opts = std::make_shared<EvalMapOptions>();
  auto* map_cmd = cmd->add_subcommand("map", "Precision, recall and F-score of occupied space, Chamfer distance");
  map_cmd->add_option("--map", map_opts->map, "Map file (.hmap)")->required();
  map_cmd->add_option("--truth", map_opts->truth, "Simulated folder (its truth_seen.ply, else truth.ply) or a PLY of the true surface")->required();
  map_cmd->add_option("--voxel-height", map_opts->params.voxel_height, "Vertical voxel size [m] (default: the cell size)");
  map_cmd->add_option("--tolerance", map_opts->params.tolerance_voxels, "Voxels of slack for the tolerant score")
      ->check(CLI::Range(0, 10))
      ->capture_default_str();
  map_cmd->add_flag("--json", map_opts->json, "One JSON object instead of text");
  map_cmd->callback([map_opts] { run_eval_map(*map_opts); });
  auto traj_opts = std::make_shared<EvalTrajOptions>();
  auto* traj_cmd = cmd->add_subcommand("traj", "ATE and RPE (KITTI-style) of an estimated trajectory");
  traj_cmd->add_option("--gt", traj_opts->gt, "True poses (KITTI or TUM)")->required();
  traj_cmd->add_option("--est", traj_opts->est, "Estimated poses, one per true pose")->required();
  traj_cmd->add_flag("--json", traj_opts->json, "One JSON object instead of text");
  traj_cmd->add_option("--plot", traj_opts->plot,
                       "Also draw the trajectories seen from above into this PNG, each from its first pose (legend, scale bar)");
  traj_cmd->add_option("--plot-path", traj_opts->plot_paths,
                       "Another trajectory for --plot (KITTI or TUM), FILE or FILE=LABEL; repeatable")
      ->needs("--plot");
  traj_cmd->callback([traj_opts] { run_eval_traj(*traj_opts); });
}

}  // namespace hmap::cli
