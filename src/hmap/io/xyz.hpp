#pragma once
// Reader for plain-text point lists: .xyz, .txt, .csv, .pts.

#include <filesystem>

#include "hmap/core/types.hpp"
#include "hmap/io/cloud_stats.hpp"

namespace hmap {

/// Reads one point per line: three or more numbers separated by whitespace and/or one comma or
/// semicolon. Blank lines and lines starting with '#' are skipped. The first other line is a
/// header when its first three fields are not all numbers (or it has fewer than three, like the
/// point count of a .pts file); a header naming columns x, y and z (any case, quoted, or as in
/// CloudCompare's "//X") selects those columns, otherwise x, y, z are the first three. Only the x,
/// y, z columns are parsed, so other columns may hold anything. Non-finite points are dropped and
/// counted in `stats`. A malformed data line throws InputError naming its line number.
[[nodiscard]] PointCloud read_xyz(const std::filesystem::path& path, CloudReadStats* stats = nullptr);

}  // namespace hmap
