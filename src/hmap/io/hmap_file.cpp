#include "hmap/io/hmap_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#include <xxhash.h>
#include <zstd.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "hmap/core/error.hpp"
#include "hmap/io/read_support.hpp"
#include "hmap/io/atomic_file.hpp"

namespace hmap {

namespace {

/// Parameters added after format version 1 was first written: a file without them takes their
/// defaults (every other parameter must be there, so a damaged header is still found).
bool is_later_parameter(const std::string& name) {
  static constexpr const char* kLater[] = {
      "ground.top_noise",         "slam.surface_max_height", "slam.attitude_gate", "slam.attitude_iterations",
      "slam.attitude_min_surfaces", "slam.attitude_min_lever", "slam.level_prior",  "slam.max_floor_tilt", "slam.level_max_slope",
      "occupancy.free_ray_height", "slam.imu_gravity_time_constant", "slam.imu_accel_gate", "slam.imu_tilt_weight",
      "slam.imu_roll", "slam.imu_pitch", "slam.imu_yaw", "slam.deskew",
      "slam.odometry_sigma_translation", "slam.odometry_sigma_rotation", "slam.odometry_noise",
      "occupancy.obstacle_reach", "slam.loop_closure", "slam.keyframe_distance", "slam.keyframe_rotation",
      "slam.loop_submap_scans", "slam.loop_min_travel", "slam.loop_search_radius", "slam.loop_max_descriptor_distance",
      "slam.loop_candidates", "slam.loop_search_translation", "slam.loop_search_rotation", "slam.loop_min_score",
      "slam.hvoxel_centroids", "slam.wall_refine", "slam.wall_min_height", "slam.wall_band_height", "slam.wall_iterations",
      "slam.wall_min_pairs", "slam.wall_max_rotation", "slam.wall_tilt_drift", "map.ring_gap_slope",
      "map.ring_gap_max"};
  for (const char* n : kLater) {
    if (name == n) return true;
  }
  return false;
}

constexpr std::array<unsigned char, 8> kMagic = {0x89, 'H', 'M', 'A', 'P', '\r', '\n', 0x1a};
constexpr std::uint32_t kVersion = 3;
constexpr std::uint32_t kOldestVersion = 1;
constexpr std::uint64_t kPatchBytes = 7 * 8 + 4;
constexpr std::uint64_t kGridTileBytes = 8 + 4 * OccupancyGrid::kTileCells;
constexpr std::uint64_t kCentroidBytes = 4 + 4 + 4 + 4 + 8;  // i, j, offset x, y, weight
constexpr std::int32_t kGridTileKeyLimit = std::int32_t{1} << (30 - OccupancyGrid::kTileBits);
constexpr std::size_t kJsonOffset = 24;                 // after magic, version, flags, J
constexpr std::size_t kMinFileBytes = kJsonOffset + 24;  // + U, C, checksum: J = C = 0
constexpr std::size_t kChecksumBytes = 8;
constexpr std::uint64_t kMaxPayloadBytes = std::uint64_t{32} << 30;  // 32 GiB
constexpr std::uint64_t kHVoxelBytes = 16;
/// The smallest stored tile: its key, 256 one-byte counts and one HVoxel (empty tiles are skipped).
constexpr std::uint64_t kMinTileBytes = 8 + HMap::kTileCells + kHVoxelBytes;
/// Tiles hold cells within ±2^30 (HMap::kMaxKey), so tile_i · 16 cannot overflow an int32.
constexpr std::int32_t kTileKeyLimit = std::int32_t{1} << (30 - HMap::kTileBits);
constexpr std::int32_t kCellKeyLimit = std::int32_t{1} << 30;  // the HMAP's tiles' cells (kTileKeyLimit)
constexpr int kZstdLevel = 3;  // zstd's default: level 3 windows are at most 2^21 bytes
/// Frames asking for a larger window are refused on reading, so a hostile frame header cannot
/// make the decoder allocate more than 8 MiB.
constexpr int kZstdWindowLogMax = 23;

// ---- little-endian encoding, byte by byte ----

void put_u32(std::string& out, std::uint32_t v) {
  for (int k = 0; k < 4; ++k) out.push_back(static_cast<char>((v >> (8 * k)) & 0xFFU));
}

void put_u64(std::string& out, std::uint64_t v) {
  for (int k = 0; k < 8; ++k) out.push_back(static_cast<char>((v >> (8 * k)) & 0xFFU));
}

void put_f32(std::string& out, float v) { put_u32(out, std::bit_cast<std::uint32_t>(v)); }

void put_varint(std::string& out, std::uint64_t v) {
  while (v >= 0x80) {
    out.push_back(static_cast<char>((v & 0x7FU) | 0x80U));
    v >>= 7;
  }
  out.push_back(static_cast<char>(v));
}

std::uint64_t varint_size(std::uint64_t v) {
  std::uint64_t n = 1;
  for (; v >= 0x80; v >>= 7) ++n;
  return n;
}

std::uint32_t get_u32(const unsigned char* p) {
  std::uint32_t v = 0;
  for (int k = 3; k >= 0; --k) v = (v << 8) | p[k];
  return v;
}

std::uint64_t get_u64(const unsigned char* p) {
  std::uint64_t v = 0;
  for (int k = 7; k >= 0; --k) v = (v << 8) | p[k];
  return v;
}

std::string byte_at(std::uint64_t offset) { return "byte " + std::to_string(offset); }

std::string cell_name(const CellKey& key) {
  return "cell (" + std::to_string(key.i) + ", " + std::to_string(key.j) + ")";
}

// ---- writing ----

using TileRef = std::pair<CellKey, const HMap::Tile*>;

/// The tiles holding at least one HVoxel, in increasing (i, j): the file's order.
std::vector<TileRef> sorted_nonempty_tiles(const HMap& map) {
  std::vector<TileRef> tiles;
  map.for_each_tile([&tiles](const CellKey& key, const HMap::Tile& tile) {
    if (!tile.empty()) tiles.emplace_back(key, &tile);
  });
  std::sort(tiles.begin(), tiles.end(), [](const TileRef& a, const TileRef& b) {
    return a.first.i != b.first.i ? a.first.i < b.first.i : a.first.j < b.first.j;
  });
  return tiles;
}

std::uint64_t tile_bytes(const HMap::Tile& tile) {
  std::uint64_t n = 8;
  for (int local = 0; local < HMap::kTileCells; ++local) {
    n += varint_size(tile.size(local)) + kHVoxelBytes * tile.size(local);
  }
  return n;
}

void append_tile(std::string& out, const CellKey& key, const HMap::Tile& tile) {
  put_u32(out, static_cast<std::uint32_t>(key.i));
  put_u32(out, static_cast<std::uint32_t>(key.j));
  for (int local = 0; local < HMap::kTileCells; ++local) {  // cells are stored in local_index order
    const ColumnView c = tile.column(local);
    put_varint(out, c.size());
    for (const HVoxel& v : c) {
      put_f32(out, v.z_min);
      put_f32(out, v.z_max);
      put_f32(out, v.count);
      put_f32(out, v.density);
    }
  }
}

void put_f64(std::string& out, double v) { put_u64(out, std::bit_cast<std::uint64_t>(v)); }

using GridTileRef = std::pair<CellKey, const OccupancyGrid::Tile*>;

std::vector<GridTileRef> sorted_grid_tiles(const OccupancyGrid* grid) {
  std::vector<GridTileRef> tiles;
  if (grid == nullptr) return tiles;
  grid->for_each_tile([&tiles](const CellKey& key, const OccupancyGrid::Tile& tile) {
    if (std::any_of(tile.log_odds.begin(), tile.log_odds.end(), [](float l) { return !std::isnan(l); })) {
      tiles.emplace_back(key, &tile);
    }
  });
  std::sort(tiles.begin(), tiles.end(), [](const GridTileRef& a, const GridTileRef& b) {
    return a.first.i != b.first.i ? a.first.i < b.first.i : a.first.j < b.first.j;
  });
  return tiles;
}

/// The version-2 sections after the tiles: ground patches, then the grid.
std::string hybrid_sections(std::span<const GroundPatch> ground, const std::vector<GridTileRef>& grid_tiles) {
  std::string out;
  put_u64(out, ground.size());
  for (const GroundPatch& p : ground) {
    for (int k = 0; k < 3; ++k) put_f64(out, p.center[k]);
    for (int k = 0; k < 3; ++k) put_f64(out, p.normal[k]);
    put_f64(out, p.half_size);
    put_u32(out, static_cast<std::uint32_t>(p.parent));
  }
  put_u64(out, grid_tiles.size());
  for (const auto& [key, tile] : grid_tiles) {
    put_u32(out, static_cast<std::uint32_t>(key.i));
    put_u32(out, static_cast<std::uint32_t>(key.j));
    for (const float l : tile->log_odds) put_f32(out, l);
  }
  return out;
}

/// The version-3 section after the grid: the cell centroids in increasing (i, j) order, those in
/// the stored tiles alone (`tiles`, sorted: a centroid whose cell's HVoxels were all carved away
/// since is left out, so that the reader can bound them by the map's tiles).
std::string centroid_section(const CellCentroids* centroids, const std::vector<TileRef>& tiles) {
  struct Entry {
    CellKey cell;
    Eigen::Vector2f offset;
    double weight;
  };
  std::vector<Entry> cells;
  if (centroids != nullptr) {
    cells.reserve(centroids->size());
    const auto stored = [&tiles](const CellKey& tile) {
      return std::binary_search(tiles.begin(), tiles.end(), TileRef{tile, nullptr}, [](const TileRef& a, const TileRef& b) {
        return a.first.i < b.first.i || (a.first.i == b.first.i && a.first.j < b.first.j);
      });
    };
    centroids->for_each([&](const CellKey& cell, const Eigen::Vector2f& offset, double weight) {
      if (stored(HMap::tile_of(cell))) cells.push_back({cell, offset, weight});
    });
  }
  std::sort(cells.begin(), cells.end(), [](const Entry& a, const Entry& b) {
    return a.cell.i < b.cell.i || (a.cell.i == b.cell.i && a.cell.j < b.cell.j);
  });
  std::string out;
  out.reserve(8 + cells.size() * kCentroidBytes);
  put_u64(out, cells.size());
  for (const Entry& e : cells) {
    put_u32(out, static_cast<std::uint32_t>(e.cell.i));
    put_u32(out, static_cast<std::uint32_t>(e.cell.j));
    put_f32(out, e.offset.x());
    put_f32(out, e.offset.y());
    put_f64(out, e.weight);
  }
  return out;
}

std::string params_json(const Params& params) {
  Params copy = params;  // param_refs hands out setters too, so it wants a mutable Params
  nlohmann::ordered_json json;
  json["format"] = "hmap";
  json["tile_size"] = HMap::kTileSize;
  for (const ParamRef& r : param_refs(copy)) json[r.name] = r.get();
  return json.dump(2);  // doubles are printed in their shortest form that reads back exactly
}

struct ZstdCCtxFree {
  void operator()(ZSTD_CCtx* c) const { ZSTD_freeCCtx(c); }
};

/// One zstd frame built from pieces, the uncompressed size pledged so it is in the frame header.
class PayloadCompressor {
 public:
  explicit PayloadCompressor(std::uint64_t size)
      : cctx_(ZSTD_createCCtx()), chunk_(ZSTD_CStreamOutSize()) {
    if (!cctx_) throw Error("zstd: cannot create a compression context");
    check(ZSTD_CCtx_setParameter(cctx_.get(), ZSTD_c_compressionLevel, kZstdLevel));
    check(ZSTD_CCtx_setPledgedSrcSize(cctx_.get(), size));
  }

