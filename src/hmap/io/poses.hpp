#pragma once
// Trajectory files: KITTI (3×4 row-major T_map_scan per line) and TUM (t tx ty tz qx qy qz qw).

#include <filesystem>
#include <span>
#include <vector>

#include "hmap/core/types.hpp"

namespace hmap {

enum class PoseFileFormat : std::uint8_t {
  kKitti,  ///< 12 numbers per line: the first three rows of the 4×4 matrix, row-major
  kTum,    ///< 8 numbers per line: timestamp [s], translation [m], quaternion x y z w
};

/// The poses of a trajectory file, with their timestamps when the format has them.
struct PoseFile {
  PoseFileFormat format = PoseFileFormat::kKitti;
  PoseList poses;
  std::vector<double> times;  ///< [s], one per pose for TUM; empty for KITTI
};

/// Reads a KITTI or TUM trajectory, the format told by the first data line (12 or 8 numbers; all
/// lines must agree). Values are separated by whitespace or commas; blank lines and lines starting
/// with '#' are skipped. Rotations are checked (|RᵀR − I| <= 1e-3 elementwise, det within 1 ± 0.01;
/// quaternion norm within 1 ± 1e-3) and then made exactly orthonormal, so the 9-digit rounding
/// of KITTI files passes. Throws InputError naming the 1-based line of a wrong value count, a
/// non-number, NaN or infinity, or a rotation that is not one.
[[nodiscard]] PoseFile read_pose_file(const std::filesystem::path& path);

/// read_pose_file, with stamps for a KITTI file too: those of `times.txt` in the file's folder
/// (KITTI's layout, one line per pose) when there is one, else none. TUM files carry their own.
/// Throws InputError naming times.txt when its count is not the poses'.
[[nodiscard]] PoseFile read_stamped_pose_file(const std::filesystem::path& path);

/// read_pose_file(path).poses.
[[nodiscard]] PoseList read_poses(const std::filesystem::path& path);

/// Writes one KITTI line per pose (shortest decimal that reads back to the same double), replacing
/// `path` atomically. Throws hmap::Error if a pose is not finite.
void write_poses_kitti(const std::filesystem::path& path, const PoseList& poses);

/// Writes one TUM line per pose, replacing `path` atomically. Throws hmap::Error if the counts of
/// times and poses differ or a value is not finite.
void write_poses_tum(const std::filesystem::path& path, std::span<const double> times, const PoseList& poses);

}  // namespace hmap
