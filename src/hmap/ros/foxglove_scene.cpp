#include "hmap/ros/foxglove_scene.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <limits>
#include <cstring>
#include <tuple>
#include <vector>

#include "hmap/core/error.hpp"
#include "hmap/view/map_scene.hpp"

namespace hmap::ros {

namespace {

// --- ROS 2 message definitions (ros2msg: the type's fields, then each nested type after a line
// of '=' and "MSG: package/Type", as rosbag2 stores them) ------------------------------------

std::string sep(const char* name, const char* text) {
  return std::string(80, '=') + "\nMSG: " + name + "\n" + text;
}
constexpr const char* kTime = "int32 sec\nuint32 nanosec\n";
constexpr const char* kHeader = "builtin_interfaces/Time stamp\nstring frame_id\n";
constexpr const char* kQuaternion = "float64 x\nfloat64 y\nfloat64 z\nfloat64 w\n";
constexpr const char* kXyz = "float64 x\nfloat64 y\nfloat64 z\n";

std::string occupancy_grid_definition() {
  return std::string("std_msgs/Header header\nnav_msgs/MapMetaData info\nint8[] data\n") + sep("std_msgs/Header", kHeader) +
         sep("builtin_interfaces/Time", kTime) +
         sep("nav_msgs/MapMetaData",
             "builtin_interfaces/Time map_load_time\nfloat32 resolution\nuint32 width\nuint32 height\n"
             "geometry_msgs/Pose origin\n") +
         sep("geometry_msgs/Pose", "geometry_msgs/Point position\ngeometry_msgs/Quaternion orientation\n") +
         sep("geometry_msgs/Point", kXyz) + sep("geometry_msgs/Quaternion", kQuaternion);
}

std::string tf_message_definition() {
  return std::string("geometry_msgs/TransformStamped[] transforms\n") +
         sep("geometry_msgs/TransformStamped", "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/Transform transform\n") +
         sep("std_msgs/Header", kHeader) + sep("builtin_interfaces/Time", kTime) +
         sep("geometry_msgs/Transform", "geometry_msgs/Vector3 translation\ngeometry_msgs/Quaternion rotation\n") +
         sep("geometry_msgs/Vector3", kXyz) + sep("geometry_msgs/Quaternion", kQuaternion);
}

// --- JSON schemas of the foxglove.* messages written (the fields of Foxglove's own schemas;
// the primitives hmap does not use are listed as arrays and written empty) -----------------

constexpr const char* kJsonTime = R"({"type":"object","properties":{"sec":{"type":"integer","minimum":0},"nsec":{"type":"integer","minimum":0,"maximum":999999999}}})";
constexpr const char* kJsonVec3 = R"({"type":"object","properties":{"x":{"type":"number"},"y":{"type":"number"},"z":{"type":"number"}}})";
constexpr const char* kJsonQuat = R"({"type":"object","properties":{"x":{"type":"number"},"y":{"type":"number"},"z":{"type":"number"},"w":{"type":"number"}}})";
constexpr const char* kJsonColor = R"({"type":"object","properties":{"r":{"type":"number"},"g":{"type":"number"},"b":{"type":"number"},"a":{"type":"number"}}})";

std::string json_pose() {
  return std::string(R"({"type":"object","properties":{"position":)") + kJsonVec3 + R"(,"orientation":)" + kJsonQuat + "}}";
}

std::string scene_update_schema() {
  const std::string cube = std::string(R"({"type":"object","properties":{"pose":)") + json_pose() + R"(,"size":)" + kJsonVec3 +
                           R"(,"color":)" + kJsonColor + "}}";
  std::string entity = std::string(R"({"type":"object","properties":{"timestamp":)") + kJsonTime +
                       R"(,"frame_id":{"type":"string"},"id":{"type":"string"},"lifetime":)" + kJsonTime +
                       R"(,"frame_locked":{"type":"boolean"},"metadata":{"type":"array","items":{"type":"object","properties":{"key":{"type":"string"},"value":{"type":"string"}}}})";
  for (const char* empty : {"arrows", "spheres", "cylinders", "lines", "triangles", "texts", "models"}) {
    entity += std::string(",\"") + empty + R"(":{"type":"array","items":{"type":"object"}})";
  }
  entity += R"(,"cubes":{"type":"array","items":)" + cube + "}}}";
  return std::string(R"({"title":"foxglove.SceneUpdate","type":"object","properties":{"deletions":{"type":"array","items":{"type":"object","properties":{"timestamp":)") +
         kJsonTime + R"(,"type":{"type":"integer"},"id":{"type":"string"}}}},"entities":{"type":"array","items":)" + entity + "}}}";
}

std::string point_cloud_schema() {
  return std::string(R"({"title":"foxglove.PointCloud","type":"object","properties":{"timestamp":)") + kJsonTime +
         R"(,"frame_id":{"type":"string"},"pose":)" + json_pose() +
         R"(,"point_stride":{"type":"integer","minimum":0},"fields":{"type":"array","items":{"type":"object","properties":{"name":{"type":"string"},"offset":{"type":"integer","minimum":0},"type":{"type":"integer"}}}},"data":{"type":"string","contentEncoding":"base64"}}})";
}

std::string poses_in_frame_schema() {
  return std::string(R"({"title":"foxglove.PosesInFrame","type":"object","properties":{"timestamp":)") + kJsonTime +
         R"(,"frame_id":{"type":"string"},"poses":{"type":"array","items":)" + json_pose() + "}}}";
}

std::string grid_schema() {
  return std::string(R"({"title":"foxglove.Grid","type":"object","properties":{"timestamp":)") + kJsonTime +
         R"(,"frame_id":{"type":"string"},"pose":)" + json_pose() +
         R"(,"column_count":{"type":"integer","minimum":0},"cell_size":{"type":"object","properties":{"x":{"type":"number"},"y":{"type":"number"}}},"row_stride":{"type":"integer","minimum":0},"cell_stride":{"type":"integer","minimum":0},"fields":{"type":"array","items":{"type":"object","properties":{"name":{"type":"string"},"offset":{"type":"integer","minimum":0},"type":{"type":"integer"}}}},"data":{"type":"string","contentEncoding":"base64"}}})";
}

// --- CDR (XCDR1, little endian), as cdr.hpp reads it ----------------------------------------

class CdrWriter {
 public:
  CdrWriter() : bytes_{0x00, 0x01, 0x00, 0x00} {}  // CDR_LE encapsulation
  template <typename T>
  CdrWriter& put(T v) {
    align(sizeof(T));
    const auto at = bytes_.size();
    bytes_.resize(at + sizeof(T));
    std::memcpy(bytes_.data() + at, &v, sizeof(T));  // little-endian host (x86-64, arm64)
    return *this;
  }
  CdrWriter& string(const std::string& s) {
    put(static_cast<std::uint32_t>(s.size() + 1));
    bytes_.insert(bytes_.end(), s.begin(), s.end());
    bytes_.push_back(0);
    return *this;
  }
  CdrWriter& raw(std::span<const std::uint8_t> b) {
    bytes_.insert(bytes_.end(), b.begin(), b.end());
    return *this;
  }
  [[nodiscard]] const std::vector<std::uint8_t>& bytes() const { return bytes_; }

