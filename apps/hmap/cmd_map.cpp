// hmap map: scans with known poses in, a saved HMAP out.

#include <cstdio>

#include "cli_common.hpp"
#include "mcap_output.hpp"
#include "hmap/core/format.hpp"
#include "hmap/core/sensor_profile.hpp"
#include "hmap/io/atomic_file.hpp"
#include "hmap/io/hmap_file.hpp"
#include "hmap/io/prefetch.hpp"
#include "hmap/maps/mapper.hpp"
#include "hmap/occupancy/hybrid_mapper.hpp"
#ifdef HMAP_HAVE_VIEW
#include "live_view.hpp"
#endif

namespace hmap::cli {

namespace {

struct MapOptions : InputOptions {
  ParamOptions params;
  std::string out;
  std::string mcap;
  std::string continue_from;  ///< a saved map the scans are added to
  bool hvoxels_only = false;
#ifdef HMAP_HAVE_VIEW
  LiveViewOptions view;
#endif
};

void run_map(const MapOptions& o) {
  Params params = o.params.resolve();  // from the named preset (or outdoor): bad values refused first
  check_output_extension(o.out, {".hmap"}, "hmap map writes a .hmap map");
  check_output_file(o.out);  // before the work: a missing folder was found after mapping every scan
  if (!o.mcap.empty()) check_mcap_output(o.mcap);
  // --continue: the saved map and its layers are the start, with the parameters it was built
  // with (a map built on with other ones, a finer cell say, would not be one map).
  std::optional<MapFile> old;
  if (!o.continue_from.empty()) {
    const ParamOptions& po = o.params;
    if (!po.preset.empty() || !po.config.empty() || !po.overrides.empty() || po.cell || po.min_range || po.max_range) {
      throw Error("hmap map --continue: the map is continued with the parameters it was built with; "
                  "--preset, --config, --set, --cell, --min-range and --max-range cannot change them");
    }
    old = load_map_file(o.continue_from);
    if (!old->grid && !o.hvoxels_only) {
      throw InputError(o.continue_from, "", "holds the HMAP alone (saved with --hvoxels-only): continue it with --hvoxels-only");
    }
    if (old->grid && o.hvoxels_only) {
      throw InputError(o.continue_from, "", "holds the 2D grid and ground patches, which --hvoxels-only would drop: continue it without --hvoxels-only");
    }
    params = old->map.params();
  }
  const MapStats old_stats = old ? old->map.stats() : MapStats{};
  const ScanSource src = o.open_inputs(/*poses_required=*/true);
  if (!o.mcap.empty()) check_mcap_stamps(src.stamps, "the scans' stamps");
  // Defaults the first scan can tell, as hmap slam takes them: the preset from the sensor's reach
  // when none is named, the height gap from a spinning LiDAR's ring spacing.
  std::string chosen_text;
  CloudReadStats first_stats;
  PointCloud first;
  if (!src.scans.empty()) {
    first = src.read(0, first_stats);
  }
  if (!src.scans.empty() && !old) {
    const ScanParams chosen = resolve_params_for_scan(o.params.sources(), first);
    params = chosen.params;
    chosen_text = chosen_summary(chosen);
  }
  // The hybrid map of section IV by default: the HMAP, the ground patches of Alg. 4 and the 2D
  // grid of eq. (3)-(4), all saved; --hvoxels-only keeps section III alone (faster).
  HybridMapper hybrid = old && !o.hvoxels_only
                            ? HybridMapper(std::move(old->map), std::move(*old->grid), std::move(old->ground))
                            : HybridMapper(params);
  Mapper mapper = old && o.hvoxels_only ? Mapper(std::move(old->map)) : Mapper(params);
#ifdef HMAP_HAVE_VIEW
  LiveView live(o.view);
  // The map as it is now, to the page: after every scan, at most once a second.
  std::vector<Eigen::Vector3d> path;
  const auto show = [&](const std::string& progress, bool final) {
    if (o.hvoxels_only) live.update(mapper.map(), {}, nullptr, path, progress, final);
    else live.update(hybrid.map(), hybrid.ground_patches(), &hybrid.grid(), path, progress, final);
  };
#endif
  CloudReadStats read_stats;
  ScanStats total;
  std::size_t no_ground = 0, grid_rays = 0;
  double ms_integrate = 0.0;
  Progress progress("mapping", src.scans.size());
  // From a bag or an RGB-D folder, scan k + 1 is decoded while scan k is integrated; the first,
  // read above, is not read again.
  Prefetcher<ReadScan> scans(src.scans.size(), [&](std::size_t k) {
    if (k == 0) return ReadScan{std::move(first), first_stats, {}};
    ReadScan r;
    r.cloud = src.read(k, r.stats);
    return r;
  }, src.frames ? ReadAhead::kYes : ReadAhead::kNo);  // bags and RGB-D frames decode; files copy
  for (std::size_t k = 0; k < src.scans.size(); ++k) {
    const ReadScan next = scans.next();
    const PointCloud& cloud = next.cloud;
    read_stats += next.stats;
    const auto t0 = Clock::now();
    ScanStats s;
    for_scan(src, k, [&] {
      if (o.hvoxels_only) {
        s = mapper.integrate(cloud, (*src.T_map_scan)[k]);
      } else {
        const HybridScanStats h = hybrid.integrate(cloud, (*src.T_map_scan)[k]);
        s = h.map;
        no_ground += h.occupancy.no_ground;
        grid_rays += h.occupancy.rays;
      }
      // The map grows with the area seen: refused by scan, before it outgrows the machine.
      const double bytes = o.hvoxels_only ? static_cast<double>(mapper.map().memory_bytes())
                                          : static_cast<double>(hybrid.map().memory_bytes() + hybrid.grid().memory_bytes());
      memory_budget().require(bytes, "the map");
    });
    ms_integrate += ms_since(t0);
    total.points_in += s.points_in;
    total.points_kept += s.points_kept;
    total.dropped_non_finite += s.dropped_non_finite;
    total.dropped_range += s.dropped_range;
    total.extrusion.removed += s.extrusion.removed;
    progress.update(k + 1, ms_integrate / static_cast<double>(k + 1));
#ifdef HMAP_HAVE_VIEW
    if (o.view.enabled) {
      path.push_back((*src.T_map_scan)[k].translation());
      show(format("scan %zu of %zu", k + 1, src.scans.size()), false);
    }
#endif
  }
  progress.finish();
  // Nothing kept from any scan: not a map but a wrong input (a pose or intrinsics file given as
  // a scan, every point within min_range), which used to save an empty map with exit 0.
  if (total.points_kept == 0 && read_stats.points_read > 0) {
    throw Error(format("no point of the %zu read from %zu scans was kept (%zu not finite, %zu out of the %g-%g m range): "
                       "are these point clouds, and is map.min_range right?",
                       read_stats.points_read, src.scans.size(), read_stats.non_finite_dropped + total.dropped_non_finite,
                       total.dropped_range, params.map.min_range, params.map.max_range));
  }
  const HMap& map = o.hvoxels_only ? mapper.map() : hybrid.map();
  // A continued SLAM map keeps the cell centroids it was saved with (the scans added here, at
  // given poses, add none: a cell they alone reach is read at its centre by a later `hmap slam
  // --continue`).
  const CellCentroids* centroids = old && old->centroids ? &*old->centroids : nullptr;
  if (o.hvoxels_only) {
    save_hmap(o.out, map, {}, nullptr, centroids);
  } else {
    save_hmap(o.out, map, hybrid.ground_patches(), &hybrid.grid(), centroids);
  }
  const MapStats st = map.stats();
  const auto n = static_cast<double>(src.scans.size());
  // Told with the result, not before the work: an error stays the one line of its run.
  if (!src.description.empty()) std::printf("input: %s\n", src.description.c_str());
  std::printf(
      "Mapped %zu scans: %s points read, %s kept, %s dropped (%s not finite, %s out of the %.2f-%.2f m "
      "range). Integration took %.1f ms per scan (%s points/s). The map has %zu cells and %zu HVoxels "
      "(%s in memory, cell %.3f m); extrusion removed %zu HVoxels. Saved to %s (%s).\n",
      src.scans.size(), human_count(static_cast<double>(read_stats.points_read)).c_str(),
      human_count(static_cast<double>(total.points_kept)).c_str(),
      human_count(static_cast<double>(read_stats.non_finite_dropped + total.dropped_non_finite + total.dropped_range)).c_str(),
      human_count(static_cast<double>(read_stats.non_finite_dropped + total.dropped_non_finite)).c_str(),
      human_count(static_cast<double>(total.dropped_range)).c_str(), params.map.min_range, params.map.max_range,
      n > 0 ? ms_integrate / n : 0.0,
      human_count(ms_integrate > 0 ? static_cast<double>(total.points_in) / (ms_integrate / 1000.0) : 0.0).c_str(),
      st.cells, st.hvoxels, human_bytes(static_cast<double>(st.memory_bytes)).c_str(), params.map.cell_size,
      total.extrusion.removed, o.out.c_str(),
      human_bytes(static_cast<double>(std::filesystem::file_size(o.out))).c_str());
  if (!chosen_text.empty()) std::printf("Chosen from the first scan:%s\n", chosen_text.c_str());
  if (old) {
    std::printf("Continued %s (%zu cells, %zu HVoxels before; its parameters, cell %.3f m).\n", o.continue_from.c_str(),
                old_stats.cells, old_stats.hvoxels, params.map.cell_size);
  }
  if (!o.hvoxels_only) {
    std::size_t occupied = 0, free_cells = 0;
    hybrid.grid().for_each_cell([&](const CellKey&, float l) { (l > 0.0F ? occupied : free_cells) += 1; });
    std::printf("The 2D grid has %zu occupied and %zu free cells; %zu ground patches; %zu of %zu scan cells had no "
                "ground patch near them and left the grid alone.\n",
                occupied, free_cells, hybrid.ground_patches().size(), no_ground, grid_rays + no_ground);
  }
  if (!o.mcap.empty()) {
    const PoseList used(src.T_map_scan->begin(), src.T_map_scan->begin() + static_cast<std::ptrdiff_t>(src.scans.size()));
    if (o.hvoxels_only) {
      write_run_mcap(o.mcap, map, {}, nullptr, used, src.stamps);
    } else {
      write_run_mcap(o.mcap, map, hybrid.ground_patches(), &hybrid.grid(), used, src.stamps);
    }
  }
#ifdef HMAP_HAVE_VIEW
  if (o.view.enabled) {
    show(format("done: %zu scans, saved to %s", src.scans.size(), o.out.c_str()), true);
    live.serve_until_stopped();
  }
#endif
}

}  // namespace

void add_map_command(CLI::App& app) {
  auto opts = std::make_shared<MapOptions>();
  auto* cmd = app.add_subcommand("map", "Build an HMAP from scans with known poses");
  opts->add_input_options(*cmd, kKnownPosesHelp);
  cmd->add_option("--out,-o", opts->out, "Output map file (.hmap)")->required();
  cmd->add_flag("--hvoxels-only", opts->hvoxels_only,
                "Build the HMAP alone (section III), without the ground patches and the 2D grid");
  cmd->add_option("--mcap", opts->mcap,
                  "Also write the map as an MCAP recording for Foxglove (OUT.mcap), as hmap export --mcap writes it, "
                  "with the scans' poses as /trajectory and one /tf per scan at its stamp (times.txt of a KITTI folder, "
                  "a TUM --poses file's times or times.txt beside a KITTI one, a bag's; else 0)");
  cmd->add_option("--continue", opts->continue_from,
                  "Add the scans to this saved map (.hmap) and its 2D grid and ground patches, with the parameters it was "
                  "built with; the result goes to --out (which may be the same file). The scans' poses are in its frame");
  opts->params.add_to(*cmd);
#ifdef HMAP_HAVE_VIEW
  opts->view.add_to(*cmd);
#endif
  cmd->callback([opts] { run_map(*opts); });
}

}  // namespace hmap::cli
