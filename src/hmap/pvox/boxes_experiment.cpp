#include "hmap/pvox/boxes_experiment.hpp"

#include <cmath>
#include <functional>
#include <random>

#include "hmap/pvox/measure.hpp"
#include "hmap/sim/builtin_scenes.hpp"
#include "hmap/sim/sensors.hpp"
#include "hmap/sim/trajectory.hpp"

namespace hmap::pvox {

namespace {

Pose stop(double x, double y, double yaw) {
  Pose T = Pose::Identity();
  T.translation() = Eigen::Vector3d(x, y, 0.0);
  T.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return T;
}

Eigen::AlignedBox3d box(double x0, double x1, double y0, double y1, double z0, double z1) {
  return {Eigen::Vector3d(x0, y0, z0), Eigen::Vector3d(x1, y1, z1)};
}

/// A face coordinate: a plane, or the end of a face along an axis.
struct FaceCoordinate {
  std::string name;
  FaceQuery query;
  int along = -1;  ///< −1: the plane; else the axis of the end
  int side = 0;
  [[nodiscard]] std::optional<double> measure(const VoxelMap& map) const {
    return along < 0 ? measure_plane(map, query) : measure_extent(map, query, along, side);
  }
};

FaceCoordinate plane(std::string name, int axis, const Eigen::AlignedBox3d& region) {
  return {std::move(name), FaceQuery{axis, region}, -1, 0};
}
FaceCoordinate end(std::string name, int axis, const Eigen::AlignedBox3d& region, int along, int side) {
  return {std::move(name), FaceQuery{axis, region}, along, side};
}

}  // namespace

BoxesRecording simulate_boxes(const BoxesExperimentParams& params) {
  BoxesRecording rec;
  const double pi = std::acos(-1.0);
  // The scanner's yaw sweep covers its +y half-space: yaw 0 looks along +y (the robot's heading).
  rec.T_world_nominal = {stop(0.3, 0.4, 0.0), stop(0.3, 1.4, 0.0), stop(0.3, 2.4, 0.0), stop(0.3, 2.4, pi),
                         stop(0.3, 1.4, pi)};
  std::mt19937_64 rng(params.seed);
  std::normal_distribution<double> placement(0.0, std::sqrt(params.motion_variance));
  rec.T_world_true.push_back(rec.T_world_nominal[0]);
  rec.commands.push_back(rec.T_world_nominal[0]);
  for (std::size_t k = 1; k < rec.T_world_nominal.size(); ++k) {
    const Pose move = rec.T_world_nominal[k - 1].inverse() * rec.T_world_nominal[k];
    rec.commands.push_back(move);
    Pose T = rec.T_world_true.back() * move;
    T.translation().x() += placement(rng);
    T.translation().y() += placement(rng);
    rec.T_world_true.push_back(T);
  }
  // Stop, move, stop: each scan is taken when the stand arrives at its stop.
  const sim::StopAndGo timeline = sim::stop_and_go(rec.T_world_true, sim::StopAndGoParams{});
  rec.times.assign(rec.T_world_true.size(), 0.0);
  for (std::size_t f = timeline.stop.size(); f-- > 0;) {
    if (timeline.stop[f] >= 0) rec.times[static_cast<std::size_t>(timeline.stop[f])] = timeline.trajectory.times[f];
  }

  const sim::Scene scene = sim::make_boxes_scene();
  sim::LineScannerParams lp = sim::LineScannerParams::utm30lx_yawing();
  lp.angular_step_deg = params.angular_step_deg;
  lp.sweep_steps = params.sweep_steps;
  lp.range_sigma = params.range_sigma;
  for (std::size_t k = 0; k < rec.T_world_true.size(); ++k) {
    lp.seed = params.seed * 1000 + k;
    sim::LineScanner scanner(lp);
    rec.scans.push_back(scanner.scan(scene, rec.T_world_true[k], rec.times[k]).points_sensor);
  }
  return rec;
}

std::vector<EdgeMeasurement> measure_boxes_edges(const VoxelMap& map) {
  // The faces of builtin_scenes.cpp's layout, windows ±5 cm (±4 cm for box B's thin faces)
  // around them, 3 cm in from their borders. Box A: x −0.45..−0.12, y 0.935..1.15, z −1..−0.88;
  // box B: x −0.45..−0.08, y 2.05..2.125, z −1..−0.215; floor z = −1; back wall y = 2.7.
  const FaceCoordinate floor_front_a = plane("floor before box A (z)", 2, box(-0.5, 0.0, 0.6, 0.9, -1.05, -0.95));
  const FaceCoordinate floor_behind_b = plane("floor behind box B (z)", 2, box(-0.5, 0.0, 2.2, 2.6, -1.05, -0.95));
  const FaceCoordinate top_a = plane("top of box A (z)", 2, box(-0.42, -0.15, 0.965, 1.12, -0.93, -0.83));
  const Eigen::AlignedBox3d top_a_wide = box(-0.65, 0.05, 0.965, 1.12, -0.92, -0.84);
  const FaceCoordinate top_a_left = end("top of box A, left end (x)", 2, top_a_wide, 0, -1);
  const FaceCoordinate top_a_right = end("top of box A, right end (x)", 2, top_a_wide, 0, +1);
  const FaceCoordinate front_a = plane("front of box A (y)", 1, box(-0.42, -0.15, 0.885, 0.985, -0.97, -0.89));
  const FaceCoordinate back_a = plane("back of box A (y)", 1, box(-0.42, -0.15, 1.10, 1.20, -0.97, -0.89));
  const FaceCoordinate front_b = plane("front of box B (y)", 1, box(-0.42, -0.11, 2.01, 2.085, -0.9, -0.3));
  const FaceCoordinate back_b = plane("back of box B (y)", 1, box(-0.42, -0.11, 2.09, 2.165, -0.9, -0.3));
  const Eigen::AlignedBox3d front_b_wide = box(-0.65, 0.05, 2.01, 2.08, -0.9, -0.3);
  const Eigen::AlignedBox3d back_b_wide = box(-0.65, 0.05, 2.095, 2.165, -0.9, 0.0);
  const FaceCoordinate front_b_left = end("front of box B, left end (x)", 1, front_b_wide, 0, -1);
  const FaceCoordinate front_b_right = end("front of box B, right end (x)", 1, front_b_wide, 0, +1);
  const FaceCoordinate back_b_left = end("back of box B, left end (x)", 1, back_b_wide, 0, -1);
  const FaceCoordinate back_b_right = end("back of box B, right end (x)", 1, back_b_wide, 0, +1);
  const FaceCoordinate back_b_top = end("back of box B, top end (z)", 1, box(-0.42, -0.11, 2.095, 2.165, -0.9, 0.0), 2, +1);
  const FaceCoordinate back_wall = plane("back wall (y)", 1, box(-0.45, 0.4, 2.65, 2.75, -0.5, 0.0));

  struct Spec {
    const char* from;
    const char* to;
    const FaceCoordinate* a;
    const FaceCoordinate* b;
  };
  const Spec specs[] = {
      {"A", "B", &top_a_left, &top_a_right}, {"A", "E", &floor_front_a, &top_a},   {"E", "G", &front_a, &back_a},
      {"G", "H", &back_a, &front_b},         {"H", "C", &front_b_left, &front_b_right},
      {"C", "F", &front_b, &back_b},         {"F", "I", &back_b_left, &back_b_right},
      {"I", "J", &floor_behind_b, &back_b_top}, {"J", "K", &back_b, &back_wall},
  };
  const auto truth = sim::boxes_edges();
  std::vector<EdgeMeasurement> out;
  for (const Spec& s : specs) {
    EdgeMeasurement m;
    m.name = std::string(s.from) + s.to;
    for (const auto& e : truth) {
      if (e.from == s.from && e.to == s.to) m.true_length = e.length;
    }
    m.how = s.b->name + " − " + s.a->name;
    const auto a = s.a->measure(map);
    const auto b = s.b->measure(map);
    m.first = a;
    m.second = b;
    if (a && b) {
      m.measured = std::abs(*b - *a);
      m.accuracy = 1.0 - std::abs(*m.measured - m.true_length) / m.true_length;
    }
    out.push_back(std::move(m));
  }
  return out;
}

double average_accuracy(const std::vector<EdgeMeasurement>& edges) {
  if (edges.empty()) return 0.0;
  double sum = 0.0;
  for (const auto& e : edges) sum += e.accuracy;
  return sum / static_cast<double>(edges.size());
}

}  // namespace hmap::pvox
