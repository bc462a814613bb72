#include "hmap/io/sequence_writer.hpp"

#include <array>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstring>
#include <string>

#include "hmap/core/error.hpp"
#include "hmap/io/atomic_file.hpp"
#include "hmap/io/ply_export.hpp"
#include "hmap/io/poses.hpp"

namespace hmap {
namespace {

static_assert(std::endian::native == std::endian::little, "KITTI .bin files are little-endian");

void check_count(std::size_t count, std::size_t frames, const char* what) {
  if (count != frames) {
    throw Error(std::string("write_simulated_sequence: ") + std::to_string(count) + " " + what + " for " +
                std::to_string(frames) + " frames");
  }
}

}  // namespace

void write_kitti_bin(const std::filesystem::path& path, const PointCloud& cloud) {
  std::string bytes(cloud.size() * 4 * sizeof(float), '\0');
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const std::array<float, 4> record{cloud[i].x(), cloud[i].y(), cloud[i].z(), 0.0F};
    std::memcpy(bytes.data() + i * sizeof(record), record.data(), sizeof(record));
  }
  write_file_atomic(path, bytes);
}

void write_pcd_with_time(const std::filesystem::path& path, const PointCloud& cloud, std::span<const float> times_s) {
  if (times_s.size() != cloud.size()) {
    throw Error("write_pcd_with_time: " + std::to_string(times_s.size()) + " times for " + std::to_string(cloud.size()) +
                " points");
  }
  const std::string n = std::to_string(cloud.size());
  const std::string header = "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z t\nSIZE 4 4 4 4\n"
                             "TYPE F F F F\nCOUNT 1 1 1 1\nWIDTH " + n + "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " +
                             n + "\nDATA binary\n";
  std::string bytes = header;
  bytes.resize(header.size() + cloud.size() * 4 * sizeof(float));
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    if (!std::isfinite(times_s[i])) throw Error("write_pcd_with_time: a time is not finite");
    const std::array<float, 4> record{cloud[i].x(), cloud[i].y(), cloud[i].z(), times_s[i]};
    std::memcpy(bytes.data() + header.size() + i * sizeof(record), record.data(), sizeof(record));
  }
  write_file_atomic(path, bytes);
}

void write_simulated_sequence(const std::filesystem::path& dir, std::span<const PointCloud> frames,
                              const PoseList& true_poses, std::span<const double> times,
                              const PoseList& odometry_poses, const PointCloud& truth_points,
                              std::span<const std::vector<float>> point_times) {
  check_count(true_poses.size(), frames.size(), "true poses");
  check_count(times.size(), frames.size(), "times");
  if (!odometry_poses.empty()) check_count(odometry_poses.size(), frames.size(), "odometry poses");
  if (!point_times.empty()) check_count(point_times.size(), frames.size(), "lists of point times");
  std::error_code error;
  std::filesystem::create_directories(dir / "velodyne", error);
  if (error) throw Error("cannot create " + (dir / "velodyne").string() + ": " + error.message());

  for (std::size_t i = 0; i < frames.size(); ++i) {
    if (point_times.empty()) {
      write_simulated_frame(dir, i, frames[i]);
    } else {
      write_simulated_frame(dir, i, frames[i], point_times[i]);
    }
  }
  write_simulated_records(dir, true_poses, times, odometry_poses, truth_points);
}

namespace {
std::string frame_number(std::size_t index) {
  std::string number = std::to_string(index);
  if (number.size() < 6) number.insert(0, 6 - number.size(), '0');
  return number;
}
}  // namespace

void write_simulated_frame(const std::filesystem::path& dir, std::size_t index, const PointCloud& frame) {
  write_kitti_bin(dir / "velodyne" / (frame_number(index) + ".bin"), frame);
}

void write_simulated_frame(const std::filesystem::path& dir, std::size_t index, const PointCloud& frame,
                           std::span<const float> point_times) {
  write_pcd_with_time(dir / "velodyne" / (frame_number(index) + ".pcd"), frame, point_times);
}

void write_simulated_records(const std::filesystem::path& dir, const PoseList& true_poses, std::span<const double> times,
                             const PoseList& odometry_poses, const PointCloud& truth_points) {
  check_count(times.size(), true_poses.size(), "times");
  if (!odometry_poses.empty()) check_count(odometry_poses.size(), true_poses.size(), "odometry poses");
  write_poses_kitti(dir / "poses.txt", true_poses);
  write_file_atomic(dir / "times.txt", [&](std::ostream& out) {
    for (const double t : times) {
      if (!std::isfinite(t)) throw Error("write_simulated_sequence: a time is not finite");
      std::array<char, 32> text{};
      const auto end = std::to_chars(text.data(), text.data() + text.size(), t).ptr;  // shortest round trip
      out.write(text.data(), end - text.data());
      out.put('\n');
    }
  });
  if (!odometry_poses.empty()) write_poses_kitti(dir / "odometry.txt", odometry_poses);
  if (!truth_points.empty()) write_points_ply(dir / "truth.ply", truth_points);
}

}  // namespace hmap
