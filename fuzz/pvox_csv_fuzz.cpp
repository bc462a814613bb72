// Fuzzes the voxel CSV parser hmap::pvox::parse_voxels_csv (src/hmap/pvox/serialize.hpp).
#include <string_view>

#include "fuzz_target.hpp"
#include "hmap/pvox/serialize.hpp"

HMAP_FUZZ_ENTRY(const std::uint8_t* data, std::size_t size) {
  try {
    const auto records =
        hmap::pvox::parse_voxels_csv(std::string_view(reinterpret_cast<const char*>(data), size), "fuzz.csv");
    (void)records.size();
  } catch (const hmap::InputError& e) {
    hmap::fuzz::check_message(e);
  }
  return 0;
}
