#include "hmap/io/point_time.hpp"

#include <algorithm>
#include <cmath>

namespace hmap {

std::vector<float> point_times_to_seconds(const std::vector<double>& raw) {
  std::vector<float> out;
  if (raw.empty()) return out;
  const auto [lo, hi] = std::minmax_element(raw.begin(), raw.end());
  const double span = *hi - *lo;
  const double scale = span <= 2.0 ? 1.0 : span <= 2e3 ? 1e-3 : span <= 2e6 ? 1e-6 : 1e-9;
  constexpr double kDay = 86400.0;  // [s] a relative time is never this far from its zero
  const double zero = std::abs(*lo * scale) > kDay ? *lo : 0.0;
  out.reserve(raw.size());
  for (const double t : raw) out.push_back(static_cast<float>((t - zero) * scale));
  return out;
}

}  // namespace hmap
