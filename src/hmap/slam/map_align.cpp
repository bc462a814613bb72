#include "hmap/slam/map_align.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

#include "hmap/core/error.hpp"
#include "hmap/core/format.hpp"

namespace hmap::slam {

namespace {

/// Columns of `moving` farther than this from their centroid are left out (the matcher's window
/// is dense over ±max_range, and validate() keeps that within 2048 cells).
constexpr double kMaxReachCells = 1024.0;

/// The lowest surface of a column: its lowest HVoxel's top.
float floor_of(const ColumnView& c) { return c[0].z_max; }

/// Median of `moving`'s lowest tops minus `reference`'s over the columns that fall on each other
/// under `shift` (x, y, yaw; z ignored); differences beyond ±2 m (a floor against a table) left out.
double floor_offset(const HMap& reference, const HMap& moving, const PlanarShift& shift, std::size_t& pairs) {
  const double c = std::cos(shift.yaw);
  const double sn = std::sin(shift.yaw);
  std::vector<double> d;
  moving.for_each_column([&](const CellKey& key, const ColumnView& column) {
    const Eigen::Vector2d v = moving.cell_center(key);
    const ColumnView other = reference.column(c * v.x() - sn * v.y() + shift.x, sn * v.x() + c * v.y() + shift.y);
    if (other.empty()) return;
    const double diff = static_cast<double>(floor_of(other)) - static_cast<double>(floor_of(column));
    if (std::abs(diff) <= 2.0) d.push_back(diff);
  });
  pairs = d.size();
  if (d.empty()) return 0.0;
  std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2), d.end());
  return d[d.size() / 2];
}

}  // namespace

