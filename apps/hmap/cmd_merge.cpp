// hmap merge: maps of different sessions made one, optionally registered first.

#include <cmath>
#include <cstdio>
#include <numbers>

#include "cli_common.hpp"
#include "hmap/core/format.hpp"
#include "hmap/io/atomic_file.hpp"
#include "hmap/io/hmap_file.hpp"
#include "hmap/maps/map_merge.hpp"
#include "hmap/occupancy/layers_merge.hpp"
#ifdef HMAP_HAVE_SLAM
#include "hmap/slam/map_align.hpp"
#endif

namespace hmap::cli {

namespace {

struct MergeOptions {
  std::string first;
  std::string second;
  std::string out;
  std::vector<double> shift;  ///< x y z yaw_deg: the second map's frame in the first's
  bool align = false;
  double search = 5.0;        ///< [m]
  double search_yaw = 30.0;   ///< [deg]
};

void run_merge(const MergeOptions& o) {
  check_output_extension(o.out, {".hmap"}, "hmap merge writes a .hmap map");
  check_output_file(o.out);
  if (!o.shift.empty()) {
    for (const double v : o.shift) {
      if (!std::isfinite(v)) throw Error("--shift: the four numbers must be finite");
    }
  }
  MapFile a = load_map_file(o.first);
  const MapFile b = load_map_file(o.second);
  if (a.map.cell_size() != b.map.cell_size()) {
    throw InputError(o.second, "", format("its cells are %g m, %s's %g m: maps of one cell size merge", b.map.cell_size(),
                                          o.first.c_str(), a.map.cell_size()));
  }
  PlanarShift shift;
  if (!o.shift.empty()) shift = {o.shift[0], o.shift[1], o.shift[2], o.shift[3] * std::numbers::pi / 180.0};
  std::string aligned;
  if (o.align) {
#ifdef HMAP_HAVE_SLAM
    slam::MapAlignOptions options;
    options.guess = shift;
    options.search_translation = o.search;
    options.search_rotation = o.search_yaw * std::numbers::pi / 180.0;
    const slam::MapAlignResult r = slam::align_maps(a.map, b.map, options);
    shift = r.shift;
    aligned = format(" Aligned on %zu columns (%zu HVoxels matched, %d iterations, mean M_H %.3f%s; z from %zu floor pairs).",
                     r.columns_used, r.match.hvoxels_used, r.match.iterations, r.match.score,
                     r.match.degenerate ? ", degenerate: an axis is poorly held" : "", r.floor_pairs);
#else
    throw Error("hmap merge --align: this build has no SLAM module");
#endif
  }
  const bool moved = shift.x != 0.0 || shift.y != 0.0 || shift.z != 0.0 || shift.yaw != 0.0;
  const HMap b_map = moved ? shifted_map(b.map, shift, memory_budget()) : HMap(b.map.params());
  const MapMergeStats st = merge_map(a.map, moved ? b_map : b.map, memory_budget());
  // The SLAM's cell centroids (`hmap slam`'s maps) of either map, the second's moved as its map;
  // a cell with none is read at its centre by a session that continues the merged map.
  const CellCentroids* centroids = nullptr;
  if (b.centroids && b.centroids->size() > 0) {
    if (!a.centroids) a.centroids.emplace(a.map.cell_size());
    a.centroids->add(*b.centroids, shift.x, shift.y, shift.yaw);
  }
  if (a.centroids && a.centroids->size() > 0) centroids = &*a.centroids;
  // The 2D grid and the ground patches only when both maps hold them: half a grid would show
  // one session's area as unknown.
  const bool layers = a.grid.has_value() && b.grid.has_value();
  std::size_t patches_kept = 0;
  if (layers) {
    if (moved) {
      add_evidence(*a.grid, shifted_grid(*b.grid, shift));
    } else {
      add_evidence(*a.grid, *b.grid);
    }
    patches_kept = join_ground(a.ground, moved ? shifted_ground(b.ground, shift) : b.ground);
    save_hmap(o.out, a.map, a.ground, &*a.grid, centroids);
  } else {
    save_hmap(o.out, a.map, {}, nullptr, centroids);
  }
  std::printf("Merged %s into %s: %zu columns added, %zu merged; %zu + %zu HVoxels -> %zu. Saved to %s (%s).\n",
              o.second.c_str(), o.first.c_str(), st.columns_added, st.columns_merged, st.hvoxels_before, st.hvoxels_from,
              st.hvoxels_after, o.out.c_str(), human_bytes(static_cast<double>(std::filesystem::file_size(o.out))).c_str());
  std::printf("The second map's frame in the first's: x %.3f m, y %.3f m, z %.3f m, yaw %.3f deg.%s\n", shift.x, shift.y,
              shift.z, shift.yaw * 180.0 / std::numbers::pi, aligned.c_str());
  if (layers) {
    std::printf("The 2D grids' evidence added (%zu known cells); %zu of the second map's %zu ground patches joined.\n",
                a.grid->known_cells(), patches_kept, b.ground.size());
  } else {
    std::printf("The HMAP alone was merged: %s has no 2D grid or ground patches (saved with --hvoxels-only).\n",
                a.grid ? o.second.c_str() : o.first.c_str());
  }
  if (centroids != nullptr) {
    std::printf("The SLAM's cell centroids kept (the second map's moved with it): %zu cells.\n", centroids->size());
  }
}

}  // namespace

void add_merge_command(CLI::App& app) {
  auto opts = std::make_shared<MergeOptions>();
  auto* cmd = app.add_subcommand("merge", "Merge two maps (.hmap) of one cell size into one, optionally registering the second first");
  cmd->add_option("first", opts->first, "The map merged into; its parameters are kept")->required();
  cmd->add_option("second", opts->second, "The map merged in")->required();
  cmd->add_option("--out,-o", opts->out, "Output map file (.hmap)")->required();
  cmd->add_option("--shift", opts->shift,
                  "X Y Z YAW_DEG: the second map's frame in the first's, applied before merging (with --align: the "
                  "guess it starts from)")
      ->expected(4);
  cmd->add_flag("--align", opts->align,
                "Register the second map onto the first first: the scan matcher over the overlapping columns, "
                "a coarse search first; z from the floors");
  cmd->add_option("--search", opts->search, "[m] half-width of --align's coarse search in x and y")
      ->check(CLI::Range(0.0, 20.0));
  cmd->add_option("--search-yaw", opts->search_yaw, "[deg] half-width of --align's coarse search in yaw")
      ->check(CLI::Range(0.0, 180.0));
  cmd->callback([opts] { run_merge(*opts); });
}

}  // namespace hmap::cli
