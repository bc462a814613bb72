#include "hmap/occupancy/grid_reading.hpp"

#include <gtest/gtest.h>

#include "hmap/occupancy/occupancy_grid.hpp"

namespace hmap {
namespace {

TEST(GridReadingTest, MapServersDefaultsAndTheMapsOwn) {
  const GridReading map_server;
  EXPECT_EQ(map_server.classify(0.9), CellClass::kOccupied);
  EXPECT_EQ(map_server.classify(0.65), CellClass::kUndecided);  // occupied only above
  EXPECT_EQ(map_server.classify(0.196), CellClass::kFree);
  EXPECT_EQ(map_server.classify(0.25), CellClass::kUndecided);
  EXPECT_EQ(map_server.classify(probability(log_odds(0.3))), CellClass::kUndecided);
  // K_g = 0.3: one clear pass, read back from its float log-odds, is free; 0.4 is not.
  const GridReading own = GridReading::for_map(outdoor_preset().occupancy);
  EXPECT_DOUBLE_EQ(own.free_at_most, 0.3);
  EXPECT_EQ(own.classify(probability(log_odds(0.3))), CellClass::kFree);
  EXPECT_EQ(own.classify(probability(log_odds(0.4))), CellClass::kUndecided);
  EXPECT_EQ(own.classify(0.66), CellClass::kOccupied);
  // Never stricter than map_server's: a small K_g keeps 0.196.
  OccupancyParams small;
  small.ground_gain = 0.1;
  EXPECT_DOUBLE_EQ(GridReading::for_map(small).free_at_most, 0.196);
}

}  // namespace
}  // namespace hmap
