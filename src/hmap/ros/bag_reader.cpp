#include "hmap/ros/bag_reader.hpp"

#include <algorithm>
#include <cstring>
#include <exception>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <map>
#include <string_view>
#include <numeric>
#include <optional>
#include <set>

#include "hmap/core/error.hpp"
#include "hmap/core/format.hpp"
#include "hmap/io/point_time.hpp"
#include "hmap/io/read_support.hpp"
#include "hmap/ros/recording_access.hpp"
#include "hmap/ros/ros2_recording.hpp"

namespace hmap::ros {

namespace fs = std::filesystem;

namespace {

/// Runs `f`, turning what rosbag throws (BagException, boost and std errors) into an InputError
/// naming the bag. Our own errors pass unchanged.
template <typename F>
auto guarded(const fs::path& path, F&& f) -> decltype(f()) {
  try {
    return f();
  } catch (const hmap::Error&) {
    throw;
  } catch (const std::bad_alloc&) {
    throw InputError(path.string(), "", "unreadable bag: a record claims more memory than available");
  } catch (const std::exception& e) {
    throw InputError(path.string(), "", std::string("unreadable bag: ") + e.what());
  }
}

std::string stamp_text(double t) {
  return format("%.6f", t);
}

/// A pose message as a rigid transform. Its quaternion must have norm 1 within 1e-3, as in pose
/// files (io/poses.cpp): one of norm 0 or 2 is a broken message, not a rotation to guess.
Pose to_pose(const access::RawTransform& t, const std::string& source, const std::string& what) {
  Eigen::Quaterniond rotation(t.q[3], t.q[0], t.q[1], t.q[2]);
  const double norm = rotation.norm();
  if (!(std::abs(norm - 1.0) <= 1e-3)) {
    throw InputError(source, what + " " + (t.child.empty() ? std::string() : t.child + " ") + "at " + stamp_text(t.stamp),
                     "quaternion norm " + format("%g", norm) + " is not 1; not a rotation");
  }
  const Eigen::Vector3d translation(t.t[0], t.t[1], t.t[2]);
  if (!translation.allFinite()) {
    throw InputError(source, what + " at " + stamp_text(t.stamp), "the translation is not finite");
  }
  Pose pose = Pose::Identity();
  pose.linear() = rotation.normalized().toRotationMatrix();
  pose.translation() = translation;
  return pose;
}

/// A time series of one transform, interpolated (lerp + slerp) at any stamp inside it.
struct TimedPoses {
  std::vector<double> times;
  PoseList poses;
  bool is_static = false;

  void add(double t, const Pose& pose) {
    times.push_back(t);
    poses.push_back(pose);
  }
  void sort() {
    std::vector<std::size_t> order(times.size());
    std::iota(order.begin(), order.end(), 0);
    std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return times[a] < times[b]; });
    std::vector<double> t2;
    PoseList p2;
    for (const std::size_t k : order) {
      t2.push_back(times[k]);
      p2.push_back(poses[k]);
    }
    times = std::move(t2);
    poses = std::move(p2);
  }
  [[nodiscard]] std::optional<Pose> at(double t, double tolerance) const {
    if (poses.empty()) return std::nullopt;
    if (is_static) return poses.back();
    if (t <= times.front()) return times.front() - t <= tolerance ? std::optional<Pose>(poses.front()) : std::nullopt;
    if (t >= times.back()) return t - times.back() <= tolerance ? std::optional<Pose>(poses.back()) : std::nullopt;
    const auto k = static_cast<std::size_t>(std::upper_bound(times.begin(), times.end(), t) - times.begin());
    const double span = times[k] - times[k - 1];
    const double a = span > 0.0 ? (t - times[k - 1]) / span : 0.0;
    Pose pose = Pose::Identity();
    pose.linear() = Eigen::Quaterniond(poses[k - 1].linear()).slerp(a, Eigen::Quaterniond(poses[k].linear())).toRotationMatrix();
    pose.translation() = (1.0 - a) * poses[k - 1].translation() + a * poses[k].translation();
    return pose;
  }
  [[nodiscard]] std::string span_text() const {
    if (is_static) return "static";
    return "samples from " + stamp_text(times.front()) + " to " + stamp_text(times.back());
  }
};