  void add(std::string_view bytes) { run(bytes, ZSTD_e_continue); }

  std::string finish() {
    run({}, ZSTD_e_end);
    return std::move(compressed_);
  }

 private:
  static void check(std::size_t code) {
    if (ZSTD_isError(code)) throw Error(std::string("zstd: ") + ZSTD_getErrorName(code));
  }

  void run(std::string_view bytes, ZSTD_EndDirective mode) {
    ZSTD_inBuffer in{bytes.data(), bytes.size(), 0};
    for (;;) {
      ZSTD_outBuffer out{chunk_.data(), chunk_.size(), 0};
      const std::size_t remaining = ZSTD_compressStream2(cctx_.get(), &out, &in, mode);
      check(remaining);
      compressed_.append(chunk_.data(), out.pos);
      if (mode == ZSTD_e_end ? remaining == 0 : in.pos == in.size) return;
    }
  }

  std::unique_ptr<ZSTD_CCtx, ZstdCCtxFree> cctx_;
  std::vector<char> chunk_;
  std::string compressed_;
};

struct Xxh64StateFree {
  void operator()(XXH64_state_t* s) const { XXH64_freeState(s); }
};

// ---- reading ----

struct FdClose {
  int fd;
  ~FdClose() { ::close(fd); }
};

std::vector<unsigned char> read_whole_file(const std::filesystem::path& path) {
  const std::string name = path.string();
  // O_NONBLOCK: a FIFO would otherwise block in open() until a writer came; it is refused below.
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
  if (fd < 0) throw InputError(name, "", std::string("cannot open: ") + std::strerror(errno));
  const FdClose closer{fd};
  struct stat st {};
  if (::fstat(fd, &st) != 0) throw InputError(name, "", std::string("cannot stat: ") + std::strerror(errno));
  if (!S_ISREG(st.st_mode)) {
    throw InputError(name, "", "is " + std::string(detail::file_kind(st.st_mode)) + ", not a regular file");
  }
  if (static_cast<std::uintmax_t>(st.st_size) > detail::kMaxInputBytes) {
    throw InputError(name, "", std::to_string(st.st_size) + " bytes, more than the " +
                                   std::to_string(detail::kMaxInputBytes >> 20) + " MiB an input may hold");
  }
  std::vector<unsigned char> bytes(static_cast<std::size_t>(st.st_size));  // a real size, not a claim
  std::size_t got = 0;
  while (got < bytes.size()) {
    const ssize_t n = ::read(fd, bytes.data() + got, bytes.size() - got);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) throw InputError(name, byte_at(got), std::string("cannot read: ") + std::strerror(errno));
    if (n == 0) break;  // shrank while being read: the checks below see a short file
    got += static_cast<std::size_t>(n);
  }
  bytes.resize(got);
  return bytes;
}

/// Parses the params JSON into a validated, empty map.
HMap map_from_params(const std::string& name, std::span<const unsigned char> text) {
  const std::string where = byte_at(kJsonOffset);
  const auto fail = [&](const std::string& problem) {
    return InputError(name, where, "params JSON: " + problem);
  };
  nlohmann::json json;
  try {
    json = nlohmann::json::parse(text.begin(), text.end());
  } catch (const nlohmann::json::exception& e) {
    throw fail(std::string("cannot be parsed: ") + e.what());
  }
  if (!json.is_object()) throw fail("expected an object");
  const auto format = json.find("format");
  if (format == json.end() || !format->is_string() || format->get<std::string>() != "hmap") {
    throw fail("expected \"format\": \"hmap\"");
  }
  const auto tile_size = json.find("tile_size");
  if (tile_size == json.end() || !tile_size->is_number() ||
      tile_size->get<double>() != HMap::kTileSize) {
    throw fail("expected \"tile_size\": " + std::to_string(HMap::kTileSize));
  }
  Params params;
  std::size_t known_keys = 2;
  for (const ParamRef& r : param_refs(params)) {
    const auto it = json.find(r.name);
    // Parameters added after a file was written keep their defaults there.
    if (it == json.end() && is_later_parameter(r.name)) continue;
    if (it == json.end()) throw fail("parameter \"" + r.name + "\" is missing");
    if (!it->is_number()) throw fail("parameter \"" + r.name + "\" is not a number");
    const double value = it->get<double>();
    try {
      r.set(value);
    } catch (const Error& e) {  // an integer parameter out of its type's range
      throw fail(e.what());
    }
    // Integer and enum parameters round on set: a value they cannot hold does not read back.
    if (!std::isfinite(value) || r.get() != value) {
      throw fail("parameter \"" + r.name + "\" = " + it->dump() + " is not a value it can take");
    }
    ++known_keys;
  }
  if (json.size() != known_keys) {
    for (const auto& item : json.items()) {
      const std::string& key = item.key();  // a plain name: clang 14 cannot capture a structured binding
      if (key == "format" || key == "tile_size") continue;
      Params scratch;
      const auto refs = param_refs(scratch);
      if (std::none_of(refs.begin(), refs.end(), [&](const ParamRef& r) { return r.name == key; })) {
        throw fail("unknown key \"" + key + "\"");
      }
    }
  }
  try {
    return HMap(params);  // validates every parameter
  } catch (const Error& e) {
    throw fail(e.what());
  }
}

struct ZstdDCtxFree {
  void operator()(ZSTD_DCtx* d) const { ZSTD_freeDCtx(d); }
};

/// The decompressed payload as a stream of bytes, decoded a block at a time: memory follows the
/// bytes actually decoded, never the size the header declares, and decoding more than declared
/// is an error.
class PayloadReader {
 public:
  PayloadReader(const std::string& name, std::span<const unsigned char> compressed,
                std::uint64_t size, std::uint64_t file_offset)
      : name_(name),
        size_(size),
        file_offset_(file_offset),
        dctx_(ZSTD_createDCtx()),
        in_{compressed.data(), compressed.size(), 0},
        buffer_(ZSTD_DStreamOutSize()) {
    if (!dctx_) throw Error("zstd: cannot create a decompression context");
    const std::size_t set = ZSTD_DCtx_setParameter(dctx_.get(), ZSTD_d_windowLogMax, kZstdWindowLogMax);
    if (ZSTD_isError(set)) throw Error(std::string("zstd: ") + ZSTD_getErrorName(set));
    const unsigned long long content = ZSTD_getFrameContentSize(compressed.data(), compressed.size());
    if (content == ZSTD_CONTENTSIZE_ERROR) throw file_error(0, "expected a zstd frame");
    if (content != ZSTD_CONTENTSIZE_UNKNOWN && content != size_) {
      throw file_error(0, "the zstd frame holds " + std::to_string(content) +
                              " bytes but the header declares " + std::to_string(size_));
    }
  }

