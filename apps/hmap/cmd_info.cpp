// hmap info: what a saved map holds.

#include <nlohmann/json.hpp>

#include <cstdio>
#include <iostream>

#include "cli_common.hpp"
#include "hmap/io/config.hpp"
#include "hmap/io/hmap_file.hpp"
#ifdef HMAP_HAVE_PVOX
#include "pvox_output.hpp"
#endif

namespace hmap::cli {

namespace {

#ifdef HMAP_HAVE_PVOX
/// The `.pvox` map of `hmap pvox`: its edge, voxels, bounds and probability model.
void run_pvox_info(const std::string& file, bool json) {
  const pvox::VoxelMap map = load_pvox_file(file);
  const auto occupied = map.occupied();
  Eigen::AlignedBox3d bounds;
  for (const auto& v : occupied) bounds.extend(v.centre);
  const pvox::ProbabilityModel& m = map.model();
  const auto file_bytes = std::filesystem::file_size(file);
  if (json) {
    nlohmann::json j;
    j["file"] = file;
    j["format"] = "pvox";
    j["file_bytes"] = file_bytes;
    j["edge"] = map.edge();
    j["voxels"] = map.voxel_count();
    j["occupied_voxels"] = occupied.size();
    j["memory_bytes"] = map.memory_bytes();
    if (!bounds.isEmpty()) {
      j["bounds"] = {{"min", {bounds.min().x(), bounds.min().y(), bounds.min().z()}},
                     {"max", {bounds.max().x(), bounds.max().y(), bounds.max().z()}}};
    }
    j["model"] = {{"measurement_variance", m.measurement_variance},
                  {"logit_min", m.logit_min},
                  {"logit_max", m.logit_max},
                  {"miss_logit", m.miss_logit}};
    std::cout << j.dump() << "\n";
    return;
  }
  std::printf("file:        %s (%s), a PVOX map\n", file.c_str(), human_bytes(static_cast<double>(file_bytes)).c_str());
  std::printf("voxel edge:  %.4g m\n", map.edge());
  std::printf("voxels:      %zu holding counts, %zu occupied (p > 0.5)\n", map.voxel_count(), occupied.size());
  std::printf("memory:      %s\n", human_bytes(static_cast<double>(map.memory_bytes())).c_str());
  if (!bounds.isEmpty()) {
    std::printf("bounds:      x %.2f..%.2f  y %.2f..%.2f  z %.2f..%.2f m (centres of the occupied voxels)\n",
                bounds.min().x(), bounds.max().x(), bounds.min().y(), bounds.max().y(), bounds.min().z(), bounds.max().z());
  }
  std::printf("model:       measurement variance %.4g m^2, logit clamp [%g, %g], miss logit %g\n", m.measurement_variance,
              m.logit_min, m.logit_max, m.miss_logit);
}
#endif

void run_info(const std::string& file, bool json) {
#ifdef HMAP_HAVE_PVOX
  if (is_pvox_file(file)) return run_pvox_info(file, json);
#endif
  const HMap map = load_hmap(file);
  const MapStats st = map.stats();
  Params params = map.params();
  if (json) {
    nlohmann::json j;
    j["file"] = file;
    j["file_bytes"] = std::filesystem::file_size(file);
    j["cells"] = st.cells;
    j["hvoxels"] = st.hvoxels;
    j["tiles"] = st.tiles;
    j["memory_bytes"] = st.memory_bytes;
    j["cell_size"] = map.cell_size();
    if (!st.bounds.isEmpty()) {
      j["bounds"] = {{"min", {st.bounds.min().x(), st.bounds.min().y(), st.bounds.min().z()}},
                     {"max", {st.bounds.max().x(), st.bounds.max().y(), st.bounds.max().z()}}};
    }
    nlohmann::json p;
    for (const auto& r : param_refs(params)) p[r.name] = r.get();
    j["parameters"] = p;
    std::cout << j.dump() << "\n";
    return;
  }
  std::printf("file:        %s (%s)\n", file.c_str(), human_bytes(static_cast<double>(std::filesystem::file_size(file))).c_str());
  std::printf("cell size:   %.4g m\n", map.cell_size());
  std::printf("cells:       %zu (in %zu tiles of %dx%d)\n", st.cells, st.tiles, HMap::kTileSize, HMap::kTileSize);
  std::printf("HVoxels:     %zu (%.2f per cell)\n", st.hvoxels,
              st.cells > 0 ? static_cast<double>(st.hvoxels) / static_cast<double>(st.cells) : 0.0);
  std::printf("memory:      %s (%.1f bytes per cell)\n", human_bytes(static_cast<double>(st.memory_bytes)).c_str(),
              st.cells > 0 ? static_cast<double>(st.memory_bytes) / static_cast<double>(st.cells) : 0.0);
  if (!st.bounds.isEmpty()) {
    std::printf("bounds:      x %.2f..%.2f  y %.2f..%.2f  z %.2f..%.2f m\n", st.bounds.min().x(), st.bounds.max().x(),
                st.bounds.min().y(), st.bounds.max().y(), st.bounds.min().z(), st.bounds.max().z());
  }
  std::printf("parameters:\n%s", params_to_yaml(params).c_str());
}

}  // namespace

void add_info_command(CLI::App& app) {
  auto file = std::make_shared<std::string>();
  auto json = std::make_shared<bool>(false);
  auto* cmd = app.add_subcommand("info", "Show the size, bounds and parameters of a map (.hmap, or the .pvox of hmap pvox)");
  cmd->add_option("map", *file, "Map file (.hmap or .pvox)")->required();
  cmd->add_flag("--json", *json, "One JSON object instead of text");
  cmd->callback([file, json] { run_info(*file, *json); });
}

}  // namespace hmap::cli
