#pragma once
// A pose graph in SE(2) + z (x, y, z, yaw: the part of a pose the SLAM estimates and drifts in),
// optimised by Ceres: odometry edges between consecutive key frames and loop edges from
// verified place matches, the loop edges under a Cauchy loss so that one false match cannot
// bend the whole trajectory.

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace hmap::slam {

/// A node of the graph: the planar pose and the height [m, m, m, rad].
struct GraphPose {
  double x = 0.0;
  double y = 0.0;
  double z = 0.0;
  double yaw = 0.0;
};

/// a⁻¹ ⊕ b in SE(2) + z: b expressed in a's frame (the measurement an edge from a to b holds).
[[nodiscard]] GraphPose relative(const GraphPose& a, const GraphPose& b);
/// a ⊕ b.
[[nodiscard]] GraphPose compose(const GraphPose& a, const GraphPose& b);

/// How an edge's residual is weighed.
enum class EdgeLoss : std::uint8_t {
  kSquared,  ///< plain least squares (odometry)
  kCauchy,   ///< Cauchy loss of scale 1 on the whitened residual (loop edges), after a first squared pass
};

/// A relative pose measurement T_from_to with its standard deviations.
struct GraphEdge {
  std::size_t from = 0;
  std::size_t to = 0;
  GraphPose T_from_to;
  Eigen::Vector4d sigma{0.1, 0.1, 0.1, 0.01};  ///< [m, m, m, rad] of x, y, z, yaw
  EdgeLoss loss = EdgeLoss::kSquared;
};

struct PoseGraphOptions {
  int max_iterations = 100;  ///< [-] Levenberg-Marquardt iterations at most
};

/// What the optimisation did.
struct PoseGraphResult {
  std::vector<GraphPose> poses;  ///< the optimised nodes (the input when nothing ran)
  bool ran = false;              ///< false: fewer than two nodes or no edge, nothing to do
  bool converged = false;
  int iterations = 0;
  double initial_cost = 0.0;     ///< ½ Σ ‖whitened residual‖² at the input (every edge squared)
  double final_cost = 0.0;       ///< ½ Σ ρ(‖whitened residual‖²) at the result, loop edges under their loss
};

/// Minimises the edges' whitened residuals over the nodes, the first node held fixed (it
/// defines the map frame): first with every edge squared, then with the loop edges' loss from there. Throws hmap::Error for an edge naming a node that does not exist or a
/// sigma that is not positive.
[[nodiscard]] PoseGraphResult optimize_pose_graph(std::span<const GraphPose> nodes, std::span<const GraphEdge> edges,
                                                  const PoseGraphOptions& options = {});

}  // namespace hmap::slam
