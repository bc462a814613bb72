#include "hmap/pvox/measure.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <unordered_map>
#include <unordered_set>

#include "hmap/core/error.hpp"

namespace hmap::pvox {

namespace {

/// A flat voxel's vote along the axis.
struct Vote {
  VoxelKey key;
  double value = 0.0;   ///< [m] its mean on the axis
  double weight = 0.0;
  std::uint32_t points = 0;
};

std::int32_t key_at(const VoxelKey& key, int axis) { return axis == 0 ? key.i : axis == 1 ? key.j : key.k; }

double weighted_median(std::vector<std::pair<double, double>> values) {
  std::sort(values.begin(), values.end());
  double total = 0.0;
  for (const auto& [x, w] : values) total += w;
  double acc = 0.0;
  for (const auto& [x, w] : values) {
    acc += w;
    if (acc >= 0.5 * total) return x;
  }
  return values.back().first;
}

/// Peaks of `density` after merging shoulders, and the valley between each consecutive pair.
std::vector<std::size_t> peaks_of(const std::vector<double>& density, double merge_valley) {
  std::vector<std::size_t> peaks;
  for (std::size_t j = 0; j < density.size(); ++j) {
    const double left = j > 0 ? density[j - 1] : 0.0;
    const double right = j + 1 < density.size() ? density[j + 1] : 0.0;
    if (density[j] > 0.0 && density[j] > left && density[j] >= right) peaks.push_back(j);
  }
  for (bool merged = true; merged && peaks.size() > 1;) {
    merged = false;
    for (std::size_t p = 0; p + 1 < peaks.size(); ++p) {
      const std::size_t a = peaks[p];
      const std::size_t b = peaks[p + 1];
      const double valley = *std::min_element(density.begin() + static_cast<std::ptrdiff_t>(a),
                                              density.begin() + static_cast<std::ptrdiff_t>(b) + 1);
      if (valley >= merge_valley * std::min(density[a], density[b])) {
        peaks.erase(peaks.begin() + static_cast<std::ptrdiff_t>(density[a] < density[b] ? p : p + 1));
        merged = true;
        break;
      }
    }
  }
  return peaks;
}

}  // namespace

namespace {

/// Which axes a voxel is flat along (bit a for axis a), and its moments.
struct Flatness {
  VoxelMoments moments;
  std::uint32_t hits = 0;
  unsigned axes = 0;
};

/// Point sums of a set of voxels, to combine their covariance (about `origin`, to keep the
/// subtraction of large numbers away).
struct Moments {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  double n = 0.0;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  Eigen::Matrix3d sum_sq = Eigen::Matrix3d::Zero();
  void add(const VoxelMoments& m, double hits) {
    const Eigen::Vector3d d = m.mean - origin;
    n += hits;
    sum += hits * d;
    sum_sq += hits * (m.covariance + d * d.transpose());
  }
  [[nodiscard]] Eigen::Matrix3d covariance() const {
    const Eigen::Vector3d mean = sum / n;
    return sum_sq / n - mean * mean.transpose();
  }
};

/// The usable voxels of `map` and the axes each is flat along. A voxel is flat along an axis when
///  - its points are thin along it (σ ≤ max_spread·edge);
///  - its own points spread more (1 / max_flatness times) in both in-plane directions: where a
///    face's border lies just past a voxel boundary, the voxel past it holds a sliver of the face
///    (its last centimetre), thin along the axis but as thin across the face, which is no plane
///    across the axis; the slivers of faces ending on one line (two faces meeting at a corner)
///    would look like one in the neighbourhood, at the coordinate of the face they end on, whether
///    that face is in the map or not;
///  - its thin neighbours (of the 26, those thin along the axis with their mean within
///    max_spread·edge of its own, so that a parallel face a few centimetres away, box B's back
///    behind its front, does not count) and it spread in both in-plane directions (min_width),
///    and max_flatness times less along the axis: a scan line, thin across every direction but its
///    own, is no plane.
std::unordered_map<VoxelKey, Flatness, VoxelKeyHash> flatness(const VoxelMap& map, const PlaneDetectionParams& params) {
  std::unordered_map<VoxelKey, Flatness, VoxelKeyHash> voxels;
  map.for_each([&](const VoxelKey& key, const Voxel& voxel) {
    if (voxel.hits < params.min_points) return;
    const VoxelMoments m = VoxelMap::moments(voxel, map.centre(key));
    if (params.region && !params.region->contains(m.mean)) return;
    voxels.emplace(key, Flatness{m, voxel.hits, 0});
  });
  const double e = map.edge();
  const double max_var = params.max_spread * params.max_spread * e * e;
  const double min_var = params.min_width * params.min_width * e * e;
  const auto thin = [&](const Flatness& f, int axis) { return f.moments.covariance(axis, axis) <= max_var; };
  const auto find = [&](const VoxelKey& key) -> const Flatness* {  // nullptr: not usable
    const auto it = voxels.find(key);
    return it == voxels.end() ? nullptr : &it->second;
  };
  std::vector<const Flatness*> around;
  for (auto& [key, f] : voxels) {
    around.clear();
    for (int di = -1; di <= 1; ++di) {
      for (int dj = -1; dj <= 1; ++dj) {
        for (int dk = -1; dk <= 1; ++dk) {
          if (const Flatness* g = find(VoxelKey{key.i + di, key.j + dj, key.k + dk})) around.push_back(g);
        }
      }
    }
    for (int axis = 0; axis < 3; ++axis) {
      if (!thin(f, axis)) continue;
      const double own_in_plane =
          std::min(f.moments.covariance((axis + 1) % 3, (axis + 1) % 3), f.moments.covariance((axis + 2) % 3, (axis + 2) % 3));
      if (!(f.moments.covariance(axis, axis) <= params.max_flatness * own_in_plane)) continue;
      Moments sums{f.moments.mean};
      for (const Flatness* g : around) {
        if (thin(*g, axis) && std::abs(g->moments.mean[axis] - f.moments.mean[axis]) <= params.max_spread * e) {
          sums.add(g->moments, g->hits);
        }
      }
      const Eigen::Matrix3d c = sums.covariance();
      const double in_plane = std::min(c((axis + 1) % 3, (axis + 1) % 3), c((axis + 2) % 3, (axis + 2) % 3));
      if (c(axis, axis) <= max_var && in_plane >= min_var && c(axis, axis) <= params.max_flatness * in_plane) {
        f.axes |= 1U << axis;
      }
    }
  }
  return voxels;
}

}  // namespace

std::vector<DetectedPlane> detect_planes(const VoxelMap& map, int axis, const PlaneDetectionParams& params) {
  if (axis < 0 || axis > 2) throw Error("detect_planes: the axis must be 0, 1 or 2");
  if (!(params.bandwidth > 0.0) || !(params.bin > 0.0)) throw Error("detect_planes: bandwidth and bin must be positive");
  const double e = map.edge();
  const auto voxels = flatness(map, params);

  // Votes of the flat voxels.
  std::vector<Vote> votes;
  const double floor_sigma = 0.05 * e;
  for (const auto& [key, f] : voxels) {
    if ((f.axes & (1U << axis)) == 0) continue;
    const double var = f.moments.covariance(axis, axis);
    votes.push_back({key, f.moments.mean[axis], static_cast<double>(f.hits) / (var + floor_sigma * floor_sigma), f.hits});
  }
  if (votes.empty()) return {};
  // Sorted so that clusters, coordinates and voxels do not depend on the hash order.
  std::sort(votes.begin(), votes.end(), [](const Vote& a, const Vote& b) { return a.key < b.key; });

  // The density of the votes along the axis: Gaussian kernels of σ h on bins.
  double lo = std::numeric_limits<double>::infinity();
  double hi = -lo;
  for (const Vote& vote : votes) {
    lo = std::min(lo, vote.value);
    hi = std::max(hi, vote.value);
  }
  const double h = params.bandwidth * e;
  const double reach = 3.0 * h;
  lo -= reach;
  hi += reach;
  const double bin = std::max(params.bin, (hi - lo) / 1e6);
  const auto bins = static_cast<std::size_t>(std::ceil((hi - lo) / bin)) + 1;
  const auto bin_of = [&](double x) {
    return std::min(bins - 1, static_cast<std::size_t>(std::max(0.0, std::floor((x - lo) / bin))));
  };
  std::vector<double> density(bins, 0.0);
  for (const Vote& vote : votes) {
    const std::size_t first = bin_of(vote.value - reach);
    const std::size_t last = bin_of(vote.value + reach);
    for (std::size_t j = first; j <= last; ++j) {
      const double d = (lo + (static_cast<double>(j) + 0.5) * bin - vote.value) / h;
      density[j] += vote.weight * std::exp(-0.5 * d * d);
    }
  }

  // Each peak is a plane; its votes reach to the lowest density between it and the next peak.
  const std::vector<std::size_t> peaks = peaks_of(density, params.merge_valley);
  std::vector<std::size_t> bounds;  // first bin of cluster c + 1
  for (std::size_t p = 0; p + 1 < peaks.size(); ++p) {
    const auto first = density.begin() + static_cast<std::ptrdiff_t>(peaks[p]);
    const auto last = density.begin() + static_cast<std::ptrdiff_t>(peaks[p + 1]) + 1;
    bounds.push_back(static_cast<std::size_t>(std::min_element(first, last) - density.begin()));
  }
  std::vector<std::vector<const Vote*>> clusters(peaks.size());
  for (const Vote& vote : votes) {
    const std::size_t c = static_cast<std::size_t>(std::upper_bound(bounds.begin(), bounds.end(), bin_of(vote.value)) - bounds.begin());
    clusters[c].push_back(&vote);
  }

  // A plane is the coherent part of a cluster: its connected pieces (26-neighbourhood) of at least
  // min_voxels voxels that spread in both in-plane directions (min_width). Flat voxels scattered
  // over the map that happen to share a coordinate (single scan lines, a map doubled by drift) are
  // no face.
  const int u = (axis + 1) % 3;
  const int w = (axis + 2) % 3;
  const double min_var = params.min_width * params.min_width * e * e;
  std::vector<DetectedPlane> planes;
  for (const auto& cluster : clusters) {
    std::unordered_map<VoxelKey, const Vote*, VoxelKeyHash> left;
    for (const Vote* vote : cluster) left.emplace(vote->key, vote);
    std::vector<const Vote*> kept;
    for (const Vote* seed : cluster) {
      if (!left.contains(seed->key)) continue;
      std::vector<const Vote*> piece{seed};
      left.erase(seed->key);
      for (std::size_t q = 0; q < piece.size(); ++q) {
        const VoxelKey at = piece[q]->key;
        for (int di = -1; di <= 1; ++di) {
          for (int dj = -1; dj <= 1; ++dj) {
            for (int dk = -1; dk <= 1; ++dk) {
              const auto it = left.find(VoxelKey{at.i + di, at.j + dj, at.k + dk});
              if (it == left.end()) continue;
              piece.push_back(it->second);
              left.erase(it);
            }
          }
        }
      }
      if (piece.size() < std::max<std::size_t>(1, params.min_voxels)) continue;
      Moments sums{voxels.at(seed->key).moments.mean};
      for (const Vote* vote : piece) sums.add(voxels.at(vote->key).moments, vote->points);
      const Eigen::Matrix3d c = sums.covariance();
      if (std::min(c(u, u), c(w, w)) < min_var) continue;
      kept.insert(kept.end(), piece.begin(), piece.end());
    }
    if (kept.empty()) continue;
    std::sort(kept.begin(), kept.end(), [](const Vote* a, const Vote* b) { return a->key < b->key; });
    DetectedPlane plane;
    plane.axis = axis;
    std::vector<std::pair<double, double>> values;
    for (const Vote* vote : kept) {
      values.emplace_back(vote->value, vote->weight);
      plane.points += vote->points;
      plane.voxels.push_back(vote->key);
    }
    plane.flat_voxels = kept.size();
    plane.coordinate = weighted_median(std::move(values));
    planes.push_back(std::move(plane));
  }

  // Each plane takes the neighbours of its flat voxels that lie within its slab (never past
  // half-way to the next plane) and are flat along no axis: the voxels at its borders, which touch
  // other faces. Its extent is that of its voxels.
  for (std::size_t p = 0; p < planes.size(); ++p) {
    DetectedPlane& plane = planes[p];
    double below = params.slab * e;
    double above = params.slab * e;
    if (p > 0) below = std::min(below, 0.5 * (plane.coordinate - planes[p - 1].coordinate));
    if (p + 1 < planes.size()) above = std::min(above, 0.5 * (planes[p + 1].coordinate - plane.coordinate));
    std::unordered_set<VoxelKey, VoxelKeyHash> taken(plane.voxels.begin(), plane.voxels.end());
    const std::size_t flat = plane.voxels.size();
    for (std::size_t v = 0; v < flat; ++v) {
      const VoxelKey at = plane.voxels[v];
      for (int di = -1; di <= 1; ++di) {
        for (int dj = -1; dj <= 1; ++dj) {
          for (int dk = -1; dk <= 1; ++dk) {
            const VoxelKey next{at.i + di, at.j + dj, at.k + dk};
            const auto it = voxels.find(next);
            if (it == voxels.end() || it->second.axes != 0 || taken.contains(next)) continue;
            const double offset = it->second.moments.mean[axis] - plane.coordinate;
            if (offset < -below || offset > above) continue;
            taken.insert(next);
            plane.voxels.push_back(next);
          }
        }
      }
    }
    std::sort(plane.voxels.begin(), plane.voxels.end());
    for (const VoxelKey& key : plane.voxels) {
      const VoxelMoments& m = voxels.at(key).moments;
      const Eigen::Vector3d half = (3.0 * m.covariance.diagonal()).cwiseSqrt();
      plane.extent.extend(m.mean - half);
      plane.extent.extend(m.mean + half);
    }
  }
  return planes;
}

std::optional<double> plane_end(const VoxelMap& map, const DetectedPlane& plane, int along, int side) {
  if (along < 0 || along > 2 || along == plane.axis) throw Error("plane_end: `along` must be an axis in the plane");
  const int third = 3 - plane.axis - along;
  // Per row (key on the third axis): the outermost voxel along `along` and its end estimate.
  std::map<std::int32_t, std::pair<std::int32_t, double>> rows;
  for (const VoxelKey& key : plane.voxels) {
    const Voxel* voxel = map.find(key);
    if (voxel == nullptr) continue;
    const VoxelMoments m = VoxelMap::moments(*voxel, map.centre(key));
    const std::int32_t rank = side < 0 ? -key_at(key, along) : key_at(key, along);
    const double end = m.mean[along] + (side < 0 ? -1.0 : 1.0) * std::sqrt(3.0 * m.covariance(along, along));
    auto [it, inserted] = rows.try_emplace(key_at(key, third), rank, end);
    if (!inserted && rank > it->second.first) it->second = {rank, end};
  }
  if (rows.empty()) return std::nullopt;
  std::vector<double> ends;
  ends.reserve(rows.size());
  for (const auto& [row, best] : rows) ends.push_back(best.second);
  std::nth_element(ends.begin(), ends.begin() + static_cast<std::ptrdiff_t>(ends.size() / 2), ends.end());
  return ends[ends.size() / 2];
}

double face_gate(const std::vector<double>& nominal, std::size_t i, double max_gate) {
  double gate = max_gate;
  for (std::size_t j = 0; j < nominal.size(); ++j) {
    if (j != i) gate = std::min(gate, 0.5 * std::abs(nominal[j] - nominal[i]));
  }
  return gate;
}

std::vector<std::optional<std::size_t>> associate_faces(const std::vector<DetectedPlane>& planes,
                                                        const std::vector<double>& nominal, double max_gate) {
  std::vector<std::optional<std::size_t>> out(nominal.size());
  for (std::size_t i = 0; i < nominal.size(); ++i) {
    const double gate = face_gate(nominal, i, max_gate);
    double best = std::numeric_limits<double>::infinity();
    for (std::size_t p = 0; p < planes.size(); ++p) {
      const double d = std::abs(planes[p].coordinate - nominal[i]);
      // Strictly inside the gate: a plane half-way between two faces serves neither.
      if (d < gate && d < best) {
        best = d;
        out[i] = p;
      }
    }
  }
  return out;
}

}  // namespace hmap::pvox
