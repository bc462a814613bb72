#pragma once
// A map as an MCAP recording that Foxglove opens with no configuration (hmap export --mcap):
//   /map      nav_msgs/msg/OccupancyGrid (ros2msg schema, CDR): the 2D grid, 0..100 percent
//             occupied, -1 unknown, cell (col, row) at row·width + col with x along col
//   /grid     foxglove.Grid (jsonschema, JSON, data base64): the same grid, one float32 field
//             "occupancy" 0..1, NaN unknown
//   /tf       tf2_msgs/msg/TFMessage (ros2msg, CDR): world -> map, identity, so that the map frame
//             is in the transform tree Foxglove's 3D panel picks its display frame from; with poses,
//             one message per pose at its stamp holding world -> map and map -> sensor (the pose),
//             so that playing the file back drives the sensor frame along the trajectory
//   /hvoxels  foxglove.SceneUpdate (jsonschema, JSON): the HVoxels as cubes coloured by height
//             (view::height_colour), one entity per square tile of cells, one message per entity
//   /points   foxglove.PointCloud (jsonschema, JSON, data base64): the points recovered from the
//             HVoxels every z_step up each one (recover_points), float32 x y z
//   /trajectory  foxglove.PosesInFrame (jsonschema, JSON): the poses given, when any, in order
// Time: the /tf of a pose is stamped (log time and header) with the pose's stamp; everything else
// (/map, /grid, /hvoxels, /points, /trajectory and, without poses, /tf) with the latest stamp, when
// the map is whole; all at 0 when no stamps are given.
// The foxglove.* messages are JSON with JSON schemas, Foxglove's own encoding for its schemas:
// no message definitions to carry and a file anyone can read with a JSON parser; the cubes
// compress well in zstd chunks. The ROS types are CDR so that ROS 2 tools read them too.
// Pure: the bytes go to a sink; the caller writes the file.

#include <cstdint>
#include <map>
#include <span>
#include <string>
#include <vector>

#include "hmap/maps/hmap.hpp"
#include "hmap/occupancy/occupancy_grid.hpp"
#include "hmap/ros/mcap_writer.hpp"

namespace hmap::ros {

inline constexpr const char* kMapTopic = "/map";
inline constexpr const char* kTfTopic = "/tf";
inline constexpr const char* kGridTopic = "/grid";
inline constexpr const char* kHVoxelTopic = "/hvoxels";
inline constexpr const char* kPointsTopic = "/points";
inline constexpr const char* kTrajectoryTopic = "/trajectory";

struct FoxgloveSceneParams {
  std::string frame = "map";         ///< frame of every message
  std::string parent_frame = "world";  ///< parent of `frame` on /tf (identity)
  std::string sensor_frame = "sensor";  ///< child of `frame` on /tf: the pose of each scan
  int tile_cells = 64;               ///< cells per /hvoxels entity edge (tile_cells² columns)
  double points_z_step = 0.0;        ///< [m] /points spacing up an HVoxel; 0: the cell size; < 0: no /points
  mcap::WriterOptions mcap;
};

struct FoxgloveSceneStats {
  std::map<std::string, std::uint64_t> messages;  ///< per topic
  std::uint64_t cubes = 0;
  std::uint64_t points = 0;
  std::uint64_t bytes = 0;  ///< the whole file
};

/// Writes `map`, its 2D `grid` (may be null: no /map nor /grid) and the poses `T_map_scans` (may
/// be empty: no /trajectory) with their stamps `stamps_ns` (one per pose [ns], or empty: no time
/// known, all at 0) to `sink` as one MCAP file. Throws hmap::Error for parameters out of range or
/// a stamp count other than the poses'.
FoxgloveSceneStats write_foxglove_mcap(const HMap& map, const OccupancyGrid* grid, std::span<const Pose> T_map_scans,
                                       std::span<const std::uint64_t> stamps_ns, const mcap::Sink& sink,
                                       const FoxgloveSceneParams& params = {});

/// Stamps [s] (times.txt, a TUM trajectory, a bag's) as MCAP times [ns], rounded to the nearest.
/// Throws hmap::Error naming `what` and the 1-based index of a stamp that is negative, not finite
/// or past MCAP's (and ROS's int32 seconds') range.
std::vector<std::uint64_t> stamps_ns_of(std::span<const double> stamps_s, const std::string& what);


}  // namespace hmap::ros
