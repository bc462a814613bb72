#include "hmap/io/vtk.hpp"

#include <algorithm>
#include <cctype>
#include <string>
#include <string_view>
#include <vector>

#include "hmap/core/error.hpp"
#include "hmap/io/read_support.hpp"

namespace hmap {

namespace {

using detail::line_position;
using detail::ScalarType;

std::string upper(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return out;
}

bool vtk_type(std::string_view name, ScalarType& type) {
  const std::string t = upper(name);
  if (t == "FLOAT") type = ScalarType::kFloat32;
  else if (t == "DOUBLE") type = ScalarType::kFloat64;
  else if (t == "CHAR") type = ScalarType::kInt8;
  else if (t == "UNSIGNED_CHAR") type = ScalarType::kUint8;
  else if (t == "SHORT") type = ScalarType::kInt16;
  else if (t == "UNSIGNED_SHORT") type = ScalarType::kUint16;
  else if (t == "INT") type = ScalarType::kInt32;
  else if (t == "UNSIGNED_INT") type = ScalarType::kUint32;
  else if (t == "LONG" || t == "VTKTYPEINT64") type = ScalarType::kInt64;
  else if (t == "UNSIGNED_LONG" || t == "VTKTYPEUINT64") type = ScalarType::kUint64;
  else return false;
  return true;
}

}  // namespace

PointCloud read_vtk(const std::filesystem::path& path, CloudReadStats* stats) {
  const std::string bytes = detail::read_file_bytes(path);
  const std::string source = path.string();
  detail::LineReader lines(bytes);
  std::string_view line;
  std::vector<std::string_view> tokens;

  const auto next_line = [&](const char* expected) {
    if (!lines.next(line)) throw InputError(source, line_position(lines.line_number() + 1), std::string("file ends; expected ") + expected);
  };
  next_line("the \"# vtk DataFile Version\" line");
  if (!line.starts_with("# vtk DataFile")) {
    throw InputError(source, line_position(1), "not a VTK legacy file: expected \"# vtk DataFile Version x.y\"");
  }
  next_line("a title line");
  next_line("ASCII or BINARY");
  detail::split_whitespace(line, tokens);
  const std::string encoding = tokens.size() == 1 ? upper(tokens[0]) : "";
  if (encoding != "ASCII" && encoding != "BINARY") {
    throw InputError(source, line_position(lines.line_number()), "expected ASCII or BINARY, found " + detail::quoted(line));
  }
  // DATASET, then the sections up to POINTS (POLYDATA puts POINTS first; FIELD data may precede).
  std::uint64_t count = 0;
  ScalarType type = ScalarType::kFloat32;
  bool dataset = false;
  while (true) {
    next_line("DATASET POLYDATA and a POINTS section");
    detail::split_whitespace(line, tokens);
    if (tokens.empty()) continue;
    const std::string keyword = upper(tokens[0]);
    if (keyword == "DATASET") {
      const std::string kind = tokens.size() == 2 ? upper(tokens[1]) : "";
      if (kind != "POLYDATA" && kind != "UNSTRUCTURED_GRID") {
        throw InputError(source, line_position(lines.line_number()),
                         "expected DATASET POLYDATA or UNSTRUCTURED_GRID, found " + detail::quoted(line));
      }
      dataset = true;
    } else if (keyword == "POINTS") {
      if (!dataset) throw InputError(source, line_position(lines.line_number()), "POINTS before DATASET");
      if (tokens.size() != 3 || !detail::parse_uint(tokens[1], count) || !vtk_type(tokens[2], type)) {
        throw InputError(source, line_position(lines.line_number()),
                         "expected \"POINTS n type\" (type float, double, int...), found " + detail::quoted(line));
      }
      break;
    } else {
      throw InputError(source, line_position(lines.line_number()), "expected DATASET or POINTS, found " + detail::quoted(line));
    }
  }
  const std::size_t data_start = lines.offset();
  const std::size_t remaining = bytes.size() - data_start;
  // Every ASCII value takes at least two bytes ("0 "), every binary one its size.
  const std::size_t min_bytes_per_value = encoding == "BINARY" ? detail::scalar_size(type) : 2;
  if (count > (remaining + 1) / (3 * min_bytes_per_value)) {
    throw InputError(source, line_position(lines.line_number()),
                     "POINTS claims " + std::to_string(count) + " points but only " + std::to_string(remaining) +
                         " bytes follow");
  }
  PointCloud cloud;
  cloud.reserve(static_cast<std::size_t>(count));
  std::size_t dropped = 0;
  if (encoding == "BINARY") {
    const std::size_t size = detail::scalar_size(type);
    if (remaining < count * 3 * size) {
      throw InputError(source, detail::byte_position(bytes.size()),
                       "binary POINTS end after " + std::to_string(remaining / (3 * size)) + " of " + std::to_string(count) + " points");
    }
    const char* p = bytes.data() + data_start;
    constexpr bool kSwapBigEndian = std::endian::native == std::endian::little;
    for (std::uint64_t k = 0; k < count; ++k, p += 3 * size) {
      detail::append_if_finite(cloud, detail::load_scalar(p, type, kSwapBigEndian),
                               detail::load_scalar(p + size, type, kSwapBigEndian),
                               detail::load_scalar(p + 2 * size, type, kSwapBigEndian), dropped);
    }
  } else {
    double xyz[3] = {0.0, 0.0, 0.0};
    int filled = 0;
    std::uint64_t points = 0;
    while (points < count) {
      if (!lines.next(line)) {
        throw InputError(source, line_position(lines.line_number() + 1),
                         "file ends after " + std::to_string(points) + " of " + std::to_string(count) + " points");
      }
      detail::split_whitespace(line, tokens);
      for (const auto token : tokens) {
        if (points == count) {
          throw InputError(source, line_position(lines.line_number()), "more values than POINTS " + std::to_string(count) + " announces");
        }
        if (!detail::parse_double(token, xyz[filled])) {
          throw InputError(source, line_position(lines.line_number()), "expected a number, found " + detail::quoted(token));
        }
        if (++filled == 3) {
          detail::append_if_finite(cloud, xyz[0], xyz[1], xyz[2], dropped);
          filled = 0;
          ++points;
        }
      }
    }
  }
  if (stats != nullptr) {
    stats->points_read += static_cast<std::size_t>(count);
    stats->non_finite_dropped += dropped;
  }
  return cloud;
}

}  // namespace hmap
