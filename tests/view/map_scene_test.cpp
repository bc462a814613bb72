// The viewer's encoding (src/hmap/view/map_scene.hpp) on a tiny map built here: every figure
// below is worked out by hand from the map's HVoxels, then checked again against the HMap API.

#include "hmap/view/map_scene.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <random>

#include "hmap/core/error.hpp"

namespace hmap::view {
namespace {

Params tiny_params() {
  Params p;
  p.map.cell_size = 0.5;
  p.occupancy.ground_gain = 0.3;      // K_g
  p.occupancy.ground_distance = 0.1;  // d_pth
  p.occupancy.z_plus = 2.0;
  p.occupancy.z_minus = -0.5;
  p.occupancy.ground_reach = 0.25;  // [m] beyond a patch's square: cell (-1, -1) is 0.5 m out
  return p;
}

HVoxel hv(float z_min, float z_max, float count, float density) { return {z_min, z_max, count, density}; }

/// Cell (1, 2): a floor HVoxel [0, 0.05] and a shelf [1.5, 2.0]; cell (1, 3): a box [0, 0.2];
/// cell (-1, -1): a post [0.5, 1.0]. Cell size 0.5 m, so z spans [0, 2].
HMap tiny_map() {
  HMap map(tiny_params());
  auto c12 = map.column_for_update({1, 2});
  c12.push_back(hv(0.0F, 0.05F, 10.0F, 0.9F));
  c12.push_back(hv(1.5F, 2.0F, 4.0F, 0.7F));
  map.column_for_update({1, 3}).push_back(hv(0.0F, 0.2F, 6.0F, 0.8F));
  map.column_for_update({-1, -1}).push_back(hv(0.5F, 1.0F, 3.0F, 0.6F));
  return map;
}

MapScene tiny_scene(std::vector<GroundPatch> ground = {}, std::optional<OccupancyGrid> grid = std::nullopt) {
  return MapScene(tiny_map(), std::move(ground), std::move(grid), {{0.0, 0.0, 0.5}, {1.0, 0.5, 0.5}});
}

TEST(HeightColour, EndsAndMidpointsOfTheRamp) {
  EXPECT_EQ(height_colour(0.0F, 0.0F, 2.0F), (std::array<std::uint8_t, 4>{48, 69, 217, 255}));   // 0.19 0.27 0.85
  EXPECT_EQ(height_colour(2.0F, 0.0F, 2.0F), (std::array<std::uint8_t, 4>{230, 38, 26, 255}));   // 0.90 0.15 0.10
  EXPECT_EQ(height_colour(9.0F, 0.0F, 2.0F), height_colour(2.0F, 0.0F, 2.0F));                   // clamped
  // z = 0.25 of [0, 2]: halfway between the first two stops: 0.145 0.51 0.875.
  EXPECT_EQ(height_colour(0.25F, 0.0F, 2.0F), (std::array<std::uint8_t, 4>{37, 130, 223, 255}));
}

TEST(ViewTile, FloorDivisionOfCellKeys) {
  EXPECT_EQ(view_tile_of({0, 63}), (CellKey{0, 0}));
  EXPECT_EQ(view_tile_of({64, -1}), (CellKey{1, -1}));
  EXPECT_EQ(view_tile_of({-64, -65}), (CellKey{-1, -2}));
}

TEST(MapSceneTest, LevelZeroIsOneBoxPerHVoxel) {
  const MapScene scene = tiny_scene();
  EXPECT_FLOAT_EQ(scene.z_low(), 0.0F);
  EXPECT_FLOAT_EQ(scene.z_high(), 2.0F);
  std::vector<Box> boxes = scene.tile_boxes({0, 0}, 0);
  ASSERT_EQ(boxes.size(), 3U);
  std::sort(boxes.begin(), boxes.end(), [](const Box& a, const Box& b) {
    return std::tie(a.centre.y(), a.centre.z()) < std::tie(b.centre.y(), b.centre.z());
  });
  // Cell (1, 2) spans x [0.5, 1.0], y [1.0, 1.5].
  EXPECT_EQ(boxes[0].centre, Eigen::Vector3f(0.75F, 1.25F, 0.025F));
  EXPECT_EQ(boxes[0].size, Eigen::Vector3f(0.5F, 0.5F, 0.05F));
  EXPECT_FLOAT_EQ(boxes[0].density, 0.9F);
  EXPECT_EQ(boxes[1].centre, Eigen::Vector3f(0.75F, 1.25F, 1.75F));
  EXPECT_EQ(boxes[1].size, Eigen::Vector3f(0.5F, 0.5F, 0.5F));
  EXPECT_EQ(boxes[1].rgba, height_colour(1.75F, 0.0F, 2.0F));
  EXPECT_EQ(boxes[2].centre, Eigen::Vector3f(0.75F, 1.75F, 0.1F));
  // The negative cell is in tile (-1, -1), centred at (-0.25, -0.25).
  const std::vector<Box> neg = scene.tile_boxes({-1, -1}, 0);
  ASSERT_EQ(neg.size(), 1U);
  EXPECT_EQ(neg[0].centre, Eigen::Vector3f(-0.25F, -0.25F, 0.75F));
  EXPECT_TRUE(scene.tile_boxes({5, 5}, 0).empty());
}

TEST(MapSceneTest, CoarseLevelsUniteABlocksHVoxels) {
  const MapScene scene = tiny_scene();
  // Level 1: blocks of 2 × 2 cells (1 m). Cells (1, 2) and (1, 3) share block (0..1, 2..3):
  // [0, 0.05], [0, 0.2] and [1.5, 2.0]; 1.5 <= 0.2 + 1.0 is false, so two boxes:
  // [0, 0.2] and [1.5, 2.0], centred on the block (0.5, 1.5).
  std::vector<Box> boxes = scene.tile_boxes({0, 0}, 1);
  ASSERT_EQ(boxes.size(), 2U);
  std::sort(boxes.begin(), boxes.end(), [](const Box& a, const Box& b) { return a.centre.z() < b.centre.z(); });
  EXPECT_EQ(boxes[0].centre, Eigen::Vector3f(0.5F, 1.5F, 0.1F));
  EXPECT_EQ(boxes[0].size, Eigen::Vector3f(1.0F, 1.0F, 0.2F));
  EXPECT_FLOAT_EQ(boxes[0].density, 0.9F);  // the largest united
  EXPECT_EQ(boxes[1].centre, Eigen::Vector3f(0.5F, 1.5F, 1.75F));
  // Level 2: blocks of 2 m: 1.5 <= 0.2 + 2.0, so one box [0, 2] at the block centre (1, 1).
  boxes = scene.tile_boxes({0, 0}, 2);
  ASSERT_EQ(boxes.size(), 1U);
  EXPECT_EQ(boxes[0].centre, Eigen::Vector3f(1.0F, 1.0F, 1.0F));
  EXPECT_EQ(boxes[0].size, Eigen::Vector3f(2.0F, 2.0F, 2.0F));
  EXPECT_THROW((void)scene.tile_boxes({0, 0}, kLevels), Error);
  EXPECT_THROW((void)scene.tile_boxes({0, 0}, -1), Error);
}

TEST(BoxRecords, BytesAreTheDocumentedLayout) {
  const Box box{Eigen::Vector3f(0.75F, -2.0F, 1.0F), Eigen::Vector3f(0.5F, 0.5F, 0.25F), 0.5F, {1, 2, 3, 255}};
  const std::vector<std::uint8_t> bytes = encode_boxes(std::span(&box, 1));
  ASSERT_EQ(bytes.size(), 32U);
  // 0.75f = 0x3F400000, -2.0f = 0xC0000000, 1.0f = 0x3F800000, little-endian.
  EXPECT_EQ((std::vector<std::uint8_t>(bytes.begin(), bytes.begin() + 12)),
            (std::vector<std::uint8_t>{0, 0, 0x40, 0x3F, 0, 0, 0, 0xC0, 0, 0, 0x80, 0x3F}));
  EXPECT_EQ(bytes[24 + 3], 0x3F);  // density 0.5f = 0x3F000000
  EXPECT_EQ((std::vector<std::uint8_t>(bytes.begin() + 28, bytes.end())), (std::vector<std::uint8_t>{1, 2, 3, 255}));
  EXPECT_EQ(decode_boxes(bytes), std::vector<Box>{box});
  EXPECT_TRUE(decode_boxes({}).empty());
  const std::vector<std::uint8_t> torn(33, 0);
  EXPECT_THROW((void)decode_boxes(torn), Error);
}

// The brute-force twin: level 0 decodes to exactly the HVoxels the map's columns hold.
TEST(BoxRecords, LevelZeroDecodesToTheMapsHVoxels) {
  HMap map(tiny_params());
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> cell(-100, 100);
  std::uniform_real_distribution<float> z(-3.0F, 3.0F);
  for (int n = 0; n < 500; ++n) {
    const float lo = z(rng);
    map.column_for_update({cell(rng), cell(rng)}).merge(hv(lo, lo + 0.3F, 1.0F, 0.5F), 0.2F, map.params().map);
  }
  const MapStats st = map.stats();
  const MapScene scene(std::move(map), {}, std::nullopt, {});
  std::size_t seen = 0;
  for (int a = -2; a <= 1; ++a) {
    for (int b = -2; b <= 1; ++b) {
      for (const Box& box : decode_boxes(encode_boxes(scene.tile_boxes({a, b}, 0)))) {
        const ColumnView c = scene.map().column(box.centre.x(), box.centre.y());
        const HVoxel* v = c.find(box.centre.z());
        ASSERT_NE(v, nullptr);
        EXPECT_FLOAT_EQ(box.centre.z(), 0.5F * (v->z_min + v->z_max));
        EXPECT_FLOAT_EQ(box.size.z(), v->z_max - v->z_min);
        EXPECT_EQ(CellKey(view_tile_of(*scene.map().key_of(box.centre.x(), box.centre.y()))), (CellKey{a, b}));
        ++seen;
      }
    }
  }
  EXPECT_EQ(seen, st.hvoxels);
}

TEST(MapSceneTest, ColumnReadsTheHVoxelsByEq4) {
  // A flat ground patch at z = 0 over the cells.
  const GroundPatch ground{Eigen::Vector3d(0.75, 1.25, 0.0), Eigen::Vector3d::UnitZ(), 1.0, -1};
  OccupancyGrid grid(0.5, 0.12, 0.97);
  grid.set({1, 2}, log_odds(0.97));
  const MapScene scene = tiny_scene({ground}, std::move(grid));
  const ColumnReport r = scene.column(0.6, 1.4);  // inside cell (1, 2)
  EXPECT_EQ(r.cell, (CellKey{1, 2}));
  EXPECT_EQ(r.centre, Eigen::Vector2d(0.75, 1.25));
  ASSERT_TRUE(r.ground_z);
  EXPECT_DOUBLE_EQ(*r.ground_z, 0.0);
  ASSERT_EQ(r.hvoxels.size(), 2U);
  EXPECT_EQ(r.hvoxels[0].hvoxel, hv(0.0F, 0.05F, 10.0F, 0.9F));
  EXPECT_EQ(r.hvoxels[0].role, HVoxelRole::kGround);  // top 0.05 within d_pth = 0.1
  EXPECT_NEAR(*r.hvoxels[0].occupancy, 0.4, 1e-12);    // K_g + (0.5 − K_g)/2 at δ = 0
  EXPECT_EQ(r.hvoxels[1].role, HVoxelRole::kObstacle);
  EXPECT_NEAR(*r.hvoxels[1].occupancy, 0.7, 1e-6);     // max(ρ, 0.5)
  EXPECT_NEAR(*r.grid_probability, 0.97, 1e-6);

  const nlohmann::json j = nlohmann::json::parse(column_json(r));
  EXPECT_EQ(j["cell"], nlohmann::json({1, 2}));
  ASSERT_EQ(j["hvoxels"].size(), 2U);
  EXPECT_FLOAT_EQ(j["hvoxels"][1]["z_min"].get<float>(), 1.5F);
  EXPECT_FLOAT_EQ(j["hvoxels"][1]["count"].get<float>(), 4.0F);
  EXPECT_EQ(j["hvoxels"][0]["role"], "ground");

  // Far from any patch (beyond its square and ground_reach): no role, no occupancy.
  const ColumnReport far = scene.column(-0.2, -0.2);
  EXPECT_FALSE(far.ground_z);
  ASSERT_EQ(far.hvoxels.size(), 1U);
  EXPECT_FALSE(far.hvoxels[0].role);
  EXPECT_TRUE(nlohmann::json::parse(column_json(far))["hvoxels"][0]["occupancy"].is_null());
  EXPECT_TRUE(scene.column(30.0, 30.0).hvoxels.empty());
  EXPECT_THROW((void)scene.column(std::nan(""), 0.0), Error);
}

TEST(GridImageTest, OneBytePerCellOverTheKnownBox) {
  OccupancyGrid grid(0.5, 0.12, 0.97);
  grid.set({0, 0}, 0.0F);               // p = 0.5
  grid.set({2, 1}, log_odds(0.97));     // p = 0.97
  const GridImage img = grid_image(grid);
  EXPECT_EQ(img.width, 3);
  EXPECT_EQ(img.height, 2);
  EXPECT_EQ(img.origin, Eigen::Vector2d(0.0, 0.0));
  EXPECT_DOUBLE_EQ(img.resolution, 0.5);
  // Row 0 is j = 0: (0, 0) 50, then unknown; row 1 is j = 1: unknown, unknown, (2, 1) 97.
  EXPECT_EQ(img.cells, (std::vector<std::uint8_t>{50, 255, 255, 255, 255, 97}));
}

TEST(MapSceneTest, SummaryListsTilesLayersAndFrames) {
  OccupancyGrid grid(0.5, 0.12, 0.97);
  grid.set({-2, 3}, 0.0F);
  const MapScene scene = tiny_scene({}, std::move(grid));
  const nlohmann::json j = nlohmann::json::parse(scene.summary_json());
  EXPECT_EQ(j["hvoxels"], 4);
  EXPECT_EQ(j["tile_cells"], kViewTileCells);
  EXPECT_EQ(j["tiles"], nlohmann::json::parse("[[-1, -1, 1], [0, 0, 3]]"));
  EXPECT_EQ(j["z_range"], nlohmann::json({0.0, 2.0}));
  EXPECT_EQ(j["trajectory"].size(), 2U);
  EXPECT_TRUE(j["ground"].empty());
  EXPECT_EQ(j["grid"]["origin"], nlohmann::json({-1.0, 1.5}));
  EXPECT_EQ(j["grid"]["width"], 1);
  EXPECT_EQ(scene.grid_image().cells, std::vector<std::uint8_t>{50});
  // An empty map still describes itself.
  const MapScene empty(HMap(tiny_params()), {}, std::nullopt, {});
  const nlohmann::json e = nlohmann::json::parse(empty.summary_json());
  EXPECT_TRUE(e["tiles"].empty());
  EXPECT_TRUE(e["bounds"].is_null());
  EXPECT_TRUE(e["grid"].is_null());
}

}  // namespace
}  // namespace hmap::view