/// The /tf tree: each child frame has one parent and a time series of T_parent_child.
struct TfTree {
  struct Edge {
    std::string parent;
    TimedPoses T_parent_child;
  };
  std::map<std::string, Edge> edges;

  void add(const access::RawTransform& t, const std::string& source) {
    auto& edge = edges[t.child];
    if (edge.parent.empty()) edge.parent = t.parent;
    if (edge.parent != t.parent) return;  // a re-parented frame: the first parent wins
    edge.T_parent_child.is_static = edge.T_parent_child.is_static || t.is_static;
    edge.T_parent_child.add(t.stamp, to_pose(t, source, "/tf"));
  }

  /// T_root_frame at `t` and the root's name, or the reason there is none.
  [[nodiscard]] std::optional<Pose> to_root(const std::string& frame, double t, double tolerance, std::string& root,
                                            std::string& why) const {
    Pose T_root_frame = Pose::Identity();
    std::string f = frame;
    for (int depth = 0; depth < 64; ++depth) {
      const auto it = edges.find(f);
      if (it == edges.end()) {
        root = f;
        return T_root_frame;
      }
      const auto T = it->second.T_parent_child.at(t, tolerance);
      if (!T) {
        why = "transform " + it->second.parent + " -> " + f + " has " + it->second.T_parent_child.span_text();
        return std::nullopt;
      }
      T_root_frame = *T * T_root_frame;
      f = it->second.parent;
    }
    why = "the /tf tree has a loop above " + frame;
    return std::nullopt;
  }

  /// T_target_source at `t`, or nullopt with the reason.
  [[nodiscard]] std::optional<Pose> lookup(const std::string& target, const std::string& source, double t,
                                           double tolerance, std::string& why) const {
    std::string root_s;
    std::string root_t;
    const auto T_root_source = to_root(source, t, tolerance, root_s, why);
    if (!T_root_source) return std::nullopt;
    if (target.empty() || target == root_s) return T_root_source;
    const auto T_root_target = to_root(target, t, tolerance, root_t, why);
    if (!T_root_target) return std::nullopt;
    if (root_s != root_t) {
      why = "frames " + target + " and " + source + " are not connected in /tf";
      return std::nullopt;
    }
    return T_root_target->inverse() * *T_root_source;
  }
};


