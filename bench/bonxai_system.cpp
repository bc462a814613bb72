// Bonxai's ProbabilisticMap behind the side-by-side interface. Built only when CMake found
// Bonxai's source (HMAP_BONXAI_DIR, default ../shared/peers/bonxai): it is compiled into the build
// folder for the benchmarks and never linked into hmap's libraries or installed.

#include "side_by_side.hpp"

#ifdef HMAP_HAVE_BONXAI
#include <bonxai_map/probabilistic_map.hpp>
#endif

namespace hmap::bench {

#ifdef HMAP_HAVE_BONXAI

namespace {

class BonxaiSystem final : public System {
 public:
  explicit BonxaiSystem(const FeedSettings& settings) : settings_(settings) {}
  [[nodiscard]] std::string name() const override { return "Bonxai"; }
  void reset() override {
    map_ = std::make_unique<Bonxai::ProbabilisticMap>(settings_.cell_size);
    received_ = {};
    received_.resolution = map_->grid().voxelSize();
    received_.max_range = settings_.max_range;
  }
  void prepare(const FedScan& scan) override {
    // Bonxai takes the map-frame points as they are (std::vector<Eigen::Vector3d>): nothing to
    // convert, only the tally, by insertPointCloud's own test (at or beyond max range a point
    // only frees).
    ++received_.scans;
    received_.origin_sum += scan.origin_map;
    const double max2 = settings_.max_range * settings_.max_range;
    for (const Eigen::Vector3d& p : scan.points_map) {
      if ((p - scan.origin_map).squaredNorm() >= max2) continue;
      ++received_.points;
      received_.point_sum += p;
    }
  }
  void insert(const FedScan& scan) override {
    map_->insertPointCloud(scan.points_map, scan.origin_map, settings_.max_range);
  }
  [[nodiscard]] std::size_t structure_bytes() const override { return map_->grid().memUsage(); }
  [[nodiscard]] std::vector<VoxelIndex> occupied_voxels() const override {
    std::vector<Bonxai::CoordT> coords;
    map_->getOccupiedVoxels(coords);
    std::vector<VoxelIndex> out;
    out.reserve(coords.size());
    for (const Bonxai::CoordT& c : coords) out.push_back({c.x, c.y, c.z});
    return out;
  }
  void clear() override { map_.reset(); }

 private:
  FeedSettings settings_;
  std::unique_ptr<Bonxai::ProbabilisticMap> map_;
};

}  // namespace

std::unique_ptr<System> make_bonxai_system(const FeedSettings& settings) {
  return std::make_unique<BonxaiSystem>(settings);
}

std::string bonxai_absent_reason() { return {}; }

#else

std::unique_ptr<System> make_bonxai_system(const FeedSettings& /*settings*/) { return nullptr; }

std::string bonxai_absent_reason() {
  return "Bonxai is not built: its source was not found at HMAP_BONXAI_DIR=" HMAP_BONXAI_DIR;
}

#endif

}  // namespace hmap::bench
