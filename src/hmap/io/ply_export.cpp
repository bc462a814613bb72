#include "hmap/io/ply_export.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <ostream>
#include <string>
#include <utility>
#include <vector>

#include "hmap/core/error.hpp"
#include "hmap/io/atomic_file.hpp"

namespace hmap {

namespace {

using Rgb = std::array<unsigned char, 3>;

constexpr std::size_t kFlushBytes = std::size_t{1} << 16;
constexpr Rgb kGrey = {128, 128, 128};

/// Blue → cyan → green → yellow → red as z goes from lo to hi; grey for a non-finite z.
Rgb height_colour(double z, double lo, double hi) {
  static constexpr std::array<std::array<double, 3>, 5> kStops = {
      {{0, 0, 255}, {0, 255, 255}, {0, 255, 0}, {255, 255, 0}, {255, 0, 0}}};
  if (!std::isfinite(z)) return kGrey;
  const double t = hi > lo ? std::clamp((z - lo) / (hi - lo), 0.0, 1.0) : 0.5;
  const double s = t * static_cast<double>(kStops.size() - 1);
  const std::size_t k = std::min(static_cast<std::size_t>(s), kStops.size() - 2);
  const double f = s - static_cast<double>(k);
  Rgb rgb{};
  for (std::size_t c = 0; c < 3; ++c) {
    rgb[c] = static_cast<unsigned char>(std::lround(kStops[k][c] + f * (kStops[k + 1][c] - kStops[k][c])));
  }
  return rgb;
}

/// Little-endian binary records, handed to the stream in large pieces.
class RecordWriter {
 public:
  explicit RecordWriter(std::ostream& out) : out_(out) { buffer_.reserve(kFlushBytes + 64); }
  ~RecordWriter() = default;
  RecordWriter(const RecordWriter&) = delete;
  RecordWriter& operator=(const RecordWriter&) = delete;

  void text(const std::string& s) { buffer_ += s; }
  void u8(unsigned char v) { buffer_.push_back(static_cast<char>(v)); }
  void u32(std::uint32_t v) {
    for (int k = 0; k < 4; ++k) buffer_.push_back(static_cast<char>((v >> (8 * k)) & 0xFFU));
  }
  void i32(std::int32_t v) { u32(static_cast<std::uint32_t>(v)); }
  void f32(float v) { u32(std::bit_cast<std::uint32_t>(v)); }
  void vertex(float x, float y, float z, const Rgb& rgb) {
    f32(x);
    f32(y);
    f32(z);
    for (const unsigned char c : rgb) u8(c);
    if (buffer_.size() >= kFlushBytes) flush();
  }
  void flush() {
    out_.write(buffer_.data(), static_cast<std::streamsize>(buffer_.size()));
    buffer_.clear();
  }

