#include "hmap/io/hmap_file.hpp"

#include <gtest/gtest.h>
#include <sys/resource.h>

#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <functional>
#include <unistd.h>
#include <iterator>
#include <limits>
#include <nlohmann/json.hpp>
#include <random>
#include <tuple>
#include <string>
#include <vector>

#define XXH_INLINE_ALL  // the test computes checksums itself, independently of hmap::io
#include <xxhash.h>

#include "common/test_data.hpp"
#include "hmap/core/error.hpp"
#include "hmap/maps/mapper.hpp"

namespace hmap {
namespace {

// ---- files and bytes ----

std::string read_bytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void write_bytes(const std::filesystem::path& path, const std::string& bytes) {
  // A new file rather than a truncated one: ext4 flushes files truncated and rewritten in place
  // (auto_da_alloc), which would make the byte-flip loops crawl.
  std::filesystem::remove(path);
  std::ofstream out(path, std::ios::binary);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

void put_u32(std::string& out, std::uint32_t v) {
  for (int k = 0; k < 4; ++k) out.push_back(static_cast<char>((v >> (8 * k)) & 0xFFU));
}
void put_u64(std::string& out, std::uint64_t v) {
  for (int k = 0; k < 8; ++k) out.push_back(static_cast<char>((v >> (8 * k)) & 0xFFU));
}
void put_i32(std::string& out, std::int32_t v) { put_u32(out, static_cast<std::uint32_t>(v)); }
void put_f32(std::string& out, float v) { put_u32(out, std::bit_cast<std::uint32_t>(v)); }
void put_varint(std::string& out, std::uint64_t v) {
  for (; v >= 0x80; v >>= 7) out.push_back(static_cast<char>((v & 0x7FU) | 0x80U));
  out.push_back(static_cast<char>(v));
}
std::uint64_t get_u64(const std::string& s, std::size_t at) {
  std::uint64_t v = 0;
  for (int k = 7; k >= 0; --k) v = (v << 8) | static_cast<unsigned char>(s[at + k]);
  return v;
}
std::uint32_t get_u32(const std::string& s, std::size_t at) {
  std::uint32_t v = 0;
  for (int k = 3; k >= 0; --k) v = (v << 8) | static_cast<unsigned char>(s[at + k]);
  return v;
}

const std::string kMagic("\x89HMAP\r\n\x1a", 8);

/// A zstd frame of raw (stored) blocks, written by hand from RFC 8878 so the tests can craft
/// payloads without hmap's writer. With `with_size` the frame header states the content size.
std::string raw_zstd_frame(const std::string& content, bool with_size) {
  std::string f;
  put_u32(f, 0xFD2FB528U);
  if (with_size) {
    f.push_back(static_cast<char>(0xE0));  // 8-byte content size, single segment
    put_u64(f, content.size());
  } else {
    f.push_back(static_cast<char>(0x00));  // no content size, window descriptor follows
    f.push_back(static_cast<char>(0x50));  // window 2^20 bytes
  }
  constexpr std::size_t kMaxBlock = 100000;
  std::size_t at = 0;
  do {
    const std::size_t n = std::min(kMaxBlock, content.size() - at);
    const bool last = at + n == content.size();
    const auto header = static_cast<std::uint32_t>((n << 3) | (last ? 1U : 0U));  // type 0: raw
    for (int k = 0; k < 3; ++k) f.push_back(static_cast<char>((header >> (8 * k)) & 0xFFU));
    f.append(content, at, n);
    at += n;
  } while (at < content.size());
  return f;
}

struct FileParts {
  std::string magic = kMagic;
  std::uint32_t version = 1;
  std::uint32_t flags = 0;
  std::string json;
  std::uint64_t payload_size = 0;
  std::string compressed;
};

/// A complete file from its parts, with a correct checksum: what it exercises is the check
/// after the checksum.
std::string assemble(const FileParts& p) {
  std::string f = p.magic;
  put_u32(f, p.version);
  put_u32(f, p.flags);
  put_u64(f, p.json.size());
  f += p.json;
  put_u64(f, p.payload_size);
  put_u64(f, p.compressed.size());
  f += p.compressed;
  put_u64(f, XXH64(f.data(), f.size(), 0));
  return f;
}

/// Payload builder: a tile is its key and, per local cell index, its HVoxels.
struct TileSpec {
  std::int32_t i;
  std::int32_t j;
  std::vector<std::pair<int, std::vector<HVoxel>>> cells;  // (local index, HVoxels)
};

std::string payload_of(const std::vector<TileSpec>& tiles) {
  std::string p;
  put_u64(p, tiles.size());
  for (const TileSpec& t : tiles) {
    put_i32(p, t.i);
    put_i32(p, t.j);
    for (int local = 0; local < HMap::kTileCells; ++local) {
      const std::vector<HVoxel>* hv = nullptr;
      for (const auto& [index, list] : t.cells) {
        if (index == local) hv = &list;
      }
      put_varint(p, hv ? hv->size() : 0);
      if (hv == nullptr) continue;
      for (const HVoxel& v : *hv) {
        put_f32(p, v.z_min);
        put_f32(p, v.z_max);
        put_f32(p, v.count);
        put_f32(p, v.density);
      }
    }
  }
  return p;
}

/// The params JSON the writer produces for `params`, as parsed JSON.
nlohmann::ordered_json params_json(const Params& params) {
  Params copy = params;
  nlohmann::ordered_json j;
  j["format"] = "hmap";
  j["tile_size"] = HMap::kTileSize;
  for (const ParamRef& r : param_refs(copy)) j[r.name] = r.get();
  return j;
}

FileParts parts_with_payload(const std::string& payload) {
  FileParts p;
  p.json = params_json(Params{}).dump();
  p.payload_size = payload.size();
  p.compressed = raw_zstd_frame(payload, true);
  return p;
}

const std::vector<TileSpec> kValidTiles = {
    {-1, 0, {{0, {{0.0F, 0.5F, 10.0F, 0.9F}, {1.0F, 1.0F, 1.0F, 0.1F}}}, {HMap::kTileCells - 1, {{-2.0F, -1.0F, 3.0F, 0.5F}}}}},
    {0, -3, {{17, {{5.0F, 6.0F, 7.0F, 0.25F}}}}},
};

// ---- maps ----

Params test_params() {
  Params p = indoor_preset();
  p.map.cell_size = 0.1;
  p.map.min_range = 0.1;
  p.map.max_range = 20.0;
  p.map.min_hvoxel_height = 0.1;
  p.ground.seed = 12345;
  p.slam.interpolation_window = 5;
  return p;
}

/// A room around the origin with a table (two HVoxels per column under it), seen from
/// `sensor`; points in the sensor frame.
PointCloud room_scan(const Eigen::Vector3d& sensor, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  PointCloud pts;
  const auto add = [&](double x, double y, double z) {
    pts.emplace_back((Eigen::Vector3d(x, y, z) - sensor).cast<float>());
  };
  for (int k = 0; k < 4000; ++k) add(-4.0 + 8.0 * u(rng), -4.0 + 8.0 * u(rng), 0.0);  // floor
  for (int k = 0; k < 2000; ++k) add(4.0, -4.0 + 8.0 * u(rng), 2.5 * u(rng));         // walls
  for (int k = 0; k < 2000; ++k) add(-4.0 + 8.0 * u(rng), -4.0, 2.5 * u(rng));
  for (int k = 0; k < 1500; ++k) add(1.0 + u(rng), 1.0 + u(rng), 0.8 + 0.05 * u(rng));  // table top
  return pts;
}

HMap mapped_room() {
  Mapper mapper(test_params());
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector3d sensor(-0.5 + 0.3 * k, -1.0 + 0.2 * k, 1.2);
    Pose T_map_sensor = Pose::Identity();
    T_map_sensor.translation() = sensor;
    mapper.integrate(room_scan(sensor, 7 + static_cast<std::uint32_t>(k)), T_map_sensor);
  }
  return std::move(mapper.map());
}

/// A map of hand-placed columns: negative keys, keys at the ±2^30 limit, several HVoxels.
HMap handmade_map() {
  HMap map(test_params());
  const auto put = [&map](CellKey key, std::vector<HVoxel> hvoxels) {
    TileColumn c = map.column_for_update(key);
    for (const HVoxel& v : hvoxels) c.push_back(v);
  };
  put({0, 0}, {{0.0F, 0.2F, 12.0F, 0.7F}});
  put({-1, -1}, {{-3.5F, -3.0F, 4.0F, 0.3F}, {-1.0F, -1.0F, 1.0F, 0.01F}, {2.0F, 7.25F, 300.0F, 1.0F}});
  put({-17, 5}, {{1e-7F, 2e-7F, 0.5F, 0.0F}, {1.0F, 2.0F, 0.0F, 0.0F}});
  put({15, -16}, {{-0.0F, 0.0F, 1.0F, 0.5F}});
  put({-(1 << 30) + 1, (1 << 30) - 1}, {{100.0F, 101.0F, 2.0F, 0.2F}});
  put({(1 << 30) - 1, -(1 << 30) + 1}, {{-100.0F, -99.0F, 2.0F, 0.2F}});
  std::vector<HVoxel> tall;
  for (int k = 0; k < 40; ++k) tall.push_back({static_cast<float>(k), static_cast<float>(k) + 0.5F, 3.0F, 0.4F});
  put({3, 3}, tall);
  (void)map.column_for_update({1000, 1000});  // an allocated tile without HVoxels: not stored
  return map;
}

bool same_bits(const HVoxel& a, const HVoxel& b) { return std::memcmp(&a, &b, sizeof(HVoxel)) == 0; }

void expect_same_params(const Params& a, const Params& b) {
  Params ca = a;
  Params cb = b;
  const auto ra = param_refs(ca);
  const auto rb = param_refs(cb);
  ASSERT_EQ(ra.size(), rb.size());
  for (std::size_t k = 0; k < ra.size(); ++k) EXPECT_EQ(ra[k].get(), rb[k].get()) << ra[k].name;
}

void expect_same_map(const HMap& expected, const HMap& actual) {
  expect_same_params(expected.params(), actual.params());
  std::size_t columns = 0;
  expected.for_each_column([&](const CellKey& key, const ColumnView& c) {
    ++columns;
    const ColumnView other = actual.column(key);
    ASSERT_EQ(other.size(), c.size()) << key.i << ", " << key.j;
    for (std::size_t k = 0; k < c.size(); ++k) {
      EXPECT_TRUE(same_bits(c[k], other[k])) << key.i << ", " << key.j << " #" << k;
    }
  });
  std::size_t actual_columns = 0;
  actual.for_each_column([&](const CellKey&, const ColumnView& c) {
    ++actual_columns;
    EXPECT_TRUE(c.is_valid());
  });
  EXPECT_EQ(actual_columns, columns);
  const MapStats se = expected.stats();
  const MapStats sa = actual.stats();
  EXPECT_EQ(sa.cells, se.cells);
  EXPECT_EQ(sa.hvoxels, se.hvoxels);
  EXPECT_EQ(sa.bounds.isEmpty(), se.bounds.isEmpty());
  if (!se.bounds.isEmpty()) {
    EXPECT_EQ(sa.bounds.min(), se.bounds.min());
    EXPECT_EQ(sa.bounds.max(), se.bounds.max());
  }
  std::size_t nonempty_tiles = 0;  // the file stores no empty tile
  expected.for_each_tile([&](const CellKey&, const HMap::Tile& t) {
    nonempty_tiles += t.empty() ? 0 : 1;
  });
  EXPECT_EQ(sa.tiles, nonempty_tiles);
}

/// Loads `bytes` written to `path`; fails the test unless hmap::InputError names the file.
::testing::AssertionResult rejected(const std::filesystem::path& path, const std::string& bytes,
                                    const std::string& expected_text = "") {
  write_bytes(path, bytes);
  try {
    (void)load_hmap(path);
  } catch (const InputError& e) {
    if (e.source() != path.string()) {
      return ::testing::AssertionFailure() << "source is " << e.source();
    }
    if (std::string(e.what()).find(expected_text) == std::string::npos) {
      return ::testing::AssertionFailure() << "message lacks '" << expected_text << "': " << e.what();
    }
    return ::testing::AssertionSuccess() << e.what();
  } catch (const std::exception& e) {
    return ::testing::AssertionFailure() << "not an InputError: " << e.what();
  }
  return ::testing::AssertionFailure() << "accepted";
}

class HMapFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = test::temp_dir(std::string("hmap_file_") +
                          ::testing::UnitTest::GetInstance()->current_test_info()->name());
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  std::filesystem::path dir_;
};

// ---- round trips ----

TEST_F(HMapFileTest, MappedRoomRoundTripsExactly) {
  const HMap map = mapped_room();
  ASSERT_GT(map.stats().hvoxels, 1000U);
  bool several = false;
  map.for_each_column([&](const CellKey&, const ColumnView& c) { several = several || c.size() > 1; });
  EXPECT_TRUE(several) << "the table gives columns of two HVoxels";
  save_hmap(dir_ / "room.hmap", map);
  const HMap loaded = load_hmap(dir_ / "room.hmap");
  expect_same_map(map, loaded);
  EXPECT_EQ(loaded.params().ground.seed, 12345U);
  EXPECT_EQ(loaded.params().slam.interpolation_window, 5);
  EXPECT_EQ(loaded.params().map.cell_size, 0.1);
}

TEST_F(HMapFileTest, NegativeKeysAndTallColumnsRoundTrip) {
  const HMap map = handmade_map();
  save_hmap(dir_ / "hand.hmap", map);
  const HMap loaded = load_hmap(dir_ / "hand.hmap");
  expect_same_map(map, loaded);
  EXPECT_EQ(loaded.column({3, 3}).size(), 40U);
  EXPECT_TRUE(std::signbit(loaded.column({15, -16}).hvoxels()[0].z_min)) << "-0 kept bit for bit";
  EXPECT_EQ(loaded.find_tile(HMap::tile_of({1000, 1000})), nullptr) << "the empty tile is not stored";
  EXPECT_NE(map.find_tile(HMap::tile_of({1000, 1000})), nullptr) << "(it exists in the saved map)";
}

TEST_F(HMapFileTest, EmptyMapRoundTrips) {
  Params p = outdoor_preset();
  p.map.free_space = FreeSpaceMode::kNone;
  HMap map(p);
  save_hmap(dir_ / "empty.hmap", map);
  const HMap loaded = load_hmap(dir_ / "empty.hmap");
  EXPECT_TRUE(loaded.empty());
  EXPECT_EQ(loaded.stats().tiles, 0U);
  EXPECT_EQ(loaded.params().map.free_space, FreeSpaceMode::kNone);
  expect_same_map(map, loaded);
}

TEST_F(HMapFileTest, LayoutIsAsDocumented) {
  const HMap map = handmade_map();
  save_hmap(dir_ / "m.hmap", map);
  const std::string f = read_bytes(dir_ / "m.hmap");
  ASSERT_GE(f.size(), 48U);
  EXPECT_EQ(f.substr(0, 8), kMagic);
  EXPECT_EQ(get_u32(f, 8), 3U);
  EXPECT_EQ(get_u32(f, 12), 0U);
  const std::uint64_t json_size = get_u64(f, 16);
  const auto json = nlohmann::json::parse(f.substr(24, json_size));
  EXPECT_EQ(json.at("format"), "hmap");
  EXPECT_EQ(json.at("tile_size"), HMap::kTileSize);
  EXPECT_EQ(json.at("map.cell_size").get<double>(), 0.1);
  EXPECT_EQ(json.at("ground.seed").get<double>(), 12345.0);
  Params p;
  EXPECT_EQ(json.size(), param_refs(p).size() + 2);
  const std::uint64_t payload_size = get_u64(f, 24 + json_size);
  const std::uint64_t compressed_size = get_u64(f, 32 + json_size);
  EXPECT_EQ(f.size(), 48 + json_size + compressed_size);
  EXPECT_EQ(get_u64(f, f.size() - 8), XXH64(f.data(), f.size() - 8, 0));
  // Payload size: 8 + per stored tile (8 + one varint count per cell) + 16 per HVoxel, + the three
  // empty counts of the ground, grid and centroid sections.
  std::uint64_t expected = 8 + 24;
  map.for_each_tile([&](const CellKey&, const HMap::Tile& tile) {
    std::uint64_t tile_bytes = 8;
    bool stored = false;
    for (int local = 0; local < HMap::kTileCells; ++local) {
      const ColumnView c = tile.column(local);
      tile_bytes += (c.size() < 128 ? 1 : 2) + 16 * c.size();
      stored = stored || !c.empty();
    }
    if (stored) expected += tile_bytes;
  });
  EXPECT_EQ(payload_size, expected);
}

TEST_F(HMapFileTest, HandCraftedFileLoads) {
  // The crafting helpers below write valid files: the rejection tests change one thing at a time.
  write_bytes(dir_ / "c.hmap", assemble(parts_with_payload(payload_of(kValidTiles))));
  const HMap map = load_hmap(dir_ / "c.hmap");
  EXPECT_EQ(map.stats().hvoxels, 4U);
  EXPECT_EQ(map.stats().tiles, 2U);
  const ColumnView c = map.column(HMap::key_in_tile({-1, 0}, 0));
  ASSERT_EQ(c.size(), 2U);
  EXPECT_EQ(c[1], (HVoxel{1.0F, 1.0F, 1.0F, 0.1F}));
  EXPECT_EQ(map.column(HMap::key_in_tile({-1, 0}, HMap::kTileCells - 1)).hvoxels()[0].z_min, -2.0F);
  EXPECT_EQ(map.column(HMap::key_in_tile({0, -3}, 17)).hvoxels()[0].z_max, 6.0F);

  // A frame without a content size, several blocks, also loads.
  FileParts p = parts_with_payload(payload_of(kValidTiles));
  TileSpec tall{0, 0, {{5, {}}}};
  for (int k = 0; k < 20000; ++k) {
    const auto z = static_cast<float>(2 * k);
    tall.cells[0].second.push_back({z, z + 1.0F, 1.0F, 0.5F});
  }
  const std::string big = payload_of({tall});
  p.payload_size = big.size();
  p.compressed = raw_zstd_frame(big, false);
  write_bytes(dir_ / "d.hmap", assemble(p));
  EXPECT_EQ(load_hmap(dir_ / "d.hmap").column({0, 5}).size(), 20000U);

  // Two columns of 40000 in one tile: past the 65,535 of 16-bit offsets, the tile widens them
  // (no wrap-around), and the map saves back to the same bytes.
  TileSpec crowded{0, 0, {{5, tall.cells[0].second}, {6, tall.cells[0].second}}};
  for (auto& cell : crowded.cells) cell.second.resize(40000, cell.second.back());
  for (std::size_t column = 0; column < 2; ++column) {
    for (int k = 20000; k < 40000; ++k) {
      const auto z = static_cast<float>(2 * k);
      crowded.cells[column].second[static_cast<std::size_t>(k)] = {z, z + 1.0F, 1.0F, 0.5F};
    }
  }
  const std::string crowded_payload = payload_of({crowded});
  p.payload_size = crowded_payload.size();
  p.compressed = raw_zstd_frame(crowded_payload, false);
  write_bytes(dir_ / "e.hmap", assemble(p));
  const HMap crowded_map = load_hmap(dir_ / "e.hmap");
  ASSERT_EQ(crowded_map.column(HMap::key_in_tile({0, 0}, 5)).size(), 40000U);
  ASSERT_EQ(crowded_map.column(HMap::key_in_tile({0, 0}, 6)).size(), 40000U);
  EXPECT_EQ(crowded_map.column(HMap::key_in_tile({0, 0}, 6))[39999].z_min, 79998.0F);
  save_hmap(dir_ / "e2.hmap", crowded_map);
  expect_same_map(crowded_map, load_hmap(dir_ / "e2.hmap"));
}

// A uniform map compresses far beyond 64:1, so the reader bounds memory by decoding in blocks
// rather than by rejecting high compression ratios: files like this one must load.
TEST_F(HMapFileTest, HighlyCompressibleMapRoundTrips) {
  HMap map(test_params());
  for (std::int32_t i = 0; i < 320; ++i) {
    for (std::int32_t j = 0; j < 320; ++j) {
      map.column_for_update({i, j}).push_back({0.0F, 0.5F, 10.0F, 0.9F});
    }
  }
  save_hmap(dir_ / "flat.hmap", map);
  const std::string f = read_bytes(dir_ / "flat.hmap");
  const std::uint64_t json_size = get_u64(f, 16);
  const std::uint64_t payload_size = get_u64(f, 24 + json_size);
  const std::uint64_t compressed_size = get_u64(f, 32 + json_size);
  EXPECT_GT(payload_size, 64 * compressed_size + (std::uint64_t{1} << 20));
  expect_same_map(map, load_hmap(dir_ / "flat.hmap"));
}

TEST_F(HMapFileTest, SavingTwiceGivesIdenticalBytes) {
  const HMap map = mapped_room();
  save_hmap(dir_ / "a.hmap", map);
  save_hmap(dir_ / "b.hmap", map);
  EXPECT_EQ(read_bytes(dir_ / "a.hmap"), read_bytes(dir_ / "b.hmap"));

  // The same columns inserted in another order (another hash table layout): the same bytes.
  HMap copy(map.params());
  std::vector<std::pair<CellKey, ColumnView>> columns;
  map.for_each_column([&](const CellKey& k, const ColumnView& c) { columns.emplace_back(k, c); });
  std::reverse(columns.begin(), columns.end());
  for (const auto& [key, c] : columns) {
    TileColumn into = copy.column_for_update(key);
    for (const HVoxel& v : c) into.push_back(v);
  }
  save_hmap(dir_ / "c.hmap", copy);
  EXPECT_EQ(read_bytes(dir_ / "a.hmap"), read_bytes(dir_ / "c.hmap"));
}

TEST_F(HMapFileTest, SavingReplacesAtomically) {
  const auto path = dir_ / "map.hmap";
  save_hmap(path, mapped_room());
  const HMap second = handmade_map();
  save_hmap(path, second);
  expect_same_map(second, load_hmap(path));
  std::vector<std::string> names;
  for (const auto& entry : std::filesystem::directory_iterator(dir_)) {
    names.push_back(entry.path().filename().string());
  }
  EXPECT_EQ(names, std::vector<std::string>{"map.hmap"}) << "no temporary file is left";
  EXPECT_THROW(save_hmap(dir_ / "missing" / "m.hmap", second), Error);
}

// ---- rejections ----

TEST_F(HMapFileTest, EverySingleByteFlipIsRejected) {
  HMap map(test_params());
  map.column_for_update({-2, 3}).push_back({0.0F, 1.0F, 5.0F, 0.5F});
  map.column_for_update({40, -1}).push_back({-1.0F, -0.5F, 2.0F, 0.25F});
  save_hmap(dir_ / "small.hmap", map);
  const std::string good = read_bytes(dir_ / "small.hmap");
  ASSERT_LT(good.size(), 2800U);  // the parameters are in the header: ~8100 loads, each byte flipped three ways
  for (std::size_t at = 0; at < good.size(); ++at) {
    for (const unsigned char mask : std::array<unsigned char, 3>{0x01, 0x80, 0xFF}) {
      std::string bad = good;
      bad[at] = static_cast<char>(bad[at] ^ mask);
      ASSERT_TRUE(rejected(dir_ / "bad.hmap", bad)) << "byte " << at << " ^ " << int{mask};
    }
  }
}

TEST_F(HMapFileTest, SampledByteFlipsOfALargeFileAreRejected) {
  save_hmap(dir_ / "room.hmap", mapped_room());
  const std::string good = read_bytes(dir_ / "room.hmap");
  ASSERT_GT(good.size(), 10000U);
  const std::size_t stride = good.size() / 300 + 1;
  for (std::size_t at = 0; at < good.size(); at += stride) {
    std::string bad = good;
    bad[at] = static_cast<char>(bad[at] ^ 0x10);
    ASSERT_TRUE(rejected(dir_ / "bad.hmap", bad)) << "byte " << at;
  }
  std::string last = good;
  last.back() = static_cast<char>(last.back() ^ 0x01);
  EXPECT_TRUE(rejected(dir_ / "bad.hmap", last, "checksum"));
}

TEST_F(HMapFileTest, EveryTruncationIsRejected) {
  HMap map(test_params());
  map.column_for_update({7, 7}).push_back({0.0F, 1.0F, 5.0F, 0.5F});
  save_hmap(dir_ / "small.hmap", map);
  const std::string good = read_bytes(dir_ / "small.hmap");
  for (std::size_t n = 0; n < good.size(); ++n) {
    ASSERT_TRUE(rejected(dir_ / "cut.hmap", good.substr(0, n))) << n << " bytes";
  }
  EXPECT_TRUE(rejected(dir_ / "cut.hmap", good.substr(0, 20), "header"));
  EXPECT_TRUE(rejected(dir_ / "cut.hmap", good + '\0', "truncated or extended"));
}

TEST_F(HMapFileTest, WrongMagicVersionAndFlagsAreRejected) {
  FileParts p = parts_with_payload(payload_of(kValidTiles));
  p.magic = "HMAP\r\n\x1a\n";
  EXPECT_TRUE(rejected(dir_ / "x.hmap", assemble(p), "magic"));
  p = parts_with_payload(payload_of(kValidTiles));
  p.version = 99;
  EXPECT_TRUE(rejected(dir_ / "x.hmap", assemble(p), "version 99"));
  p = parts_with_payload(payload_of(kValidTiles));
  p.flags = 1;
  EXPECT_TRUE(rejected(dir_ / "x.hmap", assemble(p), "flags"));
  EXPECT_TRUE(rejected(dir_ / "x.hmap", std::string(100, 'x'), "magic"));
  EXPECT_TRUE(rejected(dir_ / "x.hmap", "", "header"));
}

TEST_F(HMapFileTest, MissingFileAndFolderAreRejected) {
  try {
    (void)load_hmap(dir_ / "nothing.hmap");
    ADD_FAILURE() << "accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.source(), (dir_ / "nothing.hmap").string());
  }
  EXPECT_THROW((void)load_hmap(dir_), InputError);
}

TEST_F(HMapFileTest, FileWrittenBeforeTopNoiseLoadsWithItsDefault) {
  FileParts p = parts_with_payload(payload_of(kValidTiles));
  nlohmann::ordered_json j = params_json(Params{});
  j.erase("ground.top_noise");
  p.json = j.dump();
  const auto path = dir_ / "old.hmap";
  std::ofstream(path, std::ios::binary) << assemble(p);
  EXPECT_DOUBLE_EQ(load_hmap(path).params().ground.top_noise, GroundParams{}.top_noise);
  // The same for the attitude parameters of session 5, all absent at once; an older parameter
  // absent is still an error.
  for (const char* name : {"slam.surface_max_height", "slam.attitude_gate", "slam.attitude_iterations",
                           "slam.attitude_min_surfaces", "slam.attitude_min_lever", "slam.level_prior",
                           "slam.max_floor_tilt"}) {
    j.erase(name);
  }
  p.json = j.dump();
  std::ofstream(path, std::ios::binary | std::ios::trunc) << assemble(p);
  EXPECT_DOUBLE_EQ(load_hmap(path).params().slam.level_prior, SlamParams{}.level_prior);
  // And the IMU and deskewing parameters of issue 16 (maps written before them).
  for (const char* name : {"slam.imu_gravity_time_constant", "slam.imu_accel_gate", "slam.imu_tilt_weight",
                           "slam.imu_roll", "slam.imu_pitch", "slam.imu_yaw", "slam.deskew", "slam.level_max_slope"}) {
    j.erase(name);
  }
  p.json = j.dump();
  std::ofstream(path, std::ios::binary | std::ios::trunc) << assemble(p);
  EXPECT_EQ(load_hmap(path).params().slam.deskew, SlamParams{}.deskew);
  EXPECT_DOUBLE_EQ(load_hmap(path).params().slam.imu_tilt_weight, SlamParams{}.imu_tilt_weight);
  EXPECT_DOUBLE_EQ(load_hmap(path).params().slam.level_max_slope, SlamParams{}.level_max_slope);
  // And the odometry prior's (session 8).
  for (const char* name : {"slam.odometry_sigma_translation", "slam.odometry_sigma_rotation", "slam.odometry_noise"}) {
    j.erase(name);
  }
  p.json = j.dump();
  std::ofstream(path, std::ios::binary | std::ios::trunc) << assemble(p);
  EXPECT_DOUBLE_EQ(load_hmap(path).params().slam.odometry_noise, SlamParams{}.odometry_noise);
  EXPECT_DOUBLE_EQ(load_hmap(path).params().slam.odometry_sigma_translation, SlamParams{}.odometry_sigma_translation);
  // And loop closure's (issue 22): maps saved before it were refused, `hmap slam --continue` of them too.
  for (const char* name : {"occupancy.obstacle_reach", "slam.loop_closure", "slam.keyframe_distance", "slam.keyframe_rotation",
                           "slam.loop_submap_scans", "slam.loop_min_travel", "slam.loop_search_radius",
                           "slam.loop_max_descriptor_distance", "slam.loop_candidates", "slam.loop_search_translation",
                           "slam.loop_search_rotation", "slam.loop_min_score"}) {
    j.erase(name);
  }
  p.json = j.dump();
  std::ofstream(path, std::ios::binary | std::ios::trunc) << assemble(p);
  EXPECT_EQ(load_hmap(path).params().slam.loop_closure, SlamParams{}.loop_closure);
  EXPECT_DOUBLE_EQ(load_hmap(path).params().slam.loop_min_score, SlamParams{}.loop_min_score);
  // And the scan centroids' switch (session 28).
  j.erase("slam.hvoxel_centroids");
  p.json = j.dump();
  std::ofstream(path, std::ios::binary | std::ios::trunc) << assemble(p);
  EXPECT_EQ(load_hmap(path).params().slam.hvoxel_centroids, SlamParams{}.hvoxel_centroids);
  // And the walls' (b887c0f): maps saved between it and session 29 were refused.
  for (const char* name : {"slam.wall_refine", "slam.wall_min_height", "slam.wall_band_height", "slam.wall_iterations",
                           "slam.wall_min_pairs", "slam.wall_max_rotation"}) {
    j.erase(name);
  }
  p.json = j.dump();
  std::ofstream(path, std::ios::binary | std::ios::trunc) << assemble(p);
  EXPECT_EQ(load_hmap(path).params().slam.wall_refine, SlamParams{}.wall_refine);
  EXPECT_DOUBLE_EQ(load_hmap(path).params().slam.wall_band_height, SlamParams{}.wall_band_height);
  j.erase("slam.coarse_rotation");
  p.json = j.dump();
  std::ofstream(path, std::ios::binary | std::ios::trunc) << assemble(p);
  EXPECT_THROW((void)load_hmap(path), InputError);
}

TEST_F(HMapFileTest, BadParamsAreRejected) {
  const std::string payload = payload_of(kValidTiles);
  const auto with_json = [&](const std::string& json) {
    FileParts p = parts_with_payload(payload);
    p.json = json;
    return assemble(p);
  };
  const auto edited = [](const std::function<void(nlohmann::ordered_json&)>& edit) {
    nlohmann::ordered_json j = params_json(Params{});
    edit(j);
    return j.dump();
  };
  const auto path = dir_ / "p.hmap";
  EXPECT_TRUE(rejected(path, with_json("{\"format\": \"hmap\", "), "cannot be parsed"));
  EXPECT_TRUE(rejected(path, with_json(""), "cannot be parsed"));
  EXPECT_TRUE(rejected(path, with_json("[1, 2]"), "object"));
  EXPECT_TRUE(rejected(path, with_json(edited([](auto& j) { j.erase("map.cell_size"); })),
                       "\"map.cell_size\" is missing"));
  EXPECT_TRUE(rejected(path, with_json(edited([](auto& j) { j.erase("format"); })), "format"));
  EXPECT_TRUE(rejected(path, with_json(edited([](auto& j) { j["format"] = "pcd"; })), "format"));
  EXPECT_TRUE(rejected(path, with_json(edited([](auto& j) { j["tile_size"] = 32; })), "tile_size"));
  EXPECT_TRUE(rejected(path, with_json(edited([](auto& j) { j["map.cell_size"] = -1.0; })),
                       "map.cell_size"));
  EXPECT_TRUE(rejected(path, with_json(edited([](auto& j) { j["map.cell_size"] = "0.25"; })),
                       "not a number"));
  EXPECT_TRUE(rejected(path, with_json(edited([](auto& j) { j["map.max_range"] = 1e300; })),
                       "map.max_range"));
  EXPECT_TRUE(rejected(path, with_json(edited([](auto& j) { j["ground.iterations"] = 2.5; })),
                       "ground.iterations"));
  EXPECT_TRUE(rejected(path, with_json(edited([](auto& j) { j["ground.iterations"] = 1e30; })),
                       "ground.iterations"));
  EXPECT_TRUE(rejected(path, with_json(edited([](auto& j) { j["map.free_space"] = 7; })),
                       "map.free_space"));
  EXPECT_TRUE(rejected(path, with_json(edited([](auto& j) { j["ground.seed"] = -1; })),
                       "ground.seed"));
  EXPECT_TRUE(rejected(path, with_json(edited([](auto& j) { j["map.extra"] = 1; })),
                       "unknown key \"map.extra\""));
  EXPECT_TRUE(rejected(path, with_json("{\"format\": \"hmap\", \"tile_size\": " + std::to_string(HMap::kTileSize) + ", \"map.cell_size\": 1e999}"),
                       "params JSON"));
}

TEST_F(HMapFileTest, EnormousClaimsAreRejected) {
  const std::string payload = payload_of(kValidTiles);
  const auto path = dir_ / "e.hmap";
  FileParts p = parts_with_payload(payload);
  p.payload_size = std::uint64_t{1} << 40;
  EXPECT_TRUE(rejected(path, assemble(p), "uncompressed payload size"));
  p.payload_size = std::numeric_limits<std::uint64_t>::max();
  EXPECT_TRUE(rejected(path, assemble(p), "uncompressed payload size"));
  p.payload_size = 0;
  EXPECT_TRUE(rejected(path, assemble(p), "uncompressed payload size"));

  // Below the 32 GiB cap, the frame's own content size contradicts the claim...
  p.payload_size = (std::uint64_t{16} << 30) - 1;
  EXPECT_TRUE(rejected(path, assemble(p), "header declares"));
  // ... and a frame without one simply ends early: nothing was allocated for the claim.
  p.compressed = raw_zstd_frame(payload, false);
  EXPECT_TRUE(rejected(path, assemble(p), "header declares 17179869183 bytes"));

  // A tile count the payload cannot hold.
  std::string huge_count = payload;
  for (int k = 0; k < 8; ++k) huge_count[k] = k == 5 ? '\x01' : '\0';  // 2^40 tiles
  EXPECT_TRUE(rejected(path, assemble(parts_with_payload(huge_count)), "tile count"));
  // A smaller count the declared size could hold, but the data ends.
  std::string more_tiles = payload;
  more_tiles[0] = 3;
  EXPECT_TRUE(rejected(path, assemble(parts_with_payload(more_tiles)), "tile count"));
  FileParts q = parts_with_payload(more_tiles);
  q.payload_size = std::uint64_t{16} << 30;
  q.compressed = raw_zstd_frame(more_tiles, false);
  EXPECT_TRUE(rejected(path, assemble(q), "ends early"));

  // A cell claiming more HVoxels than bytes remain.
  std::string payload_cells = payload_of({{0, 0, {{0, {{0.0F, 1.0F, 1.0F, 0.5F}}}}}});
  payload_cells[16] = static_cast<char>(0xFF);  // cell 0's count: 1 -> varint continues
  payload_cells.insert(17, "\xFF\xFF\x0F");   // ~2^28 HVoxels
  EXPECT_TRUE(rejected(path, assemble(parts_with_payload(payload_cells)), "remain"));
}

#if !HMAP_UNDER_ASAN
/// In a death-test child: exits 0 if loading `path` with the address space capped at 512 MiB
/// above the current use throws InputError, 1 for another exception (bad_alloc), 2 if it loads.
[[noreturn]] void load_with_capped_memory(const std::filesystem::path& path) {
  std::ifstream statm("/proc/self/statm");
  std::uint64_t pages = 0;
  statm >> pages;
  const std::uint64_t limit =
      pages * static_cast<std::uint64_t>(::sysconf(_SC_PAGESIZE)) + (std::uint64_t{512} << 20);
  const rlimit rl{limit, limit};
  if (::setrlimit(RLIMIT_AS, &rl) != 0) std::_Exit(3);
  try {
    (void)load_hmap(path);
  } catch (const InputError&) {
    std::_Exit(0);
  } catch (...) {
    std::_Exit(1);
  }
  std::_Exit(2);
}
#endif

// A file claiming just under 32 GiB of payload and 2^25 tiles is loaded with the address space
// capped at 512 MiB above the current use: allocating for the claim would fail with bad_alloc.
TEST_F(HMapFileTest, ClaimsAreNotAllocated) {
#if HMAP_UNDER_ASAN
  GTEST_SKIP() << "AddressSanitizer reserves terabytes of address space: no RLIMIT_AS under it";
#else
  std::string payload = payload_of(kValidTiles);
  payload[0] = 0;
  payload[3] = 2;  // 2^25 tiles
  FileParts p = parts_with_payload(payload);
  p.payload_size = (std::uint64_t{32} << 30) - 1;
  p.compressed = raw_zstd_frame(payload, false);
  const auto path = dir_ / "claims.hmap";
  write_bytes(path, assemble(p));
  EXPECT_EXIT(load_with_capped_memory(path), ::testing::ExitedWithCode(0), "");
#endif
}

TEST_F(HMapFileTest, BadPayloadsAreRejected) {
  const auto path = dir_ / "b.hmap";
  const auto file_of = [](const std::vector<TileSpec>& tiles) {
    return assemble(parts_with_payload(payload_of(tiles)));
  };
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  EXPECT_TRUE(rejected(path, file_of({{0, 0, {{1, {{nan, 1.0F, 1.0F, 0.5F}}}}}}), "finite"));
  EXPECT_TRUE(rejected(path, file_of({{0, 0, {{1, {{0.0F, inf, 1.0F, 0.5F}}}}}}), "finite"));
  EXPECT_TRUE(rejected(path, file_of({{0, 0, {{1, {{0.0F, 1.0F, nan, 0.5F}}}}}}), "finite"));
  EXPECT_TRUE(rejected(path, file_of({{0, 0, {{1, {{0.0F, 1.0F, 1.0F, -inf}}}}}}), "finite"));
  EXPECT_TRUE(rejected(path, file_of({{0, 0, {{1, {{2.0F, 1.0F, 1.0F, 0.5F}}}}}}), "z_min <= z_max"));
  EXPECT_TRUE(rejected(path, file_of({{0, 0, {{1, {{0.0F, 1.0F, -1.0F, 0.5F}}}}}}), ">= 0"));
  EXPECT_TRUE(rejected(path, file_of({{0, 0, {{1, {{2.0F, 3.0F, 1.0F, 0.5F}, {0.0F, 1.0F, 1.0F, 0.5F}}}}}}),
                       "sorted"));
  EXPECT_TRUE(rejected(path, file_of({{0, 0, {{1, {{0.0F, 1.0F, 1.0F, 0.5F}, {1.0F, 2.0F, 1.0F, 0.5F}}}}}}),
                       "disjoint"));
  const TileSpec one{0, 0, {{0, {{0.0F, 1.0F, 1.0F, 0.5F}}}}};
  EXPECT_TRUE(rejected(path, file_of({one, one}), "twice"));
  TileSpec before = one;
  before.i = -1;
  EXPECT_TRUE(rejected(path, file_of({one, before}), "increasing key order"));
  EXPECT_TRUE(rejected(path, file_of({{0, 1, {}}, {0, 2, {{0, {{0.0F, 1.0F, 1.0F, 0.5F}, {2.0F, 3.0F, 1.0F, 0.5F}}}}}}),
                       "holds no HVoxel"));
  constexpr std::int32_t kLimit = std::int32_t{1} << (30 - HMap::kTileBits);  // keys stay within ±2^30
  EXPECT_TRUE(rejected(path, file_of({{kLimit, 0, {{0, {{0.0F, 1.0F, 1.0F, 0.5F}}}}}}), "tile keys"));
  EXPECT_TRUE(rejected(path, file_of({{0, -kLimit - 1, {{0, {{0.0F, 1.0F, 1.0F, 0.5F}}}}}}), "tile keys"));
  EXPECT_TRUE(rejected(path, file_of({{std::numeric_limits<std::int32_t>::min(), 0, {{0, {{0.0F, 1.0F, 1.0F, 0.5F}}}}}}),
                       "tile keys"));
  // The extreme keys themselves are fine.
  write_bytes(path, file_of({{-kLimit, kLimit - 1, {{HMap::kTileCells - 1, {{0.0F, 1.0F, 1.0F, 0.5F}}}}}}));
  EXPECT_FALSE(load_hmap(path).column(HMap::key_in_tile({-kLimit, kLimit - 1}, HMap::kTileCells - 1)).empty());

  // Trailing bytes inside the payload, and after the zstd frame.
  const std::string valid = payload_of(kValidTiles);
  EXPECT_TRUE(rejected(path, assemble(parts_with_payload(valid + "x")), "after the last tile"));
  FileParts p = parts_with_payload(valid);
  p.compressed += raw_zstd_frame("x", true);
  EXPECT_TRUE(rejected(path, assemble(p), "after the zstd frame"));
  // A declared size that disagrees with the frame, which has no size of its own.
  p = parts_with_payload(valid);
  p.compressed = raw_zstd_frame(valid, false);
  p.payload_size = valid.size() - 1;
  EXPECT_TRUE(rejected(path, assemble(p), "longer than"));
  p.payload_size = valid.size() + 1;
  EXPECT_TRUE(rejected(path, assemble(p), "header declares"));
  // Not zstd at all, truncated zstd, a zstd frame cut in a block.
  p = parts_with_payload(valid);
  p.compressed = std::string(40, 'z');
  EXPECT_TRUE(rejected(path, assemble(p), "zstd"));
  p = parts_with_payload(valid);
  p.compressed.resize(p.compressed.size() - 5);
  EXPECT_TRUE(rejected(path, assemble(p), "truncated"));
  p.compressed.clear();
  EXPECT_TRUE(rejected(path, assemble(p), "zstd"));
  // A frame asking for a 1 GiB window (more than the reader's 8 MiB limit).
  p = parts_with_payload(valid);
  p.compressed = raw_zstd_frame(valid, false);
  p.compressed[5] = static_cast<char>(0xA0);
  EXPECT_TRUE(rejected(path, assemble(p), "zstd"));
  // A count in a longer form than needed.
  std::string overlong = payload_of({one});
  overlong[16] = static_cast<char>(0x81);
  overlong.insert(17, 1, '\0');
  EXPECT_TRUE(rejected(path, assemble(parts_with_payload(overlong)), "shortest form"));
}

}  // namespace