/// Checks the record headers of a v2.0 bag and counts its chunks and their compression.
/// rosbag's record-header parser (ros::Header::parse) trusts the field lengths and reads past its
/// buffer when one is damaged, so every header is checked here first: each field is a 4-byte
/// length, then name=value, and the fields fill the header exactly; header and body lie inside
/// the file (or the uncompressed chunk). Throws InputError naming the byte of the first bad record
/// (open_recording then reads the bag record by record instead, without rosbag).
void check_bag_records(const fs::path& path, std::string_view bytes, BagInfo& info) {
  const std::string source = path.string();
  if (!std::string_view(bytes).starts_with("#ROSBAG V2.0\n")) {
    throw InputError(source, detail::byte_position(0), "not a ROS 1 bag (expected \"#ROSBAG V2.0\")");
  }
  std::set<std::string> kinds;
  // Offsets rosbag will seek to, checked after the walk against the record starts it found.
  std::set<std::uint64_t> top_starts;
  std::map<std::uint64_t, std::set<std::uint64_t>> chunk_inner;  // chunk start -> inner record starts (uncompressed)
  std::map<std::uint64_t, std::uint64_t> chunk_size;             // chunk start -> uncompressed size
  std::vector<std::pair<std::uint64_t, std::size_t>> seeks;      // (offset, where it was read), top-level
  struct IndexRef {
    std::uint64_t chunk;
    std::uint64_t offset;
    std::size_t where;
  };
  std::vector<IndexRef> index_refs;
  std::vector<std::pair<std::uint64_t, std::string>> top_ops;  // (start, op) of the top-level records
  std::uint64_t file_index_pos = 0;
  std::uint32_t conn_count = 0;
  std::uint32_t chunk_count = 0;
  std::uint64_t current_chunk = 0;
  const auto u64_field = [](std::string_view value, std::uint64_t& out) {
    if (value.size() != 8) return false;
    out = detail::load<std::uint64_t>(value.data(), detail::kSwapLittleEndian);
    return true;
  };
  const auto walk = [&](auto& self, std::size_t begin, std::size_t end, bool top) -> void {
    std::size_t pos = begin;
    while (pos < end) {
      if (end - pos < 4) throw InputError(source, detail::byte_position(pos), "truncated record");
      const auto header_len = detail::load<std::uint32_t>(bytes.data() + pos, detail::kSwapLittleEndian);
      if (header_len > end - pos - 4 || end - pos - 4 - header_len < 4) {
        throw InputError(source, detail::byte_position(pos), "record header of " + std::to_string(header_len) +
                                                                 " bytes runs past the end");
      }
      const std::size_t header_at = pos + 4;
      const auto data_len = detail::load<std::uint32_t>(bytes.data() + header_at + header_len, detail::kSwapLittleEndian);
      const std::size_t data_at = header_at + header_len + 4;
      if (data_len > end - data_at) {
        throw InputError(source, detail::byte_position(pos), "record body of " + std::to_string(data_len) + " bytes runs past the end");
      }
      if (top) top_starts.insert(pos);
      else chunk_inner[current_chunk].insert(pos - begin);
      std::string op;
      std::string compression;
      std::uint64_t index_pos = 0;
      std::uint64_t chunk_pos = 0;
      std::uint64_t size = 0;
      bool has_index_pos = false;
      bool has_chunk_pos = false;
      bool has_size = false;
      std::uint32_t count = 0;
      for (std::size_t at = 0; at < header_len;) {
        if (header_len - at < 4) throw InputError(source, detail::byte_position(header_at + at), "truncated header field");
        const auto field_len = detail::load<std::uint32_t>(bytes.data() + header_at + at, detail::kSwapLittleEndian);
        if (field_len > header_len - at - 4) {
          throw InputError(source, detail::byte_position(header_at + at), "header field of " + std::to_string(field_len) +
                                                                              " bytes runs past its header");
        }
        const std::string_view field(bytes.data() + header_at + at + 4, field_len);
        if (field.find('=') == std::string_view::npos) {
          throw InputError(source, detail::byte_position(header_at + at), "header field without '='");
        }
        if (field.starts_with("op=") && field.size() == 4) op = std::string(field.substr(3));
        if (field.starts_with("compression=")) compression = std::string(field.substr(12));
        if (field.starts_with("index_pos=")) has_index_pos = u64_field(field.substr(10), index_pos);
        if (field.starts_with("chunk_pos=")) has_chunk_pos = u64_field(field.substr(10), chunk_pos);
        if (field.starts_with("size=") && field.size() == 9) {
          size = detail::load<std::uint32_t>(field.data() + 5, detail::kSwapLittleEndian);
          has_size = true;
        }
        if (field.starts_with("conn_count=") && field.size() == 15) conn_count = detail::load<std::uint32_t>(field.data() + 11, detail::kSwapLittleEndian);
        if (field.starts_with("chunk_count=") && field.size() == 16) chunk_count = detail::load<std::uint32_t>(field.data() + 12, detail::kSwapLittleEndian);
        if (field.starts_with("count=") && field.size() == 10) count = detail::load<std::uint32_t>(field.data() + 6, detail::kSwapLittleEndian);
        at += 4 + field_len;
      }
      if (op == "\x07") {  // a connection record's body is a header too (topic, type, md5sum, definition)
        for (std::size_t at = 0; at < data_len;) {
          if (data_len - at < 4) throw InputError(source, detail::byte_position(data_at + at), "truncated connection field");
          const auto field_len = detail::load<std::uint32_t>(bytes.data() + data_at + at, detail::kSwapLittleEndian);
          if (field_len > data_len - at - 4 ||
              std::string_view(bytes.data() + data_at + at + 4, field_len).find('=') == std::string_view::npos) {
            throw InputError(source, detail::byte_position(data_at + at), "malformed connection field");
          }
          at += 4 + field_len;
        }
      }
      if (top) top_ops.emplace_back(pos, op);
      if (top && op == "\x03" && has_index_pos) file_index_pos = index_pos;
      if (top && op == "\x03" && has_index_pos && index_pos != 0) seeks.emplace_back(index_pos, pos);
      if (top && op == "\x06" && has_chunk_pos) seeks.emplace_back(chunk_pos, pos);
      if (top && op == "\x05") {
        ++info.chunks;
        kinds.insert(compression);
        current_chunk = pos;
        chunk_size[pos] = has_size ? size : 0;
        if (compression == "none") {
          if (size != data_len) throw InputError(source, detail::byte_position(pos), "uncompressed chunk whose size is not its length");
          self(self, data_at, data_at + data_len, false);
        } else if (!has_size || size > 1100ULL * data_len + 65536) {
          throw InputError(source, detail::byte_position(pos), "chunk claims an uncompressed size its data cannot hold");
        }
      }
      if (top && op == "\x04") {  // index data v1: count entries of (time 8 bytes, offset 4 bytes) for the chunk before it
        if (static_cast<std::uint64_t>(count) * 12 != data_len) {
          throw InputError(source, detail::byte_position(pos), "index record whose count does not match its length");
        }
        for (std::uint32_t e = 0; e < count; ++e) {
          index_refs.push_back({current_chunk,
                                detail::load<std::uint32_t>(bytes.data() + data_at + e * 12 + 8, detail::kSwapLittleEndian), pos});
        }
      }
      pos = data_at + data_len;
    }
  };
  walk(walk, 13, bytes.size(), true);
  for (const auto& [offset, where] : seeks) {
    if (top_starts.count(offset) == 0) {
      throw InputError(source, detail::byte_position(where), "points to byte " + std::to_string(offset) + ", where no record starts");
    }
  }
  // rosbag reads conn_count connection records from index_pos, then chunk_count chunk infos.
  if (file_index_pos != 0) {
    std::size_t k = 0;
    while (k < top_ops.size() && top_ops[k].first != file_index_pos) ++k;
    for (std::uint32_t c = 0; c < conn_count; ++c, ++k) {
      if (k >= top_ops.size() || top_ops[k].second != "\x07") {
        throw InputError(source, "file header", "announces " + std::to_string(conn_count) + " connection records at its index; fewer are there");
      }
    }
    for (std::uint32_t c = 0; c < chunk_count; ++c, ++k) {
      if (k >= top_ops.size() || top_ops[k].second != "\x06") {
        throw InputError(source, "file header", "announces " + std::to_string(chunk_count) + " chunk info records; fewer are there");
      }
    }
  }
  for (const auto& ref : index_refs) {
    const auto inner = chunk_inner.find(ref.chunk);
    const bool ok = inner != chunk_inner.end() ? inner->second.count(ref.offset) > 0
                                               : chunk_size.count(ref.chunk) > 0 && ref.offset + 8 <= chunk_size[ref.chunk];
    if (!ok) throw InputError(source, detail::byte_position(ref.where), "index entry points outside its chunk's records");
  }
  info.compression = kinds.empty() ? "none" : kinds.size() == 1 ? *kinds.begin() : "mixed";
}

