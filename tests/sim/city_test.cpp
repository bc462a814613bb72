// The city scene for long drives: one town per seed, its accelerated ray cast against every
// primitive, and a route of the asked length that stays on the streets and comes back over them.

#include "hmap/sim/city.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <random>
#include <set>
#include <utility>

#include "hmap/core/error.hpp"
#include "hmap/sim/builtin_scenes.hpp"
#include "hmap/sim/simulation.hpp"
#include "hmap/sim/trajectory.hpp"

namespace hmap::sim {
namespace {

bool same_boxes(const Scene& a, const Scene& b) {
  if (a.primitive_count() != b.primitive_count()) return false;
  for (std::uint32_t i = 0; i < a.primitive_count(); ++i) {
    const Eigen::AlignedBox3d x = bounding_box(a.part_at(i, 0.0).shape);
    const Eigen::AlignedBox3d y = bounding_box(b.part_at(i, 0.0).shape);
    if (x.min() != y.min() || x.max() != y.max() || a.part_at(i, 0.0).kind != b.part_at(i, 0.0).kind) return false;
  }
  return true;
}

TEST(City, OneTownPerSeed) {
  const Scene a = make_city_scene();
  const Scene b = make_city_scene();
  EXPECT_TRUE(same_boxes(a, b));
  // Thousands of solids: what the ray cast's hierarchy is for.
  EXPECT_GT(a.primitive_count(), 5000U);
  CityParams other;
  other.seed = 2;
  EXPECT_FALSE(same_boxes(a, make_city_scene(other)));
  // make_scene("city") is the default town.
  EXPECT_TRUE(same_boxes(a, make_scene("city")));
}

TEST(City, StreetsByHand) {
  const CityParams c;  // pitch 90 m, streets 10 m wide, 8 blocks
  EXPECT_DOUBLE_EQ(city_pitch(c), 90.0);
  EXPECT_TRUE(on_city_street(c, 0.0, 0.0));
  EXPECT_TRUE(on_city_street(c, 45.0, 0.0));
  EXPECT_TRUE(on_city_street(c, 45.0, 4.9));
  EXPECT_FALSE(on_city_street(c, 45.0, 5.1));
  EXPECT_FALSE(on_city_street(c, 45.0, 4.9, 0.5));
  EXPECT_FALSE(on_city_street(c, 45.0, 45.0));          // a block's middle
  EXPECT_TRUE(on_city_street(c, 720.0, 300.0));         // the outer street
  EXPECT_FALSE(on_city_street(c, 726.0, 300.0));        // beyond it
  EXPECT_DOUBLE_EQ(city_ground_z(c, 100.0, 50.0), 0.02 * 100.0 - 0.01 * 50.0);
  // The road is where the plane says, the sidewalk 12 cm above it.
  const Scene scene = make_city_scene(c);
  const auto down = [&](double x, double y) {
    const auto hit = scene.intersect({x, y, 100.0}, {0.0, 0.0, -1.0}, 0.0, 200.0);
    return hit ? 100.0 - hit->distance : -1e9;
  };
  EXPECT_NEAR(down(45.0, 0.0), city_ground_z(c, 45.0, 0.0), 1e-9);
  EXPECT_NEAR(down(45.0, 6.0), city_ground_z(c, 45.0, 6.0) + 0.12, 1e-9);
}

TEST(City, BadParamsAreRefused) {
  CityParams c;
  c.blocks = 0;
  EXPECT_THROW((void)make_city_scene(c), Error);
  c = {};
  c.street_width = 2.0;
  EXPECT_THROW((void)make_city_scene(c), Error);
  c = {};
  c.slope_x = 0.5;
  EXPECT_THROW((void)city_car_route(c, 1000.0), Error);
  EXPECT_THROW((void)city_car_route({}, 0.0), Error);
  EXPECT_THROW((void)city_car_route({}, -5.0), Error);
  EXPECT_THROW((void)city_car_route({}, std::nan("")), Error);
}

// Rays from where the car's sensor goes (over the streets) and from anywhere in the town: the
// hierarchy finds the hit that testing every solid finds.
TEST(City, IntersectEqualsBruteForce) {
  const CityParams c;
  const Scene scene = make_city_scene(c);
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::normal_distribution<double> normal(0.0, 1.0);
  const double extent = c.blocks * city_pitch(c);
  int hits = 0;
  constexpr int kRays = 1500;
  for (int i = 0; i < kRays; ++i) {
    Eigen::Vector3d o;
    if (i % 2 == 0) {
      // On a street centre line at the roof's height.
      const double along = unit(rng) * extent;
      const double line = std::floor(unit(rng) * (c.blocks + 1)) * city_pitch(c);
      o = i % 4 == 0 ? Eigen::Vector3d(along, line, 0.0) : Eigen::Vector3d(line, along, 0.0);
      o.z() = city_ground_z(c, o.x(), o.y()) + 1.73;
    } else {
      const Eigen::AlignedBox3d& b = scene.bounds();
      for (int k = 0; k < 3; ++k) o[k] = b.min()[k] + unit(rng) * b.sizes()[k];
    }
    const Eigen::Vector3d d(normal(rng), normal(rng), normal(rng));
    const auto fast = scene.intersect(o, d, 0.0, 120.0);
    const auto slow = scene.intersect_brute_force(o, d, 0.0, 120.0);
    ASSERT_EQ(fast.has_value(), slow.has_value()) << "ray " << i;
    if (!fast) continue;
    ++hits;
    EXPECT_NEAR(fast->distance, slow->distance, 1e-9) << "ray " << i;
  }
  EXPECT_GT(hits, kRays / 3);
}

TEST(City, RouteHasTheAskedLengthStaysOnTheStreetsAndComesBack) {
  const CityParams c;
  const Scene scene = make_city_scene(c);
  for (const double km : {0.1, 1.0, 10.0}) {
    SCOPED_TRACE(km);
    const CarPathParams car;
    const std::vector<Eigen::Vector3d> route = city_car_route(c, 1000.0 * km, car.turn_radius);
    const Trajectory path = car_path(route, car);
    EXPECT_NEAR(path_length(path.T_world_sensor), 1000.0 * km, 0.01 * 1000.0 * km);
    for (std::size_t k = 0; k < path.T_world_sensor.size(); ++k) {
      const Eigen::Vector3d p = path.T_world_sensor[k].translation();
      // On the carriageway with the car's half width to spare, the sensor 1.73 m over the road.
      ASSERT_TRUE(on_city_street(c, p.x(), p.y(), 1.0)) << "pose " << k << " at " << p.transpose();
      ASSERT_NEAR(p.z() - car.sensor_height, city_ground_z(c, p.x(), p.y()), 0.05) << "pose " << k;
      ASSERT_FALSE(scene.contains(p, path.times[k])) << "pose " << k << " at " << p.transpose();
      ASSERT_FALSE(scene.contains(p - Eigen::Vector3d(0.0, 0.0, 1.0), path.times[k])) << "pose " << k;
    }
    if (km == 10.0) {
      // Real drives come back: some street between two intersections is driven more than once.
      std::map<std::pair<std::pair<long, long>, std::pair<long, long>>, int> driven;
      for (std::size_t i = 0; i + 2 < route.size(); ++i) {
        auto a = std::make_pair(std::lround(route[i].x()), std::lround(route[i].y()));
        auto b = std::make_pair(std::lround(route[i + 1].x()), std::lround(route[i + 1].y()));
        if (b < a) std::swap(a, b);
        ++driven[{a, b}];
      }
      int again = 0;
      for (const auto& [street, times] : driven) again += times > 1 ? 1 : 0;
      EXPECT_GT(again, 5);
      // And it turns: not one long straight.
      int turns = 0;
      for (std::size_t i = 1; i + 1 < route.size(); ++i) {
        const Eigen::Vector3d u = route[i] - route[i - 1];
        const Eigen::Vector3d v = route[i + 1] - route[i];
        turns += std::abs(u.x() * v.y() - u.y() * v.x()) > 1.0 ? 1 : 0;
      }
      EXPECT_GT(turns, 20);
    }
  }
  // The same seed, the same route.
  EXPECT_EQ(city_car_route(c, 5000.0), city_car_route(c, 5000.0));
}

SimulationSpec city_spec() {
  SimulationSpec spec;
  spec.scene = "city";
  spec.sensor = "vlp16";
  spec.frames = 3;
  spec.stride = 20;
  spec.route_km = 0.5;
  spec.truth = false;
  return spec;
}

TEST(City, SimulationIsTheSameForASeedAndStreamsItsScans) {
  const Scene scene = make_city_scene();
  const SimulatedRecording a = simulate(city_spec(), scene);
  const SimulatedRecording b = simulate(city_spec(), scene);
  ASSERT_EQ(a.scans.size(), 3U);
  EXPECT_EQ(a.scans, b.scans);
  EXPECT_EQ(a.odometry.size(), 3U);
  EXPECT_GT(a.scans[1].size(), 10000U);
  EXPECT_TRUE(a.truth_seen.empty());
  EXPECT_TRUE(a.truth_surface.empty());
  // Streamed: the same scans go to the sink, in order, and none stay in the recording.
  std::vector<PointCloud> streamed;
  const SimulatedRecording c = simulate(city_spec(), scene, {}, [&](std::size_t k, const PointCloud& points,
                                                                    const std::vector<float>& times) {
    EXPECT_EQ(k, streamed.size());
    EXPECT_TRUE(times.empty());
    streamed.push_back(points);
  });
  EXPECT_TRUE(c.scans.empty());
  EXPECT_EQ(streamed, a.scans);
  EXPECT_EQ(c.points, a.points);
  // Another noise seed: other scans of the same town.
  SimulationSpec other = city_spec();
  other.seed = 2;
  EXPECT_NE(simulate(other, scene).scans, a.scans);
}

TEST(City, SimulationRefusesBadRouteLengthsAndTruth) {
  const Scene scene = make_city_scene();
  for (const double km : {0.0, 0.05, 20.5, -1.0, std::nan("")}) {
    SimulationSpec spec = city_spec();
    spec.route_km = km;
    EXPECT_THROW((void)simulate(spec, scene), Error) << km;
  }
  SimulationSpec spec = city_spec();
  spec.truth = true;
  EXPECT_THROW((void)simulate(spec, scene), Error);
  EXPECT_THROW((void)simulate(spec), Error);
}

}  // namespace
}  // namespace hmap::sim
