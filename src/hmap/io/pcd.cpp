#include "hmap/io/pcd.hpp"

#include <lzf.h>

#include <array>
#include <cmath>
#include <optional>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Geometry>

#include "hmap/core/error.hpp"
#include "hmap/io/point_time.hpp"
#include "hmap/io/read_support.hpp"

namespace hmap {

namespace {

using detail::byte_position;
using detail::line_position;
using detail::ScalarType;

enum class PcdEncoding : std::uint8_t { kAscii, kBinary, kBinaryCompressed };

struct PcdField {
  std::string name;
  ScalarType type = ScalarType::kFloat32;
  std::size_t count = 1;
  std::size_t bytes = 4;  ///< size × count: the bytes this field takes in one point
};

struct PcdHeader {
  std::vector<PcdField> fields;
  std::uint64_t points = 0;
  std::size_t point_bytes = 0;  ///< sum of the fields' bytes
  std::size_t value_count = 0;  ///< sum of the fields' COUNT: values on an ascii line
  PcdEncoding encoding = PcdEncoding::kAscii;
  std::size_t data_offset = 0;  ///< first byte after the DATA line
  std::size_t data_line = 0;    ///< 1-based number of the DATA line
  /// VIEWPOINT tx ty tz qw qx qy qz: the sensor's pose in the cloud's frame; identity when absent.
  Eigen::Isometry3d T_cloud_sensor = Eigen::Isometry3d::Identity();
};

/// Where one coordinate is found in a point record.
struct Coordinate {
  std::size_t field = 0;        ///< index into PcdHeader::fields
  std::size_t byte_offset = 0;  ///< within a binary point record
  std::size_t value_index = 0;  ///< within an ascii line
  ScalarType type = ScalarType::kFloat32;
};

/// LZF encodes at most 264 output bytes in a 3-byte back reference; a larger ratio is corrupt.
constexpr std::uint64_t kLzfMaxRatio = 88;
/// Far above any real PCD; keeps size × count × fields well inside 64 bits.
constexpr std::uint64_t kMaxFieldCount = std::uint64_t{1} << 24;

class PcdReader {
 public:
  PcdReader(const std::filesystem::path& path, std::string_view bytes, const MemoryBudget* budget)
      : source_(path.string()), bytes_(bytes), budget_(budget) {}

  PointCloud read(CloudReadStats& stats, std::vector<float>* times) {
    parse_header();
    const std::array<Coordinate, 3> xyz = {coordinate("x"), coordinate("y"), coordinate("z")};
    if (times != nullptr) {
      times->clear();
      for (const char* name : kPointTimeFields) {
        if (time_.has_value()) break;
        for (const PcdField& f : header_.fields) {
          if (f.name == name) time_ = coordinate(name);
        }
      }
    }
    PointCloud cloud;
    switch (header_.encoding) {
      case PcdEncoding::kAscii:
        read_ascii(xyz, cloud, stats);
        break;
      case PcdEncoding::kBinary:
        read_binary(xyz, cloud, stats);
        break;
      case PcdEncoding::kBinaryCompressed:
        read_compressed(xyz, cloud, stats);
        break;
    }
    stats.points_read = header_.points;
    if (header_.T_cloud_sensor.matrix() != Eigen::Matrix4d::Identity()) apply_viewpoint(cloud, stats);
    if (times != nullptr && time_) *times = point_times_to_seconds(raw_times_);
    return cloud;
  }

 private:
  [[noreturn]] void fail(const std::string& position, const std::string& problem) const {
    throw InputError(source_, position, problem);
  }

  std::uint64_t parse_uint_value(std::string_view token, std::size_t line, std::string_view key) const {
    std::uint64_t value = 0;
    if (!detail::parse_uint(token, value)) {
      fail(line_position(line),
           std::string(key) + " value " + detail::quoted(token) + " is not a non-negative integer");
    }
    return value;
  }

  /// Moves the points into the viewpoint's frame. A point finite in the file can leave float's range
  /// there (3e38 shifted or turned): it is dropped and counted as non-finite, with its time.
  void apply_viewpoint(PointCloud& cloud, CloudReadStats& stats) {
    const bool timed = raw_times_.size() == cloud.size() && time_.has_value();
    std::size_t kept = 0;
    for (std::size_t i = 0; i < cloud.size(); ++i) {
      const Eigen::Vector3d p = header_.T_cloud_sensor * cloud[i].cast<double>();
      if (!detail::finite_as_float(p.x(), p.y(), p.z())) {
        ++stats.non_finite_dropped;
        continue;
      }
      cloud[kept] = p.cast<float>();
      if (timed) raw_times_[kept] = raw_times_[i];
      ++kept;
    }
    cloud.resize(kept);
    if (timed) raw_times_.resize(kept);
  }

