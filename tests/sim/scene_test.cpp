// The scene's accelerated ray query against its brute-force twin, moving objects, and the truth sample.

#include "hmap/sim/scene.hpp"

#include <gtest/gtest.h>

#include <random>

#include "hmap/core/error.hpp"
#include "hmap/sim/builtin_scenes.hpp"
#include "hmap/sim/composites.hpp"

namespace hmap::sim {
namespace {

void expect_same_hits_as_brute_force(const Scene& scene, double t_seconds, int rays, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  const Eigen::AlignedBox3d& b = scene.bounds();
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::normal_distribution<double> normal(0.0, 1.0);
  int hits = 0;
  for (int i = 0; i < rays; ++i) {
    Eigen::Vector3d o;
    for (int k = 0; k < 3; ++k) o[k] = b.min()[k] + unit(rng) * b.sizes()[k];
    const Eigen::Vector3d d(normal(rng), normal(rng), normal(rng));
    const auto fast = scene.intersect(o, d, t_seconds, 80.0);
    const auto slow = scene.intersect_brute_force(o, d, t_seconds, 80.0);
    ASSERT_EQ(fast.has_value(), slow.has_value()) << "ray " << i;
    if (!fast) continue;
    ++hits;
    EXPECT_NEAR(fast->distance, slow->distance, 1e-9) << "ray " << i;
    // Where two solids touch (a leg on the floor) either may be reported: the one found must be
    // hit at the same distance.
    const auto own = intersect(scene.part_at(fast->primitive, t_seconds).shape, o, d.normalized(), 80.0);
    ASSERT_TRUE(own.has_value());
    EXPECT_NEAR(*own, slow->distance, 1e-9) << "ray " << i;
  }
  EXPECT_GT(hits, rays / 3);
}

TEST(Scene, IntersectEqualsBruteForceOnTheBuiltinScenes) {
  for (const auto& name : builtin_scene_names()) {
    SCOPED_TRACE(name);
    const Scene scene = make_scene(name);
    expect_same_hits_as_brute_force(scene, 0.0, 2000, 11);
    expect_same_hits_as_brute_force(scene, 6.5, 500, 12);
  }
}

TEST(Scene, EmptySceneHitsNothing) {
  const Scene scene = SceneBuilder().build();
  EXPECT_FALSE(scene.intersect({0, 0, 0}, {1, 0, 0}, 0.0, 100.0).has_value());
  EXPECT_FALSE(scene.contains({0, 0, 0}, 0.0));
  std::mt19937_64 rng(1);
  EXPECT_TRUE(scene.sample_surface(0.1, rng, 0.0).empty());
}

TEST(Scene, ZeroDirectionOrRangeHitsNothing) {
  SceneBuilder builder;
  builder.add("box", {{Box{{5, 0, 0}, {1, 1, 1}, 0.0}, SurfaceKind::kBox}});
  const Scene scene = builder.build();
  EXPECT_FALSE(scene.intersect({0, 0, 0}, {0, 0, 0}, 0.0, 100.0).has_value());
  EXPECT_FALSE(scene.intersect({0, 0, 0}, {1, 0, 0}, 0.0, 0.0).has_value());
  const auto hit = scene.intersect({0, 0, 0}, {2, 0, 0}, 0.0, 100.0);  // direction need not be unit
  ASSERT_TRUE(hit.has_value());
  EXPECT_DOUBLE_EQ(hit->distance, 4.0);
  EXPECT_EQ(hit->kind, SurfaceKind::kBox);
  EXPECT_EQ(scene.object_name(hit->object), "box");
  EXPECT_FALSE(scene.intersect({0, 0, 0}, {1, 0, 0}, 0.0, 3.9).has_value());
}

TEST(Scene, MovingObjectFollowsItsPath) {
  SceneBuilder builder;
  const std::uint32_t car = builder.add_moving(
      "car", make_car(), MotionPath({{0.0, {10, 0, 0}, 0.0}, {3.0, {10, 0, 0}, 0.0}, {5.0, {30, 0, 0}, 0.5}}));
  const Scene scene = builder.build();
  EXPECT_TRUE(scene.object_placement(car, 1.0).position.isApprox(Eigen::Vector3d(10, 0, 0)));
  EXPECT_TRUE(scene.object_placement(car, 4.0).position.isApprox(Eigen::Vector3d(20, 0, 0)));
  EXPECT_NEAR(scene.object_placement(car, 4.0).yaw, 0.25, 1e-12);
  EXPECT_TRUE(scene.object_placement(car, 99.0).position.isApprox(Eigen::Vector3d(30, 0, 0)));
  const Eigen::Vector3d origin(0, 0, 0.8);
  const auto before = scene.intersect(origin, {1, 0, 0}, 2.0, 100.0);
  const auto after = scene.intersect(origin, {1, 0, 0}, 6.0, 100.0);
  ASSERT_TRUE(before && after);
  EXPECT_NEAR(before->distance, 10.0 - 2.25, 1e-9);  // the rear of a 4.5 m car centred at x = 10
  EXPECT_GT(after->distance, 25.0);
  EXPECT_EQ(before->object, car);
}

TEST(Scene, MotionPathRejectsBadKeys) {
  EXPECT_THROW(MotionPath({}), Error);
  EXPECT_THROW(MotionPath({{1.0, {0, 0, 0}, 0.0}, {1.0, {1, 0, 0}, 0.0}}), Error);
}

TEST(Scene, BuilderNamesTheObjectOfAnInvalidPart) {
  SceneBuilder builder;
  try {
    builder.add("shelf", {{Box{{0, 0, 0}, {1, -1, 1}, 0.0}, SurfaceKind::kFurniture}});
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("shelf"), std::string::npos) << e.what();
  }
}

TEST(Scene, SurfaceSampleHidesCoveredFacesAndKeepsToTheBounds) {
  SceneBuilder builder;
  builder.add("a", {{Box{{0, 0, 0.5}, {0.5, 0.5, 0.5}, 0.0}, SurfaceKind::kBox}});
  const Scene alone = builder.build();
  std::mt19937_64 rng(5);
  EXPECT_EQ(alone.sample_surface(0.1, rng, 0.0).size(), 600U);  // 6 faces of 10 × 10 cells

  // A second cube on top of the first: the two touching faces disappear.
  builder.add("b", {{Box{{0, 0, 1.5}, {0.5, 0.5, 0.5}, 0.0}, SurfaceKind::kBox}});
  const Scene stacked = builder.build();
  const PointCloud points = stacked.sample_surface(0.1, rng, 0.0);
  EXPECT_EQ(points.size(), 1000U);
  for (const auto& p : points) EXPECT_GT(std::abs(p.z() - 1.0F), 1e-4F);

  // Bounds cut the sample.
  builder.set_bounds(Eigen::AlignedBox3d(Eigen::Vector3d(-1, -1, -1), Eigen::Vector3d(1, 1, 0.999)));
  const PointCloud lower = builder.build().sample_surface(0.1, rng, 0.0);
  EXPECT_EQ(lower.size(), 500U);  // the first cube without its top

  // Same seed, same truth.
  std::mt19937_64 a(9);
  std::mt19937_64 b(9);
  EXPECT_EQ(stacked.sample_surface(0.1, a, 0.0), stacked.sample_surface(0.1, b, 0.0));
}

TEST(Scene, SurfaceKindNamesRoundTrip) {
  for (int k = 0; k <= static_cast<int>(SurfaceKind::kOther); ++k) {
    const auto kind = static_cast<SurfaceKind>(k);
    EXPECT_EQ(surface_kind_from_string(to_string(kind)), kind);
  }
  EXPECT_FALSE(surface_kind_from_string("lava").has_value());
}

}  // namespace
}  // namespace hmap::sim
