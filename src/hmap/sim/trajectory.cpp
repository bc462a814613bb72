#include "hmap/sim/trajectory.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <string>

#include "hmap/core/checked.hpp"
#include "hmap/core/error.hpp"

namespace hmap::sim {
namespace {

void check_spec(bool ok, const std::string& message) {
  if (!ok) throw Error(message);
}

double wrap_angle(double a) { return std::remainder(a, 2.0 * std::numbers::pi); }

Pose pose_from(const Eigen::Vector3d& position, double yaw, double pitch = 0.0) {
  Pose T = Pose::Identity();
  T.translation() = position;
  // Positive pitch about y lowers the x axis, so a climbing path (pitch > 0 nose up) turns by −pitch.
  T.linear() = (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(-pitch, Eigen::Vector3d::UnitY()))
                   .toRotationMatrix();
  return T;
}

/// Frame times k / frame_rate for k = 0, 1, ... up to `duration` (inclusive, with a tolerance).
std::vector<double> frame_times(double duration, double frame_rate) {
  std::vector<double> times;
  for (std::size_t k = 0;; ++k) {
    const double t = static_cast<double>(k) / frame_rate;
    if (t > duration + 1e-9) break;
    times.push_back(t);
  }
  return times;
}

}  // namespace

// ---------------------------------------------------------------------------------------------

Trajectory diff_drive_path(std::span<const Eigen::Vector2d> waypoints, const DiffDriveParams& params) {
  check_spec(waypoints.size() >= 2, "diff_drive_path: needs at least two waypoints");
  check_spec(params.speed > 0.0 && params.turn_rate > 0.0 && params.frame_rate > 0.0,
        "diff_drive_path: speed, turn_rate and frame_rate must be positive");
  struct Key {
    double t;
    Eigen::Vector2d p;
    double yaw;  // unwrapped
  };
  const Eigen::Vector2d first_leg = waypoints[1] - waypoints[0];
  std::vector<Key> keys{{0.0, waypoints[0], std::atan2(first_leg.y(), first_leg.x())}};
  for (std::size_t i = 0; i + 1 < waypoints.size(); ++i) {
    const Eigen::Vector2d leg = waypoints[i + 1] - waypoints[i];
    const double length = leg.norm();
    if (length < 1e-9) continue;
    const Key last = keys.back();
    // Turn on the spot to the leg's heading, the short way round.
    const double turn = wrap_angle(std::atan2(leg.y(), leg.x()) - last.yaw);
    if (std::abs(turn) > 1e-12) keys.push_back({last.t + std::abs(turn) / params.turn_rate, last.p, last.yaw + turn});
    keys.push_back({keys.back().t + length / params.speed, waypoints[i + 1], keys.back().yaw});
  }
  Trajectory out;
  out.times = frame_times(keys.back().t, params.frame_rate);
  std::size_t k = 0;
  for (const double t : out.times) {
    while (k + 1 < keys.size() && keys[k + 1].t < t) ++k;
    const Key& a = keys[k];
    const Key& b = keys[std::min(k + 1, keys.size() - 1)];
    const double w = b.t > a.t ? std::clamp((t - a.t) / (b.t - a.t), 0.0, 1.0) : 0.0;
    const Eigen::Vector2d p = (1.0 - w) * a.p + w * b.p;
    out.T_world_sensor.push_back(
        pose_from({p.x(), p.y(), params.floor_z + params.sensor_height}, (1.0 - w) * a.yaw + w * b.yaw));
  }
  return out;
}

// ---------------------------------------------------------------------------------------------

namespace {

/// The polyline with its corners replaced by arcs, sampled every ~`step` metres.
std::vector<Eigen::Vector3d> rounded_polyline(std::span<const Eigen::Vector3d> w, double radius, double step) {
  const std::size_t n = w.size();
  std::vector<Eigen::Vector2d> dir(n - 1);
  std::vector<double> len(n - 1);
  for (std::size_t i = 0; i + 1 < n; ++i) {
    const Eigen::Vector2d d = (w[i + 1] - w[i]).head<2>();
    len[i] = d.norm();
    dir[i] = len[i] > 0.0 ? Eigen::Vector2d(d / len[i]) : Eigen::Vector2d(1.0, 0.0);
  }
  // Tangent length of the arc at each inner corner, bounded by half of each neighbouring segment.
  std::vector<double> cut(n, 0.0);
  for (std::size_t i = 1; i + 1 < n; ++i) {
    const double angle = std::acos(std::clamp(dir[i - 1].dot(dir[i]), -1.0, 1.0));
    if (angle < 1e-6 || len[i - 1] == 0.0 || len[i] == 0.0) continue;
    cut[i] = std::min({radius * std::tan(0.5 * angle), 0.5 * len[i - 1], 0.5 * len[i]});
  }
  std::vector<Eigen::Vector3d> points;
  const auto push = [&points](const Eigen::Vector3d& p) {
    if (points.empty() || (points.back() - p).norm() > 1e-9) points.push_back(p);
  };
  // Point at horizontal distance s along segment i (z linear along the segment).
  const auto along = [&](std::size_t i, double s) -> Eigen::Vector3d {
    const double f = len[i] > 0.0 ? s / len[i] : 0.0;
    return w[i] + f * (w[i + 1] - w[i]);
  };
  for (std::size_t i = 0; i + 1 < n; ++i) {
    // Straight part of segment i.
    const double s0 = cut[i];
    const double s1 = len[i] - cut[i + 1];
    // Way points come from scene files: at most 2^24 steps a segment.
    const int pieces = checked_count<int>(std::max(1.0, (s1 - s0) / step), 1 << 24, "a path segment");
    for (int k = 0; k <= pieces; ++k) push(along(i, s0 + (s1 - s0) * k / pieces));
    // Arc around corner i + 1.
    if (i + 2 >= n || cut[i + 1] <= 0.0) continue;
    const Eigen::Vector2d u1 = dir[i];
    const Eigen::Vector2d u2 = dir[i + 1];
    const double angle = std::acos(std::clamp(u1.dot(u2), -1.0, 1.0));
    const double side = u1.x() * u2.y() - u1.y() * u2.x() > 0.0 ? 1.0 : -1.0;  // +1 turning left
    const double r = cut[i + 1] / std::tan(0.5 * angle);
    const Eigen::Vector3d start = along(i, s1);
    const Eigen::Vector3d end = along(i + 1, cut[i + 1]);
    const Eigen::Vector2d centre = start.head<2>() + side * r * Eigen::Vector2d(-u1.y(), u1.x());
    const Eigen::Vector2d from = start.head<2>() - centre;
    const double a0 = std::atan2(from.y(), from.x());
    const int arc_pieces = checked_count<int>(std::max(2.0, r * angle / step), 1 << 24, "a path's corner");
    for (int k = 1; k <= arc_pieces; ++k) {
      const double f = static_cast<double>(k) / arc_pieces;
      const double a = a0 + side * angle * f;
      push({centre.x() + r * std::cos(a), centre.y() + r * std::sin(a), (1.0 - f) * start.z() + f * end.z()});
    }
  }
  return points;
}

}  // namespace

Trajectory car_path(std::span<const Eigen::Vector3d> waypoints_ground, const CarPathParams& params) {
  check_spec(waypoints_ground.size() >= 2, "car_path: needs at least two waypoints");
  check_spec(params.cruise_speed > 0.0 && params.acceleration > 0.0 && params.lateral_acceleration > 0.0 &&
            params.turn_radius > 0.0 && params.frame_rate > 0.0,
        "car_path: speeds, accelerations, turn_radius and frame_rate must be positive");
  constexpr double kStep = 0.05;  // [m] path sampling
  const std::vector<Eigen::Vector3d> p = rounded_polyline(waypoints_ground, params.turn_radius, kStep);
  check_spec(p.size() >= 2, "car_path: the waypoints do not make a path of positive length");
  const std::size_t n = p.size();
  std::vector<double> ds(n, 0.0);      // ds[i]: length from p[i-1] to p[i]
  std::vector<double> heading(n - 1);  // of segment i -> i+1
  for (std::size_t i = 0; i + 1 < n; ++i) {
    ds[i + 1] = (p[i + 1] - p[i]).norm();
    const Eigen::Vector3d d = p[i + 1] - p[i];
    heading[i] = std::atan2(d.y(), d.x());
  }
  // Speed limit from the curvature, then the acceleration bound forwards and backwards.
  std::vector<double> v(n, params.cruise_speed);
  for (std::size_t i = 1; i + 1 < n; ++i) {
    const double curvature = std::abs(wrap_angle(heading[i] - heading[i - 1])) / std::max(1e-9, 0.5 * (ds[i] + ds[i + 1]));
    if (curvature > 1e-9) v[i] = std::min(v[i], std::sqrt(params.lateral_acceleration / curvature));
  }
  v.front() = 0.0;
  v.back() = 0.0;
  for (std::size_t i = 1; i < n; ++i) v[i] = std::min(v[i], std::sqrt(v[i - 1] * v[i - 1] + 2.0 * params.acceleration * ds[i]));
  for (std::size_t i = n - 1; i-- > 0;) v[i] = std::min(v[i], std::sqrt(v[i + 1] * v[i + 1] + 2.0 * params.acceleration * ds[i + 1]));
  std::vector<double> t(n, 0.0);
  for (std::size_t i = 1; i < n; ++i) t[i] = t[i - 1] + (ds[i] > 0.0 ? 2.0 * ds[i] / (v[i - 1] + v[i]) : 0.0);

  Trajectory out;
  out.times = frame_times(t.back(), params.frame_rate);
  std::size_t i = 0;
  for (const double time : out.times) {
    while (i + 2 < n && t[i + 1] < time) ++i;
    const double w = t[i + 1] > t[i] ? std::clamp((time - t[i]) / (t[i + 1] - t[i]), 0.0, 1.0) : 0.0;
    const Eigen::Vector3d ground = (1.0 - w) * p[i] + w * p[i + 1];
    const Eigen::Vector3d d = p[i + 1] - p[i];
    const double pitch = std::atan2(d.z(), d.head<2>().norm());
    out.T_world_sensor.push_back(pose_from(ground + Eigen::Vector3d(0.0, 0.0, params.sensor_height), heading[i], pitch));
  }
  return out;
}

// ---------------------------------------------------------------------------------------------

PoseList noisy_odometry(const PoseList& truth, const OdometryNoiseParams& params) {
  check_spec(params.translation_sigma >= 0.0 && params.translation_sigma_per_metre >= 0.0 && params.rotation_sigma >= 0.0 &&
            params.rotation_sigma_per_radian >= 0.0,
        "noisy_odometry: noise terms must not be negative");
  PoseList odometry;
  if (truth.empty()) return odometry;
  std::mt19937_64 rng(params.seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  odometry.push_back(truth.front());
  for (std::size_t i = 1; i < truth.size(); ++i) {
    const Pose motion = truth[i - 1].inverse() * truth[i];
    const double sigma_t = params.translation_sigma + params.translation_sigma_per_metre * motion.translation().norm();
    const double sigma_r =
        params.rotation_sigma + params.rotation_sigma_per_radian * Eigen::AngleAxisd(motion.linear()).angle();
    // Always draw six numbers so that the two modes consume the generator alike.
    Eigen::Vector3d dt(normal(rng), normal(rng), normal(rng));
    Eigen::Vector3d dr(normal(rng), normal(rng), normal(rng));
    if (params.axes == OdometryNoiseAxes::kPlanar) {
      dt.z() = 0.0;
      dr.x() = 0.0;
      dr.y() = 0.0;
    }
    dt *= sigma_t;
    dr *= sigma_r;
    Pose noisy = motion;
    noisy.translation() += dt;
    if (dr.norm() > 0.0) noisy.linear() = motion.linear() * Eigen::AngleAxisd(dr.norm(), dr.normalized()).toRotationMatrix();
    odometry.push_back(odometry.back() * noisy);
  }
  return odometry;
}

// ---------------------------------------------------------------------------------------------

StopAndGo stop_and_go(const PoseList& stops, const StopAndGoParams& params) {
  check_spec(!stops.empty(), "stop_and_go: needs at least one stop");
  check_spec(params.stop_duration >= 0.0 && params.speed > 0.0 && params.turn_rate > 0.0 && params.frame_rate > 0.0,
        "stop_and_go: stop_duration must not be negative; speed, turn_rate and frame_rate must be positive");
  // Phase k = 2i is resting at stop i, phase 2i + 1 moving from stop i to i + 1.
  std::vector<double> phase_end;
  double t = 0.0;
  for (std::size_t i = 0; i < stops.size(); ++i) {
    t += params.stop_duration;
    phase_end.push_back(t);
    if (i + 1 == stops.size()) break;
    const Pose move = stops[i].inverse() * stops[i + 1];
    t += std::max(move.translation().norm() / params.speed, Eigen::AngleAxisd(move.linear()).angle() / params.turn_rate);
    phase_end.push_back(t);
  }
  StopAndGo out;
  out.trajectory.times = frame_times(t, params.frame_rate);
  std::size_t phase = 0;
  for (const double time : out.trajectory.times) {
    while (phase + 1 < phase_end.size() && time > phase_end[phase] + 1e-9) ++phase;
    const std::size_t i = phase / 2;
    if (phase % 2 == 0) {
      out.trajectory.T_world_sensor.push_back(stops[i]);
      out.stop.push_back(static_cast<std::int32_t>(i));
      continue;
    }
    const double start = phase_end[phase - 1];
    const double duration = phase_end[phase] - start;
    const double w = duration > 0.0 ? std::clamp((time - start) / duration, 0.0, 1.0) : 1.0;
    Pose T = Pose::Identity();
    T.translation() = (1.0 - w) * stops[i].translation() + w * stops[i + 1].translation();
    T.linear() = Eigen::Quaterniond(stops[i].linear()).slerp(w, Eigen::Quaterniond(stops[i + 1].linear())).toRotationMatrix();
    out.trajectory.T_world_sensor.push_back(T);
    out.stop.push_back(-1);
  }
  return out;
}

Pose pose_at(const Trajectory& trajectory, double t) {
  const auto& T = trajectory.T_world_sensor;
  const auto& times = trajectory.times;
  check_spec(!T.empty() && T.size() == times.size(), "pose_at: the trajectory is empty or its times do not match its poses");
  if (T.size() == 1 || !(t > times.front())) return T.front();
  if (t >= times.back()) return T.back();
  const std::size_t k = static_cast<std::size_t>(std::upper_bound(times.begin(), times.end(), t) - times.begin()) - 1;
  const double dt = times[k + 1] - times[k];
  check_spec(dt > 0.0, "pose_at: the trajectory's times must increase");
  const double u = (t - times[k]) / dt;
  // Catmull-Rom: the tangent at a frame is the velocity by central differences (one-sided at the
  // ends), times the segment's duration (Hermite's tangents are per unit of u).
  const auto p = [&](std::size_t i) -> Eigen::Vector3d { return T[i].translation(); };
  const auto velocity = [&](std::size_t i) -> Eigen::Vector3d {
    const std::size_t a = i > 0 ? i - 1 : i;
    const std::size_t b = i + 1 < T.size() ? i + 1 : i;
    return (p(b) - p(a)) / (times[b] - times[a]);
  };
  const Eigen::Vector3d m0 = velocity(k) * dt;
  const Eigen::Vector3d m1 = velocity(k + 1) * dt;
  const double u2 = u * u;
  const double u3 = u2 * u;
  Pose out = Pose::Identity();
  out.translation() = (2 * u3 - 3 * u2 + 1) * p(k) + (u3 - 2 * u2 + u) * m0 + (-2 * u3 + 3 * u2) * p(k + 1) + (u3 - u2) * m1;
  const Eigen::Quaterniond q0(T[k].linear());
  const Eigen::Quaterniond q1(T[k + 1].linear());
  out.linear() = q0.slerp(u, q1).toRotationMatrix();
  return out;
}

}  // namespace hmap::sim
