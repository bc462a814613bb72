#include "hmap/io/ply.hpp"

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "hmap/core/error.hpp"
#include "hmap/io/read_support.hpp"

namespace hmap {

namespace {

using detail::byte_position;
using detail::line_position;
using detail::ScalarType;

enum class PlyFormat : std::uint8_t { kAscii, kBinaryLittleEndian, kBinaryBigEndian };

struct PlyProperty {
  std::string name;
  ScalarType type = ScalarType::kFloat32;  ///< the value type; for a list, the item type
  bool is_list = false;
  ScalarType count_type = ScalarType::kUint8;  ///< lists only
};

struct PlyElement {
  std::string name;
  std::uint64_t count = 0;
  std::vector<PlyProperty> properties;

  [[nodiscard]] bool has_lists() const {
    for (const PlyProperty& p : properties) {
      if (p.is_list) return true;
    }
    return false;
  }
  /// Bytes of one binary record; for lists, the count only (their smallest size).
  [[nodiscard]] std::size_t min_record_bytes() const {
    std::size_t bytes = 0;
    for (const PlyProperty& p : properties) bytes += scalar_size(p.is_list ? p.count_type : p.type);
    return bytes;
  }
};

std::optional<ScalarType> ply_scalar_type(std::string_view name) {
  if (name == "char" || name == "int8") return ScalarType::kInt8;
  if (name == "uchar" || name == "uint8") return ScalarType::kUint8;
  if (name == "short" || name == "int16") return ScalarType::kInt16;
  if (name == "ushort" || name == "uint16") return ScalarType::kUint16;
  if (name == "int" || name == "int32") return ScalarType::kInt32;
  if (name == "uint" || name == "uint32") return ScalarType::kUint32;
  if (name == "float" || name == "float32") return ScalarType::kFloat32;
  if (name == "double" || name == "float64") return ScalarType::kFloat64;
  return std::nullopt;
}

/// The tokens of an ascii PLY body, a record per line: tokens of one record never cross a line
/// break, so that a vertex line missing a value is an error on that line instead of shifting
/// every later vertex by one value.
class TokenCursor {
 public:
  TokenCursor(std::string_view text, std::size_t line) : text_(text), line_(line), token_line_(line) {}

  /// Moves to the first token of the next record (blank lines between records are skipped).
  void start_record() {
    while (pos_ < text_.size() && is_blank(text_[pos_])) {
      if (text_[pos_] == '\n') ++line_;
      ++pos_;
    }
    token_line_ = line_;
  }
  /// The next token of the current line; false at the line's end or the text's.
  bool next(std::string_view& token) {
    while (pos_ < text_.size() && is_blank(text_[pos_]) && text_[pos_] != '\n') ++pos_;
    token_line_ = line_;
    if (pos_ >= text_.size() || text_[pos_] == '\n') return false;
    const std::size_t start = pos_;
    while (pos_ < text_.size() && !is_blank(text_[pos_])) ++pos_;
    token = text_.substr(start, pos_ - start);
    return true;
  }
  /// True when the current line holds nothing more; then moves past it.
  bool end_record() {
    while (pos_ < text_.size() && is_blank(text_[pos_]) && text_[pos_] != '\n') ++pos_;
    if (pos_ < text_.size() && text_[pos_] != '\n') return false;
    if (pos_ < text_.size()) {
      ++pos_;
      ++line_;
    }
    return true;
  }
  /// True when nothing but blanks is left: the file ended, rather than the line.
  [[nodiscard]] bool at_end() const {
    for (std::size_t i = pos_; i < text_.size(); ++i) {
      if (!is_blank(text_[i])) return false;
    }
    return true;
  }
  /// The line of the token last returned: where a bad token is, or where the text ran out.
  [[nodiscard]] std::size_t line() const { return token_line_; }

 private:
  static bool is_blank(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n'; }

  std::string_view text_;
  std::size_t pos_ = 0;
  std::size_t line_;
  std::size_t token_line_;
};

class PlyReader {
 public:
  PlyReader(const std::filesystem::path& path, std::string_view bytes)
      : source_(path.string()), bytes_(bytes) {}

