#include "hmap/sim/scene.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "hmap/core/error.hpp"

namespace hmap::sim {
namespace {

constexpr std::array<std::string_view, 12> kKindNames = {
    "ground", "curb", "wall", "ceiling", "pillar", "furniture", "vehicle", "trunk", "crown", "person", "box", "other",
};

/// Whether the ray o + s·d, s in [0, s_max], meets `box`; `inv` is 1/d per axis.
bool ray_meets_box(const Eigen::AlignedBox3d& box, const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                   const Eigen::Vector3d& inv, double s_max) {
  double s_in = 0.0;
  double s_out = s_max;
  for (int k = 0; k < 3; ++k) {
    if (d[k] == 0.0) {
      if (o[k] < box.min()[k] || o[k] > box.max()[k]) return false;
      continue;
    }
    double s1 = (box.min()[k] - o[k]) * inv[k];
    double s2 = (box.max()[k] - o[k]) * inv[k];
    if (s1 > s2) std::swap(s1, s2);
    s_in = std::max(s_in, s1);
    s_out = std::min(s_out, s2);
    if (s_in > s_out) return false;
  }
  return true;
}

Eigen::Vector3d to_local(const Eigen::Vector3d& v, double yaw) {
  const double c = std::cos(yaw);
  const double s = std::sin(yaw);
  return {c * v.x() + s * v.y(), -s * v.x() + c * v.y(), v.z()};
}

/// Shrinks an unturned ground patch to its part above the x-y extent of `bounds`.
void clip_to_bounds(GroundPatch& g, const Eigen::AlignedBox3d& bounds) {
  const Eigen::Vector2d lo = (g.center.head<2>() - g.half_size).cwiseMax(bounds.min().head<2>());
  const Eigen::Vector2d hi = (g.center.head<2>() + g.half_size).cwiseMin(bounds.max().head<2>());
  if ((hi.array() <= lo.array()).any()) return;
  const Eigen::Vector2d center = 0.5 * (lo + hi);
  g.center.z() += g.slope.dot(center - g.center.head<2>());
  g.center.head<2>() = center;
  g.half_size = 0.5 * (hi - lo);
}

}  // namespace

std::string_view to_string(SurfaceKind kind) { return kKindNames.at(static_cast<std::size_t>(kind)); }

std::optional<SurfaceKind> surface_kind_from_string(std::string_view name) {
  for (std::size_t i = 0; i < kKindNames.size(); ++i) {
    if (kKindNames[i] == name) return static_cast<SurfaceKind>(i);
  }
  return std::nullopt;
}

MotionPath::MotionPath(std::vector<PathKey> keys) : keys_(std::move(keys)) {
  if (keys_.empty()) throw Error("MotionPath: needs at least one key");
  for (std::size_t i = 0; i < keys_.size(); ++i) {
    if (!std::isfinite(keys_[i].time) || !keys_[i].position.allFinite() || !std::isfinite(keys_[i].yaw))
      throw Error("MotionPath: key " + std::to_string(i) + " is not finite");
    if (i > 0 && !(keys_[i].time > keys_[i - 1].time))
      throw Error("MotionPath: key times must increase strictly (key " + std::to_string(i) + ")");
  }
}

Placement MotionPath::at(double t_seconds) const {
  if (t_seconds <= keys_.front().time) return {keys_.front().position, keys_.front().yaw};
  if (t_seconds >= keys_.back().time) return {keys_.back().position, keys_.back().yaw};
  const auto next = std::upper_bound(keys_.begin(), keys_.end(), t_seconds,
                                     [](double t, const PathKey& k) { return t < k.time; });
  const PathKey& b = *next;
  const PathKey& a = *(next - 1);
  const double w = (t_seconds - a.time) / (b.time - a.time);
  return {(1.0 - w) * a.position + w * b.position, (1.0 - w) * a.yaw + w * b.yaw};
}

std::uint32_t SceneBuilder::add(const std::string& name, const Parts& parts, const Placement& where) {
  const auto object = static_cast<std::uint32_t>(objects_.size());
  Object entry{name, std::nullopt, {}};
  for (std::size_t i = 0; i < parts.size(); ++i) {
    validate(parts[i].shape, "object '" + name + "' part " + std::to_string(i));
    entry.primitives.push_back(static_cast<std::uint32_t>(parts_.size()));
    parts_.push_back({placed(parts[i].shape, where), parts[i].kind});
    object_of_.push_back(object);
  }
  objects_.push_back(std::move(entry));
  return object;
}

std::uint32_t SceneBuilder::add_moving(const std::string& name, const Parts& parts, MotionPath path) {
  const auto object = static_cast<std::uint32_t>(objects_.size());
  Object entry{name, std::move(path), {}};
  for (std::size_t i = 0; i < parts.size(); ++i) {
    validate(parts[i].shape, "object '" + name + "' part " + std::to_string(i));
    entry.primitives.push_back(static_cast<std::uint32_t>(parts_.size()));
    parts_.push_back(parts[i]);
    object_of_.push_back(object);
  }
  objects_.push_back(std::move(entry));
  return object;
}

Scene SceneBuilder::build() const {
  Scene scene;
  scene.parts_ = parts_;
  scene.object_of_ = object_of_;
  scene.objects_ = objects_;
  std::vector<Eigen::AlignedBox3d> boxes(parts_.size());
  Eigen::AlignedBox3d all_static;
  Eigen::AlignedBox3d all_moving;
  for (const Object& object : objects_) {
    if (object.path) {
      Scene::MovingObject moving{*object.path, Eigen::AlignedBox3d(), object.primitives};
      for (const std::uint32_t id : object.primitives) {
        moving.box_local.extend(bounding_box(parts_[id].shape));
        const Placement start = object.path->at(object.path->keys().front().time);
        all_moving.extend(bounding_box(placed(parts_[id].shape, start)));
      }
      if (!object.primitives.empty()) scene.moving_.push_back(std::move(moving));
    } else {
      for (const std::uint32_t id : object.primitives) {
        boxes[id] = bounding_box(parts_[id].shape);
        all_static.extend(boxes[id]);
        scene.order_.push_back(id);
      }
    }
  }
  if (!scene.order_.empty()) {
    scene.build_bvh(boxes);
  }
  scene.bounds_ = bounds_ ? *bounds_ : (all_static.isEmpty() ? all_moving : all_static);
  return scene;
}

// A binary hierarchy over order_: inner nodes split their primitives at the median centroid along
// the longest axis of the centroids' extent; leaves hold up to four.
void Scene::build_bvh(const std::vector<Eigen::AlignedBox3d>& boxes) {
  struct Task {
    std::uint32_t node, begin, end;
  };
  nodes_.assign(1, Node{});
  std::vector<Task> tasks{{0, 0, static_cast<std::uint32_t>(order_.size())}};
  constexpr std::uint32_t kLeafSize = 4;
  while (!tasks.empty()) {
    const Task task = tasks.back();
    tasks.pop_back();
    Eigen::AlignedBox3d box;
    Eigen::AlignedBox3d centroids;
    for (std::uint32_t i = task.begin; i < task.end; ++i) {
      box.extend(boxes[order_[i]]);
      centroids.extend(boxes[order_[i]].center());
    }
    nodes_[task.node].box = box;
    if (task.end - task.begin <= kLeafSize) {
      nodes_[task.node].first = task.begin;
      nodes_[task.node].count = task.end - task.begin;
      continue;
    }
    int axis = 0;
    centroids.sizes().maxCoeff(&axis);
    const std::uint32_t mid = task.begin + (task.end - task.begin) / 2;
    std::nth_element(order_.begin() + task.begin, order_.begin() + mid, order_.begin() + task.end,
                     [&](std::uint32_t a, std::uint32_t b) {
                       return boxes[a].center()[axis] < boxes[b].center()[axis];
                     });
    const auto left = static_cast<std::uint32_t>(nodes_.size());
    nodes_.resize(nodes_.size() + 2);
    nodes_[task.node].first = left;
    nodes_[task.node].count = 0;
    tasks.push_back({left, task.begin, mid});
    tasks.push_back({left + 1, mid, task.end});
  }
}

void Scene::intersect_static(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double& best,
                             std::optional<std::uint32_t>& best_id) const {
  if (nodes_.empty()) return;
  const Eigen::Vector3d inv = d.cwiseInverse();
  std::array<std::uint32_t, 64> stack{};
  std::size_t top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const Node& node = nodes_[stack[--top]];
    if (!ray_meets_box(node.box, o, d, inv, best)) continue;
    if (node.count > 0) {
      for (std::uint32_t i = node.first; i < node.first + node.count; ++i) {
        const std::uint32_t id = order_[i];
        if (const auto s = sim::intersect(parts_[id].shape, o, d, best); s && *s < best) {
          best = *s;
          best_id = id;
        }
      }
    } else {
      // Visit the child nearer along the ray first: its hit prunes the other.
      const std::uint32_t left = node.first;
      const bool right_first = (nodes_[left + 1].box.center() - nodes_[left].box.center()).dot(d) < 0.0;
      stack[top++] = right_first ? left : left + 1;
      stack[top++] = right_first ? left + 1 : left;
    }
  }
}

