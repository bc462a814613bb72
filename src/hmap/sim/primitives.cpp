#include "hmap/sim/primitives.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "hmap/core/checked.hpp"
#include "hmap/core/error.hpp"

namespace hmap::sim {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
/// Crossings closer than this to the ray origin are ignored, so that a ray starting on a surface
/// sees the next one rather than the surface it starts on.
constexpr double kMinT = 1e-9;

/// The parameter interval [t_in, t_out] of a ray inside a convex solid.
struct Span {
  double t_in = -kInf;
  double t_out = kInf;
  [[nodiscard]] bool empty() const { return t_out < t_in; }
};

/// Narrows `span` to where lo <= f0 + t·df <= hi.
void clip_slab(Span& span, double f0, double df, double lo, double hi) {
  if (std::abs(df) < 1e-300) {
    if (f0 < lo || f0 > hi) span.t_out = -kInf;
    return;
  }
  double t1 = (lo - f0) / df;
  double t2 = (hi - f0) / df;
  if (t1 > t2) std::swap(t1, t2);
  span.t_in = std::max(span.t_in, t1);
  span.t_out = std::min(span.t_out, t2);
}

/// Narrows `span` to where a·t² + b·t + c <= 0 (a >= 0).
void clip_quadric(Span& span, double a, double b, double c) {
  if (a < 1e-300) {
    if (c > 0.0) span.t_out = -kInf;
    return;
  }
  const double disc = b * b - 4.0 * a * c;
  if (disc < 0.0) {
    span.t_out = -kInf;
    return;
  }
  // Numerically stable roots (Numerical Recipes §5.6).
  const double q = -0.5 * (b + std::copysign(std::sqrt(disc), b));
  double t1 = q / a;
  double t2 = q != 0.0 ? c / q : t1;
  if (t1 > t2) std::swap(t1, t2);
  span.t_in = std::max(span.t_in, t1);
  span.t_out = std::min(span.t_out, t2);
}

std::optional<double> first_crossing(const Span& span, double t_max) {
  if (span.empty()) return std::nullopt;
  const double t = span.t_in > kMinT ? span.t_in : span.t_out;
  if (t <= kMinT || t > t_max) return std::nullopt;
  return t;
}

/// v turned by -yaw about z (world to local).
Eigen::Vector3d unturn(const Eigen::Vector3d& v, double yaw) {
  const double c = std::cos(yaw);
  const double s = std::sin(yaw);
  return {c * v.x() + s * v.y(), -s * v.x() + c * v.y(), v.z()};
}

Eigen::Vector3d turn(const Eigen::Vector3d& v, double yaw) {
  const double c = std::cos(yaw);
  const double s = std::sin(yaw);
  return {c * v.x() - s * v.y(), s * v.x() + c * v.y(), v.z()};
}

Span span_of(const Box& b, const Eigen::Vector3d& o_world, const Eigen::Vector3d& d_world) {
  const Eigen::Vector3d o = unturn(o_world - b.center, b.yaw);
  const Eigen::Vector3d d = unturn(d_world, b.yaw);
  Span span;
  for (int k = 0; k < 3; ++k) clip_slab(span, o[k], d[k], -b.half_size[k], b.half_size[k]);
  return span;
}

Span span_of(const Cylinder& c, const Eigen::Vector3d& o_world, const Eigen::Vector3d& d) {
  const double ox = o_world.x() - c.center_xy.x();
  const double oy = o_world.y() - c.center_xy.y();
  Span span;
  clip_slab(span, o_world.z(), d.z(), c.z_min, c.z_max);
  clip_quadric(span, d.x() * d.x() + d.y() * d.y(), 2.0 * (ox * d.x() + oy * d.y()),
               ox * ox + oy * oy - c.radius * c.radius);
  return span;
}

Span span_of(const Ellipsoid& e, const Eigen::Vector3d& o_world, const Eigen::Vector3d& d_world) {
  // Scaled to the unit sphere; t is unchanged by the scaling.
  const Eigen::Vector3d o = unturn(o_world - e.center, e.yaw).cwiseQuotient(e.radii);
  const Eigen::Vector3d d = unturn(d_world, e.yaw).cwiseQuotient(e.radii);
  Span span;
  clip_quadric(span, d.squaredNorm(), 2.0 * o.dot(d), o.squaredNorm() - 1.0);
  return span;
}

/// Height of a point above a ground patch's top plane, in the patch frame.
double height_above(const GroundPatch& g, const Eigen::Vector3d& local) {
  return local.z() - g.slope.x() * local.x() - g.slope.y() * local.y();
}

Span span_of(const GroundPatch& g, const Eigen::Vector3d& o_world, const Eigen::Vector3d& d_world) {
  const Eigen::Vector3d o = unturn(o_world - g.center, g.yaw);
  const Eigen::Vector3d d = unturn(d_world, g.yaw);
  Span span;
  clip_slab(span, o.x(), d.x(), -g.half_size.x(), g.half_size.x());
  clip_slab(span, o.y(), d.y(), -g.half_size.y(), g.half_size.y());
  clip_slab(span, height_above(g, o), d.z() - g.slope.x() * d.x() - g.slope.y() * d.y(), -g.thickness, 0.0);
  return span;
}

/// Calls fn(u, v) with one random point in each cell of an n_u × n_v grid over [0, 1]².
template <typename Fn>
void stratified(double len_u, double len_v, double spacing, std::mt19937_64& rng, Fn&& fn) {
  // Sizes and spacing come from scene files: at most 2^20 samples a side (1e5 m at 0.1 m).
  const int n_u = checked_count<int>(std::max(1.0, len_u / spacing), 1 << 20, "a surface's samples along one side");
  const int n_v = checked_count<int>(std::max(1.0, len_v / spacing), 1 << 20, "a surface's samples along one side");
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int i = 0; i < n_u; ++i) {
    for (int j = 0; j < n_v; ++j) {
      const double u = (i + unit(rng)) / n_u;
      const double v = (j + unit(rng)) / n_v;
      fn(u, v);
    }
  }
}