 private:
  void align(std::size_t n) {
    while ((bytes_.size() - 4) % n != 0) bytes_.push_back(0);
  }
  std::vector<std::uint8_t> bytes_;
};

// ROS's builtin_interfaces/Time holds int32 seconds: every stamp must fit there too.
constexpr std::uint64_t kMaxStampNs = 2147483647ULL * 1'000'000'000ULL;

void put_stamp(CdrWriter& w, std::uint64_t ns) {
  w.put(static_cast<std::int32_t>(ns / 1'000'000'000)).put(static_cast<std::uint32_t>(ns % 1'000'000'000));
}

std::vector<std::uint8_t> occupancy_grid_message(const view::GridImage& image, const FoxgloveSceneParams& p, std::uint64_t stamp_ns) {
  CdrWriter w;
  put_stamp(w, stamp_ns);
  w.string(p.frame);
  put_stamp(w, stamp_ns);  // map_load_time
  w.put(static_cast<float>(image.resolution)).put(static_cast<std::uint32_t>(image.width)).put(static_cast<std::uint32_t>(image.height));
  w.put(image.origin.x()).put(image.origin.y()).put(0.0);
  w.put(0.0).put(0.0).put(0.0).put(1.0);
  // The image's bytes are 0..100 and 255 for unknown, which as int8 is ROS's -1.
  w.put(static_cast<std::uint32_t>(image.cells.size())).raw(image.cells);
  return w.bytes();
}

/// world -> map (identity) and, with `T_map_sensor`, map -> sensor, both stamped `stamp_ns`.
std::vector<std::uint8_t> tf_message(const FoxgloveSceneParams& p, std::uint64_t stamp_ns, const Pose* T_map_sensor) {
  CdrWriter w;
  w.put(std::uint32_t{T_map_sensor != nullptr ? 2U : 1U});
  put_stamp(w, stamp_ns);
  w.string(p.parent_frame).string(p.frame);
  w.put(0.0).put(0.0).put(0.0);
  w.put(0.0).put(0.0).put(0.0).put(1.0);
  if (T_map_sensor != nullptr) {
    const Eigen::Vector3d t = T_map_sensor->translation();
    const Eigen::Quaterniond q(T_map_sensor->rotation());
    put_stamp(w, stamp_ns);
    w.string(p.frame).string(p.sensor_frame);
    w.put(t.x()).put(t.y()).put(t.z());
    w.put(q.x()).put(q.y()).put(q.z()).put(q.w());
  }
  return w.bytes();
}

// --- JSON text -------------------------------------------------------------------------------

/// Appends `v` with 4 decimals by default (0.1 mm, 1e-4 of a colour channel).
void number(std::string& out, double v, int decimals = 4) {
  char buf[400];  // a double's whole digits (309 at most) and the decimals
  const auto r = std::to_chars(buf, buf + sizeof(buf), v, std::chars_format::fixed, decimals);
  out.append(buf, r.ptr);
}

std::string json_stamp(std::uint64_t ns) {
  return "{\"sec\":" + std::to_string(ns / 1'000'000'000) + ",\"nsec\":" + std::to_string(ns % 1'000'000'000) + "}";
}

constexpr const char* kIdentityPose = R"({"position":{"x":0,"y":0,"z":0},"orientation":{"x":0,"y":0,"z":0,"w":1}})";

std::string base64(std::span<const std::uint8_t> in) {
  static constexpr char kAlphabet[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((in.size() + 2) / 3 * 4);
  std::size_t i = 0;
  for (; i + 2 < in.size(); i += 3) {
    const std::uint32_t v = (std::uint32_t{in[i]} << 16) | (std::uint32_t{in[i + 1]} << 8) | in[i + 2];
    for (int k = 3; k >= 0; --k) out.push_back(kAlphabet[(v >> (6 * k)) & 63]);
  }
  if (i < in.size()) {
    const std::uint32_t v = (std::uint32_t{in[i]} << 16) | (i + 1 < in.size() ? std::uint32_t{in[i + 1]} << 8 : 0);
    out.push_back(kAlphabet[(v >> 18) & 63]);
    out.push_back(kAlphabet[(v >> 12) & 63]);
    out.push_back(i + 1 < in.size() ? kAlphabet[(v >> 6) & 63] : '=');
    out.push_back('=');
  }
  return out;
}

/// foxglove.Grid of the grid image: one float32 field "occupancy", the probability 0..1, NaN
/// where unknown (a value no probability takes, unlike OccupancyGrid's -1 which a float colour
/// map would place below free); row-major from the lower-left corner.
std::string grid_message(const view::GridImage& image, const FoxgloveSceneParams& p, std::uint64_t stamp_ns) {
  std::vector<std::uint8_t> data(image.cells.size() * 4);
  for (std::size_t k = 0; k < image.cells.size(); ++k) {
    const float v = image.cells[k] == view::kUnknownCell ? std::numeric_limits<float>::quiet_NaN()
                                                           : static_cast<float>(image.cells[k]) / 100.0F;
    std::memcpy(data.data() + 4 * k, &v, 4);  // little-endian float32, NumericType FLOAT32 = 7
  }
  std::string msg = R"({"timestamp":)" + json_stamp(stamp_ns) + R"(,"frame_id":")" + p.frame + R"(","pose":{"position":{"x":)";
  number(msg, image.origin.x());
  msg += ",\"y\":";
  number(msg, image.origin.y());
  msg += R"(,"z":0},"orientation":{"x":0,"y":0,"z":0,"w":1}},"column_count":)" + std::to_string(image.width) +
         R"(,"cell_size":{"x":)";
  number(msg, image.resolution);
  msg += ",\"y\":";
  number(msg, image.resolution);
  msg += R"(},"row_stride":)" + std::to_string(4 * image.width) +
         R"(,"cell_stride":4,"fields":[{"name":"occupancy","offset":0,"type":7}],"data":")" + base64(data) + "\"}";
  return msg;
}

/// One HVoxel to draw, with its cell.
struct Cube {
  CellKey cell;
  float z_min, z_max;
};

std::int32_t floor_div(std::int32_t a, std::int32_t b) { return a >= 0 ? a / b : -((-a - 1) / b) - 1; }

}  // namespace

