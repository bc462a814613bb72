// The Python module _hmap: a thin shell over the hmap libraries. Arrays are checked and converted
// here; every map operation is a library call. python/hmap/__init__.py adds the Python-side sugar.

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <algorithm>
#include <limits>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <memory>
#include <functional>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "hmap/core/error.hpp"
#include "hmap/core/format.hpp"
#include "hmap/core/params.hpp"
#include "hmap/core/pose.hpp"
#include "hmap/core/sensor_profile.hpp"
#include "hmap/eval/trajectory_metrics.hpp"
#include "hmap/io/cloud_reader.hpp"
#include "hmap/io/config.hpp"
#include "hmap/io/gravity.hpp"
#include "hmap/io/hmap_file.hpp"
#include "hmap/io/kitti.hpp"
#include "hmap/io/octomap_export.hpp"
#include "hmap/io/pgm_export.hpp"
#include "hmap/io/ply_export.hpp"
#include "hmap/io/png.hpp"
#include "hmap/occupancy/exported_grid.hpp"
#include "hmap/occupancy/grid_reading.hpp"
#include "hmap/io/poses.hpp"
#include "hmap/maps/mapper.hpp"
#include "hmap/occupancy/hybrid_mapper.hpp"
#include "hmap/render/render.hpp"
#include "hmap/slam/hmap_slam.hpp"
#include "hmap/slam/loop_closure.hpp"
#include "hmap/maps/map_merge.hpp"
#include "hmap/maps/raycast.hpp"
#include "hmap/occupancy/layers_merge.hpp"
#include "hmap/slam/map_align.hpp"
#include "arrays.hpp"

namespace py = pybind11;

namespace hmap::python {

void bind_sim(py::module_& m);   // sim_pybind.cpp
void bind_pvox(py::module_& m);  // pvox_pybind.cpp
void bind_sources(py::module_& io);                // sources_pybind.cpp
ImuSamples imu_samples_of(const py::handle& imu);  // sources_pybind.cpp

namespace {

py::dict scan_stats_dict(const ScanStats& s) {
  py::dict d;
  d["points_in"] = s.points_in;
  d["points_kept"] = s.points_kept;
  d["dropped_non_finite"] = s.dropped_non_finite;
  d["dropped_range"] = s.dropped_range;
  d["scan_cells"] = s.scan_cells;
  d["scan_hvoxels"] = s.scan_hvoxels;
  d["rays"] = s.rays;
  d["free_cells"] = s.free_cells;
  d["extrusion_removed"] = s.extrusion.removed;
  return d;
}

// ---------------------------------------------------------------------------------------------
// Mappers and maps

/// A Mapper or a HybridMapper with the lock that lets integrate() run without the GIL while
/// other Python threads query the map or integrate into other mappers.
struct MapperBox {
  std::mutex mutex;  // read_both takes it once for merge_maps(a, a)
  std::optional<Mapper> mapper;
  std::optional<HybridMapper> hybrid;
  std::optional<slam::HmapSlam> slam;
  PoseList slam_poses;  ///< the poses SLAM merged its scans at, one per process()
  std::optional<slam::ImuAttitudeFilter> imu;  ///< Slam(params, imu=...): the prior of each scan, as `hmap slam --imu`
  std::optional<slam::LoopCloser> loops;  ///< the Slam's key frames while slam.loop_closure is on (not for a continued map)
  bool loops_closed = false;
};

struct PyMapper {
  std::shared_ptr<MapperBox> box;
};
struct PyHybridMapper {
  std::shared_ptr<MapperBox> box;
};

/// A map to query: loaded from a file (owned), or a mapper's map, live (later scans show in it).
class Map {
 public:
  explicit Map(MapFile file) : file_(std::make_shared<MapFile>(std::move(file))) {}
  explicit Map(std::shared_ptr<MapperBox> live) : live_(std::move(live)) {}

  /// Calls f(const HMap&, const OccupancyGrid* (null without one), span of ground patches)
  /// with the mapper's lock held.
  template <typename F>
  decltype(auto) read(F&& f) const {
    if (file_) {
      return f(file_->map, file_->grid ? &*file_->grid : nullptr, std::span<const GroundPatch>(file_->ground));
    }
    const std::scoped_lock lock(live_->mutex);
    if (live_->slam) {
      return f(live_->slam->map(), static_cast<const OccupancyGrid*>(nullptr), std::span<const GroundPatch>());
    }
    if (live_->hybrid) {
      const HybridMapper& h = *live_->hybrid;
      return f(h.map(), &h.grid(), std::span<const GroundPatch>(h.ground_patches()));
    }
    return f(live_->mapper->map(), static_cast<const OccupancyGrid*>(nullptr), std::span<const GroundPatch>());
  }

  /// The cell centroids saved with a loaded map (null for a live map or a file without them).
  [[nodiscard]] const CellCentroids* file_centroids() const { return file_ && file_->centroids ? &*file_->centroids : nullptr; }
  /// The SLAM's cell centroids: those saved with a loaded map, or a live SLAM's (read them inside
  /// read(), under its lock); null for a file without them or a mapper's map.
  [[nodiscard]] const CellCentroids* centroids() const {
    if (file_) return file_->centroids ? &*file_->centroids : nullptr;
    return live_->slam ? &live_->slam->map_centroids() : nullptr;
  }

 /// The live mapper whose lock read() takes; null for a loaded map.
  [[nodiscard]] const MapperBox* lock_owner() const { return live_.get(); }