 private:
  std::ostream& out_;
  std::string buffer_;
};

std::string ply_header(const std::string& comment, std::uint64_t vertices,
                       std::optional<std::uint64_t> faces) {
  std::string h = "ply\nformat binary_little_endian 1.0\ncomment " + comment + "\n";
  h += "element vertex " + std::to_string(vertices) + "\n";
  h += "property float x\nproperty float y\nproperty float z\n";
  h += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
  if (faces) {
    h += "element face " + std::to_string(*faces) + "\n";
    h += "property list uchar int vertex_indices\n";
  }
  h += "end_header\n";
  return h;
}

struct Box {
  float x0, y0, z0, x1, y1, z1;
};

/// Calls f(const Box&) for every HVoxel: tiles by key, cells by local index, HVoxels upwards.
template <typename F>
void for_each_box(const HMap& map, F&& f) {
  std::vector<std::pair<CellKey, const HMap::Tile*>> tiles;
  map.for_each_tile([&tiles](const CellKey& key, const HMap::Tile& tile) { tiles.emplace_back(key, &tile); });
  std::sort(tiles.begin(), tiles.end(), [](const auto& a, const auto& b) {
    return a.first.i != b.first.i ? a.first.i < b.first.i : a.first.j < b.first.j;
  });
  const double half = 0.5 * map.cell_size();
  const double min_height = 0.1 * map.cell_size();  // flat HVoxels would be invisible
  for (const auto& [tile_key, tile] : tiles) {
    for (int local = 0; local < HMap::kTileCells; ++local) {
      const ColumnView column = tile->column(local);
      if (column.empty()) continue;
      const Eigen::Vector2d c = map.cell_center(HMap::key_in_tile(tile_key, local));
      for (const HVoxel& v : column) {
        double z0 = v.z_min;
        double z1 = v.z_max;
        if (z1 - z0 < min_height) {
          const double mid = 0.5 * (z0 + z1);
          z0 = mid - 0.5 * min_height;
          z1 = mid + 0.5 * min_height;
        }
        f(Box{static_cast<float>(c.x() - half), static_cast<float>(c.y() - half), static_cast<float>(z0),
              static_cast<float>(c.x() + half), static_cast<float>(c.y() + half), static_cast<float>(z1)});
      }
    }
  }
}

}  // namespace

void write_hvoxel_boxes_ply(const std::filesystem::path& path, const HMap& map) {
  std::uint64_t boxes = 0;
  double lo = std::numeric_limits<double>::infinity();
  double hi = -lo;
  for_each_box(map, [&](const Box& b) {
    ++boxes;
    if (std::isfinite(b.z0)) lo = std::min(lo, static_cast<double>(b.z0));
    if (std::isfinite(b.z1)) hi = std::max(hi, static_cast<double>(b.z1));
  });
  if (boxes > static_cast<std::uint64_t>(std::numeric_limits<std::int32_t>::max()) / 8) {
    throw Error(path.string() + ": " + std::to_string(boxes) +
                " HVoxels are too many for a PLY file with int vertex indices");
  }

  write_file_atomic(path, [&](std::ostream& out) {
    RecordWriter w(out);
    w.text(ply_header("hmap HVoxels, one box each", 8 * boxes, 6 * boxes));
    for_each_box(map, [&](const Box& b) {
      const Rgb bottom = height_colour(b.z0, lo, hi);
      const Rgb top = height_colour(b.z1, lo, hi);
      w.vertex(b.x0, b.y0, b.z0, bottom);
      w.vertex(b.x1, b.y0, b.z0, bottom);
      w.vertex(b.x1, b.y1, b.z0, bottom);
      w.vertex(b.x0, b.y1, b.z0, bottom);
      w.vertex(b.x0, b.y0, b.z1, top);
      w.vertex(b.x1, b.y0, b.z1, top);
      w.vertex(b.x1, b.y1, b.z1, top);
      w.vertex(b.x0, b.y1, b.z1, top);
    });
    // Counter-clockwise seen from outside: bottom, top, y0 side, x1 side, y1 side, x0 side.
    static constexpr std::array<std::array<std::int32_t, 4>, 6> kFaces = {
        {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4}, {1, 2, 6, 5}, {2, 3, 7, 6}, {3, 0, 4, 7}}};
    for (std::uint64_t k = 0; k < boxes; ++k) {
      const auto base = static_cast<std::int32_t>(8 * k);
      for (const auto& face : kFaces) {
        w.u8(4);
        for (const std::int32_t corner : face) w.i32(base + corner);
      }
      if (k % 1024 == 1023) w.flush();
    }
    w.flush();
  });
}

void write_points_ply(const std::filesystem::path& path, const PointCloud& points) {
  double lo = std::numeric_limits<double>::infinity();
  double hi = -lo;
  for (const Point3f& p : points) {
    if (!p.allFinite()) continue;
    lo = std::min(lo, static_cast<double>(p.z()));
    hi = std::max(hi, static_cast<double>(p.z()));
  }
  write_file_atomic(path, [&](std::ostream& out) {
    RecordWriter w(out);
    w.text(ply_header("hmap point cloud", points.size(), std::nullopt));
    for (const Point3f& p : points) {
      w.vertex(p.x(), p.y(), p.z(), p.allFinite() ? height_colour(p.z(), lo, hi) : kGrey);
    }
    w.flush();
  });
}

}  // namespace hmap
