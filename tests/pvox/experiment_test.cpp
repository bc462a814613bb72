#include "hmap/pvox/boxes_experiment.hpp"

#include <gtest/gtest.h>

#include <random>

#include "hmap/pvox/mapper.hpp"
#include "hmap/pvox/measure.hpp"
#include "hmap/pvox/serialize.hpp"

namespace hmap::pvox {
namespace {

// The seed's experiment end to end at a small size (0.5° beams, 91 sweep steps; at 1° and 61 steps
// the 120 mm front of box A is one voxel row holding single scan lines, which are no plane): RBF
// registers every position to a few millimetres and the ruler finds all nine edges on its map;
// BRF drifts.
TEST(BoxesExperiment, RunsEndToEndAtASmallSize) {
  BoxesExperimentParams sp;
  sp.seed = 4;
  sp.angular_step_deg = 0.5;
  sp.sweep_steps = 91;
  const BoxesRecording rec = simulate_boxes(sp);
  ASSERT_EQ(rec.scans.size(), 5U);
  EXPECT_EQ(rec.T_world_true[0].translation(), rec.T_world_nominal[0].translation());
  EXPECT_GT((rec.T_world_true[4].translation() - rec.T_world_nominal[4].translation()).norm(), 0.0);

  double average[2] = {0.0, 0.0};
  double worst_position_error[2] = {0.0, 0.0};
  for (const FilterKind kind : {FilterKind::kRecursive, FilterKind::kNaive}) {
    PvoxParams p;
    p.filter.kind = kind;
    p.insert.min_range = 0.1;
    p.insert.max_range = 30.0;
    PvoxMapper mapper(p);
    const int f = kind == FilterKind::kRecursive ? 0 : 1;
    for (std::size_t k = 0; k < rec.scans.size(); ++k) {
      const auto r = mapper.add_scan(rec.scans[k], rec.commands[k]);
      const double error = (r.T_map_sensor.translation() - rec.T_world_true[k].translation()).norm();
      worst_position_error[f] = std::max(worst_position_error[f], error);
    }
    const auto edges = measure_boxes(mapper.map()).edges;
    ASSERT_EQ(edges.size(), 9U);
    EXPECT_EQ(edges[0].name, "AB");
    EXPECT_EQ(edges[8].name, "JK");
    average[f] = summarize_accuracy(edges).mean;
    if (kind == FilterKind::kRecursive) {
      for (const auto& e : edges) EXPECT_TRUE(e.measured.has_value()) << e.name;
      // The binary map is far smaller than the raw points.
      EXPECT_LT(encode_binary(mapper.map()).size() * 5, rec.scans.size() * rec.scans[0].size() * 24);
    }
  }
  EXPECT_LT(worst_position_error[0], 0.01);
  EXPECT_GT(worst_position_error[1], 0.05);
  EXPECT_GT(average[0], 0.9);
  EXPECT_GT(average[0], average[1]);
}

/// The boxes scene's visible faces sampled every 10 mm with 2 mm noise on each coordinate (fixed seed), into voxels
/// of 58.6 mm; `skip` names a face left out.
VoxelMap sampled_boxes_scene(const std::string& skip = "") {
  VoxelMap map(0.0586);
  std::mt19937 rng(11);
  std::normal_distribution<double> noise(0.0, 0.002);
  struct Rect {
    std::string name;
    int axis;
    double c;
    double u0, u1, v0, v1;  // on the other axes in order (x: y, z; y: x, z; z: x, y)
  };
  const std::vector<Rect> rects = {
      {"floor", 2, -1.0, -0.75, 0.75, 0.0, 2.7},         {"ceiling", 2, 1.0, -0.75, 0.75, 0.0, 2.7},
      {"left wall", 0, -0.75, 0.0, 2.7, -1.0, 1.0},      {"right wall", 0, 0.75, 0.0, 2.7, -1.0, 1.0},
      {"front wall", 1, 0.0, -0.75, 0.75, -1.0, 1.0},    {"back wall", 1, 2.7, -0.75, 0.75, -1.0, 1.0},
      {"top A", 2, -0.88, -0.45, -0.12, 0.935, 1.15},    {"front A", 1, 0.935, -0.45, -0.12, -1.0, -0.88},
      {"back A", 1, 1.15, -0.45, -0.12, -1.0, -0.88},    {"right A", 0, -0.12, 0.935, 1.15, -1.0, -0.88},
      {"top B", 2, -0.215, -0.45, -0.08, 2.05, 2.125},   {"front B", 1, 2.05, -0.45, -0.08, -1.0, -0.215},
      {"back B", 1, 2.125, -0.45, -0.08, -1.0, -0.215},  {"right B", 0, -0.08, 2.05, 2.125, -1.0, -0.215},
  };
  for (const Rect& r : rects) {
    if (r.name == skip) continue;
    const int u = r.axis == 0 ? 1 : 0;
    const int v = r.axis == 2 ? 1 : 2;
    for (double a = r.u0; a <= r.u1 + 1e-9; a += 0.01) {
      for (double b = r.v0; b <= r.v1 + 1e-9; b += 0.01) {
        Eigen::Vector3d p;
        p[r.axis] = r.c + noise(rng);
        p[u] = a + noise(rng);
        p[v] = b + noise(rng);
        map.add_hit(p);
      }
    }
  }
  return map;
}

// The ruler on a map of the scene's true faces: every edge measured, planes to 2 mm and face ends
// to a quarter of a voxel (measure_test.cpp), so every length within 2·0.25·58.6 = 29 mm and the
// planes' differences (AE, EG, GH, CF, JK) within 4 mm.
TEST(BoxesExperiment, MeasuresTheTrueFacesFromTheMapAlone) {
  const VoxelMap map = sampled_boxes_scene();
  const BoxesMeasurement m = measure_boxes(map);
  ASSERT_EQ(m.edges.size(), 9U);
  for (const auto& e : m.edges) {
    ASSERT_TRUE(e.measured.has_value()) << e.name << " missing " << e.missing;
    const bool planes_only = e.name == "AE" || e.name == "EG" || e.name == "GH" || e.name == "CF" || e.name == "JK";
    EXPECT_NEAR(*e.measured, e.true_length, planes_only ? 0.004 : 0.5 * map.edge()) << e.name << ": " << e.how;
  }
  const AccuracySummary s = summarize_accuracy(m.edges);
  EXPECT_EQ(s.measured, 9U);
  EXPECT_EQ(s.missing, 0U);
  EXPECT_GT(s.mean, 0.95);
  // Every face the sensor could see is matched; the boxes' left sides (x = −0.45) were not sampled.
  for (const auto& f : m.faces) EXPECT_EQ(f.plane.has_value(), f.name != "left sides of boxes A, B (x)") << f.name;
}

// Without the back of box B, the four edges that need it (CF, FI, IJ, JK) are reported missing (not measured on
// the front of B or the back wall), and the summary says so: 5 measured, 4 missing.
TEST(BoxesExperiment, AMissingFaceMakesItsEdgesMissing) {
  const BoxesMeasurement m = measure_boxes(sampled_boxes_scene("back B"));
  std::vector<std::string> missing;
  for (const auto& e : m.edges) {
    if (!e.measured) {
      missing.push_back(e.name);
      EXPECT_NE(e.missing.find("back of box B"), std::string::npos) << e.name << ": " << e.missing;
    }
  }
  EXPECT_EQ(missing, (std::vector<std::string>{"CF", "FI", "IJ", "JK"}));
  const AccuracySummary s = summarize_accuracy(m.edges);
  EXPECT_EQ(s.measured, 5U);
  EXPECT_EQ(s.missing, 4U);
}

TEST(BoxesExperiment, SummaryOfNoEdges) {
  const AccuracySummary s = summarize_accuracy({});
  EXPECT_EQ(s.measured, 0U);
  EXPECT_EQ(s.missing, 0U);
  EXPECT_EQ(s.mean, 0.0);
  // An empty map: every face missing, every edge missing.
  const BoxesMeasurement m = measure_boxes(VoxelMap(0.0586));
  EXPECT_EQ(summarize_accuracy(m.edges).missing, 9U);
  for (const auto& f : m.faces) EXPECT_FALSE(f.plane.has_value()) << f.name;
}

}  // namespace
}  // namespace hmap::pvox