// ---- version 2: the ground patches and the 2D grid of the hybrid map ----

namespace {

void put_f64(std::string& out, double v) { put_u64(out, std::bit_cast<std::uint64_t>(v)); }

struct PatchSpec {
  double cx, cy, cz, nx, ny, nz, half;
  std::int32_t parent;
};

/// The version-2 sections: patches, then grid tiles given as (tile i, tile j, {local: log-odds}).
std::string sections_of(const std::vector<PatchSpec>& patches,
                        const std::vector<std::tuple<std::int32_t, std::int32_t, std::vector<std::pair<int, float>>>>& tiles) {
  std::string s;
  put_u64(s, patches.size());
  for (const PatchSpec& p : patches) {
    for (const double v : {p.cx, p.cy, p.cz, p.nx, p.ny, p.nz, p.half}) put_f64(s, v);
    put_i32(s, p.parent);
  }
  put_u64(s, tiles.size());
  for (const auto& [ti, tj, cells] : tiles) {
    put_i32(s, ti);
    put_i32(s, tj);
    for (int local = 0; local < OccupancyGrid::kTileCells; ++local) {
      float l = std::numeric_limits<float>::quiet_NaN();
      for (const auto& [index, value] : cells) {
        if (index == local) l = value;
      }
      put_f32(s, l);
    }
  }
  return s;
}

std::string v2_file(const std::string& sections) {
  FileParts p = parts_with_payload(payload_of(kValidTiles) + sections);
  p.version = 2;
  return assemble(p);
}

const std::vector<PatchSpec> kValidPatches = {{0, 0, 0, 0, 0, 1, 0.45, -1}, {0.9, 0, 0.05, 0, 0, 1, 0.45, 0}};

}  // namespace

