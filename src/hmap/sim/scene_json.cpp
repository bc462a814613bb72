#include "hmap/sim/scene_json.hpp"

#include <cmath>
#include <initializer_list>
#include <nlohmann/json.hpp>
#include <numbers>
#include <set>

#include "hmap/core/error.hpp"
#include "hmap/sim/composites.hpp"

namespace hmap::sim {
namespace {

using nlohmann::json;

/// A JSON object with the path that leads to it, for messages.
class Node {
 public:
  Node(const json& value, std::string path) : value_(value), path_(std::move(path)) {}

  [[noreturn]] void fail(const std::string& key, const std::string& problem) const {
    throw Error((key.empty() ? path_ : path_ + "." + key) + ": " + problem);
  }
  [[nodiscard]] bool has(const char* key) const { return value_.contains(key); }
  [[nodiscard]] const std::string& path() const { return path_; }

  [[nodiscard]] double number(const char* key) const {
    if (!has(key)) fail(key, "missing");
    const json& v = value_.at(key);
    if (!v.is_number() || !std::isfinite(v.get<double>())) fail(key, "expected a finite number");
    return v.get<double>();
  }
  [[nodiscard]] double number(const char* key, double fallback) const { return has(key) ? number(key) : fallback; }
  [[nodiscard]] double positive(const char* key, double fallback) const {
    const double v = number(key, fallback);
    if (!(v > 0.0)) fail(key, "expected a positive number");
    return v;
  }
  [[nodiscard]] double positive(const char* key) const {
    const double v = number(key);
    if (!(v > 0.0)) fail(key, "expected a positive number");
    return v;
  }

  /// An array of `n` finite numbers (or of n_alt, the rest zero).
  [[nodiscard]] Eigen::VectorXd numbers(const char* key, int n, int n_alt = 0) const {
    if (!has(key)) fail(key, "missing");
    const json& v = value_.at(key);
    const auto expected = [&] {
      return n_alt > 0 ? "expected " + std::to_string(n_alt) + " or " + std::to_string(n) + " numbers"
                       : "expected " + std::to_string(n) + " numbers";
    };
    if (!v.is_array() || (static_cast<int>(v.size()) != n && static_cast<int>(v.size()) != n_alt)) fail(key, expected());
    Eigen::VectorXd out = Eigen::VectorXd::Zero(n);
    for (std::size_t i = 0; i < v.size(); ++i) {
      if (!v[i].is_number() || !std::isfinite(v[i].get<double>())) fail(key, expected());
      out[static_cast<Eigen::Index>(i)] = v[i].get<double>();
    }
    return out;
  }
  [[nodiscard]] Eigen::Vector3d vec3(const char* key) const { return numbers(key, 3); }
  [[nodiscard]] Eigen::Vector2d vec2(const char* key) const { return numbers(key, 2); }

  [[nodiscard]] std::string string(const char* key, const std::string& fallback) const {
    if (!has(key)) return fallback;
    if (!value_.at(key).is_string()) fail(key, "expected a string");
    return value_.at(key).get<std::string>();
  }

  void allow_only(const std::set<std::string>& keys) const {
    for (const auto& [key, unused] : value_.items()) {
      if (!keys.contains(key)) fail("", "unknown key '" + key + "'");
    }
  }

