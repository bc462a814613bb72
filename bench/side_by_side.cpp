#include "side_by_side.hpp"

#include <octomap/OcTree.h>
#include <tbb/global_control.h>

#include <malloc.h>
#include <sys/resource.h>

#include <chrono>
#include <cmath>
#include <optional>

#include "hmap/maps/mapper.hpp"

namespace hmap::bench {

void feed_scan(std::span<const Point3f> points_sensor, const Pose& T_map_sensor, const FeedSettings& settings,
               FedScan& out) {
  out.points_sensor.clear();
  out.points_map.clear();
  out.T_map_sensor = T_map_sensor;
  out.origin_map = T_map_sensor.translation();
  out.points_read = points_sensor.size();
  // hmap's own range test (scan_hvoxels.cpp): single precision, sensor frame.
  const auto min_r2 = static_cast<float>(settings.min_range * settings.min_range);
  const auto max_r2 = static_cast<float>(settings.max_range * settings.max_range);
  // The peers' test in the map frame, a micrometre-scale margin inside max range so that
  // OctoMap's single-precision copy cannot round a hit into a ray that only frees.
  const double peer_max = settings.max_range * (1.0 - 1e-6);
  const Eigen::Matrix3d R = T_map_sensor.linear();
  for (const Point3f& p : points_sensor) {
    if (!p.allFinite()) continue;
    const float r2 = p.squaredNorm();
    if (r2 < min_r2 || r2 > max_r2) continue;
    const Eigen::Vector3d p_map = R * p.cast<double>() + out.origin_map;  // as hmap computes it
    if ((p_map - out.origin_map).squaredNorm() >= peer_max * peer_max) continue;
    out.points_sensor.push_back(p);
    out.points_map.push_back(p_map);
  }
}

std::size_t heap_in_use() {
  const struct mallinfo2 m = mallinfo2();
  return m.uordblks + m.hblkhd;
}

double process_cpu_ms() {
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  const auto ms = [](const timeval& t) { return static_cast<double>(t.tv_sec) * 1e3 + static_cast<double>(t.tv_usec) * 1e-3; };
  return ms(ru.ru_utime) + ms(ru.ru_stime);
}

RunMeasurement run_system(System& system, std::span<const FedScan> scans) {
  std::optional<tbb::global_control> limit;
  if (system.threads() > 0) {
    limit.emplace(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(system.threads()));
  }
  RunMeasurement m;
  const std::size_t heap_before = heap_in_use();
  system.reset();
  for (const FedScan& scan : scans) {
    system.prepare(scan);
    const double cpu0 = process_cpu_ms();
    const auto t0 = std::chrono::steady_clock::now();
    system.insert(scan);
    const auto t1 = std::chrono::steady_clock::now();
    m.cpu_ms += process_cpu_ms() - cpu0;
    m.wall_ms += std::chrono::duration<double, std::milli>(t1 - t0).count();
    m.points += scan.points_sensor.size();
  }
  m.scans = scans.size();
  system.release_buffers();
  m.structure_bytes = system.structure_bytes();
  const std::size_t heap_after = heap_in_use();
  m.heap_bytes = heap_after > heap_before ? heap_after - heap_before : 0;
  system.clear();
  return m;
}

namespace {

std::int32_t voxel_of(double v, double resolution) { return static_cast<std::int32_t>(std::floor(v / resolution)); }

class HmapSystem final : public System {
 public:
  HmapSystem(const Params& params, int threads) : params_(params), threads_(threads) {}
  [[nodiscard]] std::string name() const override { return threads_ == 1 ? "hmap 1 thread" : "hmap"; }
  [[nodiscard]] int threads() const override { return threads_; }
  void reset() override {
    map_.reset();
    mapper_.emplace(params_);
    received_ = {};
    received_.resolution = mapper_->map().cell_size();
    received_.max_range = mapper_->map().params().map.max_range;
  }
  void prepare(const FedScan& scan) override {
    ++received_.scans;
    received_.origin_sum += scan.T_map_sensor.translation();
    for (const Point3f& p : scan.points_sensor) received_.point_sum += scan.T_map_sensor * p.cast<double>();
  }
  void insert(const FedScan& scan) override {
    const ScanStats s = mapper_->integrate(scan.points_sensor, scan.T_map_sensor);
    received_.points += s.points_kept;  // hmap's own count of the points it used
  }
  void release_buffers() override {
    map_.emplace(std::move(mapper_->map()));
    mapper_.reset();
  }
  [[nodiscard]] std::size_t structure_bytes() const override { return map().stats().memory_bytes; }
  [[nodiscard]] std::vector<VoxelIndex> occupied_voxels() const override {
    std::vector<VoxelIndex> out;
    const double res = map().cell_size();
    map().for_each_column([&](const CellKey& key, const ColumnView& column) {
      for (const HVoxel& v : column) {
        for (std::int32_t z = voxel_of(v.z_min, res); z <= voxel_of(v.z_max, res); ++z) out.push_back({key.i, key.j, z});
      }
    });
    return out;
  }
  void clear() override {
    mapper_.reset();
    map_.reset();
  }