MapAlignResult align_maps(const HMap& reference, const HMap& moving, const MapAlignOptions& options) {
  if (reference.cell_size() != moving.cell_size()) {
    throw Error(format("aligning maps: the maps' cells differ (%g m and %g m); build both with the same map.cell_size",
                       reference.cell_size(), moving.cell_size()));
  }
  const PlanarShift& g = options.guess;
  if (!(std::isfinite(g.x) && std::isfinite(g.y) && std::isfinite(g.z) && std::isfinite(g.yaw))) {
    throw Error("aligning maps: the guess must be finite");
  }
  const double s = reference.cell_size();
  const MapStats ref_stats = reference.stats();
  if (ref_stats.hvoxels == 0 || moving.empty()) throw Error("aligning maps: a map is empty");

  // The columns of `moving` that land on `reference`'s area at the guess (widened by the search).
  const double margin = options.search_translation + s;
  Eigen::AlignedBox2d area(ref_stats.bounds.min().head<2>() - Eigen::Vector2d::Constant(margin),
                           ref_stats.bounds.max().head<2>() + Eigen::Vector2d::Constant(margin));
  const double c = std::cos(g.yaw);
  const double sn = std::sin(g.yaw);
  std::vector<CellKey> keys;
  Eigen::Vector2d sum = Eigen::Vector2d::Zero();
  moving.for_each_column([&](const CellKey& key, const ColumnView&) {
    const Eigen::Vector2d v = moving.cell_center(key);
    if (!area.contains(Eigen::Vector2d(c * v.x() - sn * v.y() + g.x, sn * v.x() + c * v.y() + g.y))) return;
    keys.push_back(key);
    sum += v;
  });
  if (keys.empty()) throw Error("aligning maps: at the guess, no column of the second map lies over the first");
  // The scan is centred on a whole cell o (so the cell centres stay exact): a point v of `moving`
  // is v' = v - o in the scan. On the moving frame's origin when the columns lie close enough
  // about it that the coarse search's yaw step (two cells at their RMS radius) is not widened
  // over the window: one search then covers every heading (a scan's map about its sensor, as
  // `hmap slam --continue` aligns). Else on the columns' centroid, in yaw sectors (below).
  double radius2 = 0.0;
  double reach_cells = 0.0;
  for (const CellKey& key : keys) {
    radius2 += moving.cell_center(key).squaredNorm();
    reach_cells = std::max({reach_cells, std::abs(key.i + 0.5), std::abs(key.j + 0.5)});
  }
  const double rms_radius = std::sqrt(radius2 / static_cast<double>(keys.size()));
  const bool about_origin = reach_cells <= kMaxReachCells &&
                            (options.search_rotation <= 0.0 ||
                             2.0 * s / std::max(rms_radius, s) >= options.search_rotation / ScanMatcher::kCoarseMaxYawSteps);
  const CellKey o = about_origin ? CellKey{0, 0}
                                 : moving.key_of(sum.x() / static_cast<double>(keys.size()), sum.y() / static_cast<double>(keys.size())).value();
  std::sort(keys.begin(), keys.end(), [](const CellKey& a, const CellKey& b) { return a.i != b.i ? a.i < b.i : a.j < b.j; });

  MapAlignResult result;
  const double z0 = floor_offset(reference, moving, g, result.floor_pairs);
  const auto build_scan = [&](double dz) {
    ScanHVoxels scan;
    double reach = 0.0;
    for (const CellKey& key : keys) {
      const double di = key.i - o.i;
      const double dj = key.j - o.j;
      if (std::max(std::abs(di), std::abs(dj)) > kMaxReachCells) continue;
      reach = std::max(reach, std::hypot(di + 0.5, dj + 0.5) * s);
      const ColumnView column = moving.column(key);
      ScanCell cell{{key.i - o.i, key.j - o.j}, static_cast<std::uint32_t>(scan.hvoxels.size()), static_cast<std::uint32_t>(column.size())};
      for (HVoxel v : column) {
        v.z_min += static_cast<float>(dz);
        v.z_max += static_cast<float>(dz);
        scan.hvoxels.push_back(v);
      }
      scan.cells.push_back(cell);
    }
    return std::pair{std::move(scan), reach};
  };
  auto [scan, reach] = build_scan(z0);
  result.columns_used = scan.cells.size();

  // The coarse search turns the centred scan about o, but the window is about the moving frame's
  // origin: turned by ψ about o instead, the origin moves by the chord 2·|o|·sin(ψ/2) (12.7 m for
  // 105° at 8 m; balm_os0's second half, whose right pose then lay outside the ±5 m window). The
  // yaw window is cut into sectors, each searched from its own centre turned about the origin, so
  // narrow that within one the chord stays under kChord, which widens its translation window.
  const Eigen::Vector2d os((o.i) * s, (o.j) * s);
  constexpr double kChord = 1.0;  // [m]
  const double lever = os.norm();
  int sectors = 1;
  if (options.search_rotation > 0.0 && lever > 0.5 * kChord) {
    const double w = 2.0 * std::asin(0.5 * kChord / lever);  // the sector's half-width for that chord
    sectors = static_cast<int>(std::min(256.0, std::ceil(options.search_rotation / w)));
  }
  const double half = options.search_rotation / sectors;
  Params params = reference.params();
  params.map.max_range = std::max(params.map.min_range + s, reach + s);
  params.slam.coarse_translation = std::min({options.search_translation + 2.0 * lever * std::sin(0.5 * half), 20.0, 100.0 * s});
  params.slam.coarse_rotation = half;
  if (params.slam.max_hvoxels == 0) params.slam.max_hvoxels = 50000;
  if (params.slam.coarse_trigger_ratio <= 0.0) params.slam.coarse_trigger_ratio = 0.85;
  try {
    validate(params);
  } catch (const Error& e) {
    throw Error(std::string("aligning maps: ") + e.what());
  }
  ScanMatcher matcher(params);
  // The centred scan at the guess: its origin o sits at R(yaw) o + t.
  const auto centred = [&](const PlanarShift& shift) {
    const double cc = std::cos(shift.yaw), ss = std::sin(shift.yaw);
    return PlanarPose{shift.x + cc * os.x() - ss * os.y(), shift.y + ss * os.x() + cc * os.y(), shift.yaw};
  };
  const auto uncentred = [&](const PlanarPose& p, double z) {
    const double cc = std::cos(p.yaw), ss = std::sin(p.yaw);
    return PlanarShift{p.x - (cc * os.x() - ss * os.y()), p.y - (ss * os.x() + cc * os.y()), z, p.yaw};
  };
  // Each sector from its centre; the match that agrees best (mean M_H) wins.
  for (int k = 0; k < sectors; ++k) {
    PlanarShift start = g;
    start.yaw += -options.search_rotation + (2 * k + 1) * half;
    MatchResult m = matcher.match(scan, reference, centred(start), CoarseSearch::kAlways);
    if (k == 0 || m.score > result.match.score) result.match = m;
  }
  result.sectors = sectors;
  result.about_origin = about_origin;
  PlanarShift shift = uncentred(result.match.pose, z0);
  // z again where the columns now fall, and the planar match refined from there.
  const double z1 = floor_offset(reference, moving, shift, result.floor_pairs);
  if (std::abs(z1 - z0) > 1e-6) {
    scan = build_scan(z1).first;
    result.match = matcher.match(scan, reference, result.match.pose);
    shift = uncentred(result.match.pose, z1);
  }
  result.shift = shift;
  return result;
}

}  // namespace hmap::slam
