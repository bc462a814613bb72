// Fuzzes the .hmap loader (src/hmap/io/hmap_file.hpp): any bytes give a map with its layers or
// one hmap::InputError. A checksum and zstd guard the payload, which a fuzzer would almost never
// get through, so the first input byte picks how the rest is used (mod 3):
//   0  the file as it is;
//   1  the file with its last 8 bytes replaced by the right XXH64 (header and JSON fuzzed);
//   2  an uncompressed payload, wrapped by the target into a valid version-3 file with the default
//      parameters: zstd frame, sizes and checksum right (the payload decoder fuzzed).
#include <xxhash.h>
#include <zstd.h>

#include <unistd.h>

#include <string>
#include <vector>

#include "fuzz_target.hpp"
#include "hmap/io/hmap_file.hpp"
#include "hmap/io/read_support.hpp"

namespace {

constexpr std::size_t kChecksumBytes = 8;

void put_u32(std::string& out, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<char>((v >> (8 * i)) & 0xFFu));
}
void put_u64(std::string& out, std::uint64_t v) {
  for (int i = 0; i < 8; ++i) out.push_back(static_cast<char>((v >> (8 * i)) & 0xFFu));
}
std::uint64_t get_u64(const std::string& bytes, std::size_t at) {
  std::uint64_t v = 0;
  for (int i = 7; i >= 0; --i) v = (v << 8) | static_cast<unsigned char>(bytes[at + static_cast<std::size_t>(i)]);
  return v;
}

/// The params JSON of a map saved with the default parameters (saved once, by the library itself).
const std::string& default_params_json() {
  static const std::string json = [] {
    const auto path = std::filesystem::temp_directory_path() /
                      ("hmap_fuzz_defaults_" + std::to_string(::getpid()) + ".hmap");
    hmap::save_hmap(path, hmap::HMap(hmap::Params{}));
    const std::string bytes = hmap::detail::read_file_bytes(path);
    std::filesystem::remove(path);
    return bytes.substr(24, static_cast<std::size_t>(get_u64(bytes, 16)));
  }();
  return json;
}

void append_checksum(std::string& file) { put_u64(file, XXH64(file.data(), file.size(), 0)); }

std::string wrap_payload(std::string_view payload) {
  const std::string& json = default_params_json();
  std::string file("\x89HMAP\r\n\x1a", 8);
  put_u32(file, 3);
  put_u32(file, 0);
  put_u64(file, json.size());
  file += json;
  std::string compressed(ZSTD_compressBound(payload.size()), '\0');
  const std::size_t c = ZSTD_compress(compressed.data(), compressed.size(), payload.data(), payload.size(), 1);
  if (ZSTD_isError(c) != 0) hmap::fuzz::fail("ZSTD_compress failed");
  compressed.resize(c);
  put_u64(file, payload.size());
  put_u64(file, compressed.size());
  file += compressed;
  append_checksum(file);
  return file;
}

}  // namespace

HMAP_FUZZ_ENTRY(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const std::string_view rest(reinterpret_cast<const char*>(data) + 1, size - 1);
  std::string file;
  switch (data[0] % 3) {
    case 0:
      file = rest;
      break;
    case 1:
      file = rest;
      if (file.size() >= kChecksumBytes) {
        file.resize(file.size() - kChecksumBytes);
        append_checksum(file);
      }
      break;
    default:
      file = wrap_payload(rest);
      break;
  }
  hmap::fuzz::read_input(reinterpret_cast<const std::uint8_t*>(file.data()), file.size(),
                         [](const std::filesystem::path& path) { (void)hmap::load_map_file(path); });
  return 0;
}