  PointCloud read(CloudReadStats& stats) {
    parse_header();
    std::size_t vertex = elements_.size();
    for (std::size_t e = 0; e < elements_.size(); ++e) {
      if (elements_[e].name == "vertex") {
        vertex = e;
        break;
      }
    }
    if (vertex == elements_.size()) fail("header", "no 'element vertex'");
    const std::array<std::size_t, 3> xyz = {coordinate(elements_[vertex], "x"),
                                            coordinate(elements_[vertex], "y"),
                                            coordinate(elements_[vertex], "z")};
    PointCloud cloud;
    if (format_ == PlyFormat::kAscii) {
      TokenCursor tokens(bytes_.substr(data_offset_), data_line_);
      for (std::size_t e = 0; e < vertex; ++e) skip_ascii(elements_[e], tokens);
      read_ascii_vertices(elements_[vertex], xyz, tokens, cloud, stats);
    } else {
      std::size_t pos = data_offset_;
      for (std::size_t e = 0; e < vertex; ++e) skip_binary(elements_[e], pos);
      read_binary_vertices(elements_[vertex], xyz, pos, cloud, stats);
    }
    stats.points_read = static_cast<std::size_t>(elements_[vertex].count);
    return cloud;
  }

 private:
  [[noreturn]] void fail(const std::string& position, const std::string& problem) const {
    throw InputError(source_, position, problem);
  }

  void parse_header() {
    detail::LineReader lines(bytes_);
    std::vector<std::string_view> tokens;
    std::string_view line;
    if (!lines.next(line) || line != "ply") fail(line_position(1), "not a PLY file: expected 'ply'");
    bool has_format = false;
    while (lines.next(line)) {
      detail::split_whitespace(line, tokens);
      const std::size_t n = lines.line_number();
      if (tokens.empty()) continue;
      const std::string_view key = tokens.front();
      if (key == "comment" || key == "obj_info") continue;
      if (key == "end_header") {
        if (!has_format) fail(line_position(n), "no 'format' line before end_header");
        data_offset_ = lines.offset();
        data_line_ = n + 1;
        return;
      }
      if (key == "format") {
        if (tokens.size() != 3) fail(line_position(n), "expected 'format <encoding> 1.0'");
        if (tokens[1] == "ascii") {
          format_ = PlyFormat::kAscii;
        } else if (tokens[1] == "binary_little_endian") {
          format_ = PlyFormat::kBinaryLittleEndian;
        } else if (tokens[1] == "binary_big_endian") {
          format_ = PlyFormat::kBinaryBigEndian;
        } else {
          fail(line_position(n), "format " + detail::quoted(tokens[1]) +
                                     "; expected ascii, binary_little_endian or binary_big_endian");
        }
        has_format = true;
      } else if (key == "element") {
        PlyElement element;
        if (tokens.size() != 3 || !detail::parse_uint(tokens[2], element.count)) {
          fail(line_position(n), "expected 'element <name> <count>'");
        }
        element.name = tokens[1];
        elements_.push_back(std::move(element));
      } else if (key == "property") {
        if (elements_.empty()) fail(line_position(n), "property before any element");
        elements_.back().properties.push_back(parse_property(tokens, n));
      } else {
        fail(line_position(n), "unknown PLY header keyword " + detail::quoted(key));
      }
    }
    fail("header", "no end_header line");
  }

  PlyProperty parse_property(const std::vector<std::string_view>& tokens, std::size_t n) const {
    const auto type_of = [&](std::string_view name) {
      const std::optional<ScalarType> type = ply_scalar_type(name);
      if (!type) fail(line_position(n), "unknown property type " + detail::quoted(name));
      return *type;
    };
    PlyProperty property;
    if (tokens.size() >= 2 && tokens[1] == "list") {
      if (tokens.size() != 5)
        fail(line_position(n), "expected 'property list <count type> <item type> <name>'");
      property.is_list = true;
      property.count_type = type_of(tokens[2]);
      if (!detail::is_integer(property.count_type)) {
        fail(line_position(n), "list count type " + detail::quoted(tokens[2]) + " is not an integer type");
      }
      property.type = type_of(tokens[3]);
      property.name = tokens[4];
    } else {
      if (tokens.size() != 3) fail(line_position(n), "expected 'property <type> <name>'");
      property.type = type_of(tokens[1]);
      property.name = tokens[2];
    }
    return property;
  }

  std::size_t coordinate(const PlyElement& vertex, std::string_view name) const {
    for (std::size_t p = 0; p < vertex.properties.size(); ++p) {
      if (vertex.properties[p].name != name) continue;
      if (vertex.properties[p].is_list) {
        fail("header", "vertex property " + detail::quoted(name) + " is a list; expected a scalar");
      }
      return p;
    }
    fail("header",
         "element vertex has no property " + detail::quoted(name) + "; a point cloud needs x, y and z");
  }

