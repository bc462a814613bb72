#pragma once
// Per-point time of a sweep (PCD fields and PointCloud2 fields named t, time or timestamp).

#include <string>
#include <vector>

namespace hmap {

/// The field names read as per-point time, in order of preference.
inline constexpr const char* kPointTimeFields[] = {"t", "time", "timestamp"};

/// Turns raw per-point times into seconds from the scan's reference time, in place of `raw`.
/// Units from the sweep's span (max − min), which for any scan period in [0.01, 1] s tells them
/// apart: span ≤ 2 → seconds; ≤ 2·10³ → milliseconds; ≤ 2·10⁶ → microseconds; more → nanoseconds
/// (Ouster's `t` is uint32 ns from the sweep's start, Velodyne's `time` float seconds). Relative
/// times (|min| under a day once scaled) keep their zero, which the drivers put at the message's
/// stamp; absolute ones (unix time) are taken from the sweep's first point.
[[nodiscard]] std::vector<float> point_times_to_seconds(const std::vector<double>& raw);

}  // namespace hmap
