#include "hmap/occupancy/traversability.hpp"

#include <algorithm>
#include <climits>
#include <cmath>
#include <limits>
#include <string>

#include "hmap/core/error.hpp"

namespace hmap {

namespace {
void require(bool ok, const char* name, double value, const char* range) {
  if (!ok) throw Error(std::string("traversability: ") + name + " = " + std::to_string(value) + " is out of range " + range);
}
constexpr double kPi = 3.14159265358979323846;
}  // namespace

void validate(const TraversabilityParams& p) {
  require(p.max_step > 0.0 && p.max_step <= 10.0, "max_step", p.max_step, "(0, 10] m");
  require(p.max_slope_deg > 0.0 && p.max_slope_deg <= 90.0, "max_slope_deg", p.max_slope_deg, "(0, 90] deg");
  require(p.reading.free_at_most > 0.0 && p.reading.free_at_most < p.reading.occupied_above &&
              p.reading.occupied_above < 1.0,
          "reading.free_at_most", p.reading.free_at_most, "0 < free_at_most < occupied_above < 1");
  require(p.ground_reach > 0.0 && p.ground_reach <= 1000.0, "ground_reach", p.ground_reach, "(0, 1000] m");
  require(p.inflation_radius >= 0.0 && p.inflation_radius <= 100.0, "inflation_radius", p.inflation_radius,
          "[0, 100] m");
  require(p.cost_scaling >= 0.0 && p.cost_scaling <= 1000.0, "cost_scaling", p.cost_scaling, "[0, 1000] 1/m");
}

TraversabilityLayers traversability(const OccupancyGrid& grid, const GroundModel& ground, const TraversabilityParams& p,
                                    std::size_t max_cells) {
  validate(p);
  TraversabilityLayers out;
  out.cell_size = grid.cell_size();
  long i_min = LONG_MAX, i_max = LONG_MIN, j_min = LONG_MAX, j_max = LONG_MIN;
  grid.for_each_cell([&](const CellKey& k, float) {
    i_min = std::min<long>(i_min, k.i);
    i_max = std::max<long>(i_max, k.i);
    j_min = std::min<long>(j_min, k.j);
    j_max = std::max<long>(j_max, k.j);
  });
  if (i_min > i_max) return out;  // nothing known: empty layers
  const long width = i_max - i_min + 1;
  const long height = j_max - j_min + 1;
  if (static_cast<double>(width) * static_cast<double>(height) > static_cast<double>(max_cells)) {
    throw Error("traversability: the grid spans " + std::to_string(width) + " x " + std::to_string(height) +
                " cells, more than the limit of " + std::to_string(max_cells));
  }
  out.i_min = static_cast<std::int32_t>(i_min);
  out.j_min = static_cast<std::int32_t>(j_min);
  out.width = static_cast<std::int32_t>(width);
  out.height = static_cast<std::int32_t>(height);
  const std::size_t n = static_cast<std::size_t>(width * height);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  out.ground_z.assign(n, nan);
  out.slope_deg.assign(n, nan);
  out.step.assign(n, nan);
  out.cost.assign(n, TraversabilityLayers::kUnknown);
  const double cell = out.cell_size;

  // The local ground: the nearest patch's plane, within reach of its square.
  for (std::int32_t row = 0; row < out.height; ++row) {
    for (std::int32_t col = 0; col < out.width; ++col) {
      const double x = (out.i_min + col + 0.5) * cell;
      const double y = (out.j_min + row + 0.5) * cell;
      const GroundPatch* patch = ground.nearest(x, y);
      if (patch == nullptr ||
          (patch->center.head<2>() - Eigen::Vector2d(x, y)).cwiseAbs().maxCoeff() - patch->half_size > p.ground_reach) {
        continue;
      }
      const std::size_t k = out.index(col, row);
      out.ground_z[k] = static_cast<float>(patch->height_at(x, y));
      out.slope_deg[k] = static_cast<float>(std::acos(std::clamp(std::abs(patch->normal.z()), 0.0, 1.0)) * 180.0 / kPi);
    }
  }
  // Steps: the largest difference to a neighbour's ground.
  for (std::int32_t row = 0; row < out.height; ++row) {
    for (std::int32_t col = 0; col < out.width; ++col) {
      const float g = out.ground_z[out.index(col, row)];
      if (std::isnan(g)) continue;
      float step = 0.0F;
      for (int dr = -1; dr <= 1; ++dr) {
        for (int dc = -1; dc <= 1; ++dc) {
          const std::int32_t c2 = col + dc;
          const std::int32_t r2 = row + dr;
          if (c2 < 0 || r2 < 0 || c2 >= out.width || r2 >= out.height) continue;
          const float g2 = out.ground_z[out.index(c2, r2)];
          if (!std::isnan(g2)) step = std::max(step, std::abs(g2 - g));
        }
      }
      out.step[out.index(col, row)] = step;
    }
  }
  // The cost.
  for (std::int32_t row = 0; row < out.height; ++row) {
    for (std::int32_t col = 0; col < out.width; ++col) {
      const std::size_t k = out.index(col, row);
      const auto prob = grid.probability_at({out.i_min + col, out.j_min + row});
      const bool has_ground = !std::isnan(out.ground_z[k]);
      if (!prob && !has_ground) continue;
      double term = 0.0;
      if (prob) {
        // The reading's classes (with its slack), so lethal and grid-free cells are the PGM's.
        const CellClass c = p.reading.classify(*prob);
        if (c == CellClass::kOccupied) {
          out.cost[k] = 100;
          continue;
        }
        if (c == CellClass::kUndecided) {
          term = (*prob - p.reading.free_at_most) / (p.reading.occupied_above - p.reading.free_at_most);
        }
      }
      if (has_ground) {
        term = std::max({term, out.step[k] / p.max_step, out.slope_deg[k] / p.max_slope_deg});
      }
      out.cost[k] = term >= 1.0 ? std::uint8_t{100} : static_cast<std::uint8_t>(std::lround(99.0 * term));
    }
  }
  // Inflation around lethal cells (a brute-force window: radii are a few cells).
  if (p.inflation_radius > 0.0) {
    const int r = static_cast<int>(std::floor(p.inflation_radius / cell));
    std::vector<std::uint8_t> inflated = out.cost;
    for (std::int32_t row = 0; row < out.height; ++row) {
      for (std::int32_t col = 0; col < out.width; ++col) {
        if (out.cost[out.index(col, row)] != 100) continue;
        for (int dr = -r; dr <= r; ++dr) {
          for (int dc = -r; dc <= r; ++dc) {
            const std::int32_t c2 = col + dc;
            const std::int32_t r2 = row + dr;
            if (c2 < 0 || r2 < 0 || c2 >= out.width || r2 >= out.height) continue;
            const double d = std::hypot(dc, dr) * cell;
            if (d > p.inflation_radius || d == 0.0) continue;
            std::uint8_t& slot = inflated[out.index(c2, r2)];
            if (slot == TraversabilityLayers::kUnknown || slot == 100) continue;
            const auto c = static_cast<std::uint8_t>(std::lround(99.0 * std::exp(-p.cost_scaling * d)));
            slot = std::max(slot, c);
          }
        }
      }
    }
    out.cost = std::move(inflated);
  }
  return out;
}

}  // namespace hmap
