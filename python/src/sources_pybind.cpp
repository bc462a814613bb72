// hmap.io's scan sequences and IMU samples: a thin shell over the library's one opener of a run's
// scans (hmap/sources/open_scan_source.hpp), the opener `hmap map --kitti/--rgbd/--bag` uses, and
// over read_imu_text (`hmap slam --imu`). python/hmap/io.py gives the sequences their names.

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <cmath>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "hmap/core/error.hpp"
#include "hmap/core/format.hpp"
#include "hmap/core/imu.hpp"
#include "hmap/io/imu_text.hpp"
#include "hmap/sources/open_scan_source.hpp"
#include "arrays.hpp"
#ifdef HMAP_HAVE_ROS
#include "hmap/ros/bag_reader.hpp"
#endif

namespace py = pybind11;

namespace hmap::python {

namespace {

/// An opened source read scan after scan: a Python iterator (each scan read when it is reached,
/// without the GIL) with len() the number of scans.
struct ScanSequence {
  std::shared_ptr<const ScanSource> src;
  std::shared_ptr<std::mutex> mutex = std::make_shared<std::mutex>();  // a recording is one file handle
  std::size_t next = 0;
  bool with_times = false;
};

py::tuple read_scan(const ScanSequence& seq, std::size_t k) {
  const ScanSource& src = *seq.src;
  CloudReadStats stats;
  std::vector<float> times;
  PointCloud cloud;
  {
    py::gil_scoped_release release;
    const std::scoped_lock lock(*seq.mutex);
    cloud = src.read(k, stats, seq.with_times ? &times : nullptr);
  }
  py::object pose = src.T_map_scan ? py::object(matrix_array((*src.T_map_scan)[k])) : py::object(py::none());
  py::object stamp = k < src.stamps.size() ? py::object(py::float_(src.stamps[k])) : py::object(py::none());
  py::array_t<float> points = points_array(std::move(cloud));
  if (!seq.with_times) return py::make_tuple(points, pose, stamp);
  py::object t = py::none();
  if (!times.empty()) t = py::array_t<float>(static_cast<py::ssize_t>(times.size()), times.data());
  return py::make_tuple(points, pose, stamp, t);
}

/// The library's spec from the keyword arguments of hmap.io.*_sequence.
ScanSequence open_source(const std::string& kitti, const std::vector<std::string>& files, const std::string& poses,
                         const std::string& rgbd, const std::string& tum, const std::string& intrinsics,
                         std::optional<double> depth_scale, const std::string& up, const py::handle& rotation,
                         const std::string& bag, const std::string& cloud_topic, const std::string& pose_topic,
                         const std::vector<std::string>& tf_frames, std::optional<std::size_t> max_scans, bool with_times) {
  ScanSourceSpec spec;
  spec.kitti = kitti;
  spec.files = files;
  spec.poses = poses;
  spec.max_scans = max_scans.value_or(0);
  spec.rgbd = rgbd;
  spec.tum = tum;
  spec.intrinsics = intrinsics;
  spec.depth_scale = depth_scale;
  spec.up = up;
  if (!rotation.is_none()) {
    const auto r = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(rotation);
    if (!r || r.ndim() != 2 || r.shape(0) != 3 || r.shape(1) != 3) throw py::value_error("rotation must be a 3x3 matrix of numbers");
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) spec.rotation += format("%.17g ", r.at(i, j));  // the library checks it
  }
  spec.bag = bag;
  spec.cloud_topic = cloud_topic;
  spec.pose_topic = pose_topic;
  if (tf_frames.size() > 2) throw py::value_error("tf_frames must be [MAP] or [MAP, SENSOR]");
  spec.tf_frames = tf_frames;
  std::vector<std::string> warnings;
  spec.warn = [&warnings](const std::string& w) { warnings.push_back(w); };
  ScanSequence seq;
  {
    py::gil_scoped_release release;
    seq.src = std::make_shared<const ScanSource>(open_scan_source(spec));
  }
  for (const auto& w : warnings) {
    if (PyErr_WarnEx(PyExc_UserWarning, w.c_str(), 2) != 0) throw py::error_already_set();
  }
  seq.with_times = with_times;
  return seq;
}

py::dict imu_dict(const ImuSamples& samples) {
  const auto n = static_cast<py::ssize_t>(samples.size());
  py::array_t<double> stamps(n), gyro({n, py::ssize_t{3}}), accel({n, py::ssize_t{3}}), orientation({n, py::ssize_t{4}});
  auto t = stamps.mutable_unchecked<1>();
  auto g = gyro.mutable_unchecked<2>();
  auto a = accel.mutable_unchecked<2>();
  auto q = orientation.mutable_unchecked<2>();
  bool any_orientation = false;
  for (py::ssize_t k = 0; k < n; ++k) {
    const ImuSample& s = samples[static_cast<std::size_t>(k)];
    t(k) = s.t;
    for (int d = 0; d < 3; ++d) {
      g(k, d) = s.gyro[d];
      a(k, d) = s.accel[d];
    }
    const Eigen::Vector4d xyzw = s.orientation ? s.orientation->coeffs() : Eigen::Vector4d::Constant(std::nan(""));
    for (int d = 0; d < 4; ++d) q(k, d) = xyzw[d];
    any_orientation = any_orientation || s.orientation.has_value();
  }
  py::dict d;
  d["stamps"] = stamps;
  d["gyro"] = gyro;
  d["accel"] = accel;
  d["orientation"] = any_orientation ? py::object(orientation) : py::object(py::none());
  return d;
}

/// An (n, cols) array of finite numbers, or a ValueError naming it.
py::array_t<double> imu_column(const py::handle& obj, const char* what, py::ssize_t n, py::ssize_t cols) {
  const auto a = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(obj);
  const bool shape_ok = a && (cols == 0 ? a.ndim() == 1 && (n < 0 || a.shape(0) == n)
                                        : a.ndim() == 2 && a.shape(0) == n && a.shape(1) == cols);
  if (!shape_ok) {
    throw py::value_error(cols == 0 ? format("imu: %s must be a 1-D array of numbers", what)
                                    : format("imu: %s must be an (N, %zd) array of numbers, N = %zd samples", what, cols, n));
  }
  return a;
}

}  // namespace

