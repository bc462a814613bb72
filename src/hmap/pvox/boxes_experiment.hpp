#pragma once
// The seed's experiment in the simulator: the `boxes` enclosure scanned by a yaw-sweeping Hokuyo
// UTM-30LX from five stop-move-stop positions, and its edges (Table 1) measured on the map.
//
// Positions (sensor 1 m above the floor, x = 0.3 m, beside the boxes): P1 y = 0.4, P2 y = 1.4,
// P3 y = 2.4 heading +y; P4 = P3 turned 180°; P5 = P2 heading −y (the seed: "1000 mm forward at a
// heading of 180°"). Every move (the turn too) is placed imprecisely: the true position is the
// previous true one plus the commanded move plus N(0, motion variance) per planar axis. P1 is
// exact, so the map frame is the scene's.

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "hmap/core/types.hpp"
#include "hmap/pvox/voxel_map.hpp"

namespace hmap::pvox {

struct BoxesExperimentParams {
  std::uint64_t seed = 1;
  double motion_variance = 2000e-6;  ///< [m²] of the placement error per move and axis
  double angular_step_deg = 0.25;    ///< [deg] UTM-30LX beam step
  int sweep_steps = 181;             ///< yaw steps over 0..180°
  double range_sigma = 0.01;         ///< [m] (UTM-30LX: 10 mm)
};

struct BoxesRecording {
  std::vector<PointCloud> scans;  ///< sensor frame, one per position
  PoseList T_world_nominal;       ///< the commanded stops
  PoseList T_world_true;          ///< where the sensor really stood
  PoseList commands;              ///< per scan: the first nominal stop, then nominal moves T_prev_next
  std::vector<double> times;      ///< [s] scan start times on the stop-and-go timeline
};

[[nodiscard]] BoxesRecording simulate_boxes(const BoxesExperimentParams& params);

/// One edge of Table 1 as measured on a map.
struct EdgeMeasurement {
  std::string name;                 ///< "AB", ...
  double true_length = 0.0;         ///< [m]
  std::optional<double> measured;   ///< [m], nothing when a face was not found
  double accuracy = 0.0;            ///< 1 − |measured − true| / true (0 when not measured)
  std::string how;                  ///< the two face measurements it is the difference of
  std::optional<double> first;      ///< [m] the first face coordinate
  std::optional<double> second;     ///< [m] the second
};

/// The nine edges AB, AE, EG, GH, HC, CF, FI, IJ, JK measured on `map` (a map of the boxes scene in
/// its frame): each is the difference of two face coordinates, a plane (measure_plane) or the
/// end of a face (measure_extent), looked for in generous windows around the nominal faces.
[[nodiscard]] std::vector<EdgeMeasurement> measure_boxes_edges(const VoxelMap& map);

[[nodiscard]] double average_accuracy(const std::vector<EdgeMeasurement>& edges);

}  // namespace hmap::pvox
