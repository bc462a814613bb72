#pragma once
// Exact 2D grid traversal (Amanatides & Woo): every cell a segment crosses, in order, with the
// segment parameters t where it enters and leaves the cell. Allocates nothing.
//
// Two walks: traverse_2d accumulates the crossing parameters (the classic form, used by Alg. 3);
// traverse_2d_from computes each from its grid line's index, so it can start anywhere along the
// segment and still visit exactly the cells, and t values, of the whole walk.

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

namespace detail {

/// One axis of traverse_2d_from: crossing(n) is the t at which the segment meets the n-th grid line
/// after its start cell, a pure function of n (so of the cell), monotone in n, +inf past the end.
struct WalkAxis {
  double g0 = 0.0;         // start coordinate [cells]
  double inv_d = 0.0;      // 1 / (end − start) [1/cells]
  double first_line = 0.0; // the grid line met first [cells]
  double step = 1.0;       // +1 or −1
  long steps = 0;          // grid lines between the start and the end cell

  WalkAxis(double g_start, double g_end, std::int32_t key_start, std::int32_t key_end) : g0(g_start) {
    const double d = g_end - g_start;
    steps = std::labs(static_cast<long>(key_end) - key_start);
    if (steps == 0) return;  // no line to cross (d may still be nonzero inside one cell column)
    inv_d = 1.0 / d;
    step = d > 0.0 ? 1.0 : -1.0;
    first_line = d > 0.0 ? static_cast<double>(key_start) + 1.0 : static_cast<double>(key_start);
  }
  [[nodiscard]] double crossing(long n) const {
    return n < steps ? (first_line + step * static_cast<double>(n) - g0) * inv_d
                     : std::numeric_limits<double>::infinity();
  }
  /// How many crossings come before t: #{n : crossing(n) < t}. An estimate, then exact steps.
  [[nodiscard]] long count_before(double t) const {
    if (steps == 0 || !(t > 0.0)) return 0;
    const double estimate = t * std::abs(1.0 / inv_d) - std::abs(first_line - g0);
    long n = estimate <= 0.0 ? 0 : estimate >= static_cast<double>(steps) ? steps : static_cast<long>(estimate);
    while (n > 0 && crossing(n - 1) >= t) --n;
    while (n < steps && crossing(n) < t) ++n;
    return n;
  }
};

}  // namespace detail

/// The walk of traverse_2d from the first cell whose t_out >= t_start on (t_start <= 0: the whole
/// walk; t_start > 1: nothing). visit(CellKey key, double t_in, double t_out) as traverse_2d's.
/// Each crossing's t is computed from its grid line, never accumulated, and the axis whose line
/// comes first is stepped (at a tie, j, as traverse_2d does): the sequence is a property of the
/// segment, so starting late gives exactly the tail of the whole walk. It equals traverse_2d's
/// cells except where rounding breaks a tie at a grid corner the other way.
template <typename Visitor>
void traverse_2d_from(double x0, double y0, double x1, double y1, double cell, double t_start, Visitor&& visit) {
  if (t_start > 1.0) return;
  const double gx0 = x0 / cell;
  const double gy0 = y0 / cell;
  const double gx1 = x1 / cell;
  const double gy1 = y1 / cell;
  const CellKey start{static_cast<std::int32_t>(std::floor(gx0)), static_cast<std::int32_t>(std::floor(gy0))};
  const CellKey end{static_cast<std::int32_t>(std::floor(gx1)), static_cast<std::int32_t>(std::floor(gy1))};
  const detail::WalkAxis along_i(gx0, gx1, start.i, end.i);
  const detail::WalkAxis along_j(gy0, gy1, start.j, end.j);
  // The crossings before t_start are a prefix of the merged order: skip them on both axes.
  long n_i = along_i.count_before(t_start);
  long n_j = along_j.count_before(t_start);
  const int step_i = end.i >= start.i ? 1 : -1;
  const int step_j = end.j >= start.j ? 1 : -1;
  CellKey key{start.i + static_cast<std::int32_t>(step_i * n_i), start.j + static_cast<std::int32_t>(step_j * n_j)};
  double t_in = std::min(std::max(n_i > 0 ? along_i.crossing(n_i - 1) : 0.0, n_j > 0 ? along_j.crossing(n_j - 1) : 0.0), 1.0);
  double t_i = along_i.crossing(n_i);
  double t_j = along_j.crossing(n_j);
  while (n_i < along_i.steps || n_j < along_j.steps) {
    const bool step_along_i = t_i < t_j;
    const double t_out = std::min(step_along_i ? t_i : t_j, 1.0);
    if (!visit(static_cast<const CellKey&>(key), t_in, t_out)) return;
    t_in = t_out;
    if (step_along_i) {
      key.i += step_i;
      t_i = along_i.crossing(++n_i);
    } else {
      key.j += step_j;
      t_j = along_j.crossing(++n_j);
    }
  }
  visit(static_cast<const CellKey&>(key), t_in, 1.0);
}

}  // namespace hmap