ImuSamples imu_samples_of(const py::handle& imu) {
  if (!py::isinstance<py::dict>(imu)) {
    throw py::value_error("imu must be a dict {'stamps': (N,), 'gyro': (N, 3), 'accel': (N, 3)[, 'orientation': (N, 4) "
                          "x y z w]}, as hmap.io.read_imu returns");
  }
  const auto d = py::reinterpret_borrow<py::dict>(imu);
  for (const char* key : {"stamps", "gyro", "accel"}) {
    if (!d.contains(key)) throw py::value_error(format("imu has no '%s'", key));
  }
  const auto t = imu_column(d["stamps"], "stamps", -1, 0);
  const py::ssize_t n = t.shape(0);
  const auto g = imu_column(d["gyro"], "gyro", n, 3);
  const auto a = imu_column(d["accel"], "accel", n, 3);
  std::optional<py::array_t<double>> q;
  if (d.contains("orientation") && !d["orientation"].is_none()) q = imu_column(d["orientation"], "orientation", n, 4);
  ImuSamples samples(static_cast<std::size_t>(n));
  for (py::ssize_t k = 0; k < n; ++k) {
    ImuSample& s = samples[static_cast<std::size_t>(k)];
    s.t = t.at(k);
    s.gyro = {g.at(k, 0), g.at(k, 1), g.at(k, 2)};
    s.accel = {a.at(k, 0), a.at(k, 1), a.at(k, 2)};
    // A row of NaN: no orientation for that sample (as read_imu gives it).
    if (q && !std::isnan(q->at(k, 3))) s.orientation = Eigen::Quaterniond(q->at(k, 3), q->at(k, 0), q->at(k, 1), q->at(k, 2)).normalized();
  }
  return samples;  // the filter checks the values (finite, stamps increasing)
}

