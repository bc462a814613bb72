#pragma once
// Arrays in and out of the Python module: (N, 3) points, 4x4 poses, per-point times, checked here
// with a ValueError that names the argument; shared by the module's source files.

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <cmath>
#include <cstring>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "hmap/core/error.hpp"
#include "hmap/core/format.hpp"
#include "hmap/core/pose.hpp"
#include "hmap/core/types.hpp"
#include "hmap/io/png.hpp"

namespace hmap::python {

namespace py = pybind11;

// ---------------------------------------------------------------------------------------------
// Arrays in

/// What to do with points holding NaN or infinity.
enum class NonFinite { kRaise, kDrop };

inline NonFinite non_finite_mode(const std::string& text) {
  if (text == "raise") return NonFinite::kRaise;
  if (text == "drop") return NonFinite::kDrop;
  throw py::value_error("non_finite must be 'raise' or 'drop', got '" + text + "'");
}

/// `a` checked to be an (N, 3) array of float32 or float64; `what` names it in messages.
inline py::array checked_points(const py::handle& a, const char* what) {
  if (!py::isinstance<py::array>(a)) {
    throw py::value_error(format("%s must be a numpy array of shape (N, 3), got %s", what,
                                 std::string(py::str(py::type::handle_of(a).attr("__name__"))).c_str()));
  }
  auto arr = py::reinterpret_borrow<py::array>(a);
  if (arr.ndim() != 2 || arr.shape(1) != 3) {
    std::string shape = "(";
    for (py::ssize_t d = 0; d < arr.ndim(); ++d) shape += (d ? ", " : "") + std::to_string(arr.shape(d));
    shape += arr.ndim() == 1 ? ",)" : ")";
    throw py::value_error(format("%s must have shape (N, 3), got %s", what, shape.c_str()));
  }
  if (!arr.dtype().is(py::dtype::of<float>()) && !arr.dtype().is(py::dtype::of<double>())) {
    throw py::value_error(format("%s must hold float32 or float64, got dtype %s", what,
                                 std::string(py::str(arr.dtype())).c_str()));
  }
  return arr;
}

/// Points of an (N, 3) array, viewed without a copy when it is C-contiguous float32 (the layout
/// of std::vector<Point3f>), else converted into `storage`.
inline std::span<const Point3f> points_of(const py::array& arr, PointCloud& storage, NonFinite mode, const char* what) {
  static_assert(sizeof(Point3f) == 3 * sizeof(float), "Point3f must be three packed floats");
  const auto n = static_cast<std::size_t>(arr.shape(0));
  std::span<const Point3f> points;
  if (arr.dtype().is(py::dtype::of<float>()) && (arr.flags() & py::array::c_style) != 0) {
    points = {static_cast<const Point3f*>(arr.data()), n};
  } else if (arr.dtype().is(py::dtype::of<float>())) {
    const auto r = py::reinterpret_borrow<py::array_t<float>>(arr).unchecked<2>();
    storage.resize(n);
    for (std::size_t i = 0; i < n; ++i) storage[i] = {r(i, 0), r(i, 1), r(i, 2)};
    points = storage;
  } else {
    const auto r = py::reinterpret_borrow<py::array_t<double>>(arr).unchecked<2>();
    storage.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
      storage[i] = {static_cast<float>(r(i, 0)), static_cast<float>(r(i, 1)), static_cast<float>(r(i, 2))};
    }
    points = storage;
  }
  if (mode == NonFinite::kRaise) {
    // Over the points as the library reads them: a float64 beyond float's range is infinite too.
    for (std::size_t i = 0; i < n; ++i) {
      if (points[i].allFinite()) continue;
      const Point3f& p = points[i];
      throw py::value_error(format("%s: row %zu is not finite (%g, %g, %g); pass non_finite='drop' to drop such "
                                   "points and count them, as the CLI does",
                                   what, i, static_cast<double>(p.x()), static_cast<double>(p.y()),
                                   static_cast<double>(p.z())));
    }
  }
  return points;
}

/// A 4×4 array (any real dtype) as a rigid pose, checked by the library (rigid_pose).
inline Pose pose_of(const py::handle& obj, const char* what) {
  // ensure() converts any array-like of numbers and gives a null array for anything else.
  const auto m = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(obj);
  if (!m || m.ndim() != 2 || m.shape(0) != 4 || m.shape(1) != 4) {
    throw py::value_error(format("%s must be a 4x4 matrix of numbers", what));
  }
  Eigen::Matrix4d matrix;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) matrix(r, c) = m.at(r, c);
  try {
    return rigid_pose(matrix);
  } catch (const Error& e) {
    throw py::value_error(std::string(what) + ": " + e.what());
  }
}

/// An (N, 4, 4) array (any real dtype) as N rigid poses; `what` names it in messages.
inline PoseList poses_of(const py::handle& obj, const char* what) {
  const auto m = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(obj);
  if (!m || m.ndim() != 3 || m.shape(1) != 4 || m.shape(2) != 4) {
    throw py::value_error(format("%s must be an (N, 4, 4) array of poses", what));
  }
  const auto r = m.unchecked<3>();
  PoseList poses;
  for (py::ssize_t k = 0; k < r.shape(0); ++k) {
    Eigen::Matrix4d matrix;
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) matrix(i, j) = r(k, i, j);
    try {
      poses.push_back(rigid_pose(matrix));
    } catch (const Error& e) {
      throw py::value_error(format("%s[%zd]: %s", what, k, e.what()));
    }
  }
  return poses;
}

