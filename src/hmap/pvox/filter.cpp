#include "hmap/pvox/filter.hpp"

#include <algorithm>
#include <cmath>

#include "hmap/core/error.hpp"

namespace hmap::pvox {

AxisBelief predict(const AxisBelief& prior, double u, double variance_u) {
  return {prior.mean + u, prior.variance + variance_u};
}

AxisBelief fuse(const AxisBelief& prior, double z, double variance_z) {
  const double sum = prior.variance + variance_z;
  return {(variance_z * prior.mean + prior.variance * z) / sum,  // eq. (8)
          prior.variance * variance_z / sum};                    // eq. (9)
}

PlanarFilter::PlanarFilter(const FilterParams& params, const Eigen::Vector2d& initial_xy) : params_(params) {
  for (const double v : {params.motion_variance, params.measurement_variance, params.initial_variance}) {
    if (!(v > 0.0) || !std::isfinite(v)) throw Error("pvox filter: variances must be positive and finite");
  }
  x_ = {initial_xy.x(), params.initial_variance};
  y_ = {initial_xy.y(), params.initial_variance};
}

void PlanarFilter::predict(const Eigen::Vector2d& u_xy) {
  // BRF keeps the variance of its first posterior: only the mean follows the command.
  const double variance_u = params_.kind == FilterKind::kRecursive ? params_.motion_variance : 0.0;
  x_ = pvox::predict(x_, u_xy.x(), variance_u);
  y_ = pvox::predict(y_, u_xy.y(), variance_u);
}

bool PlanarFilter::wants_measurement() const { return params_.kind == FilterKind::kRecursive || updates_ == 0; }

void PlanarFilter::update(const Eigen::Vector2d& z_xy) {
  if (!wants_measurement()) return;
  x_ = fuse(x_, z_xy.x(), params_.measurement_variance);
  y_ = fuse(y_, z_xy.y(), params_.measurement_variance);
  ++updates_;
}

double PlanarFilter::sigma() const { return std::sqrt(std::max(x_.variance, y_.variance)); }

}  // namespace hmap::pvox
