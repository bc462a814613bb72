#include "hmap/slam/loop_closure.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <optional>

#include "hmap/core/error.hpp"
#include "hmap/core/format.hpp"
#include "hmap/slam/hmap_slam.hpp"
#include "hmap/slam/map_align.hpp"

namespace hmap::slam {

namespace {

// Odometry edges between key frames: σ = base + growth · (metres travelled), per axis; yaw
// σ = base + growth · (metres) + turn growth · (radians turned). Loop edges: fixed σ. What matters
// is their ratio: a loop edge is worth the odometry of about 20 m.
constexpr double kOdometrySigmaBase = 0.05;        // [m]
constexpr double kOdometrySigmaPerMetre = 0.01;    // [-]
constexpr double kOdometryYawBase = 0.005;         // [rad]
constexpr double kOdometryYawPerMetre = 0.001;     // [rad/m]
constexpr double kOdometryYawPerRadian = 0.01;     // [-]
constexpr double kLoopSigmaTranslation = 0.1;      // [m]
constexpr double kLoopSigmaYaw = 0.01;             // [rad]
// The descriptor's grid: rings over the sub-map's reach, 6° sectors.
constexpr int kRings = 20;
constexpr int kSectors = 60;

GraphPose graph_pose(const Pose& T) {
  const PlanarPose p = planar_of(T);
  return {p.x, p.y, T.translation().z(), p.yaw};
}

double wrap(double a) { return std::remainder(a, 2.0 * std::numbers::pi); }

/// Rz(yaw) · R and the translation moved by the planar + z correction `c` (applied in the map frame).
Pose corrected(const GraphPose& c, const Pose& T) {
  Pose out = T;
  const Eigen::Matrix3d Rz = Eigen::AngleAxisd(c.yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  out.linear() = Rz * T.linear();
  out.translation() = Rz * T.translation() + Eigen::Vector3d(c.x, c.y, c.z);
  return out;
}

/// The correction that moves `before` onto `after`: after = correction ⊕ before.
GraphPose correction_of(const GraphPose& before, const GraphPose& after) {
  const double yaw = wrap(after.yaw - before.yaw);
  const double c = std::cos(yaw);
  const double s = std::sin(yaw);
  return {after.x - (c * before.x - s * before.y), after.y - (s * before.x + c * before.y), after.z - before.z, yaw};
}

}  // namespace

struct LoopCloser::State {
  struct KeyFrame {
    std::size_t scan = 0;
    GraphPose pose;          // of the sensor at the key frame's scan, as estimated
    Pose T_map_level;        // the sub-map's frame: the key frame's x, y, z and yaw, level
    double path = 0.0;       // [m] along the estimated path
    // The sub-map while its scans come (the mapper's scan buffers are megabytes), then the map alone.
    std::unique_ptr<Mapper> builder;
    std::optional<HMap> submap;
    int submap_scans = 0;
    PlaceDescriptor descriptor;
  };

  Params params;
  std::vector<KeyFrame> keyframes;
  PoseList poses;            // every scan's estimate
  std::vector<double> path;  // [m] along the estimated path, per scan
  std::vector<LoopClosure> closures;
  std::size_t verified = 0;