  [[nodiscard]] std::uint64_t size() const { return size_; }
  [[nodiscard]] std::uint64_t position() const { return consumed_; }
  [[nodiscard]] std::uint64_t remaining() const { return size_ - consumed_; }

  [[nodiscard]] InputError error(std::uint64_t payload_offset, const std::string& problem) const {
    return InputError(name_, "payload byte " + std::to_string(payload_offset), problem);
  }

  unsigned char byte() {
    if (begin_ == end_ && !refill()) throw ends_early();
    ++consumed_;
    return buffer_[begin_++];
  }

  void read(unsigned char* out, std::size_t n) {
    while (n > 0) {
      if (begin_ == end_ && !refill()) throw ends_early();
      const std::size_t k = std::min(n, end_ - begin_);
      std::memcpy(out, buffer_.data() + begin_, k);
      begin_ += k;
      out += k;
      n -= k;
      consumed_ += k;
    }
  }

  std::uint32_t u32() {
    std::array<unsigned char, 4> b{};
    read(b.data(), b.size());
    return get_u32(b.data());
  }
  std::uint64_t u64() {
    std::array<unsigned char, 8> b{};
    read(b.data(), b.size());
    return get_u64(b.data());
  }
  float f32() { return std::bit_cast<float>(u32()); }
  double f64() { return std::bit_cast<double>(u64()); }

