#include "hmap/pvox/serialize.hpp"

#include <xxhash.h>
#include <zstd.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>

#include "hmap/core/error.hpp"
#include "hmap/core/format.hpp"

namespace hmap::pvox {

namespace {

constexpr std::uint8_t kMagic[8] = {0x89, 'P', 'V', 'O', 'X', '\r', '\n', 0x1a};
constexpr std::uint32_t kVersion = 1;
constexpr std::size_t kHeader = 80;

void put_u64(std::vector<std::uint8_t>& out, std::uint64_t v) {
  for (int b = 0; b < 8; ++b) out.push_back(static_cast<std::uint8_t>(v >> (8 * b)));
}
void put_u32(std::vector<std::uint8_t>& out, std::uint32_t v) {
  for (int b = 0; b < 4; ++b) out.push_back(static_cast<std::uint8_t>(v >> (8 * b)));
}
void put_f64(std::vector<std::uint8_t>& out, double v) {
  std::uint64_t bits = 0;
  std::memcpy(&bits, &v, sizeof bits);
  put_u64(out, bits);
}
std::uint64_t get_u64(std::span<const std::uint8_t> b, std::size_t at) {
  std::uint64_t v = 0;
  for (int k = 0; k < 8; ++k) v |= std::uint64_t{b[at + static_cast<std::size_t>(k)]} << (8 * k);
  return v;
}
std::uint32_t get_u32(std::span<const std::uint8_t> b, std::size_t at) {
  std::uint32_t v = 0;
  for (int k = 0; k < 4; ++k) v |= std::uint32_t{b[at + static_cast<std::size_t>(k)]} << (8 * k);
  return v;
}
double get_f64(std::span<const std::uint8_t> b, std::size_t at) {
  const std::uint64_t bits = get_u64(b, at);
  double v = 0.0;
  std::memcpy(&v, &bits, sizeof v);
  return v;
}
void put_varint(std::vector<std::uint8_t>& out, std::uint64_t v) {
  while (v >= 0x80) {
    out.push_back(static_cast<std::uint8_t>(v | 0x80));
    v >>= 7;
  }
  out.push_back(static_cast<std::uint8_t>(v));
}
std::uint64_t zigzag(std::int64_t v) { return (static_cast<std::uint64_t>(v) << 1) ^ static_cast<std::uint64_t>(v >> 63); }
std::int64_t unzigzag(std::uint64_t v) { return static_cast<std::int64_t>(v >> 1) ^ -static_cast<std::int64_t>(v & 1); }

std::string at_byte(std::size_t offset) { return "byte " + std::to_string(offset); }

/// Reads the payload; every read is bounds-checked.
class PayloadReader {
 public:
  PayloadReader(std::span<const std::uint8_t> bytes, const std::string& source) : b_(bytes), source_(source) {}
  std::uint64_t varint() {
    std::uint64_t v = 0;
    for (int shift = 0; shift < 64; shift += 7) {
      const std::uint8_t byte = u8();
      v |= std::uint64_t{byte & 0x7FU} << shift;
      if ((byte & 0x80U) == 0) return v;
    }
    fail("a LEB128 number longer than 64 bits");
  }
  std::uint8_t u8() {
    if (at_ >= b_.size()) fail("the voxel records end early");
    return b_[at_++];
  }
  [[nodiscard]] bool done() const { return at_ == b_.size(); }
  [[noreturn]] void fail(const std::string& problem) const {
    throw InputError(source_, "payload byte " + std::to_string(at_), problem);
  }