TEST_F(HMapFileTest, HybridLayersRoundTrip) {
  const HMap map = handmade_map();
  const Params& params = map.params();
  OccupancyGrid grid(map.cell_size(), params.occupancy.clamp_min, params.occupancy.clamp_max);
  grid.update({0, 0}, 2.0F);
  grid.update({-9, 17}, -0.7F);
  grid.update({100000, -100000}, 50.0F);  // clamped to clamp_max
  const std::vector<GroundPatch> ground = {{{1.0, 2.0, -0.5}, Eigen::Vector3d(0.1, 0.0, 1.0).normalized(), 0.45, -1},
                                           {{1.9, 2.0, -0.4}, {0.0, 0.0, 1.0}, 0.45, 0}};
  save_hmap(dir_ / "h.hmap", map, ground, &grid);
  const MapFile back = load_map_file(dir_ / "h.hmap");
  EXPECT_EQ(back.map.stats().hvoxels, map.stats().hvoxels);
  ASSERT_EQ(back.ground.size(), 2U);
  EXPECT_EQ(back.ground[0].center, ground[0].center);
  EXPECT_EQ(back.ground[0].normal, ground[0].normal);
  EXPECT_EQ(back.ground[1].parent, 0);
  EXPECT_EQ(back.ground[0].parent, -1);
  ASSERT_TRUE(back.grid.has_value());
  EXPECT_EQ(back.grid->known_cells(), 3U);
  EXPECT_EQ(back.grid->log_odds_at({0, 0}), grid.log_odds_at({0, 0}));
  EXPECT_EQ(back.grid->log_odds_at({-9, 17}), grid.log_odds_at({-9, 17}));
  EXPECT_EQ(back.grid->log_odds_at({100000, -100000}), grid.clamp_max_log_odds());
  EXPECT_FALSE(back.grid->log_odds_at({1, 0}).has_value());

  // Without layers: no patches, no grid; load_hmap reads both kinds.
  save_hmap(dir_ / "plain.hmap", map);
  const MapFile plain = load_map_file(dir_ / "plain.hmap");
  EXPECT_TRUE(plain.ground.empty());
  EXPECT_FALSE(plain.grid.has_value());
  EXPECT_EQ(load_hmap(dir_ / "h.hmap").stats().hvoxels, map.stats().hvoxels);

  // A grid at another cell size or a patch pointing forward is refused before anything is written.
  OccupancyGrid coarse(2 * map.cell_size(), 0.12, 0.97);
  EXPECT_THROW(save_hmap(dir_ / "x.hmap", map, ground, &coarse), Error);
  std::vector<GroundPatch> forward = ground;
  forward[0].parent = 1;
  EXPECT_THROW(save_hmap(dir_ / "x.hmap", map, forward, nullptr), Error);
  EXPECT_FALSE(std::filesystem::exists(dir_ / "x.hmap"));
}

