#pragma once
// Parameter files: YAML, either flat dotted names or nested by section.
//
//   map:                         # or, flat:  map.cell_size: 0.1
//     cell_size: 0.1
//     max_range: 30
//   ground: {iterations: 400}
//   preset: indoor               # optional: start from a preset, then apply the rest

#include <filesystem>
#include <optional>
#include <span>
#include <utility>
#include <string>
#include <string_view>
#include <vector>

#include "hmap/core/params.hpp"
#include "hmap/core/sensor_profile.hpp"
#include "hmap/core/types.hpp"

namespace hmap {

/// Applies the parameters of a YAML file on top of `params` (a `preset:` key first resets them
/// to that preset). Throws InputError naming the file, the line and the key for an unknown key,
/// a value that is not a number, or YAML syntax errors; the result is validated.
void apply_config_file(const std::filesystem::path& path, Params& params);

/// Sets the parameter called `name` ("map.cell_size") to `value`, rounding integer fields; throws
/// hmap::Error naming the parameter when the name is unknown or the value is not finite. Ranges
/// are left to validate(), as rules between parameters need them all set.
void set_param(Params& params, std::string_view name, double value);
/// The value of the parameter called `name`; throws hmap::Error for an unknown name.
[[nodiscard]] double get_param(const Params& params, std::string_view name);

/// Applies one "name=value" override (as given on the command line); throws hmap::Error naming
/// the parameter when the name is unknown or the value is not a number.
void apply_override(std::string_view assignment, Params& params);

/// Where the parameters of a run come from, applied in this order: the preset, the YAML file,
/// the `name=value` overrides, then the named values (the CLI's --cell, --min-range, --max-range),
/// then `values` (the CLI's --imu-rpy).
struct ParamSources {
  /// Empty: none named; resolve_params_for_scan then chooses it from the first scan (resolve_params
  /// refuses it).
  std::string preset = "outdoor";
  std::filesystem::path config;         ///< empty: none
  std::vector<std::string> overrides;   ///< "name=value"
  std::optional<double> cell_size;      ///< map.cell_size [m]
  std::optional<double> min_range;      ///< map.min_range [m]
  std::optional<double> max_range;      ///< map.max_range [m]
  std::vector<std::pair<std::string, double>> values;  ///< (name, value), set last, exactly
};

/// The parameters of `sources`, validated: hmap::Error naming the parameter, its value and its
/// range (or the file and line) for anything out of place.
[[nodiscard]] Params resolve_params(const ParamSources& sources);

/// The parameters of a run over scans and what its first scan chose of them.
struct ScanParams {
  Params params;
  std::string preset;                  ///< the preset they start from
  std::string preset_reason;           ///< why the first scan chose it; empty when `sources` named it
  std::vector<ChosenDefault> adapted;  ///< the parameters adapt_to_sensor changed
};

/// The parameters `hmap map` and `hmap slam` run with: the preset of `sources`, or when none is
/// named (empty) the one that fits the first scan's sensor (preset_for_sensor); then the file,
/// the overrides and the named values (resolve_params); then the parameters still at that preset's
/// value adapted to the sensor (adapt_to_sensor), validated. One function, so that the CLI and the
/// Python package choose the same.
[[nodiscard]] ScanParams resolve_params_for_scan(const ParamSources& sources, std::span<const Point3f> first_scan);

/// Writes every parameter as flat YAML, `name: value  # [unit] description; range [lo, hi]` per
/// line; applying it to any Params gives these values back exactly.
[[nodiscard]] std::string params_to_yaml(const Params& params);

}  // namespace hmap