bool is_ros2(const fs::path& path) { return fs::is_directory(path) || access::is_mcap_file(path); }

/// The recording at `path`, whatever its kind: a folder is rosbag2, a file starting with the MCAP
/// magic is MCAP, anything else must be a ROS 1 bag (its records checked first, into `ros1_info`).
/// A ROS 1 bag that rosbag cannot open by its index (cut off before the index was written, or
/// with the index or a record damaged) is read record by record up to where it stops being
/// readable (no `rosbag reindex` needed), with a warning saying so.
std::unique_ptr<access::Recording> open_recording(const fs::path& path, BagInfo& ros1_info) {
  if (!fs::exists(path)) throw InputError(path.string(), "", "cannot open: no such file or folder");
  if (is_ros2(path)) return access::open_ros2(path);
  if (!fs::is_regular_file(path)) throw InputError(path.string(), "", "cannot open: not a regular file");
  // Read once: for the record check, and for the linear reading if rosbag cannot use the index.
  std::string bytes = detail::read_file_bytes(path);
  std::exception_ptr indexed_error;
  try {
    check_bag_records(path, bytes, ros1_info);
    return access::open_ros1_bag(path.string());
  } catch (const std::bad_alloc&) {
    throw;
  } catch (const std::exception&) {
    indexed_error = std::current_exception();
  }
  // Not a bag at all: the indexed reader's error says so.
  if (!std::string_view(bytes).starts_with("#ROSBAG V2.0\n")) std::rethrow_exception(indexed_error);
  ros1_info = BagInfo{};
  return access::open_scanned_ros1_bag(path.string(), std::move(bytes));
}

}  // namespace