namespace hmap::view {
namespace {

TEST(VoxelsAsColumns, EachVoxelAnHVoxelOfItsCellWithItsProbability) {
  // Edge 0.5: two voxels stacked in cell (0, 0), one in cell (-1, 2), one given twice.
  const std::vector<Eigen::Vector3d> centres{{0.25, 0.25, 1.25}, {0.25, 0.25, 0.75}, {-0.25, 1.25, 0.25}, {0.25, 0.25, 0.75}};
  const std::vector<double> p{0.9, 0.6, 0.75, 0.6};
  const HMap map = voxels_as_columns(centres, p, 0.5);
  EXPECT_DOUBLE_EQ(map.cell_size(), 0.5);
  EXPECT_EQ(map.stats().hvoxels, 3U);
  const ColumnView c = map.column({0, 0});
  ASSERT_EQ(c.size(), 2U);
  EXPECT_TRUE(c.is_valid());  // 0.99 of the edge high: stacked voxels do not touch
  EXPECT_FLOAT_EQ(c[0].z_min, 0.5025F);  // 0.75 − 0.495 · 0.5
  EXPECT_FLOAT_EQ(c[0].z_max, 0.9975F);
  EXPECT_FLOAT_EQ(c[0].density, 0.6F);
  EXPECT_FLOAT_EQ(c[1].density, 0.9F);
  EXPECT_FLOAT_EQ(map.column({-1, 2})[0].density, 0.75F);
  const MapScene scene(voxels_as_columns(centres, p, 0.5), {}, std::nullopt, {}, "pvox");
  EXPECT_EQ(nlohmann::json::parse(scene.summary_json())["format"], "pvox");
  EXPECT_TRUE(voxels_as_columns({}, {}, 0.1).empty());
  EXPECT_THROW((void)voxels_as_columns(centres, std::vector<double>{0.5}, 0.5), Error);
  EXPECT_THROW((void)voxels_as_columns(centres, p, -1.0), Error);
}

}  // namespace
}  // namespace hmap::view