  /// VIEWPOINT tx ty tz qw qx qy qz (PCL's sensor_origin_ and sensor_orientation_): applied to the
  /// points, which then lie in the frame the sensor pose is given in.
  void parse_viewpoint(const std::vector<std::string_view>& tokens, std::size_t line) {
    if (tokens.size() != 8) fail(line_position(line), "VIEWPOINT expects 7 numbers (tx ty tz qw qx qy qz)");
    double v[7];
    for (std::size_t k = 0; k < 7; ++k) {
      if (!detail::parse_double(tokens[k + 1], v[k]) || !std::isfinite(v[k])) {
        fail(line_position(line), "VIEWPOINT value " + detail::quoted(tokens[k + 1]) + " is not a finite number");
      }
    }
    Eigen::Quaterniond q(v[3], v[4], v[5], v[6]);
    // PCL writes its quaternions in float: a norm within 1e-3 of 1 is a rotation, rounded.
    if (std::abs(q.norm() - 1.0) > 1e-3) {
      fail(line_position(line), "VIEWPOINT quaternion (qw qx qy qz) has norm " + std::to_string(q.norm()) + ", not 1");
    }
    header_.T_cloud_sensor = Eigen::Isometry3d::Identity();
    header_.T_cloud_sensor.linear() = q.normalized().toRotationMatrix();
    header_.T_cloud_sensor.translation() = Eigen::Vector3d(v[0], v[1], v[2]);
  }

