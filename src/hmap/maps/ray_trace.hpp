#pragma once
// Exact 2D grid traversal (Amanatides & Woo): every cell a segment crosses, in order, with the
// segment parameters t where it enters and leaves the cell. Allocates nothing.

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <limits>

#include "hmap/core/types.hpp"

namespace hmap {

/// Walks the segment from (x0, y0) to (x1, y1) over a grid of `cell` metres, calling
/// visit(CellKey key, double t_in, double t_out) for each crossed cell from the start cell to the
/// end cell inclusive; t runs from 0 at (x0, y0) to 1 at (x1, y1). The visitor returns false to
/// stop. Coordinates must be finite and within the key range (the caller checks).
template <typename Visitor>
void traverse_2d(double x0, double y0, double x1, double y1, double cell, Visitor&& visit) {
  const double gx0 = x0 / cell;
  const double gy0 = y0 / cell;
  const double gx1 = x1 / cell;
  const double gy1 = y1 / cell;
  CellKey key{static_cast<std::int32_t>(std::floor(gx0)), static_cast<std::int32_t>(std::floor(gy0))};
  const CellKey end{static_cast<std::int32_t>(std::floor(gx1)),
                    static_cast<std::int32_t>(std::floor(gy1))};
  const double dx = gx1 - gx0;
  const double dy = gy1 - gy0;
  constexpr double kInf = std::numeric_limits<double>::infinity();
  const int step_i = dx > 0 ? 1 : -1;
  const int step_j = dy > 0 ? 1 : -1;
  // t at which the segment crosses the next vertical / horizontal grid line, and t per cell.
  const double t_delta_i = dx != 0.0 ? std::abs(1.0 / dx) : kInf;
  const double t_delta_j = dy != 0.0 ? std::abs(1.0 / dy) : kInf;
  double t_max_i = dx > 0   ? (key.i + 1 - gx0) / dx
                   : dx < 0 ? (key.i - gx0) / dx
                            : kInf;
  double t_max_j = dy > 0   ? (key.j + 1 - gy0) / dy
                   : dy < 0 ? (key.j - gy0) / dy
                            : kInf;
  // The number of cells is fixed by the end key: floating-point drift cannot loop forever.
  const long n_steps = std::labs(static_cast<long>(end.i) - key.i) + std::labs(static_cast<long>(end.j) - key.j);
  double t_in = 0.0;
  for (long s = 0; s < n_steps; ++s) {
    // Step along the axis whose grid line comes first, never past the end key on either axis.
    const bool along_i = key.i == end.i ? false : key.j == end.j ? true : t_max_i < t_max_j;
    const double t_out = std::min(along_i ? t_max_i : t_max_j, 1.0);
    if (!visit(key, t_in, t_out)) return;
    t_in = t_out;
    if (along_i) {
      key.i += step_i;
      t_max_i += t_delta_i;
    } else {
      key.j += step_j;
      t_max_j += t_delta_j;
    }
  }
  visit(key, t_in, 1.0);
}

}  // namespace hmap