void bind_sources(py::module_& io) {
  py::class_<ScanSequence>(io, "ScanSequence",
      "A run's scans, opened by the library's one opener (as the CLI's --kitti, scan files, --rgbd, --tum, --bag): "
      "an iterator of (points (N, 3) float32 in the sensor frame, T_map_scan 4x4 or None, stamp [s] or None"
      "[, times (N,) float32 [s] or None with with_times]); len() is the number of scans. Each scan is read when "
      "it is reached, without the GIL.")
      .def("__iter__", [](ScanSequence& self) -> ScanSequence& { return self; })
      .def("__next__", [](ScanSequence& self) {
        if (self.next >= self.src->scans.size()) throw py::stop_iteration();
        return read_scan(self, self.next++);
      })
      .def("__len__", [](const ScanSequence& self) { return self.src->scans.size(); })
      .def("read", [](const ScanSequence& self, std::size_t k) {
        if (k >= self.src->scans.size()) throw py::index_error(format("scan %zu of %zu", k, self.src->scans.size()));
        return read_scan(self, k);
      }, py::arg("index"), "Scan `index` as the iterator yields it, wherever the iterator is.")
      .def_property_readonly("names", [](const ScanSequence& self) {
        std::vector<std::string> names;
        for (const auto& p : self.src->scans) names.push_back(p.string());
        return names;
      }, "Each scan's file, depth image or 'topic@stamp'.")
      .def_property_readonly("poses", [](const ScanSequence& self) {
        return self.src->T_map_scan ? py::object(poses_array(*self.src->T_map_scan)) : py::object(py::none());
      }, "(N, 4, 4) T_map_scan, or None for a source without poses.")
      .def_property_readonly("stamps", [](const ScanSequence& self) {
        const auto& s = self.src->stamps;
        return s.empty() ? py::object(py::none()) : py::object(py::array_t<double>(static_cast<py::ssize_t>(s.size()), s.data()));
      }, "(N,) stamps [s], or None for a source without them.")
      .def_property_readonly("description", [](const ScanSequence& self) { return self.src->description; },
                             "What was opened, as `hmap map` prints it after 'input:' (empty for scan files).");
  io.def("open_source", &open_source, py::kw_only(), py::arg("kitti") = "", py::arg("files") = std::vector<std::string>(),
         py::arg("poses") = "", py::arg("rgbd") = "", py::arg("tum") = "", py::arg("intrinsics") = "",
         py::arg("depth_scale") = py::none(), py::arg("up") = "", py::arg("rotation") = py::none(), py::arg("bag") = "",
         py::arg("cloud_topic") = "", py::arg("pose_topic") = "", py::arg("tf_frames") = std::vector<std::string>(),
         py::arg("max_scans") = py::none(), py::arg("with_times") = false,
         "The library's open_scan_source with the CLI's inputs as keywords (one input of kitti, files, rgbd, tum, "
         "bag); a ScanSequence. hmap.io.kitti_sequence, scan_sequence, rgbd_sequence and bag_sequence call it.");
  io.def("read_bag_imu", [](const std::filesystem::path& path, const std::string& topic) -> py::object {
#ifdef HMAP_HAVE_ROS
    std::optional<ImuSamples> samples;
    {
      py::gil_scoped_release release;
      if (const auto found = ros::bag_imu_topic(path, topic)) samples = ros::read_bag_imu(path, *found);
    }
    return samples ? py::object(imu_dict(*samples)) : py::object(py::none());
#else
    (void)path;
    (void)topic;
    throw Error("this hmap was built without ROS bag support");
#endif
  }, py::arg("path"), py::arg("topic") = "",
     "The sensor_msgs/Imu messages of a recording as read_imu gives a file's, as `hmap slam --bag` takes them: "
     "`topic` (--imu-topic), else the recording's only Imu topic; None when it has none.");
  io.def("read_imu", [](const std::filesystem::path& path) { return imu_dict(read_imu_text(path)); }, py::arg("path"),
         "An IMU text file as `hmap slam --imu` reads it (t gx gy gz ax ay az [qx qy qz qw]): {'stamps': (N,) [s], "
         "'gyro': (N, 3) [rad/s], 'accel': (N, 3) [m/s^2], 'orientation': (N, 4) x y z w (NaN rows where a sample "
         "has none) or None}; hmap.slam.Slam(params, imu=...) takes it.");
}

}  // namespace hmap::python