  void parse_header() {
    std::vector<std::string> names;
    std::vector<std::uint64_t> sizes;
    std::vector<char> types;
    std::vector<std::uint64_t> counts;
    bool has_sizes = false;
    bool has_types = false;
    bool has_counts = false;
    std::uint64_t width = 0;
    std::uint64_t height = 1;
    std::uint64_t points = 0;
    bool has_width = false;
    bool has_points = false;
    bool has_data = false;

    detail::LineReader lines(bytes_);
    std::vector<std::string_view> tokens;
    std::string_view line;
    while (!has_data && lines.next(line)) {
      detail::split_whitespace(line, tokens);
      if (tokens.empty() || tokens.front().front() == '#') continue;
      const std::string_view key = tokens.front();
      const std::size_t n = lines.line_number();
      const auto expect_one = [&] {
        if (tokens.size() != 2) fail(line_position(n), std::string(key) + " expects one value");
      };
      if (key == "VERSION") {
        continue;  // the version changes nothing we read
      } else if (key == "VIEWPOINT") {
        parse_viewpoint(tokens, n);
      } else if (key == "FIELDS" || key == "COLUMNS") {
        names.assign(tokens.begin() + 1, tokens.end());
      } else if (key == "SIZE") {
        has_sizes = true;
        sizes.clear();
        for (std::size_t i = 1; i < tokens.size(); ++i) sizes.push_back(parse_uint_value(tokens[i], n, key));
      } else if (key == "TYPE") {
        has_types = true;
        types.clear();
        for (std::size_t i = 1; i < tokens.size(); ++i) {
          if (tokens[i].size() != 1)
            fail(line_position(n), "TYPE " + detail::quoted(tokens[i]) + " is not F, I or U");
          types.push_back(tokens[i].front());
        }
      } else if (key == "COUNT") {
        has_counts = true;
        counts.clear();
        for (std::size_t i = 1; i < tokens.size(); ++i) counts.push_back(parse_uint_value(tokens[i], n, key));
      } else if (key == "WIDTH") {
        expect_one();
        width = parse_uint_value(tokens[1], n, key);
        has_width = true;
      } else if (key == "HEIGHT") {
        expect_one();
        height = parse_uint_value(tokens[1], n, key);
      } else if (key == "POINTS") {
        expect_one();
        points = parse_uint_value(tokens[1], n, key);
        has_points = true;
      } else if (key == "DATA") {
        expect_one();
        if (tokens[1] == "ascii") {
          header_.encoding = PcdEncoding::kAscii;
        } else if (tokens[1] == "binary") {
          header_.encoding = PcdEncoding::kBinary;
        } else if (tokens[1] == "binary_compressed") {
          header_.encoding = PcdEncoding::kBinaryCompressed;
        } else {
          fail(line_position(n),
               "DATA " + detail::quoted(tokens[1]) + "; expected ascii, binary or binary_compressed");
        }
        header_.data_offset = lines.offset();
        header_.data_line = n;
        has_data = true;
      } else {
        fail(line_position(n), "unknown PCD header keyword " + detail::quoted(key) + "; is this a PCD file?");
      }
    }
    if (!has_data) fail("header", "no DATA line; is this a PCD file?");
    if (names.empty()) fail("header", "no FIELDS line");

    const auto check_length = [&](bool present, std::size_t length, const char* key) {
      if (present && length != names.size()) {
        fail("header", std::string(key) + " has " + std::to_string(length) + " values for " +
                           std::to_string(names.size()) + " FIELDS");
      }
    };
    check_length(has_sizes, sizes.size(), "SIZE");
    check_length(has_types, types.size(), "TYPE");
    check_length(has_counts, counts.size(), "COUNT");

    for (std::size_t i = 0; i < names.size(); ++i) {
      PcdField field;
      field.name = names[i];
      const std::uint64_t size = has_sizes ? sizes[i] : 4;
      const char type = has_types ? types[i] : 'F';
      field.type = scalar_type(field.name, type, size);
      const std::uint64_t count = has_counts ? counts[i] : 1;
      if (count == 0 || count > kMaxFieldCount) {
        fail("header", "field " + detail::quoted(field.name) + " has COUNT " + std::to_string(count) +
                           "; expected 1 to " + std::to_string(kMaxFieldCount));
      }
      field.count = count;
      field.bytes = static_cast<std::size_t>(size * count);
      header_.point_bytes += field.bytes;
      header_.value_count += field.count;
      header_.fields.push_back(std::move(field));
    }

    // POINTS may be missing in old files, WIDTH in hand-written ones: each follows from the other.
    if (!has_points) points = width * height;
    if (!has_width) width = height == 0 ? 0 : points / height;
    const bool product_overflows = height != 0 && width > std::numeric_limits<std::uint64_t>::max() / height;
    if (product_overflows || width * height != points) {
      fail("header", "WIDTH " + std::to_string(width) + " × HEIGHT " + std::to_string(height) +
                         " differs from POINTS " + std::to_string(points));
    }
    header_.points = points;
  }

  ScalarType scalar_type(const std::string& name, char type, std::uint64_t size) const {
    const auto wrong = [&](const char* expected) {
      fail("header", "field " + detail::quoted(name) + " has TYPE " + std::string(1, type) + " with SIZE " +
                         std::to_string(size) + "; expected " + expected);
    };
    switch (type) {
      case 'F':
        if (size == 4) return ScalarType::kFloat32;
        if (size == 8) return ScalarType::kFloat64;
        wrong("SIZE 4 or 8");
        break;
      case 'I':
      case 'U': {
        const bool is_signed = type == 'I';
        if (size == 1) return is_signed ? ScalarType::kInt8 : ScalarType::kUint8;
        if (size == 2) return is_signed ? ScalarType::kInt16 : ScalarType::kUint16;
        if (size == 4) return is_signed ? ScalarType::kInt32 : ScalarType::kUint32;
        if (size == 8) return is_signed ? ScalarType::kInt64 : ScalarType::kUint64;
        wrong("SIZE 1, 2, 4 or 8");
        break;
      }
      default:
        fail("header", "field " + detail::quoted(name) + " has TYPE " + detail::quoted({&type, 1}) +
                           "; expected F, I or U");
    }
    return ScalarType::kFloat32;
  }

  Coordinate coordinate(const std::string& name) const {
    Coordinate c;
    for (std::size_t i = 0; i < header_.fields.size(); ++i) {
      const PcdField& field = header_.fields[i];
      if (field.name == name) {
        if (field.count != 1) {
          fail("header", "field " + detail::quoted(name) + " has COUNT " + std::to_string(field.count) +
                             "; expected 1");
        }
        c.field = i;
        c.type = field.type;
        return c;
      }
      c.byte_offset += field.bytes;
      c.value_index += field.count;
    }
    fail("header", "no field " + detail::quoted(name) + "; a point cloud needs fields x, y and z");
  }

