// The extension module mcslam._mcslam: the library facade (mcslam/mcslam.hpp) for Python, with
// images and trajectories as numpy arrays. python/mcslam/__init__.py builds the public API on it.
//
// Conventions: a trajectory is an N x 8 float64 array of TUM rows (timestamp tx ty tz qx qy qz
// qw, T_w_c); a pose is a 4 x 4 float64 matrix. Every mcslam::InputError becomes
// mcslam.InputError (a ValueError) with the same message.

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <cstring>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "mcslam/mcslam.hpp"

namespace py = pybind11;

namespace {

using mcslam::InputError;

py::array_t<double> pose_matrix(const mcslam::SE3& T) {
  py::array_t<double> out({4, 4});
  const Eigen::Matrix4d m = T.matrix();
  auto a = out.mutable_unchecked<2>();
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) a(r, c) = m(r, c);
  return out;
}

py::array_t<double> trajectory_array(const mcslam::Trajectory& t) {
  py::array_t<double> out({static_cast<py::ssize_t>(t.size()), static_cast<py::ssize_t>(8)});
  auto a = out.mutable_unchecked<2>();
  for (std::size_t i = 0; i < t.size(); ++i) {
    const auto& q = t[i].T_w_c.quaternion();
    const auto& p = t[i].T_w_c.translation();
    const double row[8] = {t[i].timestamp, p.x(), p.y(), p.z(), q.x(), q.y(), q.z(), q.w()};
    for (int c = 0; c < 8; ++c) a(static_cast<py::ssize_t>(i), c) = row[c];
  }
  return out;
}

mcslam::Trajectory trajectory_from(const py::handle& object, const char* what) {
  py::array arr = py::array::ensure(object);
  if (!arr || arr.ndim() != 2 || arr.shape(1) != 8)
    throw InputError(std::string(what) +
                     ": expected an N x 8 array of TUM rows (timestamp tx ty tz qx qy qz qw)");
  auto values = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(arr);
  if (!values) throw InputError(std::string(what) + ": expected numbers");
  auto a = values.unchecked<2>();
  mcslam::Trajectory t;
  for (py::ssize_t i = 0; i < a.shape(0); ++i) {
    const Eigen::Quaterniond q(a(i, 7), a(i, 4), a(i, 5), a(i, 6));
    if (!(q.norm() > 0.0))
      throw InputError(std::string(what) + ": row " + std::to_string(i) + " has a zero quaternion");
    t.push_back({a(i, 0), mcslam::SE3(q, Eigen::Vector3d(a(i, 1), a(i, 2), a(i, 3)))});
  }
  return t;
}

std::string shape_text(const py::array& a) {
  std::string s = "(";
  for (py::ssize_t d = 0; d < a.ndim(); ++d) s += (d ? ", " : "") + std::to_string(a.shape(d));
  return s + (a.ndim() == 1 ? ",)" : ")");
}

std::string dtype_text(const py::array& a) { return py::str(a.dtype()).cast<std::string>(); }

/// A copy of `a` (the system keeps the colour image of keyframes and for the detector).
template <typename T>
cv::Mat to_mat(const py::array& a, int type) {
  auto c = py::array_t<T, py::array::c_style>::ensure(a);
  const int rows = static_cast<int>(a.shape(0)), cols = static_cast<int>(a.shape(1));
  cv::Mat out(rows, cols, type);
  std::memcpy(out.data, c.data(), out.total() * out.elemSize());
  return out;
}

std::string type_name(const py::handle& object) {
  return py::str(py::type::handle_of(object).attr("__name__")).cast<std::string>();
}