BagInfo read_bag_info(const fs::path& path) {
  return guarded(path, [&] {
    BagInfo info;
    const auto bag = open_recording(path, info);
    const access::Summary summary = bag->summary();
    info.format = summary.format;
    if (!summary.compression.empty()) info.compression = summary.compression;
    if (!summary.format.starts_with("ROS 1") || summary.scanned) info.chunks = summary.chunks;
    if (summary.scanned) {
      info.scanned_to = summary.readable_end;
      info.file_size = summary.file_size;
    }
    info.warnings = summary.warnings;
    info.version = summary.version;
    info.start_time = summary.start_time;
    info.end_time = summary.end_time;
    info.messages = summary.messages;
    for (const auto& t : summary.topics) info.topics.push_back({t.name, t.type, t.messages});
    return info;
  });
}

void decode_pointcloud2(const PointCloud2Data& cloud, PointCloud& points, CloudReadStats* stats,
                        const std::string& source, const std::string& position, std::vector<float>* times_s) {
  points.clear();
  if (times_s != nullptr) times_s->clear();
  struct Axis {
    std::uint32_t offset = 0;
    detail::ScalarType type = detail::ScalarType::kFloat32;
    bool found = false;
  };
  Axis axes[3];
  static constexpr const char* kNames[3] = {"x", "y", "z"};
  static constexpr detail::ScalarType kTypes[8] = {
      detail::ScalarType::kInt8,  detail::ScalarType::kUint8,  detail::ScalarType::kInt16,   detail::ScalarType::kUint16,
      detail::ScalarType::kInt32, detail::ScalarType::kUint32, detail::ScalarType::kFloat32, detail::ScalarType::kFloat64};
  for (const auto& f : cloud.fields) {
    for (int a = 0; a < 3; ++a) {
      if (f.name != kNames[a] || axes[a].found) continue;
      if (f.datatype < 1 || f.datatype > 8) {
        throw InputError(source, position, "field " + f.name + " has unknown datatype " + std::to_string(f.datatype));
      }
      axes[a] = {f.offset, kTypes[f.datatype - 1], true};
      if (static_cast<std::uint64_t>(f.offset) + detail::scalar_size(axes[a].type) > cloud.point_step) {
        throw InputError(source, position, "field " + f.name + " at offset " + std::to_string(f.offset) +
                                               " lies outside the point step of " + std::to_string(cloud.point_step) + " bytes");
      }
    }
  }
  for (int a = 0; a < 3; ++a) {
    if (!axes[a].found) throw InputError(source, position, std::string("the cloud has no ") + kNames[a] + " field");
  }
  Axis time_axis;
  if (times_s != nullptr) {
    for (const char* name : kPointTimeFields) {
      for (const auto& f : cloud.fields) {
        if (time_axis.found || f.name != name || f.datatype < 1 || f.datatype > 8) continue;
        time_axis = {f.offset, kTypes[f.datatype - 1], true};
        if (static_cast<std::uint64_t>(f.offset) + detail::scalar_size(time_axis.type) > cloud.point_step) {
          throw InputError(source, position, "field " + f.name + " lies outside the point step");
        }
      }
    }
  }
  std::vector<double> raw_times;
  const std::uint64_t row_bytes = static_cast<std::uint64_t>(cloud.width) * cloud.point_step;
  if (cloud.row_step < row_bytes) {
    throw InputError(source, position, "row_step " + std::to_string(cloud.row_step) + " is less than width " +
                                           std::to_string(cloud.width) + " x point_step " + std::to_string(cloud.point_step));
  }
  const std::uint64_t needed = static_cast<std::uint64_t>(cloud.height) * cloud.row_step;
  if (cloud.data.size() < needed) {
    throw InputError(source, position, "data holds " + std::to_string(cloud.data.size()) + " bytes, height x row_step needs " +
                                           std::to_string(needed));
  }
  const bool swap = cloud.is_bigendian != (std::endian::native == std::endian::big);
  const std::size_t n = static_cast<std::size_t>(cloud.height) * cloud.width;
  // No points: done, before a loop over rows that a height of 4e9 with empty rows (width 0, or
  // row_step 0) would make endless. With points, each row holds >= 1 byte of data, so the rows
  // are bounded by the data size checked above.
  if (n == 0) {
    if (time_axis.found) times_s->clear();
    return;
  }
  points.reserve(n);
  std::size_t dropped = 0;
  const char* base = reinterpret_cast<const char*>(cloud.data.data());
  // The common layout (x, y, z float32 in this machine's byte order, no time wanted): the floats
  // taken as they are, the same points and counts as the general loop below (a float is finite
  // exactly when its double is within FLT_MAX), in two fifths of its instructions.
  const bool plain = !swap && !time_axis.found && axes[0].type == detail::ScalarType::kFloat32 &&
                     axes[1].type == detail::ScalarType::kFloat32 && axes[2].type == detail::ScalarType::kFloat32;
  for (std::uint32_t r = 0; plain && r < cloud.height; ++r) {
    const char* row = base + static_cast<std::size_t>(r) * cloud.row_step;
    for (std::uint32_t c = 0; c < cloud.width; ++c) {
      const char* p = row + static_cast<std::size_t>(c) * cloud.point_step;
      float v[3];
      for (int a = 0; a < 3; ++a) std::memcpy(&v[a], p + axes[a].offset, sizeof(float));
      if (std::isfinite(v[0]) && std::isfinite(v[1]) && std::isfinite(v[2])) {
        points.emplace_back(v[0], v[1], v[2]);
      } else {
        ++dropped;
      }
    }
  }
  for (std::uint32_t r = 0; !plain && r < cloud.height; ++r) {
    const char* row = base + static_cast<std::size_t>(r) * cloud.row_step;
    for (std::uint32_t c = 0; c < cloud.width; ++c) {
      const char* p = row + static_cast<std::size_t>(c) * cloud.point_step;
      const std::size_t before = points.size();
      detail::append_if_finite(points, detail::load_scalar(p + axes[0].offset, axes[0].type, swap),
                               detail::load_scalar(p + axes[1].offset, axes[1].type, swap),
                               detail::load_scalar(p + axes[2].offset, axes[2].type, swap), dropped);
      if (time_axis.found && points.size() > before) {
        const double t = detail::load_scalar(p + time_axis.offset, time_axis.type, swap);
        if (!std::isfinite(t)) throw InputError(source, position, "a point's time is not a finite number");
        raw_times.push_back(t);
      }
    }
  }
  if (time_axis.found) *times_s = point_times_to_seconds(raw_times);
  if (stats != nullptr) {
    stats->points_read += n;
    stats->non_finite_dropped += dropped;
  }
}