void sample(const Box& b, double spacing, std::mt19937_64& rng, std::vector<SurfaceSample>& out) {
  const Eigen::Vector3d& h = b.half_size;
  for (int axis = 0; axis < 3; ++axis) {
    const int a1 = (axis + 1) % 3;
    const int a2 = (axis + 2) % 3;
    for (const double side : {-1.0, 1.0}) {
      stratified(2.0 * h[a1], 2.0 * h[a2], spacing, rng, [&](double u, double v) {
        Eigen::Vector3d p;
        p[axis] = side * h[axis];
        p[a1] = (2.0 * u - 1.0) * h[a1];
        p[a2] = (2.0 * v - 1.0) * h[a2];
        Eigen::Vector3d n = Eigen::Vector3d::Zero();
        n[axis] = side;
        out.push_back({b.center + turn(p, b.yaw), turn(n, b.yaw)});
      });
    }
  }
}

void sample(const Cylinder& c, double spacing, std::mt19937_64& rng, std::vector<SurfaceSample>& out) {
  const double circumference = 2.0 * std::numbers::pi * c.radius;
  stratified(circumference, c.z_max - c.z_min, spacing, rng, [&](double u, double v) {
    const double a = 2.0 * std::numbers::pi * u;
    const Eigen::Vector3d n(std::cos(a), std::sin(a), 0.0);
    out.push_back({Eigen::Vector3d(c.center_xy.x() + c.radius * n.x(), c.center_xy.y() + c.radius * n.y(),
                                   c.z_min + v * (c.z_max - c.z_min)),
                   n});
  });
  for (const double side : {-1.0, 1.0}) {
    const double z = side > 0.0 ? c.z_max : c.z_min;
    stratified(2.0 * c.radius, 2.0 * c.radius, spacing, rng, [&](double u, double v) {
      const double x = (2.0 * u - 1.0) * c.radius;
      const double y = (2.0 * v - 1.0) * c.radius;
      if (x * x + y * y > c.radius * c.radius) return;
      out.push_back({Eigen::Vector3d(c.center_xy.x() + x, c.center_xy.y() + y, z), Eigen::Vector3d(0, 0, side)});
    });
  }
}

