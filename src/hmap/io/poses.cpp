#include "hmap/io/poses.hpp"

#include <Eigen/SVD>
#include <array>
#include <charconv>
#include <cmath>
#include <ostream>
#include <string>
#include <string_view>

#include "hmap/core/error.hpp"
#include "hmap/io/atomic_file.hpp"
#include "hmap/io/kitti.hpp"
#include "hmap/io/read_support.hpp"

namespace hmap {

namespace {

using detail::line_position;

constexpr double kOrthonormalTolerance = 1e-3;  ///< elementwise on RᵀR − I
constexpr double kDeterminantTolerance = 0.01;
constexpr double kQuaternionNormTolerance = 1e-3;

/// Splits at whitespace and commas (some tools write CSV trajectories).
void split_values(std::string_view line, std::vector<std::string_view>& tokens) {
  tokens.clear();
  std::size_t i = 0;
  const auto is_separator = [](char c) { return c == ' ' || c == '\t' || c == ','; };
  while (i < line.size()) {
    while (i < line.size() && is_separator(line[i])) ++i;
    const std::size_t start = i;
    while (i < line.size() && !is_separator(line[i])) ++i;
    if (i > start) tokens.push_back(line.substr(start, i - start));
  }
}

/// The nearest rotation to a matrix already checked to be nearly one (SVD: R = U Vᵀ).
Eigen::Matrix3d orthonormalized(const Eigen::Matrix3d& m) {
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(m, Eigen::ComputeFullU | Eigen::ComputeFullV);
  return svd.matrixU() * svd.matrixV().transpose();
}

Pose kitti_pose(const std::array<double, 12>& v, const std::string& source, std::size_t line) {
  Eigen::Matrix3d rotation;
  rotation << v[0], v[1], v[2], v[4], v[5], v[6], v[8], v[9], v[10];
  const double orthogonality_error =
      (rotation.transpose() * rotation - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  const double determinant = rotation.determinant();
  if (orthogonality_error > kOrthonormalTolerance || std::abs(determinant - 1.0) > kDeterminantTolerance) {
    throw InputError(
        source, line_position(line),
        "the 3×3 part is not a rotation (max |RᵀR − I| = " + std::to_string(orthogonality_error) +
            ", det = " + std::to_string(determinant) + ")");
  }
  Pose pose = Pose::Identity();
  pose.linear() = orthonormalized(rotation);
  pose.translation() = Eigen::Vector3d(v[3], v[7], v[11]);
  return pose;
}

Pose tum_pose(const std::array<double, 12>& v, const std::string& source, std::size_t line) {
  // v[0] is the timestamp.
  Eigen::Quaterniond q(v[7], v[4], v[5], v[6]);  // Eigen takes w first
  const double norm = q.norm();
  if (std::abs(norm - 1.0) > kQuaternionNormTolerance) {
    throw InputError(source, line_position(line),
                     "quaternion norm " + std::to_string(norm) + " is not 1; not a rotation");
  }
  q.normalize();
  Pose pose = Pose::Identity();
  pose.linear() = q.toRotationMatrix();
  pose.translation() = Eigen::Vector3d(v[1], v[2], v[3]);
  return pose;
}

/// Appends the shortest decimal that reads back as the same double.
void append_number(std::string& out, double value) {
  char buffer[32];
  const auto [end, ec] = std::to_chars(buffer, buffer + sizeof buffer, value);
  out.append(buffer, ec == std::errc() ? end : buffer);
}

void check_finite(const std::filesystem::path& path, const Pose& pose, std::size_t index) {
  if (!pose.matrix().allFinite()) {
    throw Error(path.string() + ": pose " + std::to_string(index) + " is not finite");
  }
}

}  // namespace

PoseFile read_pose_file(const std::filesystem::path& path) {
  const std::string bytes = detail::read_file_bytes(path);
  const std::string source = path.string();
  PoseFile file;
  std::size_t values_per_line = 0;  // fixed by the first data line

  detail::LineReader lines(bytes);
  std::vector<std::string_view> tokens;
  std::string_view line;
  while (lines.next(line)) {
    split_values(line, tokens);
    if (tokens.empty() || tokens.front().starts_with('#')) continue;
    const std::size_t n = lines.line_number();
    if (values_per_line == 0) {
      if (tokens.size() != 12 && tokens.size() != 8) {
        throw InputError(source, line_position(n),
                         "expected 12 values (KITTI 3×4 matrix) or 8 (TUM t tx ty tz qx qy qz qw), found " +
                             std::to_string(tokens.size()));
      }
      values_per_line = tokens.size();
      file.format = values_per_line == 12 ? PoseFileFormat::kKitti : PoseFileFormat::kTum;
    } else if (tokens.size() != values_per_line) {
      throw InputError(source, line_position(n),
                       "expected " + std::to_string(values_per_line) +
                           " values like the first pose line, found " + std::to_string(tokens.size()));
    }
    std::array<double, 12> v{};
    for (std::size_t k = 0; k < values_per_line; ++k) {
      if (!detail::parse_double(tokens[k], v[k])) {
        throw InputError(
            source, line_position(n),
            "value " + std::to_string(k + 1) + " " + detail::quoted(tokens[k]) + " is not a number");
      }
      if (!std::isfinite(v[k])) {
        throw InputError(
            source, line_position(n),
            "value " + std::to_string(k + 1) + " " + detail::quoted(tokens[k]) + " is not finite");
      }
    }
    if (file.format == PoseFileFormat::kKitti) {
      file.poses.push_back(kitti_pose(v, source, n));
    } else {
      file.times.push_back(v[0]);
      file.poses.push_back(tum_pose(v, source, n));
    }
  }
  return file;
}

PoseFile read_stamped_pose_file(const std::filesystem::path& path) {
  PoseFile file = read_pose_file(path);
  if (file.format != PoseFileFormat::kKitti) return file;
  const std::filesystem::path times_path = path.parent_path() / "times.txt";
  std::error_code ec;
  if (!std::filesystem::is_regular_file(times_path, ec)) return file;
  file.times = read_kitti_times(times_path);
  if (file.times.size() != file.poses.size()) {
    throw InputError(times_path.string(), "", "holds " + std::to_string(file.times.size()) + " timestamps for the " +
                                                  std::to_string(file.poses.size()) + " poses of " + path.string());
  }
  return file;
}

PoseList read_poses(const std::filesystem::path& path) { return read_pose_file(path).poses; }

void write_poses_kitti(const std::filesystem::path& path, const PoseList& poses) {
  std::string text;
  text.reserve(poses.size() * 12 * 24);
  for (std::size_t i = 0; i < poses.size(); ++i) {
    check_finite(path, poses[i], i);
    const Eigen::Matrix4d m = poses[i].matrix();
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 4; ++c) {
        append_number(text, m(r, c));
        text += (r == 2 && c == 3) ? '\n' : ' ';
      }
    }
  }
  write_file_atomic(path, text);
}

void write_poses_tum(const std::filesystem::path& path, std::span<const double> times,
                     const PoseList& poses) {
  if (times.size() != poses.size()) {
    throw Error(path.string() + ": " + std::to_string(times.size()) + " timestamps for " +
                std::to_string(poses.size()) + " poses");
  }
  std::string text;
  text.reserve(poses.size() * 8 * 24);
  for (std::size_t i = 0; i < poses.size(); ++i) {
    check_finite(path, poses[i], i);
    if (!std::isfinite(times[i])) {
      throw Error(path.string() + ": timestamp " + std::to_string(i) + " is not finite");
    }
    const Eigen::Quaterniond q(poses[i].rotation());
    const Eigen::Vector3d t = poses[i].translation();
    for (const double value : {times[i], t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w()}) {
      append_number(text, value);
      text += ' ';
    }
    text.back() = '\n';
  }
  write_file_atomic(path, text);
}

}  // namespace hmap
