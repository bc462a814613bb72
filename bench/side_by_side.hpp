#pragma once
// hmap beside its peers (Bonxai, OctoMap) on the same scans, in one process: one scan feed for
// every system, each system behind the same small interface, each measured the same way.
//
// Fairness is by construction and counted: feed_scan keeps the points every system would keep
// (so no system drops or truncates what another uses), each adapter hands those points over
// unchanged and tallies what it handed over (`Received`), and tests/bench checks that the tallies
// and the occupied voxels of the three maps agree.

#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "hmap/core/params.hpp"
#include "hmap/core/types.hpp"

namespace hmap::bench {

/// What every system is configured with.
struct FeedSettings {
  double cell_size = 0.2;   ///< [m] hmap's cell edge, the peers' voxel edge
  double min_range = 1.2;   ///< [m] closer points are dropped for everyone (the peers have no such setting)
  double max_range = 50.0;  ///< [m] farther points are dropped for everyone
};

/// One scan as every system receives it: the same points, in the sensor frame for hmap (which
/// takes a pose) and in the map frame for the peers (which take a sensor origin).
struct FedScan {
  PointCloud points_sensor;
  std::vector<Eigen::Vector3d> points_map;  ///< T_map_sensor · points_sensor, in the same order
  Pose T_map_sensor = Pose::Identity();
  Eigen::Vector3d origin_map = Eigen::Vector3d::Zero();
  std::size_t points_read = 0;              ///< before the range filter
};

/// Keeps the points of `points_sensor` that every system keeps as hits: finite, within
/// [min_range, max_range] by hmap's test (single precision, sensor frame), and closer than
/// max_range by the peers' (double precision, map frame; Bonxai turns a point at or beyond max
/// range into a ray that only frees, OctoMap one beyond it). Reuses `out`'s buffers.
void feed_scan(std::span<const Point3f> points_sensor, const Pose& T_map_sensor, const FeedSettings& settings,
               FedScan& out);

/// What reached one system, tallied by its adapter as handed over (hmap's point count is hmap's
/// own: the points its update kept).
struct Received {
  std::size_t scans = 0;
  std::size_t points = 0;                                  ///< points taken as hits
  Eigen::Vector3d point_sum = Eigen::Vector3d::Zero();     ///< [m] sum of those points, map frame
  Eigen::Vector3d origin_sum = Eigen::Vector3d::Zero();    ///< [m] sum of the sensor origins
  double resolution = 0.0;                                 ///< [m] the structure's own cell / voxel edge
  double max_range = 0.0;                                  ///< [m] the range the update was given
};

/// A voxel index (x, y, z) of edge `resolution`: floor(coordinate / resolution).
using VoxelIndex = std::array<std::int32_t, 3>;

/// One system of the comparison. `prepare` converts a scan to the system's own input type (not
/// timed); `insert` is the map update alone (timed).
class System {
 public:
  virtual ~System() = default;
  [[nodiscard]] virtual std::string name() const = 0;
  /// Threads the update may use; 0: the library's default (hmap: TBB's, here both cores).
  [[nodiscard]] virtual int threads() const { return 1; }
  /// Starts a fresh, empty map; the tally restarts.
  virtual void reset() = 0;
  virtual void prepare(const FedScan& scan) = 0;
  virtual void insert(const FedScan& scan) = 0;
  /// Frees what the update keeps between scans beyond the map itself (hmap's scan buffers, the
  /// converted scan): the heap is then measured with the map alone.
  virtual void release_buffers() {}
  /// The structure's own accounting of its memory [bytes].
  [[nodiscard]] virtual std::size_t structure_bytes() const = 0;
  /// Every occupied voxel of the map at `resolution` (for the fairness test; hmap's HVoxels are
  /// cut into voxels of that edge).
  [[nodiscard]] virtual std::vector<VoxelIndex> occupied_voxels() const = 0;
  /// Destroys the map.
  virtual void clear() = 0;
  [[nodiscard]] const Received& received() const { return received_; }

 protected:
  Received received_;
};

/// hmap's Mapper (HMAP with free space and extrusion, as `hmap bench`) with `params`, whose
/// cell size and ranges are the feed's; `threads` 0 for TBB's default.
[[nodiscard]] std::unique_ptr<System> make_hmap_system(const Params& params, int threads);
/// OctoMap's OcTree::insertPointCloud (Debian's liboctomap).
[[nodiscard]] std::unique_ptr<System> make_octomap_system(const FeedSettings& settings);
/// Bonxai's ProbabilisticMap::insertPointCloud, or nullptr when this build has no Bonxai
/// (HMAP_BONXAI_DIR absent at configure time).
[[nodiscard]] std::unique_ptr<System> make_bonxai_system(const FeedSettings& settings);
/// Why make_bonxai_system returns nullptr, or empty when it does not.
[[nodiscard]] std::string bonxai_absent_reason();

/// One run of a system over all scans, on a fresh map.
struct RunMeasurement {
  std::size_t scans = 0;
  std::size_t points = 0;        ///< points handed to the update
  double wall_ms = 0.0;          ///< steady clock around the updates
  double cpu_ms = 0.0;           ///< user + system time of all threads (getrusage RUSAGE_SELF) around the updates
  std::size_t structure_bytes = 0;
  std::size_t heap_bytes = 0;    ///< mallinfo2 uordblks + hblkhd held by the map after the run
  [[nodiscard]] double wall_ms_per_scan() const { return scans ? wall_ms / static_cast<double>(scans) : 0.0; }
  [[nodiscard]] double cpu_ms_per_scan() const { return scans ? cpu_ms / static_cast<double>(scans) : 0.0; }
  [[nodiscard]] double points_per_s() const { return wall_ms > 0 ? static_cast<double>(points) / (wall_ms / 1000.0) : 0.0; }
};

/// Runs `system` over `scans` on a fresh map (at its thread count) and measures it.
[[nodiscard]] RunMeasurement run_system(System& system, std::span<const FedScan> scans);

/// Bytes the allocator has handed out and not taken back: mallinfo2's uordblks (arena blocks in
/// use) + hblkhd (blocks served by mmap, which uordblks leaves out).
[[nodiscard]] std::size_t heap_in_use();
/// User + system CPU time of the whole process, all threads [ms].
[[nodiscard]] double process_cpu_ms();

}  // namespace hmap::bench
