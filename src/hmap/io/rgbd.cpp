#include "hmap/io/rgbd.hpp"

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <limits>
#include <string_view>

#include "hmap/core/error.hpp"
#include "hmap/io/poses.hpp"
#include "hmap/io/read_support.hpp"

namespace hmap {

namespace fs = std::filesystem;

namespace {

constexpr std::string_view kDepthSuffix = ".depth.png";

bool is_7scenes_depth(const fs::path& p) {
  const std::string name = p.filename().string();
  return name.starts_with("frame-") && name.size() > kDepthSuffix.size() && name.ends_with(kDepthSuffix);
}

std::vector<fs::path> sorted_depth_frames(const fs::path& dir) {
  std::vector<fs::path> found;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    if (entry.is_regular_file() && is_7scenes_depth(entry.path())) found.push_back(entry.path());
  }
  std::sort(found.begin(), found.end());
  return found;
}

/// 7-Scenes: frame-N.depth.png in `dir`, or in its sub-folders (seq-01/, seq-02/...) in name order.
void open_7scenes(RgbdSequence& seq, const RgbdOptions& options) {
  std::vector<fs::path> depth = sorted_depth_frames(seq.dir);
  if (depth.empty()) {
    std::vector<fs::path> subdirs;
    for (const auto& entry : fs::directory_iterator(seq.dir)) {
      if (entry.is_directory()) subdirs.push_back(entry.path());
    }
    std::sort(subdirs.begin(), subdirs.end());
    for (const auto& sub : subdirs) {
      const auto more = sorted_depth_frames(sub);
      depth.insert(depth.end(), more.begin(), more.end());
    }
  }
  if (depth.empty()) throw InputError(seq.dir.string(), "", "holds no frame-*.depth.png (7-Scenes) nor depth.txt (TUM)");
  seq.camera.depth_scale = 0.001;
  seq.camera.invalid_value = 65535;
  for (const fs::path& dir : {seq.dir, depth.front().parent_path()}) {
    if (!options.intrinsics && fs::exists(dir / "camera-intrinsics.txt")) {
      seq.camera = read_intrinsics(dir / "camera-intrinsics.txt", seq.camera);
      break;
    }
  }
  for (const auto& png : depth) {
    const std::string name = png.filename().string();
    const std::string stem = name.substr(0, name.size() - kDepthSuffix.size());
    const fs::path pose_path = png.parent_path() / (stem + ".pose.txt");
    std::optional<Pose> pose;
    if (fs::exists(pose_path)) pose = read_matrix4_pose(pose_path);
    if (!pose) {
      ++seq.frames_without_pose;
      continue;
    }
    double number = 0.0;
    (void)detail::parse_double(stem.substr(6), number);
    seq.frames.push_back({png, *pose, number});
    if (options.max_frames > 0 && seq.frames.size() == options.max_frames) break;
  }
}

/// TUM RGB-D: depth.txt lists "t depth/t.png"; groundtruth.txt is a TUM trajectory of the camera.
void open_tum(RgbdSequence& seq, const RgbdOptions& options) {
  seq.layout = RgbdLayout::kTum;
  // TUM's recommended intrinsics for its registered depth (the "ROS default"); 5000 units per metre.
  seq.camera = DepthCamera{525.0, 525.0, 319.5, 239.5, 1.0 / 5000.0, 0};
  if (!options.intrinsics && fs::exists(seq.dir / "camera-intrinsics.txt")) {
    seq.camera = read_intrinsics(seq.dir / "camera-intrinsics.txt", seq.camera);
  }
  const fs::path list = seq.dir / "depth.txt";
  const fs::path gt_path = seq.dir / "groundtruth.txt";
  if (!fs::exists(gt_path)) throw InputError(gt_path.string(), "", "missing: a TUM folder needs the camera's ground-truth trajectory");
  const PoseFile gt = read_pose_file(gt_path);
  if (gt.format != PoseFileFormat::kTum) throw InputError(gt_path.string(), "", "expected TUM lines: t tx ty tz qx qy qz qw");
  for (std::size_t k = 1; k < gt.times.size(); ++k) {
    if (!(gt.times[k] > gt.times[k - 1])) {
      throw InputError(gt_path.string(), "pose " + std::to_string(k + 1), "timestamps must increase");
    }
  }
  const std::string bytes = detail::read_file_bytes(list);
  detail::LineReader lines(bytes);
  std::string_view line;
  std::vector<std::string_view> tokens;
  double last_time = -std::numeric_limits<double>::infinity();
  while (lines.next(line)) {
    detail::split_whitespace(line, tokens);
    if (tokens.empty() || tokens.front().starts_with("#")) continue;
    double t = 0.0;
    if (tokens.size() != 2 || !detail::parse_double(tokens[0], t) || !std::isfinite(t)) {
      throw InputError(list.string(), detail::line_position(lines.line_number()),
                       "expected \"timestamp file\", found " + detail::quoted(line));
    }
    if (!(t > last_time)) throw InputError(list.string(), detail::line_position(lines.line_number()), "timestamps must increase");
    last_time = t;
    // The ground-truth poses around t, interpolated (slerp) when close enough in time.
    const auto after = std::lower_bound(gt.times.begin(), gt.times.end(), t);
    std::optional<Pose> pose;
    if (after != gt.times.end() && *after == t) {
      pose = gt.poses[static_cast<std::size_t>(after - gt.times.begin())];
    } else if (after != gt.times.begin() && after != gt.times.end() && *after - *(after - 1) <= options.max_pose_gap) {
      const auto k = static_cast<std::size_t>(after - gt.times.begin());
      const double a = (t - gt.times[k - 1]) / (gt.times[k] - gt.times[k - 1]);
      const Pose& p0 = gt.poses[k - 1];
      const Pose& p1 = gt.poses[k];
      Pose p = Pose::Identity();
      p.linear() = Eigen::Quaterniond(p0.linear()).slerp(a, Eigen::Quaterniond(p1.linear())).toRotationMatrix();
      p.translation() = (1.0 - a) * p0.translation() + a * p1.translation();
      pose = p;
    }
    if (!pose) {
      ++seq.frames_without_pose;
      continue;
    }
    seq.frames.push_back({seq.dir / fs::path(std::string(tokens[1])), *pose, t});
    if (options.max_frames > 0 && seq.frames.size() == options.max_frames) break;
  }
}

}  // namespace