  /// Unsigned LEB128 in its shortest form.
  std::uint64_t varint() {
    const std::uint64_t at = consumed_;
    std::uint64_t value = 0;
    for (int shift = 0;; shift += 7) {
      const unsigned char b = byte();
      if (shift == 63 && b > 1) throw error(at, "varint overflows 64 bits");
      value |= static_cast<std::uint64_t>(b & 0x7FU) << shift;
      if ((b & 0x80U) == 0) {
        if (b == 0 && shift > 0) throw error(at, "varint is not in its shortest form");
        return value;
      }
    }
  }

  /// Requires the frame to end exactly where the parser stopped and the declared size.
  void finish() {
    if (begin_ != end_ || refill()) throw error(consumed_, "unexpected bytes after the last tile");
    if (consumed_ != size_) {
      throw error(consumed_, "the payload ends here but the header declares " +
                                 std::to_string(size_) + " bytes");
    }
  }

 private:
  [[nodiscard]] InputError file_error(std::uint64_t compressed_offset, const std::string& problem) const {
    return InputError(name_, byte_at(file_offset_ + compressed_offset), "compressed payload: " + problem);
  }

  [[nodiscard]] InputError ends_early() const {
    return error(consumed_, "the payload ends early (the header declares " +
                                std::to_string(size_) + " bytes)");
  }