TEST_F(HMapFileTest, VersionOneFilesHaveNoLayers) {
  FileParts p = parts_with_payload(payload_of(kValidTiles));
  p.version = 1;
  write_bytes(dir_ / "v1.hmap", assemble(p));
  const MapFile f = load_map_file(dir_ / "v1.hmap");
  EXPECT_EQ(f.map.stats().hvoxels, 4U);
  EXPECT_TRUE(f.ground.empty());
  EXPECT_FALSE(f.grid.has_value());
  EXPECT_FALSE(f.centroids.has_value());
  // Version 4 is from the future.
  p.version = 4;
  EXPECT_TRUE(rejected(dir_ / "v4.hmap", assemble(p), "unsupported format version 4"));
}

TEST_F(HMapFileTest, HybridSectionsAreChecked) {
  const auto path = dir_ / "bad.hmap";
  // The valid crafted file loads.
  write_bytes(path, v2_file(sections_of(kValidPatches, {{0, 0, {{0, 1.0F}, {63, -1.0F}}}})));
  const MapFile ok = load_map_file(path);
  EXPECT_EQ(ok.ground.size(), 2U);
  ASSERT_TRUE(ok.grid.has_value());
  EXPECT_EQ(ok.grid->known_cells(), 2U);
  EXPECT_EQ(ok.grid->log_odds_at({7, 7}), -1.0F);
  EXPECT_FALSE(ok.centroids.has_value()) << "a version-2 file has no centroid section";

  auto patches = kValidPatches;
  patches[1].parent = 1;
  EXPECT_TRUE(rejected(path, v2_file(sections_of(patches, {})), "earlier patch"));
  patches = kValidPatches;
  patches[0].nz = 2.0;
  EXPECT_TRUE(rejected(path, v2_file(sections_of(patches, {})), "unit normal"));
  patches = kValidPatches;
  patches[0].cx = std::numeric_limits<double>::infinity();
  EXPECT_TRUE(rejected(path, v2_file(sections_of(patches, {})), "finite"));
  patches = kValidPatches;
  patches[1].half = 0.0;
  EXPECT_TRUE(rejected(path, v2_file(sections_of(patches, {})), "half size"));
  EXPECT_TRUE(rejected(path, v2_file(sections_of(kValidPatches, {{0, 0, {{5, 30.0F}}}})), "clamping bounds"));
  EXPECT_TRUE(rejected(path, v2_file(sections_of(kValidPatches, {{0, 0, {}}})), "no known cell"));
  EXPECT_TRUE(rejected(path, v2_file(sections_of(kValidPatches, {{0, 1, {{0, 0.0F}}}, {0, 0, {{0, 0.0F}}}})),
                       "increasing key order"));
  EXPECT_TRUE(rejected(path, v2_file(sections_of(kValidPatches, {{1 << 27, 0, {{0, 0.0F}}}})), "tile keys"));
  // Absurd counts are refused from the bytes that remain, before any allocation.
  std::string huge;
  put_u64(huge, std::uint64_t{1} << 40);
  EXPECT_TRUE(rejected(path, v2_file(huge), "ground patch count"));
  std::string huge_grid;
  put_u64(huge_grid, 0);
  put_u64(huge_grid, std::uint64_t{1} << 40);
  EXPECT_TRUE(rejected(path, v2_file(huge_grid), "occupancy tile count"));
  // A version-2 file must hold both sections.
  EXPECT_TRUE(rejected(path, v2_file(""), "ends early"));
}

