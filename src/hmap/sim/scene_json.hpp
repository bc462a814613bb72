#pragma once
// Scenes written by users as JSON text. Reading the file is the caller's business.
//
//   {
//     "bounds": {"min": [x, y, z], "max": [x, y, z]},        // optional: region of sample_surface
//     "objects": [
//       {"type": "box", "center": [x, y, z], "size": [sx, sy, sz], "yaw_deg": 0, "kind": "wall"},
//       {"type": "cylinder", "base": [x, y, z], "radius": r, "height": h},
//       {"type": "sphere", "center": [x, y, z], "radius": r},
//       {"type": "ellipsoid", "center": [x, y, z], "radii": [a, b, c], "yaw_deg": 0},
//       {"type": "ground", "center": [x, y, z_top], "size": [sx, sy], "slope": [dzdx, dzdy],
//        "thickness": 0.3, "yaw_deg": 0},
//       {"type": "wall", "from": [x, y], "to": [x, y], "height": h, "thickness": 0.2, "z": 0},
//       {"type": "ceiling", "min": [x, y], "max": [x, y], "z": z_underside, "thickness": 0.3},
//       {"type": "table", "length": 1.6, "width": 0.8, "height": 0.75},
//       {"type": "chair"}, {"type": "cabinet", "width": 1, "depth": 0.45, "height": 1.9},
//       {"type": "tree", "trunk_radius": 0.15, "crown_bottom": 2.5, "crown_height": 3, "crown_radius": 2.5},
//       {"type": "person", "height": 1.75}, {"type": "car", "length": 4.5, "width": 1.8, "height": 1.5}
//     ]
//   }
//
// Lengths in metres, angles in degrees. Every object may have "name", "position" ([x, y] or
// [x, y, z]) and "yaw_deg" that place it (composites are built around their own origin), or
// instead a "path" of keys {"t": s, "position": [...], "yaw_deg": ...} that moves it. Primitives
// take "kind" (ground, curb, wall, ceiling, pillar, furniture, vehicle, trunk, crown, person, box,
// other). Sizes shown are the defaults of the optional fields.

#include <string>

#include "hmap/sim/scene.hpp"

namespace hmap::sim {

/// Builds the scene described by `json_text`. Throws hmap::Error whose message names the JSON path
/// of the fault ("objects[3].size: expected 3 numbers"), or the line and column of a syntax error.
[[nodiscard]] Scene scene_from_json(const std::string& json_text);

}  // namespace hmap::sim
