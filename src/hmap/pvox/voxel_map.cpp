#include "hmap/pvox/voxel_map.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "hmap/core/checked.hpp"
#include "hmap/core/error.hpp"
#include "hmap/core/format.hpp"

namespace hmap::pvox {

// ---------------------------------------------------------------------------------------------
// The probability function

void ProbabilityModel::validate() const {
  if (!(measurement_variance > 0.0) || !std::isfinite(measurement_variance)) {
    throw Error("pvox: measurement_variance must be positive");
  }
  if (!(logit_min < 0.0) || !(logit_max > 0.0) || !std::isfinite(logit_min) || !std::isfinite(logit_max)) {
    throw Error("pvox: need logit_min < 0 < logit_max");
  }
  if (!(miss_logit >= 0.0) || !std::isfinite(miss_logit)) throw Error("pvox: miss_logit must not be negative");
}

double ProbabilityModel::hit_logit(double edge) const {
  return std::log1p(edge * edge / (2.0 * measurement_variance));
}

double ProbabilityModel::logit(double edge, std::uint64_t hits, std::uint64_t misses) const {
  const double l = static_cast<double>(hits) * hit_logit(edge) - static_cast<double>(misses) * miss_logit;
  return std::clamp(l, logit_min, logit_max);
}

double ProbabilityModel::probability(double edge, std::uint64_t hits, std::uint64_t misses) const {
  return 1.0 / (1.0 + std::exp(-logit(edge, hits, misses)));
}

// ---------------------------------------------------------------------------------------------

std::size_t VoxelKeyHash::operator()(const VoxelKey& key) const noexcept {
  std::uint64_t x = static_cast<std::uint64_t>(static_cast<std::uint32_t>(key.i)) * 0x9E3779B97F4A7C15ULL;
  x ^= static_cast<std::uint64_t>(static_cast<std::uint32_t>(key.j)) * 0xC2B2AE3D27D4EB4FULL;
  x ^= static_cast<std::uint64_t>(static_cast<std::uint32_t>(key.k)) * 0x165667B19E3779F9ULL;
  x ^= x >> 29;
  x *= 0xbf58476d1ce4e5b9ULL;
  x ^= x >> 32;
  return static_cast<std::size_t>(x);
}

namespace {

constexpr double kMaxIndex = 2.0e9;  // keys are int32: points beyond ±2e9 edges are rejected

VoxelKey block_of(const VoxelKey& key) {
  // C++20: >> of a negative value is an arithmetic shift, i.e. floor division by the block side.
  return {key.i >> VoxelMap::kBlockBits, key.j >> VoxelMap::kBlockBits, key.k >> VoxelMap::kBlockBits};
}

std::size_t local_index(const VoxelKey& key) {
  constexpr int mask = VoxelMap::kBlockSide - 1;
  return static_cast<std::size_t>(((key.i & mask) * VoxelMap::kBlockSide + (key.j & mask)) * VoxelMap::kBlockSide +
                                  (key.k & mask));
}

VoxelKey key_in_block(const VoxelKey& block, std::size_t local) {
  const auto l = static_cast<int>(local);
  constexpr int s = VoxelMap::kBlockSide;
  return {block.i * s + l / (s * s), block.j * s + (l / s) % s, block.k * s + l % s};
}

void add_point(Voxel& v, const Eigen::Vector3d& d) {
  ++v.hits;
  const auto x = static_cast<float>(d.x());
  const auto y = static_cast<float>(d.y());
  const auto z = static_cast<float>(d.z());
  v.sum[0] += x;
  v.sum[1] += y;
  v.sum[2] += z;
  v.sum_sq[0] += x * x;
  v.sum_sq[1] += x * y;
  v.sum_sq[2] += x * z;
  v.sum_sq[3] += y * y;
  v.sum_sq[4] += y * z;
  v.sum_sq[5] += z * z;
}

}  // namespace

VoxelMap::VoxelMap(double edge, const ProbabilityModel& model) : edge_(edge), inv_edge_(1.0 / edge), model_(model) {
  if (!(edge > 0.0) || !std::isfinite(edge)) throw Error("pvox: the voxel edge must be positive and finite");
  model_.validate();
}

VoxelMap::VoxelMap(const VoxelMap& other)
    : edge_(other.edge_),
      inv_edge_(other.inv_edge_),
      model_(other.model_),
      voxel_count_(other.voxel_count_),
      budget_(other.budget_) {
  blocks_.reserve(other.blocks_.size());
  for (const auto& [key, block] : other.blocks_) blocks_.emplace(key, std::make_unique<Block>(*block));
}

VoxelMap& VoxelMap::operator=(const VoxelMap& other) {
  if (this != &other) *this = VoxelMap(other);
  return *this;
}

VoxelKey VoxelMap::key_of(const Eigen::Vector3d& p) const {
  const std::optional<std::int32_t> i = floor_to<std::int32_t>(p.x() * inv_edge_);
  const std::optional<std::int32_t> j = floor_to<std::int32_t>(p.y() * inv_edge_);
  const std::optional<std::int32_t> k = floor_to<std::int32_t>(p.z() * inv_edge_);
  // insert() checks its points against kMaxIndex first, so this throws only for a caller's own
  // point beyond the key range, never in the loop over a scan.
  if (!i || !j || !k) {
    throw Error(format("pvox: the point (%g, %g, %g) m is beyond the voxel key range at edge %g m", p.x(), p.y(), p.z(), edge_));
  }
  return {*i, *j, *k};
}

Eigen::Vector3d VoxelMap::centre(const VoxelKey& key) const {
  return {(key.i + 0.5) * edge_, (key.j + 0.5) * edge_, (key.k + 0.5) * edge_};
}

Voxel& VoxelMap::touch(const VoxelKey& key) {
  const VoxelKey bkey = block_of(key);
  auto it = blocks_.find(bkey);
  if (it == blocks_.end()) {
    // Checked before the allocation; the table's growth is in the per-block estimate.
    const std::size_t blocks = blocks_.size() + 1;
    budget_.require(static_cast<double>(blocks) * (sizeof(Block) + sizeof(VoxelKey) + sizeof(void*) * 5),
                    "the voxel map (" + std::to_string(blocks) + " blocks of 4^3 voxels of " + format("%g", edge_) + " m)");
    it = blocks_.emplace(bkey, std::make_unique<Block>()).first;
  }
  Voxel& v = it->second->voxels[local_index(key)];
  if (v.empty()) ++voxel_count_;
  return v;
}

void VoxelMap::add_hit(const Eigen::Vector3d& p) {
  const VoxelKey key = key_of(p);
  add_point(touch(key), p - centre(key));
}

void VoxelMap::add_miss(const VoxelKey& key) {
  Voxel& v = touch(key);
  if (v.misses < std::numeric_limits<std::uint32_t>::max()) ++v.misses;
}

void VoxelMap::set_voxel(const VoxelKey& key, std::uint32_t hits, std::uint32_t misses, const Eigen::Vector3d& mean) {
  if (hits == 0 && misses == 0) return;
  Voxel& v = touch(key);
  v = Voxel{};
  v.hits = hits;
  v.misses = misses;
  const Eigen::Vector3d d = mean - centre(key);
  const double n = hits;
  for (int a = 0; a < 3; ++a) v.sum[static_cast<std::size_t>(a)] = static_cast<float>(n * d[a]);
  v.sum_sq = {static_cast<float>(n * d.x() * d.x()), static_cast<float>(n * d.x() * d.y()),
              static_cast<float>(n * d.x() * d.z()), static_cast<float>(n * d.y() * d.y()),
              static_cast<float>(n * d.y() * d.z()), static_cast<float>(n * d.z() * d.z())};
}

void VoxelMap::set_edge(double edge) {
  if (!(edge > 0.0) || !std::isfinite(edge)) throw Error("pvox: the voxel edge must be positive and finite");
  if (edge == edge_) return;
  VoxelMap next(edge, model_);
  next.budget_ = budget_;
  for (const auto& [bkey, block] : blocks_) {
    for (std::size_t l = 0; l < block->voxels.size(); ++l) {
      const Voxel& v = block->voxels[l];
      if (v.empty()) continue;
      const VoxelKey key = key_in_block(bkey, l);
      const Eigen::Vector3d c = centre(key);
      const VoxelMoments m = moments(v, c);
      const VoxelKey to = next.key_of(v.hits > 0 ? m.mean : c);
      Voxel& w = next.touch(to);
      // Offsets from the old centre become offsets from the new one: d' = d + δ, δ = c − c'.
      const Eigen::Vector3d delta = c - next.centre(to);
      const double n = v.hits;
      const Eigen::Vector3d s(v.sum[0], v.sum[1], v.sum[2]);
      Eigen::Matrix3d ss;
      ss << v.sum_sq[0], v.sum_sq[1], v.sum_sq[2], v.sum_sq[1], v.sum_sq[3], v.sum_sq[4], v.sum_sq[2], v.sum_sq[4],
          v.sum_sq[5];
      const Eigen::Vector3d s2 = s + n * delta;
      const Eigen::Matrix3d ss2 = ss + s * delta.transpose() + delta * s.transpose() + n * delta * delta.transpose();
      w.hits += v.hits;
      w.misses = static_cast<std::uint32_t>(std::min<std::uint64_t>(
          std::uint64_t{w.misses} + v.misses, std::numeric_limits<std::uint32_t>::max()));
      for (int a = 0; a < 3; ++a) w.sum[static_cast<std::size_t>(a)] += static_cast<float>(s2[a]);
      w.sum_sq[0] += static_cast<float>(ss2(0, 0));
      w.sum_sq[1] += static_cast<float>(ss2(0, 1));
      w.sum_sq[2] += static_cast<float>(ss2(0, 2));
      w.sum_sq[3] += static_cast<float>(ss2(1, 1));
      w.sum_sq[4] += static_cast<float>(ss2(1, 2));
      w.sum_sq[5] += static_cast<float>(ss2(2, 2));
    }
  }
  *this = std::move(next);
}

InsertStats VoxelMap::insert(const PointCloud& points_sensor, const Pose& T_map_sensor, const InsertParams& params) {
  InsertStats stats;
  const Eigen::Vector3d origin = T_map_sensor.translation();
  const double limit = kMaxIndex * edge_;
  // A pose beyond the key range would drop every point: an empty map that looks like success.
  if (!(origin.cwiseAbs().maxCoeff() <= limit)) {
    throw Error(format("pvox: the scan pose (%g, %g, %g) m is beyond the voxel key range of +-%g m at edge %g m",
                       origin.x(), origin.y(), origin.z(), limit, edge_));
  }
  for (const Point3f& ps : points_sensor) {
    const Eigen::Vector3d p_sensor = ps.cast<double>();
    const double range = p_sensor.norm();
    if (!std::isfinite(range) || range < params.min_range || range > params.max_range) {
      ++stats.rejected;
      continue;
    }
    const Eigen::Vector3d p = T_map_sensor * p_sensor;
    if (p.cwiseAbs().maxCoeff() > limit || origin.cwiseAbs().maxCoeff() > limit) {
      ++stats.rejected;
      continue;
    }
    add_hit(p);
    ++stats.hits;
    if (params.free_space != FreeSpace::kRays) continue;
    // 3D DDA (Amanatides & Woo): every voxel from the sensor's to the point's, the last excluded.
    const VoxelKey end = key_of(p);
    VoxelKey at = key_of(origin);
    const Eigen::Vector3d dir = p - origin;
    std::array<int, 3> step{};
    std::array<double, 3> t_max{};
    std::array<double, 3> t_delta{};
    const std::array<std::int32_t, 3> start = {at.i, at.j, at.k};
    for (int a = 0; a < 3; ++a) {
      const auto ua = static_cast<std::size_t>(a);
      if (dir[a] > 0.0) {
        step[ua] = 1;
        t_max[ua] = ((start[ua] + 1) * edge_ - origin[a]) / dir[a];
        t_delta[ua] = edge_ / dir[a];
      } else if (dir[a] < 0.0) {
        step[ua] = -1;
        t_max[ua] = (start[ua] * edge_ - origin[a]) / dir[a];
        t_delta[ua] = -edge_ / dir[a];
      } else {
        t_max[ua] = std::numeric_limits<double>::infinity();
        t_delta[ua] = std::numeric_limits<double>::infinity();
      }
    }
    const std::int64_t budget = std::int64_t{std::abs(std::int64_t{end.i} - at.i)} + std::abs(std::int64_t{end.j} - at.j) +
                                std::abs(std::int64_t{end.k} - at.k);
    for (std::int64_t n = 0; n < budget && !(at == end); ++n) {
      add_miss(at);
      ++stats.misses;
      const std::size_t a = t_max[0] < t_max[1] ? (t_max[0] < t_max[2] ? 0 : 2) : (t_max[1] < t_max[2] ? 1 : 2);
      if (a == 0) at.i += step[0];
      if (a == 1) at.j += step[1];
      if (a == 2) at.k += step[2];
      t_max[a] += t_delta[a];
    }
  }
  return stats;
}

const Voxel* VoxelMap::find(const VoxelKey& key) const {
  const auto it = blocks_.find(block_of(key));
  if (it == blocks_.end()) return nullptr;
  const Voxel& v = it->second->voxels[local_index(key)];
  return v.empty() ? nullptr : &v;
}

double VoxelMap::probability(const VoxelKey& key) const {
  const Voxel* v = find(key);
  return v == nullptr ? 0.5 : model_.probability(edge_, v->hits, v->misses);
}

double VoxelMap::probability_at(const Eigen::Vector3d& p) const { return probability(key_of(p)); }

FieldSample VoxelMap::field_at(const Eigen::Vector3d& p) const {
  // Voxel centres sit at (i + ½)·e: interpolate in u = p/e − ½.
  const Eigen::Vector3d u = p * inv_edge_ - Eigen::Vector3d::Constant(0.5);
  const Eigen::Vector3d f = u.array().floor();
  const Eigen::Vector3d t = u - f;
  // Beyond the key range (and NaN): no voxel around, the unknown field (p 0.5, no gradient).
  const std::optional<std::int32_t> fi = floor_to<std::int32_t>(f.x());
  const std::optional<std::int32_t> fj = floor_to<std::int32_t>(f.y());
  const std::optional<std::int32_t> fk = floor_to<std::int32_t>(f.z());
  constexpr std::int32_t kLast = std::numeric_limits<std::int32_t>::max();  // i0 + 1 must not overflow
  if (!fi || !fj || !fk || *fi == kLast || *fj == kLast || *fk == kLast) return FieldSample{};
  const std::int32_t i0 = *fi;
  const std::int32_t j0 = *fj;
  const std::int32_t k0 = *fk;
  double c[2][2][2];
  for (int a = 0; a < 2; ++a) {
    for (int b = 0; b < 2; ++b) {
      for (int d = 0; d < 2; ++d) c[a][b][d] = probability({i0 + a, j0 + b, k0 + d});
    }
  }
  FieldSample out;
  out.probability = 0.0;
  for (int a = 0; a < 2; ++a) {
    const double wx = a == 1 ? t.x() : 1.0 - t.x();
    const double dwx = a == 1 ? 1.0 : -1.0;
    for (int b = 0; b < 2; ++b) {
      const double wy = b == 1 ? t.y() : 1.0 - t.y();
      const double dwy = b == 1 ? 1.0 : -1.0;
      for (int d = 0; d < 2; ++d) {
        const double wz = d == 1 ? t.z() : 1.0 - t.z();
        const double dwz = d == 1 ? 1.0 : -1.0;
        out.probability += wx * wy * wz * c[a][b][d];
        out.gradient += Eigen::Vector3d(dwx * wy * wz, wx * dwy * wz, wx * wy * dwz) * c[a][b][d];
      }
    }
  }
  out.gradient *= inv_edge_;
  return out;
}

VoxelMoments VoxelMap::moments(const Voxel& v, const Eigen::Vector3d& c) {
  VoxelMoments m;
  m.mean = c;
  if (v.hits == 0) return m;
  const double n = v.hits;
  const Eigen::Vector3d mean_d = Eigen::Vector3d(v.sum[0], v.sum[1], v.sum[2]) / n;
  m.mean = c + mean_d;
  if (v.hits < 2) return m;
  Eigen::Matrix3d ss;
  ss << v.sum_sq[0], v.sum_sq[1], v.sum_sq[2], v.sum_sq[1], v.sum_sq[3], v.sum_sq[4], v.sum_sq[2], v.sum_sq[4], v.sum_sq[5];
  m.covariance = ss / n - mean_d * mean_d.transpose();
  for (int a = 0; a < 3; ++a) m.covariance(a, a) = std::max(m.covariance(a, a), 0.0);  // float round-off
  return m;
}

VoxelView VoxelMap::view(const VoxelKey& key, const Voxel& v) const {
  return {key, centre(key), model_.probability(edge_, v.hits, v.misses), v.hits, v.misses};
}

void VoxelMap::for_each(const std::function<void(const VoxelKey&, const Voxel&)>& visit) const {
  for (const auto& [bkey, block] : blocks_) {
    for (std::size_t l = 0; l < block->voxels.size(); ++l) {
      if (!block->voxels[l].empty()) visit(key_in_block(bkey, l), block->voxels[l]);
    }
  }
}

std::vector<VoxelView> VoxelMap::voxels() const {
  std::vector<VoxelView> out;
  out.reserve(voxel_count_);
  for_each([&](const VoxelKey& key, const Voxel& v) { out.push_back(view(key, v)); });
  std::sort(out.begin(), out.end(), [](const VoxelView& a, const VoxelView& b) { return a.key < b.key; });
  return out;
}

std::vector<VoxelView> VoxelMap::occupied(double threshold) const {
  std::vector<VoxelView> out = voxels();
  std::erase_if(out, [&](const VoxelView& v) { return !(v.probability > threshold); });
  return out;
}

std::size_t VoxelMap::memory_bytes() const {
  return blocks_.size() * (sizeof(Block) + sizeof(VoxelKey) + sizeof(void*) * 3) +
         blocks_.bucket_count() * sizeof(void*);
}

}  // namespace hmap::pvox
