#include "hmap/occupancy/exported_grid.hpp"

#include <gtest/gtest.h>

#include <optional>

#include "hmap/core/error.hpp"

namespace hmap {
namespace {

// A 4 m × 4 m floor at z = 0 in 0.1 m cells with a wall column at (1.05, 1.05), one flat patch
// under it all, and a kept grid that disagrees with the columns at the wall (free) and holds a
// cell the map has no column for.
class ExportedGridTest : public ::testing::Test {
 protected:
  ExportedGridTest() : map_(params()), kept_(0.1, 0.12, 0.97) {
    for (int i = -20; i < 20; ++i) {
      for (int j = -20; j < 20; ++j) {
        TileColumn c = map_.column_for_update({i, j});
        c.insert(0, HVoxel{0.0F, 0.01F, 10.0F, 0.9F});
      }
    }
    wall_ = *map_.key_of(1.05, 1.05);
    TileColumn w = map_.column_for_update(wall_);
    w.insert(1, HVoxel{0.3F, 1.5F, 10.0F, 0.9F});
    floor_ = *map_.key_of(-1.05, 0.55);
    kept_.update(wall_, -2.0F);   // the kept grid says free where the wall stands
    kept_.update(floor_, -2.0F);  // and free on the floor, as the columns do
    kept_.update(outside_, 1.0F);  // a cell the map holds no column for
    ground_.push_back(GroundPatch{{0.0, 0.0, 0.0}, {0.0, 0.0, 1.0}, 100.0, -1});
  }
  static Params params() {
    Params p = indoor_preset();
    p.map.cell_size = 0.1;
    return p;
  }
  HMap map_;
  OccupancyGrid kept_;
  std::vector<GroundPatch> ground_;
  CellKey wall_{}, floor_{};
  CellKey outside_{100, 100};
};

TEST_F(ExportedGridTest, KeptJudgedAndBothCellByCell) {
  ExportGridParams p;
  p.source = GridSource::kKept;
  const ExportedGrid kept = export_grid(map_, ground_, &kept_, p);
  EXPECT_FALSE(kept.derived);
  EXPECT_EQ(kept.grid.known_cells(), 3U);
  EXPECT_EQ(kept.grid.log_odds_at(wall_), kept_.log_odds_at(wall_));
  EXPECT_EQ(kept.grid.log_odds_at(outside_), kept_.log_odds_at(outside_));

  p.source = GridSource::kJudged;
  const ExportedGrid judged = export_grid(map_, ground_, &kept_, p);
  EXPECT_EQ(judged.grid.log_odds_at(wall_), std::optional<float>(judged.grid.clamp_max_log_odds()));
  EXPECT_EQ(judged.grid.log_odds_at(floor_), std::optional<float>(judged.grid.clamp_min_log_odds()));
  EXPECT_FALSE(judged.grid.log_odds_at(outside_).has_value());

  p.source = GridSource::kBoth;  // the default: the more occupied of the two per cell
  const ExportedGrid both = export_grid(map_, ground_, &kept_, p);
  EXPECT_EQ(both.grid.log_odds_at(wall_), judged.grid.log_odds_at(wall_));
  EXPECT_EQ(both.grid.log_odds_at(outside_), kept_.log_odds_at(outside_));
  EXPECT_EQ(both.grid.known_cells(), judged.grid.known_cells() + 1);
  EXPECT_EQ(both.ground.size(), 1U);
}

TEST_F(ExportedGridTest, WithoutAKeptGridOneIsDerivedFromTheColumns) {
  for (const bool rederive : {false, true}) {
    ExportGridParams p;
    p.rederive = rederive;
    p.ground_hint = Eigen::Vector3d(0.0, 0.0, 0.2);
    const ExportedGrid g = export_grid(map_, {}, rederive ? &kept_ : nullptr, p);
    EXPECT_TRUE(g.derived);
    ASSERT_TRUE(g.ground_found);
    EXPECT_GT(g.ground.size(), 1U);
    EXPECT_EQ(g.grid.log_odds_at(wall_), std::optional<float>(g.grid.clamp_max_log_odds()));
    EXPECT_EQ(g.grid.log_odds_at(floor_), std::optional<float>(g.grid.clamp_min_log_odds()));
    EXPECT_FALSE(g.grid.log_odds_at(outside_).has_value());
  }
  // No ground near a hint 50 m off the map: said, not thrown, and the grid left empty.
  ExportGridParams high;
  high.ground_hint = Eigen::Vector3d(50.0, 50.0, 0.2);
  const ExportedGrid none = export_grid(map_, {}, nullptr, high);
  EXPECT_FALSE(none.ground_found);
  EXPECT_EQ(none.grid.known_cells(), 0U);
}

TEST_F(ExportedGridTest, EmptyMapsAndBadParametersAreRefused) {
  EXPECT_THROW((void)export_grid(HMap(params()), {}, nullptr), Error);
  ExportGridParams p;
  p.ground_iterations = -1;
  EXPECT_THROW((void)export_grid(map_, ground_, &kept_, p), Error);
  p.ground_iterations = 0;
  p.ground_hint = Eigen::Vector3d(0.0, std::nan(""), 0.0);
  EXPECT_THROW((void)export_grid(map_, ground_, &kept_, p), Error);
  EXPECT_EQ(parse_grid_source("both"), GridSource::kBoth);
  EXPECT_EQ(parse_grid_source("judged"), GridSource::kJudged);
  EXPECT_FALSE(parse_grid_source("Both").has_value());
}

}  // namespace
}  // namespace hmap
