// hmap info: what a saved map holds.

#include <nlohmann/json.hpp>

#include <cstdio>
#include <iostream>

#include "cli_common.hpp"
#include "hmap/io/config.hpp"
#include "hmap/io/hmap_file.hpp"

namespace hmap::cli {

namespace {

void run_info(const std::string& file, bool json) {
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
  auto* cmd = app.add_subcommand("info", "Show the size, bounds and parameters of a map");
  cmd->add_option("map", *file, "Map file (.hmap)")->required();
  cmd->add_flag("--json", *json, "One JSON object instead of text");
  cmd->callback([file, json] { run_info(*file, *json); });
}

}  // namespace hmap::cli