cv::Mat colour_image(const py::handle& object, bool rgb_order) {
  if (!py::isinstance<py::array>(object))
    throw InputError("process: rgb must be a numpy array, not " + type_name(object));
  py::array a = py::reinterpret_borrow<py::array>(object);
  if (!a.dtype().is(py::dtype::of<std::uint8_t>()))
    throw InputError("process: rgb has dtype " + dtype_text(a) + "; expected uint8");
  if (a.ndim() == 2) return to_mat<std::uint8_t>(a, CV_8UC1);
  if (a.ndim() != 3 || a.shape(2) != 3)
    throw InputError("process: rgb has shape " + shape_text(a) +
                     "; expected (height, width, 3) or (height, width)");
  cv::Mat m = to_mat<std::uint8_t>(a, CV_8UC3);
  if (rgb_order)
    cv::Mat(m.rows, m.cols, CV_8UC3, m.data).forEach<cv::Vec3b>([](cv::Vec3b& p, const int*) {
      std::swap(p[0], p[2]);
    });
  return m;
}

cv::Mat depth_image(const py::handle& object) {
  if (!py::isinstance<py::array>(object))
    throw InputError("process: depth must be a numpy array, not " + type_name(object));
  py::array a = py::reinterpret_borrow<py::array>(object);
  if (a.ndim() != 2)
    throw InputError("process: depth has shape " + shape_text(a) + "; expected (height, width)");
  if (a.dtype().is(py::dtype::of<float>())) return to_mat<float>(a, CV_32FC1);
  if (a.dtype().is(py::dtype::of<std::uint16_t>())) return to_mat<std::uint16_t>(a, CV_16UC1);
  throw InputError("process: depth has dtype " + dtype_text(a) +
                   "; expected float32 (metres) or uint16 (raw units, divided by the camera's "
                   "depth_factor)");
}

py::array image_array(const cv::Mat& m) {
  if (m.type() == CV_8UC3) {
    py::array_t<std::uint8_t> out({m.rows, m.cols, 3});
    for (int r = 0; r < m.rows; ++r)
      std::memcpy(out.mutable_data(r), m.ptr(r), static_cast<std::size_t>(m.cols) * 3);
    return out;
  }
  py::array_t<float> out({m.rows, m.cols});
  for (int r = 0; r < m.rows; ++r)
    std::memcpy(out.mutable_data(r), m.ptr(r), static_cast<std::size_t>(m.cols) * sizeof(float));
  return out;
}

using Api = mcslam::System;

/// The System behind Python's System, with the lock that serialises the calls of several
/// Python threads on it (see the class's binding).
struct LockedSystem {
  explicit LockedSystem(const mcslam::Settings& settings) : system(settings) {}
  /// Calls a reader without the GIL (its copy can take a while). The readers may run beside
  /// process() (System's thread rules), so they do not take the lock.
  template <typename R>
  R read(R (Api::*reader)() const) const {
    py::gil_scoped_release release;
    return (system.*reader)();
  }
  mcslam::System system;
  mutable std::mutex mutex;
};

}  // namespace

