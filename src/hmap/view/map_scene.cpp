#include "hmap/view/map_scene.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <map>

#include "hmap/core/error.hpp"

namespace hmap::view {

namespace {

/// A vertical interval being united with its neighbours (level > 0).
struct Span {
  float z_min, z_max, density;
};

void put_f32(std::uint8_t* out, float v) {
  static_assert(std::endian::native == std::endian::little, "the box records are little-endian");
  std::memcpy(out, &v, 4);
}

float get_f32(const std::uint8_t* in) {
  float v = 0.0F;
  std::memcpy(&v, in, 4);
  return v;
}

const char* role_name(HVoxelRole role) {
  switch (role) {
    case HVoxelRole::kObstacle: return "obstacle";
    case HVoxelRole::kGround: return "ground";
    case HVoxelRole::kIgnored: break;
  }
  return "ignored";
}

}  // namespace

MapScene::MapScene(HMap map, std::vector<GroundPatch> ground, std::optional<OccupancyGrid> grid,
                   std::vector<Eigen::Vector3d> trajectory, std::string format)
    : map_(std::move(map)),
      ground_(std::move(ground)),
      grid_(std::move(grid)),
      trajectory_(std::move(trajectory)),
      format_(std::move(format)) {
  bool any = false;
  map_.for_each_column([&](const CellKey&, const ColumnView& c) {
    z_low_ = any ? std::min(z_low_, c[0].z_min) : c[0].z_min;
    z_high_ = any ? std::max(z_high_, c[c.size() - 1].z_max) : c[c.size() - 1].z_max;
    any = true;
  });
  if (!any) {
    z_low_ = 0.0F;
    z_high_ = 1.0F;
  }
  if (z_high_ <= z_low_) z_high_ = z_low_ + 1.0F;  // a flat map still gets a colour range
  if (grid_ && grid_->known_cells() > 0) grid_image_ = view::grid_image(*grid_);
}

std::vector<Box> MapScene::tile_boxes(const CellKey& tile, int level) const {
  if (level < 0 || level >= kLevels) {
    throw Error("view: level " + std::to_string(level) + " is not in 0.." + std::to_string(kLevels - 1));
  }
  const double cell = map_.cell_size();
  const int block = 1 << level;
  const auto edge = static_cast<float>(cell * block);
  const std::int64_t i0 = static_cast<std::int64_t>(tile.i) * kViewTileCells;
  const std::int64_t j0 = static_cast<std::int64_t>(tile.j) * kViewTileCells;
  // Cell keys stay within ±2^30 (HMap::kMaxKey): a tile beyond holds nothing.
  if (std::abs(i0) > (std::int64_t{1} << 31) || std::abs(j0) > (std::int64_t{1} << 31)) return {};
  std::vector<Box> boxes;
  std::vector<Span> spans;
  for (int bi = 0; bi < kViewTileCells; bi += block) {
    for (int bj = 0; bj < kViewTileCells; bj += block) {
      spans.clear();
      for (int di = 0; di < block; ++di) {
        for (int dj = 0; dj < block; ++dj) {
          const CellKey key{static_cast<std::int32_t>(i0 + bi + di), static_cast<std::int32_t>(j0 + bj + dj)};
          for (const HVoxel& v : map_.column(key)) spans.push_back({v.z_min, v.z_max, v.density});
        }
      }
      if (spans.empty()) continue;
      if (level > 0) {
        // Unite what overlaps or lies closer than the block's edge: a coarse box per wall
        // stretch, not per HVoxel.
        std::sort(spans.begin(), spans.end(), [](const Span& a, const Span& b) { return a.z_min < b.z_min; });
        std::size_t kept = 0;
        for (std::size_t k = 1; k < spans.size(); ++k) {
          Span& top = spans[kept];
          if (spans[k].z_min <= top.z_max + edge) {
            top.z_max = std::max(top.z_max, spans[k].z_max);
            top.density = std::max(top.density, spans[k].density);
          } else {
            spans[++kept] = spans[k];
          }
        }
        spans.resize(kept + 1);
      }
      const auto x = static_cast<float>((static_cast<double>(i0 + bi) + 0.5 * block) * cell);
      const auto y = static_cast<float>((static_cast<double>(j0 + bj) + 0.5 * block) * cell);
      for (const Span& s : spans) {
        const float zc = 0.5F * (s.z_min + s.z_max);
        boxes.push_back({Eigen::Vector3f(x, y, zc), Eigen::Vector3f(edge, edge, s.z_max - s.z_min), s.density,
                         height_colour(zc, z_low_, z_high_)});
      }
    }
  }
  return boxes;
}

ColumnReport MapScene::column(double x, double y) const {
  ColumnReport r;
  const std::optional<CellKey> key = map_.key_of(x, y);
  if (!key) throw Error("view: (" + std::to_string(x) + ", " + std::to_string(y) + ") is outside the map's domain");
  r.cell = *key;
  r.centre = map_.cell_center(*key);
  const OccupancyParams& op = map_.params().occupancy;
  if (const GroundPatch* patch = ground_.nearest(r.centre.x(), r.centre.y())) {
    // The reach of occupancy_from_map: a patch farther than its square plus ground_reach says
    // nothing about this cell.
    const double dx = std::max(0.0, std::abs(r.centre.x() - patch->center.x()) - patch->half_size);
    const double dy = std::max(0.0, std::abs(r.centre.y() - patch->center.y()) - patch->half_size);
    if (std::max(dx, dy) <= op.ground_reach) r.ground_z = patch->height_at(r.centre.x(), r.centre.y());
  }
  for (const HVoxel& v : map_.column(*key)) {
    ColumnEntry e{v, std::nullopt, std::nullopt};
    if (r.ground_z) {
      e.role = hvoxel_role(v, *r.ground_z, op);
      e.occupancy = inverse_sensor_model(*e.role, v.density, 0.0, op);
    }
    r.hvoxels.push_back(e);
  }
  if (grid_) r.grid_probability = grid_->probability_at(*key);
  return r;
}

const std::string& MapScene::summary_json() const {
  std::call_once(summary_->once, [this] { summary_->json = make_summary_json(); });
  return summary_->json;
}

std::string MapScene::make_summary_json() const {
  nlohmann::json j;
  j["format"] = format_;
  j["cell_size"] = map_.cell_size();
  j["tile_cells"] = kViewTileCells;
  j["levels"] = kLevels;
  j["box_bytes"] = kBoxBytes;
  j["z_range"] = {z_low_, z_high_};
  const MapStats st = map_.stats();
  j["hvoxels"] = st.hvoxels;
  j["cells"] = st.cells;
  if (!st.bounds.isEmpty()) {
    j["bounds"] = {{"min", {st.bounds.min().x(), st.bounds.min().y(), st.bounds.min().z()}},
                   {"max", {st.bounds.max().x(), st.bounds.max().y(), st.bounds.max().z()}}};
  } else {
    j["bounds"] = nullptr;
  }
  // The view tiles holding HVoxels, in (a, b) order, with their count at level 0.
  std::map<std::pair<std::int32_t, std::int32_t>, std::size_t> tiles;
  map_.for_each_column([&](const CellKey& key, const ColumnView& c) {
    const CellKey t = view_tile_of(key);
    tiles[{t.i, t.j}] += c.size();
  });
  nlohmann::json tj = nlohmann::json::array();
  for (const auto& [key, n] : tiles) tj.push_back({key.first, key.second, n});
  j["tiles"] = std::move(tj);
  nlohmann::json gj = nlohmann::json::array();
  for (const GroundPatch& p : ground_.patches()) {
    gj.push_back({p.center.x(), p.center.y(), p.center.z(), p.normal.x(), p.normal.y(), p.normal.z(), p.half_size});
  }
  j["ground"] = std::move(gj);
  nlohmann::json pj = nlohmann::json::array();
  for (const Eigen::Vector3d& p : trajectory_) pj.push_back({p.x(), p.y(), p.z()});
  j["trajectory"] = std::move(pj);
  if (grid_image_.cells.empty()) {
    j["grid"] = nullptr;
  } else {
    j["grid"] = {{"origin", {grid_image_.origin.x(), grid_image_.origin.y()}},
                 {"resolution", grid_image_.resolution},
                 {"width", grid_image_.width},
                 {"height", grid_image_.height}};
  }
  return j.dump();
}

MapScene snapshot(const HMap& map, std::span<const GroundPatch> ground, const OccupancyGrid* grid,
                  std::vector<Eigen::Vector3d> trajectory) {
  HMap copy(map.params());
  map.for_each_column([&](const CellKey& key, const ColumnView& c) {
    auto column = copy.column_for_update(key);
    for (const HVoxel& v : c) column.push_back(v);
  });
  std::optional<OccupancyGrid> grid_copy;
  if (grid != nullptr) {
    grid_copy.emplace(grid->cell_size(), probability(grid->clamp_min_log_odds()), probability(grid->clamp_max_log_odds()));
    grid->for_each_cell([&](const CellKey& key, float l) { grid_copy->set(key, l); });
  }
  return MapScene(std::move(copy), std::vector<GroundPatch>(ground.begin(), ground.end()), std::move(grid_copy),
                  std::move(trajectory));
}

HMap voxels_as_columns(std::span<const Eigen::Vector3d> centres, std::span<const double> probability, double edge) {
  if (centres.size() != probability.size()) throw Error("view: voxel centres and probabilities differ in number");
  Params p;
  p.map.cell_size = edge;
  // Only the cell size matters here; the ranges tied to it are brought along so it validates.
  p.map.max_range = std::min(p.map.max_range, 2000.0 * edge);
  p.map.min_range = std::min(p.map.min_range, 0.5 * p.map.max_range);
  p.slam.coarse_translation = std::min(p.slam.coarse_translation, 100.0 * edge);
  HMap map(p);
  struct Entry {
    CellKey key;
    double z, p;
  };
  std::vector<Entry> voxels;
  voxels.reserve(centres.size());
  for (std::size_t k = 0; k < centres.size(); ++k) {
    const std::optional<CellKey> key = map.key_of(centres[k].x(), centres[k].y());
    if (!key || !std::isfinite(centres[k].z())) throw Error("view: a voxel centre is outside the map's domain");
    voxels.push_back({*key, centres[k].z(), probability[k]});
  }
  std::sort(voxels.begin(), voxels.end(),
            [](const Entry& a, const Entry& b) { return std::tie(a.key.i, a.key.j, a.z) < std::tie(b.key.i, b.key.j, b.z); });
  for (const Entry& v : voxels) {
    auto column = map.column_for_update(v.key);
    const auto lo = static_cast<float>(v.z - 0.495 * edge);
    const auto hi = static_cast<float>(v.z + 0.495 * edge);
    if (!column.empty() && column[column.size() - 1].z_max >= lo) continue;  // the same voxel twice
    column.push_back({lo, hi, 1.0F, static_cast<float>(v.p)});
  }
  return map;
}

std::array<std::uint8_t, 4> height_colour(float z, float z_low, float z_high) {
  static constexpr std::array<std::array<float, 3>, 5> kStops{{
      {0.19F, 0.27F, 0.85F}, {0.10F, 0.75F, 0.90F}, {0.20F, 0.80F, 0.25F}, {0.98F, 0.85F, 0.15F}, {0.90F, 0.15F, 0.10F}}};
  const float span = z_high > z_low ? z_high - z_low : 1.0F;
  float t = std::isfinite(z) ? (z - z_low) / span : 0.0F;
  t = std::clamp(t, 0.0F, 1.0F) * 4.0F;
  const int k = std::min(3, static_cast<int>(t));
  const float f = t - static_cast<float>(k);
  std::array<std::uint8_t, 4> c{0, 0, 0, 255};
  for (int ch = 0; ch < 3; ++ch) {
    const float v = kStops[k][ch] + f * (kStops[k + 1][ch] - kStops[k][ch]);
    c[ch] = static_cast<std::uint8_t>(std::lround(v * 255.0F));
  }
  return c;
}

std::vector<std::uint8_t> encode_boxes(std::span<const Box> boxes) {
  std::vector<std::uint8_t> out(boxes.size() * kBoxBytes);
  std::uint8_t* p = out.data();
  for (const Box& b : boxes) {
    for (int k = 0; k < 3; ++k) put_f32(p + 4 * k, b.centre[k]);
    for (int k = 0; k < 3; ++k) put_f32(p + 12 + 4 * k, b.size[k]);
    put_f32(p + 24, b.density);
    std::memcpy(p + 28, b.rgba.data(), 4);
    p += kBoxBytes;
  }
  return out;
}

std::vector<Box> decode_boxes(std::span<const std::uint8_t> bytes) {
  if (bytes.size() % kBoxBytes != 0) {
    throw Error("view: " + std::to_string(bytes.size()) + " bytes is not a whole number of 32-byte boxes");
  }
  std::vector<Box> boxes(bytes.size() / kBoxBytes);
  const std::uint8_t* p = bytes.data();
  for (Box& b : boxes) {
    for (int k = 0; k < 3; ++k) b.centre[k] = get_f32(p + 4 * k);
    for (int k = 0; k < 3; ++k) b.size[k] = get_f32(p + 12 + 4 * k);
    b.density = get_f32(p + 24);
    std::memcpy(b.rgba.data(), p + 28, 4);
    p += kBoxBytes;
  }
  return boxes;
}

GridImage grid_image(const OccupancyGrid& grid, std::size_t max_cells) {
  const GridRaster r = raster(grid, max_cells);
  GridImage img;
  img.origin = Eigen::Vector2d(r.i_min * r.cell_size, r.j_min * r.cell_size);
  img.resolution = grid.cell_size();
  img.width = r.width;
  img.height = r.height;
  img.cells.resize(r.probability.size());
  for (std::size_t k = 0; k < r.probability.size(); ++k) {
    const float p = r.probability[k];
    img.cells[k] = std::isnan(p) ? kUnknownCell : static_cast<std::uint8_t>(std::lround(std::clamp(p, 0.0F, 1.0F) * 100.0F));
  }
  return img;
}

std::string column_json(const ColumnReport& report) {
  nlohmann::json j;
  j["cell"] = {report.cell.i, report.cell.j};
  j["centre"] = {report.centre.x(), report.centre.y()};
  j["ground_z"] = report.ground_z ? nlohmann::json(*report.ground_z) : nlohmann::json(nullptr);
  j["grid_probability"] = report.grid_probability ? nlohmann::json(*report.grid_probability) : nlohmann::json(nullptr);
  nlohmann::json hv = nlohmann::json::array();
  for (const ColumnEntry& e : report.hvoxels) {
    hv.push_back({{"z_min", e.hvoxel.z_min},
                  {"z_max", e.hvoxel.z_max},
                  {"count", e.hvoxel.count},
                  {"density", e.hvoxel.density},
                  {"role", e.role ? nlohmann::json(role_name(*e.role)) : nlohmann::json(nullptr)},
                  {"occupancy", e.occupancy ? nlohmann::json(*e.occupancy) : nlohmann::json(nullptr)}});
  }
  j["hvoxels"] = std::move(hv);
  return j.dump();
}

}  // namespace hmap::view