// ---- version 3: the SLAM's cell centroids ----

namespace {

struct CentroidSpec {
  std::int32_t i, j;
  float ox, oy;
  double weight;
};

std::string centroid_section_of(const std::vector<CentroidSpec>& cells) {
  std::string s;
  put_u64(s, cells.size());
  for (const CentroidSpec& c : cells) {
    put_i32(s, c.i);
    put_i32(s, c.j);
    put_f32(s, c.ox);
    put_f32(s, c.oy);
    put_f64(s, c.weight);
  }
  return s;
}

/// A version-3 file of the crafted tiles (the default cell, 0.25 m), no ground or grid, and `centroids`.
std::string v3_file(const std::string& centroids) {
  FileParts p = parts_with_payload(payload_of(kValidTiles) + sections_of({}, {}) + centroids);
  p.version = 3;
  return assemble(p);
}

}  // namespace

// Saved and read back, every cell's offset and weight are as they were, bit for bit, and the file
// saved again from what was read is the same file.
TEST_F(HMapFileTest, CellCentroidsRoundTripExactly) {
  const HMap map = handmade_map();
  CellCentroids centroids(map.cell_size());
  std::mt19937 rng(3);
  // Points over the map's tiles (0, 0) and (-1, -1) of 8 × 8 cells of 0.1 m.
  std::uniform_real_distribution<double> pos(-0.8, 0.8);
  for (int k = 0; k < 500; ++k) {
    const double x = pos(rng);
    centroids.add(x, std::copysign(std::abs(pos(rng)), x), 1.0 + k % 7);
  }
  centroids.restore({-(1 << 30) + 2, (1 << 30) - 3}, {0.05F, -0.05F}, 12.5);  // a half-cell offset, far out
  // In no tile the map stores (the allocated tile at (1000, 1000) holds no HVoxel): not saved.
  centroids.add(100.05, 100.05, 1.0);
  centroids.add(1000.05, 1000.05, 1.0);
  save_hmap(dir_ / "c.hmap", map, {}, nullptr, &centroids);
  const MapFile back = load_map_file(dir_ / "c.hmap");
  ASSERT_TRUE(back.centroids.has_value());
  ASSERT_EQ(back.centroids->size(), centroids.size() - 2);
  EXPECT_GT(back.centroids->size(), 60U);
  EXPECT_EQ(back.centroids->offset({1000, 1000}), nullptr);
  EXPECT_EQ(back.centroids->offset({10000, 10000}), nullptr);
  EXPECT_EQ(back.centroids->cell_size(), map.cell_size());
  std::size_t checked = 0;
  centroids.for_each([&](const CellKey& cell, const Eigen::Vector2f& offset, double weight) {
    if (cell.i >= 1000) return;  // the two left out
    const Eigen::Vector2f* got = back.centroids->offset(cell);
    ASSERT_NE(got, nullptr) << cell.i << "," << cell.j;
    EXPECT_EQ(*got, offset) << cell.i << "," << cell.j;
    back.centroids->for_each([&](const CellKey& c, const Eigen::Vector2f&, double w) {
      if (c == cell) {
        EXPECT_EQ(w, weight) << cell.i << "," << cell.j;
      }
    });
    ++checked;
  });
  EXPECT_EQ(checked, centroids.size() - 2);
  save_hmap(dir_ / "c2.hmap", back.map, {}, nullptr, &*back.centroids);
  EXPECT_EQ(read_bytes(dir_ / "c2.hmap"), read_bytes(dir_ / "c.hmap"));
  // Without centroids the section is there and empty; with another cell size, nothing is written.
  save_hmap(dir_ / "none.hmap", map);
  const MapFile none = load_map_file(dir_ / "none.hmap");
  ASSERT_TRUE(none.centroids.has_value());
  EXPECT_EQ(none.centroids->size(), 0U);
  const CellCentroids other(2.0 * map.cell_size());
  EXPECT_THROW(save_hmap(dir_ / "x.hmap", map, {}, nullptr, &other), Error);
  EXPECT_FALSE(std::filesystem::exists(dir_ / "x.hmap"));
}