std::optional<std::string> bag_imu_topic(const fs::path& path, const std::string& topic) {
  const BagInfo info = read_bag_info(path);
  std::vector<std::string> imu;
  for (const auto& t : info.topics) {
    if (t.type == "sensor_msgs/Imu" || t.type == "sensor_msgs/msg/Imu") imu.push_back(t.name);
  }
  if (!topic.empty()) {
    if (std::find(imu.begin(), imu.end(), topic) == imu.end()) {
      throw InputError(path.string(), "", "topic " + topic + " is not a sensor_msgs/Imu topic of the bag (see hmap bag-info)");
    }
    return topic;
  }
  if (imu.empty()) return std::nullopt;
  if (imu.size() > 1) {
    std::string names;
    for (const auto& n : imu) names += " " + n;
    throw InputError(path.string(), "", "several sensor_msgs/Imu topics (" + names.substr(1) + "): choose one with --imu-topic");
  }
  return imu.front();
}

ImuSamples read_bag_imu(const fs::path& path, const std::string& topic) {
  return guarded(path, [&] {
    BagInfo checked;
    const auto bag = open_recording(path, checked);
    ImuSamples out;
    for (const access::RawImu& r : bag->read_imu(topic)) {
      const std::string where = topic + " at stamp " + stamp_text(r.stamp);
      ImuSample s;
      s.t = r.stamp;
      s.gyro = Eigen::Vector3d(r.gyro[0], r.gyro[1], r.gyro[2]);
      s.accel = Eigen::Vector3d(r.accel[0], r.accel[1], r.accel[2]);
      if (!std::isfinite(s.t) || !s.gyro.allFinite() || !s.accel.allFinite()) {
        throw InputError(path.string(), where, "an IMU value is not a finite number");
      }
      if (r.orientation_covariance0 != -1.0) {
        const Eigen::Quaterniond q(r.orientation[3], r.orientation[0], r.orientation[1], r.orientation[2]);
        if (q.coeffs().allFinite() && q.norm() > 1e-6) s.orientation = q.normalized();
      }
      if (!out.empty() && !(s.t > out.back().t)) {
        throw InputError(path.string(), where, "stamp is not after the previous IMU message's");
      }
      out.push_back(s);
    }
    if (out.empty()) throw InputError(path.string(), "", "IMU topic " + topic + " has no messages");
    return out;
  });
}