void sample(const Ellipsoid& e, double spacing, std::mt19937_64& rng, std::vector<SurfaceSample>& out) {
  // Uniform directions mapped onto the ellipsoid, kept with probability proportional to the area
  // stretch abc·|A⁻¹u| so that the points are uniform over the surface.
  const double a = e.radii.x();
  const double b = e.radii.y();
  const double c = e.radii.z();
  constexpr double p = 1.6075;  // Knud Thomsen's approximation of the area, within 1.1 %
  const double area = 4.0 * std::numbers::pi *
                      std::pow((std::pow(a * b, p) + std::pow(a * c, p) + std::pow(b * c, p)) / 3.0, 1.0 / p);
  const auto wanted = static_cast<std::size_t>(std::max(1.0, std::round(area / (spacing * spacing))));
  const double min_radius = e.radii.minCoeff();
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (std::size_t kept = 0; kept < wanted;) {
    Eigen::Vector3d u(normal(rng), normal(rng), normal(rng));
    const double norm = u.norm();
    if (norm < 1e-12) continue;
    u /= norm;
    const Eigen::Vector3d grad = u.cwiseQuotient(e.radii);  // normal direction, unnormalised
    if (unit(rng) > grad.norm() * min_radius) continue;
    out.push_back({e.center + turn(u.cwiseProduct(e.radii), e.yaw), turn(grad.normalized(), e.yaw)});
    ++kept;
  }
}

void sample(const GroundPatch& g, double spacing, std::mt19937_64& rng, std::vector<SurfaceSample>& out) {
  const Eigen::Vector3d n_local = Eigen::Vector3d(-g.slope.x(), -g.slope.y(), 1.0).normalized();
  const Eigen::Vector3d n = turn(n_local, g.yaw);
  stratified(2.0 * g.half_size.x(), 2.0 * g.half_size.y(), spacing, rng, [&](double u, double v) {
    const double x = (2.0 * u - 1.0) * g.half_size.x();
    const double y = (2.0 * v - 1.0) * g.half_size.y();
    const Eigen::Vector3d local(x, y, g.slope.x() * x + g.slope.y() * y);
    out.push_back({g.center + turn(local, g.yaw), n});
  });
}

void require(bool ok, const std::string& what, const std::string& problem) {
  if (!ok) throw Error(what + ": " + problem);
}

}  // namespace

std::optional<double> intersect(const Shape& shape, const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                                double t_max) {
  return std::visit([&](const auto& s) { return first_crossing(span_of(s, origin, direction), t_max); }, shape);
}

bool contains(const Shape& shape, const Eigen::Vector3d& point) {
  struct Visitor {
    const Eigen::Vector3d& p;
    bool operator()(const Box& b) const {
      const Eigen::Vector3d l = unturn(p - b.center, b.yaw);
      return (l.cwiseAbs().array() <= b.half_size.array()).all();
    }
    bool operator()(const Cylinder& c) const {
      return p.z() >= c.z_min && p.z() <= c.z_max && (p.head<2>() - c.center_xy).squaredNorm() <= c.radius * c.radius;
    }
    bool operator()(const Ellipsoid& e) const {
      return unturn(p - e.center, e.yaw).cwiseQuotient(e.radii).squaredNorm() <= 1.0;
    }
    bool operator()(const GroundPatch& g) const {
      const Eigen::Vector3d l = unturn(p - g.center, g.yaw);
      const double h = height_above(g, l);
      return std::abs(l.x()) <= g.half_size.x() && std::abs(l.y()) <= g.half_size.y() && h <= 0.0 &&
             h >= -g.thickness;
    }
  };
  return std::visit(Visitor{point}, shape);
}

