#include "hmap/sim/city.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <random>
#include <string>

#include "hmap/core/error.hpp"
#include "hmap/core/format.hpp"
#include "hmap/sim/composites.hpp"

namespace hmap::sim {
namespace {

constexpr double kKerb = 0.12;       // [m] sidewalks above the road
constexpr double kKerbWidth = 0.2;   // [m]
constexpr double kSidewalk = 4.0;    // [m] kerb to building line
constexpr double kMargin = 40.0;     // [m] raised ground beyond the outer streets

/// A uniform number in [lo, hi) from `rng`, drawn the same way on every platform.
double uniform(std::mt19937_64& rng, double lo, double hi) {
  return lo + (hi - lo) * (static_cast<double>(rng() >> 11) * 0x1.0p-53);
}
bool chance(std::mt19937_64& rng, double p) { return uniform(rng, 0.0, 1.0) < p; }

/// A ground patch over [lo, hi] in plan whose top lies `above` [m] over the town's plane.
Part plane_patch(const CityParams& c, const Eigen::Vector2d& lo, const Eigen::Vector2d& hi, double above,
                 SurfaceKind kind, double thickness = 0.4) {
  const Eigen::Vector2d centre = 0.5 * (lo + hi);
  GroundPatch g;
  g.center = {centre.x(), centre.y(), city_ground_z(c, centre.x(), centre.y()) + above};
  g.half_size = 0.5 * (hi - lo);
  g.slope = {c.slope_x, c.slope_y};
  g.thickness = thickness;
  return {g, kind};
}

/// Lowest and highest plane height over the rectangle [lo, hi] (a plane: at its corners).
std::pair<double, double> plane_range(const CityParams& c, const Eigen::Vector2d& lo, const Eigen::Vector2d& hi) {
  double zmin = 1e300;
  double zmax = -1e300;
  for (const double x : {lo.x(), hi.x()}) {
    for (const double y : {lo.y(), hi.y()}) {
      zmin = std::min(zmin, city_ground_z(c, x, y));
      zmax = std::max(zmax, city_ground_z(c, x, y));
    }
  }
  return {zmin, zmax};
}

/// One side of a block: from `a` to `b` along the kerb line, `inward` the unit normal into the block.
struct Side {
  Eigen::Vector2d a, b, inward;
};

}  // namespace

void validate(const CityParams& c) {
  if (c.blocks < 1 || c.blocks > 40) throw Error("city: blocks must be in [1, 40]");
  if (!(c.block_size >= 20.0 && c.block_size <= 300.0)) throw Error("city: block_size must be in [20, 300] m");
  if (!(c.street_width >= 6.0 && c.street_width <= 30.0)) throw Error("city: street_width must be in [6, 30] m");
  if (!(std::abs(c.slope_x) <= 0.1) || !(std::abs(c.slope_y) <= 0.1)) throw Error("city: slopes must be within ±0.1");
}

double city_pitch(const CityParams& c) { return c.block_size + c.street_width; }

double city_ground_z(const CityParams& c, double x, double y) { return c.slope_x * x + c.slope_y * y; }

bool on_city_street(const CityParams& c, double x, double y, double margin) {
  const double p = city_pitch(c);
  const double half = 0.5 * c.street_width - margin;
  const double extent = c.blocks * p;
  if (x < -half || x > extent + half || y < -half || y > extent + half) return false;
  const auto near_line = [&](double v) {
    const double k = std::clamp(std::round(v / p), 0.0, static_cast<double>(c.blocks));
    return std::abs(v - k * p) <= half;
  };
  return near_line(x) || near_line(y);
}

Scene make_city_scene(const CityParams& c) {
  validate(c);
  SceneBuilder b;
  std::mt19937_64 rng(c.seed);
  const double p = city_pitch(c);
  const double w = c.street_width;
  const double extent = c.blocks * p;
  const Eigen::Vector2d town_lo(-0.5 * w - kMargin, -0.5 * w - kMargin);
  const Eigen::Vector2d town_hi(extent + 0.5 * w + kMargin, extent + 0.5 * w + kMargin);
  // The road under the whole town; blocks and the outer ring are raised patches on it, their
  // sides the kerbs' faces.
  b.add("road", {plane_patch(c, town_lo, town_hi, 0.0, SurfaceKind::kGround, 0.5)});
  const double in = 0.5 * w;  // kerb line's offset from a street's centre line
  b.add("verge", {plane_patch(c, town_lo, {town_hi.x(), -in}, kKerb, SurfaceKind::kGround)});
  b.add("verge", {plane_patch(c, {town_lo.x(), extent + in}, town_hi, kKerb, SurfaceKind::kGround)});
  b.add("verge", {plane_patch(c, {town_lo.x(), -in}, {-in, extent + in}, kKerb, SurfaceKind::kGround)});
  b.add("verge", {plane_patch(c, {extent + in, -in}, {town_hi.x(), extent + in}, kKerb, SurfaceKind::kGround)});

  for (int i = 0; i < c.blocks; ++i) {
    for (int j = 0; j < c.blocks; ++j) {
      const Eigen::Vector2d lo(i * p + in, j * p + in);
      const Eigen::Vector2d hi((i + 1) * p - in, (j + 1) * p - in);
      const Eigen::Vector2d k(kKerbWidth, kKerbWidth);
      // Kerb stones round the block, then the sidewalk and yards inside them.
      b.add("kerb", {plane_patch(c, lo, {hi.x(), lo.y() + kKerbWidth}, kKerb, SurfaceKind::kCurb),
                     plane_patch(c, {lo.x(), hi.y() - kKerbWidth}, hi, kKerb, SurfaceKind::kCurb),
                     plane_patch(c, {lo.x(), lo.y() + kKerbWidth}, {lo.x() + kKerbWidth, hi.y() - kKerbWidth}, kKerb,
                                 SurfaceKind::kCurb),
                     plane_patch(c, {hi.x() - kKerbWidth, lo.y() + kKerbWidth}, {hi.x(), hi.y() - kKerbWidth}, kKerb,
                                 SurfaceKind::kCurb)});
      b.add("block", {plane_patch(c, lo + k, hi - k, kKerb, SurfaceKind::kGround)});

      // Buildings on lots: two rows, two to four columns; some lots are small parks.
      const Eigen::Vector2d blo = lo + Eigen::Vector2d::Constant(kSidewalk);
      const Eigen::Vector2d bhi = hi - Eigen::Vector2d::Constant(kSidewalk);
      const int columns = 2 + static_cast<int>(rng() % 3);
      for (int r = 0; r < 2; ++r) {
        for (int q = 0; q < columns; ++q) {
          Eigen::Vector2d llo(blo.x() + (bhi.x() - blo.x()) * q / columns, blo.y() + (bhi.y() - blo.y()) * r / 2.0);
          Eigen::Vector2d lhi(blo.x() + (bhi.x() - blo.x()) * (q + 1) / columns,
                              blo.y() + (bhi.y() - blo.y()) * (r + 1) / 2.0);
          if (chance(rng, 0.12)) {
            const Eigen::Vector2d centre = 0.5 * (llo + lhi);
            for (int t = 0; t < 3; ++t) {
              const Eigen::Vector2d at = centre + Eigen::Vector2d(uniform(rng, -6.0, 6.0), uniform(rng, -6.0, 6.0));
              const TreeSize size{0.2, uniform(rng, 2.0, 3.5), uniform(rng, 3.0, 5.0), uniform(rng, 2.0, 3.5)};
              b.add("park_tree", make_tree(size), {{at.x(), at.y(), city_ground_z(c, at.x(), at.y()) + kKerb}, 0.0});
            }
            continue;
          }
          llo += Eigen::Vector2d(0.5 + uniform(rng, 0.0, 2.0), 0.5 + uniform(rng, 0.0, 2.0));
          lhi -= Eigen::Vector2d(0.5 + uniform(rng, 0.0, 2.0), 0.5 + uniform(rng, 0.0, 2.0));
          const double height = chance(rng, 0.2) ? uniform(rng, 30.0, 50.0) : uniform(rng, 5.0, 30.0);
          const auto [zmin, zmax] = plane_range(c, llo, lhi);
          const Eigen::Vector3d box_lo(llo.x(), llo.y(), zmin + kKerb - 0.5);
          const Eigen::Vector3d box_hi(lhi.x(), lhi.y(), zmax + kKerb + height);
          b.add("building", {{Box{0.5 * (box_lo + box_hi), 0.5 * (box_hi - box_lo), 0.0}, SurfaceKind::kWall}});
        }
      }

      // Along each side: trees and lamp poles on the sidewalk, cars parked at the kerb.
      const std::array<Side, 4> sides{Side{lo, {hi.x(), lo.y()}, {0.0, 1.0}}, Side{{lo.x(), hi.y()}, hi, {0.0, -1.0}},
                                      Side{lo, {lo.x(), hi.y()}, {1.0, 0.0}}, Side{{hi.x(), lo.y()}, hi, {-1.0, 0.0}}};
      for (const Side& s : sides) {
        const Eigen::Vector2d along = (s.b - s.a).normalized();
        const double length = (s.b - s.a).norm();
        const double yaw = std::atan2(along.y(), along.x());
        if (chance(rng, 0.6)) {
          for (double d = 6.0 + uniform(rng, 0.0, 4.0); d < length - 6.0; d += 10.0 + uniform(rng, 0.0, 6.0)) {
            const Eigen::Vector2d at = s.a + d * along + 2.0 * s.inward;
            const TreeSize size{0.15, uniform(rng, 2.5, 4.0), uniform(rng, 2.5, 4.0), uniform(rng, 1.8, 2.8)};
            b.add("tree", make_tree(size), {{at.x(), at.y(), city_ground_z(c, at.x(), at.y()) + kKerb}, 0.0});
          }
        }
        for (double d = 3.0 + uniform(rng, 0.0, 6.0); d < length - 3.0; d += 30.0) {
          const Eigen::Vector2d at = s.a + d * along + 0.6 * s.inward;
          const double z = city_ground_z(c, at.x(), at.y()) + kKerb;
          b.add("pole", {{Cylinder{at, z - 0.3, z + 7.0, 0.08}, SurfaceKind::kOther}});
        }
        for (double d = 8.0; d + 8.0 < length; d += 6.0) {
          if (!chance(rng, 0.35)) continue;
          const Eigen::Vector2d at = s.a + (d + uniform(rng, -0.5, 0.5)) * along - 1.1 * s.inward;
          const double turn = chance(rng, 0.5) ? 0.0 : std::numbers::pi;
          b.add("parked_car", make_car(), {{at.x(), at.y(), city_ground_z(c, at.x(), at.y())}, yaw + turn});
        }
      }
    }
  }
  const auto [zmin, zmax] = plane_range(c, town_lo, town_hi);
  b.set_bounds(Eigen::AlignedBox3d(Eigen::Vector3d(town_lo.x(), town_lo.y(), zmin - 1.0),
                                   Eigen::Vector3d(town_hi.x(), town_hi.y(), zmax + 60.0)));
  return b.build();
}

std::vector<Eigen::Vector3d> city_car_route(const CityParams& c, double length_m, double turn_radius) {
  validate(c);
  if (!(length_m > 0.0 && length_m <= 100000.0)) throw Error("city route: length must be in (0, 100000] m");
  if (!(turn_radius > 0.0)) throw Error("city route: turn_radius must be positive");
  // The route's own generator, apart from the layout's: the same town whatever the route.
  std::mt19937_64 rng(c.seed ^ 0x9e3779b97f4a7c15ULL);
  const double p = city_pitch(c);
  const std::array<std::array<int, 2>, 4> step{{{1, 0}, {0, 1}, {-1, 0}, {0, -1}}};
  std::array<int, 2> node{c.blocks / 2, c.blocks / 2};
  const auto point = [&](double x, double y) { return Eigen::Vector3d(x, y, city_ground_z(c, x, y)); };
  std::vector<Eigen::Vector3d> route{point(node[0] * p, node[1] * p)};
  // A 90° corner rounded into an arc of radius r is 2r − πr/2 shorter than its two tangents.
  const double per_turn = (2.0 - 0.5 * std::numbers::pi) * turn_radius;
  double target = length_m;
  double driven = 0.0;
  int heading = 0;  // east first
  for (bool first = true;; first = false) {
    if (!first) {
      std::array<int, 4> options{};
      int n = 0;
      for (int d = 0; d < 4; ++d) {
        if (d == (heading + 2) % 4) continue;  // never back
        const int x = node[0] + step[d][0];
        const int y = node[1] + step[d][1];
        if (x >= 0 && x <= c.blocks && y >= 0 && y <= c.blocks) options[n++] = d;
      }
      if (n == 0) throw Error("city route: a dead end");  // not on a grid of at least one block
      const int chosen = options[rng() % static_cast<std::uint64_t>(n)];
      if (chosen != heading) target += per_turn;
      heading = chosen;
    }
    const Eigen::Vector3d& from = route.back();
    const int x = node[0] + step[heading][0];
    const int y = node[1] + step[heading][1];
    const double remaining = target - driven;
    if (remaining <= p) {
      const double f = remaining / p;
      route.push_back(point(from.x() + f * p * step[heading][0], from.y() + f * p * step[heading][1]));
      break;
    }
    node = {x, y};
    route.push_back(point(x * p, y * p));
    driven += p;
  }
  return route;
}

std::vector<Eigen::Vector3d> city_loop_route(const CityParams& c, double length_m, double overlap_m) {
  validate(c);
  if (!(length_m > 0.0 && length_m <= 100000.0)) throw Error("city loop: length must be in (0, 100000] m");
  if (!(overlap_m >= 0.0)) throw Error("city loop: overlap must not be negative");
  const double p = city_pitch(c);
  int a = 1;
  int b = 1;
  while (2.0 * (a + b) * p < length_m) (a == b ? a : b) += 1;
  if (a > c.blocks) {
    throw Error(format("city loop: %.0f m needs a rectangle of %d x %d blocks; the town has %d x %d", length_m, a, b, c.blocks, c.blocks));
  }
  overlap_m = std::min(overlap_m, a * p);
  const int i0 = (c.blocks - a) / 2;
  const int j0 = (c.blocks - b) / 2;
  const auto point = [&](double x, double y) { return Eigen::Vector3d(x, y, city_ground_z(c, x, y)); };
  return {point(i0 * p, j0 * p),       point((i0 + a) * p, j0 * p), point((i0 + a) * p, (j0 + b) * p),
          point(i0 * p, (j0 + b) * p), point(i0 * p, j0 * p),       point(i0 * p + overlap_m, j0 * p)};
}

}  // namespace hmap::sim
