#include "hmap/occupancy/exported_grid.hpp"

#include <algorithm>
#include <cstdio>

#include "hmap/core/error.hpp"
#include "hmap/core/format.hpp"
#include "hmap/occupancy/occupancy_update.hpp"

namespace hmap {

std::optional<GridSource> parse_grid_source(std::string_view name) {
  if (name == "both") return GridSource::kBoth;
  if (name == "kept") return GridSource::kKept;
  if (name == "judged") return GridSource::kJudged;
  return std::nullopt;
}

namespace {

OccupancyGrid empty_grid(const HMap& map) {
  const OccupancyParams& o = map.params().occupancy;
  return OccupancyGrid(map.cell_size(), o.clamp_min, o.clamp_max);
}

OccupancyGrid copy_of(const OccupancyGrid& g) {
  OccupancyGrid out(g.cell_size(), probability(g.clamp_min_log_odds()), probability(g.clamp_max_log_odds()));
  g.for_each_cell([&](const CellKey& key, float l) { out.set(key, l); });
  return out;
}

ExportedGrid derive(const HMap& map, const ExportGridParams& p) {
  const MapStats st = map.stats();
  Params params = map.params();
  ExportedGrid out{empty_grid(map), {}, {}};
  out.derived = true;
  if (p.ground_hint) {
    out.hint = *p.ground_hint;
  } else {
    std::vector<float> tops;
    map.for_each_column([&](const CellKey&, const ColumnView& c) { tops.push_back(c[0].z_max); });
    std::sort(tops.begin(), tops.end());
    const Eigen::Vector3d mid = st.bounds.center();
    out.hint = {mid.x(), mid.y(), tops[tops.size() / 5] + 0.5};  // above the low fifth of the lowest tops
  }
  // K of the paper (400) explores a few hundred square metres; grow it with the map's area.
  const double d_n = params.ground.expansion_distance;
  const double area = st.bounds.sizes().x() * st.bounds.sizes().y();
  params.ground.iterations = p.ground_iterations > 0
                                 ? p.ground_iterations
                                 : std::clamp(static_cast<int>(2.0 * area / (d_n * d_n)), params.ground.iterations, 4000);
  out.iterations = params.ground.iterations;
  GroundResult ground = extract_ground(map, out.hint, params.ground);
  if (!ground.seeded) {
    out.ground_found = false;
    return out;
  }
  out.grid = occupancy_from_map(map, GroundModel(ground.patches), params, 2.0 * d_n);
  out.what = format("derived from %zu ground patches (%d RRT iterations); cells without a ground patch within %.2f m are unknown",
                    ground.patches.size(), params.ground.iterations, 2.0 * d_n);
  out.ground = std::move(ground.patches);
  return out;
}

}  // namespace

ExportedGrid export_grid(const HMap& map, std::span<const GroundPatch> ground, const OccupancyGrid* kept,
                         const ExportGridParams& p) {
  if (p.ground_iterations < 0 || p.ground_iterations > 100000) {
    throw Error("ground iterations = " + std::to_string(p.ground_iterations) + " is out of its range [1, 100000] (0: from the map's area)");
  }
  if (p.ground_hint && !p.ground_hint->allFinite()) throw Error("the ground hint is not a finite point");
  if (map.stats().hvoxels == 0) throw Error("the map is empty");
  if (kept == nullptr || kept->known_cells() == 0 || p.rederive) return derive(map, p);
  ExportedGrid out{empty_grid(map), {}, {}};
  out.ground.assign(ground.begin(), ground.end());
  const Params& params = map.params();
  std::optional<OccupancyGrid> judged;
  if (p.source != GridSource::kKept && !ground.empty()) {
    judged = occupancy_from_map(map, GroundModel(out.ground), params, params.occupancy.ground_reach);
  }
  if (judged && p.source == GridSource::kBoth) {
    out.grid = more_occupied(*kept, *judged);
    out.what = "the map's own 2D grid and its columns judged, the more occupied per cell";
  } else if (judged && p.source == GridSource::kJudged) {
    out.grid = std::move(*judged);
    out.what = "the map's columns judged by eq. (4) on its ground patches";
  } else {
    out.grid = copy_of(*kept);
    out.what = "the map's own 2D grid (kept scan by scan)";
  }
  return out;
}

}  // namespace hmap