  [[nodiscard]] std::size_t data_bytes() const { return bytes_.size() - header_.data_offset; }

  void reserve(PointCloud& cloud) const { cloud.reserve(static_cast<std::size_t>(header_.points)); }

  void read_ascii(const std::array<Coordinate, 3>& xyz, PointCloud& cloud, CloudReadStats& stats) {
    // A point line holds value_count tokens of at least one character, each followed by a
    // separator or newline (the last line may lack it): a bound checked before reserving.
    const std::uint64_t min_line_bytes = 2 * std::uint64_t{header_.value_count};
    if (header_.points > (data_bytes() + 1) / min_line_bytes) {
      fail(byte_position(header_.data_offset),
           "data section holds " + std::to_string(data_bytes()) + " bytes, too few for POINTS " +
               std::to_string(header_.points) + " of " + std::to_string(header_.value_count) +
               " values each; the file is truncated or its header wrong");
    }
    reserve(cloud);
    detail::LineReader lines(bytes_.substr(header_.data_offset), header_.data_line + 1);
    std::vector<std::string_view> tokens;
    std::string_view line;
    std::uint64_t read = 0;
    while (read < header_.points && lines.next(line)) {
      detail::split_whitespace(line, tokens);
      if (tokens.empty()) continue;
      if (tokens.size() != header_.value_count) {
        fail(line_position(lines.line_number()), "expected " + std::to_string(header_.value_count) +
                                                     " values as FIELDS and COUNT say, found " +
                                                     std::to_string(tokens.size()));
      }
      double v[3];
      for (int k = 0; k < 3; ++k) {
        const std::string_view token = tokens[xyz[k].value_index];
        if (!detail::parse_double(token, v[k])) {
          fail(line_position(lines.line_number()), detail::quoted(token) + " is not a number");
        }
      }
      const std::size_t before = cloud.size();
      detail::append_if_finite(cloud, v[0], v[1], v[2], stats.non_finite_dropped);
      if (time_ && cloud.size() > before) {
        const std::string_view token = tokens[time_->value_index];
        double t = 0.0;
        if (!detail::parse_double(token, t) || !std::isfinite(t)) {
          fail(line_position(lines.line_number()), "time " + detail::quoted(token) + " is not a finite number");
        }
        raw_times_.push_back(t);
      }
      ++read;
    }
    if (read < header_.points) {
      fail(line_position(lines.line_number() + 1),
           "file ends after " + std::to_string(read) + " of " + std::to_string(header_.points) + " points");
    }
  }

  void check_binary_size(std::size_t offset, std::uint64_t available) const {
    if (header_.points > available / header_.point_bytes) {
      fail(byte_position(offset), "data section holds " + std::to_string(available) +
                                      " bytes, too few for POINTS " + std::to_string(header_.points) +
                                      " of " + std::to_string(header_.point_bytes) +
                                      " bytes each; the file is truncated or its header wrong");
    }
  }

  void read_binary(const std::array<Coordinate, 3>& xyz, PointCloud& cloud, CloudReadStats& stats) {
    check_binary_size(header_.data_offset, data_bytes());
    reserve(cloud);
    const char* record = bytes_.data() + header_.data_offset;
    // PCD binary data is in the writer's byte order, which PCL takes to be the reader's.
    for (std::uint64_t i = 0; i < header_.points; ++i, record += header_.point_bytes) {
      const std::size_t before = cloud.size();
      detail::append_if_finite(cloud, detail::load_scalar(record + xyz[0].byte_offset, xyz[0].type, false),
                               detail::load_scalar(record + xyz[1].byte_offset, xyz[1].type, false),
                               detail::load_scalar(record + xyz[2].byte_offset, xyz[2].type, false),
                               stats.non_finite_dropped);
      if (time_ && cloud.size() > before) {
        keep_time(detail::load_scalar(record + time_->byte_offset, time_->type, false), i);
      }
    }
  }

