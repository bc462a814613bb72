// Exact ray intersection of every primitive against marching along the ray with the inside test.

#include "hmap/sim/primitives.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>

#include "hmap/core/error.hpp"

namespace hmap::sim {
namespace {

constexpr double kStep = 5e-4;  // [m] march step
constexpr double kRange = 6.0;  // [m]

/// First t in (0, kRange] where the inside test differs from the origin's, by marching.
std::optional<double> march(const Shape& shape, const Eigen::Vector3d& o, const Eigen::Vector3d& d) {
  const bool start_inside = contains(shape, o);
  for (double t = kStep; t <= kRange; t += kStep) {
    if (contains(shape, o + t * d) != start_inside) return t;
  }
  return std::nullopt;
}

struct Case {
  std::string name;
  Shape shape;
};

class PrimitiveIntersection : public ::testing::TestWithParam<Case> {};

TEST_P(PrimitiveIntersection, MatchesMarchingAlongTheRay) {
  const Shape& shape = GetParam().shape;
  const Eigen::AlignedBox3d box = bounding_box(shape);
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::normal_distribution<double> normal(0.0, 1.0);
  int hits = 0;
  int misses = 0;
  int inside_starts = 0;
  for (int ray = 0; ray < 300; ++ray) {
    // Origins in the bounding box grown by 1 m: some inside, most outside.
    Eigen::Vector3d o;
    for (int k = 0; k < 3; ++k) o[k] = box.min()[k] - 1.0 + unit(rng) * (box.sizes()[k] + 2.0);
    // Half the rays aim at a point of the box, so that hits are common.
    Eigen::Vector3d d(normal(rng), normal(rng), normal(rng));
    if (ray % 2 == 0) {
      Eigen::Vector3d target;
      for (int k = 0; k < 3; ++k) target[k] = box.min()[k] + unit(rng) * box.sizes()[k];
      d = target - o;
    }
    d.normalize();
    const auto exact = intersect(shape, o, d, kRange);
    const auto marched = march(shape, o, d);
    inside_starts += contains(shape, o) ? 1 : 0;
    if (marched) {
      ASSERT_TRUE(exact.has_value()) << "ray " << ray << " marched to a crossing at " << *marched;
      EXPECT_NEAR(*exact, *marched, 1.01 * kStep) << "ray " << ray;
      ++hits;
    } else if (exact) {
      // Only a grazing ray may cross between two march samples: its chord must be shorter than a step.
      const auto exit = intersect(shape, o + (*exact + 1e-9) * d, d, kRange);
      ASSERT_TRUE(exit.has_value());
      EXPECT_LT(*exit, 2.0 * kStep) << "ray " << ray << " hit at " << *exact << " but marching saw nothing";
    } else {
      ++misses;
    }
  }
  EXPECT_GT(hits, 60);
  EXPECT_GT(misses, 10);
  EXPECT_GT(inside_starts, 3);
}

TEST_P(PrimitiveIntersection, RespectsMaxDistanceAndStartsInsideAtTheExit) {
  const Shape& shape = GetParam().shape;
  const Eigen::Vector3d centre = bounding_box(shape).center();
  // Pick a point surely inside: the centre for all shapes but the ground patch, just under its top.
  Eigen::Vector3d inside = centre;
  if (const auto* g = std::get_if<GroundPatch>(&shape)) inside = g->center - Eigen::Vector3d(0, 0, 0.5 * g->thickness);
  ASSERT_TRUE(contains(shape, inside));
  const Eigen::Vector3d up(0.0, 0.0, 1.0);
  const auto exit = intersect(shape, inside, up, kRange);
  ASSERT_TRUE(exit.has_value());
  EXPECT_FALSE(contains(shape, inside + (*exit + 1e-6) * up));
  EXPECT_FALSE(intersect(shape, inside, up, 0.5 * *exit).has_value());
}

TEST_P(PrimitiveIntersection, SurfaceSamplesLieOnTheSurfaceWithOutwardNormals) {
  const Shape& shape = GetParam().shape;
  std::mt19937_64 rng(7);
  std::vector<SurfaceSample> samples;
  sample_surface(shape, 0.1, rng, samples);
  ASSERT_FALSE(samples.empty());
  for (const SurfaceSample& s : samples) {
    EXPECT_TRUE(contains(shape, s.point - 1e-6 * s.normal));
    EXPECT_FALSE(contains(shape, s.point + 1e-6 * s.normal));
    EXPECT_NEAR(s.normal.norm(), 1.0, 1e-9);
  }
}

TEST_P(PrimitiveIntersection, PlacingMovesTheInsideTest) {
  const Shape& shape = GetParam().shape;
  const Placement where{{1.5, -2.0, 0.3}, 0.7};
  const Shape moved = placed(shape, where);
  const Eigen::AlignedBox3d box = bounding_box(shape);
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const Eigen::Matrix3d R = Eigen::AngleAxisd(where.yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  for (int i = 0; i < 500; ++i) {
    Eigen::Vector3d p;
    for (int k = 0; k < 3; ++k) p[k] = box.min()[k] - 0.2 + unit(rng) * (box.sizes()[k] + 0.4);
    EXPECT_EQ(contains(shape, p), contains(moved, R * p + where.position));
    if (contains(shape, p)) {
      EXPECT_TRUE(bounding_box(shape).contains(p));
    }
  }
}

INSTANTIATE_TEST_SUITE_P(
    Shapes, PrimitiveIntersection,
    ::testing::Values(Case{"box", Box{{0.2, -0.1, 0.5}, {0.6, 0.3, 0.4}, 0.0}},
                      Case{"yawed_box", Box{{0.0, 0.0, 0.0}, {1.0, 0.2, 0.5}, 0.6}},
                      Case{"cylinder", Cylinder{{0.3, 0.2}, -0.4, 1.1, 0.35}},
                      Case{"sphere", Ellipsoid{{0.0, 0.0, 1.0}, Eigen::Vector3d::Constant(0.5), 0.0}},
                      Case{"ellipsoid", Ellipsoid{{0.5, 0.0, 2.0}, {1.2, 0.6, 0.4}, -0.4}},
                      Case{"flat_ground", GroundPatch{{0.0, 0.0, 0.0}, {1.5, 1.0}, 0.0, {0.0, 0.0}, 0.3}},
                      Case{"sloped_ground", GroundPatch{{0.0, 0.0, 0.2}, {1.5, 1.0}, 0.5, {0.3, -0.1}, 0.4}}),
    [](const ::testing::TestParamInfo<Case>& param_info) { return param_info.param.name; });

TEST(Primitives, ValidateRejectsDegenerateShapes) {
  EXPECT_THROW(validate(Box{{0, 0, 0}, {0.0, 1.0, 1.0}, 0.0}, "b"), Error);
  EXPECT_THROW(validate(Cylinder{{0, 0}, 1.0, 0.5, 0.1}, "c"), Error);
  EXPECT_THROW(validate(Ellipsoid{{0, 0, 0}, {1.0, -1.0, 1.0}, 0.0}, "e"), Error);
  EXPECT_THROW(validate(GroundPatch{{0, 0, 0}, {1.0, 1.0}, 0.0, {0.0, 0.0}, 0.0}, "g"), Error);
  EXPECT_NO_THROW(validate(Box{}, "b"));
}

TEST(Primitives, RayParallelToAFaceOutsideMisses) {
  const Box box{{0, 0, 0}, {1, 1, 1}, 0.0};
  EXPECT_FALSE(intersect(box, {-5, 2, 0}, {1, 0, 0}, 100.0).has_value());
  const auto hit = intersect(box, {-5, 0.5, 0}, {1, 0, 0}, 100.0);
  ASSERT_TRUE(hit.has_value());
  EXPECT_DOUBLE_EQ(*hit, 4.0);
}

}  // namespace
}  // namespace hmap::sim
