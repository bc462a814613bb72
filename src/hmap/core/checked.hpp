#pragma once
// Conversions of a double (from data or parameters) to an integer that cannot overflow: a
// static_cast of 1e12 to int is undefined behaviour, and a NaN casts to anything.

#include <cmath>
#include <limits>
#include <optional>
#include <string>

#include "hmap/core/error.hpp"
#include "hmap/core/format.hpp"

namespace hmap {

/// `v` rounded toward negative infinity as an Int, or nothing when it is not finite or Int cannot
/// hold it.
template <typename Int>
[[nodiscard]] std::optional<Int> floor_to(double v) {
  const double f = std::floor(v);
  // [lowest, 2^digits): both bounds are exact in a double, so the cast below is defined.
  if (!(f >= static_cast<double>(std::numeric_limits<Int>::lowest()) &&
        f < std::ldexp(1.0, std::numeric_limits<Int>::digits))) {
    return std::nullopt;
  }
  return static_cast<Int>(f);
}

/// `v` rounded up as an Int, or nothing when it is not finite or Int cannot hold it.
template <typename Int>
[[nodiscard]] std::optional<Int> ceil_to(double v) {
  return floor_to<Int>(std::ceil(v));
}

/// `v` rounded toward negative infinity as an Int; hmap::Error saying `what` it is otherwise. For
/// values a check before has bounded (a pose within 10^9 cells), once per scan, not per point:
/// inner loops use floor_to and drop what it refuses.
template <typename Int>
[[nodiscard]] Int checked_floor(double v, const char* what) {
  const std::optional<Int> n = floor_to<Int>(v);
  if (!n) throw Error(std::string(what) + " " + format("%.6g", v) + " does not fit a " + std::to_string(std::numeric_limits<Int>::digits + (std::numeric_limits<Int>::is_signed ? 1 : 0)) + "-bit integer");
  return *n;
}

/// `v` rounded up as an Int in [0, limit]; hmap::Error saying `what` it counts otherwise
/// ("the coarse search in yaw needs 2e+12 steps, at most 64").
template <typename Int>
[[nodiscard]] Int checked_count(double v, Int limit, const std::string& what) {
  const std::optional<Int> n = ceil_to<Int>(v);
  if (!n || *n < 0 || *n > limit) {
    throw Error(what + " needs " + (std::isfinite(v) ? format("%.6g", std::ceil(v)) : std::string("a non-finite number of")) +
                " steps, at most " + std::to_string(limit));
  }
  return *n;
}

}  // namespace hmap