 private:
  [[nodiscard]] const HMap& map() const { return map_ ? *map_ : mapper_->map(); }
  Params params_;
  int threads_;
  std::optional<Mapper> mapper_;
  std::optional<HMap> map_;  // after release_buffers: the map alone
};

class OctomapSystem final : public System {
 public:
  explicit OctomapSystem(const FeedSettings& settings) : settings_(settings) {}
  [[nodiscard]] std::string name() const override { return "OctoMap"; }
  void reset() override {
    tree_ = std::make_unique<octomap::OcTree>(settings_.cell_size);
    received_ = {};
    received_.resolution = tree_->getResolution();
    received_.max_range = settings_.max_range;
  }
  void prepare(const FedScan& scan) override {
    cloud_.clear();
    cloud_.reserve(scan.points_map.size());
    for (const Eigen::Vector3d& p : scan.points_map) {
      cloud_.push_back(static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z()));
    }
    origin_ = octomap::point3d(static_cast<float>(scan.origin_map.x()), static_cast<float>(scan.origin_map.y()),
                               static_cast<float>(scan.origin_map.z()));
    ++received_.scans;
    received_.origin_sum += Eigen::Vector3d(origin_.x(), origin_.y(), origin_.z());
    for (std::size_t k = 0; k < cloud_.size(); ++k) {
      const octomap::point3d& p = cloud_[k];
      // OcTree::insertPointCloud's own test: beyond max range a point only frees.
      if ((p - origin_).norm() > settings_.max_range) continue;
      ++received_.points;
      received_.point_sum += Eigen::Vector3d(p.x(), p.y(), p.z());
    }
  }
  void insert(const FedScan& /*scan*/) override { tree_->insertPointCloud(cloud_, origin_, settings_.max_range); }
  void release_buffers() override { cloud_ = octomap::Pointcloud(); }
  [[nodiscard]] std::size_t structure_bytes() const override { return tree_->memoryUsage(); }
  [[nodiscard]] std::vector<VoxelIndex> occupied_voxels() const override {
    std::vector<VoxelIndex> out;
    const unsigned depth = tree_->getTreeDepth();
    const auto offset = static_cast<std::int32_t>(1U << (depth - 1));  // key of coordinate 0
    for (auto it = tree_->begin_leafs(), end = tree_->end_leafs(); it != end; ++it) {
      if (!tree_->isNodeOccupied(*it)) continue;
      // A pruned leaf stands for 2^(depth − its depth) voxels per axis from its index key.
      const octomap::OcTreeKey k = it.getIndexKey();
      const auto n = static_cast<std::int32_t>(1U << (depth - it.getDepth()));
      for (std::int32_t a = 0; a < n; ++a) {
        for (std::int32_t b = 0; b < n; ++b) {
          for (std::int32_t c = 0; c < n; ++c) out.push_back({k[0] - offset + a, k[1] - offset + b, k[2] - offset + c});
        }
      }
    }
    return out;
  }
  void clear() override {
    tree_.reset();
    cloud_ = octomap::Pointcloud();
  }

 private:
  FeedSettings settings_;
  std::unique_ptr<octomap::OcTree> tree_;
  octomap::Pointcloud cloud_;
  octomap::point3d origin_;
};

}  // namespace

std::unique_ptr<System> make_hmap_system(const Params& params, int threads) {
  return std::make_unique<HmapSystem>(params, threads);
}

std::unique_ptr<System> make_octomap_system(const FeedSettings& settings) {
  return std::make_unique<OctomapSystem>(settings);
}

}  // namespace hmap::bench
