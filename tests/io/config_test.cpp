// Parameter files on bad input (the cases the config fuzz target found are kept here too, in
// fuzz/regressions/config/).
#include "hmap/io/config.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <utility>

#include "hmap/core/format.hpp"
#include "hmap/core/params.hpp"
#include "io/io_test_util.hpp"

namespace hmap {
namespace {

class ConfigTest : public test::IoTest {
 protected:
  /// The message of the InputError that applying `yaml` throws ("" when it is accepted).
  std::string error(std::string_view yaml) {
    Params params;
    try {
      apply_config_file(write("p.yaml", yaml), params);
    } catch (const InputError& e) {
      return e.what();
    }
    return "";
  }
};

TEST_F(ConfigTest, ReadsNestedAndFlatNames) {
  Params params;
  apply_config_file(write("p.yaml", "preset: indoor\nmap:\n  cell_size: 0.2\nground.iterations: 12\n"), params);
  EXPECT_EQ(params.map.cell_size, 0.2);
  EXPECT_EQ(params.ground.iterations, 12);
}

TEST_F(ConfigTest, ARecursiveAliasIsRefusedNotRecursedForever) {
  // Found by fuzzing: a map that holds itself made apply_node recurse until the stack overflowed.
  const std::string message = error("a: &x {b: *x}\n");
  EXPECT_NE(message.find("p.yaml: line 1: 'a.b.b.b' nests sections too deep"), std::string::npos) << message;
}

TEST_F(ConfigTest, YamlErrorsStayOneLine) {
  // Found by fuzzing: yaml-cpp quotes the offending character in its message, here a control
  // character after a backslash; it is written as \xNN.
  const std::string message = error("x: \"\\\x01\"\n");
  EXPECT_NE(message.find("p.yaml: line 1: YAML syntax error"), std::string::npos) << message;
  EXPECT_NE(message.find("\\x01"), std::string::npos) << message;
  EXPECT_EQ(message.find('\x01'), std::string::npos) << message;
}

TEST_F(ConfigTest, IntegersOutOfRangeAreRefusedByName) {
  const std::string message = error("ground:\n  iterations: 4294967696\n");
  EXPECT_NE(message.find("ground.iterations = 4294967696 must be an integer"), std::string::npos) << message;
  EXPECT_NE(error("map.free_space: 256\n").find("map.free_space"), std::string::npos);
}

TEST_F(ConfigTest, AbsurdValuesAreRefusedByName) {
  EXPECT_NE(error("map: {cell_size: 0.000001}\n").find("map.cell_size"), std::string::npos);
  EXPECT_NE(error("map: {max_range: 1000000000}\n").find("map.max_range"), std::string::npos);
}

TEST(SetParamTest, SetsAndGetsByNameWithTheOverridesMessages) {
  Params p;
  set_param(p, "map.cell_size", 0.2);
  EXPECT_EQ(p.map.cell_size, 0.2);
  EXPECT_EQ(get_param(p, "map.cell_size"), 0.2);
  set_param(p, "ground.iterations", 99.6);  // integer fields round, as apply_override does
  EXPECT_EQ(p.ground.iterations, 100);
  EXPECT_EQ(get_param(p, "ground.iterations"), 100.0);
  const auto message = [&](auto&& f) {
    try {
      f();
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_EQ(message([&] { set_param(p, "map.cell", 0.2); }).rfind("unknown parameter 'map.cell' (known: map.cell_size, ", 0), 0U);
  EXPECT_EQ(message([&] { (void)get_param(p, "nope"); }).rfind("unknown parameter 'nope' (known: ", 0), 0U);
  EXPECT_EQ(message([&] { set_param(p, "map.cell_size", std::nan("")); }),
            "parameter 'map.cell_size' needs a finite number, got 'nan'");
  EXPECT_EQ(p.map.cell_size, 0.2);
}

/// A room's worth of points: 2000 within 3 m of the sensor, as a depth camera sees.
PointCloud near_scan() {
  PointCloud points;
  for (int i = 0; i < 2000; ++i) {
    const double a = 0.01 * i;
    points.emplace_back(static_cast<float>(2.0 * std::cos(a)), static_cast<float>(2.0 * std::sin(a)),
                        static_cast<float>(-1.0 + 0.001 * i));
  }
  return points;
}

TEST(ResolveParamsForScanTest, NoPresetNamedTheScanChoosesIt) {
  ParamSources sources;
  sources.preset = "";
  sources.cell_size = 0.07;
  sources.values = {{"slam.imu_roll", 0.25}};
  const ScanParams chosen = resolve_params_for_scan(sources, near_scan());
  EXPECT_EQ(chosen.preset, "indoor");
  EXPECT_FALSE(chosen.preset_reason.empty());
  EXPECT_EQ(chosen.params.map.max_range, indoor_preset().map.max_range);
  EXPECT_EQ(chosen.params.map.cell_size, 0.07);  // the named value over the preset's
  EXPECT_EQ(chosen.params.slam.imu_roll, 0.25);  // `values`, set last
}

/// A spinning LiDAR in a room, by hand: 16 rings 2° apart (−15° to +15°), a point every degree
/// all around, 8 m away.
PointCloud lidar_in_a_room() {
  PointCloud points;
  for (int ring = 0; ring < 16; ++ring) {
    const double el = (-15.0 + 2.0 * ring) * std::numbers::pi / 180.0;
    for (int a = 0; a < 360; ++a) {
      const double az = (a + 0.5) * std::numbers::pi / 180.0;
      points.emplace_back(static_cast<float>(8.0 * std::cos(el) * std::cos(az)),
                          static_cast<float>(8.0 * std::cos(el) * std::sin(az)), static_cast<float>(8.0 * std::sin(el)));
    }
  }
  return points;
}

TEST(ResolveParamsForScanTest, ALidarInARoomTakesTheRoomCellAndKeepsItsReach) {
  ParamSources sources;
  sources.preset = "";
  const ScanParams chosen = resolve_params_for_scan(sources, lidar_in_a_room());
  EXPECT_EQ(chosen.preset, "room");
  EXPECT_EQ(chosen.params.map.cell_size, 0.1);
  // The LiDAR's, not the room preset's 10 m: its 2° rings lie map.ring_gap_max (3 m) apart on a
  // wall at 3 / slope, 3 / 0.0384 = 78.1 m (the spacing is read in 0.05° bins: 77-78 m), held to
  // 512 cells of 0.1 m each way of the scan window, 51.2 m.
  const double slope = chosen.params.map.ring_gap_slope;
  EXPECT_EQ(chosen.params.map.max_range, 51.2);
  ASSERT_FALSE(chosen.adapted.empty());
  EXPECT_EQ(chosen.adapted[0].name, "map.max_range");
  EXPECT_NE(chosen.adapted[0].reason.find(format("a LiDAR (16 rings 2.00 deg apart): its rings lie map.ring_gap_max "
                                                 "= 3 m apart on a wall %.0f m away (held to 512 cells each way of "
                                                 "the scan window)",
                                                 std::floor(3.0 / slope))),
            std::string::npos)
      << chosen.adapted[0].reason;
  // 2° rings are 0.35 m apart at the room's 10 m: the preset's 0.4 m gap stays there, and grows
  // beyond it by 1.1 · tan 2° per metre.
  EXPECT_EQ(chosen.params.map.point_distance_threshold, 0.4);
  ASSERT_EQ(chosen.adapted.size(), 2U);
  EXPECT_EQ(chosen.adapted[1].name, "map.ring_gap_slope");
  EXPECT_NEAR(chosen.params.map.ring_gap_slope, 0.0384, 0.001);
  // A gap the user names stands, even at the preset's value: `--set map.ring_gap_slope=0` keeps
  // one gap for every cell, and so does a threshold named at the preset's 0.4 m (by --set or a value).
  for (const auto& [overrides, values] :
       {std::pair<std::vector<std::string>, std::vector<std::pair<std::string, double>>>{{"map.ring_gap_slope=0"}, {}},
        {{"map.point_distance_threshold=0.4"}, {}},
        {{}, {{"map.ring_gap_slope", 0.0}}}}) {
    ParamSources gap = sources;
    gap.overrides = overrides;
    gap.values = values;
    const ScanParams one_gap = resolve_params_for_scan(gap, lidar_in_a_room());
    EXPECT_EQ(one_gap.params.map.ring_gap_slope, 0.0);
    EXPECT_EQ(one_gap.params.map.point_distance_threshold, 0.4);
    EXPECT_EQ(one_gap.params.map.max_range, chosen.params.map.max_range);  // the range is still the LiDAR's
  }
  // A smaller most gap the user names brings the range in with it (1.5 / 0.0384 = 39 m), not under
  // the outdoor preset's 25 m: 0.5 / 0.0384 = 13 m.
  ParamSources most = sources;
  most.overrides = {"map.ring_gap_max=1.5"};
  EXPECT_EQ(resolve_params_for_scan(most, lidar_in_a_room()).params.map.max_range, std::floor(1.5 / slope));
  most.overrides = {"map.ring_gap_max=0.5"};
  EXPECT_EQ(resolve_params_for_scan(most, lidar_in_a_room()).params.map.max_range, 25.0);
  // A range the user names stands, by flag or by --set, even at the preset's value; so does a named
  // preset's.
  ParamSources flag = sources;
  flag.max_range = 10.0;
  EXPECT_EQ(resolve_params_for_scan(flag, lidar_in_a_room()).params.map.max_range, 10.0);
  ParamSources set = sources;
  set.overrides = {"map.max_range=10"};
  EXPECT_EQ(resolve_params_for_scan(set, lidar_in_a_room()).params.map.max_range, 10.0);
  ParamSources named = sources;
  named.preset = "room";
  EXPECT_EQ(resolve_params_for_scan(named, lidar_in_a_room()).params.map.max_range, 10.0);
  // The same points seen through a 70° window (a depth camera's view) are no LiDAR: the room's 10 m.
  PointCloud window;
  for (const Point3f& q : lidar_in_a_room()) {
    if (std::abs(std::atan2(q.y(), q.x())) < 0.6) window.push_back(q);
  }
  const ScanParams narrow = resolve_params_for_scan(sources, window);
  EXPECT_EQ(narrow.preset, "room");
  EXPECT_EQ(narrow.params.map.max_range, 10.0);
}

TEST(ResolveParamsForScanTest, ANamedPresetStandsAndSaysNoReason) {
  ParamSources sources;
  sources.preset = "outdoor";
  const ScanParams chosen = resolve_params_for_scan(sources, near_scan());
  EXPECT_EQ(chosen.preset, "outdoor");
  EXPECT_TRUE(chosen.preset_reason.empty());
  EXPECT_EQ(chosen.params.map.max_range, outdoor_preset().map.max_range);
  sources.values = {{"map.cell_size", -1.0}};
  EXPECT_THROW((void)resolve_params_for_scan(sources, near_scan()), Error);  // validated
}

}  // namespace
}  // namespace hmap
