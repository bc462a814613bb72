#include "hmap/slam/place_descriptor.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "hmap/core/error.hpp"

namespace hmap::slam {

PlaceDescriptor describe_place(const HMap& map, const PlanarPose& place, const PlaceDescriptorOptions& options) {
  if (!(options.radius > 0.0 && options.radius <= 500.0)) throw Error("place descriptor: radius must be in (0, 500] m");
  if (options.rings < 1 || options.rings > 200) throw Error("place descriptor: rings must be in [1, 200]");
  if (options.sectors < 4 || options.sectors > 720) throw Error("place descriptor: sectors must be in [4, 720]");
  PlaceDescriptor d;
  d.rings = options.rings;
  d.sectors = options.sectors;
  const std::size_t bins = static_cast<std::size_t>(d.rings * d.sectors);
  std::vector<float> top(bins, std::numeric_limits<float>::lowest());
  std::vector<float> bottom(bins, std::numeric_limits<float>::max());
  const double c = std::cos(place.yaw);
  const double s = std::sin(place.yaw);
  const double ring_width = options.radius / d.rings;
  const double sector_width = 2.0 * std::numbers::pi / d.sectors;
  // Only the tiles near the place are visited; each column falls in the bin of its centre.
  map.for_each_column([&](const CellKey& key, const ColumnView& column) {
    const Eigen::Vector2d at = map.cell_center(key);
    const double dx = at.x() - place.x;
    const double dy = at.y() - place.y;
    const double r = std::hypot(dx, dy);
    if (r >= options.radius) return;
    // The bearing in the place's frame, in [0, 2π).
    double bearing = std::atan2(-s * dx + c * dy, c * dx + s * dy);
    if (bearing < 0.0) bearing += 2.0 * std::numbers::pi;
    const int ring = std::min(d.rings - 1, static_cast<int>(r / ring_width));
    const int sector = std::min(d.sectors - 1, static_cast<int>(bearing / sector_width));
    const std::size_t bin = static_cast<std::size_t>(ring * d.sectors + sector);
    const HVoxel* v = column.data();
    top[bin] = std::max(top[bin], v[column.size() - 1].z_max);
    bottom[bin] = std::min(bottom[bin], v[0].z_min);
  });
  d.cells.assign(bins, 0.0f);
  d.ring_key.assign(static_cast<std::size_t>(d.rings), 0.0f);
  for (std::size_t b = 0; b < bins; ++b) {
    if (top[b] >= bottom[b]) d.cells[b] = top[b] - bottom[b];
  }
  for (int ring = 0; ring < d.rings; ++ring) {
    float sum = 0.0f;
    for (int sector = 0; sector < d.sectors; ++sector) sum += d.at(ring, sector);
    d.ring_key[static_cast<std::size_t>(ring)] = sum / static_cast<float>(d.sectors);
  }
  return d;
}

double ring_key_distance(const PlaceDescriptor& a, const PlaceDescriptor& b) {
  if (a.rings != b.rings) throw Error("place descriptors of different sizes");
  double sum = 0.0;
  for (std::size_t k = 0; k < a.ring_key.size(); ++k) sum += std::abs(a.ring_key[k] - b.ring_key[k]);
  return a.ring_key.empty() ? 0.0 : sum / static_cast<double>(a.ring_key.size());
}

PlaceMatch compare_places(const PlaceDescriptor& a, const PlaceDescriptor& b) {
  if (a.rings != b.rings || a.sectors != b.sectors) throw Error("place descriptors of different sizes");
  PlaceMatch best;
  // Each sector is a column of `rings` heights; the distance of a shift is the mean of
  // 1 − cos between a's sector s + shift and b's sector s, over the sectors occupied in both.
  std::vector<double> norm_a(static_cast<std::size_t>(a.sectors), 0.0);
  std::vector<double> norm_b(static_cast<std::size_t>(b.sectors), 0.0);
  for (int s = 0; s < a.sectors; ++s) {
    for (int r = 0; r < a.rings; ++r) {
      norm_a[static_cast<std::size_t>(s)] += static_cast<double>(a.at(r, s)) * a.at(r, s);
      norm_b[static_cast<std::size_t>(s)] += static_cast<double>(b.at(r, s)) * b.at(r, s);
    }
  }
  for (int shift = 0; shift < a.sectors; ++shift) {
    double sum = 0.0;
    int used = 0;
    for (int s = 0; s < b.sectors; ++s) {
      const int sa = (s + shift) % a.sectors;
      const double na = norm_a[static_cast<std::size_t>(sa)];
      const double nb = norm_b[static_cast<std::size_t>(s)];
      if (na <= 0.0 || nb <= 0.0) continue;
      double dot = 0.0;
      for (int r = 0; r < a.rings; ++r) dot += static_cast<double>(a.at(r, sa)) * b.at(r, s);
      sum += 1.0 - dot / std::sqrt(na * nb);
      ++used;
    }
    // Sectors occupied in one only count as unlike (1): a shift that lines up few is no match.
    int occupied = 0;
    for (int s = 0; s < b.sectors; ++s) {
      occupied += (norm_a[static_cast<std::size_t>((s + shift) % a.sectors)] > 0.0 || norm_b[static_cast<std::size_t>(s)] > 0.0) ? 1 : 0;
    }
    if (occupied == 0) continue;
    const double distance = (sum + static_cast<double>(occupied - used)) / occupied;
    if (distance < best.distance) {
      best.distance = distance;
      best.shift = shift;
    }
  }
  const int signed_shift = best.shift > a.sectors / 2 ? best.shift - a.sectors : best.shift;
  best.yaw = signed_shift * 2.0 * std::numbers::pi / a.sectors;
  return best;
}

}  // namespace hmap::slam