  void read_compressed(const std::array<Coordinate, 3>& xyz, PointCloud& cloud, CloudReadStats& stats) {
    // Layout: uint32 compressed size, uint32 uncompressed size, LZF block.
    const std::size_t offset = header_.data_offset;
    if (data_bytes() < 8) {
      fail(byte_position(offset), "file ends inside the 8-byte size header of binary_compressed data");
    }
    const auto compressed = detail::load<std::uint32_t>(bytes_.data() + offset, detail::kSwapLittleEndian);
    const auto uncompressed =
        detail::load<std::uint32_t>(bytes_.data() + offset + 4, detail::kSwapLittleEndian);
    if (compressed > data_bytes() - 8) {
      fail(byte_position(offset), "compressed size " + std::to_string(compressed) + " exceeds the " +
                                      std::to_string(data_bytes() - 8) +
                                      " bytes left in the file; the file is truncated or corrupt");
    }
    if (header_.points > uncompressed / header_.point_bytes ||
        header_.points * header_.point_bytes != uncompressed) {
      fail(byte_position(offset + 4), "uncompressed size " + std::to_string(uncompressed) +
                                          " differs from POINTS " + std::to_string(header_.points) + " × " +
                                          std::to_string(header_.point_bytes) + " bytes");
    }
    if (uncompressed > kLzfMaxRatio * compressed) {
      fail(byte_position(offset), "uncompressed size " + std::to_string(uncompressed) + " cannot come from " +
                                      std::to_string(compressed) +
                                      " LZF-compressed bytes; the file is corrupt");
    }
    if (uncompressed == 0) return;
    if (budget_ != nullptr) {
      budget_->require(static_cast<double>(uncompressed) + static_cast<double>(header_.points) * sizeof(Point3f),
                       source_ + ": the decompressed points of its binary_compressed data");
    }

    const auto soa = std::make_unique_for_overwrite<char[]>(uncompressed);
    const unsigned int decompressed =
        lzf_decompress(bytes_.data() + offset + 8, compressed, soa.get(), uncompressed);
    if (decompressed != uncompressed) {
      fail(byte_position(offset + 8), "corrupt LZF data: decompressed " + std::to_string(decompressed) +
                                          " of " + std::to_string(uncompressed) + " bytes");
    }

    // Decompressed data is structure of arrays: every point's field 0, then every point's field 1...
    const std::size_t points = static_cast<std::size_t>(header_.points);
    std::array<const char*, 3> column{};
    std::array<std::size_t, 3> stride{};
    for (int k = 0; k < 3; ++k) {
      std::size_t start = 0;
      for (std::size_t f = 0; f < xyz[k].field; ++f) start += header_.fields[f].bytes * points;
      column[k] = soa.get() + start;
      stride[k] = header_.fields[xyz[k].field].bytes;
    }
    const char* time_column = nullptr;
    std::size_t time_stride = 0;
    if (time_) {
      std::size_t start = 0;
      for (std::size_t f = 0; f < time_->field; ++f) start += header_.fields[f].bytes * points;
      time_column = soa.get() + start;
      time_stride = header_.fields[time_->field].bytes;
    }
    reserve(cloud);
    for (std::size_t i = 0; i < points; ++i) {
      const std::size_t before = cloud.size();
      detail::append_if_finite(cloud, detail::load_scalar(column[0] + i * stride[0], xyz[0].type, false),
                               detail::load_scalar(column[1] + i * stride[1], xyz[1].type, false),
                               detail::load_scalar(column[2] + i * stride[2], xyz[2].type, false),
                               stats.non_finite_dropped);
      if (time_column != nullptr && cloud.size() > before) {
        keep_time(detail::load_scalar(time_column + i * time_stride, time_->type, false), i);
      }
    }
  }

  /// A binary point's time: refused when not finite (a point without a time cannot be deskewed).
  void keep_time(double t, std::uint64_t index) {
    if (!std::isfinite(t)) fail("point " + std::to_string(index), "its time is not a finite number");
    raw_times_.push_back(t);
  }

  std::string source_;
  std::string_view bytes_;
  const MemoryBudget* budget_ = nullptr;
  PcdHeader header_;
  std::optional<Coordinate> time_;  // the per-point time field, when asked for and present
  std::vector<double> raw_times_;   // per kept point, in the file's unit
};

}  // namespace

PointCloud read_pcd(const std::filesystem::path& path, CloudReadStats* stats, std::vector<float>* times_s,
                    const MemoryBudget* budget) {
  const std::string bytes = detail::read_file_bytes(path);
  CloudReadStats local;
  PointCloud cloud = PcdReader(path, bytes, budget).read(local, times_s);
  if (stats != nullptr) *stats = local;
  return cloud;
}

}  // namespace hmap
