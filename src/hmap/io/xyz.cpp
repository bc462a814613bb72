#include "hmap/io/xyz.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <string>
#include <string_view>
#include <vector>

#include "hmap/core/error.hpp"
#include "hmap/io/read_support.hpp"

namespace hmap {

namespace {

using detail::line_position;

bool is_space(char c) { return c == ' ' || c == '\t'; }
bool is_separator(char c) { return c == ',' || c == ';'; }

/// Splits a line into fields: whitespace, optionally around one ',' or ';', separates two fields;
/// two commas in a row leave an empty field between them; a trailing separator is ignored.
void split_fields(std::string_view line, std::vector<std::string_view>& fields) {
  fields.clear();
  const std::size_t n = line.size();
  std::size_t i = 0;
  while (i < n && is_space(line[i])) ++i;
  while (i < n) {
    const std::size_t start = i;
    while (i < n && !is_space(line[i]) && !is_separator(line[i])) ++i;
    fields.push_back(line.substr(start, i - start));
    while (i < n && is_space(line[i])) ++i;
    if (i < n && is_separator(line[i])) {
      ++i;
      while (i < n && is_space(line[i])) ++i;
    }
  }
}

/// A header field as a lower-case column name: `"X"`, `'x'` and `//X` all give "x".
std::string column_name(std::string_view field) {
  while (!field.empty() && (field.front() == '/' || field.front() == '"' || field.front() == '\'')) {
    field.remove_prefix(1);
  }
  while (!field.empty() && (field.back() == '"' || field.back() == '\'')) field.remove_suffix(1);
  std::string name(field);
  std::transform(name.begin(), name.end(), name.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return name;
}

bool starts_with_numbers(const std::vector<std::string_view>& fields) {
  if (fields.size() < 3) return false;
  for (std::size_t k = 0; k < 3; ++k) {
    double value = 0.0;
    if (!detail::parse_double(fields[k], value)) return false;
  }
  return true;
}

/// The columns of x, y, z named in a header, or 0, 1, 2 when it does not name all three.
std::array<std::size_t, 3> columns_from_header(const std::vector<std::string_view>& fields) {
  constexpr std::array<std::string_view, 3> kNames = {"x", "y", "z"};
  std::array<std::size_t, 3> columns{};
  for (std::size_t k = 0; k < 3; ++k) {
    const auto found = std::find_if(fields.begin(), fields.end(),
                                    [&](std::string_view f) { return column_name(f) == kNames[k]; });
    if (found == fields.end()) return {0, 1, 2};
    columns[k] = static_cast<std::size_t>(found - fields.begin());
  }
  return columns;
}

}  // namespace

PointCloud read_xyz(const std::filesystem::path& path, CloudReadStats* stats) {
  const std::string bytes = detail::read_file_bytes(path);
  const std::string source = path.string();

  PointCloud cloud;
  // Lines bound the points; counting newlines costs far less than parsing them.
  cloud.reserve(static_cast<std::size_t>(std::count(bytes.begin(), bytes.end(), '\n')) + 1);

  CloudReadStats local;
  std::array<std::size_t, 3> columns = {0, 1, 2};
  std::size_t fields_needed = 3;
  bool first_content_line = true;
  detail::LineReader lines(bytes);
  std::vector<std::string_view> fields;
  std::string_view line;
  while (lines.next(line)) {
    split_fields(line, fields);
    if (fields.empty() || fields.front().starts_with('#')) continue;
    if (first_content_line) {
      first_content_line = false;
      if (!starts_with_numbers(fields)) {
        columns = columns_from_header(fields);
        fields_needed = *std::max_element(columns.begin(), columns.end()) + 1;
        continue;
      }
    }
    if (fields.size() < fields_needed) {
      throw InputError(source, line_position(lines.line_number()),
                       "expected at least " + std::to_string(fields_needed) + " values, found " +
                           std::to_string(fields.size()));
    }
    std::array<double, 3> v{};
    for (std::size_t k = 0; k < 3; ++k) {
      const std::string_view field = fields[columns[k]];
      if (!detail::parse_double(field, v[k])) {
        throw InputError(source, line_position(lines.line_number()),
                         field.empty() ? "empty value in column " + std::to_string(columns[k] + 1)
                                       : detail::quoted(field) + " is not a number");
      }
    }
    detail::append_if_finite(cloud, v[0], v[1], v[2], local.non_finite_dropped);
    ++local.points_read;
  }
  if (stats != nullptr) *stats = local;
  return cloud;
}

}  // namespace hmap
