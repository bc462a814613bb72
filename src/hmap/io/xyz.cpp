#include "hmap/io/xyz.hpp"

#include <algorithm>
#include <array>
#include <optional>
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

/// Splits a line into fields: whitespace, optionally around one separator, separates two
/// fields; two separators in a row leave an empty field between them; a trailing separator is
/// ignored. The separator is ';' on a line that holds one (the convention of decimal-comma
/// locales: "1,5;2,5;3,5" is then three fields that are refused as numbers, not (1, 5, 2)), else ','.
void split_fields(std::string_view line, std::vector<std::string_view>& fields) {
  fields.clear();
  const char separator = line.find(';') != std::string_view::npos ? ';' : ',';
  const std::size_t n = line.size();
  std::size_t i = 0;
  while (i < n && is_space(line[i])) ++i;
  while (i < n) {
    const std::size_t start = i;
    while (i < n && !is_space(line[i]) && line[i] != separator) ++i;
    fields.push_back(line.substr(start, i - start));
    while (i < n && is_space(line[i])) ++i;
    if (i < n && line[i] == separator) {
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

bool all_numbers(const std::vector<std::string_view>& fields) {
  double value = 0.0;
  return std::all_of(fields.begin(), fields.end(), [&](std::string_view f) { return detail::parse_double(f, value); });
}

/// A value that is not a number, said helpfully: "1,5" is a decimal comma.
std::string not_a_number(std::string_view field) {
  const bool decimal_comma = field.find(',') != std::string_view::npos;
  return detail::quoted(field) + " is not a number" + (decimal_comma ? " (a decimal comma? write 1.5, not 1,5)" : "");
}

/// The columns of x, y, z named in a header; InputError when it does not name all three (the
/// columns are not guessed).
std::array<std::size_t, 3> columns_from_header(const std::vector<std::string_view>& fields, const std::string& source,
                                               std::size_t line) {
  constexpr std::array<std::string_view, 3> kNames = {"x", "y", "z"};
  std::array<std::size_t, 3> columns{};
  for (std::size_t k = 0; k < 3; ++k) {
    const auto found = std::find_if(fields.begin(), fields.end(),
                                    [&](std::string_view f) { return column_name(f) == kNames[k]; });
    if (found == fields.end()) {
      // "1,5;2,5;3,5" is no header but numbers with decimal commas: say so.
      for (const auto f : fields) {
        std::string dotted(f);
        std::replace(dotted.begin(), dotted.end(), ',', '.');
        double value = 0.0;
        if (dotted != f && detail::parse_double(dotted, value)) throw InputError(source, line_position(line), not_a_number(f));
      }
      std::string names;
      for (const auto f : fields) {
        if (!names.empty()) names += ' ';  // appended piecewise: `"" + std::string` trips GCC 12's -Wrestrict
        names.append(f);
      }
      throw InputError(source, line_position(line),
                       "a header must name the columns x, y and z, found " + detail::quoted(names) +
                           " (not a point cloud, or a line of fewer than 3 numbers)");
    }
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
  std::optional<std::uint64_t> claimed_points;  // the count line of a .pts file
  std::size_t claim_line = 0;
  // A UTF-8 byte order mark (spreadsheet exports) is not part of the first column's name.
  std::string_view text = bytes;
  if (text.starts_with("\xEF\xBB\xBF")) text.remove_prefix(3);
  detail::LineReader lines(text);
  std::vector<std::string_view> fields;
  std::string_view line;
  while (lines.next(line)) {
    split_fields(line, fields);
    if (fields.empty() || fields.front().starts_with('#')) continue;
    if (first_content_line) {
      first_content_line = false;
      std::uint64_t count = 0;
      if (fields.size() == 1 && detail::parse_uint(fields[0], count)) {  // .pts: the number of points
        claimed_points = count;
        claim_line = lines.line_number();
        continue;
      }
      if (!all_numbers(fields)) {  // a header; a line of numbers is data, however many
        columns = columns_from_header(fields, source, lines.line_number());
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
                         field.empty() ? "empty value in column " + std::to_string(columns[k] + 1) : not_a_number(field));
      }
    }
    detail::append_if_finite(cloud, v[0], v[1], v[2], local.non_finite_dropped);
    ++local.points_read;
  }
  if (claimed_points && *claimed_points != local.points_read) {
    throw InputError(source, line_position(claim_line),
                     "the point count " + std::to_string(*claimed_points) + " does not match the " +
                         std::to_string(local.points_read) + " points that follow");
  }
  if (stats != nullptr) *stats = local;
  return cloud;
}

}  // namespace hmap
