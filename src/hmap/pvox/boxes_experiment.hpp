#pragma once
// The seed's experiment in the simulator: the `boxes` enclosure scanned by a yaw-sweeping Hokuyo
// UTM-30LX from five stop-move-stop positions, and its edges (Table 1) measured on the map.
//
// Positions (sensor 1 m above the floor, x = 0.3 m, beside the boxes): P1 y = 0.4, P2 y = 1.4,
// P3 y = 2.4 heading +y; P4 = P3 turned 180°; P5 = P2 heading −y (the seed: "1000 mm forward at a
// heading of 180°"). Every move (the turn too) is placed imprecisely: the true position is the
// previous true one plus the commanded move plus N(0, motion variance) per planar axis. P1 is
// exact, so the map frame is the scene's.

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "hmap/core/types.hpp"
#include "hmap/pvox/measure.hpp"
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

/// A face of the boxes scene and the plane of the map it was matched with.
struct FaceMatch {
  std::string name;                  ///< "front of box B (y)", ...
  int axis = 0;                      ///< its normal
  double nominal = 0.0;              ///< [m] where the scene puts it
  double gate = 0.0;                 ///< [m] how far its plane may lie (half the gap to the next face)
  std::optional<std::size_t> plane;  ///< index into BoxesMeasurement::planes[axis]; nothing: missing
};

/// One edge of Table 1 as measured on a map.
struct EdgeMeasurement {
  std::string name;                 ///< "AB", ...
  double true_length = 0.0;         ///< [m]
  std::optional<double> measured;   ///< [m], nothing when a face is missing from the map
  double accuracy = 0.0;            ///< 1 − |measured − true| / true (meaningless when not measured)
  std::string how;                  ///< the two face coordinates it is the difference of
  std::optional<double> first;      ///< [m] the first face coordinate
  std::optional<double> second;     ///< [m] the second
  std::string missing;              ///< the faces that were not found, when not measured
};

/// The ruler's reading of a map: the planes found, the scene's faces matched with them, the edges.
struct BoxesMeasurement {
  std::array<std::vector<DetectedPlane>, 3> planes;  ///< per axis, sorted by coordinate
  std::vector<FaceMatch> faces;                      ///< every axis-aligned face of the scene
  std::vector<EdgeMeasurement> edges;                ///< AB, AE, EG, GH, HC, CF, FI, IJ, JK
};

/// Measures `map` (a map of the boxes scene in its frame) from the map alone, then compares with
/// the scene: planes are detected along each axis in the enclosure (detect_planes, without the
/// scene's face positions), each face of the scene is matched with the nearest plane within half
/// the gap to its nearest neighbouring face (associate_faces), and each of the nine edges is the
/// difference of two face coordinates, a plane or the end of one (plane_end); an edge with a
/// missing face is not measured.
[[nodiscard]] BoxesMeasurement measure_boxes(const VoxelMap& map, const PlaneDetectionParams& params = {});

/// Accuracy over the measured edges, and how many were not measured: a missing edge is neither
/// accurate nor inaccurate, and a mean that counted it as 0 or left it out silently would mislead.
struct AccuracySummary {
  double mean = 0.0;          ///< over the measured edges (0 when none)
  std::size_t measured = 0;
  std::size_t missing = 0;
};

[[nodiscard]] AccuracySummary summarize_accuracy(const std::vector<EdgeMeasurement>& edges);

}  // namespace hmap::pvox