struct BagCloudReader::Impl {
  fs::path path;
  BagCloudOptions options;
  std::unique_ptr<access::Recording> bag;
  std::vector<BagCloudFrame> frames;
  std::string pose_source;
  std::vector<std::string> warnings;
  bool cloud_topic_chosen = false;
};

BagCloudReader::BagCloudReader(const fs::path& path, const BagCloudOptions& options) : impl_(std::make_unique<Impl>()) {
  impl_->path = path;
  impl_->options = options;
  guarded(path, [&] {
    BagInfo checked;
    impl_->bag = open_recording(path, checked);
    impl_->warnings = impl_->bag->summary().warnings;
    const std::string source = path.string();
    if (impl_->options.cloud_topic.empty()) {
      // No topic asked for: the recording's only PointCloud2 topic, as a user would pick it.
      std::vector<std::string> clouds;
      for (const access::TopicCount& t : impl_->bag->summary().topics) {
        if (t.type == "sensor_msgs/PointCloud2" || t.type == "sensor_msgs/msg/PointCloud2") clouds.push_back(t.name);
      }
      if (clouds.empty()) throw InputError(source, "", "no sensor_msgs/PointCloud2 topic (see hmap bag-info " + source + ")");
      if (clouds.size() > 1) {
        std::string names;
        for (const std::string& c : clouds) names += (names.empty() ? "" : ", ") + c;
        throw Error(source + " has " + std::to_string(clouds.size()) + " PointCloud2 topics (" + names +
                    "): choose one with --cloud-topic");
      }
      impl_->options.cloud_topic = clouds.front();
      impl_->cloud_topic_chosen = true;
    }

    // The cloud messages and their headers (stamp, frame), indexed without decoding the points.
    for (auto& h : impl_->bag->index_clouds(impl_->options.cloud_topic, options.max_clouds)) {
      impl_->frames.push_back({h.stamp, std::move(h.frame_id), Pose::Identity()});
    }
    if (impl_->frames.empty()) {
      throw InputError(source, "", "topic " + impl_->options.cloud_topic + " has no messages (see hmap bag-info)");
    }
    TfTree tf;
    for (const auto& t : impl_->bag->read_tf()) tf.add(t, source);
    for (auto& [child, edge] : tf.edges) edge.T_parent_child.sort();

    const double tol = options.max_extrapolation;
    if (!options.pose_topic.empty()) {
      TimedPoses odom;
      std::string parent;
      std::string child;
      const auto raw = impl_->bag->read_poses(options.pose_topic);
      if (raw.empty()) throw InputError(source, "", "pose topic " + options.pose_topic + " has no messages");
      for (const auto& r : raw) {
        odom.add(r.stamp, to_pose(r, source, "pose topic " + options.pose_topic));
        parent = r.parent;
        child = r.child;
      }
      odom.sort();
      impl_->pose_source = "poses of " + options.pose_topic + " (" + parent + " <- " + (child.empty() ? "?" : child) + ")";
      for (auto& frame : impl_->frames) {
        const auto T = odom.at(frame.stamp, tol);
        if (!T) {
          throw InputError(source, impl_->options.cloud_topic + " at stamp " + stamp_text(frame.stamp),
                           "no pose: " + options.pose_topic + " has " + odom.span_text());
        }
        frame.T_map_cloud = *T;
        const std::string& cloud_frame = options.sensor_frame.empty() ? frame.frame_id : options.sensor_frame;
        if (!child.empty() && cloud_frame != child) {
          std::string why;
          if (const auto T_child_cloud = tf.lookup(child, cloud_frame, frame.stamp, tol, why)) {
            frame.T_map_cloud = *T * *T_child_cloud;
          }
        }
      }
    } else {
      if (tf.edges.empty()) {
        throw InputError(source, "", "no poses: the bag has no /tf; give --pose-topic (see hmap bag-info)");
      }
      impl_->pose_source = "/tf";
      for (auto& frame : impl_->frames) {
        const std::string& cloud_frame = options.sensor_frame.empty() ? frame.frame_id : options.sensor_frame;
        std::string why;
        const auto T = tf.lookup(options.map_frame, cloud_frame, frame.stamp, tol, why);
        if (!T) {
          throw InputError(source, impl_->options.cloud_topic + " at stamp " + stamp_text(frame.stamp),
                           "no pose from /tf for frame " + cloud_frame + ": " + why);
        }
        frame.T_map_cloud = *T;
      }
      std::string root;
      std::string why;
      (void)tf.to_root(impl_->frames.front().frame_id, impl_->frames.front().stamp, tol, root, why);
      impl_->pose_source = "/tf (" + (options.map_frame.empty() ? root : options.map_frame) + " <- " +
                           (options.sensor_frame.empty() ? impl_->frames.front().frame_id : options.sensor_frame) + ")";
    }
  });
}