void Scene::intersect_moving(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t_seconds, double& best,
                             std::optional<std::uint32_t>& best_id) const {
  for (const MovingObject& moving : moving_) {
    const Placement where = moving.path.at(t_seconds);
    const Eigen::Vector3d o_local = to_local(o - where.position, where.yaw);
    const Eigen::Vector3d d_local = to_local(d, where.yaw);
    if (!ray_meets_box(moving.box_local, o_local, d_local, d_local.cwiseInverse(), best)) continue;
    for (const std::uint32_t id : moving.primitives) {
      if (const auto s = sim::intersect(parts_[id].shape, o_local, d_local, best); s && *s < best) {
        best = *s;
        best_id = id;
      }
    }
  }
}

std::optional<Hit> Scene::intersect(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                                    double t_seconds, double max_range) const {
  const double norm = direction.norm();
  if (!(norm > 0.0) || !(max_range > 0.0)) return std::nullopt;
  const Eigen::Vector3d d = direction / norm;
  double best = max_range;
  std::optional<std::uint32_t> best_id;
  intersect_static(origin, d, best, best_id);
  intersect_moving(origin, d, t_seconds, best, best_id);
  if (!best_id) return std::nullopt;
  return Hit{best, *best_id, object_of_[*best_id], parts_[*best_id].kind};
}

