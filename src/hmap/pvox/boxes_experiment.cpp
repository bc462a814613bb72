#include "hmap/pvox/boxes_experiment.hpp"

#include <cmath>
#include <functional>
#include <random>

#include "hmap/core/error.hpp"
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

BoxesMeasurement measure_boxes(const VoxelMap& map, const PlaneDetectionParams& params) {
  BoxesMeasurement out;
  // Find the planes in the enclosure (its walls 0.3 m out, so a drifted wall stays in), knowing
  // nothing of where the faces are.
  PlaneDetectionParams detection = params;
  if (!detection.region) {
    detection.region = Eigen::AlignedBox3d(Eigen::Vector3d(-1.05, -0.3, -1.3), Eigen::Vector3d(1.05, 3.0, 1.3));
  }
  for (int axis = 0; axis < 3; ++axis) out.planes[static_cast<std::size_t>(axis)] = detect_planes(map, axis, detection);

  // Then compare with the scene: every axis-aligned face of builtin_scenes.cpp's layout (box A:
  // x −0.45..−0.12, y 0.935..1.15, z −1..−0.88; box B: x −0.45..−0.08, y 2.05..2.125, z −1..−0.215;
  // the room x ±0.75, y 0..2.7, z ±1), the unseen ones too, so that the gates are honest.
  const std::array<std::vector<std::pair<const char*, double>>, 3> nominal = {{
      {{"left wall (x)", -0.75}, {"left sides of boxes A, B (x)", -0.45}, {"right side of box A (x)", -0.12},
       {"right side of box B (x)", -0.08}, {"right wall (x)", 0.75}},
      {{"front wall (y)", 0.0}, {"front of box A (y)", 0.935}, {"back of box A (y)", 1.15}, {"front of box B (y)", 2.05},
       {"back of box B (y)", 2.125}, {"back wall (y)", 2.7}},
      {{"floor (z)", -1.0}, {"top of box A (z)", -0.88}, {"top of box B (z)", -0.215}, {"ceiling (z)", 1.0}},
  }};
  for (int axis = 0; axis < 3; ++axis) {
    const auto& faces = nominal[static_cast<std::size_t>(axis)];
    std::vector<double> coordinates;
    for (const auto& [name, c] : faces) coordinates.push_back(c);
    const auto matches = associate_faces(out.planes[static_cast<std::size_t>(axis)], coordinates);
    for (std::size_t f = 0; f < faces.size(); ++f) {
      out.faces.push_back({faces[f].first, axis, faces[f].second, face_gate(coordinates, f), matches[f]});
    }
  }
  const auto face = [&](const std::string& name) -> const FaceMatch& {
    for (const FaceMatch& f : out.faces) {
      if (f.name == name) return f;
    }
    throw Error("measure_boxes: no face " + name);
  };

  /// A face coordinate: the plane of a face, or where it ends along another axis.
  struct Coordinate {
    std::string face;
    int along = -1;  ///< −1: the plane; else the axis of the end
    int side = 0;
    [[nodiscard]] std::string name() const {
      if (along < 0) return face;
      return face + ", " + (side < 0 ? "low" : "high") + " end (" + "xyz"[along] + ")";
    }
  };
  const auto read = [&](const Coordinate& c) -> std::optional<double> {
    const FaceMatch& f = face(c.face);
    if (!f.plane) return std::nullopt;
    const DetectedPlane& plane = out.planes[static_cast<std::size_t>(f.axis)][*f.plane];
    return c.along < 0 ? std::optional<double>(plane.coordinate) : plane_end(map, plane, c.along, c.side);
  };
  const Coordinate floor{"floor (z)"};
  const Coordinate top_a{"top of box A (z)"};
  const Coordinate front_a{"front of box A (y)"};
  const Coordinate back_a{"back of box A (y)"};
  const Coordinate front_b{"front of box B (y)"};
  const Coordinate back_b{"back of box B (y)"};
  const Coordinate back_wall{"back wall (y)"};
  struct Spec {
    const char* from;
    const char* to;
    Coordinate a;
    Coordinate b;
  };
  const Spec specs[] = {
      {"A", "B", {top_a.face, 0, -1}, {top_a.face, 0, +1}},
      {"A", "E", floor, top_a},
      {"E", "G", front_a, back_a},
      {"G", "H", back_a, front_b},
      {"H", "C", {front_b.face, 0, -1}, {front_b.face, 0, +1}},
      {"C", "F", front_b, back_b},
      {"F", "I", {back_b.face, 0, -1}, {back_b.face, 0, +1}},
      {"I", "J", floor, {back_b.face, 2, +1}},
      {"J", "K", back_b, back_wall},
  };
  const auto truth = sim::boxes_edges();
  for (const Spec& s : specs) {
    EdgeMeasurement m;
    m.name = std::string(s.from) + s.to;
    for (const auto& e : truth) {
      if (e.from == s.from && e.to == s.to) m.true_length = e.length;
    }
    m.how = s.b.name() + " − " + s.a.name();
    m.first = read(s.a);
    m.second = read(s.b);
    if (m.first && m.second) {
      m.measured = std::abs(*m.second - *m.first);
      m.accuracy = 1.0 - std::abs(*m.measured - m.true_length) / m.true_length;
    } else {
      for (const Coordinate* c : {&s.a, &s.b}) {
        if (face(c->face).plane || m.missing.find(c->face) != std::string::npos) continue;
        m.missing += (m.missing.empty() ? "" : "; ") + c->face;
      }
      if (m.missing.empty()) m.missing = "face end";
    }
    out.edges.push_back(std::move(m));
  }
  return out;
}

AccuracySummary summarize_accuracy(const std::vector<EdgeMeasurement>& edges) {
  AccuracySummary s;
  double sum = 0.0;
  for (const auto& e : edges) {
    if (e.measured) {
      sum += e.accuracy;
      ++s.measured;
    } else {
      ++s.missing;
    }
  }
  if (s.measured > 0) s.mean = sum / static_cast<double>(s.measured);
  return s;
}

}  // namespace hmap::pvox