TEST_F(HMapFileTest, CellCentroidSectionIsChecked) {
  const auto path = dir_ / "bad.hmap";
  // The valid crafted file loads (offsets within half a cell; cells in the tiles (-1, 0) and (0, -3)).
  write_bytes(path, v3_file(centroid_section_of({{-3, 5, 0.0F, 0.0F, 0.5}, {-3, 7, 0.01F, -0.05F, 2.0}, {4, -20, 0.049F, 0.02F, 7.0}})));
  const MapFile ok = load_map_file(path);
  ASSERT_TRUE(ok.centroids.has_value());
  EXPECT_EQ(ok.centroids->size(), 3U);
  ASSERT_NE(ok.centroids->offset({-3, 7}), nullptr);
  EXPECT_EQ(*ok.centroids->offset({-3, 7}), Eigen::Vector2f(0.01F, -0.05F));
  EXPECT_EQ(ok.centroids->offset({-3, 6}), nullptr);

  EXPECT_TRUE(rejected(path, v3_file(centroid_section_of({{4, -20, 0.0F, 0.0F, 1.0}, {-3, 7, 0.0F, 0.0F, 1.0}})),
                       "increasing key order"));
  EXPECT_TRUE(rejected(path, v3_file(centroid_section_of({{-3, 7, 0.0F, 0.0F, 1.0}, {-3, 7, 0.0F, 0.0F, 1.0}})),
                       "increasing key order"));
  EXPECT_TRUE(rejected(path, v3_file(centroid_section_of({{-3, 7, 0.2F, 0.0F, 1.0}})), "half a cell"));
  EXPECT_TRUE(rejected(path, v3_file(centroid_section_of({{-3, 7, 0.0F, std::numeric_limits<float>::quiet_NaN(), 1.0}})),
                       "half a cell"));
  EXPECT_TRUE(rejected(path, v3_file(centroid_section_of({{-3, 7, 0.0F, 0.0F, 0.0}})), "positive, finite weight"));
  EXPECT_TRUE(rejected(path, v3_file(centroid_section_of({{-3, 7, 0.0F, 0.0F, std::numeric_limits<double>::infinity()}})),
                       "positive, finite weight"));
  EXPECT_TRUE(rejected(path, v3_file(centroid_section_of({{1 << 30, 0, 0.0F, 0.0F, 1.0}})), "cell keys"));
  EXPECT_TRUE(rejected(path, v3_file(centroid_section_of({{800, 800, 0.0F, 0.0F, 1.0}})), "a tile the map holds"));
  // An absurd count is refused from the bytes that remain, before any allocation.
  std::string huge;
  put_u64(huge, std::uint64_t{1} << 40);
  EXPECT_TRUE(rejected(path, v3_file(huge), "cell centroid count"));
  // A version-3 file must hold the section.
  EXPECT_TRUE(rejected(path, v3_file(""), "ends early"));
}

}  // namespace hmap