  // ---- binary ----

  [[nodiscard]] bool swap_bytes() const {
    return format_ == PlyFormat::kBinaryLittleEndian ? detail::kSwapLittleEndian : !detail::kSwapLittleEndian;
  }

  [[noreturn]] void fail_truncated(std::size_t pos, const PlyElement& element, std::uint64_t record) const {
    fail(byte_position(pos), "file ends inside element " + detail::quoted(element.name) + " record " +
                                 std::to_string(record) + " of " + std::to_string(element.count));
  }

  /// Advances `pos` past one record; stores where each scalar property starts in `starts`.
  void walk_binary_record(const PlyElement& element, std::uint64_t record, std::size_t& pos,
                          std::vector<std::size_t>* starts) const {
    for (std::size_t p = 0; p < element.properties.size(); ++p) {
      const PlyProperty& property = element.properties[p];
      if (starts != nullptr) (*starts)[p] = pos;
      if (!property.is_list) {
        if (bytes_.size() - pos < scalar_size(property.type)) fail_truncated(pos, element, record);
        pos += scalar_size(property.type);
        continue;
      }
      const std::size_t count_bytes = scalar_size(property.count_type);
      if (bytes_.size() - pos < count_bytes) fail_truncated(pos, element, record);
      const double count = detail::load_scalar(bytes_.data() + pos, property.count_type, swap_bytes());
      if (count < 0) {
        fail(byte_position(pos), "negative list length " + std::to_string(static_cast<long long>(count)) +
                                     " in element " + detail::quoted(element.name));
      }
      pos += count_bytes;
      if (count > static_cast<double>(bytes_.size())) fail_truncated(pos, element, record);
      const auto items = static_cast<std::uint64_t>(count);
      if (items > (bytes_.size() - pos) / scalar_size(property.type)) fail_truncated(pos, element, record);
      pos += static_cast<std::size_t>(items) * scalar_size(property.type);
    }
  }

  void check_records_fit(const PlyElement& element, std::size_t pos, std::size_t record_bytes) const {
    if (record_bytes > 0 && element.count > (bytes_.size() - pos) / record_bytes) {
      fail(byte_position(pos), "element " + detail::quoted(element.name) + " claims " +
                                   std::to_string(element.count) + " records of at least " +
                                   std::to_string(record_bytes) + " bytes, but only " +
                                   std::to_string(bytes_.size() - pos) +
                                   " bytes are left; the file is truncated or its header wrong");
    }
  }

  void skip_binary(const PlyElement& element, std::size_t& pos) const {
    const std::size_t record_bytes = element.min_record_bytes();
    check_records_fit(element, pos, record_bytes);
    if (!element.has_lists()) {
      pos += static_cast<std::size_t>(element.count) * record_bytes;
      return;
    }
    for (std::uint64_t r = 0; r < element.count; ++r) walk_binary_record(element, r, pos, nullptr);
  }

  void read_binary_vertices(const PlyElement& vertex, const std::array<std::size_t, 3>& xyz, std::size_t pos,
                            PointCloud& cloud, CloudReadStats& stats) const {
    const std::size_t record_bytes = vertex.min_record_bytes();
    check_records_fit(vertex, pos, record_bytes);
    cloud.reserve(static_cast<std::size_t>(vertex.count));
    const bool swap = swap_bytes();
    std::array<ScalarType, 3> type{};
    for (int k = 0; k < 3; ++k) type[k] = vertex.properties[xyz[k]].type;

    if (!vertex.has_lists()) {
      // Fixed-size records: the coordinates sit at fixed offsets.
      std::array<std::size_t, 3> offset{};
      for (int k = 0; k < 3; ++k) {
        for (std::size_t p = 0; p < xyz[k]; ++p) offset[k] += scalar_size(vertex.properties[p].type);
      }
      const char* record = bytes_.data() + pos;
      for (std::uint64_t r = 0; r < vertex.count; ++r, record += record_bytes) {
        detail::append_if_finite(cloud, detail::load_scalar(record + offset[0], type[0], swap),
                                 detail::load_scalar(record + offset[1], type[1], swap),
                                 detail::load_scalar(record + offset[2], type[2], swap),
                                 stats.non_finite_dropped);
      }
      return;
    }
    std::vector<std::size_t> starts(vertex.properties.size());
    for (std::uint64_t r = 0; r < vertex.count; ++r) {
      walk_binary_record(vertex, r, pos, &starts);
      detail::append_if_finite(cloud, detail::load_scalar(bytes_.data() + starts[xyz[0]], type[0], swap),
                               detail::load_scalar(bytes_.data() + starts[xyz[1]], type[1], swap),
                               detail::load_scalar(bytes_.data() + starts[xyz[2]], type[2], swap),
                               stats.non_finite_dropped);
    }
  }