BagCloudReader::~BagCloudReader() = default;

const std::vector<BagCloudFrame>& BagCloudReader::frames() const { return impl_->frames; }

const std::string& BagCloudReader::pose_source() const { return impl_->pose_source; }

const std::string& BagCloudReader::cloud_topic() const { return impl_->options.cloud_topic; }

bool BagCloudReader::cloud_topic_chosen() const { return impl_->cloud_topic_chosen; }

const std::vector<std::string>& BagCloudReader::warnings() const { return impl_->warnings; }

PointCloud BagCloudReader::read(std::size_t index, CloudReadStats* stats, std::vector<float>* times_s) const {
  const BagCloudFrame& frame = impl_->frames.at(index);
  return guarded(impl_->path, [&] {
    const access::RawCloud msg = impl_->bag->read_cloud(index);
    PointCloud2Data data;
    data.height = msg.height;
    data.width = msg.width;
    for (const auto& f : msg.fields) data.fields.push_back({f.name, f.offset, f.datatype, f.count});
    data.is_bigendian = msg.is_bigendian;
    data.point_step = msg.point_step;
    data.row_step = msg.row_step;
    data.data = std::span<const std::uint8_t>(msg.data.data(), msg.data.size());
    PointCloud points;
    decode_pointcloud2(data, points, stats, impl_->path.string(),
                       impl_->options.cloud_topic + " at stamp " + stamp_text(frame.stamp), times_s);
    return points;
  });
}

}  // namespace hmap::ros