std::optional<Pose> read_matrix4_pose(const fs::path& path) {
  const std::string bytes = detail::read_file_bytes(path);
  std::vector<std::string_view> tokens;
  std::vector<double> values;
  detail::LineReader lines(bytes);
  std::string_view line;
  bool finite = true;
  while (lines.next(line)) {
    detail::split_whitespace(line, tokens);
    for (const auto token : tokens) {
      double value = 0.0;
      if (!detail::parse_double(token, value)) {
        throw InputError(path.string(), detail::line_position(lines.line_number()),
                         "expected a number, found " + detail::quoted(token));
      }
      if (values.size() == 16) {
        throw InputError(path.string(), detail::line_position(lines.line_number()), "more than 16 numbers: expected a 4x4 matrix");
      }
      finite = finite && std::isfinite(value);
      values.push_back(value);
    }
  }
  if (values.size() != 16) {
    throw InputError(path.string(), "", "holds " + std::to_string(values.size()) + " numbers: expected a 4x4 matrix");
  }
  if (!finite) return std::nullopt;
  Eigen::Matrix4d m;
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) m(r, c) = values[static_cast<std::size_t>(r * 4 + c)];
  }
  const Eigen::Matrix3d rotation = m.topLeftCorner<3, 3>();
  if ((rotation.transpose() * rotation - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-3 ||
      std::abs(rotation.determinant() - 1.0) > 1e-2 ||
      (m.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > 1e-6) {
    throw InputError(path.string(), "", "is not a rigid transform (rotation not orthonormal or last row not 0 0 0 1)");
  }
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(rotation, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Pose pose = Pose::Identity();
  pose.linear() = svd.matrixU() * svd.matrixV().transpose();
  pose.translation() = m.topRightCorner<3, 1>();
  return pose;
}

RgbdSequence open_rgbd_sequence(const fs::path& dir, const RgbdOptions& options) {
  if (!fs::is_directory(dir)) throw InputError(dir.string(), "", "is not a folder");
  RgbdSequence seq;
  seq.dir = dir;
  if (fs::exists(dir / "depth.txt")) {
    open_tum(seq, options);
  } else {
    open_7scenes(seq, options);
  }
  if (options.intrinsics) seq.camera = read_intrinsics(*options.intrinsics, seq.camera);
  if (options.depth_scale) {
    if (!(*options.depth_scale > 0.0) || !std::isfinite(*options.depth_scale)) {
      throw Error("the depth scale must be a positive number of metres per unit");
    }
    seq.camera.depth_scale = *options.depth_scale;
  }
  if (seq.frames.empty()) {
    throw InputError(dir.string(), "", "no depth frame has a pose (" + std::to_string(seq.frames_without_pose) +
                                           " frames without one)");
  }
  return seq;
}

PointCloud read_rgbd_frame(const RgbdSequence& sequence, std::size_t index, CloudReadStats* stats) {
  const DepthImage image = read_depth_png(sequence.frames.at(index).depth_png);
  PointCloud points_cam;
  points_cam.reserve(image.pixels.size());
  depth_to_points(image, sequence.camera, points_cam, stats);
  return points_cam;
}

}  // namespace hmap