 private:
  const json& value_;
  std::string path_;
};

SurfaceKind kind_of(const Node& node, SurfaceKind fallback) {
  if (!node.has("kind")) return fallback;
  const std::string name = node.string("kind", "");
  if (const auto kind = surface_kind_from_string(name)) return *kind;
  node.fail("kind", "unknown kind '" + name + "'");
}

Parts parts_of(const Node& o, const std::string& type) {
  std::set<std::string> keys{"type", "name", "position", "yaw_deg", "path"};
  const auto allow = [&](std::initializer_list<const char*> more) {
    for (const char* k : more) keys.insert(k);
    o.allow_only(keys);
  };
  if (type == "box") {
    allow({"center", "size", "kind"});
    return {{Box{o.vec3("center"), 0.5 * o.vec3("size"), 0.0}, kind_of(o, SurfaceKind::kOther)}};
  }
  if (type == "cylinder") {
    allow({"base", "radius", "height", "kind"});
    const Eigen::Vector3d base = o.vec3("base");
    return {{Cylinder{base.head<2>(), base.z(), base.z() + o.positive("height"), o.positive("radius")},
             kind_of(o, SurfaceKind::kOther)}};
  }
  if (type == "sphere") {
    allow({"center", "radius", "kind"});
    return {{Ellipsoid{o.vec3("center"), Eigen::Vector3d::Constant(o.positive("radius")), 0.0},
             kind_of(o, SurfaceKind::kOther)}};
  }
  if (type == "ellipsoid") {
    allow({"center", "radii", "kind"});
    return {{Ellipsoid{o.vec3("center"), o.vec3("radii"), 0.0}, kind_of(o, SurfaceKind::kOther)}};
  }
  if (type == "ground") {
    allow({"center", "size", "slope", "thickness", "kind"});
    const Eigen::Vector2d slope = o.has("slope") ? o.vec2("slope") : Eigen::Vector2d::Zero();
    return {{GroundPatch{o.vec3("center"), 0.5 * o.vec2("size"), 0.0, slope, o.positive("thickness", 0.3)},
             kind_of(o, SurfaceKind::kGround)}};
  }
  if (type == "wall") {
    allow({"from", "to", "height", "thickness", "z", "kind"});
    const Eigen::Vector2d from = o.vec2("from");
    const Eigen::Vector2d to = o.vec2("to");
    if ((to - from).norm() <= 0.0) o.fail("to", "must differ from 'from'");
    return make_wall(from, to, o.positive("height"), o.positive("thickness", 0.2), o.number("z", 0.0),
                     kind_of(o, SurfaceKind::kWall));
  }
  if (type == "ceiling") {
    allow({"min", "max", "z", "thickness"});
    return make_ceiling(o.vec2("min"), o.vec2("max"), o.number("z"), o.positive("thickness", 0.3));
  }
  if (type == "table") {
    allow({"length", "width", "height"});
    TableSize s;
    s.length = o.positive("length", s.length);
    s.width = o.positive("width", s.width);
    s.height = o.positive("height", s.height);
    return make_table(s);
  }
  if (type == "chair") {
    allow({});
    return make_chair();
  }
  if (type == "cabinet") {
    allow({"width", "depth", "height"});
    CabinetSize s;
    s.width = o.positive("width", s.width);
    s.depth = o.positive("depth", s.depth);
    s.height = o.positive("height", s.height);
    return make_cabinet(s);
  }
  if (type == "tree") {
    allow({"trunk_radius", "crown_bottom", "crown_height", "crown_radius"});
    TreeSize s;
    s.trunk_radius = o.positive("trunk_radius", s.trunk_radius);
    s.crown_bottom = o.positive("crown_bottom", s.crown_bottom);
    s.crown_height = o.positive("crown_height", s.crown_height);
    s.crown_radius = o.positive("crown_radius", s.crown_radius);
    return make_tree(s);
  }
  if (type == "person") {
    allow({"height"});
    return make_person(o.positive("height", 1.75));
  }
  if (type == "car") {
    allow({"length", "width", "height"});
    CarSize s;
    s.length = o.positive("length", s.length);
    s.width = o.positive("width", s.width);
    s.height = o.positive("height", s.height);
    return make_car(s);
  }
  o.fail("type", "unknown type '" + type +
                     "'; known: box, cylinder, sphere, ellipsoid, ground, wall, ceiling, table, chair, cabinet, "
                     "tree, person, car");
}

/// Primitives given with yaw_deg turn about their own centre; composites about their origin.
bool turns_about_own_centre(const std::string& type) {
  return type == "box" || type == "ellipsoid" || type == "ground";
}

MotionPath path_of(const json& value, const std::string& path) {
  if (!value.is_array() || value.empty()) throw Error(path + ": expected a non-empty array of keys");
  std::vector<PathKey> keys;
  for (std::size_t i = 0; i < value.size(); ++i) {
    const std::string key_path = path + "[" + std::to_string(i) + "]";
    if (!value[i].is_object()) throw Error(key_path + ": expected an object");
    const Node k(value[i], key_path);
    k.allow_only({"t", "position", "yaw_deg"});
    const double t = k.number("t");
    if (!keys.empty() && !(t > keys.back().time)) k.fail("t", "times must increase");
    keys.push_back({t, k.numbers("position", 3, 2), k.number("yaw_deg", 0.0) * kRadiansPerDegree});
  }
  return MotionPath(std::move(keys));
}

}  // namespace

Scene scene_from_json(const std::string& json_text) {
  json root;
  try {
    root = json::parse(json_text);
  } catch (const json::parse_error& e) {
    throw Error(std::string("scene JSON: ") + e.what());
  }
  if (!root.is_object()) throw Error("scene JSON: expected an object at the top level");
  const Node top(root, "scene");
  top.allow_only({"objects", "bounds"});
  if (!root.contains("objects") || !root["objects"].is_array()) throw Error("objects: expected an array");

  SceneBuilder builder;
  if (root.contains("bounds")) {
    if (!root["bounds"].is_object()) throw Error("bounds: expected an object with min and max");
    const Node bounds(root["bounds"], "bounds");
    bounds.allow_only({"min", "max"});
    const Eigen::Vector3d lo = bounds.vec3("min");
    const Eigen::Vector3d hi = bounds.vec3("max");
    if ((hi.array() < lo.array()).any()) bounds.fail("max", "must not be below min");
    builder.set_bounds(Eigen::AlignedBox3d(lo, hi));
  }
  const json& objects = root["objects"];
  for (std::size_t i = 0; i < objects.size(); ++i) {
    const std::string path = "objects[" + std::to_string(i) + "]";
    if (!objects[i].is_object()) throw Error(path + ": expected an object");
    const Node o(objects[i], path);
    if (!o.has("type")) o.fail("type", "missing");
    const std::string type = o.string("type", "");
    Parts parts = parts_of(o, type);
    const std::string name = o.string("name", type);
    const double yaw = o.number("yaw_deg", 0.0) * kRadiansPerDegree;
    double object_yaw = yaw;
    if (turns_about_own_centre(type)) {
      // A primitive turns in place; a composite turns about its origin with the whole object.
      for (Part& part : parts) {
        std::visit([yaw](auto& s) {
          if constexpr (requires { s.yaw; }) s.yaw += yaw;
        }, part.shape);
      }
      object_yaw = 0.0;
    }
    try {
      if (o.has("path")) {
        if (o.has("position")) o.fail("path", "give either 'position' or 'path', not both");
        builder.add_moving(name, parts, path_of(objects[i]["path"], path + ".path"));
      } else {
        const Eigen::Vector3d position =
            o.has("position") ? Eigen::Vector3d(o.numbers("position", 3, 2)) : Eigen::Vector3d::Zero();
        builder.add(name, parts, {position, object_yaw});
      }
    } catch (const Error& e) {
      const std::string message = e.what();
      // Messages from this file already carry the path; those from validation get it here.
      throw Error(message.starts_with(path) ? message : path + ": " + message);
    }
  }
  return builder.build();
}

}  // namespace hmap::sim
