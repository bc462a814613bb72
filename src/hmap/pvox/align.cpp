#include "hmap/pvox/align.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <vector>
// nanoflann trips GCC 12's -Wmaybe-uninitialized inside the header; silence it for this file.
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#include <nanoflann.hpp>

namespace hmap::pvox {

namespace {

struct Plane {
  Eigen::Vector3d mean;
  Eigen::Vector3d normal;
};

struct PlaneCloud {
  const std::vector<Plane>* planes;
  [[nodiscard]] std::size_t kdtree_get_point_count() const { return planes->size(); }
  [[nodiscard]] double kdtree_get_pt(std::size_t i, std::size_t dim) const {
    return (*planes)[i].mean[static_cast<Eigen::Index>(dim)];
  }
  template <class Box>
  bool kdtree_get_bbox(Box& /*box*/) const {
    return false;
  }
};

using Tree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, PlaneCloud>, PlaneCloud, 3,
                                                 std::uint32_t>;

}  // namespace

AlignResult align_xy(const VoxelMap& map, const PointCloud& points_sensor, const Pose& T_guess, const AlignParams& params) {
  AlignResult result;
  // The planes of the map. A voxel's own points can be a single scan line (a sweeping scanner
  // draws lines, far apart at range), so each plane is fitted to the points of the voxel and its
  // 26 neighbours (their moments combined), anchored at the voxel's own mean.
  std::vector<Plane> planes;
  planes.reserve(map.voxel_count());
  map.for_each([&](const VoxelKey& key, const Voxel& v) {
    if (v.hits < params.min_voxel_points) return;
    const Eigen::Vector3d c = map.centre(key);
    double n = 0.0;
    Eigen::Vector3d s = Eigen::Vector3d::Zero();
    Eigen::Matrix3d ss = Eigen::Matrix3d::Zero();
    for (int di = -1; di <= 1; ++di) {
      for (int dj = -1; dj <= 1; ++dj) {
        for (int dk = -1; dk <= 1; ++dk) {
          const VoxelKey nk{key.i + di, key.j + dj, key.k + dk};
          const Voxel* w = map.find(nk);
          if (w == nullptr || w->hits == 0) continue;
          // Sums about the neighbour's centre, moved to sums about c: d' = d + δ.
          const Eigen::Vector3d delta = map.centre(nk) - c;
          const double m = w->hits;
          const Eigen::Vector3d sw(w->sum[0], w->sum[1], w->sum[2]);
          Eigen::Matrix3d ssw;
          ssw << w->sum_sq[0], w->sum_sq[1], w->sum_sq[2], w->sum_sq[1], w->sum_sq[3], w->sum_sq[4], w->sum_sq[2],
              w->sum_sq[4], w->sum_sq[5];
          n += m;
          s += sw + m * delta;
          ss += ssw + sw * delta.transpose() + delta * sw.transpose() + m * delta * delta.transpose();
        }
      }
    }
    if (n < static_cast<double>(params.min_plane_points)) return;
    const Eigen::Vector3d mean = s / n;
    const Eigen::Matrix3d covariance = ss / n - mean * mean.transpose();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(covariance);
    const Eigen::Vector3d lambda = eig.eigenvalues();  // ascending
    if (!(lambda[0] <= params.flatness * lambda[1])) return;
    planes.push_back({VoxelMap::moments(v, c).mean, eig.eigenvectors().col(0)});
  });
  result.planes = planes.size();
  if (planes.size() < 3) return result;
  const PlaneCloud cloud{&planes};
  Tree tree(3, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(10));
  tree.buildIndex();

  // The scan in the map frame at the guess, evenly subsampled.
  std::vector<Eigen::Vector3d> source;
  const std::size_t stride = std::max<std::size_t>(1, points_sensor.size() / std::max<std::size_t>(1, params.max_points));
  source.reserve(points_sensor.size() / stride + 1);
  for (std::size_t i = 0; i < points_sensor.size(); i += stride) {
    const Eigen::Vector3d p = points_sensor[i].cast<double>();
    if (p.allFinite()) source.push_back(T_guess * p);
  }

  Eigen::Vector2d t = Eigen::Vector2d::Zero();
  for (int it = 0; it < params.max_iterations; ++it) {
    const double w_gate = std::min(1.0, static_cast<double>(it) / 10.0);
    const double gate = params.max_distance + w_gate * (params.min_distance - params.max_distance);
    Eigen::Matrix2d H = Eigen::Matrix2d::Zero();
    Eigen::Vector2d g = Eigen::Vector2d::Zero();
    double sum_sq = 0.0;
    std::size_t used = 0;
    for (const Eigen::Vector3d& p0 : source) {
      const Eigen::Vector3d q(p0.x() + t.x(), p0.y() + t.y(), p0.z());
      std::uint32_t index = 0;
      double d2 = 0.0;
      nanoflann::KNNResultSet<double, std::uint32_t> knn(1);
      knn.init(&index, &d2);
      tree.findNeighbors(knn, q.data(), nanoflann::SearchParams());
      if (knn.size() == 0 || d2 > gate * gate) continue;
      const Plane& pl = planes[index];
      const double r = pl.normal.dot(q - pl.mean);
      const Eigen::Vector2d J(pl.normal.x(), pl.normal.y());
      const double w = std::abs(r) <= params.huber ? 1.0 : params.huber / std::abs(r);
      H += w * J * J.transpose();
      g += w * J * r;
      sum_sq += r * r;
      ++used;
    }
    result.iterations = it + 1;
    result.correspondences = used;
    if (used < 10) return AlignResult{Eigen::Vector2d::Zero(), false, false, it + 1, used, planes.size(), 0.0};
    result.rms = std::sqrt(sum_sq / static_cast<double>(used));
    // A little damping keeps a corridor (no constraint along it) from running away.
    H += Eigen::Matrix2d::Identity() * (1e-6 * H.trace() + 1e-12);
    const Eigen::Vector2d step = -H.ldlt().solve(g);
    t += step;
    if (step.norm() < params.convergence && w_gate >= 1.0) {
      result.converged = true;
      break;
    }
  }
  if (!(t.norm() <= params.max_offset) || !t.allFinite()) {
    result.converged = false;
    return result;
  }
  result.offset = t;
  result.valid = true;
  return result;
}

}  // namespace hmap::pvox
