// Fuzzes the parameter file reader hmap::apply_config_file (src/hmap/io/config.hpp): a YAML file
// gives valid parameters or one hmap::Error (InputError for the file, Error from validation).
#include "fuzz_target.hpp"
#include "hmap/core/params.hpp"
#include "hmap/io/config.hpp"

HMAP_FUZZ_ENTRY(const std::uint8_t* data, std::size_t size) {
  const auto& path = hmap::fuzz::input_file().write(data, size);
  hmap::Params params;
  try {
    hmap::apply_config_file(path, params);
    hmap::validate(params);  // what was accepted must be valid
  } catch (const hmap::Error& e) {
    hmap::fuzz::check_message(e);
  }
  return 0;
}