 private:
  std::shared_ptr<MapFile> file_;
  std::shared_ptr<MapperBox> live_;
};

/// Calls f(map_a, grid_a, ground_a, map_b, grid_b, ground_b) with both maps' locks held: taken
/// once when both are the same mapper's (a second lock of one std::mutex would never return), and
/// in the order of their addresses otherwise, so that merge(a, b) and merge(b, a) on two threads
/// cannot wait on each other.
template <typename F>
decltype(auto) read_both(const Map& a, const Map& b, F&& f) {
  if (a.lock_owner() != nullptr && a.lock_owner() == b.lock_owner()) {
    return a.read([&](const HMap& m, const OccupancyGrid* g, std::span<const GroundPatch> p) { return f(m, g, p, m, g, p); });
  }
  if (std::less<const MapperBox*>()(b.lock_owner(), a.lock_owner())) {
    return b.read([&](const HMap& mb, const OccupancyGrid* gb, std::span<const GroundPatch> pb) {
      return a.read([&](const HMap& ma, const OccupancyGrid* ga, std::span<const GroundPatch> pa) { return f(ma, ga, pa, mb, gb, pb); });
    });
  }
  return a.read([&](const HMap& ma, const OccupancyGrid* ga, std::span<const GroundPatch> pa) {
    return b.read([&](const HMap& mb, const OccupancyGrid* gb, std::span<const GroundPatch> pb) { return f(ma, ga, pa, mb, gb, pb); });
  });
}

void save(const Map& m, const std::filesystem::path& path) {
  m.read([&](const HMap& map, const OccupancyGrid* grid, std::span<const GroundPatch> ground) {
    py::gil_scoped_release release;
    save_hmap(path, map, ground, grid, m.centroids());  // a SLAM's map keeps its centroids, as `hmap slam` saves it
  });
}

/// An exact copy of cell centroids (their offsets as they are, not summed again).
CellCentroids copy_of(const CellCentroids& c) {
  CellCentroids out(c.cell_size());
  c.for_each([&](const CellKey& k, const Eigen::Vector2f& o, double w) { out.restore(k, o, w); });
  return out;
}

py::dict stats_dict(const Map& m) {
  return m.read([&m](const HMap& map, const OccupancyGrid* grid, std::span<const GroundPatch> ground) {
    const MapStats s = map.stats();
    py::dict d;
    d["cells"] = s.cells;
    d["hvoxels"] = s.hvoxels;
    d["tiles"] = s.tiles;
    d["memory_bytes"] = s.memory_bytes;
    d["cell_size"] = map.cell_size();
    if (s.bounds.isEmpty()) {
      d["bounds"] = py::none();
    } else {
      const Eigen::Vector3d lo = s.bounds.min(), hi = s.bounds.max();
      d["bounds"] = py::make_tuple(py::make_tuple(lo.x(), lo.y(), lo.z()), py::make_tuple(hi.x(), hi.y(), hi.z()));
    }
    d["ground_patches"] = ground.size();
    d["grid_cells"] = grid == nullptr ? py::object(py::none()) : py::object(py::int_(grid->known_cells()));
    const CellCentroids* centroids = m.centroids();  // (under the lock read() holds)
    d["cell_centroids"] = centroids == nullptr ? 0 : centroids->size();
    return d;
  });
}

py::array_t<bool> occupied(const Map& m, const py::handle& xyz) {
  const py::array arr = checked_points(xyz, "xyz");
  const auto q = py::array_t<double, py::array::forcecast>::ensure(arr).unchecked<2>();
  py::array_t<bool> out(q.shape(0));
  auto w = out.mutable_unchecked<1>();
  m.read([&](const HMap& map, const OccupancyGrid*, std::span<const GroundPatch>) {
    for (py::ssize_t i = 0; i < q.shape(0); ++i) w(i) = map.occupied(q(i, 0), q(i, 1), q(i, 2));
    return 0;
  });
  return out;
}

/// Map.raycast: rays from `origins` along `directions` ((N, 3) each, or one (3,) for all), their
/// first HVoxel within max_range: ranges (N,), NaN where none, and the points met (N, 3).
py::tuple raycast_rays(const Map& m, const py::handle& origins, const py::handle& directions, double max_range) {
  const auto rows = [](const py::handle& h, const char* name) {
    py::array a = py::array::ensure(h);
    if (!a) throw py::value_error(std::string(name) + " must be an array of shape (N, 3) or (3,)");
    if (a.ndim() == 1) a = a.attr("reshape")(1, -1);
    return checked_points(a, name);
  };
  const auto o = py::array_t<double, py::array::forcecast>::ensure(rows(origins, "origins")).unchecked<2>();
  const auto d = py::array_t<double, py::array::forcecast>::ensure(rows(directions, "directions")).unchecked<2>();
  const py::ssize_t n = std::max(o.shape(0), d.shape(0));
  if ((o.shape(0) != n && o.shape(0) != 1) || (d.shape(0) != n && d.shape(0) != 1)) {
    throw py::value_error(format("origins hold %zd rows and directions %zd: give as many, or one of either",
                                 o.shape(0), d.shape(0)));
  }
  py::array_t<double> ranges(n);
  py::array_t<double> points({n, py::ssize_t{3}});
  auto r = ranges.mutable_unchecked<1>();
  auto q = points.mutable_unchecked<2>();
  m.read([&](const HMap& map, const OccupancyGrid*, std::span<const GroundPatch>) {
    py::gil_scoped_release release;
    for (py::ssize_t k = 0; k < n; ++k) {
      const py::ssize_t a = o.shape(0) == 1 ? 0 : k;
      const py::ssize_t b = d.shape(0) == 1 ? 0 : k;
      const auto hit = raycast(map, {o(a, 0), o(a, 1), o(a, 2)}, {d(b, 0), d(b, 1), d(b, 2)}, max_range);
      const double nan = std::numeric_limits<double>::quiet_NaN();
      r(k) = hit ? hit->range : nan;
      for (int c = 0; c < 3; ++c) q(k, c) = hit ? hit->point[c] : nan;
    }
    return 0;
  });
  return py::make_tuple(ranges, points);
}

/// Map.__iter__: (i, j, column) per non-empty cell, by i then j; the column as Map.column gives it.
py::iterator cells_of(const Map& m) {
  py::list cells;
  m.read([&](const HMap& map, const OccupancyGrid*, std::span<const GroundPatch>) {
    std::vector<CellKey> keys;
    map.for_each_column([&](const CellKey& k, const ColumnView&) { keys.push_back(k); });
    std::sort(keys.begin(), keys.end(), [](const CellKey& a, const CellKey& b) { return a.i != b.i ? a.i < b.i : a.j < b.j; });
    for (const CellKey& k : keys) {
      const ColumnView c = map.column(k);
      py::array_t<HVoxel> col(static_cast<py::ssize_t>(c.size()));
      std::memcpy(col.mutable_data(), c.data(), c.size() * sizeof(HVoxel));
      cells.append(py::make_tuple(k.i, k.j, col));
    }
    return 0;
  });
  return py::iter(cells);
}

py::array column(const Map& m, double x, double y) {
  return m.read([&](const HMap& map, const OccupancyGrid*, std::span<const GroundPatch>) {
    const ColumnView c = map.column(x, y);
    py::array_t<HVoxel> out(static_cast<py::ssize_t>(c.size()));
    if (!c.empty()) std::memcpy(out.mutable_data(), c.data(), c.size() * sizeof(HVoxel));
    return py::array(out);
  });
}

/// One HVoxel with its cell, for Map.hvoxels().
struct CellHVoxel {
  std::int32_t i, j;
  float z_min, z_max, count, density;
};

py::array hvoxels_of(const Map& m) {
  return m.read([](const HMap& map, const OccupancyGrid*, std::span<const GroundPatch>) {
    std::vector<CellHVoxel> all;
    map.for_each_column([&](const CellKey& k, const ColumnView& c) {
      for (const HVoxel& v : c) all.push_back({k.i, k.j, v.z_min, v.z_max, v.count, v.density});
    });
    // The tiles come in no particular order: by cell, then height, the same for the same map.
    std::stable_sort(all.begin(), all.end(), [](const CellHVoxel& a, const CellHVoxel& b) {
      return a.i != b.i ? a.i < b.i : a.j < b.j;
    });
    py::array_t<CellHVoxel> out(static_cast<py::ssize_t>(all.size()));
    if (!all.empty()) std::memcpy(out.mutable_data(), all.data(), all.size() * sizeof(CellHVoxel));
    return py::array(out);
  });
}

py::array_t<float> recover(const Map& m, std::optional<double> z_step) {
  return m.read([&](const HMap& map, const OccupancyGrid*, std::span<const GroundPatch>) {
    const double step = z_step.value_or(map.cell_size());  // the CLI's default (export --points)
    if (!(step >= 1e-3 && step <= 100.0)) {
      throw py::value_error(format("z_step = %g m is out of its range [0.001, 100] m", step));
    }
    PointCloud points;
    {
      py::gil_scoped_release release;
      points = recover_points(map, step);
    }
    return points_array(std::move(points));
  });
}

/// The 2D occupancy grid as a dense array with where it lies.
struct Grid2D {
  py::array_t<float> probability;  ///< (height, width); [row, col] is the cell at x = ox + (col + ½)·res, y = oy + (row + ½)·res
  std::pair<double, double> origin;  ///< [m] lower-left corner of cell [0, 0]
  double resolution = 0.0;           ///< [m]
};

std::optional<Grid2D> grid_of(const Map& m) {
  return m.read([](const HMap&, const OccupancyGrid* grid, std::span<const GroundPatch>) -> std::optional<Grid2D> {
    if (grid == nullptr) return std::nullopt;
    const GridRaster r = raster(*grid);
    Grid2D g;
    g.probability = py::array_t<float>({static_cast<py::ssize_t>(r.height), static_cast<py::ssize_t>(r.width)});
    if (!r.probability.empty()) std::memcpy(g.probability.mutable_data(), r.probability.data(), r.probability.size() * sizeof(float));
    g.origin = {r.i_min * r.cell_size, r.j_min * r.cell_size};
    g.resolution = r.cell_size;
    return g;
  });
}

py::dict ground_of(const Map& m) {
  return m.read([](const HMap&, const OccupancyGrid*, std::span<const GroundPatch> ground) {
    const auto n = static_cast<py::ssize_t>(ground.size());
    py::array_t<double> center({n, py::ssize_t{3}}), normal({n, py::ssize_t{3}});
    py::array_t<double> half_size(n);
    py::array_t<std::int32_t> parent(n);
    auto c = center.mutable_unchecked<2>();
    auto nm = normal.mutable_unchecked<2>();
    auto h = half_size.mutable_unchecked<1>();
    auto p = parent.mutable_unchecked<1>();
    for (py::ssize_t k = 0; k < n; ++k) {
      const GroundPatch& g = ground[static_cast<std::size_t>(k)];
      for (int d = 0; d < 3; ++d) {
        c(k, d) = g.center[d];
        nm(k, d) = g.normal[d];
      }
      h(k) = g.half_size;
      p(k) = g.parent;
    }
    py::dict d;
    d["center"] = center;
    d["normal"] = normal;
    d["half_size"] = half_size;
    d["parent"] = parent;
    return d;
  });
}

/// Integrates one scan without the GIL, under the mapper's lock.
template <typename Integrate>
auto integrate_scan(MapperBox& box, const py::handle& points, const py::handle& pose, const std::string& non_finite,
                    Integrate&& integrate) {
  const NonFinite mode = non_finite_mode(non_finite);
  const py::array arr = checked_points(points, "points");
  const Pose T_map_sensor = pose_of(pose, "T_map_sensor");
  PointCloud storage;
  const std::span<const Point3f> pts = points_of(arr, storage, mode, "points");
  py::gil_scoped_release release;  // `arr` keeps the viewed buffer alive meanwhile
  const std::scoped_lock lock(box.mutex);
  return integrate(pts, T_map_sensor);
}

// ---------------------------------------------------------------------------------------------
// Parameters

std::vector<std::string> param_names() {
  Params p;
  std::vector<std::string> names;
  for (const auto& r : param_refs(p)) names.push_back(r.name);
  return names;
}

/// Sets one parameter and validates the whole (the library's checks and messages); on failure
/// `params` is left as it was.
void set_validated(Params& params, const std::string& name, double value) {
  Params changed = params;
  set_param(changed, name, value);
  validate(changed);
  params = changed;
}

py::dict describe(const std::string& name) {
  Params p;
  for (const auto& r : param_refs(p)) {
    if (r.name != name) continue;
    py::dict d;
    d["name"] = r.name;
    d["unit"] = r.unit;
    d["description"] = r.description;
    d["default"] = r.get();
    d["range"] = r.range.text();
    return d;
  }
  (void)get_param(p, name);  // throws the library's "unknown parameter" message
  return {};
}

// ---------------------------------------------------------------------------------------------
// Parameters chosen from a scan, SLAM, trajectory metrics, sequences

py::dict scan_params_dict(const py::handle& first_scan, const std::optional<std::string>& preset_name,
                          const std::optional<std::filesystem::path>& config, const std::vector<std::string>& overrides,
                          std::optional<double> cell_size, std::optional<double> min_range,
                          std::optional<double> max_range) {
  const py::array arr = checked_points(first_scan, "first_scan");
  PointCloud storage;
  const std::span<const Point3f> pts = points_of(arr, storage, NonFinite::kDrop, "first_scan");
  ParamSources sources{preset_name.value_or(""), config.value_or(std::filesystem::path()), overrides, cell_size,
                       min_range, max_range, {}};
  const ScanParams chosen = resolve_params_for_scan(sources, pts);
  py::list adapted;
  for (const ChosenDefault& c : chosen.adapted) {
    py::dict d;
    d["name"] = c.name;
    d["value"] = c.value;
    d["reason"] = c.reason;
    adapted.append(d);
  }
  py::dict d;
  d["params"] = chosen.params;
  d["preset"] = chosen.preset;
  d["preset_reason"] = chosen.preset_reason.empty() ? py::object(py::none()) : py::object(py::str(chosen.preset_reason));
  d["adapted"] = adapted;
  return d;
}

struct PySlam {
  std::shared_ptr<MapperBox> box;
};

py::dict slam_step_dict(const slam::SlamStep& step) {
  const slam::MatchResult& m = step.match;
  const slam::AttitudeFit& af = step.attitude;
  py::dict d;
  d["T_map_sensor"] = matrix_array(step.T_map_sensor);
  d["T_map_merged"] = matrix_array(step.T_map_merged);
  d["merged_at_s"] = step.merged_at_s;
  d["guess"] = py::make_tuple(step.guess.x, step.guess.y, step.guess.yaw);
  d["matched"] = step.matched;
  d["converged"] = m.converged;
  d["iterations"] = m.iterations;
  d["initial_cost"] = m.initial_cost;
  d["final_cost"] = m.final_cost;
  d["score"] = m.score;
  d["prior_cost"] = m.prior_cost;
  d["hvoxels_used"] = m.hvoxels_used;
  d["eigenvalues"] = vector_array(m.eigenvalues);
  d["degenerate"] = m.degenerate;
  d["coarse_search"] = m.coarse_search;
  d["coarse_rejected"] = m.coarse_rejected;
  d["wide_search"] = m.wide_search;
  d["skipped"] = m.skipped;
  d["heading_only"] = m.heading_only;
  py::dict fit;
  fit["ran"] = af.ran;
  fit["iterations"] = af.iterations;
  fit["surfaces"] = af.surfaces;
  fit["rms"] = af.rms;
  fit["z"] = af.attitude.z;
  fit["roll"] = af.attitude.roll;
  fit["pitch"] = af.attitude.pitch;
  d["attitude_fit"] = fit;
  py::dict walls;  // slam.wall_refine: the refinement against the map's walls
  walls["applied"] = step.walls.applied;
  walls["pairs"] = step.walls.pairs;
  walls["rms"] = step.walls.rms;
  walls["iterations"] = step.walls.iterations;
  walls["change"] = py::make_tuple(step.walls.change.x, step.walls.change.y, step.walls.change.yaw);
  walls["skipped_because"] = std::string(step.walls.skipped_because);
  d["walls"] = walls;
  // slam.wall_tilt_drift: the tilt the walls' lean corrected [rad], and the walls it was read on
  d["wall_tilt"] = py::make_tuple(step.wall_tilt, step.wall_tilt_walls);
  py::dict observable;
  const char* axes[] = {"x", "y", "z", "roll", "pitch", "yaw"};
  for (std::size_t a = 0; a < 6; ++a) observable[axes[a]] = step.observable[a];
  d["observable"] = observable;
  d["planar_passes"] = step.planar_passes;
  d["deskewed"] = step.deskewed;
  d["sweep_velocity"] = py::make_tuple(vector_array(step.sweep_velocity.angular), vector_array(step.sweep_velocity.linear));
  d["imu_used"] = step.imu_used;
  d["tilt_hypotheses"] = step.tilt_hypotheses;
  d["tilt_from_floor"] = step.tilt_from_floor;
  d["mapping"] = scan_stats_dict(step.mapping);
  if (step.relocalised) {
    const slam::MapAlignResult& r = *step.relocalised;
    py::dict found;
    found["shift"] = py::make_tuple(r.shift.x, r.shift.y, r.shift.z, r.shift.yaw);
    found["score"] = r.match.score;
    found["columns_used"] = r.columns_used;
    found["floor_pairs"] = r.floor_pairs;
    d["relocalised"] = found;
  } else {
    d["relocalised"] = py::none();
  }
  return d;
}

py::dict slam_process(PySlam& self, const py::handle& points, std::optional<double> stamp, const py::handle& times,
                      const py::handle& attitude, const py::handle& guess, const std::string& non_finite) {
  const NonFinite mode = non_finite_mode(non_finite);
  const py::array arr = checked_points(points, "points");
  PointCloud storage;
  std::span<const Point3f> pts = points_of(arr, storage, mode, "points");
  std::vector<float> point_times = times_of(times, pts.size());
  if (mode == NonFinite::kDrop) {
    // The matcher reads every point: the non-finite ones (and their times) go before it, as the
    // CLI's readers drop them.
    PointCloud finite;
    std::vector<float> finite_times;
    for (std::size_t i = 0; i < pts.size(); ++i) {
      if (!pts[i].allFinite()) continue;
      finite.push_back(pts[i]);
      if (!point_times.empty()) finite_times.push_back(point_times[i]);
    }
    if (finite.size() != pts.size()) {
      storage = std::move(finite);
      point_times = std::move(finite_times);
      pts = storage;
    }
  }
  if (stamp && !std::isfinite(*stamp)) throw py::value_error(format("stamp must be finite, got %g", *stamp));
  if (self.box->imu && !stamp) throw py::value_error("a Slam with an IMU needs each scan's stamp [s], on the IMU's clock");
  slam::ScanInput in;
  in.points_sensor = pts;
  in.times = point_times;
  in.stamp = stamp;
  if (!attitude.is_none()) in.attitude = slam::attitude_of(pose_of(attitude, "attitude"));
  if (!guess.is_none()) in.guess = slam::planar_of(pose_of(guess, "guess"));
  MapperBox& box = *self.box;
  slam::SlamStep step;
  {
    py::gil_scoped_release release;  // `arr` keeps the viewed buffer alive meanwhile
    const std::scoped_lock lock(box.mutex);
    if (box.imu) in.imu = box.imu->prior_for_scan(*stamp, in.times, box.slam->velocity().linear);
    step = box.slam->process(in);
    box.slam_poses.push_back(step.T_map_sensor);
    if (box.loops) box.loops->add_scan(pts, step.T_map_sensor);
  }
  return slam_step_dict(step);
}

/// Slam.close_loops: the pose graph over the key frames, every pose corrected, the map rebuilt
/// from the scans read again (as `hmap slam` does after its last scan).
py::dict slam_close_loops(PySlam& self, const py::function& read_scan) {
  MapperBox& box = *self.box;
  slam::LoopClosureResult closed;
  PoseList built_at;
  std::optional<HMap> built;  // a copy: read_scan may use this Slam while the tiles are rebuilt
  std::optional<CellCentroids> centroids;  // the same
  Params params;
  {
    py::gil_scoped_release release;
    const std::scoped_lock lock(box.mutex);
    if (!box.loops) {
      throw py::value_error("close_loops: loop closure is off for this Slam (slam.loop_closure=0, or a continued map)");
    }
    if (box.loops_closed) throw py::value_error("close_loops: the loops were closed already (call it once, after the last scan)");
    box.loops_closed = true;
    closed = box.loops->close();
    built_at = box.slam_poses;
    params = box.slam->params();
    if (!closed.closures.empty() && box.slam->map_holds_scans_as_given()) {
      built.emplace(box.slam->map().params());
      merge_map(*built, box.slam->map());  // into an empty map: an exact copy
    }
    if (!closed.closures.empty()) {
      centroids = copy_of(box.slam->map_centroids());
    }
  }
  py::dict d;
  py::list closures;
  for (const slam::LoopClosure& c : closed.closures) {
    py::dict e;
    e["keyframe_old"] = c.keyframe_old;
    e["keyframe_new"] = c.keyframe_new;
    e["scan_old"] = c.scan_old;
    e["scan_new"] = c.scan_new;
    e["descriptor_distance"] = c.descriptor_distance;
    e["descriptor_yaw"] = c.descriptor_yaw;
    e["score"] = c.score;
    e["T_old_new"] = py::make_tuple(c.T_old_new.x, c.T_old_new.y, c.T_old_new.z, c.T_old_new.yaw);
    e["drift_translation"] = c.drift_translation;
    e["drift_yaw"] = c.drift_yaw;
    closures.append(e);
  }
  d["closures"] = closures;
  d["keyframes"] = closed.keyframes;
  d["candidates_verified"] = closed.candidates_verified;
  d["max_correction"] = closed.max_correction;
  d["end_correction"] = closed.end_correction;
  if (closed.closures.empty()) {
    d["poses"] = poses_array(built_at);
    d["map"] = Map(self.box);
    d["rebuild"] = py::none();
    return d;
  }
  std::optional<TileRebuild> rebuilt_at;
  {
    py::gil_scoped_release release;
    rebuilt_at = slam::map_at_corrected_poses(params, built ? &*built : nullptr, built_at, closed.T_map_sensor,
                                           [&](std::size_t k, PointCloud& out) {
      py::gil_scoped_acquire gil;
      const py::array arr = checked_points(read_scan(k), "read_scan(k)");
      PointCloud storage;
      const std::span<const Point3f> pts = points_of(arr, storage, NonFinite::kDrop, "read_scan(k)");
      out.assign(pts.begin(), pts.end());
    }, centroids ? &*centroids : nullptr);
  }
  TileRebuild& rebuilt = *rebuilt_at;
  {
    const std::scoped_lock lock(box.mutex);
    box.slam_poses = rebuilt.T_map_sensor;
  }
  py::dict r;
  r["whole"] = rebuilt.whole;
  r["scans_moved"] = rebuilt.scans_moved;
  r["scans_integrated"] = rebuilt.scans_integrated;
  r["tiles_rebuilt"] = rebuilt.tiles_rebuilt;
  r["tiles_kept"] = rebuilt.tiles_kept;
  d["rebuild"] = r;
  d["poses"] = poses_array(rebuilt.T_map_sensor);
  // The centroids at the corrected poses go with the map, so that Map.save writes them as `hmap
  // slam` does.
  d["map"] = Map(MapFile{std::move(rebuilt.map), {}, std::nullopt, std::move(rebuilt.centroids)});
  return d;
}

py::dict trajectory_dict(const py::handle& truth, const py::handle& estimate, const std::optional<std::vector<double>>& lengths,
                         int start_frame_step) {
  const PoseList t = poses_of(truth, "truth");
  const PoseList e = poses_of(estimate, "estimate");
  if (t.size() != e.size()) {
    throw py::value_error(format("estimate holds %zu poses, truth holds %zu", e.size(), t.size()));
  }
  TrajectoryEvalParams params;
  if (lengths) params.segment_lengths = *lengths;
  params.start_frame_step = start_frame_step;
  const TrajectoryMetrics m = evaluate_trajectory(t, e, params);
  py::dict d;
  d["frames"] = m.frames;
  d["path_length_m"] = m.path_length_m;
  d["ate_rmse_m"] = m.ate_rmse_m;
  d["ate_mean_m"] = m.ate_mean_m;
  d["ate_median_m"] = m.ate_median_m;
  d["ate_max_m"] = m.ate_max_m;
  d["ate_rmse_aligned_m"] = m.ate_rmse_aligned_m;
  d["ate_mean_aligned_m"] = m.ate_mean_aligned_m;
  d["ate_median_aligned_m"] = m.ate_median_aligned_m;
  d["ate_max_aligned_m"] = m.ate_max_aligned_m;
  d["ate_rmse_origin_m"] = m.ate_rmse_origin_m;
  d["ate_max_origin_m"] = m.ate_max_origin_m;
  d["end_error_origin_m"] = m.end_error_origin_m;
  d["end_error_origin_planar_m"] = m.end_error_origin_planar_m;
  d["T_truth_estimate"] = matrix_array(m.T_truth_estimate);
  d["rpe_frame_trans_rmse_m"] = m.rpe_frame_trans_rmse_m;
  d["rpe_frame_rot_rmse_deg"] = m.rpe_frame_rot_rmse_deg;
  d["rpe_trans_pct"] = m.rpe_trans_pct;
  d["rpe_rot_deg_per_m"] = m.rpe_rot_deg_per_m;
  d["rpe_segments"] = m.rpe_segments;
  d["segment_lengths"] = m.segment_length_source == SegmentLengthSource::kFractionOfPath ? "fraction_of_path" : "kitti";
  d["segment_lengths_m"] = m.segment_lengths_m;
  py::list per_length;
  for (const auto& l : m.per_length) {
    py::dict p;
    p["length_m"] = l.length_m;
    p["segments"] = l.segments;
    p["trans_pct"] = l.trans_pct;
    p["rot_deg_per_m"] = l.rot_deg_per_m;
    per_length.append(p);
  }
  d["per_length"] = per_length;
  return d;
}

py::dict kitti_dict(const std::filesystem::path& dir, std::optional<std::size_t> max_scans) {
  KittiSequenceOptions options;
  if (max_scans && *max_scans > 0) options.max_scans = max_scans;
  const KittiSequence seq = open_kitti_sequence(dir, options);
  std::vector<std::string> paths;
  for (const auto& p : seq.scan_paths) paths.push_back(p.string());
  if (max_scans && *max_scans > 0 && paths.size() > *max_scans) paths.resize(*max_scans);
  py::dict d;
  d["scans"] = paths;
  if (seq.T_map_scan) {
    PoseList poses = *seq.T_map_scan;
    poses.resize(std::min(poses.size(), paths.size()));
    d["T_map_scan"] = poses_array(poses);
  } else {
    d["T_map_scan"] = py::none();
  }
  d["T_cam_velo"] = seq.T_cam_velo ? py::object(matrix_array(*seq.T_cam_velo)) : py::object(py::none());
  if (seq.times.empty()) {
    d["times"] = py::none();
  } else {
    std::vector<double> times(seq.times.begin(), seq.times.begin() + static_cast<std::ptrdiff_t>(std::min(seq.times.size(), paths.size())));
    d["times"] = py::array_t<double>(static_cast<py::ssize_t>(times.size()), times.data());
  }
  return d;
}

// ---------------------------------------------------------------------------------------------
// Writers: `hmap export`'s files from a Map

/// The grid `hmap export` writes (hmap/occupancy/exported_grid.hpp) for a map and its grid choice.
ExportedGrid exported_grid(const HMap& map, const OccupancyGrid* grid, std::span<const GroundPatch> ground,
                           const std::string& source) {
  const std::optional<GridSource> parsed = parse_grid_source(source);
  if (!parsed) throw py::value_error("grid must be 'both', 'kept' or 'judged', got '" + source + "'");
  ExportGridParams p;
  p.source = *parsed;
  ExportedGrid choice = export_grid(map, ground, grid, p);
  if (!choice.ground_found) {
    throw Error(format("no ground found near the hint (%g, %g, %g): the map holds no floor to judge its columns on",
                       choice.hint.x(), choice.hint.y(), choice.hint.z()));
  }
  return choice;
}

void write_ply(const Map& m, const std::filesystem::path& path, bool points, std::optional<double> z_step) {
  m.read([&](const HMap& map, const OccupancyGrid*, std::span<const GroundPatch>) {
    if (!points) {
      py::gil_scoped_release release;
      write_hvoxel_boxes_ply(path, map);
      return 0;
    }
    const double step = z_step.value_or(map.cell_size());  // export --points' default
    if (!(step >= 1e-3 && step <= 100.0)) throw py::value_error(format("z_step = %g m is out of its range [0.001, 100] m", step));
    py::gil_scoped_release release;
    write_points_ply(path, recover_points(map, step, MemoryBudget{}));
    return 0;
  });
}

py::dict write_pgm(const Map& m, const std::filesystem::path& stem, const std::string& source) {
  return m.read([&](const HMap& map, const OccupancyGrid* grid, std::span<const GroundPatch> ground) {
    std::size_t occupied = 0, free_cells = 0;
    std::string what;
    {
      py::gil_scoped_release release;
      const ExportedGrid choice = exported_grid(map, grid, ground, source);
      PgmExportParams pgm;
      pgm.reading = GridReading::for_map(map.params().occupancy);  // as `hmap export --pgm` reads the grid
      write_pgm_map(stem, choice.grid, pgm);
      choice.grid.for_each_cell([&](const CellKey&, float l) {
        const CellClass c = pgm.reading.classify(probability(l));
        occupied += c == CellClass::kOccupied ? 1 : 0;
        free_cells += c == CellClass::kFree ? 1 : 0;
      });
      what = choice.what;
    }
    py::dict d;
    d["pgm"] = pgm_stem(stem).string() + ".pgm";
    d["yaml"] = pgm_stem(stem).string() + ".yaml";
    d["occupied"] = occupied;
    d["free"] = free_cells;
    d["grid"] = what;
    return d;
  });
}

py::dict write_bt(const Map& m, const std::filesystem::path& path) {
  return m.read([&](const HMap& map, const OccupancyGrid* grid, std::span<const GroundPatch> ground) {
    OctomapExportStats s;
    {
      py::gil_scoped_release release;
      // Free leaves from the exported grid when the map holds one and its ground, as `hmap export --bt`.
      std::vector<FreeBand> free;
      if (grid != nullptr && grid->known_cells() > 0 && !ground.empty()) {
        const ExportedGrid choice = exported_grid(map, grid, ground, "both");
        free = free_bands(choice.grid, choice.ground, map.params().occupancy.z_plus);
      }
      s = write_octomap_bt(path, map, free, MemoryBudget{});
    }
    py::dict d;
    d["occupied_voxels"] = s.occupied_voxels;
    d["free_voxels"] = s.free_voxels;
    d["leaves"] = s.leaves;
    return d;
  });
}

// ---------------------------------------------------------------------------------------------
// Pictures (hmap.render): the library's RgbImage as (H, W, 3) uint8 arrays

render::HeightRange height_range(std::optional<double> z_low, std::optional<double> z_high) {
  for (const std::optional<double>& z : {z_low, z_high}) {
    if (z && !std::isfinite(*z)) throw py::value_error(format("z_low / z_high must be finite, got %g", *z));
  }
  return {z_low.value_or(NAN), z_high.value_or(NAN)};
}

/// `paths`: None, one (N, 4, 4) array, or a sequence of them (each an array or a list of 4x4).
std::vector<PoseList> paths_of(const py::handle& paths) {
  std::vector<PoseList> out;
  if (paths.is_none()) return out;
  if (py::isinstance<py::array>(paths)) {
    if (py::reinterpret_borrow<py::array>(paths).ndim() != 3) {
      throw py::value_error("paths must be an (N, 4, 4) array of poses or a sequence of them, got an array of " +
                            std::to_string(py::reinterpret_borrow<py::array>(paths).ndim()) + " dimensions");
    }
    out.push_back(poses_of(paths, "paths"));
    return out;
  }
  if (!py::isinstance<py::sequence>(paths) || py::isinstance<py::str>(paths)) {
    throw py::value_error("paths must be an (N, 4, 4) array of poses or a sequence of them");
  }
  const auto seq = py::reinterpret_borrow<py::sequence>(paths);
  for (std::size_t k = 0; k < seq.size(); ++k) {
    out.push_back(poses_of(seq[k], format("paths[%zu]", k).c_str()));
  }
  return out;
}

py::tuple render_top(const Map& m, const std::string& layer_name, int max_pixels, std::optional<double> z_low,
                     std::optional<double> z_high, const py::handle& paths_obj,
                     const std::optional<std::vector<std::string>>& labels, bool legend) {
  render::check_max_pixels(max_pixels);
  const render::HeightRange range = height_range(z_low, z_high);
  render::TopLayer layer = render::TopLayer::kHeight;
  if (layer_name == "occupancy") {
    layer = render::TopLayer::kOccupancy;
  } else if (layer_name == "ground") {
    layer = render::TopLayer::kGround;
  } else if (layer_name != "height") {
    throw py::value_error("layer must be 'height', 'occupancy' or 'ground', got '" + layer_name + "'");
  }
  const std::vector<PoseList> paths = paths_of(paths_obj);
  if (labels && labels->size() != paths.size()) {
    throw py::value_error(format("labels: %zu given for %zu paths", labels->size(), paths.size()));
  }
  std::vector<render::LabelledPath> labelled;
  for (std::size_t k = 0; k < paths.size(); ++k) {
    labelled.push_back({&paths[k], labels ? (*labels)[k] : format("path %zu", k + 1)});
  }
  render::TopPicture picture = m.read([&](const HMap& map, const OccupancyGrid* grid, std::span<const GroundPatch> ground) {
    py::gil_scoped_release release;
    if (layer == render::TopLayer::kOccupancy && (grid == nullptr || grid->known_cells() == 0)) {
      // No grid kept scan by scan (a SLAM map, a Mapper's): the one `hmap export --pgm` derives.
      const ExportedGrid derived = exported_grid(map, nullptr, ground, "both");
      return render::render_top_view(map, layer, range, max_pixels, &derived.grid, derived.ground, labelled, legend);
    }
    return render::render_top_view(map, layer, range, max_pixels, grid, ground, labelled, legend);
  });
  return py::make_tuple(image_array(std::move(picture.image)), picture.viewport);
}

py::array_t<std::uint8_t> render_oblique(const Map& m, int max_pixels, std::optional<double> z_low,
                                         std::optional<double> z_high) {
  render::check_max_pixels(max_pixels);
  const render::HeightRange range = height_range(z_low, z_high);
  RgbImage image = m.read([&](const HMap& map, const OccupancyGrid*, std::span<const GroundPatch>) {
    py::gil_scoped_release release;
    return render::render_oblique(map, range, max_pixels);
  });
  return image_array(std::move(image));
}

py::array_t<std::uint8_t> draw_path(const py::handle& image, const render::TopViewport& vp, const py::handle& poses,
                                    const std::array<int, 3>& colour) {
  RgbImage img = image_of(image, "image");
  for (const int c : colour) {
    if (c < 0 || c > 255) throw py::value_error(format("colour must be three numbers in [0, 255], got %d", c));
  }
  const PoseList path = poses_of(poses, "poses");
  render::draw_path(img, vp, path, static_cast<std::uint8_t>(colour[0]), static_cast<std::uint8_t>(colour[1]),
                    static_cast<std::uint8_t>(colour[2]));
  return image_array(std::move(img));
}

void write_png_array(const std::filesystem::path& path, const py::handle& image) {
  const RgbImage img = image_of(image, "image");
  py::gil_scoped_release release;
  write_png(path, img);
}

}  // namespace

/// Maps of two sessions made one (`hmap merge`): the HMAP, and the 2D grid and ground patches
/// when both maps hold them.
Map merge_maps(const Map& a, const Map& b, const std::array<double, 4>& shift_xyzyaw) {
  const PlanarShift shift{shift_xyzyaw[0], shift_xyzyaw[1], shift_xyzyaw[2], shift_xyzyaw[3]};
  const bool moved = shift.x != 0.0 || shift.y != 0.0 || shift.z != 0.0 || shift.yaw != 0.0;
  return read_both(a, b, [&](const HMap& map_a, const OccupancyGrid* grid_a, std::span<const GroundPatch> ground_a,
                             const HMap& map_b, const OccupancyGrid* grid_b, std::span<const GroundPatch> ground_b) {
    py::gil_scoped_release release;
    MapFile out{HMap(map_a.params()), {}, std::nullopt, std::nullopt};
    merge_map(out.map, map_a);  // into an empty map: an exact copy
    if (moved) {
      merge_map(out.map, shifted_map(map_b, shift));
    } else {
      merge_map(out.map, map_b);
    }
    if (grid_a != nullptr && grid_b != nullptr) {
      out.grid.emplace(grid_a->cell_size(), probability(grid_a->clamp_min_log_odds()), probability(grid_a->clamp_max_log_odds()));
      add_evidence(*out.grid, *grid_a);
      if (moved) {
        add_evidence(*out.grid, shifted_grid(*grid_b, shift));
      } else {
        add_evidence(*out.grid, *grid_b);
      }
      out.ground.assign(ground_a.begin(), ground_a.end());
      if (moved) {
        join_ground(out.ground, shifted_ground(ground_b, shift));
      } else {
        join_ground(out.ground, ground_b);
      }
    }
    // The SLAM's cell centroids of either map, the second's moved as its map (as `hmap merge`).
    const CellCentroids* centroids_a = a.centroids();
    const CellCentroids* centroids_b = b.centroids();
    if ((centroids_a != nullptr && centroids_a->size() > 0) || (centroids_b != nullptr && centroids_b->size() > 0)) {
      out.centroids = centroids_a != nullptr ? copy_of(*centroids_a) : CellCentroids(map_a.cell_size());
      if (centroids_b != nullptr) out.centroids->add(*centroids_b, shift.x, shift.y, shift.yaw);
    }
    return Map(std::move(out));
  });
}

/// A map cut to a range of tiles (the HMAP alone: the ground tree and the 2D grid are not cut).
Map crop_map_of(const Map& m, const std::array<std::int32_t, 4>& tiles) {
  return m.read([&](const HMap& map, const OccupancyGrid*, std::span<const GroundPatch>) {
    py::gil_scoped_release release;
    return Map(MapFile{crop_map(map, TileRange{tiles[0], tiles[1], tiles[2], tiles[3]}), {}, std::nullopt, std::nullopt});
  });
}

py::dict align_maps_dict(const Map& a, const Map& b, const std::array<double, 4>& guess, double search, double search_yaw) {
  const slam::MapAlignResult r = read_both(a, b, [&](const HMap& map_a, const OccupancyGrid*, std::span<const GroundPatch>,
                                                     const HMap& map_b, const OccupancyGrid*, std::span<const GroundPatch>) {
    py::gil_scoped_release release;
    slam::MapAlignOptions options;
    options.guess = {guess[0], guess[1], guess[2], guess[3]};
    options.search_translation = search;
    options.search_rotation = search_yaw;
    return slam::align_maps(map_a, map_b, options);
  });
  py::dict d;
  d["shift"] = py::make_tuple(r.shift.x, r.shift.y, r.shift.z, r.shift.yaw);
  d["score"] = r.match.score;
  d["converged"] = r.match.converged;
  d["degenerate"] = r.match.degenerate;
  d["hvoxels_used"] = r.match.hvoxels_used;
  d["columns_used"] = r.columns_used;
  d["floor_pairs"] = r.floor_pairs;
  return d;
}

void bind_merge(py::module_& m) {
  m.def("merge_maps", &merge_maps, py::arg("a"), py::arg("b"), py::kw_only(),
        py::arg("shift") = std::array<double, 4>{0.0, 0.0, 0.0, 0.0},
        "`hmap merge`: a new Map, `a` with `b` merged in (III-D per column; a column only one map holds is copied "
        "exactly), `b` first moved by shift = (x, y, z [m], yaw [rad]), its frame in `a`'s. The 2D grids' "
        "log-odds add and the ground patches join when both maps hold them; the SLAM's cell centroids of either are "
        "kept (`b`'s moved with it). Same cell size required (hmap.Error).");
  m.def("align_maps", &align_maps_dict, py::arg("a"), py::arg("b"), py::kw_only(),
        py::arg("guess") = std::array<double, 4>{0.0, 0.0, 0.0, 0.0}, py::arg("search") = 5.0, py::arg("search_yaw") = 0.5,
        "`hmap merge --align`: registers `b` onto `a` (the scan matcher over the overlapping columns after a coarse "
        "search of +-search [m] and +-search_yaw [rad] around guess = (x, y, z, yaw)). Returns {'shift': (x, y, z, "
        "yaw), 'score', 'converged', 'degenerate', 'hvoxels_used', 'columns_used', 'floor_pairs'}; pass the shift "
        "to merge_maps.");
  m.def("crop_map", &crop_map_of, py::arg("map"), py::arg("tiles"),
        "A new Map holding the HVoxels of `map` in tiles = (i_begin, j_begin, i_end, j_end), tile keys "
        "[i_begin, i_end) x [j_begin, j_end), copied exactly; tile (a, b) covers x in [a, a + 1) * TILE_CELLS * "
        "cell_size, y likewise. The HMAP alone (no 2D grid, no ground patches). Built from every scan that reaches "
        "those tiles, it equals the one-run map there; maps cut to disjoint ranges merge_maps to their union.");
  m.attr("TILE_CELLS") = HMap::kTileSize;
}

PYBIND11_MODULE(_hmap, m) {
  PYBIND11_NUMPY_DTYPE(HVoxel, z_min, z_max, count, density);  // a column as a structured array
  PYBIND11_NUMPY_DTYPE(CellHVoxel, i, j, z_min, z_max, count, density);
  m.doc() = "hmap: height-voxel maps (HMAP), 2D occupancy and ground patches from 3D point clouds";

  // hmap::Error and hmap::InputError: every library message, as ValueError subclasses (the
  // caller or the input caused them). InputError after Error: the later translator runs first.
  static py::exception<Error> error(m, "Error", PyExc_ValueError);
  static py::exception<InputError> input_error(m, "InputError", error.ptr());
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const InputError& e) {
      input_error(e.what());
    } catch (const Error& e) {
      error(e.what());
    }
  });

  py::class_<Params>(m, "Params", "Every parameter of hmap, from a preset ('indoor', 'room' or 'outdoor').")
      .def(py::init([](const std::string& preset_name) { return preset(preset_name); }), py::arg("preset") = "outdoor")
      .def("get", [](const Params& p, const std::string& name) { return get_param(p, name); }, py::arg("name"),
           "The value of a parameter by its dotted name ('map.cell_size').")
      .def("set", &set_validated, py::arg("name"), py::arg("value"),
           "Sets a parameter, validated as the CLI validates it; raises ValueError (hmap.Error) with the library's "
           "message and leaves the parameters unchanged when the name is unknown or the value is out of range.")
      .def("update",
           [](Params& p, const py::dict& values) {
             Params changed = p;
             for (const auto& [k, v] : values) set_param(changed, py::cast<std::string>(k), py::cast<double>(v));
             validate(changed);  // once, after all: rules between parameters see the new values together
             p = changed;
           },
           py::arg("values"), "Sets several parameters at once ({'map.min_range': 2, 'map.max_range': 40}), validated together.")
      .def_static("names", &param_names, "The dotted names of every parameter.")
      .def_static("describe", &describe, py::arg("name"), "Unit, description, default and range of a parameter.")
      .def_static("presets", [] { return std::vector<std::string>{"indoor", "room", "outdoor"}; })
      .def("to_yaml", [](const Params& p) { return params_to_yaml(p); }, "The parameters as the YAML the CLI's --config reads.")
      .def("copy", [](const Params& p) { return p; })
      .def("__eq__", [](const Params& a, const Params& b) { return params_to_yaml(a) == params_to_yaml(b); });

  py::class_<Map>(m, "Map", "An HMAP with, when built by a HybridMapper, its 2D grid and ground patches.")
      .def_static("load", [](const std::filesystem::path& path) {
        MapFile file = [&] { py::gil_scoped_release release; return load_map_file(path); }();
        return Map(std::move(file));
      }, py::arg("path"), "Reads a .hmap file (the CLI's `hmap map` output).")
      .def("save", &save, py::arg("path"), "Writes the map as a .hmap file, atomically.")
      .def_property_readonly("params", [](const Map& self) {
        return self.read([](const HMap& map, const OccupancyGrid*, std::span<const GroundPatch>) { return map.params(); });
      }, "A copy of the parameters the map was built with.")
      .def_property_readonly("cell_size", [](const Map& self) {
        return self.read([](const HMap& map, const OccupancyGrid*, std::span<const GroundPatch>) { return map.cell_size(); });
      })
      .def("stats", &stats_dict,
           "Cells, HVoxels, tiles, memory, bounds ((xmin, ymin, zmin), (xmax, ymax, zmax)) or None, ground patches, grid "
           "cells (None without a grid), and the SLAM's cell centroids (0 for a map without them).")
      .def("occupied", &occupied, py::arg("xyz"), "For an (N, 3) array of points: a bool array, True inside an HVoxel.")
      .def("raycast", &raycast_rays, py::arg("origins"), py::arg("directions"), py::arg("max_range"),
           "raycast(origins, directions, max_range) -> (ranges, points): where rays first meet an HVoxel, walked cell "
           "by cell (exact for the columns: no thin HVoxel is stepped over). origins, directions: (N, 3) arrays, or "
           "one (3,) for every ray (directions need not be unit); max_range [m] in [0, 1e6]. ranges: (N,) metres "
           "along each ray, NaN where it meets nothing; points: (N, 3), NaN likewise. Runs without the GIL.")
      .def("__iter__", &cells_of,
           "Iterates over the non-empty cells by i then j: (i, j, column), the column as Map.column gives it; the "
           "cell's centre is ((i + 0.5)·cell_size, (j + 0.5)·cell_size).")
      .def("column", &column, py::arg("x"), py::arg("y"),
           "The HVoxels of the cell holding (x, y), lowest first, as a structured array (z_min, z_max, count, density).")
      .def("hvoxels", &hvoxels_of,
           "Every HVoxel of the map with its cell, as a structured array (i, j, z_min, z_max, count, density), by "
           "cell (i, j) then height; cell (i, j) covers x in [i, i + 1) * cell_size, y in [j, j + 1) * cell_size.")
      .def("recover_points", &recover, py::arg("z_step") = py::none(),
           "The height-upsampled point cloud: each HVoxel sampled at its cell centre every z_step metres "
           "(default: the cell size), as an (N, 3) float32 array.")
      .def("grid", &grid_of, "The 2D occupancy grid as a Grid2D, or None for a map without one.")
      .def("ground_patches", &ground_of, "The ground patches as arrays: center (P, 3), normal (P, 3), half_size (P,), parent (P,).");

  py::class_<Grid2D>(m, "Grid2D", "The 2D occupancy grid over the bounding box of its observed cells.")
      .def_readonly("probability", &Grid2D::probability,
                    "(rows, cols) float32 occupancy probability, NaN where never observed; [r, c] is the cell at "
                    "x = origin[0] + (c + 0.5) * resolution, y = origin[1] + (r + 0.5) * resolution (row 0 southernmost)")
      .def_readonly("origin", &Grid2D::origin, "[m] (x, y) of the lower-left corner of cell [0, 0]")
      .def_readonly("resolution", &Grid2D::resolution, "[m] cell edge")
      .def("__repr__", [](const Grid2D& g) {
        return format("Grid2D(%zd x %zd cells of %g m, origin (%g, %g))", g.probability.shape(0), g.probability.shape(1),
                      g.resolution, g.origin.first, g.origin.second);
      });

  py::class_<PyMapper>(m, "Mapper",
      "The HMAP of section III alone: HVoxels, free space by ray tracing, merging, extrusion.")
      .def(py::init([](const Params& p) {
        auto box = std::make_shared<MapperBox>();
        box->mapper.emplace(p);
        return PyMapper{box};
      }), py::arg("params"))
      .def("integrate", [](PyMapper& self, const py::handle& points, const py::handle& pose, const std::string& non_finite) {
        MapperBox& box = *self.box;
        const ScanStats s = integrate_scan(box, points, pose, non_finite,
            [&](std::span<const Point3f> pts, const Pose& T) { return box.mapper->integrate(pts, T); });
        return scan_stats_dict(s);
      }, py::arg("points"), py::arg("T_map_sensor"), py::kw_only(), py::arg("non_finite") = "raise",
         "Integrates one scan: points (N, 3) float32 or float64 in the sensor frame (C-contiguous float32 is read "
         "without a copy), T_map_sensor a 4x4 rigid transform. Runs without the GIL. Returns the scan's figures.")
      .def_property_readonly("map", [](const PyMapper& self) { return Map(self.box); },
                             "The map, live: later scans show in it.");

  py::class_<PyHybridMapper>(m, "HybridMapper",
      "The hybrid map of section IV: the HMAP, the ground patches of Alg. 4 and the 2D occupancy grid.")
      .def(py::init([](const Params& p) {
        auto box = std::make_shared<MapperBox>();
        box->hybrid.emplace(p);
        return PyHybridMapper{box};
      }), py::arg("params"))
      .def("integrate", [](PyHybridMapper& self, const py::handle& points, const py::handle& pose, const std::string& non_finite) {
        MapperBox& box = *self.box;
        const HybridScanStats s = integrate_scan(box, points, pose, non_finite,
            [&](std::span<const Point3f> pts, const Pose& T) { return box.hybrid->integrate(pts, T); });
        py::dict d = scan_stats_dict(s.map);
        d["ground_accepted"] = s.ground.accepted;
        d["grid_rays"] = s.occupancy.rays;
        d["grid_cells"] = s.occupancy.cells;
        d["grid_no_ground"] = s.occupancy.no_ground;
        return d;
      }, py::arg("points"), py::arg("T_map_sensor"), py::kw_only(), py::arg("non_finite") = "raise",
         "Integrates one scan into the HMAP, the ground patches and the 2D grid; as Mapper.integrate.")
      .def_property_readonly("map", [](const PyHybridMapper& self) { return Map(self.box); },
                             "The map with its grid and ground patches, live: later scans show in it.");

  m.def("params_for_scan", &scan_params_dict, py::arg("first_scan"), py::arg("preset") = py::none(), py::kw_only(),
        py::arg("config") = py::none(), py::arg("overrides") = std::vector<std::string>(),
        py::arg("cell_size") = py::none(), py::arg("min_range") = py::none(), py::arg("max_range") = py::none(),
        "The parameters `hmap map` and `hmap slam` choose for a run whose first scan is `first_scan` ((N, 3)): "
        "the preset (named, or indoor when 95 % of the scan lies within 5 m), then the YAML `config`, the "
        "'name=value' `overrides`, cell_size / min_range / max_range (--cell, --min-range, --max-range), then the "
        "height gap from a spinning LiDAR's ring spacing. Returns {'params': Params, 'preset': str, "
        "'preset_reason': str or None (None when named), 'adapted': [{'name', 'value', 'reason'}]}.");

  py::module_ slam_module = m.def_submodule("slam", "SLAM on the HMAP (section IV-C)");
  py::class_<PySlam>(slam_module, "Slam",
      "Scan-to-map SLAM on the HMAP: each scan is matched against the map by Gauss-Newton over (x, y, yaw), z, "
      "roll and pitch fitted to the map's horizontal surfaces, then merged at the estimate. The first scan "
      "defines the map frame. Use hmap.params_for_scan(first_scan) for the parameters `hmap slam` runs with.")
      .def(py::init([](const Params& p, const py::handle& imu, const std::optional<Map>& continue_map,
                       const std::array<double, 3>& start, double search, double search_yaw) {
        auto box = std::make_shared<MapperBox>();
        if (continue_map) {
          slam::ContinueOptions where;
          where.guess = {start[0], start[1], start[2]};
          where.search_translation = search;
          where.search_rotation = search_yaw;
          // The map and its centroids (slam.hvoxel_centroids 2: saved with it, or a live SLAM's),
          // copied under its lock: the Map stays as it was.
          std::optional<CellCentroids> centroids;
          HMap copy = continue_map->read([&](const HMap& saved, const OccupancyGrid*, std::span<const GroundPatch>) {
            HMap out(saved.params());
            merge_map(out, saved);  // into an empty map: an exact copy
            if (const CellCentroids* c = continue_map->centroids()) centroids = copy_of(*c);
            return out;
          });
          box->slam.emplace(p, std::move(copy), where, std::move(centroids));
        } else {
          box->slam.emplace(p);
          // As `hmap slam`: off for a continued map, whose rebuild would lose what was saved.
          if (p.slam.loop_closure != 0) box->loops.emplace(p);
        }
        if (!imu.is_none()) box->imu.emplace(imu_samples_of(imu), box->slam->params());
        return PySlam{box};
      }), py::arg("params"), py::kw_only(), py::arg("imu") = py::none(), py::arg("continue_map") = py::none(),
           py::arg("start") = std::array<double, 3>{0.0, 0.0, 0.0}, py::arg("search") = 5.0,
           py::arg("search_yaw") = std::numbers::pi,
           "imu: IMU samples as hmap.io.read_imu returns them ({'stamps', 'gyro', 'accel'[, 'orientation']}); each "
           "scan's stamp then says where it lies on the IMU's clock, and the IMU's gravity and rotation are its prior "
           "as in `hmap slam --imu` (the mounting: slam.imu_roll, imu_pitch, imu_yaw). continue_map: a saved map "
           "(hmap.Map) to localise the scans in and add them to, as `hmap slam --continue`: it keeps its own map "
           "parameters (params gives slam.*); the first scan is found by a coarse search of +-search m and "
           "+-search_yaw rad about start = (x, y, yaw [rad]) (its step's 'relocalised' says where), then matched "
           "as every later scan; the poses are in the saved map's frame. Raises hmap.Error for an empty map or a "
           "search window out of range.")
      .def("process", &slam_process, py::arg("points"), py::arg("stamp") = py::none(), py::arg("times") = py::none(),
           py::kw_only(), py::arg("attitude") = py::none(), py::arg("guess") = py::none(),
           py::arg("non_finite") = "raise",
           "Matches one scan against the map and merges it at the estimate. points: (N, 3) float32 or float64 in "
           "the sensor frame; stamp: the scan's time [s] (None: the sweep's span is the scan period); times: (N,) "
           "per-point times [s] from the scan's reference time, for deskewing (slam.deskew); attitude: a 4x4 pose "
           "whose z, roll and pitch are taken as they are (reference poses, an IMU); guess: a 4x4 pose whose x, y "
           "and yaw start the match (odometry; None: constant velocity). Runs without the GIL. Returns the step as "
           "a dict: T_map_sensor (4x4, at the stamp), T_map_merged (4x4, the pose the scan was merged at, "
           "merged_at_s [s] after the stamp: the sweep's middle when deskewed by the estimates' velocity), matched, converged, iterations, initial_cost, final_cost, score (mean M_H), "
           "hvoxels_used, eigenvalues, degenerate, coarse_search, coarse_rejected, wide_search, skipped, heading_only, attitude_fit, walls (slam.wall_refine: "
           "{'applied', 'pairs', 'rms', 'iterations', 'change': (dx, dy, dyaw), 'skipped_because'}), wall_tilt ((the tilt the walls' lean corrected [rad], the walls read): slam.wall_tilt_drift), observable ({'x': bool, "
           "... 'yaw': bool}), planar_passes, deskewed, sweep_velocity, imu_used, tilt_hypotheses, tilt_from_floor, "
           "mapping (the map update's figures), relocalised (the first scan of a continued map: {'shift': (x, y, z, yaw), "
           "'score', 'columns_used', 'floor_pairs'}; else None).")
      .def("close_loops", &slam_close_loops, py::arg("read_scan"),
           "Loop closure, once, after the last scan (slam.loop_closure, on by default; off for a continued map): the "
           "key frames' loops are searched and verified, the pose graph optimised, every pose corrected and the map "
           "built again from the scans, which read_scan(k) returns again as (N, 3) arrays (non-finite points "
           "dropped). Only the tiles the moved scans reach are rebuilt when no scan was merged deskewed (a scan "
           "moved by at most a tenth of a cell keeps its pose); else the whole map. Runs without the GIL but for "
           "read_scan. Returns {'closures': [{'keyframe_old', 'keyframe_new', 'scan_old', 'scan_new', "
           "'descriptor_distance', 'descriptor_yaw', 'score', 'T_old_new': (x, y, z, yaw), 'drift_translation', "
           "'drift_yaw'}], 'keyframes', 'candidates_verified', 'max_correction', 'end_correction', 'poses' ((K, 4, 4), "
           "the corrected T_map_sensor, also Slam.poses from then on), 'map' (hmap.Map at those poses; the live "
           "map when nothing closed), 'rebuild' ({'whole', 'scans_moved', 'scans_integrated', 'tiles_rebuilt', "
           "'tiles_kept'}, or None when nothing closed)}. Raises ValueError when loop closure is off or it ran already.")
      .def("start_at_height", [](PySlam& self, double z) {
        const std::scoped_lock lock(self.box->mutex);
        if (self.box->slam->scans() > 0) throw py::value_error("start_at_height must come before the first scan");
        self.box->slam->start_at_height(z);
      }, py::arg("z"), "The height [m] the first scan is put at when its attitude is estimated (default 0).")
      .def("start_with_up", [](PySlam& self, const std::array<double, 3>& up) {
        const std::scoped_lock lock(self.box->mutex);
        if (self.box->slam->scans() > 0) throw py::value_error("start_with_up must come before the first scan");
        self.box->slam->start_with_up(Eigen::Vector3d(up[0], up[1], up[2]));
      }, py::arg("up"),
           "The first scan's tilt guess when its attitude is estimated: gravity's up (ux, uy, uz) in its sensor "
           "frame, e.g. hmap.io.floor_under_sensor(points)['up'] for a depth camera's optical frame (`hmap slam "
           "--attitude-from scans` on an RGB-D folder). Raises ValueError for a zero or non-finite vector.")
      .def("predict", [](const PySlam& self) {
        const std::scoped_lock lock(self.box->mutex);
        const slam::PlanarPose p = self.box->slam->predict();
        return py::make_tuple(p.x, p.y, p.yaw);
      }, "The constant-velocity guess (x, y, yaw) for the next scan.")
      .def_property_readonly("poses", [](const PySlam& self) {
        const std::scoped_lock lock(self.box->mutex);
        return poses_array(self.box->slam_poses);
      }, "(K, 4, 4) float64: T_map_sensor of every scan processed, as `hmap slam` writes them to poses.txt.")
      .def_property_readonly("scans", [](const PySlam& self) {
        const std::scoped_lock lock(self.box->mutex);
        return self.box->slam->scans();
      })
      .def_property_readonly("map", [](const PySlam& self) { return Map(self.box); },
                             "The map SLAM builds, live: later scans show in it.");

  py::module_ eval = m.def_submodule("eval", "Accuracy of trajectories");
  eval.def("trajectory", &trajectory_dict, py::arg("truth"), py::arg("estimate"), py::kw_only(),
           py::arg("segment_lengths") = py::none(), py::arg("start_frame_step") = 1,
           "ATE (without and after SE(3) alignment), RPE per frame and KITTI's per-distance drift of `estimate` "
           "against `truth`, both (N, 4, 4) T_world_frame. The dict holds the keys of `hmap eval traj --json` "
           "(NaN where it writes null) and ate_median_m, the aligned mean and median, T_truth_estimate, "
           "segment_lengths_m.");

  py::module_ io = m.def_submodule("io", "Readers of point clouds and trajectories");
  io.def("read_cloud", [](const std::filesystem::path& path) {
    PointCloud cloud = [&] { py::gil_scoped_release release; return read_cloud(path); }();
    return points_array(std::move(cloud));
  }, py::arg("path"),
     "A point cloud file by its extension (.pcd .ply .bin (KITTI) .xyz .txt .csv .pts .vtk) as an (N, 3) float32 "
     "array; non-finite points are dropped, as the CLI drops them.");
  io.def("read_poses", [](const std::filesystem::path& path) { return poses_array(read_poses(path)); }, py::arg("path"),
         "A KITTI or TUM trajectory as an (N, 4, 4) float64 array of T_map_sensor.");
  io.def("open_kitti", &kitti_dict, py::arg("dir"), py::arg("max_scans") = py::none(),
         "A KITTI folder listed, not read: {'scans': paths, 'T_map_scan': (N, 4, 4) or None (poses.txt turned into "
         "scanner poses by calib.txt's Tr), 'T_cam_velo': 4x4 or None, 'times': (N,) or None}.");

  io.def("write_ply", &write_ply, py::arg("map"), py::arg("path"), py::kw_only(), py::arg("points") = false,
         py::arg("z_step") = py::none(),
         "`hmap export --ply`: each HVoxel as a box coloured by height (binary PLY, MeshLab, CloudCompare, Open3D); "
         "points=True: the recovered points instead, every z_step [m] (default: the cell size) up each HVoxel "
         "(`--points`). Written atomically; equal maps give equal files.");
  io.def("floor_under_sensor", [](const py::handle& points, const std::array<double, 3>& prior_up) -> py::object {
    const py::array arr = checked_points(points, "points");
    PointCloud storage;
    const std::span<const Point3f> pts = points_of(arr, storage, NonFinite::kDrop, "points");
    const Eigen::Vector3d prior(prior_up[0], prior_up[1], prior_up[2]);
    if (!prior.allFinite() || !(prior.norm() > 0.0)) throw py::value_error("prior_up must be finite and non-zero");
    std::optional<SensorFloor> floor;
    {
      py::gil_scoped_release release;
      floor = floor_under_sensor(pts, prior);
    }
    if (!floor) return py::none();
    py::dict d;
    d["up"] = py::make_tuple(floor->up_sensor.x(), floor->up_sensor.y(), floor->up_sensor.z());
    d["sensor_height"] = floor->sensor_height;
    d["inliers"] = floor->inliers;
    d["points"] = floor->points;
    return d;
  }, py::arg("points"), py::arg("prior_up") = std::array<double, 3>{0.0, -1.0, 0.0},
         "The floor under a sensor from one (N, 3) scan in its own frame (non-finite rows dropped): {'up' (its "
         "normal, unit, toward the sensor), 'sensor_height' [m], 'inliers', 'points'}, or None when no plane within "
         "34° of prior_up lies within 3 m below the sensor. prior_up: -y (the default) for a depth camera's "
         "optical frame, +z for a LiDAR.");
  io.def("write_points_ply", [](const std::filesystem::path& path, const py::handle& points) {
    const py::array arr = checked_points(points, "points");
    PointCloud storage;
    const std::span<const Point3f> pts = points_of(arr, storage, NonFinite::kRaise, "points");
    const PointCloud cloud(pts.begin(), pts.end());
    py::gil_scoped_release release;
    write_points_ply(path, cloud);
  }, py::arg("path"), py::arg("points"), "An (N, 3) array as a PLY point cloud coloured by height, atomically.");
  io.def("write_pgm", &write_pgm, py::arg("map"), py::arg("stem"), py::kw_only(), py::arg("grid") = "both",
         "`hmap export --pgm`: the 2D occupancy grid as STEM.pgm + STEM.yaml (ROS map_server, Nav2); grid: "
         "'both', 'kept' or 'judged' (`--grid`); a map without a kept grid has one derived from its columns. "
         "Returns {'pgm', 'yaml' (paths), 'occupied', 'free' (cells as written), 'grid' (which grid)}.");
  io.def("write_bt", &write_bt, py::arg("map"), py::arg("path"),
         "`hmap export --bt`: the HVoxels as occupied OctoMap leaves at the cell size (octovis), the 2D grid's "
         "free cells as free leaves from the ground up to occupancy.z_plus when the map holds a grid and ground "
         "patches. Returns {'occupied_voxels', 'free_voxels', 'leaves'}.");
  io.def("write_png", &write_png_array, py::arg("path"), py::arg("image"),
         "An (H, W, 3) uint8 RGB image (row 0 the top) as a PNG file, atomically.");

  py::module_ pictures = m.def_submodule("render", "Pictures of maps as (H, W, 3) uint8 arrays (src/hmap/render)");
  py::class_<render::TopViewport>(pictures, "Viewport",
                                  "Where a top view lies: pixel (col, row) covers x in x0 + [col, col + 1]·m_per_px, "
                                  "y in y1 − [row + 1, row]·m_per_px (north up).")
      .def_readonly("x0", &render::TopViewport::x0, "World x at the picture's left edge [m].")
      .def_readonly("y1", &render::TopViewport::y1, "World y at the picture's top edge [m].")
      .def_readonly("m_per_px", &render::TopViewport::m_per_px, "Metres per pixel [m].")
      .def_readonly("width", &render::TopViewport::width, "The map's width [px] (a legend panel lies beyond it).")
      .def_readonly("height", &render::TopViewport::height, "The map's height [px].")
      .def_property_readonly("origin", [](const render::TopViewport& v) {
        return py::make_tuple(v.x0, v.y1 - v.height * v.m_per_px);
      }, "(x, y) of the map's lower-left corner [m].")
      .def_property_readonly("extent", [](const render::TopViewport& v) {
        return py::make_tuple(v.x0, v.x0 + v.width * v.m_per_px, v.y1 - v.height * v.m_per_px, v.y1);
      }, "(left, right, bottom, top) [m]: matplotlib's imshow(image[:, :width], extent=...).")
      .def("pixel", [](const render::TopViewport& v, double x, double y) {
        return py::make_tuple(static_cast<int>(std::floor(v.px(x))), static_cast<int>(std::floor(v.py(y))));
      }, py::arg("x"), py::arg("y"), "pixel(x, y) -> (col, row): the pixel holding world point (x, y).")
      .def("__repr__", [](const render::TopViewport& v) {
        return format("hmap.render.Viewport(x0=%g, y1=%g, m_per_px=%g, width=%d, height=%d)", v.x0, v.y1, v.m_per_px,
                      v.width, v.height);
      });
  pictures.def("top", &render_top, py::arg("map"), py::kw_only(), py::arg("layer") = "height",
               py::arg("max_pixels") = 2000, py::arg("z_low") = py::none(), py::arg("z_high") = py::none(),
               py::arg("paths") = py::none(), py::arg("labels") = py::none(), py::arg("legend") = false,
               "top(map, *, layer='height', max_pixels=2000, z_low=None, z_high=None, paths=None, labels=None, "
               "legend=False) -> (image, Viewport): the top view `hmap render` draws. layer: 'height' (each cell "
               "coloured by its highest HVoxel top, blue z_low to red z_high, default the 2nd/98th percentiles; cells "
               "with overhangs lighter; unknown black), 'occupancy' (the 2D grid as map_server draws it: free white, "
               "occupied black, unknown grey; a map without a kept grid gets the one `hmap export --pgm` derives) or "
               "'ground' (heights with Alg. 4's patches outlined). paths: an (N, 4, 4) array of poses or a sequence "
               "of them, drawn over the map (widened by 2 m) in white (blue on the grid), then red, magenta, orange; "
               "legend=True adds the CLI's legend and scale bar panel to the right (image wider than "
               "Viewport.width). Raises ValueError (hmap.Error) for max_pixels outside [1, 20000], an empty map or "
               "bad poses.");
  pictures.def("oblique", &render_oblique, py::arg("map"), py::kw_only(), py::arg("max_pixels") = 2000,
               py::arg("z_low") = py::none(), py::arg("z_high") = py::none(),
               "oblique(map, *, max_pixels=2000, z_low=None, z_high=None) -> image: the HVoxels as bars seen from the "
               "south-west, 35 degrees up, height-coloured (`hmap render --view oblique`).");
  pictures.def("draw_path", &draw_path, py::arg("image"), py::arg("viewport"), py::arg("poses"),
               py::arg("colour") = std::array<int, 3>{255, 0, 255},
               "draw_path(image, viewport, poses, colour=(255, 0, 255)) -> image: a copy of a top view with the x, y "
               "path of an (N, 4, 4) array of poses drawn 2 px wide, a dot at its start.");

  bind_sources(io);
  bind_sim(m);
  bind_pvox(m);
  bind_merge(m);
}

}  // namespace hmap::python
