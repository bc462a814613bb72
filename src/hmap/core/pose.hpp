#pragma once
// A 4×4 matrix given by a caller (a file, a script) checked and taken as a rigid transform.

#include <Eigen/Core>

#include "hmap/core/types.hpp"

namespace hmap {

/// The pose of `m`: its rotation must be orthonormal within 1e-3 elementwise (|RᵀR − I|) with a
/// determinant within 1 ± 0.01 and its last row 0 0 0 1 within 1e-6, the tolerances of the pose
/// files; the rotation is then made exactly orthonormal (R = U Vᵀ), as read_poses does. Throws
/// hmap::Error saying which test failed, for a matrix holding NaN or infinity too.
[[nodiscard]] Pose rigid_pose(const Eigen::Matrix4d& m);

}  // namespace hmap
