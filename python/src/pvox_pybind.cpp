// hmap.pvox: the PVOX probabilistic voxel grid (src/hmap/pvox): the map, its Kalman-filtered
// scan-by-scan builder, and the .pvox file of `hmap pvox`.

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "arrays.hpp"
#include "hmap/io/atomic_file.hpp"
#include "hmap/io/read_support.hpp"
#include "hmap/pvox/mapper.hpp"
#include "hmap/pvox/serialize.hpp"
#include "hmap/pvox/voxel_map.hpp"
#include "hmap/render/pvox_render.hpp"
#include "hmap/render/render.hpp"

namespace hmap::python {

namespace {

/// A voxel map with the lock that lets insert() run without the GIL. A PvoxMapper's map is a
/// copy taken when asked for (the mapper changes its edge, and so every voxel, as it goes).
struct PyVoxelMap {
  std::mutex mutex;
  pvox::VoxelMap map;
  explicit PyVoxelMap(pvox::VoxelMap m) : map(std::move(m)) {}
};

struct PyPvoxMapper {
  std::mutex mutex;
  pvox::PvoxMapper mapper;
  explicit PyPvoxMapper(const pvox::PvoxParams& p) : mapper(p) {}
};

/// One voxel for the structured arrays of VoxelMap.voxels() / occupied().
struct VoxelRow {
  std::int32_t i, j, k;
  double x, y, z;
  double probability;
  std::uint32_t hits, misses;
};

py::array voxel_rows(const std::vector<pvox::VoxelView>& views) {
  py::array_t<VoxelRow> out(static_cast<py::ssize_t>(views.size()));
  auto* w = out.mutable_data();
  for (std::size_t n = 0; n < views.size(); ++n) {
    const pvox::VoxelView& v = views[n];
    w[n] = {v.key.i, v.key.j, v.key.k, v.centre.x(), v.centre.y(), v.centre.z(), v.probability, v.hits, v.misses};
  }
  return out;
}

pvox::FreeSpace free_space_of(const std::string& text) {
  if (text == "off") return pvox::FreeSpace::kOff;
  if (text == "rays") return pvox::FreeSpace::kRays;
  throw py::value_error("free_space must be 'off' or 'rays', got '" + text + "'");
}

/// Checked points, copied into a PointCloud (the library takes one); non-finite rows raise or
/// are dropped (`non_finite`), as Mapper.integrate does.
PointCloud cloud_for(const py::handle& points, const std::string& non_finite) {
  const NonFinite mode = non_finite_mode(non_finite);
  const py::array arr = checked_points(points, "points");
  PointCloud storage;
  const std::span<const Point3f> pts = points_of(arr, storage, mode, "points");
  if (mode == NonFinite::kRaise) return PointCloud(pts.begin(), pts.end());
  PointCloud kept;
  kept.reserve(pts.size());
  for (const Point3f& p : pts)
    if (p.allFinite()) kept.push_back(p);
  return kept;
}

/// Query points as doubles, checked: (N, 3), float32/float64, finite.
std::vector<Eigen::Vector3d> queries_of(const py::handle& xyz) {
  const py::array arr = checked_points(xyz, "xyz");
  const auto q = py::array_t<double, py::array::forcecast>::ensure(arr).unchecked<2>();
  std::vector<Eigen::Vector3d> out(static_cast<std::size_t>(q.shape(0)));
  for (py::ssize_t i = 0; i < q.shape(0); ++i) {
    out[static_cast<std::size_t>(i)] = {q(i, 0), q(i, 1), q(i, 2)};
    if (!out[static_cast<std::size_t>(i)].allFinite()) throw py::value_error(format("xyz: row %zd is not finite", i));
  }
  return out;
}

py::dict insert_stats_dict(const pvox::InsertStats& s) {
  py::dict d;
  d["hits"] = s.hits;
  d["rejected"] = s.rejected;
  d["misses"] = s.misses;
  return d;
}

py::array_t<double> vec2(const Eigen::Vector2d& v) {
  py::array_t<double> out(2);
  out.mutable_at(0) = v.x();
  out.mutable_at(1) = v.y();
  return out;
}

py::dict registration_dict(const pvox::RegistrationResult& r) {
  py::dict d;
  d["T_map_sensor"] = matrix_array(r.T_map_sensor);
  d["prior_mean"] = vec2(r.prior_mean);
  d["prior_variance"] = vec2(r.prior_variance);
  d["measurement"] = r.measurement ? py::object(vec2(*r.measurement)) : py::object(py::none());
  d["measured_by_alignment"] = r.measured_by_alignment;
  py::dict a;
  a["offset"] = vec2(r.align.offset);
  a["valid"] = r.align.valid;
  a["converged"] = r.align.converged;
  a["iterations"] = r.align.iterations;
  a["correspondences"] = r.align.correspondences;
  a["planes"] = r.align.planes;
  a["rms"] = r.align.rms;
  d["align"] = a;
  d["posterior_variance"] = vec2(r.posterior_variance);
  d["edge"] = r.edge;
  d["insert"] = insert_stats_dict(r.insert);
  return d;
}

std::shared_ptr<PyVoxelMap> load_pvox(const std::filesystem::path& path) {
  py::gil_scoped_release release;
  const std::string bytes = detail::read_file_bytes(path);
  return std::make_shared<PyVoxelMap>(pvox::decode_binary(
      std::span(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size()), path.string()));
}

void save_pvox(PyVoxelMap& self, const std::filesystem::path& path) {
  py::gil_scoped_release release;
  const std::scoped_lock lock(self.mutex);
  const std::vector<std::uint8_t> binary = pvox::encode_binary(self.map);
  write_file_atomic(path, std::string_view(reinterpret_cast<const char*>(binary.data()), binary.size()));
}

}  // namespace

/// The picture `hmap render` draws of a .pvox map: the bulk of it (render::bulk_view), from above or
/// isometric.
py::array_t<std::uint8_t> render_pvox(PyVoxelMap& self, const std::string& view_name, int max_pixels) {
  if (view_name != "top" && view_name != "iso") throw py::value_error("view must be 'top' or 'iso', got '" + view_name + "'");
  render::check_max_pixels(max_pixels);
  RgbImage image;
  {
    py::gil_scoped_release release;
    const std::scoped_lock lock(self.mutex);
    if (self.map.occupied().empty()) throw Error("the map has no occupied voxel, nothing to draw");
    render::PvoxView view = render::bulk_view(self.map);
    view.max_pixels = max_pixels;
    image = view_name == "iso" ? render::render_pvox_iso(self.map, view) : render::render_pvox_top(self.map, view);
  }
  return image_array(std::move(image));
}

void bind_pvox(py::module_& m) {
  PYBIND11_NUMPY_DTYPE(VoxelRow, i, j, k, x, y, z, probability, hits, misses);
  py::module_ s = m.def_submodule("pvox", "The PVOX probabilistic voxel grid and its Kalman-filtered builder");

  py::class_<PyVoxelMap, std::shared_ptr<PyVoxelMap>>(s, "VoxelMap",
      "A sparse grid of cubic voxels of edge `edge` [m] counting hits and misses; p = 1 / (1 + exp(-L)) with "
      "L = clamp(hits * ln(1 + edge^2 / (2 measurement_variance)) - misses * miss_logit, logit_min, logit_max); "
      "unseen space has p = 0.5.")
      .def(py::init([](double edge, double measurement_variance, double logit_min, double logit_max, double miss_logit) {
        pvox::ProbabilityModel model{measurement_variance, logit_min, logit_max, miss_logit};
        return std::make_shared<PyVoxelMap>(pvox::VoxelMap(edge, model));
      }), py::arg("edge"), py::kw_only(), py::arg("measurement_variance") = 100e-6, py::arg("logit_min") = -2.0,
         py::arg("logit_max") = 3.5, py::arg("miss_logit") = 0.4,
         "edge [m]; measurement_variance [m^2] (sigma_m^2); hmap.Error for a non-positive edge or an invalid model.")
      .def_static("load", &load_pvox, py::arg("path"), "Reads a .pvox file (what `hmap pvox` writes as map.pvox).")
      .def("save", &save_pvox, py::arg("path"), "Writes the map as a .pvox file, atomically (`hmap info` reads it).")
      .def_property_readonly("edge", [](PyVoxelMap& self) {
        const std::scoped_lock lock(self.mutex);
        return self.map.edge();
      }, "[m]")
      .def_property_readonly("voxel_count", [](PyVoxelMap& self) {
        const std::scoped_lock lock(self.mutex);
        return self.map.voxel_count();
      })
      .def_property_readonly("memory_bytes", [](PyVoxelMap& self) {
        const std::scoped_lock lock(self.mutex);
        return self.map.memory_bytes();
      })
      .def("set_edge", [](PyVoxelMap& self, double edge) {
        py::gil_scoped_release release;
        const std::scoped_lock lock(self.mutex);
        self.map.set_edge(edge);
      }, py::arg("edge"), "Re-voxelates at a new edge [m]: each voxel moves, with its counts, to the voxel of its points' mean.")
      .def("insert", [](PyVoxelMap& self, const py::handle& points, const py::handle& pose, double min_range,
                        double max_range, const std::string& free_space, const std::string& non_finite) {
        const PointCloud cloud = cloud_for(points, non_finite);
        const Pose T = pose_of(pose, "T_map_sensor");
        const pvox::InsertParams p{min_range, max_range, free_space_of(free_space)};
        pvox::InsertStats stats;
        {
          py::gil_scoped_release release;
          const std::scoped_lock lock(self.mutex);
          stats = self.map.insert(cloud, T, p);
        }
        return insert_stats_dict(stats);
      }, py::arg("points"), py::arg("T_map_sensor"), py::kw_only(), py::arg("min_range") = 0.0,
         py::arg("max_range") = 60.0, py::arg("free_space") = "off", py::arg("non_finite") = "raise",
         "Inserts a scan: points (N, 3) float32/float64 in the sensor frame, T_map_sensor 4x4. Each point within "
         "[min_range, max_range] [m] of the sensor is a hit in its voxel; free_space='rays' counts a miss in every "
         "voxel a ray crosses before its end. Runs without the GIL. Returns {'hits', 'rejected', 'misses'}.")
      .def("probability", [](PyVoxelMap& self, const py::handle& xyz) {
        const auto q = queries_of(xyz);
        py::array_t<double> out(static_cast<py::ssize_t>(q.size()));
        auto w = out.mutable_unchecked<1>();
        const std::scoped_lock lock(self.mutex);
        for (std::size_t i = 0; i < q.size(); ++i) w(static_cast<py::ssize_t>(i)) = self.map.probability_at(q[i]);
        return out;
      }, py::arg("xyz"), "p of the voxel holding each point of an (N, 3) array: (N,) float64, 0.5 where nothing was counted.")
      .def("field", [](PyVoxelMap& self, const py::handle& xyz) {
        const auto q = queries_of(xyz);
        const auto n = static_cast<py::ssize_t>(q.size());
        py::array_t<double> p(n), g({n, py::ssize_t{3}});
        auto pw = p.mutable_unchecked<1>();
        auto gw = g.mutable_unchecked<2>();
        const std::scoped_lock lock(self.mutex);
        for (py::ssize_t i = 0; i < n; ++i) {
          const pvox::FieldSample f = self.map.field_at(q[static_cast<std::size_t>(i)]);
          pw(i) = f.probability;
          for (int d = 0; d < 3; ++d) gw(i, d) = f.gradient[d];
        }
        return py::make_tuple(p, g);
      }, py::arg("xyz"),
         "The continuous field at each point of an (N, 3) array: (probability (N,), gradient (N, 3) [1/m]), p "
         "trilinearly interpolated between voxel centres.")
      .def("voxels", [](PyVoxelMap& self) {
        const std::scoped_lock lock(self.mutex);
        return voxel_rows(self.map.voxels());
      }, "Every voxel holding a count, sorted by key, as a structured array (i, j, k, x, y, z (centre [m]), "
         "probability, hits, misses); voxel (i, j, k) covers [i, i + 1) * edge on x, and so on.")
      .def("occupied", [](PyVoxelMap& self, double threshold) {
        const std::scoped_lock lock(self.mutex);
        return voxel_rows(self.map.occupied(threshold));
      }, py::arg("threshold") = 0.5, "The voxels with p > threshold, as voxels() gives them.")
      .def("voxels_csv", [](PyVoxelMap& self) {
        const std::scoped_lock lock(self.mutex);
        return pvox::voxels_csv(self.map);
      }, "The voxel CSV of `hmap pvox` (voxels.csv): x,y,z,edge,probability per voxel holding points.");

  py::class_<PyPvoxMapper>(s, "Mapper",
      "Scan-by-scan PVOX map building: predict the pose from the commanded motion, measure it (a given x, y, or "
      "by aligning the scan to the map), fuse (a Kalman filter per planar axis), set the voxel edge to "
      "k_sigma * sigma of the posterior (or fixed_edge), and insert the scan at the posterior mean. Variances "
      "in m^2, as `hmap pvox`'s options in mm^2 times 1e-6.")
      .def(py::init([](double k_sigma, double fixed_edge, const std::string& filter, double motion_variance,
                       double measurement_variance, std::optional<double> initial_variance, double min_range,
                       double max_range, const std::string& free_space) {
        pvox::PvoxParams p;
        if (filter == "rbf") {
          p.filter.kind = pvox::FilterKind::kRecursive;
        } else if (filter == "brf") {
          p.filter.kind = pvox::FilterKind::kNaive;
        } else {
          throw py::value_error("filter must be 'rbf' or 'brf', got '" + filter + "'");
        }
        p.filter.motion_variance = motion_variance;
        p.filter.initial_variance = initial_variance.value_or(motion_variance);  // as `hmap pvox`
        p.filter.measurement_variance = measurement_variance;
        p.probability.measurement_variance = measurement_variance;
        p.k_sigma = k_sigma;
        p.fixed_edge = fixed_edge;
        p.insert = {min_range, max_range, free_space_of(free_space)};
        return std::make_unique<PyPvoxMapper>(p);
      }), py::kw_only(), py::arg("k_sigma") = 6.0, py::arg("fixed_edge") = 0.0, py::arg("filter") = "rbf",
         // The CLI's mm² times 1e-6, computed as it computes them: 100 * 1e-6 is not the double 100e-6,
         // and the variance is stored in the .pvox file.
         py::arg("motion_variance") = 2000.0 * 1e-6, py::arg("measurement_variance") = 100.0 * 1e-6,
         py::arg("initial_variance") = py::none(), py::arg("min_range") = 0.1, py::arg("max_range") = 60.0,
         py::arg("free_space") = "off",
         "The defaults are `hmap pvox`'s: k 6, filter rbf, motion 2000 mm^2, measurement 100 mm^2, ranges 0.1-60 m.")
      .def("add_scan", [](PyPvoxMapper& self, const py::handle& points, const py::handle& motion,
                          const py::handle& measured_xy, const std::string& non_finite) {
        const PointCloud cloud = cloud_for(points, non_finite);
        const Pose T = pose_of(motion, "motion");
        std::optional<Eigen::Vector2d> measured;
        if (!measured_xy.is_none()) {
          const auto a = py::array_t<double, py::array::forcecast>::ensure(measured_xy);
          if (!a || a.ndim() != 1 || a.shape(0) != 2 || !std::isfinite(a.at(0)) || !std::isfinite(a.at(1))) {
            throw py::value_error("measured_xy must be two finite numbers (x, y) [m] or None");
          }
          measured = Eigen::Vector2d(a.at(0), a.at(1));
        }
        pvox::RegistrationResult r;
        {
          py::gil_scoped_release release;
          const std::scoped_lock lock(self.mutex);
          r = self.mapper.add_scan(cloud, T, measured);
        }
        return registration_dict(r);
      }, py::arg("points"), py::arg("motion"), py::arg("measured_xy") = py::none(), py::kw_only(),
         py::arg("non_finite") = "raise",
         "Registers one scan ((N, 3) sensor frame). motion: the commanded move T_previous_current as a 4x4 (for the "
         "first scan, the initial T_map_sensor); measured_xy: the measured position, or None to align the scan to "
         "the map. Runs without the GIL. Returns the registration as a dict (T_map_sensor, prior and posterior "
         "variance [m^2], measurement, align, edge [m], insert).")
      .def_property_readonly("map", [](PyPvoxMapper& self) {
        const std::scoped_lock lock(self.mutex);
        return std::make_shared<PyVoxelMap>(self.mapper.map());
      }, "A copy of the map as it stands.")
      .def_property_readonly("scans", [](PyPvoxMapper& self) {
        const std::scoped_lock lock(self.mutex);
        return self.mapper.scans();
      });
  py::module_ pictures = m.attr("render");
  pictures.def("pvox", &render_pvox, py::arg("map"), py::kw_only(), py::arg("view") = "top", py::arg("max_pixels") = 1200,
               "pvox(map, *, view='top', max_pixels=1200) -> image: a pvox.VoxelMap as `hmap render` draws a .pvox file: "
               "its bulk (the 2nd-98th percentile box of the occupied voxels), 'top' (the highest occupied voxel per "
               "pixel, height-coloured, with a scale bar panel) or 'iso' (shaded cubes from the south-west).");
}

}  // namespace hmap::python
