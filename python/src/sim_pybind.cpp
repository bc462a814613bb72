// hmap.sim: the simulator's scenes, sensors, scripted paths, noisy odometry and the sequence
// writer (src/hmap/sim, src/hmap/io/sequence_writer.hpp), bound as they are.

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <memory>
#include <mutex>
#include <numbers>
#include <optional>
#include <random>
#include <string>
#include <variant>
#include <vector>

#include "arrays.hpp"
#include "hmap/io/sequence_writer.hpp"
#include "hmap/sim/builtin_scenes.hpp"
#include "hmap/sim/scene_json.hpp"
#include "hmap/sim/sensors.hpp"
#include "hmap/sim/simulation.hpp"
#include "hmap/sim/trajectory.hpp"

namespace hmap::python {

namespace {

/// A sensor with the lock that keeps its noise generator to one scan at a time while scans run
/// without the GIL.
struct PySensor {
  std::string name;
  std::mutex mutex;
  sim::AnySensor sensor;
  PySensor(std::string n, std::uint64_t seed, bool noise)
      : name(std::move(n)), sensor(sim::make_sensor(name, seed, noise ? sim::SensorNoise::kModelled : sim::SensorNoise::kNone)) {}
};

template <typename T>
py::array_t<T> vector_of(const std::vector<T>& v) {
  py::array_t<T> out(static_cast<py::ssize_t>(v.size()));
  if (!v.empty()) std::memcpy(out.mutable_data(), v.data(), v.size() * sizeof(T));
  return out;
}

py::dict scan_dict(sim::SimulatedScan&& s) {
  py::dict d;
  d["points"] = points_array(std::move(s.points_sensor));
  d["channel"] = vector_of(s.channel);
  d["primitive"] = vector_of(s.primitive);
  std::vector<std::uint8_t> kind(s.kind.size());
  for (std::size_t i = 0; i < kind.size(); ++i) kind[i] = static_cast<std::uint8_t>(s.kind[i]);
  d["kind"] = vector_of(kind);
  d["time"] = s.time.empty() ? py::object(py::none()) : py::object(vector_of(s.time));
  d["rays"] = s.rays;
  d["no_return"] = s.no_return;
  d["out_of_range"] = s.out_of_range;
  d["dropped"] = s.dropped;
  return d;
}

double finite_time(double t, const char* what) {
  if (!std::isfinite(t)) throw py::value_error(format("%s must be finite, got %g", what, t));
  return t;
}

/// Waypoints as an (N, dims) array of finite numbers.
template <int Dims>
std::vector<Eigen::Matrix<double, Dims, 1>> waypoints_of(const py::handle& obj, const char* what) {
  const auto a = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(obj);
  if (!a || a.ndim() != 2 || a.shape(1) != Dims) {
    throw py::value_error(format("%s must be an (N, %d) array of numbers", what, Dims));
  }
  const auto r = a.unchecked<2>();
  std::vector<Eigen::Matrix<double, Dims, 1>> out(static_cast<std::size_t>(r.shape(0)));
  for (py::ssize_t i = 0; i < r.shape(0); ++i) {
    for (int d = 0; d < Dims; ++d) {
      if (!std::isfinite(r(i, d))) throw py::value_error(format("%s: row %zd is not finite", what, i));
      out[static_cast<std::size_t>(i)][d] = r(i, d);
    }
  }
  return out;
}

template <int Dims>
py::array_t<double> waypoints_array(const std::vector<Eigen::Matrix<double, Dims, 1>>& w) {
  py::array_t<double> out({static_cast<py::ssize_t>(w.size()), py::ssize_t{Dims}});
  auto o = out.mutable_unchecked<2>();
  for (std::size_t i = 0; i < w.size(); ++i)
    for (int d = 0; d < Dims; ++d) o(static_cast<py::ssize_t>(i), d) = w[i][d];
  return out;
}

py::array_t<double> route(const std::string& name) {
  if (name == "parking") return waypoints_array<3>(sim::parking_car_route());
  if (name == "parking-long") return waypoints_array<3>(sim::parking_long_car_route());
  if (name == "office") return waypoints_array<2>(sim::office_robot_route());
  throw py::value_error("unknown route '" + name + "' (known: parking, parking-long, office)");
}

/// A point cloud from an (N, 3) array, copied (the library keeps it).
PointCloud cloud_of(const py::handle& obj, const char* what) {
  const py::array arr = checked_points(obj, what);
  PointCloud storage;
  const std::span<const Point3f> pts = points_of(arr, storage, NonFinite::kRaise, what);
  return PointCloud(pts.begin(), pts.end());
}

void write_sequence(const std::filesystem::path& dir, const py::sequence& frames, const py::handle& poses,
                    const py::handle& times, const py::handle& odometry, const py::handle& truth_points,
                    const py::handle& point_times) {
  std::vector<PointCloud> clouds;
  for (std::size_t k = 0; k < frames.size(); ++k) {
    const std::string what = format("frames[%zu]", k);
    clouds.push_back(cloud_of(frames[k], what.c_str()));
  }
  const PoseList truth = poses_of(poses, "poses");
  const auto t = py::array_t<double, py::array::forcecast>::ensure(times);
  if (!t || t.ndim() != 1) throw py::value_error("times must be a 1-D array of numbers, one per frame");
  std::vector<double> stamps(t.data(), t.data() + t.shape(0));
  for (std::size_t k = 0; k < stamps.size(); ++k) {
    if (!std::isfinite(stamps[k])) throw py::value_error(format("times: element %zu is not finite", k));
  }
  const PoseList odom = odometry.is_none() ? PoseList() : poses_of(odometry, "odometry");
  const PointCloud truth_cloud = truth_points.is_none() ? PointCloud() : cloud_of(truth_points, "truth_points");
  std::vector<std::vector<float>> per_point;
  if (!point_times.is_none()) {
    const auto seq = py::reinterpret_borrow<py::sequence>(point_times);
    if (seq.size() != clouds.size()) {
      throw py::value_error(format("point_times must hold one array per frame: %zu frames, %zu arrays", clouds.size(),
                                   static_cast<std::size_t>(seq.size())));
    }
    for (std::size_t k = 0; k < clouds.size(); ++k) per_point.push_back(times_of(seq[k], clouds[k].size()));
  }
  py::gil_scoped_release release;
  write_simulated_sequence(dir, clouds, truth, stamps, odom, truth_cloud, per_point);
}

py::dict simulate_dict(const py::handle& scene_arg, const std::string& sensor, std::size_t frames, std::size_t stride,
                       bool long_route, std::uint64_t seed, double truth_spacing, double truth_reach, double imu_rate,
                       bool sweep, double mount_yaw_deg) {
  sim::SimulationSpec spec;
  const sim::Scene* scene = nullptr;
  std::optional<sim::Scene> builtin;
  if (py::isinstance<py::str>(scene_arg)) {
    spec.scene = py::cast<std::string>(scene_arg);
    builtin.emplace(sim::make_scene(spec.scene));
    scene = &*builtin;
  } else if (py::isinstance<sim::Scene>(scene_arg)) {
    spec.scene.clear();  // a scene of the caller's: the office robot's route, as --scene-file
    scene = &py::cast<const sim::Scene&>(scene_arg);
  } else {
    throw py::value_error("scene must be a built-in scene's name or an hmap.sim.Scene");
  }
  spec.sensor = sensor;
  spec.frames = frames;
  spec.stride = stride;
  spec.long_route = long_route;
  spec.seed = seed;
  spec.truth_spacing = truth_spacing;
  spec.truth_reach = truth_reach;
  spec.imu_rate = imu_rate;
  spec.sweep = sweep;
  spec.mount_yaw = mount_yaw_deg * std::numbers::pi / 180.0;
  sim::SimulatedRecording rec;
  {
    py::gil_scoped_release release;  // `scene_arg` keeps a caller's scene alive meanwhile
    rec = sim::simulate(spec, *scene);
  }
  py::dict d;
  py::list scans;
  for (PointCloud& c : rec.scans) scans.append(points_array(std::move(c)));
  d["scans"] = scans;
  if (rec.point_times.empty()) {
    d["point_times"] = py::none();
  } else {
    py::list times;
    for (const auto& t : rec.point_times) times.append(vector_of(t));
    d["point_times"] = times;
  }
  d["poses"] = poses_array(rec.T_world_sensor);
  d["times"] = vector_of(rec.times);
  d["odometry"] = poses_array(rec.odometry);
  if (rec.imu.empty()) {
    d["imu"] = py::none();
  } else {
    const auto n = static_cast<py::ssize_t>(rec.imu.size());
    py::array_t<double> t(n), gyro({n, py::ssize_t{3}}), accel({n, py::ssize_t{3}});
    auto tw = t.mutable_unchecked<1>();
    auto gw = gyro.mutable_unchecked<2>();
    auto aw = accel.mutable_unchecked<2>();
    for (py::ssize_t i = 0; i < n; ++i) {
      const ImuSample& sample = rec.imu[static_cast<std::size_t>(i)];
      tw(i) = sample.t;
      for (int a = 0; a < 3; ++a) gw(i, a) = sample.gyro[a], aw(i, a) = sample.accel[a];
    }
    py::dict imu;
    imu["t"] = t;
    imu["gyro"] = gyro;
    imu["accel"] = accel;
    d["imu"] = imu;
  }
  d["truth_surface"] = points_array(std::move(rec.truth_surface));
  d["truth_ground"] = points_array(std::move(rec.truth_ground));
  d["truth_seen"] = points_array(std::move(rec.truth_seen));
  d["points"] = rec.points;
  return d;
}

}  // namespace

void bind_sim(py::module_& m) {
  py::module_ s = m.def_submodule("sim", "The simulator: built-in scenes, sensors, scripted paths, noisy odometry");

  s.def("scene_names", &sim::builtin_scene_names, "The built-in scenes: boxes, office, parking.");
  s.def("kind_names", [] {
    std::vector<std::string> names;
    for (int k = 0; k <= static_cast<int>(sim::SurfaceKind::kOther); ++k) {
      names.emplace_back(sim::to_string(static_cast<sim::SurfaceKind>(k)));
    }
    return names;
  }, "What each value of a scan's `kind` stands for: kind_names()[scan['kind'][i]] ('ground', 'curb', 'wall', ...).");

  py::class_<sim::Scene, std::shared_ptr<sim::Scene>>(s, "Scene", "A scene of solids that sensors are simulated in.")
      .def(py::init([](const std::string& name) { return std::make_shared<sim::Scene>(sim::make_scene(name)); }),
           py::arg("name"), "The built-in scene `name` (hmap.sim.scene_names()); hmap.Error for any other.")
      .def_static("from_json", [](const std::string& text) { return std::make_shared<sim::Scene>(sim::scene_from_json(text)); },
                  py::arg("text"), "A scene from its JSON description (the format of `hmap simulate --scene-file`).")
      .def("sample_surface", [](const sim::Scene& self, double spacing, std::uint64_t seed, double t) {
        if (!(spacing >= 0.005)) throw py::value_error(format("spacing must be at least 0.005 m, got %g", spacing));
        finite_time(t, "t");
        std::mt19937_64 rng(seed);
        PointCloud points;
        {
          py::gil_scoped_release release;
          points = self.sample_surface(spacing, rng, t);
        }
        return points_array(std::move(points));
      }, py::arg("spacing"), py::arg("seed") = 1, py::arg("t") = 0.0,
         "Points on every surface about `spacing` [m] apart, as the scene stands at time t [s]: (N, 3) float32.")
      .def_property_readonly("bounds", [](const sim::Scene& self) {
        const Eigen::Vector3d lo = self.bounds().min(), hi = self.bounds().max();
        return py::make_tuple(py::make_tuple(lo.x(), lo.y(), lo.z()), py::make_tuple(hi.x(), hi.y(), hi.z()));
      }, "((xmin, ymin, zmin), (xmax, ymax, zmax)) [m]")
      .def_property_readonly("primitive_count", &sim::Scene::primitive_count)
      .def_property_readonly("object_count", &sim::Scene::object_count);

  py::class_<sim::Trajectory>(s, "Trajectory", "True sensor poses at the frame times of a scripted path.")
      .def(py::init([](const py::handle& poses, const py::handle& times) {
        sim::Trajectory t;
        t.T_world_sensor = poses_of(poses, "poses");
        const auto a = py::array_t<double, py::array::forcecast>::ensure(times);
        if (!a || a.ndim() != 1 || static_cast<std::size_t>(a.shape(0)) != t.T_world_sensor.size()) {
          throw py::value_error("times must be a 1-D array of numbers, one per pose");
        }
        t.times.assign(a.data(), a.data() + a.shape(0));
        return t;
      }), py::arg("poses"), py::arg("times"), "From (N, 4, 4) T_world_sensor and (N,) increasing times [s].")
      .def_property_readonly("poses", [](const sim::Trajectory& t) { return poses_array(t.T_world_sensor); },
                             "(N, 4, 4) float64 T_world_sensor")
      .def_property_readonly("times", [](const sim::Trajectory& t) { return vector_of(t.times); }, "(N,) float64 [s]")
      .def("pose_at", [](const sim::Trajectory& t, double time) { return matrix_array(sim::pose_at(t, finite_time(time, "t"))); },
           py::arg("t"), "The 4x4 pose at time t [s]: Catmull-Rom positions, slerped rotations, clamped at the ends.")
      .def("__len__", [](const sim::Trajectory& t) { return t.T_world_sensor.size(); });

  py::class_<PySensor>(s, "Sensor",
      "A simulated sensor by the name `hmap simulate --sensor` takes: vlp16 (Velodyne VLP-16), hdl64 (HDL-64E), os0-64 (Ouster OS0-64), "
      "kinect (Kinect One depth), utm30lx-tilt / utm30lx-yaw (Hokuyo UTM-30LX on a tilting / turning unit). "
      "Its noise comes from `seed`: the same seed and the same calls give the same points.")
      .def(py::init([](const std::string& name, std::uint64_t seed, bool noise) {
        return std::make_unique<PySensor>(name, seed, noise);
      }), py::arg("name"), py::arg("seed") = 1, py::kw_only(), py::arg("noise") = true)
      .def_static("names", &sim::sensor_names)
      .def_readonly("name", &PySensor::name)
      .def_property_readonly("max_range", [](PySensor& self) {
        return std::visit([](const auto& x) { return x.params().max_range; }, self.sensor);
      }, "[m]")
      .def("scan", [](PySensor& self, const sim::Scene& scene, const py::handle& pose, double t) {
        const Pose T = pose_of(pose, "T_world_sensor");
        finite_time(t, "t");
        sim::SimulatedScan scan;
        {
          py::gil_scoped_release release;
          const std::scoped_lock lock(self.mutex);
          scan = std::visit([&](auto& x) { return x.scan(scene, T, t); }, self.sensor);
        }
        return scan_dict(std::move(scan));
      }, py::arg("scene"), py::arg("T_world_sensor"), py::arg("t") = 0.0,
         "One scan of `scene` (at time t [s]) from the 4x4 pose T_world_sensor, without the GIL. Returns a dict: points "
         "((N, 3) float32, sensor frame: x forward, y left, z up), channel (ring / image row / sweep step, uint16), "
         "primitive (uint32), kind (uint8), time (None), rays, no_return, out_of_range, dropped.")
      .def("sweep", [](PySensor& self, const sim::Scene& scene, const sim::Trajectory& path, double t0) {
        auto* lidar = std::get_if<sim::SpinningLidar>(&self.sensor);
        if (lidar == nullptr) throw py::value_error("sweep needs a spinning lidar (vlp16, hdl64 or os0-64), not '" + self.name + "'");
        if (path.T_world_sensor.empty()) throw py::value_error("sweep: the trajectory is empty");
        finite_time(t0, "t0");
        sim::SimulatedScan scan;
        {
          py::gil_scoped_release release;
          const std::scoped_lock lock(self.mutex);
          scan = lidar->sweep(scene, [&](double t) { return sim::pose_at(path, t); }, t0);
        }
        return scan_dict(std::move(scan));
      }, py::arg("scene"), py::arg("trajectory"), py::arg("t0"),
         "One revolution (sweep_period, 0.1 s) while the sensor moves along `trajectory` from time t0 [s], as "
         "`hmap simulate --sweep`: each column in the sensor frame of its firing time, `time` [s] per point from t0.");

  s.def("route", &route, py::arg("name"),
        "A built-in route's waypoints [m]: 'parking' and 'parking-long' ((N, 3) ground points, for car_path), "
        "'office' ((N, 2) floor points, for diff_drive_path).");
  s.def("car_path", [](const py::handle& waypoints, double cruise_speed, double acceleration, double lateral_acceleration,
                       double turn_radius, double frame_rate, double sensor_height) {
    const auto w = waypoints_of<3>(waypoints, "waypoints");
    sim::CarPathParams p{cruise_speed, acceleration, lateral_acceleration, turn_radius, frame_rate, sensor_height};
    return sim::car_path(w, p);
  }, py::arg("waypoints"), py::kw_only(), py::arg("cruise_speed") = 8.0, py::arg("acceleration") = 1.5,
     py::arg("lateral_acceleration") = 2.0, py::arg("turn_radius") = 6.0, py::arg("frame_rate") = 10.0,
     py::arg("sensor_height") = 1.73,
     "A car along (N, 3) ground waypoints with rounded corners, from rest to rest: speeds [m/s], accelerations "
     "[m/s^2], turn_radius [m], frame_rate [Hz], sensor_height [m]. `hmap simulate --scene parking` drives "
     "car_path(route('parking')) with a spinning lidar at 1.73 m.");
  s.def("diff_drive_path", [](const py::handle& waypoints, double speed, double turn_rate, double frame_rate,
                              double sensor_height, double floor_z) {
    const auto w = waypoints_of<2>(waypoints, "waypoints");
    sim::DiffDriveParams p{speed, turn_rate, frame_rate, sensor_height, floor_z};
    return sim::diff_drive_path(w, p);
  }, py::arg("waypoints"), py::kw_only(), py::arg("speed") = 0.5, py::arg("turn_rate") = 0.6,
     py::arg("frame_rate") = 10.0, py::arg("sensor_height") = 0.5, py::arg("floor_z") = 0.0,
     "A differential-drive robot along (N, 2) floor waypoints, straight between them, turning on the spot: speed "
     "[m/s], turn_rate [rad/s], frame_rate [Hz], sensor_height and floor_z [m].");
  s.def("noisy_odometry", [](const py::handle& truth, double translation_sigma, double translation_sigma_per_metre,
                             double rotation_sigma, double rotation_sigma_per_radian, const std::string& axes,
                             std::uint64_t seed) {
    sim::OdometryNoiseParams p;
    p.translation_sigma = translation_sigma;
    p.translation_sigma_per_metre = translation_sigma_per_metre;
    p.rotation_sigma = rotation_sigma;
    p.rotation_sigma_per_radian = rotation_sigma_per_radian;
    if (axes == "planar") {
      p.axes = sim::OdometryNoiseAxes::kPlanar;
    } else if (axes == "full") {
      p.axes = sim::OdometryNoiseAxes::kFull;
    } else {
      throw py::value_error("axes must be 'planar' or 'full', got '" + axes + "'");
    }
    p.seed = seed;
    return poses_array(sim::noisy_odometry(poses_of(truth, "truth"), p));
  }, py::arg("truth"), py::kw_only(), py::arg("translation_sigma") = 0.005, py::arg("translation_sigma_per_metre") = 0.02,
     py::arg("rotation_sigma") = 0.001, py::arg("rotation_sigma_per_radian") = 0.02, py::arg("axes") = "planar",
     py::arg("seed") = 1,
     "The frame-to-frame motions of (N, 4, 4) `truth`, each perturbed (sigma = fixed + proportional * |motion|, "
     "[m] and [rad]), integrated from truth[0]: (N, 4, 4), what `hmap simulate` writes to odometry.txt for its seed.");
  s.def("simulate", &simulate_dict, py::arg("scene") = "parking", py::arg("sensor") = "vlp16", py::kw_only(),
        py::arg("frames") = 0, py::arg("stride") = 1, py::arg("long_route") = false, py::arg("seed") = 1,
        py::arg("truth_spacing") = 0.1, py::arg("truth_reach") = 30.0, py::arg("imu_rate") = 0.0,
        py::arg("sweep") = false, py::arg("mount_yaw") = 0.0,
        "`hmap simulate` in memory: the sensor (Sensor.names()) along the scene's scripted path (a Scene object "
        "drives the office robot's route, as --scene-file), every `stride`-th frame of the 10 Hz path, the "
        "first `frames` (0: all). Runs without the GIL. Returns a dict: scans (list of (N, 3) float32, sensor "
        "frame), point_times (with sweep=True: a (N,) float32 per scan [s] from the sweep's start; else None), "
        "poses (K, 4, 4) true T_world_sensor, times (K,), odometry (K, 4, 4) noisy, imu ({'t', 'gyro', 'accel'} "
        "at imu_rate Hz, or None), truth_surface / truth_ground (the dense surface sample every truth_spacing m "
        "within truth_reach m of the path, and its walkable part) and truth_seen (noise-free returns, world "
        "frame), points (the scans' total). The same seed gives the files `hmap simulate --seed` writes. "
        "mount_yaw [deg]: a spinning lidar mounted turned about its axis (--mount-yaw).");
  s.def("write_sequence", &write_sequence, py::arg("dir"), py::arg("frames"), py::arg("poses"), py::arg("times"),
        py::kw_only(), py::arg("odometry") = py::none(), py::arg("truth_points") = py::none(),
        py::arg("point_times") = py::none(),
        "Writes a KITTI-layout folder as `hmap simulate` does: velodyne/NNNNNN.bin per frame ((N, 3) arrays, sensor "
        "frame; .pcd with a per-point time t when `point_times` gives one array per frame), poses.txt, times.txt, "
        "odometry.txt and truth.ply when given. hmap.io.kitti_sequence(dir) reads it back.");
}

}  // namespace hmap::python
