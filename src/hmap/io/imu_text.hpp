#pragma once
// IMU samples from a text file (for scan folders; bags carry sensor_msgs/Imu instead).
//
// One sample per line, values separated by spaces, tabs or commas:
//   t gx gy gz ax ay az [qx qy qz qw]
// t [s] (or [ns] when every stamp exceeds 1e14, as EuRoC's imu0/data.csv writes them), the
// gyro's angular velocity [rad/s], the accelerometer's specific force [m/s²] (+9.81 up at rest),
// optionally the IMU's own orientation (world ← imu, a quaternion, normalised on reading). Lines
// that are empty or start with '#' are skipped. Stamps must increase strictly.

#include <filesystem>

#include "hmap/core/imu.hpp"

namespace hmap {

/// Throws InputError naming the file and the line for a line with another number of values than 7
/// or 11, a value that is not a finite number, a zero quaternion, a stamp not after the previous
/// one, or a file with no sample.
[[nodiscard]] ImuSamples read_imu_text(const std::filesystem::path& path);

/// Writes `samples` in the format read_imu_text reads (t gx gy gz ax ay az, the orientation when a
/// sample has one), shortest round-trip decimals, atomically. Throws hmap::Error for a value that
/// is not finite.
void write_imu_text(const std::filesystem::path& path, const ImuSamples& samples);

}  // namespace hmap