/// An (H, W, 3) uint8 array as an RgbImage (copied); `what` names it in messages.
inline RgbImage image_of(const py::handle& image, const char* what) {
  if (!py::isinstance<py::array>(image)) throw py::value_error(format("%s must be a numpy array of shape (H, W, 3), dtype uint8", what));
  const auto arr = py::reinterpret_borrow<py::array>(image);
  if (arr.ndim() != 3 || arr.shape(2) != 3 || arr.shape(0) < 1 || arr.shape(1) < 1) {
    std::string shape = "(";
    for (py::ssize_t d = 0; d < arr.ndim(); ++d) shape += (d ? ", " : "") + std::to_string(arr.shape(d));
    throw py::value_error(format("%s must have shape (H, W, 3) with H, W >= 1, got ", what) + shape +
                          (arr.ndim() == 1 ? ",)" : ")"));
  }
  if (!arr.dtype().is(py::dtype::of<std::uint8_t>())) {
    throw py::value_error(format("%s must hold uint8, got dtype ", what) + std::string(py::str(arr.dtype())));
  }
  if (arr.shape(0) > 1 << 16 || arr.shape(1) > 1 << 16) throw py::value_error(format("%s is larger than 65536 pixels on a side", what));
  const auto c = py::array_t<std::uint8_t, py::array::c_style | py::array::forcecast>::ensure(arr);
  RgbImage img;
  img.width = static_cast<int>(arr.shape(1));
  img.height = static_cast<int>(arr.shape(0));
  img.rgb.assign(c.data(), c.data() + c.size());
  return img;
}

/// Per-point times [s] for `n` points: None gives none; else a 1-D array of n finite numbers.
inline std::vector<float> times_of(const py::handle& obj, std::size_t n) {
  std::vector<float> times;
  if (obj.is_none()) return times;
  const auto t = py::array_t<double, py::array::forcecast>::ensure(obj);
  if (!t || t.ndim() != 1 || static_cast<std::size_t>(t.shape(0)) != n) {
    throw py::value_error(format("times must be a 1-D array of %zu numbers, one per point", n));
  }
  const auto r = t.unchecked<1>();
  times.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double v = r(static_cast<py::ssize_t>(i));
    if (!std::isfinite(v)) throw py::value_error(format("times: element %zu is not finite (%g)", i, v));
    times[i] = static_cast<float>(v);
  }
  return times;
}

// ---------------------------------------------------------------------------------------------
// Arrays out

inline py::array_t<float> points_array(const PointCloud& cloud) {
  py::array_t<float> out({static_cast<py::ssize_t>(cloud.size()), py::ssize_t{3}});
  if (!cloud.empty()) std::memcpy(out.mutable_data(), cloud.data(), cloud.size() * sizeof(Point3f));
  return out;
}

/// The same without a copy: `cloud` moves into the array's owner (a capsule), its floats become
/// the array's buffer.
inline py::array_t<float> points_array(PointCloud&& cloud) {
  if (cloud.empty()) return points_array(static_cast<const PointCloud&>(cloud));
  auto* owned = new PointCloud(std::move(cloud));
  py::capsule owner(owned, [](void* p) { delete static_cast<PointCloud*>(p); });
  return py::array_t<float>({static_cast<py::ssize_t>(owned->size()), py::ssize_t{3}},
                            {static_cast<py::ssize_t>(sizeof(Point3f)), static_cast<py::ssize_t>(sizeof(float))},
                            owned->front().data(), owner);
}

inline py::array_t<double> poses_array(const PoseList& poses) {
  py::array_t<double> out({static_cast<py::ssize_t>(poses.size()), py::ssize_t{4}, py::ssize_t{4}});
  auto w = out.mutable_unchecked<3>();
  for (std::size_t k = 0; k < poses.size(); ++k) {
    const Eigen::Matrix4d m = poses[k].matrix();
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c) w(static_cast<py::ssize_t>(k), r, c) = m(r, c);
  }
  return out;
}

/// A picture as an (H, W, 3) uint8 array, row 0 the top; its bytes move into the array's owner.
inline py::array_t<std::uint8_t> image_array(RgbImage&& image) {
  auto* owned = new std::vector<std::uint8_t>(std::move(image.rgb));
  py::capsule owner(owned, [](void* p) { delete static_cast<std::vector<std::uint8_t>*>(p); });
  const auto h = static_cast<py::ssize_t>(image.height), w = static_cast<py::ssize_t>(image.width);
  return py::array_t<std::uint8_t>({h, w, py::ssize_t{3}}, {w * 3, py::ssize_t{3}, py::ssize_t{1}}, owned->data(), owner);
}

inline py::array_t<double> matrix_array(const Pose& T) {
  py::array_t<double> out({py::ssize_t{4}, py::ssize_t{4}});
  auto w = out.mutable_unchecked<2>();
  const Eigen::Matrix4d m = T.matrix();
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) w(r, c) = m(r, c);
  return out;
}

inline py::array_t<double> vector_array(const Eigen::Vector3d& v) {
  py::array_t<double> out(3);
  for (int d = 0; d < 3; ++d) out.mutable_at(d) = v[d];
  return out;
}

}  // namespace hmap::python