  void finish_keyframe(std::size_t k);
  void search_loops(std::size_t k);
};

LoopCloser::LoopCloser(const Params& params) : state_(std::make_unique<State>()) {
  validate(params);
  state_->params = params;
}
LoopCloser::~LoopCloser() = default;
LoopCloser::LoopCloser(LoopCloser&&) noexcept = default;
LoopCloser& LoopCloser::operator=(LoopCloser&&) noexcept = default;

std::size_t LoopCloser::keyframes() const { return state_->keyframes.size(); }
const std::vector<LoopClosure>& LoopCloser::closures() const { return state_->closures; }

void LoopCloser::add_scan(std::span<const Point3f> points_sensor, const Pose& T_map_sensor) {
  State& s = *state_;
  const auto& sp = s.params.slam;
  const GraphPose pose = graph_pose(T_map_sensor);
  s.path.push_back(s.poses.empty() ? 0.0 : s.path.back() + (T_map_sensor.translation() - s.poses.back().translation()).norm());
  s.poses.push_back(T_map_sensor);
  const std::size_t scan = s.poses.size() - 1;
  bool start = s.keyframes.empty();
  if (!start) {
    const auto& last = s.keyframes.back();
    start = s.path.back() - last.path >= sp.keyframe_distance || std::abs(wrap(pose.yaw - last.pose.yaw)) >= sp.keyframe_rotation;
  }
  if (start) {
    if (!s.keyframes.empty()) s.finish_keyframe(s.keyframes.size() - 1);
    State::KeyFrame kf;
    kf.scan = scan;
    kf.pose = pose;
    kf.path = s.path.back();
    kf.T_map_level = Pose::Identity();
    kf.T_map_level.linear() = Eigen::AngleAxisd(pose.yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    kf.T_map_level.translation() = T_map_sensor.translation();
    // Occupied HVoxels only: over a few consecutive scans carving free space changes little of
    // what the descriptor and the alignment see, and cost as much again as the SLAM's own update
    // (parking long route: 61.5 ms per key frame with it).
    Params submap_params = s.params;
    submap_params.map.free_space = FreeSpaceMode::kNone;
    kf.builder = std::make_unique<Mapper>(submap_params);
    s.keyframes.push_back(std::move(kf));
  }
  State::KeyFrame& kf = s.keyframes.back();
  if (kf.builder && kf.submap_scans < sp.loop_submap_scans) {
    (void)kf.builder->integrate(points_sensor, kf.T_map_level.inverse() * T_map_sensor);
    ++kf.submap_scans;
  }
}

void LoopCloser::State::finish_keyframe(std::size_t k) {
  KeyFrame& kf = keyframes[k];
  if (kf.submap) return;
  kf.submap.emplace(std::move(kf.builder->map()));
  kf.builder.reset();
  kf.descriptor = describe_place(*kf.submap, {}, {params.map.max_range, kRings, kSectors});
  search_loops(k);
}

void LoopCloser::State::search_loops(std::size_t k) {
  const auto& sp = params.slam;
  KeyFrame& now = keyframes[k];
  if (now.submap->empty()) return;
  // Candidates: far back along the path, near the drifted estimate, near in descriptor.
  struct Candidate {
    std::size_t keyframe;
    PlaceMatch match;
  };
  std::vector<Candidate> candidates;
  for (std::size_t j = 0; j < k; ++j) {
    const KeyFrame& old = keyframes[j];
    if (now.path - old.path < sp.loop_min_travel) break;  // key frames are in path order
    if (std::hypot(now.pose.x - old.pose.x, now.pose.y - old.pose.y) > sp.loop_search_radius) continue;
    if (old.submap->empty()) continue;
    const PlaceMatch m = compare_places(old.descriptor, now.descriptor);
    if (m.distance <= sp.loop_max_descriptor_distance) candidates.push_back({j, m});
  }
  std::sort(candidates.begin(), candidates.end(),
            [](const Candidate& a, const Candidate& b) { return a.match.distance < b.match.distance; });
  if (candidates.size() > static_cast<std::size_t>(sp.loop_candidates)) candidates.resize(static_cast<std::size_t>(sp.loop_candidates));
  // Verification: the new sub-map aligned onto the old one from the descriptor's yaw.
  for (const Candidate& c : candidates) {
    const KeyFrame& old = keyframes[c.keyframe];
    MapAlignOptions options;
    options.guess = {0.0, 0.0, 0.0, c.match.yaw};
    // The coarse search walks (2n + 1)² cells' positions: align_maps takes at most 100 cells, so
    // that a small cell (--cell 0.02) does not make the default 4 m refused.
    options.search_translation = std::min(sp.loop_search_translation, 100.0 * params.map.cell_size);
    options.search_rotation = sp.loop_search_rotation;
    ++verified;
    MapAlignResult r;
    try {
      r = align_maps(*old.submap, *now.submap, options);
    } catch (const Error&) {
      continue;  // no overlap at the guess: no match
    }
    if (r.match.skipped || r.match.score < sp.loop_min_score) continue;
    // A result at the edge of the search window is the window's best, not a match.
    if (options.search_translation > 0.0 &&
        std::max(std::abs(r.shift.x), std::abs(r.shift.y)) > options.search_translation - params.map.cell_size) {
      continue;
    }
    LoopClosure closure;
    closure.keyframe_old = c.keyframe;
    closure.keyframe_new = k;
    closure.scan_old = old.scan;
    closure.scan_new = now.scan;
    closure.descriptor_distance = c.match.distance;
    closure.descriptor_yaw = c.match.yaw;
    closure.score = r.match.score;
    closure.T_old_new = {r.shift.x, r.shift.y, r.shift.z, r.shift.yaw};
    const GraphPose drifted = relative(old.pose, now.pose);
    closure.drift_translation = std::hypot(drifted.x - r.shift.x, drifted.y - r.shift.y);
    closure.drift_yaw = std::abs(wrap(drifted.yaw - r.shift.yaw));
    closures.push_back(closure);
    break;  // one loop edge per key frame
  }
}

LoopClosureResult LoopCloser::close() {
  State& s = *state_;
  if (!s.keyframes.empty()) s.finish_keyframe(s.keyframes.size() - 1);
  LoopClosureResult result;
  result.T_map_sensor = s.poses;
  result.closures = s.closures;
  result.keyframes = s.keyframes.size();
  result.candidates_verified = s.verified;
  if (s.closures.empty()) return result;

  // The pose graph: odometry edges between consecutive key frames, the loop edges.
  std::vector<GraphPose> nodes;
  for (const auto& kf : s.keyframes) nodes.push_back(kf.pose);
  std::vector<GraphEdge> edges;
  for (std::size_t k = 1; k < nodes.size(); ++k) {
    const double metres = s.keyframes[k].path - s.keyframes[k - 1].path;
    GraphEdge e{k - 1, k, relative(nodes[k - 1], nodes[k])};
    const double sigma = kOdometrySigmaBase + kOdometrySigmaPerMetre * metres;
    e.sigma = {sigma, sigma, sigma, kOdometryYawBase + kOdometryYawPerMetre * metres + kOdometryYawPerRadian * std::abs(e.T_from_to.yaw)};
    edges.push_back(e);
  }
  for (const LoopClosure& c : s.closures) {
    GraphEdge e{c.keyframe_old, c.keyframe_new, c.T_old_new};
    e.sigma = {kLoopSigmaTranslation, kLoopSigmaTranslation, kLoopSigmaTranslation, kLoopSigmaYaw};
    e.loss = EdgeLoss::kCauchy;
    edges.push_back(e);
  }
  result.graph = optimize_pose_graph(nodes, edges);

  // Each scan's correction: its key frame's and the next one's, blended by the path between them.
  std::vector<GraphPose> corrections(nodes.size());
  for (std::size_t k = 0; k < nodes.size(); ++k) corrections[k] = correction_of(nodes[k], result.graph.poses[k]);
  std::size_t kf = 0;
  for (std::size_t j = 0; j < s.poses.size(); ++j) {
    while (kf + 1 < s.keyframes.size() && s.keyframes[kf + 1].scan <= j) ++kf;
    GraphPose c = corrections[kf];
    if (kf + 1 < s.keyframes.size()) {
      const double span = s.keyframes[kf + 1].path - s.keyframes[kf].path;
      const double t = span > 0.0 ? std::clamp((s.path[j] - s.keyframes[kf].path) / span, 0.0, 1.0) : 0.0;
      const Pose a = corrected(corrections[kf], s.poses[j]);
      const Pose b = corrected(corrections[kf + 1], s.poses[j]);
      const double yaw = corrections[kf].yaw + t * wrap(corrections[kf + 1].yaw - corrections[kf].yaw);
      Pose T = corrected({0.0, 0.0, 0.0, yaw}, s.poses[j]);
      T.translation() = (1.0 - t) * a.translation() + t * b.translation();
      result.T_map_sensor[j] = T;
    } else {
      result.T_map_sensor[j] = corrected(c, s.poses[j]);
    }
    const double moved = (result.T_map_sensor[j].translation() - s.poses[j].translation()).norm();
    result.max_correction = std::max(result.max_correction, moved);
    if (j + 1 == s.poses.size()) result.end_correction = moved;
  }
  return result;
}

HMap rebuild_map(const Params& params, std::span<const Pose> T_map_sensor,
                 const std::function<void(std::size_t, PointCloud&)>& scan, const RebuiltScan& integrated) {
  Mapper mapper(params);
  PointCloud points;
  for (std::size_t k = 0; k < T_map_sensor.size(); ++k) {
    points.clear();
    scan(k, points);
    (void)mapper.integrate(points, T_map_sensor[k]);
    if (integrated) integrated(k, points, T_map_sensor[k]);
  }
  return std::move(mapper.map());
}

TileRebuild map_at_corrected_poses(const Params& params, const HMap* built, std::span<const Pose> T_built,
                                   std::span<const Pose> T_corrected,
                                   const std::function<void(std::size_t, PointCloud&)>& scan,
                                   const CellCentroids* centroids) {
  if (centroids != nullptr && params.slam.hvoxel_centroids < 2) centroids = nullptr;
  if (centroids != nullptr && centroids->cell_size() != params.map.cell_size) {
    throw Error(format("rebuilding the cell centroids: they are of %g m cells, the map of %g m", centroids->cell_size(),
                       params.map.cell_size));
  }
  // The centroids of the scans read again, as HmapSlam sums them: in the level frame of the
  // pose's attitude, moved into the map by its planar part.
  std::optional<CellCentroids> fresh;
  ScanHVoxelizer level(params.map);
  ScanHVoxels hvoxels;
  RebuiltScan add_centroids;
  if (centroids != nullptr) {
    fresh.emplace(params.map.cell_size);
    level.keep_centroids(true);
    add_centroids = [&](std::size_t, const PointCloud& points, const Pose& T) {
      const PlanarPose at = planar_of(T);
      level.build(points, compose(PlanarPose{}, attitude_of(T)), hvoxels);
      fresh->add(hvoxels, at.x, at.y, at.yaw, static_cast<float>(params.slam.min_match_height));
    };
  }
  const auto whole_map = [&] {
    TileRebuild w{rebuild_map(params, T_corrected, scan, add_centroids), PoseList(T_corrected.begin(), T_corrected.end())};
    w.whole = true;
    for (std::size_t k = 0; k < T_corrected.size(); ++k) {
      const bool moved = k >= T_built.size() ||
                         pose_displacement_bound(T_built[k], T_corrected[k], params.map.max_range) > params.map.cell_size / 10.0;
      w.scans_moved += moved ? 1 : 0;
    }
    w.scans_integrated = T_corrected.size();
    w.tiles_rebuilt = w.map.stats().tiles;
    return w;
  };
  TileRebuild out = built != nullptr
                        ? rebuild_moved_tiles(*built, T_built, T_corrected, params.map.cell_size / 10.0, scan, add_centroids)
                        : whole_map();
  if (centroids != nullptr) {
    // The rebuilt tiles' centroids from the scans read again; the others' as they were.
    out.centroids.emplace(params.map.cell_size);
    const auto rebuilt = [&](const CellKey& cell) { return out.whole || out.rebuilt.contains(HMap::tile_of(cell)); };
    centroids->for_each([&](const CellKey& cell, const Eigen::Vector2f& offset, double weight) {
      if (!rebuilt(cell)) out.centroids->restore(cell, offset, weight);
    });
    fresh->for_each([&](const CellKey& cell, const Eigen::Vector2f& offset, double weight) {
      if (rebuilt(cell)) out.centroids->restore(cell, offset, weight);
    });
  }
  return out;
}

}  // namespace hmap::slam
