#include "hmap/slam/map_align.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "hmap/core/error.hpp"
#include "hmap/maps/mapper.hpp"
#include "hmap/sim/composites.hpp"
#include "hmap/sim/scene.hpp"
#include "hmap/sim/sensors.hpp"

namespace hmap::slam {
namespace map_align_test {

sim::Scene yard() {
  using sim::Box;
  using sim::Cylinder;
  using sim::SurfaceKind;
  sim::SceneBuilder b;
  b.add("ground", sim::make_ground({-25, -20}, {25, 20}, 0.0));
  b.add("north", sim::make_wall({-20, 15}, {20, 15}, 3.0));
  b.add("south", sim::make_wall({-20, -15}, {12, -15}, 4.0));
  b.add("west", sim::make_wall({-20, -15}, {-20, 15}, 2.5));
  b.add("east", sim::make_wall({20, -8}, {20, 15}, 3.5));
  for (int k = 0; k < 5; ++k) {
    b.add("pillar", {{Cylinder{{-12.0 + 6.0 * k, 6.0 + (k % 2) * 2.0}, 0.0, 3.0, 0.3}, SurfaceKind::kPillar}});
  }
  b.add("box1", {{Box{{4, -6, 0.6}, {1.0, 0.5, 0.6}, 0.4}, SurfaceKind::kBox}});
  b.add("kiosk", {{Box{{10, 4, 1.5}, {2.0, 1.5, 1.5}, 0.0}, SurfaceKind::kWall}});
  return b.build();
}

Params params() {
  Params p = outdoor_preset();
  p.map.cell_size = 0.2;
  p.map.max_range = 30.0;
  return p;
}

Pose at(double x, double y, double yaw) {
  Pose T = Pose::Identity();
  T.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(x, y, 1.8);
  return T;
}

/// The map of VLP-16 scans taken at `truth`, their poses written in a frame `S` away (S · T).
HMap session(const sim::Scene& scene, const std::vector<Pose>& truth, const Pose& S, std::uint64_t seed) {
  Mapper mapper(params());
  for (const Pose& T : truth) {
    sim::SpinningLidarParams lp = sim::SpinningLidarParams::vlp16();
    lp.seed = seed++;
    const PointCloud pts = sim::SpinningLidar(lp).scan(scene, T, 0.0).points_sensor;
    mapper.integrate(pts, S * T);
  }
  return std::move(mapper.map());
}

TEST(MapAlign, RecoversAKnownShiftBetweenTwoSessions) {
  const sim::Scene scene = yard();
  const HMap a = session(scene, {at(0, 0, 0), at(4, 1, 0.3), at(-5, 3, -0.4)}, Pose::Identity(), 1);
  Pose S = Pose::Identity();
  S.linear() = Eigen::AngleAxisd(12.0 * std::numbers::pi / 180.0, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  S.translation() = Eigen::Vector3d(1.1, -0.6, 0.15);
  const HMap b = session(scene, {at(2, -2, 0.8), at(-3, 0, 2.0), at(6, 5, -1.0)}, S, 10);
  // b's frame in a's is S⁻¹.
  const Pose want = S.inverse();
  const double want_yaw = std::atan2(want.linear()(1, 0), want.linear()(0, 0));
  MapAlignOptions options;
  options.search_translation = 2.0;
  options.search_rotation = 0.4;
  const MapAlignResult r = align_maps(a, b, options);
  EXPECT_NEAR(r.shift.x, want.translation().x(), 0.05);
  EXPECT_NEAR(r.shift.y, want.translation().y(), 0.05);
  EXPECT_NEAR(r.shift.z, want.translation().z(), 0.05);
  EXPECT_NEAR(r.shift.yaw, want_yaw, 0.3 * std::numbers::pi / 180.0);
  EXPECT_GT(r.columns_used, 1000U);
  EXPECT_GT(r.floor_pairs, 1000U);
  // ±0.4 rad: the yaw step stays two cells at the columns' radius about b's origin, so it is
  // turned about that origin, in one search.
  EXPECT_TRUE(r.about_origin);
  EXPECT_EQ(r.sectors, 1);
  // b moved by the result covers a's columns as b moved by the truth does.
  const auto overlap = [&](const PlanarShift& shift) {
    std::size_t on = 0;
    shifted_map(b, shift).for_each_column([&](const CellKey& k, const ColumnView&) { on += a.column(k).empty() ? 0 : 1; });
    return static_cast<double>(on);
  };
  const double truth = overlap({want.translation().x(), want.translation().y(), want.translation().z(), want_yaw});
  EXPECT_GT(overlap(r.shift), 0.97 * truth);
  EXPECT_LT(overlap({}), 0.8 * truth);
  // Without the search from the identity, 12° and 1.2 m are beyond Gauss-Newton's basin.
  MapAlignOptions narrow;
  narrow.search_translation = 0.0;
  narrow.search_rotation = 0.0;
  const MapAlignResult n = align_maps(a, b, narrow);
  EXPECT_GT(std::abs(n.shift.yaw - want_yaw) + std::hypot(n.shift.x - want.translation().x(), n.shift.y - want.translation().y()), 0.1);
}

TEST(MapAlign, RefusesWhatCannotBeAligned) {
  const Params p = params();
  HMap a(p), empty(p);
  a.column_for_update({0, 0}).push_back({0.0F, 1.0F, 5.0F, 1.0F});
  EXPECT_THROW((void)align_maps(a, empty, {}), Error);
  Params q = p;
  q.map.cell_size = 0.1;
  HMap other(q);
  other.column_for_update({0, 0}).push_back({0.0F, 1.0F, 5.0F, 1.0F});
  EXPECT_THROW((void)align_maps(a, other, {}), Error);
  MapAlignOptions far;
  far.guess.x = 500.0;
  EXPECT_THROW((void)align_maps(a, a, far), Error);  // nothing of it over the first at the guess
  MapAlignOptions bad;
  bad.guess.yaw = NAN;
  EXPECT_THROW((void)align_maps(a, a, bad), Error);
}


TEST(MapAlign, FindsAMapFarFromItsOriginOverAllHeadings) {
  // b's scans lie 9-13 m from its frame's origin and its frame is turned 120° from a's: turned
  // about b's columns' centroid, the window about the guess would miss it by 17 m (the
  // chord), so the yaw window is cut into sectors searched from their own centres.
  const sim::Scene scene = yard();
  const HMap a = session(scene, {at(0, 0, 0), at(4, 1, 0.3), at(-5, 3, -0.4)}, Pose::Identity(), 1);
  Pose S = Pose::Identity();
  S.linear() = Eigen::AngleAxisd(120.0 * std::numbers::pi / 180.0, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  S.translation() = Eigen::Vector3d(-2.0, 9.5, 0.1);
  const HMap b = session(scene, {at(2, -2, 0.8), at(-3, 0, 2.0)}, S, 10);
  const Pose want = S.inverse();
  const double want_yaw = std::atan2(want.linear()(1, 0), want.linear()(0, 0));
  MapAlignOptions options;  // a guess 0.7 m off with no heading: ±1.5 m and every heading
  options.guess = {want.translation().x() + 0.6, want.translation().y() - 0.4, 0.0, 0.0};
  options.search_translation = 1.5;
  options.search_rotation = std::numbers::pi;
  const MapAlignResult r = align_maps(a, b, options);
  EXPECT_GT(r.sectors, 1);
  EXPECT_FALSE(r.about_origin);  // every heading: at 9-13 m the step would widen past two cells
  EXPECT_NEAR(r.shift.x, want.translation().x(), 0.05);
  EXPECT_NEAR(r.shift.y, want.translation().y(), 0.05);
  EXPECT_NEAR(r.shift.z, want.translation().z(), 0.05);
  EXPECT_NEAR(std::remainder(r.shift.yaw - want_yaw, 2.0 * std::numbers::pi), 0.0, 0.3 * std::numbers::pi / 180.0);
}

}  // namespace map_align_test
}  // namespace hmap::slam
