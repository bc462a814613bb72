#include "hmap/io/kitti.hpp"

#include <Eigen/SVD>
#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <string_view>
#include <system_error>

#include "hmap/core/error.hpp"
#include "hmap/io/poses.hpp"
#include "hmap/io/read_support.hpp"

namespace hmap {

namespace {

using detail::line_position;

constexpr std::size_t kBytesPerPoint = 16;  // float32 x, y, z, intensity

/// Tr of a KITTI calib.txt ("Tr: r11 r12 r13 tx r21 ... tz"), or nothing when no line has it.
std::optional<Pose> read_calib_tr(const std::filesystem::path& path) {
  const std::string bytes = detail::read_file_bytes(path);
  detail::LineReader lines(bytes);
  std::vector<std::string_view> tokens;
  std::string_view line;
  while (lines.next(line)) {
    detail::split_whitespace(line, tokens);
    if (tokens.empty() || tokens.front() != "Tr:") continue;
    const std::size_t n = lines.line_number();
    if (tokens.size() != 13) {
      throw InputError(path.string(), line_position(n),
                       "Tr expects 12 values (3×4 row-major), found " + std::to_string(tokens.size() - 1));
    }
    Eigen::Matrix<double, 3, 4> m;
    for (int k = 0; k < 12; ++k) {
      double value = 0.0;
      if (!detail::parse_double(tokens[k + 1], value) || !std::isfinite(value)) {
        throw InputError(path.string(), line_position(n),
                         "Tr value " + detail::quoted(tokens[k + 1]) + " is not a finite number");
      }
      m(k / 4, k % 4) = value;
    }
    const double error =
        (m.leftCols<3>().transpose() * m.leftCols<3>() - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
    if (error > 1e-3 || m.leftCols<3>().determinant() < 0.99) {
      throw InputError(path.string(), line_position(n), "Tr's 3×3 part is not a rotation");
    }
    Pose tr = Pose::Identity();
    // Re-orthonormalise like read_poses (R = U Vᵀ): Tr is printed with 9 digits.
    const Eigen::JacobiSVD<Eigen::Matrix3d> svd(m.leftCols<3>(), Eigen::ComputeFullU | Eigen::ComputeFullV);
    tr.linear() = svd.matrixU() * svd.matrixV().transpose();
    tr.translation() = m.col(3);
    return tr;
  }
  return std::nullopt;
}

/// Whether `path` is there to be read; an error while checking (no permission) counts as
/// present, so that reading it reports the error.
bool file_exists(const std::filesystem::path& path) {
  std::error_code ec;
  return std::filesystem::exists(path, ec) || ec;
}

std::vector<std::filesystem::path> list_scans(const std::filesystem::path& velodyne) {
  std::error_code ec;
  std::filesystem::directory_iterator it(velodyne, ec);
  if (ec) throw InputError(velodyne.string(), "", "cannot open: " + ec.message());
  std::vector<std::filesystem::path> scans;
  std::vector<std::filesystem::path> pcd;  // scans with per-point time (hmap simulate --sweep)
  for (; it != std::filesystem::directory_iterator(); it.increment(ec)) {
    if (ec) throw InputError(velodyne.string(), "", "cannot list: " + ec.message());
    if (it->path().extension() == ".bin") scans.push_back(it->path());
    if (it->path().extension() == ".pcd") pcd.push_back(it->path());
  }
  if (scans.empty()) scans = std::move(pcd);
  std::sort(scans.begin(), scans.end());
  if (scans.empty()) throw InputError(velodyne.string(), "", "no .bin (or .pcd) scans");
  return scans;
}

}  // namespace

std::vector<double> read_kitti_times(const std::filesystem::path& path) {
  const std::string bytes = detail::read_file_bytes(path);
  detail::LineReader lines(bytes);
  std::vector<std::string_view> tokens;
  std::vector<double> times;
  std::string_view line;
  while (lines.next(line)) {
    detail::split_whitespace(line, tokens);
    if (tokens.empty() || tokens.front().starts_with('#')) continue;
    double t = 0.0;
    if (tokens.size() != 1 || !detail::parse_double(tokens.front(), t) || !std::isfinite(t)) {
      throw InputError(path.string(), line_position(lines.line_number()),
                       "expected one finite timestamp [s]");
    }
    times.push_back(t);
  }
  return times;
}

PointCloud read_kitti_bin(const std::filesystem::path& path, CloudReadStats* stats) {
  CloudReadStats local;
  PointCloud cloud;
  std::size_t size = 0;  // the file's, when it is a regular file
  std::size_t kept = 0;
  // Record by record as the file streams in: a scan is read in 256 KiB pieces, not into a
  // buffer of its own size first (1.3 MB per OS0-64 scan, zero-filled, then copied again).
  const std::size_t bytes = detail::read_file_records(
      path, kBytesPerPoint,
      [&](std::span<const char> records) {
        const std::size_t n = records.size() / kBytesPerPoint;
        if (cloud.size() < kept + n) cloud.resize(std::max(kept + n, size / kBytesPerPoint));
        Point3f* out = cloud.data() + kept;
        std::size_t written = 0;
        const char* record = records.data();
        for (std::size_t i = 0; i < n; ++i, record += kBytesPerPoint) {
          const auto x = detail::load<float>(record, detail::kSwapLittleEndian);
          const auto y = detail::load<float>(record + 4, detail::kSwapLittleEndian);
          const auto z = detail::load<float>(record + 8, detail::kSwapLittleEndian);
          // Written either way, kept only when finite: no branch on the data.
          out[written] = Point3f(x, y, z);
          written += std::isfinite(x) && std::isfinite(y) && std::isfinite(z) ? 1 : 0;
        }
        local.non_finite_dropped += n - written;
        kept += written;
      },
      detail::kMaxInputBytes, &size);
  cloud.resize(kept);
  if (bytes % kBytesPerPoint != 0) {
    throw InputError(path.string(), "",
                     "size " + std::to_string(bytes) +
                         " bytes is not a multiple of 16 (float32 x, y, z, intensity); truncated?");
  }
  local.points_read = bytes / kBytesPerPoint;
  if (stats != nullptr) *stats = local;
  return cloud;
}

KittiSequence open_kitti_sequence(const std::filesystem::path& dir, const KittiSequenceOptions& options) {
  KittiSequence sequence;
  sequence.dir = dir;
  sequence.scan_paths = list_scans(dir / "velodyne");
  if (options.max_scans && *options.max_scans < sequence.scan_paths.size()) {
    sequence.scan_paths.resize(*options.max_scans);
  }
  const std::size_t scans = sequence.scan_paths.size();

  if (const auto calib = dir / "calib.txt"; file_exists(calib)) {
    sequence.T_cam_velo = read_calib_tr(calib);
  }
  if (const auto poses_path = dir / "poses.txt"; file_exists(poses_path)) {
    PoseList poses = read_poses(poses_path);
    // With a scan limit, lines beyond the scans used are ignored; too few is still an error.
    if (options.max_scans && poses.size() > scans) poses.resize(scans);
    if (sequence.T_cam_velo) {
      const Pose& Tr = *sequence.T_cam_velo;
      const Pose Tr_inverse = Tr.inverse();
      for (Pose& P : poses) P = Tr_inverse * P * Tr;
    }
    sequence.T_map_scan = std::move(poses);
  }
  if (const auto times_path = dir / "times.txt"; file_exists(times_path)) {
    sequence.times = read_kitti_times(times_path);
    if (options.max_scans && sequence.times.size() > scans) sequence.times.resize(scans);
  }
  check_kitti_sequence(sequence);
  return sequence;
}

void check_kitti_sequence(const KittiSequence& sequence) {
  const std::size_t scans = sequence.scan_paths.size();
  if (sequence.T_map_scan && sequence.T_map_scan->size() != scans) {
    throw InputError((sequence.dir / "poses.txt").string(), "",
                     std::to_string(sequence.T_map_scan->size()) + " poses for " + std::to_string(scans) +
                         " scans in velodyne/; expected one pose per scan");
  }
  if (!sequence.times.empty() && sequence.times.size() != scans) {
    throw InputError((sequence.dir / "times.txt").string(), "",
                     std::to_string(sequence.times.size()) + " timestamps for " + std::to_string(scans) +
                         " scans in velodyne/; expected one per scan");
  }
}

}  // namespace hmap