std::optional<Hit> Scene::intersect_brute_force(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                                                double t_seconds, double max_range) const {
  const double norm = direction.norm();
  if (!(norm > 0.0) || !(max_range > 0.0)) return std::nullopt;
  const Eigen::Vector3d d = direction / norm;
  double best = max_range;
  std::optional<std::uint32_t> best_id;
  for (std::uint32_t id = 0; id < parts_.size(); ++id) {
    if (const auto s = sim::intersect(part_at(id, t_seconds).shape, origin, d, best); s && *s < best) {
      best = *s;
      best_id = id;
    }
  }
  if (!best_id) return std::nullopt;
  return Hit{best, *best_id, object_of_[*best_id], parts_[*best_id].kind};
}

bool Scene::covered(const Eigen::Vector3d& point, double t_seconds, std::uint32_t except) const {
  if (!nodes_.empty()) {
    std::array<std::uint32_t, 64> stack{};
    std::size_t top = 0;
    stack[top++] = 0;
    while (top > 0) {
      const Node& node = nodes_[stack[--top]];
      if (!node.box.contains(point)) continue;
      if (node.count > 0) {
        for (std::uint32_t i = node.first; i < node.first + node.count; ++i) {
          if (order_[i] != except && sim::contains(parts_[order_[i]].shape, point)) return true;
        }
      } else {
        stack[top++] = node.first;
        stack[top++] = node.first + 1;
      }
    }
  }
  for (const MovingObject& moving : moving_) {
    const Placement where = moving.path.at(t_seconds);
    const Eigen::Vector3d local = to_local(point - where.position, where.yaw);
    if (!moving.box_local.contains(local)) continue;
    for (const std::uint32_t id : moving.primitives) {
      if (id != except && sim::contains(parts_[id].shape, local)) return true;
    }
  }
  return false;
}

bool Scene::contains(const Eigen::Vector3d& point, double t_seconds) const {
  return covered(point, t_seconds, std::numeric_limits<std::uint32_t>::max());
}

PointCloud Scene::sample_surface(double spacing_m, std::mt19937_64& rng, double t_seconds) const {
  return sample_surface_kinds(spacing_m, rng, t_seconds).points;
}

Scene::KindedSample Scene::sample_surface_kinds(double spacing_m, std::mt19937_64& rng, double t_seconds) const {
  if (!(spacing_m > 0.0)) throw Error("Scene::sample_surface: spacing must be positive");
  constexpr double kCoverProbe = 1e-3;  // [m] a sample is hidden when just outside it is solid
  KindedSample out;
  std::vector<SurfaceSample> samples;
  for (std::uint32_t id = 0; id < parts_.size(); ++id) {
    samples.clear();
    const Part part = part_at(id, t_seconds);
    Shape shape = part.shape;
    if (!bounds_.intersects(bounding_box(shape))) continue;
    if (auto* ground = std::get_if<GroundPatch>(&shape); ground != nullptr && ground->yaw == 0.0) {
      clip_to_bounds(*ground, bounds_);  // a ground plane may reach far beyond the region sampled
    }
    sim::sample_surface(shape, spacing_m, rng, samples);
    for (const SurfaceSample& s : samples) {
      if (!bounds_.contains(s.point) || covered(s.point + kCoverProbe * s.normal, t_seconds, id)) continue;
      out.points.push_back(s.point.cast<float>());
      out.kinds.push_back(part.kind);
    }
  }
  return out;
}

std::optional<std::uint32_t> Scene::find_object(std::string_view name) const {
  for (std::size_t i = 0; i < objects_.size(); ++i) {
    if (objects_[i].name == name) return static_cast<std::uint32_t>(i);
  }
  return std::nullopt;
}

Part Scene::part_at(std::uint32_t primitive, double t_seconds) const {
  const Part& part = parts_.at(primitive);
  const auto& object = objects_[object_of_[primitive]];
  if (!object.path) return part;
  return {placed(part.shape, object.path->at(t_seconds)), part.kind};
}

Placement Scene::object_placement(std::uint32_t object, double t_seconds) const {
  const auto& entry = objects_.at(object);
  return entry.path ? entry.path->at(t_seconds) : Placement{};
}

}  // namespace hmap::sim
