#include "hmap/pvox/mapper.hpp"

#include <cmath>

#include "hmap/core/error.hpp"
#include "hmap/core/format.hpp"

namespace hmap::pvox {

namespace {

/// hmap::Error "pvox: NAME = V UNIT is out of its range [lo, hi]" unless lo <= v <= hi (NaN fails).
void require_in(double v, double lo, double hi, const char* name, const char* unit) {
  if (v >= lo && v <= hi) return;
  throw Error(format("pvox: %s = %g%s%s is out of its range [%g, %g]", name, v, *unit ? " " : "", unit, lo, hi));
}

}  // namespace

void PvoxParams::validate() const {
  // Bounded so that what is sized from them stays bounded: an edge of 1e-300 m put every point
  // beyond the key range (an empty map, exit 0), a range of 1e6 m made each ray 10^8 voxels.
  require_in(k_sigma, 1e-3, 1000.0, "k_sigma", "");
  if (fixed_edge != 0.0) require_in(fixed_edge, 1e-4, 100.0, "voxel edge", "m");
  require_in(insert.min_range, 0.0, 1000.0, "min_range", "m");
  require_in(insert.max_range, 0.0, 1000.0, "max_range", "m");
  if (!(insert.max_range > insert.min_range)) throw Error("pvox: need 0 <= min_range < max_range");
  require_in(filter.motion_variance, 0.0, 1e4, "motion variance", "m^2");
  require_in(filter.initial_variance, 0.0, 1e4, "initial variance", "m^2");
  require_in(filter.measurement_variance, 1e-12, 1e4, "measurement variance", "m^2");
  probability.validate();
}

namespace {

double initial_edge(const PvoxParams& p) {
  p.validate();
  // Before the first scan the map is empty; any edge will do until the filter gives one.
  return p.fixed_edge > 0.0 ? p.fixed_edge : p.k_sigma * std::sqrt(p.filter.initial_variance);
}

}  // namespace

PvoxMapper::PvoxMapper(const PvoxParams& params) : params_(params), map_(initial_edge(params), params.probability) {
  map_.set_budget(params.budget);
}

double PvoxMapper::edge_for(double sigma) const {
  return params_.fixed_edge > 0.0 ? params_.fixed_edge : params_.k_sigma * sigma;
}

RegistrationResult PvoxMapper::add_scan(const PointCloud& points_sensor, const Pose& motion,
                                        const std::optional<Eigen::Vector2d>& measured_xy) {
  RegistrationResult r;
  // 1. Predict: the commanded move from the previous posterior pose.
  Pose T_predicted = scans_ == 0 ? motion : T_map_previous_ * motion;
  if (!filter_) {
    filter_.emplace(params_.filter, T_predicted.translation().head<2>());
  } else {
    filter_->predict(T_predicted.translation().head<2>() - T_map_previous_.translation().head<2>());
  }
  r.prior_mean = filter_->mean();
  r.prior_variance = filter_->variance();
  T_predicted.translation().head<2>() = r.prior_mean;

  // 2. Measure: given, or the scan aligned to the map at the prediction.
  if (filter_->wants_measurement()) {
    if (measured_xy) {
      r.measurement = *measured_xy;
    } else if (scans_ == 0) {
      r.measurement = r.prior_mean;
    } else {
      r.align = align_xy(map_, points_sensor, T_predicted, params_.align);
      r.measured_by_alignment = true;
      if (r.align.valid) r.measurement = r.prior_mean + r.align.offset;
    }
    // 3. Update, eq. (8)–(9).
    if (r.measurement) filter_->update(*r.measurement);
  }
  r.posterior_variance = filter_->variance();

  // 4. Voxelate at k·σ of the posterior, register the scan at the posterior mean.
  map_.set_edge(edge_for(filter_->sigma()));
  r.edge = map_.edge();
  r.T_map_sensor = T_predicted;
  r.T_map_sensor.translation().head<2>() = filter_->mean();
  r.insert = map_.insert(points_sensor, r.T_map_sensor, params_.insert);
  T_map_previous_ = r.T_map_sensor;
  ++scans_;
  return r;
}

}  // namespace hmap::pvox
