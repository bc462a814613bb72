// Fuzzes the PVOX binary loader hmap::pvox::decode_binary (src/hmap/pvox/serialize.hpp): any bytes
// give a voxel map or one hmap::InputError. As for .hmap files, the first input byte picks how the
// rest is used (mod 3), so that the checksum and zstd do not hide the decoder from the fuzzer:
//   0  the file as it is;
//   1  the file with its last 8 bytes replaced by the right XXH64;
//   2  bytes 16..64 of the header (edge, model, voxel count N), then the uncompressed payload,
//      wrapped by the target into a file with the right magic, sizes, zstd frame and checksum.
#include <xxhash.h>
#include <zstd.h>

#include <string>
#include <vector>

#include "fuzz_target.hpp"
#include "hmap/pvox/serialize.hpp"

namespace {

constexpr std::size_t kChecksumBytes = 8;
constexpr std::size_t kFieldBytes = 48;  // header bytes [16, 64)

void put_u64(std::vector<std::uint8_t>& out, std::uint64_t v) {
  for (int i = 0; i < 8; ++i) out.push_back(static_cast<std::uint8_t>((v >> (8 * i)) & 0xFFu));
}
void append_checksum(std::vector<std::uint8_t>& file) { put_u64(file, XXH64(file.data(), file.size(), 0)); }

std::vector<std::uint8_t> wrap(const std::uint8_t* data, std::size_t size) {
  std::vector<std::uint8_t> file = {0x89, 'P', 'V', 'O', 'X', '\r', '\n', 0x1a, 1, 0, 0, 0, 0, 0, 0, 0};
  const std::size_t fields = size < kFieldBytes ? size : kFieldBytes;
  file.insert(file.end(), data, data + fields);
  file.resize(16 + kFieldBytes, 0);
  const std::uint8_t* payload = data + fields;
  const std::size_t payload_size = size - fields;
  std::vector<std::uint8_t> compressed(ZSTD_compressBound(payload_size));
  const std::size_t c = ZSTD_compress(compressed.data(), compressed.size(), payload, payload_size, 1);
  if (ZSTD_isError(c) != 0) hmap::fuzz::fail("ZSTD_compress failed");
  put_u64(file, payload_size);
  put_u64(file, c);
  file.insert(file.end(), compressed.begin(), compressed.begin() + static_cast<std::ptrdiff_t>(c));
  append_checksum(file);
  return file;
}

}  // namespace

HMAP_FUZZ_ENTRY(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  std::vector<std::uint8_t> file;
  switch (data[0] % 3) {
    case 0:
      file.assign(data + 1, data + size);
      break;
    case 1:
      file.assign(data + 1, data + size);
      if (file.size() >= kChecksumBytes) {
        file.resize(file.size() - kChecksumBytes);
        append_checksum(file);
      }
      break;
    default:
      file = wrap(data + 1, size - 1);
      break;
  }
  try {
    const hmap::pvox::VoxelMap map = hmap::pvox::decode_binary(file, "fuzz.pvox");
    if (!(map.edge() > 0.0) || !std::isfinite(map.edge())) hmap::fuzz::fail("voxel map with an invalid edge");
  } catch (const hmap::InputError& e) {
    hmap::fuzz::check_message(e);
  }
  return 0;
}