PYBIND11_MODULE(_mcslam, m) {
  m.doc() = "mcslam: semantic RGB-D SLAM for dynamic indoor scenes (the C++ extension)";
  m.attr("__version__") = mcslam::version();
  py::register_exception<InputError>(m, "InputError", PyExc_ValueError);

  py::class_<mcslam::PinholeCamera>(m, "Camera", "A pinhole RGB-D camera (raw images)")
      .def(py::init<>())
      .def_readwrite("fx", &mcslam::PinholeCamera::fx)
      .def_readwrite("fy", &mcslam::PinholeCamera::fy)
      .def_readwrite("cx", &mcslam::PinholeCamera::cx)
      .def_readwrite("cy", &mcslam::PinholeCamera::cy)
      .def_readwrite("width", &mcslam::PinholeCamera::width)
      .def_readwrite("height", &mcslam::PinholeCamera::height)
      .def_readwrite("distortion", &mcslam::PinholeCamera::distortion,
                     "k1 k2 p1 p2 k3 of the raw images")
      .def_readwrite("depth_factor", &mcslam::PinholeCamera::depth_factor,
                     "raw depth units per metre")
      .def_readwrite("bf", &mcslam::PinholeCamera::bf)
      .def_readwrite("readout_time", &mcslam::PinholeCamera::readout_time,
                     "rolling-shutter readout time (s)")
      .def("__repr__", [](const mcslam::PinholeCamera& c) {
        return "Camera(" + std::to_string(c.width) + "x" + std::to_string(c.height) + ", fx " +
               std::to_string(c.fx) + ", fy " + std::to_string(c.fy) + ")";
      });

  py::class_<mcslam::Settings>(m, "Settings", "The camera and every option of a run")
      .def(py::init<>())
      .def(py::init<const mcslam::Settings&>(), py::arg("other"), "A copy")
      .def_static("preset", &mcslam::Settings::preset, py::arg("name"))
      .def_static("for_sequence", &mcslam::Settings::for_sequence, py::arg("sequence_dir"),
                  py::arg("settings_file") = "")
      .def("load_file", &mcslam::Settings::load_file, py::arg("path"))
      .def("load_yaml", &mcslam::Settings::load_yaml, py::arg("yaml"),
           py::arg("name") = "<settings>")
      .def_property("camera", &mcslam::Settings::camera, &mcslam::Settings::set_camera)
      .def_property("sequential", &mcslam::Settings::sequential, &mcslam::Settings::set_sequential)
      .def_property("vocabulary", &mcslam::Settings::vocabulary, &mcslam::Settings::set_vocabulary)
      .def("set_loop_closing", &mcslam::Settings::set_loop_closing, py::arg("enabled"))
      .def("set_detector", &mcslam::Settings::set_detector, py::arg("model"),
           py::arg("confidence") = py::none())
      .def("set_detections_file", &mcslam::Settings::set_detections_file, py::arg("path"))
      .def_property_readonly("detector_model", &mcslam::Settings::detector_model)
      .def_property_readonly("detections_file", &mcslam::Settings::detections_file)
      .def("to_yaml", &mcslam::Settings::to_yaml);

  py::class_<mcslam::FrameReport>(m, "Frame", "What tracking made of one frame")
      .def_readonly("frame_id", &mcslam::FrameReport::frame_id)
      .def_readonly("timestamp", &mcslam::FrameReport::timestamp)
      .def_property_readonly(
          "state", [](const mcslam::FrameReport& r) { return mcslam::to_string(r.state); })
      .def_property_readonly(
          "pose",
          [](const mcslam::FrameReport& r) -> py::object {
            if (!r.T_w_c) return py::none();
            return pose_matrix(*r.T_w_c);
          },
          "4 x 4 T_w_c when tracked, else None")
      .def_property_readonly(
          "lagged_pose",
          [](const mcslam::FrameReport& r) -> py::object {
            if (!r.lagged) return py::none();
            return py::make_tuple(r.lagged->timestamp, pose_matrix(r.lagged->T_w_c));
          },
          "(timestamp, 4 x 4 T_w_c): with tracker.pose_filter.lag > 0, the pose of the frame lag "
          "tracked frames back, smoothed with the frames since; else None")
      .def_readonly("keyframe", &mcslam::FrameReport::keyframe)
      .def_readonly("relocalised", &mcslam::FrameReport::relocalised)
      .def_readonly("features", &mcslam::FrameReport::features)
      .def_readonly("lines", &mcslam::FrameReport::lines)
      .def_readonly("planes", &mcslam::FrameReport::planes)
      .def_readonly("matches", &mcslam::FrameReport::matches)
      .def_readonly("inliers", &mcslam::FrameReport::inliers)
      .def_readonly("objects", &mcslam::FrameReport::objects)
      .def_readonly("dynamic_objects", &mcslam::FrameReport::dynamic_objects)
      .def_readonly("dynamic_points", &mcslam::FrameReport::dynamic_points)
      .def_readonly("tracking_ms", &mcslam::FrameReport::tracking_ms)
      .def("__repr__", [](const mcslam::FrameReport& r) {
        return "Frame(" + std::to_string(r.frame_id) + ", " + mcslam::to_string(r.state) +
               (r.keyframe ? ", keyframe" : "") + ")";
      });

  // A System is driven by one thread at a time: process() and finish() run without the GIL,
  // so two Python threads could otherwise enter it at once. Each call takes the object's lock
  // (after letting the GIL go, so that a waiting thread does not hold up the interpreter).
  py::class_<LockedSystem>(m, "_System")
      .def(py::init([](const mcslam::Settings& settings) {
             py::gil_scoped_release release;  // the vocabulary and the model load meanwhile
             return std::make_unique<LockedSystem>(settings);
           }),
           py::arg("settings"))
      .def(
          "process",
          [](LockedSystem& s, const py::object& rgb, const py::object& depth, double timestamp,
             std::optional<double> depth_timestamp, bool rgb_order) {
            const cv::Mat colour = colour_image(rgb, rgb_order);
            const cv::Mat d = depth_image(depth);
            py::gil_scoped_release release;
            std::lock_guard<std::mutex> lock(s.mutex);
            return s.system.process(colour, d, timestamp, depth_timestamp);
          },
          py::arg("rgb"), py::arg("depth"), py::arg("timestamp"),
          py::arg("depth_timestamp") = py::none(), py::arg("rgb_order") = false)
      .def("finish",
           [](LockedSystem& s) {
             py::gil_scoped_release release;
             std::lock_guard<std::mutex> lock(s.mutex);
             s.system.finish();
           })
      .def("trajectory",
           [](const LockedSystem& s) { return trajectory_array(s.read(&Api::trajectory)); })
      .def("unsmoothed_trajectory",
           [](const LockedSystem& s) {
             return trajectory_array(s.read(&Api::unsmoothed_trajectory));
           })
      .def(
          "keyframe_trajectory",
          [](const LockedSystem& s) { return trajectory_array(s.read(&Api::keyframe_trajectory)); })
      .def("online_trajectory",
           [](const LockedSystem& s) { return trajectory_array(s.read(&Api::online_trajectory)); })
      .def("lagged_trajectory",
           [](const LockedSystem& s) { return trajectory_array(s.read(&Api::lagged_trajectory)); })
      .def("map",
           [](const LockedSystem& s) {
             const mcslam::MapSnapshot snap = s.read(&Api::map);
             py::array_t<double> points(
                 {static_cast<py::ssize_t>(snap.points.size()), static_cast<py::ssize_t>(3)});
             auto p = points.mutable_unchecked<2>();
             for (std::size_t i = 0; i < snap.points.size(); ++i)
               for (int c = 0; c < 3; ++c) p(static_cast<py::ssize_t>(i), c) = snap.points[i][c];
             py::array_t<double> lines(
                 {static_cast<py::ssize_t>(snap.lines.size()), static_cast<py::ssize_t>(6)});
             auto l = lines.mutable_unchecked<2>();
             for (std::size_t i = 0; i < snap.lines.size(); ++i)
               for (int c = 0; c < 3; ++c) {
                 l(static_cast<py::ssize_t>(i), c) = snap.lines[i].first[c];
                 l(static_cast<py::ssize_t>(i), c + 3) = snap.lines[i].second[c];
               }
             py::array_t<double> planes(
                 {static_cast<py::ssize_t>(snap.planes.size()), static_cast<py::ssize_t>(4)});
             auto q = planes.mutable_unchecked<2>();
             for (std::size_t i = 0; i < snap.planes.size(); ++i)
               for (int c = 0; c < 4; ++c) q(static_cast<py::ssize_t>(i), c) = snap.planes[i][c];
             py::dict out;
             out["points"] = points;
             out["lines"] = lines;
             out["planes"] = planes;
             out["keyframes"] = trajectory_array(snap.keyframes);
             return out;
           })
      .def("grid",
           [](const LockedSystem& s) {
             const mcslam::OccupancyGridSnapshot g = s.read(&Api::grid);
             py::array_t<std::int8_t> cells(
                 {static_cast<py::ssize_t>(g.height), static_cast<py::ssize_t>(g.width)});
             if (!g.cells.empty())
               std::memcpy(cells.mutable_data(), g.cells.data(), g.cells.size());
             py::array_t<double> T({static_cast<py::ssize_t>(4), static_cast<py::ssize_t>(4)});
             auto t = T.mutable_unchecked<2>();
             for (int r = 0; r < 4; ++r)
               for (int c = 0; c < 4; ++c) t(r, c) = g.T_world_grid(r, c);
             py::dict out;
             out["cells"] = cells;
             out["resolution"] = g.resolution;
             out["T_world_grid"] = T;
             return out;
           })
      .def("occupied_voxels",
           [](const LockedSystem& s) {
             const std::vector<Eigen::Vector3d> v = s.read(&Api::occupied_voxels);
             py::array_t<double> out(
                 {static_cast<py::ssize_t>(v.size()), static_cast<py::ssize_t>(3)});
             auto o = out.mutable_unchecked<2>();
             for (std::size_t i = 0; i < v.size(); ++i)
               for (int c = 0; c < 3; ++c) o(static_cast<py::ssize_t>(i), c) = v[i][c];
             return out;
           })
      .def(
          "save_session",
          [](LockedSystem& s, const std::string& path) {
            py::gil_scoped_release release;
            std::lock_guard<std::mutex> lock(s.mutex);
            s.system.save_session(path);
          },
          py::arg("path"))
      .def_property_readonly("settings", [](const LockedSystem& s) { return s.system.settings(); });

  py::class_<mcslam::Sequence>(m, "Sequence", "A TUM-layout RGB-D folder")
      .def(py::init([](const std::string& directory, const std::string& associations) {
             py::gil_scoped_release release;
             return mcslam::Sequence::open(directory, associations);
           }),
           py::arg("directory"), py::arg("associations") = "")
      .def_property_readonly("directory", &mcslam::Sequence::directory)
      .def("__len__", &mcslam::Sequence::size)
      .def_property_readonly("timestamps",
                             [](const mcslam::Sequence& s) {
                               py::array_t<double> out(static_cast<py::ssize_t>(s.size()));
                               for (std::size_t i = 0; i < s.size(); ++i)
                                 out.mutable_at(static_cast<py::ssize_t>(i)) = s.timestamp(i);
                               return out;
                             })
      .def(
          "load",
          [](const mcslam::Sequence& s, std::size_t index, double depth_factor) {
            mcslam::Sequence::Frame f;
            {
              py::gil_scoped_release release;  // reading and decoding two images
              f = s.load(index, depth_factor);
            }
            return py::make_tuple(image_array(f.rgb), image_array(f.depth), f.timestamp,
                                  f.depth_timestamp);
          },
          py::arg("index"), py::arg("depth_factor"),
          "(rgb uint8 HxWx3 BGR, depth float32 metres, timestamp, depth timestamp)")
      .def("groundtruth",
           [](const mcslam::Sequence& s) -> py::object {
             const auto gt = s.groundtruth();
             if (!gt) return py::none();
             return trajectory_array(*gt);
           })
      .def("warnings", &mcslam::Sequence::warnings);

  m.def(
      "_evaluate",
      [](const py::object& gt, const py::object& est, double max_time_difference) {
        const mcslam::Trajectory g = trajectory_from(gt, "groundtruth");
        const mcslam::Trajectory e = trajectory_from(est, "estimate");
        return mcslam::evaluate(g, e, max_time_difference).json;
      },
      py::arg("groundtruth"), py::arg("estimate"), py::arg("max_time_difference") = 0.02);
  m.def(
      "read_trajectory",
      [](const std::string& path) { return trajectory_array(mcslam::read_trajectory(path)); },
      py::arg("path"), "A TUM trajectory file as an N x 8 array");
  m.def(
      "write_trajectory",
      [](const std::string& path, const py::object& trajectory) {
        mcslam::write_trajectory(path, trajectory_from(trajectory, "trajectory"));
      },
      py::arg("path"), py::arg("trajectory"));
  m.def("data_file_candidates", &mcslam::data_file_candidates, py::arg("name"),
        "Where the data file `name` is looked for, in order");
}