  /// Decodes the next block into buffer_; false at the end of the frame.
  bool refill() {
    while (!frame_done_) {
      ZSTD_outBuffer out{buffer_.data(), buffer_.size(), 0};
      const std::size_t in_before = in_.pos;
      const std::size_t status = ZSTD_decompressStream(dctx_.get(), &out, &in_);
      if (ZSTD_isError(status)) {
        throw file_error(in_before, std::string("zstd: ") + ZSTD_getErrorName(status));
      }
      produced_ += out.pos;
      if (produced_ > size_) {
        throw error(size_, "the payload is longer than the " + std::to_string(size_) +
                               " bytes the header declares");
      }
      if (status == 0) {
        frame_done_ = true;
        if (in_.pos != in_.size) throw file_error(in_.pos, "unexpected bytes after the zstd frame");
      } else if (out.pos == 0 && in_.pos == in_before) {
        throw file_error(in_.pos, "the zstd frame is truncated");
      }
      if (out.pos > 0) {
        begin_ = 0;
        end_ = out.pos;
        return true;
      }
    }
    return false;
  }

  const std::string& name_;
  std::uint64_t size_;
  std::uint64_t file_offset_;
  std::unique_ptr<ZSTD_DCtx, ZstdDCtxFree> dctx_;
  ZSTD_inBuffer in_;
  std::vector<unsigned char> buffer_;
  std::size_t begin_ = 0;
  std::size_t end_ = 0;
  std::uint64_t produced_ = 0;
  std::uint64_t consumed_ = 0;
  bool frame_done_ = false;
};

void check_hvoxel(const PayloadReader& in, std::uint64_t at, const CellKey& key, const HVoxel& v,
                  const HVoxel* below) {
  const std::string what = "HVoxel of " + cell_name(key);
  if (!std::isfinite(v.z_min) || !std::isfinite(v.z_max) || !std::isfinite(v.count) ||
      !std::isfinite(v.density)) {
    throw in.error(at, what + ": expected finite numbers");
  }
  if (!(v.z_min <= v.z_max)) throw in.error(at, what + ": expected z_min <= z_max");
  if (!(v.count >= 0.0F && v.density >= 0.0F)) {
    throw in.error(at, what + ": expected a count and a density >= 0");
  }
  if (below != nullptr && !(below->z_max < v.z_min)) {
    throw in.error(at, what + ": expected HVoxels sorted by height and disjoint");
  }
}

void read_tiles(PayloadReader& in, HMap& map) {
  const std::uint64_t tile_count = in.u64();
  if (tile_count > (in.size() - 8) / kMinTileBytes) {
    throw in.error(0, "tile count " + std::to_string(tile_count) + " cannot fit in a payload of " +
                          std::to_string(in.size()) + " bytes");
  }
  std::optional<CellKey> previous;
  for (std::uint64_t t = 0; t < tile_count; ++t) {
    const std::uint64_t tile_at = in.position();
    const CellKey tile{static_cast<std::int32_t>(in.u32()), static_cast<std::int32_t>(in.u32())};
    const std::string tile_name =
        "tile (" + std::to_string(tile.i) + ", " + std::to_string(tile.j) + ")";
    if (tile.i < -kTileKeyLimit || tile.i >= kTileKeyLimit || tile.j < -kTileKeyLimit ||
        tile.j >= kTileKeyLimit) {
      throw in.error(tile_at, tile_name + ": expected tile keys in [-2^26, 2^26)");
    }
    if (previous) {
      if (*previous == tile) throw in.error(tile_at, tile_name + " appears twice");
      if (previous->i > tile.i || (previous->i == tile.i && previous->j > tile.j)) {
        throw in.error(tile_at, tile_name + ": expected tiles in increasing key order");
      }
    }
    previous = tile;

    bool any = false;
    std::uint64_t tile_hvoxels = 0;
    for (int local = 0; local < HMap::kTileCells; ++local) {
      const CellKey key = HMap::key_in_tile(tile, local);
      const std::uint64_t cell_at = in.position();
      const std::uint64_t n = in.varint();
      if (n > in.remaining() / kHVoxelBytes) {
        throw in.error(cell_at, cell_name(key) + " claims " + std::to_string(n) +
                                    " HVoxels but only " + std::to_string(in.remaining()) +
                                    " payload bytes remain");
      }
      if (n == 0) continue;
      any = true;
      tile_hvoxels += n;
      if (tile_hvoxels > HMap::Tile::kMaxHVoxels) {
        throw in.error(cell_at, tile_name + " holds more than " + std::to_string(HMap::Tile::kMaxHVoxels) +
                                    " HVoxels, the most a tile of the map can hold");
      }
      TileColumn column = map.column_for_update(key);
      for (std::uint64_t k = 0; k < n; ++k) {
        const std::uint64_t at = in.position();
        const HVoxel v{in.f32(), in.f32(), in.f32(), in.f32()};  // braces: read left to right
        check_hvoxel(in, at, key, v, column.empty() ? nullptr : &column[column.size() - 1]);
        column.push_back(v);
      }
    }
    if (!any) throw in.error(tile_at, tile_name + " holds no HVoxel (empty tiles are not stored)");
  }
}

std::vector<GroundPatch> read_ground(PayloadReader& in) {
  const std::uint64_t at = in.position();
  const std::uint64_t count = in.u64();
  if (count > in.remaining() / kPatchBytes) {
    throw in.error(at, "ground patch count " + std::to_string(count) + " cannot fit in the " +
                           std::to_string(in.remaining()) + " payload bytes that remain");
  }
  std::vector<GroundPatch> patches;
  patches.reserve(static_cast<std::size_t>(count));
  for (std::uint64_t k = 0; k < count; ++k) {
    const std::uint64_t patch_at = in.position();
    const std::string what = "ground patch " + std::to_string(k);
    GroundPatch p{};
    for (int c = 0; c < 3; ++c) p.center[c] = std::bit_cast<double>(in.u64());
    for (int c = 0; c < 3; ++c) p.normal[c] = std::bit_cast<double>(in.u64());
    p.half_size = std::bit_cast<double>(in.u64());
    p.parent = static_cast<std::int32_t>(in.u32());
    if (!p.center.allFinite() || !p.normal.allFinite() || !std::isfinite(p.half_size)) {
      throw in.error(patch_at, what + ": expected finite numbers");
    }
    if (std::abs(p.normal.norm() - 1.0) > 1e-6 || !(p.normal.z() > 0.0)) {
      throw in.error(patch_at, what + ": expected a unit normal pointing up");
    }
    if (!(p.half_size > 0.0)) throw in.error(patch_at, what + ": expected a half size > 0");
    if (p.parent < -1 || p.parent >= static_cast<std::int32_t>(k)) {
      throw in.error(patch_at, what + ": expected parent -1 or the index of an earlier patch");
    }
    patches.push_back(p);
  }
  return patches;
}

std::optional<OccupancyGrid> read_grid(PayloadReader& in, const Params& params) {
  const std::uint64_t at = in.position();
  const std::uint64_t count = in.u64();
  if (count > in.remaining() / kGridTileBytes) {
    throw in.error(at, "occupancy tile count " + std::to_string(count) + " cannot fit in the " +
                           std::to_string(in.remaining()) + " payload bytes that remain");
  }
  if (count == 0) return std::nullopt;
  OccupancyGrid grid(params.map.cell_size, params.occupancy.clamp_min, params.occupancy.clamp_max);
  // Saved values were clamped with these bounds as float32: allow their rounding only.
  const float lo = grid.clamp_min_log_odds() - 1e-4F;
  const float hi = grid.clamp_max_log_odds() + 1e-4F;
  std::optional<CellKey> previous;
  for (std::uint64_t t = 0; t < count; ++t) {
    const std::uint64_t tile_at = in.position();
    const CellKey tile{static_cast<std::int32_t>(in.u32()), static_cast<std::int32_t>(in.u32())};
    const std::string tile_name = "occupancy tile (" + std::to_string(tile.i) + ", " + std::to_string(tile.j) + ")";
    if (tile.i < -kGridTileKeyLimit || tile.i >= kGridTileKeyLimit || tile.j < -kGridTileKeyLimit ||
        tile.j >= kGridTileKeyLimit) {
      throw in.error(tile_at, tile_name + ": expected tile keys in [-2^27, 2^27)");
    }
    if (previous && (previous->i > tile.i || (previous->i == tile.i && previous->j >= tile.j))) {
      throw in.error(tile_at, tile_name + ": expected tiles in increasing key order, each once");
    }
    previous = tile;
    bool any = false;
    for (int local = 0; local < OccupancyGrid::kTileCells; ++local) {
      const std::uint64_t cell_at = in.position();
      const float l = in.f32();
      if (std::isnan(l)) continue;
      if (!(l >= lo && l <= hi)) {
        throw in.error(cell_at, tile_name + ": expected log-odds within the clamping bounds [" +
                                    std::to_string(lo) + ", " + std::to_string(hi) + "] or NaN");
      }
      any = true;
      grid.set({tile.i * OccupancyGrid::kTileSize + (local >> OccupancyGrid::kTileBits),
                tile.j * OccupancyGrid::kTileSize + (local & (OccupancyGrid::kTileSize - 1))},
               l);
    }
    if (!any) throw in.error(tile_at, tile_name + " holds no known cell (such tiles are not stored)");
  }
  return grid;
}

CellCentroids read_centroids(PayloadReader& in, const HMap& map) {
  const double cell_size = map.cell_size();
  const std::uint64_t at = in.position();
  const std::uint64_t count = in.u64();
  if (count > in.remaining() / kCentroidBytes) {
    throw in.error(at, "cell centroid count " + std::to_string(count) + " cannot fit in the " +
                           std::to_string(in.remaining()) + " payload bytes that remain");
  }
  CellCentroids centroids(cell_size);
  // Saved offsets are float32 means of points within their cell: allow their rounding only.
  const double half = 0.5 * cell_size * (1.0 + 1e-5);
  std::optional<CellKey> previous;
  for (std::uint64_t k = 0; k < count; ++k) {
    const std::uint64_t cell_at = in.position();
    const CellKey cell{static_cast<std::int32_t>(in.u32()), static_cast<std::int32_t>(in.u32())};
    const std::string cell_name = "cell centroid (" + std::to_string(cell.i) + ", " + std::to_string(cell.j) + ")";
    if (cell.i < -kCellKeyLimit || cell.i >= kCellKeyLimit || cell.j < -kCellKeyLimit || cell.j >= kCellKeyLimit) {
      throw in.error(cell_at, cell_name + ": expected cell keys in [-2^30, 2^30)");
    }
    if (previous && (previous->i > cell.i || (previous->i == cell.i && previous->j >= cell.j))) {
      throw in.error(cell_at, cell_name + ": expected cells in increasing key order, each once");
    }
    previous = cell;
    // In a tile the map holds: the centroids' tiles are then bounded by the map's own.
    if (map.find_tile(HMap::tile_of(cell)) == nullptr) {
      throw in.error(cell_at, cell_name + ": expected a cell in a tile the map holds");
    }
    const float ox = in.f32();
    const float oy = in.f32();
    const double weight = in.f64();
    if (!std::isfinite(ox) || !std::isfinite(oy) || std::abs(ox) > half || std::abs(oy) > half) {
      throw in.error(cell_at + 8, cell_name + ": expected an offset within half a cell of its centre");
    }
    if (!(weight > 0.0) || !std::isfinite(weight)) {
      throw in.error(cell_at + 16, cell_name + ": expected a positive, finite weight");
    }
    const float limit = static_cast<float>(0.5 * cell_size);  // restore()'s bound; the rounding allowed above
    centroids.restore(cell, {std::clamp(ox, -limit, limit), std::clamp(oy, -limit, limit)}, weight);
  }
  return centroids;
}

}  // namespace