namespace hmap::view {
namespace {

TEST(Snapshot, CopiesTheMapGroundAndGrid) {
  HMap map(tiny_params());
  map.column_for_update({3, -4}).push_back(hv(0.0F, 1.0F, 5.0F, 0.8F));
  OccupancyGrid grid(0.5, 0.12, 0.97);
  grid.set({3, -4}, log_odds(0.97));
  const GroundPatch patch{Eigen::Vector3d(1.0, -2.0, 0.0), Eigen::Vector3d::UnitZ(), 0.5, -1};
  const MapScene s = snapshot(map, std::span(&patch, 1), &grid, {{1.0, 2.0, 3.0}});
  map.column_for_update({3, -4}).push_back(hv(2.0F, 3.0F, 5.0F, 0.8F));  // the original changes later
  EXPECT_EQ(s.map().stats().hvoxels, 1U);
  EXPECT_EQ(s.map().column({3, -4})[0], hv(0.0F, 1.0F, 5.0F, 0.8F));
  EXPECT_EQ(s.ground().size(), 1U);
  EXPECT_NEAR(*s.grid()->probability_at({3, -4}), 0.97, 1e-6);
  EXPECT_EQ(s.grid()->known_cells(), 1U);
  EXPECT_EQ(s.trajectory().size(), 1U);
  EXPECT_EQ(snapshot(map, {}, nullptr, {}).grid(), std::nullopt);
}

}  // namespace
}  // namespace hmap::view