Eigen::AlignedBox3d bounding_box(const Shape& shape) {
  struct Visitor {
    Eigen::AlignedBox3d operator()(const Box& b) const {
      const double c = std::abs(std::cos(b.yaw));
      const double s = std::abs(std::sin(b.yaw));
      const Eigen::Vector3d e(c * b.half_size.x() + s * b.half_size.y(), s * b.half_size.x() + c * b.half_size.y(),
                              b.half_size.z());
      return {b.center - e, b.center + e};
    }
    Eigen::AlignedBox3d operator()(const Cylinder& c) const {
      return {Eigen::Vector3d(c.center_xy.x() - c.radius, c.center_xy.y() - c.radius, c.z_min),
              Eigen::Vector3d(c.center_xy.x() + c.radius, c.center_xy.y() + c.radius, c.z_max)};
    }
    Eigen::AlignedBox3d operator()(const Ellipsoid& e) const {
      // Exact extent of a yawed ellipsoid along x and y.
      const double c = std::cos(e.yaw);
      const double s = std::sin(e.yaw);
      const double ex = std::hypot(c * e.radii.x(), s * e.radii.y());
      const double ey = std::hypot(s * e.radii.x(), c * e.radii.y());
      const Eigen::Vector3d ext(ex, ey, e.radii.z());
      return {e.center - ext, e.center + ext};
    }
    Eigen::AlignedBox3d operator()(const GroundPatch& g) const {
      Eigen::AlignedBox3d box;
      for (const double sx : {-1.0, 1.0}) {
        for (const double sy : {-1.0, 1.0}) {
          const double x = sx * g.half_size.x();
          const double y = sy * g.half_size.y();
          const double z = g.slope.x() * x + g.slope.y() * y;
          box.extend(g.center + turn(Eigen::Vector3d(x, y, z), g.yaw));
          box.extend(g.center + turn(Eigen::Vector3d(x, y, z - g.thickness), g.yaw));
        }
      }
      return box;
    }
  };
  return std::visit(Visitor{}, shape);
}

Shape placed(const Shape& shape, const Placement& where) {
  struct Visitor {
    const Placement& w;
    Eigen::Vector3d move(const Eigen::Vector3d& p) const { return turn(p, w.yaw) + w.position; }
    Shape operator()(Box b) const {
      b.center = move(b.center);
      b.yaw += w.yaw;
      return b;
    }
    Shape operator()(Cylinder c) const {
      const Eigen::Vector3d p = move(Eigen::Vector3d(c.center_xy.x(), c.center_xy.y(), 0.0));
      c.center_xy = p.head<2>();
      c.z_min += p.z();
      c.z_max += p.z();
      return c;
    }
    Shape operator()(Ellipsoid e) const {
      e.center = move(e.center);
      e.yaw += w.yaw;
      return e;
    }
    Shape operator()(GroundPatch g) const {
      g.center = move(g.center);
      g.yaw += w.yaw;
      return g;
    }
  };
  return std::visit(Visitor{where}, shape);
}

void sample_surface(const Shape& shape, double spacing, std::mt19937_64& rng, std::vector<SurfaceSample>& out) {
  if (!(spacing > 0.0)) throw Error("sample_surface: spacing must be positive, got " + std::to_string(spacing));
  std::visit([&](const auto& s) { sample(s, spacing, rng, out); }, shape);
}

void validate(const Shape& shape, const std::string& what) {
  struct Visitor {
    const std::string& what;
    void operator()(const Box& b) const {
      require(b.center.allFinite() && std::isfinite(b.yaw), what, "box values must be finite");
      require((b.half_size.array() > 0.0).all() && b.half_size.allFinite(), what, "box sizes must be positive");
    }
    void operator()(const Cylinder& c) const {
      require(c.center_xy.allFinite() && std::isfinite(c.z_min) && std::isfinite(c.z_max), what,
              "cylinder values must be finite");
      require(c.radius > 0.0 && std::isfinite(c.radius), what, "cylinder radius must be positive");
      require(c.z_max > c.z_min, what, "cylinder top must be above its bottom");
    }
    void operator()(const Ellipsoid& e) const {
      require(e.center.allFinite() && std::isfinite(e.yaw), what, "ellipsoid values must be finite");
      require((e.radii.array() > 0.0).all() && e.radii.allFinite(), what, "ellipsoid radii must be positive");
    }
    void operator()(const GroundPatch& g) const {
      require(g.center.allFinite() && g.slope.allFinite() && std::isfinite(g.yaw), what,
              "ground patch values must be finite");
      require((g.half_size.array() > 0.0).all() && g.half_size.allFinite(), what,
              "ground patch sizes must be positive");
      require(g.thickness > 0.0 && std::isfinite(g.thickness), what, "ground patch thickness must be positive");
    }
  };
  std::visit(Visitor{what}, shape);
}

}  // namespace hmap::sim
