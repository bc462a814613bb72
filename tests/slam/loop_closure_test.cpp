#include "hmap/slam/loop_closure.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>
#include <string>

#include "hmap/core/error.hpp"
#include "hmap/sim/city.hpp"
#include "hmap/sim/sensors.hpp"
#include "hmap/sim/trajectory.hpp"
#include "hmap/slam/hmap_slam.hpp"
#include "common/same_map.hpp"

namespace hmap::slam {
namespace loop_closure_test {

Params loop_params() {
  Params p = outdoor_preset();
  p.map.cell_size = 0.25;
  p.map.max_range = 30.0;
  p.slam.loop_closure = 1;
  p.slam.keyframe_distance = 8.0;
  p.slam.loop_submap_scans = 2;
  p.slam.loop_min_travel = 60.0;
  return p;
}

/// A drive once around one block of a small town (2 × 2 blocks of 40 m), back to the start and
/// 30 m on; VLP-16 scans every 4 m at the true poses; the poses given to the loop closer drift
/// as odometry does (a yaw bias and a height creep per scan).
struct DriftedLoop {
  PoseList truth;
  PoseList drifted;
  std::vector<PointCloud> scans;
};

/// The first `scans` of the drive (all by default): the scans are most of a test's time, four
/// times over under the sanitizers.
DriftedLoop drive(std::size_t scans = std::numeric_limits<std::size_t>::max()) {
  sim::CityParams city;
  city.blocks = 2;
  city.block_size = 40.0;
  const sim::Scene scene = sim::make_city_scene(city);
  const auto route = sim::city_loop_route(city, 150.0, 30.0);
  sim::CarPathParams cp;
  cp.frame_rate = 2.0;  // 4 m apart at 8 m/s
  const sim::Trajectory path = sim::car_path(route, cp);
  DriftedLoop d;
  d.truth = path.T_world_sensor;
  if (d.truth.size() > scans) d.truth.resize(scans);
  sim::SpinningLidarParams lp = sim::SpinningLidarParams::vlp16();
  lp.max_range = 40.0;
  for (std::size_t k = 0; k < d.truth.size(); ++k) {
    lp.seed = 100 + k;
    d.scans.push_back(sim::SpinningLidar(lp).scan(scene, d.truth[k], 0.0).points_sensor);
    if (k == 0) {
      d.drifted.push_back(d.truth[0]);
      continue;
    }
    Pose step = d.truth[k - 1].inverse() * d.truth[k];
    Pose bias = Pose::Identity();
    bias.linear() = Eigen::AngleAxisd(0.004, Eigen::Vector3d::UnitZ()).toRotationMatrix();  // 0.23° per scan
    bias.translation() = Eigen::Vector3d(0.0, 0.0, 0.01);
    d.drifted.push_back(d.drifted.back() * step * bias);
  }
  return d;
}

/// The SLAM's cell centroids of `scans` at `poses`, summed from scratch as HmapSlam sums them:
/// each scan HVoxelised in the level frame of its pose's z, roll and pitch, its tall HVoxels'
/// centroids moved by the pose's x, y and yaw.
CellCentroids centroids_at(const Params& p, const std::vector<PointCloud>& scans, std::span<const Pose> poses) {
  CellCentroids out(p.map.cell_size);
  ScanHVoxelizer level(p.map);
  level.keep_centroids(true);
  ScanHVoxels hvoxels;
  for (std::size_t k = 0; k < scans.size(); ++k) {
    const PlanarPose at = planar_of(poses[k]);
    level.build(scans[k], compose(PlanarPose{}, attitude_of(poses[k])), hvoxels);
    out.add(hvoxels, at.x, at.y, at.yaw, static_cast<float>(p.slam.min_match_height));
  }
  return out;
}

struct SavedCentroid {
  Eigen::Vector2f offset;
  double weight;
};
std::map<std::pair<int, int>, SavedCentroid> cells_of(const CellCentroids& c) {
  std::map<std::pair<int, int>, SavedCentroid> out;
  c.for_each([&](const CellKey& k, const Eigen::Vector2f& o, double w) { out[{k.i, k.j}] = {o, w}; });
  return out;
}

/// The same cells, each with its offset within 1 µm and its weight.
void expect_same_centroids(const CellCentroids& want, const CellCentroids& got) {
  const auto a = cells_of(want);
  const auto b = cells_of(got);
  ASSERT_EQ(a.size(), b.size());
  for (const auto& [key, c] : a) {
    const auto it = b.find(key);
    ASSERT_NE(it, b.end()) << key.first << " " << key.second;
    EXPECT_NEAR(it->second.offset.x(), c.offset.x(), 1e-6F) << key.first << " " << key.second;
    EXPECT_NEAR(it->second.offset.y(), c.offset.y(), 1e-6F) << key.first << " " << key.second;
    EXPECT_EQ(it->second.weight, c.weight) << key.first << " " << key.second;
  }
}

double planar_error(const Pose& a, const Pose& b) { return (a.translation() - b.translation()).head<2>().norm(); }

TEST(LoopClosure, ASmallSimulatedLoopClosesAndTheEndErrorFalls) {
  const DriftedLoop d = drive();
  ASSERT_GT(d.truth.size(), 40u);
  const double drifted_end = planar_error(d.drifted.back(), d.truth.back());
  ASSERT_GT(drifted_end, 2.0);  // the drift the loop must remove

  LoopCloser closer(loop_params());
  for (std::size_t k = 0; k < d.scans.size(); ++k) closer.add_scan(d.scans[k], d.drifted[k]);
  const LoopClosureResult r = closer.close();
  ASSERT_FALSE(r.closures.empty());
  EXPECT_GT(r.keyframes, 15u);
  // Each accepted closure measured the true relative pose of its key frames.
  for (const LoopClosure& c : r.closures) {
    const Pose T = d.truth[c.scan_old].inverse() * d.truth[c.scan_new];
    EXPECT_NEAR(c.T_old_new.x, T.translation().x(), 0.25) << c.scan_old << " " << c.scan_new;
    EXPECT_NEAR(c.T_old_new.y, T.translation().y(), 0.25);
    EXPECT_NEAR(c.T_old_new.yaw, std::atan2(T.linear()(1, 0), T.linear()(0, 0)), 0.02);
    EXPECT_GE(c.score, loop_params().slam.loop_min_score);
  }
  ASSERT_TRUE(r.graph.ran);
  ASSERT_EQ(r.T_map_sensor.size(), d.truth.size());
  const double corrected_end = planar_error(r.T_map_sensor.back(), d.truth.back());
  // The heading drifted before the first key frame the loop ties (0.03 rad by scan 7) is not
  // observable: the end keeps about that much of its error.
  EXPECT_LT(corrected_end, 1.5);
  EXPECT_LT(corrected_end, 0.2 * drifted_end);
  // Where the loop ties the path to itself, the corrected poses agree with each other as the
  // true ones do.
  for (const LoopClosure& c : r.closures) {
    const Pose want = d.truth[c.scan_old].inverse() * d.truth[c.scan_new];
    const Pose got = r.T_map_sensor[c.scan_old].inverse() * r.T_map_sensor[c.scan_new];
    const Pose before = d.drifted[c.scan_old].inverse() * d.drifted[c.scan_new];
    EXPECT_LT((got.translation() - want.translation()).head<2>().norm(), 0.3);
    EXPECT_GT((before.translation() - want.translation()).head<2>().norm(), 3.0);
  }
  EXPECT_NEAR(r.end_correction, (r.T_map_sensor.back().translation() - d.drifted.back().translation()).norm(), 1e-9);
  // The height creep is taken out too.
  EXPECT_LT(std::abs(r.T_map_sensor.back().translation().z() - d.truth.back().translation().z()),
            0.3 * std::abs(d.drifted.back().translation().z() - d.truth.back().translation().z()));
  // The first scan defines the frame and stays.
  EXPECT_TRUE(r.T_map_sensor.front().isApprox(d.drifted.front()));

  // The map at the corrected poses: rebuilt where the moved scans reach, it holds what the whole
  // map rebuilt at the result's poses does; the scans the graph left within a tenth of a cell
  // (the first ones, before the closed loop's first key frame) keep their pose and are not read.
  const Params p = loop_params();
  Mapper built(p);
  for (std::size_t k = 0; k < d.scans.size(); ++k) (void)built.integrate(d.scans[k], d.drifted[k]);
  std::size_t read = 0;
  const auto scan = [&](std::size_t k, PointCloud& out) {
    ++read;
    out = d.scans[k];
  };
  const TileRebuild tiles = map_at_corrected_poses(p, &built.map(), d.drifted, r.T_map_sensor, scan);
  EXPECT_FALSE(tiles.whole);
  EXPECT_GT(tiles.scans_moved, 0u);
  EXPECT_LT(tiles.scans_moved, d.scans.size());
  EXPECT_EQ(tiles.scans_integrated, read);
  test::expect_same_columns(rebuild_map(p, tiles.T_map_sensor, scan), tiles.map);
  for (std::size_t k = 0; k < d.scans.size(); ++k) {
    const double moved = pose_displacement_bound(d.drifted[k], r.T_map_sensor[k], p.map.max_range);
    EXPECT_TRUE(tiles.T_map_sensor[k].isApprox(moved > p.map.cell_size / 10.0 ? r.T_map_sensor[k] : d.drifted[k])) << k;
  }
  EXPECT_FALSE(tiles.centroids.has_value());  // none given
  // Without the built map, all of it is rebuilt at the corrected poses.
  const TileRebuild whole = map_at_corrected_poses(p, nullptr, d.drifted, r.T_map_sensor, scan);
  EXPECT_TRUE(whole.whole);
  EXPECT_EQ(whole.scans_integrated, d.scans.size());
  EXPECT_EQ(whole.scans_moved, tiles.scans_moved);
  for (std::size_t k = 0; k < d.scans.size(); ++k) EXPECT_TRUE(whole.T_map_sensor[k].isApprox(r.T_map_sensor[k]));

  // The SLAM's cell centroids, summed at the drifted poses, come back as if summed at the result's
  // poses from the start: summed again from the scans read in the rebuilt tiles, kept elsewhere.
  const CellCentroids built_centroids = centroids_at(p, d.scans, d.drifted);
  const TileRebuild with = map_at_corrected_poses(p, &built.map(), d.drifted, r.T_map_sensor, scan, &built_centroids);
  ASSERT_TRUE(with.centroids.has_value());
  EXPECT_EQ(with.scans_integrated, tiles.scans_integrated);  // no scan read twice for them
  test::expect_same_columns(tiles.map, with.map);
  const CellCentroids want = centroids_at(p, d.scans, with.T_map_sensor);
  expect_same_centroids(want, *with.centroids);
  // The correction moved them: the drift was metres.
  const auto before = cells_of(built_centroids);
  std::size_t moved = 0;
  with.centroids->for_each([&](const CellKey& k, const Eigen::Vector2f& o, double) {
    const auto it = before.find({k.i, k.j});
    moved += it == before.end() || (it->second.offset - o).norm() > 0.01F ? 1 : 0;
  });
  EXPECT_GT(moved, with.centroids->size() / 4);
  const TileRebuild whole_with = map_at_corrected_poses(p, nullptr, d.drifted, r.T_map_sensor, scan, &built_centroids);
  ASSERT_TRUE(whole_with.centroids.has_value());
  expect_same_centroids(centroids_at(p, d.scans, r.T_map_sensor), *whole_with.centroids);
  // Not kept when the SLAM does not match at centroids; refused for another cell size.
  Params cell_centres = p;
  cell_centres.slam.hvoxel_centroids = 0;
  EXPECT_FALSE(map_at_corrected_poses(cell_centres, &built.map(), d.drifted, r.T_map_sensor, scan, &built_centroids)
                   .centroids.has_value());
  const CellCentroids other(0.1);
  EXPECT_THROW((void)map_at_corrected_poses(p, &built.map(), d.drifted, r.T_map_sensor, scan, &other), Error);
}

// Only the last 3 of 20 scans (76 m of the drive, round a corner) moved: the centroids of the
// tiles they cannot reach, at the start, are the built ones bit for bit; all of them are as if
// summed at the new poses.
TEST(LoopClosure, CentroidsOfTilesNoMovedScanReachesAreKept) {
  const DriftedLoop d = drive(20);
  const Params p = loop_params();
  Mapper built(p);
  for (std::size_t k = 0; k < d.scans.size(); ++k) (void)built.integrate(d.scans[k], d.truth[k]);
  PoseList corrected = d.truth;
  for (std::size_t k = 17; k < corrected.size(); ++k) corrected[k].translation() += Eigen::Vector3d(0.3, -0.2, 0.0);
  const CellCentroids built_centroids = centroids_at(p, d.scans, d.truth);
  std::size_t read = 0;
  const TileRebuild r = map_at_corrected_poses(p, &built.map(), d.truth, corrected,
                                               [&](std::size_t k, PointCloud& out) {
                                                 ++read;
                                                 out = d.scans[k];
                                               }, &built_centroids);
  ASSERT_TRUE(r.centroids.has_value());
  EXPECT_EQ(r.scans_moved, 3u);
  EXPECT_EQ(read, r.scans_integrated);  // read once, for the map and the centroids
  expect_same_centroids(centroids_at(p, d.scans, corrected), *r.centroids);
  const auto before = cells_of(built_centroids);
  std::size_t kept = 0;
  std::size_t rebuilt = 0;
  r.centroids->for_each([&](const CellKey& k, const Eigen::Vector2f& o, double w) {
    if (r.rebuilt.contains(HMap::tile_of(k))) {
      ++rebuilt;
      return;
    }
    const auto it = before.find({k.i, k.j});
    ASSERT_NE(it, before.end());
    EXPECT_EQ(it->second.offset, o);
    EXPECT_EQ(it->second.weight, w);
    ++kept;
  });
  EXPECT_GT(kept, 20u);
  EXPECT_GT(rebuilt, 100u);
}

TEST(LoopClosure, AStraightDriveClosesNothingAndChangesNothing) {
  const DriftedLoop d = drive(10);
  LoopCloser closer(loop_params());
  // The first 40 m only: nothing far enough back along the path to revisit.
  for (std::size_t k = 0; k < 10; ++k) closer.add_scan(d.scans[k], d.drifted[k]);
  const LoopClosureResult r = closer.close();
  EXPECT_TRUE(r.closures.empty());
  EXPECT_FALSE(r.graph.ran);
  for (std::size_t k = 0; k < 10; ++k) EXPECT_TRUE(r.T_map_sensor[k].isApprox(d.drifted[k]));
  EXPECT_EQ(r.max_correction, 0.0);
  // No scan at all.
  LoopCloser none(loop_params());
  EXPECT_TRUE(none.close().T_map_sensor.empty());
}

TEST(LoopClosure, RebuildsTheMapAtTheGivenPoses) {
  const DriftedLoop d = drive(5);
  const Params p = loop_params();
  Mapper direct(p);
  for (std::size_t k = 0; k < 5; ++k) (void)direct.integrate(d.scans[k], d.truth[k]);
  const HMap rebuilt = rebuild_map(p, std::span<const Pose>(d.truth.data(), 5),
                                   [&](std::size_t k, PointCloud& out) { out = d.scans[k]; });
  EXPECT_EQ(rebuilt.stats().hvoxels, direct.map().stats().hvoxels);
  EXPECT_EQ(rebuilt.stats().cells, direct.map().stats().cells);
}

TEST(LoopClosure, BadParametersAreRefusedNamingThem) {
  const auto refused = [](auto change, const std::string& name) {
    Params p = loop_params();
    change(p);
    try {
      LoopCloser closer(p);
      ADD_FAILURE() << name << " accepted";
    } catch (const Error& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find(name), std::string::npos) << what;
      EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    }
  };
  refused([](Params& p) { p.slam.keyframe_distance = 0.0; }, "slam.keyframe_distance");
  refused([](Params& p) { p.slam.keyframe_rotation = -0.1; }, "slam.keyframe_rotation");
  refused([](Params& p) { p.slam.loop_closure = 2; }, "slam.loop_closure");
  refused([](Params& p) { p.slam.loop_min_score = 1.5; }, "slam.loop_min_score");
  refused([](Params& p) { p.slam.loop_max_descriptor_distance = 0.0; }, "slam.loop_max_descriptor_distance");
  refused([](Params& p) { p.slam.loop_submap_scans = 0; }, "slam.loop_submap_scans");
  refused([](Params& p) { p.slam.loop_search_translation = 30.0; }, "slam.loop_search_translation");
  // A small cell does not make the default search refused: it is searched over 100 cells at most.
  Params small = loop_params();
  small.map.cell_size = 0.02;
  EXPECT_NO_THROW(LoopCloser{small});
}

}  // namespace loop_closure_test
}  // namespace hmap::slam
