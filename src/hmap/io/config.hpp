#pragma once
// Parameter files: YAML, either flat dotted names or nested by section.
//
//   map:                         # or, flat:  map.cell_size: 0.1
//     cell_size: 0.1
//     max_range: 30
//   ground: {iterations: 400}
//   preset: indoor               # optional: start from a preset, then apply the rest

#include <filesystem>
#include <string_view>

#include "hmap/core/params.hpp"

namespace hmap {

/// Applies the parameters of a YAML file on top of `params` (a `preset:` key first resets them
/// to that preset). Throws InputError naming the file, the line and the key for an unknown key,
/// a value that is not a number, or YAML syntax errors; the result is validated.
void apply_config_file(const std::filesystem::path& path, Params& params);

/// Applies one "name=value" override (as given on the command line); throws hmap::Error naming
/// the parameter when the name is unknown or the value is not a number.
void apply_override(std::string_view assignment, Params& params);

/// Writes every parameter as flat YAML, `name: value  # [unit] description` per line.
[[nodiscard]] std::string params_to_yaml(const Params& params);

}  // namespace hmap
