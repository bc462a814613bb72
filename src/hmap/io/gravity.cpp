#include "hmap/io/gravity.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "hmap/core/error.hpp"
#include "hmap/io/read_support.hpp"

namespace hmap {

Eigen::Vector3d parse_up_axis(std::string_view axis) {
  std::string a(axis);
  for (char& c : a) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  double sign = 1.0;
  if (!a.empty() && (a.front() == '+' || a.front() == '-')) {
    sign = a.front() == '-' ? -1.0 : 1.0;
    a.erase(0, 1);
  }
  if (a == "x") return sign * Eigen::Vector3d::UnitX();
  if (a == "y") return sign * Eigen::Vector3d::UnitY();
  if (a == "z") return sign * Eigen::Vector3d::UnitZ();
  throw Error("up axis '" + std::string(axis) + "': expected x, y or z with an optional sign (e.g. -y)");
}

Pose parse_rotation(std::string_view text) {
  std::string cleaned(text);
  for (char& c : cleaned) {
    if (c == ',' || c == ';') c = ' ';
  }
  std::vector<std::string_view> tokens;
  detail::split_whitespace(cleaned, tokens);
  Eigen::Matrix3d r;
  if (tokens.size() != 9) throw Error("rotation '" + std::string(text) + "': expected 9 numbers (row-major)");
  for (std::size_t k = 0; k < 9; ++k) {
    double v = 0.0;
    if (!detail::parse_double(tokens[k], v) || !std::isfinite(v)) {
      throw Error("rotation '" + std::string(text) + "': " + detail::quoted(tokens[k]) + " is not a number");
    }
    r(static_cast<Eigen::Index>(k / 3), static_cast<Eigen::Index>(k % 3)) = v;
  }
  if ((r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-3 || std::abs(r.determinant() - 1.0) > 1e-3) {
    throw Error("rotation '" + std::string(text) + "': not orthonormal with determinant +1");
  }
  Pose pose = Pose::Identity();
  pose.linear() = Eigen::Quaterniond(r).normalized().toRotationMatrix();
  return pose;
}

Pose gravity_rotation(const Eigen::Vector3d& up_world) {
  if (!(up_world.norm() > 0.0) || !up_world.allFinite()) throw Error("the up vector must be finite and non-zero");
  Pose T_map_world = Pose::Identity();
  T_map_world.linear() = Eigen::Quaterniond::FromTwoVectors(up_world.normalized(), Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return T_map_world;
}

FloorEstimate estimate_floor(std::span<const Point3f> points_world, const Eigen::Vector3d& prior_up_world,
                             const FloorParams& params, std::span<const Eigen::Vector3d> sensors_world) {
  FloorEstimate best;
  best.points = points_world.size();
  if (points_world.size() < 3 || !(prior_up_world.norm() > 0.0)) return best;
  const Eigen::Vector3d prior = prior_up_world.normalized();
  const double min_cos = std::cos(params.max_tilt);
  std::mt19937 rng(params.seed);
  std::uniform_int_distribution<std::size_t> pick(0, points_world.size() - 1);
  Eigen::Vector3d best_n = prior;
  double best_d = 0.0;
  std::size_t best_count = 0;
  const auto near_a_sensor = [&](const Eigen::Vector3d& n, double d) {
    if (sensors_world.empty()) return true;
    return std::any_of(sensors_world.begin(), sensors_world.end(),
                       [&](const Eigen::Vector3d& s) {
                         const double above = n.dot(s) - d;
                         return params.below_sensors ? above > 0.0 && above <= params.max_sensor_distance
                                                     : std::abs(above) <= params.max_sensor_distance;
                       });
  };
  const auto count_inliers = [&](const Eigen::Vector3d& n, double d) {
    std::size_t count = 0;
    for (const auto& p : points_world) count += std::abs(n.dot(p.cast<double>()) - d) <= params.inlier_distance ? 1U : 0U;
    return count;
  };
  for (int it = 0; it < params.iterations; ++it) {
    const Eigen::Vector3d a = points_world[pick(rng)].cast<double>();
    const Eigen::Vector3d b = points_world[pick(rng)].cast<double>();
    const Eigen::Vector3d c = points_world[pick(rng)].cast<double>();
    Eigen::Vector3d n = (b - a).cross(c - a);
    if (!(n.norm() > 1e-9)) continue;
    n.normalize();
    if (n.dot(prior) < 0.0) n = -n;
    if (n.dot(prior) < min_cos) continue;
    const double d = n.dot(a);
    if (!near_a_sensor(n, d)) continue;
    const std::size_t count = count_inliers(n, d);
    if (count > best_count) {
      best_count = count;
      best_n = n;
      best_d = d;
    }
  }
  if (best_count < 3 || static_cast<double>(best_count) < params.min_inlier_fraction * static_cast<double>(points_world.size())) {
    return best;
  }
  // Least-squares refinement: the normal is the smallest-eigenvalue eigenvector of the inliers' scatter.
  for (int round = 0; round < 2; ++round) {
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    std::size_t n_in = 0;
    for (const auto& p : points_world) {
      if (std::abs(best_n.dot(p.cast<double>()) - best_d) <= params.inlier_distance) {
        mean += p.cast<double>();
        ++n_in;
      }
    }
    mean /= static_cast<double>(n_in);
    Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
    for (const auto& p : points_world) {
      const Eigen::Vector3d q = p.cast<double>();
      if (std::abs(best_n.dot(q) - best_d) <= params.inlier_distance) scatter += (q - mean) * (q - mean).transpose();
    }
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(scatter);
    Eigen::Vector3d n = eig.eigenvectors().col(0);
    if (n.dot(prior) < 0.0) n = -n;
    best_n = n.normalized();
    best_d = best_n.dot(mean);
  }
  best.found = true;
  best.up_world = best_n;
  best.height = best_d;
  best.inliers = count_inliers(best_n, best_d);
  return best;
}

bool orient_floor_below_sensors(FloorEstimate& floor, std::span<const Eigen::Vector3d> sensors_world,
                                const Eigen::Vector3d& prior_up_world, double min_tilt) {
  if (!floor.found || sensors_world.empty() || !(prior_up_world.norm() > 0.0)) return false;
  for (const Eigen::Vector3d& s : sensors_world) {
    if (floor.up_world.dot(s) - floor.height >= 0.0) return false;  // a sensor above it: a floor
  }
  if (floor.up_world.dot(prior_up_world.normalized()) >= std::cos(min_tilt)) return false;  // a ceiling
  floor.up_world = -floor.up_world;
  floor.height = -floor.height;
  return true;
}

std::optional<SensorFloor> floor_under_sensor(std::span<const Point3f> points_sensor, const Eigen::Vector3d& prior_up_sensor,
                                              const FloorParams& params) {
  const std::array<Eigen::Vector3d, 1> sensor{Eigen::Vector3d::Zero()};
  FloorParams below = params;
  below.below_sensors = true;
  const FloorEstimate floor = estimate_floor(points_sensor, prior_up_sensor, below, sensor);
  // The floor {p : up · p = height} lies below the sensor at the origin: height < 0 (the least
  // squares refit could in principle carry it through the sensor).
  if (!floor.found || !(floor.height < 0.0)) return std::nullopt;
  SensorFloor out;
  out.up_sensor = floor.up_world;
  out.sensor_height = -floor.height;
  out.inliers = floor.inliers;
  out.points = floor.points;
  return out;
}

}  // namespace hmap