void save_hmap(const std::filesystem::path& path, const HMap& map) { save_hmap(path, map, {}, nullptr); }

void save_hmap(const std::filesystem::path& path, const HMap& map, std::span<const GroundPatch> ground,
               const OccupancyGrid* grid) {
  save_hmap(path, map, ground, grid, nullptr);
}

void save_hmap(const std::filesystem::path& path, const HMap& map, std::span<const GroundPatch> ground,
               const OccupancyGrid* grid, const CellCentroids* centroids) {
  if (grid != nullptr && grid->cell_size() != map.cell_size()) {
    throw Error("cannot save " + path.string() + ": the occupancy grid's cell size differs from the map's");
  }
  if (centroids != nullptr && centroids->cell_size() != map.cell_size()) {
    throw Error("cannot save " + path.string() + ": the cell centroids' cell size differs from the map's");
  }
  for (std::size_t k = 0; k < ground.size(); ++k) {
    if (ground[k].parent < -1 || ground[k].parent >= static_cast<int>(k)) {
      throw Error("cannot save " + path.string() + ": ground patch " + std::to_string(k) +
                  " has a parent that is not an earlier patch");
    }
  }
  // Everything happens inside the writer: on any error the old file stays and no temporary is
  // left, and hmap::Error messages get the path.
  write_file_atomic(path, [&map, ground, grid, centroids](std::ostream& out) {
    const std::vector<TileRef> tiles = sorted_nonempty_tiles(map);
    const std::string sections = hybrid_sections(ground, sorted_grid_tiles(grid)) + centroid_section(centroids, tiles);
    std::uint64_t payload_size = 8 + sections.size();
    for (const auto& [key, tile] : tiles) payload_size += tile_bytes(*tile);
    if (payload_size > kMaxPayloadBytes) {
      throw Error("the map takes " + std::to_string(payload_size) +
                  " payload bytes, more than the 32 GiB a .hmap file may hold");
    }

    PayloadCompressor compressor(payload_size);
    std::string chunk;
    std::uint64_t written = 0;
    put_u64(chunk, tiles.size());
    for (const auto& [key, tile] : tiles) {
      append_tile(chunk, key, *tile);
      if (chunk.size() >= (std::size_t{1} << 16)) {
        compressor.add(chunk);
        written += chunk.size();
        chunk.clear();
      }
    }
    compressor.add(chunk);
    written += chunk.size();
    compressor.add(sections);
    written += sections.size();
    if (written != payload_size) throw Error("internal error: payload size miscounted");
    const std::string compressed = compressor.finish();

    const std::string json = params_json(map.params());
    std::string head(kMagic.begin(), kMagic.end());
    put_u32(head, kVersion);
    put_u32(head, 0);  // flags
    put_u64(head, json.size());
    head += json;
    put_u64(head, payload_size);
    put_u64(head, compressed.size());

    const std::unique_ptr<XXH64_state_t, Xxh64StateFree> state(XXH64_createState());
    if (!state || XXH64_reset(state.get(), 0) != XXH_OK ||
        XXH64_update(state.get(), head.data(), head.size()) != XXH_OK ||
        XXH64_update(state.get(), compressed.data(), compressed.size()) != XXH_OK) {
      throw Error("xxhash: cannot compute the checksum");
    }
    std::string trailer;
    put_u64(trailer, XXH64_digest(state.get()));

    out.write(head.data(), static_cast<std::streamsize>(head.size()));
    out.write(compressed.data(), static_cast<std::streamsize>(compressed.size()));
    out.write(trailer.data(), static_cast<std::streamsize>(trailer.size()));
  });
}