 private:
  std::span<const std::uint8_t> b_;
  const std::string& source_;
  std::size_t at_ = 0;
};

}  // namespace

std::string points_csv(const PointCloud& points) {
  std::string out = "x,y,z\n";
  out.reserve(points.size() * 26 + 8);
  for (const Point3f& p : points) {
    out += format("%.4f,%.4f,%.4f\n", static_cast<double>(p.x()), static_cast<double>(p.y()), static_cast<double>(p.z()));
  }
  return out;
}

std::string voxels_csv(const VoxelMap& map) {
  auto voxels = map.voxels();
  std::erase_if(voxels, [](const VoxelView& v) { return v.hits == 0; });  // free space is in the binary only
  std::string out = "x,y,z,edge,probability\n";
  out.reserve(voxels.size() * 40 + 32);
  for (const VoxelView& v : voxels) {
    out += format("%.5f,%.5f,%.5f,%.6f,%.5f\n", v.centre.x(), v.centre.y(), v.centre.z(), map.edge(), v.probability);
  }
  return out;
}

std::vector<VoxelRecord> parse_voxels_csv(std::string_view text, const std::string& source) {
  std::vector<VoxelRecord> out;
  std::size_t line_no = 0;
  std::size_t pos = 0;
  bool header_seen = false;
  while (pos < text.size()) {
    const std::size_t end = std::min(text.find('\n', pos), text.size());
    std::string_view line = text.substr(pos, end - pos);
    pos = end + 1;
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    if (line.empty()) continue;
    if (!header_seen) {
      if (line != "x,y,z,edge,probability") {
        throw InputError(source, "line " + std::to_string(line_no), "expected the header 'x,y,z,edge,probability'");
      }
      header_seen = true;
      continue;
    }
    double v[5];
    const char* p = line.data();
    const char* const last = line.data() + line.size();
    for (int k = 0; k < 5; ++k) {
      const auto [next, ec] = std::from_chars(p, last, v[k]);
      if (ec != std::errc() || !std::isfinite(v[k]) || (k < 4 ? next == last || *next != ',' : next != last)) {
        throw InputError(source, "line " + std::to_string(line_no), "expected 5 comma-separated numbers x,y,z,edge,probability");
      }
      p = next + 1;
    }
    if (!(v[3] > 0.0) || !(v[4] > 0.0 && v[4] < 1.0)) {
      throw InputError(source, "line " + std::to_string(line_no), "edge must be positive and probability in (0, 1)");
    }
    out.push_back({Eigen::Vector3d(v[0], v[1], v[2]), v[3], v[4]});
  }
  if (!header_seen) throw InputError(source, "line 1", "expected the header 'x,y,z,edge,probability'");
  return out;
}

std::vector<std::uint8_t> encode_binary(const VoxelMap& map) {
  const auto voxels = map.voxels();
  std::vector<std::uint8_t> payload;
  payload.reserve(voxels.size() * 9);
  VoxelKey previous;
  const double e = map.edge();
  for (const VoxelView& v : voxels) {
    put_varint(payload, zigzag(std::int64_t{v.key.i} - previous.i));
    put_varint(payload, zigzag(std::int64_t{v.key.j} - previous.j));
    put_varint(payload, zigzag(std::int64_t{v.key.k} - previous.k));
    previous = v.key;
    put_varint(payload, v.hits);
    put_varint(payload, v.misses);
    const VoxelMoments m = VoxelMap::moments(*map.find(v.key), v.centre);
    for (int a = 0; a < 3; ++a) {
      const double q = std::round((m.mean[a] - v.centre[a]) / e * 255.0 + 127.5);
      payload.push_back(static_cast<std::uint8_t>(std::clamp(q, 0.0, 255.0)));
    }
  }
  std::vector<std::uint8_t> compressed(ZSTD_compressBound(payload.size()));
  const std::size_t c = ZSTD_compress(compressed.data(), compressed.size(), payload.data(), payload.size(), 12);
  if (ZSTD_isError(c) != 0U) throw Error(std::string("pvox: zstd compression failed: ") + ZSTD_getErrorName(c));

  std::vector<std::uint8_t> out(kMagic, kMagic + 8);
  put_u32(out, kVersion);
  put_u32(out, 0);
  put_f64(out, e);
  put_f64(out, map.model().measurement_variance);
  put_f64(out, map.model().logit_min);
  put_f64(out, map.model().logit_max);
  put_f64(out, map.model().miss_logit);
  put_u64(out, voxels.size());
  put_u64(out, payload.size());
  put_u64(out, c);
  out.insert(out.end(), compressed.begin(), compressed.begin() + static_cast<std::ptrdiff_t>(c));
  put_u64(out, XXH64(out.data(), out.size(), 0));
  return out;
}

VoxelMap decode_binary(std::span<const std::uint8_t> b, const std::string& source, const MemoryBudget& budget) {
  if (b.size() < kHeader + 8) {
    throw InputError(source, at_byte(b.size()), "truncated: a PVOX file has at least " + std::to_string(kHeader + 8) + " bytes");
  }
  if (!std::equal(kMagic, kMagic + 8, b.begin())) throw InputError(source, at_byte(0), "not a PVOX file (wrong magic)");
  if (const std::uint32_t v = get_u32(b, 8); v != kVersion) {
    throw InputError(source, at_byte(8), "unsupported PVOX version " + std::to_string(v) + " (this reader knows 1)");
  }
  if (get_u32(b, 12) != 0) throw InputError(source, at_byte(12), "unknown flags");
  const std::uint64_t c = get_u64(b, 72);
  if (c > b.size() - kHeader - 8 || kHeader + 8 + c != b.size()) {
    throw InputError(source, at_byte(72), "the compressed size " + std::to_string(c) + " does not match the file size " +
                                              std::to_string(b.size()) + " (truncated or trailing bytes)");
  }
  const std::size_t body = kHeader + static_cast<std::size_t>(c);
  if (XXH64(b.data(), body, 0) != get_u64(b, body)) {
    throw InputError(source, at_byte(body), "checksum mismatch: the file is corrupt");
  }
  ProbabilityModel model;
  const double edge = get_f64(b, 16);
  model.measurement_variance = get_f64(b, 24);
  model.logit_min = get_f64(b, 32);
  model.logit_max = get_f64(b, 40);
  model.miss_logit = get_f64(b, 48);
  if (!(edge > 0.0) || !std::isfinite(edge)) throw InputError(source, at_byte(16), "the edge must be positive");
  try {
    model.validate();
  } catch (const Error& e) {
    throw InputError(source, at_byte(24), e.what());
  }
  const std::uint64_t n = get_u64(b, 56);
  const std::uint64_t u = get_u64(b, 64);
  if (u > 256 * c + 4096 || u > (std::uint64_t{1} << 31)) {
    throw InputError(source, at_byte(64), "implausible uncompressed size " + std::to_string(u));
  }
  if (n > u / 8) throw InputError(source, at_byte(56), "voxel count " + std::to_string(n) + " does not fit the payload");
  budget.require(static_cast<double>(u), source + ": the PVOX payload");
  std::vector<std::uint8_t> payload(static_cast<std::size_t>(u));
  const std::size_t got = ZSTD_decompress(payload.data(), payload.size(), b.data() + kHeader, static_cast<std::size_t>(c));
  if (ZSTD_isError(got) != 0U || got != u) {
    throw InputError(source, at_byte(kHeader), "the payload does not decompress to " + std::to_string(u) + " bytes");
  }
  VoxelMap map(edge, model);
  map.set_budget(budget);  // the voxels come as the file claims them: each new block is checked
  PayloadReader in(payload, source);
  std::int64_t key[3] = {0, 0, 0};
  VoxelKey previous;
  for (std::uint64_t r = 0; r < n; ++r) {
    for (auto& k : key) {
      // |k| < 2^31: a delta beyond ±2^33 leaves the 32-bit range anyway, and adding it could
      // overflow 64 bits (found by fuzzing: fuzz/regressions/pvox_binary/).
      const std::int64_t delta = unzigzag(in.varint());
      if (delta < -(std::int64_t{1} << 33) || delta > (std::int64_t{1} << 33)) {
        in.fail("a voxel key outside the 32-bit range");
      }
      k += delta;
      if (k < INT32_MIN || k > INT32_MAX) in.fail("a voxel key outside the 32-bit range");
    }
    const VoxelKey vk{static_cast<std::int32_t>(key[0]), static_cast<std::int32_t>(key[1]), static_cast<std::int32_t>(key[2])};
    if (r > 0 && !(previous < vk)) in.fail("voxel keys not in increasing order");
    previous = vk;
    const std::uint64_t hits = in.varint();
    const std::uint64_t misses = in.varint();
    if (hits > UINT32_MAX || misses > UINT32_MAX || (hits == 0 && misses == 0)) in.fail("invalid voxel counts");
    Eigen::Vector3d mean = map.centre(vk);
    for (int a = 0; a < 3; ++a) mean[a] += (in.u8() - 127.5) / 255.0 * edge;
    try {
      map.set_voxel(vk, static_cast<std::uint32_t>(hits), static_cast<std::uint32_t>(misses), mean);
    } catch (const InputError&) {
      throw;
    } catch (const Error& e) {  // the memory budget
      throw InputError(source, "voxel " + std::to_string(r) + " of " + std::to_string(n), e.what());
    }
  }
  if (!in.done()) in.fail("trailing bytes after the last voxel record");
  return map;
}

}  // namespace hmap::pvox
