#include "hmap/io/config.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <map>
#include <sstream>

#include "hmap/core/error.hpp"
#include "hmap/io/read_support.hpp"

namespace hmap {

namespace {

bool parse_double(std::string_view text, double& out) {
  while (!text.empty() && text.front() == ' ') text.remove_prefix(1);
  while (!text.empty() && text.back() == ' ') text.remove_suffix(1);
  if (text.empty()) return false;
  const auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), out);
  return ec == std::errc() && ptr == text.data() + text.size() && std::isfinite(out);
}

ParamRef* find_param(std::vector<ParamRef>& refs, std::string_view name) {
  for (auto& r : refs)
    if (r.name == name) return &r;
  return nullptr;
}

std::string known_names(const std::vector<ParamRef>& refs) {
  std::string s;
  for (const auto& r : refs) s += (s.empty() ? "" : ", ") + r.name;
  return s;
}

/// Parameter names are "section.name": sections nest no deeper than this. The bound also stops
/// a recursive alias (`a: &x {b: *x}`, a map that holds itself) from recursing forever.
constexpr int kMaxNesting = 4;

/// Lines where each parameter (or section) was given, by dotted name.
using SeenNames = std::map<std::string, int>;

void apply_node(const std::filesystem::path& path, const std::string& prefix, const YAML::Node& node,
                std::vector<ParamRef>& refs, int depth, SeenNames& seen) {
  for (const auto& entry : node) {
    const std::string key = entry.first.as<std::string>();
    const std::string name = prefix.empty() ? key : prefix + "." + key;
    const int line_number = entry.first.Mark().line + 1;
    const std::string line = "line " + std::to_string(line_number);
    // yaml-cpp keeps the last of two equal keys: a silent choice between two values.
    if (const auto [it, first] = seen.emplace(name, line_number); !first) {
      throw InputError(path.string(), line, "'" + name + "' is given twice (first on line " + std::to_string(it->second) + ")");
    }
    if (entry.second.IsMap()) {
      if (depth + 1 >= kMaxNesting) {
        throw InputError(path.string(), line, "'" + name + "' nests sections too deep (parameters are 'section.name')");
      }
      apply_node(path, name, entry.second, refs, depth + 1, seen);
      continue;
    }
    if (name == "preset") continue;  // handled first
    ParamRef* ref = find_param(refs, name);
    if (ref == nullptr) {
      throw InputError(path.string(), line, "unknown parameter '" + name + "' (known: " + known_names(refs) + ")");
    }
    double value = 0.0;
    if (!entry.second.IsScalar() || !parse_double(entry.second.Scalar(), value)) {
      throw InputError(path.string(), line, "parameter '" + name + "' needs a finite number");
    }
    ref->set(value);
  }
}

}  // namespace

void apply_config_file(const std::filesystem::path& path, Params& params) {
  YAML::Node root;
  // Read like every input (regular files only, bounded; a folder gives "is a folder", not the
  // standard library's message), then parsed. A parameter file is small: 1 MiB is plenty.
  const std::string text = detail::read_file_bytes(path, std::size_t{1} << 20);
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw InputError(path.string(), "line " + std::to_string(e.mark.line + 1), "YAML syntax error: " + e.msg);
  }
  if (root.IsNull()) return;  // an empty file changes nothing
  if (!root.IsMap()) throw InputError(path.string(), "", "expected a YAML mapping of parameter names to numbers");
  try {
    if (const auto p = root["preset"]; p && p.IsScalar()) params = preset(p.Scalar());
    auto refs = param_refs(params);
    SeenNames seen;
    apply_node(path, "", root, refs, 0, seen);
  } catch (const InputError&) {
    throw;
  } catch (const YAML::Exception& e) {
    throw InputError(path.string(), "line " + std::to_string(e.mark.line + 1), e.msg);
  } catch (const Error& e) {
    throw InputError(path.string(), "", e.what());
  }
  try {
    validate(params);
  } catch (const Error& e) {
    throw InputError(path.string(), "", e.what());
  }
}

