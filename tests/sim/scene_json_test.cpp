#include "hmap/sim/scene_json.hpp"

#include <gtest/gtest.h>

#include <string>

#include "hmap/core/error.hpp"

namespace hmap::sim {
namespace {

/// The message of the hmap::Error that parsing `text` throws, or "" when it does not throw.
std::string error_of(const std::string& text) {
  try {
    (void)scene_from_json(text);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(SceneJson, BuildsPrimitivesCompositesAndMovingObjects) {
  const Scene scene = scene_from_json(R"({
    "bounds": {"min": [-10, -10, -1], "max": [10, 10, 5]},
    "objects": [
      {"type": "ground", "center": [0, 0, 0], "size": [20, 20]},
      {"type": "ground", "center": [5, 0, 0.5], "size": [2, 2], "slope": [0.1, 0], "yaw_deg": 30},
      {"type": "box", "name": "crate", "center": [2, 2, 0.5], "size": [1, 1, 1], "yaw_deg": 45, "kind": "box"},
      {"type": "cylinder", "base": [-2, 2, 0], "radius": 0.2, "height": 2, "kind": "pillar"},
      {"type": "sphere", "center": [0, -3, 1], "radius": 0.5},
      {"type": "ellipsoid", "center": [0, 3, 3], "radii": [1, 2, 0.5]},
      {"type": "wall", "from": [-5, -5], "to": [5, -5], "height": 2.5},
      {"type": "ceiling", "min": [-5, -5], "max": [5, 5], "z": 3},
      {"type": "table", "position": [1, -1], "yaw_deg": 90},
      {"type": "chair", "position": [1, -2, 0]},
      {"type": "cabinet"}, {"type": "tree", "position": [-6, 6]}, {"type": "person", "height": 1.6},
      {"type": "car", "name": "mover", "path": [{"t": 0, "position": [0, 8]}, {"t": 2, "position": [6, 8], "yaw_deg": 10}]}
    ]})");
  EXPECT_EQ(scene.object_count(), 14U);
  EXPECT_EQ(scene.primitive_count(), 8U + 5U + 6U + 1U + 2U + 4U + 6U);
  const auto crate = scene.find_object("crate");
  ASSERT_TRUE(crate.has_value());
  // The crate is turned 45° in place: a ray along y at x = 2 + 0.6 still hits it (corner reaches 0.707).
  const auto hit = scene.intersect({2.6, -4.0, 0.5}, {0, 1, 0}, 0.0, 20.0);
  ASSERT_TRUE(hit.has_value());
  EXPECT_EQ(hit->object, *crate);
  EXPECT_EQ(hit->kind, SurfaceKind::kBox);
  const auto mover = scene.find_object("mover");
  ASSERT_TRUE(mover.has_value());
  EXPECT_TRUE(scene.object_placement(*mover, 1.0).position.isApprox(Eigen::Vector3d(3, 8, 0)));
}

TEST(SceneJson, ErrorsNameTheJsonPath) {
  const std::string three = R"({"type": "table"}, {"type": "chair"}, {"type": "cabinet"}, )";
  EXPECT_EQ(error_of(R"({"objects": [)" + three + R"({"type": "box", "center": [0, 0, 0], "size": [1, 1]}]})"),
            "objects[3].size: expected 3 numbers");
  EXPECT_EQ(error_of(R"({"objects": [{"type": "box", "center": [0, 0, "a"], "size": [1, 1, 1]}]})"),
            "objects[0].center: expected 3 numbers");
  EXPECT_EQ(error_of(R"({"objects": [{"type": "cylinder", "base": [0, 0, 0], "radius": -1, "height": 1}]})"),
            "objects[0].radius: expected a positive number");
  EXPECT_EQ(error_of(R"({"objects": [{"type": "box", "size": [1, 1, 1]}]})"), "objects[0].center: missing");
  EXPECT_EQ(error_of(R"({"objects": [{"center": [0, 0, 0]}]})"), "objects[0].type: missing");
  EXPECT_EQ(error_of(R"({"objects": [{"type": "box", "center": [0, 0, 0], "size": [1, 1, 1], "colour": 1}]})"),
            "objects[0]: unknown key 'colour'");
  EXPECT_EQ(error_of(R"({"objects": [{"type": "box", "center": [0, 0, 0], "size": [1, 1, 1], "kind": "lava"}]})"),
            "objects[0].kind: unknown kind 'lava'");
  EXPECT_EQ(error_of(R"({"objects": [{"type": "car", "path": [{"t": 1, "position": [0, 0]}, {"t": 0, "position": [1, 0]}]}]})"),
            "objects[0].path[1].t: times must increase");
  EXPECT_EQ(error_of(R"({"objects": [{"type": "box", "center": [0, 0, 0], "size": [1, 0, 1]}]})"),
            "objects[0]: object 'box' part 0: box sizes must be positive");
  EXPECT_NE(error_of(R"({"objects": [{"type": "spaceship"}]})").find("objects[0].type: unknown type 'spaceship'"),
            std::string::npos);
  EXPECT_EQ(error_of(R"({"objects": 3})"), "objects: expected an array");
  EXPECT_EQ(error_of(R"({"objects": [], "bounds": {"min": [0, 0, 0], "max": [1, 1]}})"), "bounds.max: expected 3 numbers");
  EXPECT_NE(error_of(R"({"objects": [)").find("scene JSON"), std::string::npos);
  EXPECT_EQ(error_of(R"({"objects": []})"), "");
}

}  // namespace
}  // namespace hmap::sim
