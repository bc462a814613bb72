// Fuzzes the parameter layer of the CLI, hmap::resolve_params (src/hmap/io/config.hpp): what
// `--preset`, `--config`, `--set NAME=VALUE` (repeated) and `--cell/--min-range/--max-range` give.
// The input is text, one source per line:
//
//   preset NAME            --preset NAME (the first line only; default outdoor)
//   set NAME=VALUE         --set NAME=VALUE
//   cell V | min V | max V --cell V, --min-range V, --max-range V
//   yaml                   every later line is the --config file
//
// Accepted parameters must be valid, hold up in the map (HMap's constructor), and read back
// exactly from what `hmap params` prints; a refusal is one hmap::Error of one printable line.
#include <algorithm>
#include <charconv>
#include <string>
#include <string_view>

#include "fuzz_target.hpp"
#include "hmap/core/params.hpp"
#include "hmap/io/config.hpp"
#include "hmap/maps/hmap.hpp"

namespace {

/// The number of `text` as std::from_chars reads it (flags take what CLI11 parses: a double).
double number(std::string_view text) {
  double v = 0.0;
  (void)std::from_chars(text.data(), text.data() + text.size(), v);
  return v;
}

}  // namespace

HMAP_FUZZ_ENTRY(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  hmap::ParamSources sources;
  std::size_t pos = 0;
  bool first = true;
  while (pos < text.size()) {
    const std::size_t end = std::min(text.find('\n', pos), text.size());
    const std::string_view line = text.substr(pos, end - pos);
    pos = end + 1;
    const std::size_t space = line.find(' ');
    const std::string_view word = line.substr(0, space);
    const std::string_view rest = space == std::string_view::npos ? std::string_view() : line.substr(space + 1);
    if (first && word == "preset") sources.preset = std::string(rest);
    first = false;
    if (word == "set") sources.overrides.emplace_back(rest);
    if (word == "cell") sources.cell_size = number(rest);
    if (word == "min") sources.min_range = number(rest);
    if (word == "max") sources.max_range = number(rest);
    if (word == "yaml") {
      const std::string_view yaml = pos < text.size() ? text.substr(pos) : std::string_view();
      sources.config = hmap::fuzz::input_file().write(reinterpret_cast<const std::uint8_t*>(yaml.data()), yaml.size());
      break;
    }
    if (sources.overrides.size() > 64) break;  // more adds nothing but time
  }
  hmap::Params params;
  try {
    params = hmap::resolve_params(sources);
  } catch (const hmap::Error& e) {
    hmap::fuzz::check_message(e);
    return 0;
  }
  try {
    hmap::validate(params);
    const hmap::HMap map(params);
    // What `hmap params` prints reads back to the same values, bit for bit.
    const std::string yaml = hmap::params_to_yaml(params);
    hmap::fuzz::InputFile printed;
    hmap::Params back = hmap::indoor_preset();  // every value is printed: any start will do
    hmap::apply_config_file(printed.write(reinterpret_cast<const std::uint8_t*>(yaml.data()), yaml.size()), back);
    hmap::Params copy = params;
    const auto a = hmap::param_refs(copy);
    const auto b = hmap::param_refs(back);
    for (std::size_t k = 0; k < a.size(); ++k) {
      if (a[k].get() != b[k].get()) hmap::fuzz::fail("a parameter does not read back from params_to_yaml: " + a[k].name);
    }
  } catch (const hmap::Error& e) {
    hmap::fuzz::fail(std::string("accepted parameters then refused: ") + e.what());
  }
  return 0;
}