  // ---- ascii ----

  std::string_view next_token(TokenCursor& tokens, const PlyElement& element, std::uint64_t record) const {
    std::string_view token;
    if (!tokens.next(token)) {
      if (tokens.at_end()) {
        fail(line_position(tokens.line()), "file ends inside element " + detail::quoted(element.name) +
                                               " record " + std::to_string(record) + " of " +
                                               std::to_string(element.count));
      }
      fail(line_position(tokens.line()), "too few values for element " + detail::quoted(element.name) + " record " +
                                             std::to_string(record) + " (" + std::to_string(element.properties.size()) +
                                             " properties, a record per line)");
    }
    return token;
  }

  void end_record(TokenCursor& tokens, const PlyElement& element, std::uint64_t record) const {
    if (tokens.end_record()) return;
    fail(line_position(tokens.line()), "more values than element " + detail::quoted(element.name) + " record " +
                                           std::to_string(record) + " has properties (" +
                                           std::to_string(element.properties.size()) + ", a record per line)");
  }

  std::uint64_t list_length(TokenCursor& tokens, const PlyElement& element, std::uint64_t record) const {
    const std::string_view token = next_token(tokens, element, record);
    std::uint64_t length = 0;
    if (!detail::parse_uint(token, length)) {
      fail(line_position(tokens.line()),
           "list length " + detail::quoted(token) + " is not a non-negative integer");
    }
    return length;
  }

  void skip_ascii(const PlyElement& element, TokenCursor& tokens) const {
    if (element.properties.empty()) return;  // records of nothing: however many, no tokens
    for (std::uint64_t r = 0; r < element.count; ++r) {
      tokens.start_record();
      for (const PlyProperty& property : element.properties) {
        const std::uint64_t items = property.is_list ? list_length(tokens, element, r) : 1;
        for (std::uint64_t i = 0; i < items; ++i) next_token(tokens, element, r);
      }
      end_record(tokens, element, r);
    }
  }

  void read_ascii_vertices(const PlyElement& vertex, const std::array<std::size_t, 3>& xyz,
                           TokenCursor& tokens, PointCloud& cloud, CloudReadStats& stats) const {
    // Each value takes at least one character and one separator: bound the claim before reserving.
    const std::uint64_t min_record_bytes = 2 * std::uint64_t{vertex.properties.size()};
    const std::size_t left = bytes_.size() - data_offset_;
    if (vertex.count > (left + 1) / min_record_bytes) {
      fail(line_position(data_line_),
           "element vertex claims " + std::to_string(vertex.count) + " records, more than the " +
               std::to_string(left) + " bytes of data can hold; the file is truncated or its header wrong");
    }
    cloud.reserve(static_cast<std::size_t>(vertex.count));
    for (std::uint64_t r = 0; r < vertex.count; ++r) {
      std::array<double, 3> v{};
      tokens.start_record();
      for (std::size_t p = 0; p < vertex.properties.size(); ++p) {
        const PlyProperty& property = vertex.properties[p];
        if (property.is_list) {
          const std::uint64_t items = list_length(tokens, vertex, r);
          for (std::uint64_t i = 0; i < items; ++i) next_token(tokens, vertex, r);
          continue;
        }
        const std::string_view token = next_token(tokens, vertex, r);
        for (int k = 0; k < 3; ++k) {
          if (xyz[k] == p && !detail::parse_double(token, v[k])) {
            fail(line_position(tokens.line()), detail::quoted(token) + " is not a number");
          }
        }
      }
      end_record(tokens, vertex, r);
      detail::append_if_finite(cloud, v[0], v[1], v[2], stats.non_finite_dropped);
    }
  }

  std::string source_;
  std::string_view bytes_;
  PlyFormat format_ = PlyFormat::kAscii;
  std::vector<PlyElement> elements_;
  std::size_t data_offset_ = 0;
  std::size_t data_line_ = 0;
};

}  // namespace

PointCloud read_ply(const std::filesystem::path& path, CloudReadStats* stats) {
  const std::string bytes = detail::read_file_bytes(path);
  CloudReadStats local;
  PointCloud cloud = PlyReader(path, bytes).read(local);
  if (stats != nullptr) *stats = local;
  return cloud;
}

}  // namespace hmap