std::vector<std::uint64_t> stamps_ns_of(std::span<const double> stamps_s, const std::string& what) {
  std::vector<std::uint64_t> out;
  out.reserve(stamps_s.size());
  for (std::size_t k = 0; k < stamps_s.size(); ++k) {
    const double t = stamps_s[k];
    if (!(t >= 0.0 && t * 1e9 < static_cast<double>(kMaxStampNs) - 1.0)) {
      throw Error(what + ": stamp " + std::to_string(k + 1) + " (" + std::to_string(t) +
                  " s) is not a time an MCAP message can carry (0 to 2^31 s)");
    }
    // Whole seconds and the fraction apart: t · 1e9 in one double (~1.7e18 for a Unix time) would
    // round to 256 ns; the fraction is exact in a double and rounds to the nanosecond.
    const double seconds = std::floor(t);
    out.push_back(static_cast<std::uint64_t>(seconds) * 1'000'000'000ULL +
                  static_cast<std::uint64_t>(std::llround((t - seconds) * 1e9)));
  }
  return out;
}

FoxgloveSceneStats write_foxglove_mcap(const HMap& map, const OccupancyGrid* grid, std::span<const Pose> T_map_scans,
                                       std::span<const std::uint64_t> stamps_ns, const mcap::Sink& sink,
                                       const FoxgloveSceneParams& p) {
  if (p.tile_cells < 1 || p.tile_cells > 4096) throw Error("foxglove scene: tile_cells must be in 1..4096");
  if (p.frame.empty() || p.parent_frame.empty() || p.frame == p.parent_frame) {
    throw Error("foxglove scene: the frame and its parent must be two non-empty names");
  }
  if (p.sensor_frame.empty() || p.sensor_frame == p.frame || p.sensor_frame == p.parent_frame) {
    throw Error("foxglove scene: the sensor frame must be a non-empty name other than the map frame and its parent");
  }
  if (!stamps_ns.empty() && stamps_ns.size() != T_map_scans.size()) {
    throw Error("foxglove scene: " + std::to_string(stamps_ns.size()) + " stamps for " + std::to_string(T_map_scans.size()) +
                " poses");
  }
  for (const std::uint64_t t : stamps_ns) {
    if (t >= kMaxStampNs) throw Error("foxglove scene: stamp " + std::to_string(t) + " ns is past ROS's int32 seconds");
  }
  // The map as a whole is the state after the last scan.
  const std::uint64_t map_stamp = stamps_ns.empty() ? 0 : *std::max_element(stamps_ns.begin(), stamps_ns.end());
  FoxgloveSceneStats stats;
  mcap::Writer writer(sink, p.mcap);
  auto count = [&](const char* topic) { ++stats.messages[topic]; };

  // /tf first: the frames exist before anything drawn in them. One message per pose at its
  // stamp (the drive played back); without poses one, for the map frame.
  const auto tf_schema = writer.add_schema("tf2_msgs/msg/TFMessage", "ros2msg", tf_message_definition());
  const auto tf_channel = writer.add_channel(tf_schema, kTfTopic, "cdr");
  for (std::size_t k = 0; k < T_map_scans.size(); ++k) {
    const std::uint64_t stamp = stamps_ns.empty() ? 0 : stamps_ns[k];
    writer.write(tf_channel, stamp, tf_message(p, stamp, &T_map_scans[k]));
    count(kTfTopic);
  }
  if (T_map_scans.empty()) {
    writer.write(tf_channel, map_stamp, tf_message(p, map_stamp, nullptr));
    count(kTfTopic);
  }

  if (grid != nullptr && grid->known_cells() > 0) {
    const auto schema = writer.add_schema("nav_msgs/msg/OccupancyGrid", "ros2msg", occupancy_grid_definition());
    const auto channel = writer.add_channel(schema, kMapTopic, "cdr");
    const view::GridImage image = view::grid_image(*grid);
    writer.write(channel, map_stamp, occupancy_grid_message(image, p, map_stamp));
    count(kMapTopic);
    const auto grid_schema_id = writer.add_schema("foxglove.Grid", "jsonschema", grid_schema());
    const auto grid_channel = writer.add_channel(grid_schema_id, kGridTopic, "json");
    writer.write(grid_channel, map_stamp, grid_message(image, p, map_stamp));
    count(kGridTopic);
  }

  // /hvoxels: the columns by tile, in (tile, cell) order so that the same map gives the same file.
  std::vector<Cube> cubes;
  float z_low = 0.0F, z_high = 0.0F;
  map.for_each_column([&](const CellKey& key, const ColumnView& column) {
    for (const HVoxel& v : column) {
      z_low = cubes.empty() ? v.z_min : std::min(z_low, v.z_min);
      z_high = cubes.empty() ? v.z_max : std::max(z_high, v.z_max);
      cubes.push_back({key, v.z_min, v.z_max});
    }
  });
  const std::int32_t t = p.tile_cells;
  auto tile_of = [&](const Cube& c) { return std::make_pair(floor_div(c.cell.i, t), floor_div(c.cell.j, t)); };
  std::sort(cubes.begin(), cubes.end(), [&](const Cube& a, const Cube& b) {
    return std::tuple(tile_of(a), a.cell.i, a.cell.j, a.z_min) < std::tuple(tile_of(b), b.cell.i, b.cell.j, b.z_min);
  });
  if (!cubes.empty()) {
    const auto schema = writer.add_schema("foxglove.SceneUpdate", "jsonschema", scene_update_schema());
    const auto channel = writer.add_channel(schema, kHVoxelTopic, "json");
    const double cell = map.cell_size();
    const std::string stamp = json_stamp(map_stamp);
    std::string msg;
    for (std::size_t begin = 0; begin < cubes.size();) {
      const auto tile = tile_of(cubes[begin]);
      std::size_t end = begin;
      while (end < cubes.size() && tile_of(cubes[end]) == tile) ++end;
      // One entity per tile, kept until replaced (lifetime 0), so that every tile stays drawn.
      msg = R"({"deletions":[],"entities":[{"timestamp":)" + stamp + R"(,"frame_id":")" + p.frame +
            R"(","id":"hvoxels/)" + std::to_string(tile.first) + "_" + std::to_string(tile.second) +
            R"(","lifetime":{"sec":0,"nsec":0},"frame_locked":true,"metadata":[],"arrows":[],"spheres":[],"cylinders":[],"lines":[],"triangles":[],"texts":[],"models":[],"cubes":[)";
      for (std::size_t k = begin; k < end; ++k) {
        const Cube& c = cubes[k];
        const auto rgba = view::height_colour(0.5F * (c.z_min + c.z_max), z_low, z_high);
        if (k > begin) msg += ',';
        msg += R"({"pose":{"position":{"x":)";
        number(msg, (c.cell.i + 0.5) * cell);
        msg += ",\"y\":";
        number(msg, (c.cell.j + 0.5) * cell);
        msg += ",\"z\":";
        number(msg, 0.5 * (static_cast<double>(c.z_min) + c.z_max));
        msg += R"(},"orientation":{"x":0,"y":0,"z":0,"w":1}},"size":{"x":)";
        number(msg, cell);
        msg += ",\"y\":";
        number(msg, cell);
        msg += ",\"z\":";
        number(msg, static_cast<double>(c.z_max) - c.z_min);
        msg += R"(},"color":{"r":)";
        number(msg, rgba[0] / 255.0);
        msg += ",\"g\":";
        number(msg, rgba[1] / 255.0);
        msg += ",\"b\":";
        number(msg, rgba[2] / 255.0);
        msg += ",\"a\":1}}";
      }
      msg += "]}]}";
      writer.write(channel, map_stamp, msg);
      count(kHVoxelTopic);
      begin = end;
    }
    stats.cubes = cubes.size();
  }

  // /points: one message, since Foxglove draws a point cloud topic's latest message only.
  if (p.points_z_step >= 0.0 && !cubes.empty()) {
    PointCloud points = recover_points(map, p.points_z_step > 0.0 ? p.points_z_step : map.cell_size());
    // In (x, y, z) order: recover_points walks the tile index, whose order depends on how the map was built.
    std::sort(points.begin(), points.end(), [](const Point3f& a, const Point3f& b) {
      return std::tuple(a.x(), a.y(), a.z()) < std::tuple(b.x(), b.y(), b.z());
    });
    std::vector<std::uint8_t> data(points.size() * 12);
    for (std::size_t k = 0; k < points.size(); ++k) {
      const float xyz[3] = {points[k].x(), points[k].y(), points[k].z()};
      std::memcpy(data.data() + 12 * k, xyz, 12);  // little-endian float32, Foxglove's NumericType FLOAT32 = 7
    }
    const auto schema = writer.add_schema("foxglove.PointCloud", "jsonschema", point_cloud_schema());
    const auto channel = writer.add_channel(schema, kPointsTopic, "json");
    const std::string msg = R"({"timestamp":)" + json_stamp(map_stamp) + R"(,"frame_id":")" + p.frame + R"(","pose":)" +
                            kIdentityPose +
                            R"(,"point_stride":12,"fields":[{"name":"x","offset":0,"type":7},{"name":"y","offset":4,"type":7},{"name":"z","offset":8,"type":7}],"data":")" +
                            base64(data) + "\"}";
    writer.write(channel, map_stamp, msg);
    count(kPointsTopic);
    stats.points = points.size();
  }

  if (!T_map_scans.empty()) {
    const auto schema = writer.add_schema("foxglove.PosesInFrame", "jsonschema", poses_in_frame_schema());
    const auto channel = writer.add_channel(schema, kTrajectoryTopic, "json");
    std::string msg = R"({"timestamp":)" + json_stamp(map_stamp) + R"(,"frame_id":")" + p.frame + R"(","poses":[)";
    for (std::size_t k = 0; k < T_map_scans.size(); ++k) {
      const Eigen::Vector3d position = T_map_scans[k].translation();
      const Eigen::Quaterniond q(T_map_scans[k].rotation());
      msg += k == 0 ? "" : ",";
      msg += R"({"position":{"x":)";
      const double values[7] = {position.x(), position.y(), position.z(), q.x(), q.y(), q.z(), q.w()};
      const char* names[7] = {nullptr, ",\"y\":", ",\"z\":", R"(},"orientation":{"x":)", ",\"y\":", ",\"z\":", ",\"w\":"};
      for (int v = 0; v < 7; ++v) {
        if (names[v] != nullptr) msg += names[v];
        number(msg, values[v], 6);  // 1 µm, 1e-6 of a unit quaternion
      }
      msg += "}}";
    }
    msg += "]}";
    writer.write(channel, map_stamp, msg);
    count(kTrajectoryTopic);
  }

  stats.bytes = writer.finish().bytes;
  return stats;
}

}  // namespace hmap::ros