HMap load_hmap(const std::filesystem::path& path) { return std::move(load_map_file(path).map); }

MapFile load_map_file(const std::filesystem::path& path) {
  const std::string name = path.string();
  const std::vector<unsigned char> file = read_whole_file(path);
  const std::span<const unsigned char> bytes(file);

  // Header: every length is checked against the real file size before it is used.
  if (bytes.size() < kMinFileBytes) {
    throw InputError(name, "header", "the file has " + std::to_string(bytes.size()) +
                                         " bytes; a .hmap file has at least " +
                                         std::to_string(kMinFileBytes));
  }
  if (!std::equal(kMagic.begin(), kMagic.end(), bytes.begin())) {
    throw InputError(name, byte_at(0), "not a .hmap file: expected the magic bytes 89 48 4D 41 50 0D 0A 1A");
  }
  const std::uint32_t version = get_u32(&bytes[8]);
  if (version < kOldestVersion || version > kVersion) {
    throw InputError(name, byte_at(8), "unsupported format version " + std::to_string(version) +
                                           " (this reader knows versions " + std::to_string(kOldestVersion) +
                                           " to " + std::to_string(kVersion) + ")");
  }
  const std::uint32_t flags = get_u32(&bytes[12]);
  if (flags != 0) {
    throw InputError(name, byte_at(12), "unknown flags " + std::to_string(flags) + "; expected 0");
  }
  const std::uint64_t json_size = get_u64(&bytes[16]);
  if (json_size > bytes.size() - kMinFileBytes) {
    throw InputError(name, byte_at(16), "params JSON of " + std::to_string(json_size) +
                                            " bytes does not fit in a file of " +
                                            std::to_string(bytes.size()) + " bytes");
  }
  const std::size_t sizes_at = kJsonOffset + static_cast<std::size_t>(json_size);
  const std::uint64_t payload_size = get_u64(&bytes[sizes_at]);
  const std::uint64_t compressed_size = get_u64(&bytes[sizes_at + 8]);
  const std::size_t payload_at = sizes_at + 16;
  const std::size_t checksum_at = bytes.size() - kChecksumBytes;
  if (compressed_size != checksum_at - payload_at) {
    throw InputError(name, byte_at(sizes_at + 8),
                     "compressed payload of " + std::to_string(compressed_size) +
                         " bytes, but the file holds " + std::to_string(checksum_at - payload_at) +
                         " bytes between header and checksum (truncated or extended file?)");
  }

  // The checksum covers everything before it: nothing below runs on damaged bytes.
  const std::uint64_t stored = get_u64(&bytes[checksum_at]);
  const std::uint64_t computed = XXH64(bytes.data(), checksum_at, 0);
  if (stored != computed) {
    throw InputError(name, byte_at(checksum_at), "checksum mismatch: the file is damaged");
  }

  HMap map = map_from_params(name, bytes.subspan(kJsonOffset, static_cast<std::size_t>(json_size)));

  // The declared size bounds the parse; it is never allocated (PayloadReader decodes in blocks).
  if (payload_size < 8 || payload_size > kMaxPayloadBytes) {
    throw InputError(name, byte_at(sizes_at),
                     "uncompressed payload size " + std::to_string(payload_size) +
                         ": expected 8 bytes to 32 GiB");
  }
  PayloadReader payload(name, bytes.subspan(payload_at, static_cast<std::size_t>(compressed_size)),
                        payload_size, payload_at);
  read_tiles(payload, map);
  MapFile result{std::move(map), {}, std::nullopt, std::nullopt};
  if (version >= 2) {
    result.ground = read_ground(payload);
    result.grid = read_grid(payload, result.map.params());
  }
  if (version >= 3) result.centroids = read_centroids(payload, result.map);
  payload.finish();
  return result;
}

}  // namespace hmap