void apply_override(std::string_view assignment, Params& params) {
  const auto eq = assignment.find('=');
  if (eq == std::string_view::npos) {
    throw Error("parameter override '" + std::string(assignment) + "' must read name=value");
  }
  const std::string name(assignment.substr(0, eq));
  auto refs = param_refs(params);
  ParamRef* ref = find_param(refs, name);
  if (ref == nullptr) throw Error("unknown parameter '" + name + "' (known: " + known_names(refs) + ")");
  double value = 0.0;
  if (!parse_double(assignment.substr(eq + 1), value)) {
    throw Error("parameter '" + name + "' needs a finite number, got '" + std::string(assignment.substr(eq + 1)) + "'");
  }
  ref->set(value);
}

void set_param(Params& params, std::string_view name, double value) {
  auto refs = param_refs(params);
  ParamRef* ref = find_param(refs, name);
  if (ref == nullptr) throw Error("unknown parameter '" + std::string(name) + "' (known: " + known_names(refs) + ")");
  if (!std::isfinite(value)) {
    throw Error("parameter '" + std::string(name) + "' needs a finite number, got '" + std::to_string(value) + "'");
  }
  ref->set(value);
}

double get_param(const Params& params, std::string_view name) {
  Params copy = params;  // param_refs binds to a mutable Params
  auto refs = param_refs(copy);
  const ParamRef* ref = find_param(refs, name);
  if (ref == nullptr) throw Error("unknown parameter '" + std::string(name) + "' (known: " + known_names(refs) + ")");
  return ref->get();
}

Params resolve_params(const ParamSources& sources) {
  Params p = preset(sources.preset);
  if (!sources.config.empty()) apply_config_file(sources.config, p);
  for (const auto& o : sources.overrides) apply_override(o, p);
  if (sources.cell_size) p.map.cell_size = *sources.cell_size;
  if (sources.min_range) p.map.min_range = *sources.min_range;
  if (sources.max_range) p.map.max_range = *sources.max_range;
  for (const auto& [name, value] : sources.values) set_param(p, name, value);
  validate(p);
  return p;
}

ScanParams resolve_params_for_scan(const ParamSources& sources, std::span<const Point3f> first_scan) {
  const SensorProfile sensor = profile_scan(first_scan);
  ScanParams out;
  ParamSources chosen = sources;
  if (chosen.preset.empty()) chosen.preset = preset_for_sensor(sensor, &out.preset_reason);
  out.preset = chosen.preset;
  out.params = resolve_params(chosen);
  // A range the user named (--max-range, --set, a value) stands even where it equals the preset's,
  // and so does the range of a preset the user named. So does a height gap named by --set or a
  // value (`--set map.ring_gap_slope=0`: one gap for every cell). A parameter file's values are
  // taken as unset where they equal the preset's.
  const auto named = [&sources](std::initializer_list<std::string_view> names) {
    const auto is = [&names](std::string_view n) { return std::find(names.begin(), names.end(), n) != names.end(); };
    bool any = false;
    for (const std::string& o : sources.overrides) any = any || is(std::string_view(o).substr(0, o.find('=')));
    for (const auto& [name, value] : sources.values) any = any || is(name);
    return any;
  };
  const bool range_named = sources.max_range.has_value() || !sources.preset.empty() || named({"map.max_range"});
  const bool gap_named = named({"map.ring_gap_slope", "map.point_distance_threshold"});
  out.adapted = adapt_to_sensor(out.params, preset(out.preset), sensor, range_named, gap_named);
  validate(out.params);
  return out;
}

std::string params_to_yaml(const Params& params) {
  Params copy = params;
  std::ostringstream out;
  for (const auto& r : param_refs(copy)) {
    char number[32];
    const auto end = std::to_chars(number, number + sizeof number, r.get()).ptr;  // shortest exact
    out << r.name << ": " << std::string_view(number, static_cast<std::size_t>(end - number))
        << "  # [" << r.unit << "] " << r.description << "; range " << r.range.text() << "\n";
  }
  return out.str();
}

}  // namespace hmap
