// Python bindings (`import lshloc`): the global map, the localizer, the map
// store, CARMEN logs and ROS occupancy grids. Scans are numpy arrays of ranges with their beam
// angles; poses are (x, y, theta) tuples [m, m, rad]. The heavy calls
// (adding scans, localizing, loading and saving maps) release the GIL.
// Thread safety: a GlobalMap may be used from several Python threads: its
// writes (add_submap, add_scan, add_grid_submap) take its lock exclusively,
// its reads (Localizer.add_scan, save, stats) shared (the C++ map's contract:
// concurrent reads, exclusive writes). A Localizer serializes its own calls.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <memory>
#include <mutex>
#include <numbers>
#include <shared_mutex>
#include <string>
#include <tuple>
#include <variant>

#include "lshloc/common/error.hpp"
#include "lshloc/runtime/session.hpp"
#include "lshloc/io/atomic_file.hpp"
#include "lshloc/io/carmen_reader.hpp"
#include "lshloc/io/scan_record.hpp"
#include "lshloc/io/config_json.hpp"
#include "lshloc/io/map_source.hpp"
#include "lshloc/io/map_store.hpp"
#include "lshloc/io/ros_map.hpp"
#include "lshloc/localization/global_map.hpp"
#include "lshloc/localization/grid_submap.hpp"
#include "lshloc/localization/localizer.hpp"
#include "lshloc/slam/occupancy_grid.hpp"

namespace py = pybind11;
using namespace lshloc;

namespace {

using PoseTuple = std::tuple<double, double, double>;
PoseTuple to_tuple(const Pose2& p) { return {p.x, p.y, p.theta}; }
Pose2 to_pose(const PoseTuple& t) { return {std::get<0>(t), std::get<1>(t), std::get<2>(t)}; }

/// `p` unless a value is not finite.
Pose2 finite_pose(const PoseTuple& t, const char* what) {
  const Pose2 p = to_pose(t);
  if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.theta))
    throw Error(std::string(what) + ": expected a finite (x, y, theta)");
  return p;
}

LaserScan make_scan(const py::array_t<float, py::array::c_style | py::array::forcecast>& ranges, double angle_min,
                    double angle_increment, double max_range, double timestamp, const PoseTuple& pose,
                    const PoseTuple& odometry) {
  if (ranges.ndim() != 1)
    throw Error("LaserScan: ranges must be a 1-D array, got " + std::to_string(ranges.ndim()) + "-D");
  LaserScan s;
  s.ranges.assign(ranges.data(), ranges.data() + ranges.size());
  if (!std::isfinite(timestamp)) throw Error("LaserScan: expected a finite timestamp [s]");
  if (s.ranges.size() > 1 && !(std::abs(angle_increment) > 0.0))
    throw Error("LaserScan: expected a non-zero finite angle_increment [rad] between " +
                std::to_string(s.ranges.size()) + " beams, got " + std::to_string(angle_increment));
  s.angle_min = angle_min, s.angle_increment = angle_increment, s.max_range = max_range, s.timestamp = timestamp;
  s.pose = to_pose(pose), s.odometry = finite_pose(odometry, "LaserScan.odometry");
  if (const char* problem = io::scan_update_problem(s, s.pose))
    throw Error(std::string("LaserScan: expected ") + problem);
  const double span = std::abs(angle_increment) * static_cast<double>(s.ranges.empty() ? 0 : s.ranges.size() - 1);
  if (!scan_angles_in_radians(angle_min, span))
    throw Error("LaserScan: angle_min " + std::to_string(angle_min) + " and angle_increment " +
                std::to_string(angle_increment) + " over " + std::to_string(s.ranges.size()) +
                " beams: expected radians (a scan spans at most 2 pi)");
  if (!(max_range > 0.0)) throw Error("LaserScan: expected max_range > 0 [m], got " + std::to_string(max_range));
  return s;
}

/// The stamp of a ROS message's header [s]: ROS 2's builtin_interfaces/Time
/// (sec, nanosec) or ROS 1's rospy Time (secs, nsecs).
double ros_stamp(const py::object& msg) {
  const py::object stamp = msg.attr("header").attr("stamp");
  if (py::hasattr(stamp, "nanosec"))
    return stamp.attr("sec").cast<double>() + 1e-9 * stamp.attr("nanosec").cast<double>();
  if (py::hasattr(stamp, "nsecs")) return stamp.attr("secs").cast<double>() + 1e-9 * stamp.attr("nsecs").cast<double>();
  throw Error("LaserScan.from_ros: header.stamp has neither sec/nanosec (ROS 2) nor secs/nsecs (ROS 1)");
}

/// A planar pose (x, y, yaw) from a ROS message: nav_msgs/Odometry,
/// geometry_msgs/PoseWithCovarianceStamped, PoseStamped or Pose (position +
/// orientation), TransformStamped or Transform (translation + rotation).
PoseTuple pose_from_ros(const py::object& msg) {
  py::object at = msg;
  for (const char* inner : {"pose", "pose", "transform"})  // Odometry.pose.pose, PoseStamped.pose, ...
    if (py::hasattr(at, inner)) at = at.attr(inner);
  const char* place = py::hasattr(at, "position") ? "position" : "translation";
  const char* turn = py::hasattr(at, "orientation") ? "orientation" : "rotation";
  if (!py::hasattr(at, place) || !py::hasattr(at, turn))
    throw Error(
        "pose_from_ros: expected a nav_msgs/Odometry, a geometry_msgs pose (position, orientation) or transform "
        "(translation, rotation)");
  const py::object p = at.attr(place), q = at.attr(turn);
  const auto get = [](const py::object& o, const char* name) { return o.attr(name).cast<double>(); };
  const double qx = get(q, "x"), qy = get(q, "y"), qz = get(q, "z"), qw = get(q, "w");
  const double yaw = std::atan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz));
  const PoseTuple pose{get(p, "x"), get(p, "y"), yaw};
  finite_pose(pose, "pose_from_ros");
  return pose;
}

/// A sensor_msgs/LaserScan message (rclpy's or rospy's, or any object with its
/// fields) as lshloc reads it: no return (+inf, above range_max) as
/// range_max, invalid beams (NaN, -inf, below range_min) as NaN, as
/// scripts/tools/rosbag_to_carmen.py converts them.
LaserScan scan_from_ros(const py::object& msg, const py::object& odometry_in, const PoseTuple& pose) {
  // The odometry as (x, y, theta), or a ROS odometry or pose message.
  const PoseTuple odometry = py::isinstance<py::tuple>(odometry_in) || py::isinstance<py::list>(odometry_in)
                                 ? odometry_in.cast<PoseTuple>()
                                 : pose_from_ros(odometry_in);
  for (const char* field : {"ranges", "angle_min", "angle_increment", "range_min", "range_max", "header"})
    if (!py::hasattr(msg, field))
      throw Error(std::string("LaserScan.from_ros: the message has no field '") + field +
                  "'; expected a sensor_msgs/LaserScan");
  const auto range_min = msg.attr("range_min").cast<float>();
  const auto range_max = msg.attr("range_max").cast<float>();
  if (!(range_max > 0.0f))
    throw Error("LaserScan.from_ros: expected range_max > 0 [m], got " + std::to_string(range_max));
  const auto given = py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(msg.attr("ranges"));
  if (!given || given.ndim() != 1) throw Error("LaserScan.from_ros: expected ranges, a sequence of numbers");
  // A copy: the message's own array is the caller's.
  py::array_t<float> ranges(given.shape(0));
  const auto in = given.unchecked<1>();
  auto out = ranges.mutable_unchecked<1>();
  for (py::ssize_t i = 0; i < in.shape(0); ++i) {
    const float r = in(i);
    out(i) = std::isnan(r) || r < range_min ? std::numeric_limits<float>::quiet_NaN() : std::min(r, range_max);
  }
  return make_scan(ranges, msg.attr("angle_min").cast<double>(), msg.attr("angle_increment").cast<double>(), range_max,
                   ros_stamp(msg), pose, odometry);
}

/// A grid of nav_msgs cells, checked: what the constructor and __setstate__ make.
OccupancyGrid make_grid(const py::array& cells_in, double resolution, const PoseTuple& origin) {
  // nav_msgs data: int8, -1 unknown, 0..100 (0 free, 100 occupied); a uint8 view reads -1 as 255.
  const char kind = cells_in.dtype().kind();
  if (kind != 'i' && kind != 'u')
    throw Error(
        "OccupancyGrid: cells must be integers as nav_msgs/OccupancyGrid holds them (-1 unknown, "
        "0 free, 100 occupied), got dtype kind '" +
        std::string(1, kind) + "'");
  const bool bytes = kind == 'u' && cells_in.itemsize() == 1;
  const auto cells = py::array_t<std::int64_t, py::array::c_style | py::array::forcecast>::ensure(cells_in);
  if (!cells || cells.ndim() != 2)
    throw Error("OccupancyGrid: cells must be a 2-D array (rows, columns), got " + std::to_string(cells_in.ndim()) +
                "-D");
  if (cells.size() == 0) throw Error("OccupancyGrid: cells must not be empty");
  if (!(resolution > 0.0) || !std::isfinite(resolution))
    throw Error("OccupancyGrid: resolution must be a finite > 0 m");
  OccupancyGrid g;
  g.resolution = resolution;
  const Pose2 o = finite_pose(origin, "OccupancyGrid origin");
  g.origin = {o.x, o.y};
  g.origin_yaw = o.theta;
  g.height = static_cast<std::size_t>(cells.shape(0)), g.width = static_cast<std::size_t>(cells.shape(1));
  g.cells.resize(static_cast<std::size_t>(cells.size()));
  const std::int64_t* data = cells.data();
  for (std::size_t i = 0; i < g.cells.size(); ++i) {
    const std::int64_t v = bytes && data[i] == 255 ? -1 : data[i];
    if (v < -1 || v > 100)
      throw Error("OccupancyGrid: cell " + std::to_string(i) + " (row " + std::to_string(i / g.width) + ", column " +
                  std::to_string(i % g.width) + ") is " + std::to_string(data[i]) +
                  "; expected -1 (unknown) or 0..100 (nav_msgs occupancy)");
    g.cells[i] = v == 0 ? occupancy::kFree : v == 100 ? occupancy::kOccupied : occupancy::kUnknown;
  }
  return g;
}

/// `a` with numpy's writeable flag down: the properties return copies, so a write into one would be lost
/// without a word; a read-only copy raises ValueError instead.
template <class A>
A read_only(A a) {
  a.attr("setflags")(py::arg("write") = false);
  return a;
}

py::array_t<float> ranges_array(const LaserScan& s) {
  return read_only(py::array_t<float>(s.ranges.size(), s.ranges.data()));
}

py::array_t<std::int8_t> grid_cells(const OccupancyGrid& g) {
  return read_only(py::array_t<std::int8_t>({g.height, g.width}, g.cells.data()));
}

/// The tuple `state` that a __setstate__ of `cls` was given, checked: `size` items, version 1 first
/// (`layout` names them in the errors).
py::tuple checked_state(const py::handle& state, std::size_t size, const std::string& cls, const std::string& layout) {
  const std::string expected = cls + ".__setstate__: expected a state tuple " + layout;
  if (!py::isinstance<py::tuple>(state)) throw Error(expected + ", got " + std::string(Py_TYPE(state.ptr())->tp_name));
  const auto t = py::reinterpret_borrow<py::tuple>(state);
  if (t.size() == 0 || !py::isinstance<py::int_>(t[0])) throw Error(expected + ": the version, an int, first");
  const py::object version = t[0];
  if (!version.equal(py::int_(1)))
    throw Error(cls + ".__setstate__: unknown state version " + py::repr(version).cast<std::string>() +
                " (pickled by another lshloc version?); expected a state tuple " + layout);
  if (t.size() != size)
    throw Error(expected + ", got " + std::to_string(t.size()) + " items instead of " + std::to_string(size));
  return t;
}

/// Item `i` (`name`) of a checked state tuple as a T.
template <class T>
T state_item(const py::tuple& t, std::size_t i, const std::string& cls, const char* name, const std::string& layout) {
  try {
    return t[i].cast<T>();
  } catch (const py::cast_error&) {
    throw Error(cls + ".__setstate__: item " + std::to_string(i) + " (" + name + ") is " +
                py::repr(t[i]).cast<std::string>() + ", which does not fit a state tuple " + layout);
  }
}

// Pickled LaserScan and OccupancyGrid: a versioned tuple of every field, read back through the
// constructors' checks (a field added later gets a new version; old states stay readable).
constexpr const char* kScanState =
    "(1, ranges, angle_min, angle_increment, max_range, timestamp, pose, odometry, source_line)";
constexpr const char* kGridState = "(1, cells, resolution, origin, width, height)";

py::object scan_state(const LaserScan& s) {
  return py::make_tuple(1, ranges_array(s), s.angle_min, s.angle_increment, s.max_range, s.timestamp, to_tuple(s.pose),
                        to_tuple(s.odometry), s.source_line);
}

LaserScan scan_from_state(const py::object& state) {
  const std::string cls = "LaserScan";
  const py::tuple t = checked_state(state, 9, cls, kScanState);
  using Ranges = py::array_t<float, py::array::c_style | py::array::forcecast>;
  LaserScan s = make_scan(
      state_item<Ranges>(t, 1, cls, "ranges", kScanState), state_item<double>(t, 2, cls, "angle_min", kScanState),
      state_item<double>(t, 3, cls, "angle_increment", kScanState),
      state_item<double>(t, 4, cls, "max_range", kScanState), state_item<double>(t, 5, cls, "timestamp", kScanState),
      state_item<PoseTuple>(t, 6, cls, "pose", kScanState), state_item<PoseTuple>(t, 7, cls, "odometry", kScanState));
  s.source_line = state_item<std::size_t>(t, 8, cls, "source_line", kScanState);
  return s;
}

py::object grid_state(const OccupancyGrid& g) {
  return py::make_tuple(1, grid_cells(g), g.resolution, PoseTuple{g.origin.x(), g.origin.y(), g.origin_yaw}, g.width,
                        g.height);
}

OccupancyGrid grid_from_state(const py::object& state) {
  const std::string cls = "OccupancyGrid";
  const py::tuple t = checked_state(state, 6, cls, kGridState);
  OccupancyGrid g = make_grid(state_item<py::array>(t, 1, cls, "cells", kGridState),
                              state_item<double>(t, 2, cls, "resolution", kGridState),
                              state_item<PoseTuple>(t, 3, cls, "origin", kGridState));
  const auto width = state_item<std::size_t>(t, 4, cls, "width", kGridState);
  const auto height = state_item<std::size_t>(t, 5, cls, "height", kGridState);
  if (width != g.width || height != g.height)
    throw Error("OccupancyGrid.__setstate__: width " + std::to_string(width) + " and height " + std::to_string(height) +
                " disagree with the cells' " + std::to_string(g.height) + " rows of " + std::to_string(g.width));
  return g;
}

/// A config_json argument: JSON text, or a dict of the same settings.
using ConfigJson = std::variant<std::string, py::dict>;

/// The JSON text of a config_json argument; a dict is written by Python's json module (no NaN: JSON has none).
std::string config_text(const ConfigJson& config) {
  if (const auto* text = std::get_if<std::string>(&config)) return *text;
  try {
    return py::module_::import("json")
        .attr("dumps")(std::get<py::dict>(config), py::arg("allow_nan") = false)
        .cast<std::string>();
  } catch (const py::error_already_set& e) {
    if (!e.matches(PyExc_TypeError) && !e.matches(PyExc_ValueError)) throw;
    throw Error(std::string("config_json: expected a dict of JSON values (str keys; numbers, bools, str, None, lists "
                            "and dicts); json.dumps says: ") +
                py::str(e.value()).cast<std::string>());
  }
}

/// Takes a map lock without holding the GIL (where this thread holds it): a thread waiting for the map
/// never stops the other Python threads, and every lock is taken so (no thread waits for the map while
/// holding the GIL that its holder may need back).
template <class Lock>
void lock_without_gil(Lock& l) {
  if (PyGILState_Check()) {
    const py::gil_scoped_release no_gil;
    l.lock();
  } else {
    l.lock();
  }
}

/// The Python GlobalMap: the map and the lock its Python users share (see the top of this file).
struct PyGlobalMap {
  std::shared_ptr<GlobalMap> map;
  std::shared_ptr<std::shared_mutex> lock = std::make_shared<std::shared_mutex>();

  /// f(map) under the lock shared: what reads the map.
  template <class F>
  auto read(F f) const {
    std::shared_lock reading(*lock, std::defer_lock);
    lock_without_gil(reading);
    return f(static_cast<const GlobalMap&>(*map));
  }
  /// f(map) under the lock alone: what writes it.
  template <class F>
  auto write(F f) {
    std::unique_lock writing(*lock, std::defer_lock);
    lock_without_gil(writing);
    return f(*map);
  }

  std::uint32_t checked(std::uint32_t submap) const {
    if (submap >= map->submap_count())
      throw Error("GlobalMap: no submap " + std::to_string(submap) + " (ids 0 to " +
                  std::to_string(map->submap_count()) + " - 1)");
    return submap;
  }
};

/// A localizer that keeps its map (and the map's lock) alive.
struct PyLocalizer {
  PyGlobalMap map;
  std::unique_ptr<Localizer> localizer;
  std::unique_ptr<std::mutex> busy = std::make_unique<std::mutex>();  ///< one add_scan at a time
};

/// A config_json argument parsed, its syntax errors as lshloc.Error naming it.
nlohmann::json parse_config_json(const std::string& text) {
  try {
    return nlohmann::json::parse(text);
  } catch (const nlohmann::json::parse_error& e) {
    throw Error(std::string("config_json: ") + e.what());
  }
}

LocalizerConfig localizer_config(const GlobalMap& map, const std::string& config_json, const Pose2& laser_offset) {
  LocalizerConfig c;
  if (!config_json.empty()) {
    const nlohmann::json patch = parse_config_json(config_json);
    if (patch.is_object() && patch.contains("features"))
      throw Error(
          "config_json: features: the localizer takes the map's feature settings; set them in the map's "
          "config_json");
    io::apply_config_patch(patch, c, "config_json");
  }
  // The map's descriptor settings, as every command does (the Localizer refuses others).
  return with_target_laser_offset(with_map_descriptor_settings(c, map.config()), laser_offset);
}

}  // namespace

PYBIND11_MODULE(lshloc, m) {
  m.doc() =
      "lshloc: global localization of 2D-laser robots in large, growing maps (LSH-RANSAC)\n\n"
      "Poses are (x, y, theta) tuples [m, m, rad]. The `pose` of a scan or an estimate is the laser's; an "
      "estimate's `robot_pose` is the robot's (the laser mount, laser_offset, taken off). A NaN (or negative) range "
      "is an invalid beam, a range >= max_range no return.\n"
      "Threads: the heavy calls (adding scans, localizing, reading and writing logs, maps and grids) release the "
      "GIL. A GlobalMap may be used from several threads: its writes (add_submap, add_scan, add_grid_submap, "
      "set_query_settings) take its lock exclusively, its reads (Localizer.add_scan, save, stats, ...) shared. A "
      "Localizer serializes its own calls.\n"
      "Bad input raises lshloc.Error (a ValueError) saying what was expected; a file that cannot be opened, read or "
      "written, lshloc.FileError (also an OSError).";
  m.attr("__version__") = LSHLOC_VERSION;
  const auto error = py::register_exception<Error>(m, "Error", PyExc_ValueError);
  // A file that cannot be opened or read: both lshloc.Error and OSError.
  py::register_exception<FileError>(m, "FileError", py::make_tuple(error, py::handle(PyExc_OSError)));

  py::class_<LaserScan>(m, "LaserScan", "One planar laser scan: ranges [m] at angle_min + i * angle_increment [rad]")
      .def(py::init(&make_scan), py::arg("ranges"), py::arg("angle_min"), py::arg("angle_increment"),
           py::arg("max_range") = 81.0, py::arg("timestamp") = 0.0, py::arg("pose") = PoseTuple{0, 0, 0},
           py::arg("odometry") = PoseTuple{0, 0, 0},
           "ranges: 1-D array [m], kept as float32 (NaN or negative: invalid beam; >= max_range: no return); "
           "angle_min: [rad] beam 0's bearing in the laser frame (x forward, y left); angle_increment: [rad] between "
           "beams; max_range: [m]; timestamp: [s]; pose: the laser's pose (x, y, theta) the log gives (the "
           "Localizer ignores it; occupancy_grid_from_scans draws the scan there, mappers pass it to "
           "GlobalMap.add_scan); odometry: the robot's odometry pose (x, y, theta) at the scan (the "
           "Localizer uses only its change from scan to scan)")
      .def_property_readonly(
          "ranges", &ranges_array,
          "[m] float32, a read-only copy (NaN or negative: invalid beam; >= max_range: no return); for other "
          "ranges build a new LaserScan")
      .def_property_readonly(
          "angles",
          [](const LaserScan& s) {
            py::array_t<double> a(s.ranges.size());
            auto v = a.mutable_unchecked<1>();
            for (std::size_t i = 0; i < s.ranges.size(); ++i) v(i) = s.bearing(i);
            return read_only(a);
          },
          "[rad] each beam's bearing in the laser frame, a read-only copy (angle_min + i * angle_increment)")
      .def_property_readonly(
          "angle_min", [](const LaserScan& s) { return s.angle_min; }, "[rad] the first beam's angle")
      .def_property_readonly(
          "angle_increment", [](const LaserScan& s) { return s.angle_increment; }, "[rad] between beams")
      .def_property(
          "timestamp", [](const LaserScan& s) { return s.timestamp; },
          [](LaserScan& s, double t) {
            if (!std::isfinite(t)) throw Error("LaserScan.timestamp: expected a finite time [s]");
            s.timestamp = t;
          },
          "[s]")
      .def_property(
          "max_range", [](const LaserScan& s) { return s.max_range; },
          [](LaserScan& s, double r) {
            if (!(r > 0.0)) throw Error("LaserScan.max_range: expected > 0 [m]");
            s.max_range = r;
          },
          "[m] ranges at or beyond it are no return")
      .def_property(
          "pose", [](const LaserScan& s) { return to_tuple(s.pose); },
          [](LaserScan& s, const PoseTuple& p) { s.pose = finite_pose(p, "LaserScan.pose"); },
          "laser pose the log gives (x, y, theta)")
      .def_property(
          "odometry", [](const LaserScan& s) { return to_tuple(s.odometry); },
          [](LaserScan& s, const PoseTuple& p) { s.odometry = finite_pose(p, "LaserScan.odometry"); },
          "the robot's odometry pose (x, y, theta) at the scan")
      .def_static("from_ros", &scan_from_ros, py::arg("msg"), py::arg("odometry") = py::make_tuple(0.0, 0.0, 0.0),
                  py::arg("pose") = PoseTuple{0, 0, 0},
                  "A sensor_msgs/LaserScan message from rclpy or rospy (any object with its fields): its ranges, "
                  "angles, range_max and header stamp [s]; no return (+inf, above range_max) becomes range_max and "
                  "invalid beams (NaN, -inf, below range_min) NaN, as scripts/tools/rosbag_to_carmen.py converts them. "
                  "odometry: the robot's odometry pose at the scan, (x, y, theta) or a nav_msgs/Odometry or "
                  "geometry_msgs pose or transform message (as pose_from_ros reads it)")
      .def("__len__", [](const LaserScan& s) { return s.ranges.size(); })
      .def(py::pickle(&scan_state, &scan_from_state))
      .def("__repr__", [](const LaserScan& s) {
        const double last =
            s.angle_min + s.angle_increment * static_cast<double>(s.ranges.empty() ? 0 : s.ranges.size() - 1);
        std::string text;
        io::append_format(text, "<lshloc.LaserScan: %zu beams, %.1f..%.1f deg, max_range %g m, timestamp %.6f>",
                          s.ranges.size(), s.angle_min * 180.0 / std::numbers::pi, last * 180.0 / std::numbers::pi,
                          s.max_range, s.timestamp);
        return text;
      });

  py::class_<io::CarmenLog>(m, "CarmenLog", "A CARMEN log in memory")
      .def_readonly("path", &io::CarmenLog::path, "the file read, as given")
      .def_readonly("scans", &io::CarmenLog::scans,
                    "the laser scans, a new list on each access (items refer into the log): keep "
                    "`scans = log.scans` rather than indexing log.scans in a loop")
      .def_property_readonly(
          "laser_offset", [](const io::CarmenLog& l) { return to_tuple(l.front_laser_offset()); },
          "the laser's mount on the robot (x, y, theta), from the ROBOTLASER1 lines or PARAM "
          "robot_frontlaser_* (0 when absent): pass it to Localizer(laser_offset=...) for this robot")
      .def_property_readonly("gmapping_corrected", &io::CarmenLog::gmapping_corrected,
                             "whether GMapping corrected the log (it has NEFF messages): its scan poses are then map "
                             "poses, not odometry")
      .def_property_readonly("poses_corrected", &io::CarmenLog::poses_corrected,
                             "whether the log's scan poses are map poses: GMapping's NEFF messages, or lshloc's "
                             "PARAM lshloc_scan_poses map (a corrected log that lshloc wrote)")
      .def_readonly("warnings", &io::CarmenLog::warnings,
                    "what the reader noticed (time stamps backwards or repeated, bytes after the gzip stream), "
                    "each naming the file and line")
      .def(
          "__len__", [](const io::CarmenLog& l) { return l.scans.size(); }, "the number of laser scans")
      .def(
          "__getitem__",
          [](const io::CarmenLog& l, std::ptrdiff_t i) {
            const auto n = static_cast<std::ptrdiff_t>(l.scans.size());
            if (i < 0) i += n;
            if (i < 0 || i >= n)
              throw py::index_error("CarmenLog: scan index out of range (" + std::to_string(n) + " scans)");
            return l.scans[static_cast<std::size_t>(i)];
          },
          py::arg("index"), "the laser scan at `index` (a copy), without building the list `scans` makes")
      .def(
          "__iter__", [](const io::CarmenLog& l) { return py::make_iterator(l.scans.begin(), l.scans.end()); },
          py::keep_alive<0, 1>(), "the laser scans in log order")
      .def("__repr__", [](const io::CarmenLog& l) {
        std::string text;
        io::append_format(text, "<lshloc.CarmenLog %s: %zu scans, %s>", l.path.c_str(), l.scans.size(),
                          l.poses_corrected() ? "corrected poses" : "raw");
        return text;
      });
  m.def("pose_from_ros", &pose_from_ros, py::arg("msg"),
        "(x, y, yaw) [m, m, rad] of a ROS message: nav_msgs/Odometry, geometry_msgs PoseWithCovarianceStamped, "
        "PoseStamped or Pose, TransformStamped or Transform (rclpy's, rospy's, or any object with those fields); "
        "the yaw of its quaternion");
  m.def(
      "read_carmen_log", [](const std::filesystem::path& path) { return io::read_carmen_log(path.string()); },
      py::arg("path"), py::call_guard<py::gil_scoped_release>(), "Reads a CARMEN log (plain or .gz)");

  py::class_<OccupancyGrid>(m, "OccupancyGrid",
                            "An occupancy grid as nav_msgs has it: cells[row, col] is -1 (unknown), 0 (free) or 100 "
                            "(occupied), row 0 at the origin's y")
      .def(py::init(&make_grid), py::arg("cells"), py::arg("resolution"), py::arg("origin") = PoseTuple{0, 0, 0},
           "cells: 2-D integer array as nav_msgs/OccupancyGrid data, row 0 at the origin's y: -1 unknown, 0 free, "
           "100 occupied; 1..99 read as unknown (as AMCL reads them); uint8 255 is -1. resolution [m]; origin (x, y, "
           "yaw) of cell (0, 0)'s corner")
      .def_readonly("resolution", &OccupancyGrid::resolution, "[m] a cell's edge")
      .def_property_readonly(
          "origin",
          [](const OccupancyGrid& g) {
            return PoseTuple{g.origin.x(), g.origin.y(), g.origin_yaw};
          },
          "(x, y, yaw) [m, m, rad]: cell (0, 0)'s lower left corner and the grid's rotation about it, as map_server's "
          "origin")
      .def_property_readonly("cells", &grid_cells,
                             "int8 (rows, columns), row 0 at the origin's y: -1 unknown, 0 free, 100 occupied; a "
                             "read-only copy (for other cells build a new OccupancyGrid)")
      .def(py::pickle(&grid_state, &grid_from_state))
      .def("__repr__", [](const OccupancyGrid& g) {
        std::string text;
        io::append_format(text, "<lshloc.OccupancyGrid: %zu x %zu cells of %g m, origin (%g, %g, %g)>", g.width,
                          g.height, g.resolution, g.origin.x(), g.origin.y(), g.origin_yaw);
        return text;
      });
  m.def(
      "read_ros_map", [](const std::filesystem::path& path) { return io::read_ros_map(path.string()); },
      py::arg("yaml_path"), py::call_guard<py::gil_scoped_release>(),
      "Reads a ROS map_server map (MAP.yaml and its PGM or 8-bit PNG)");
  m.def(
      "write_ros_map",
      [](const std::filesystem::path& stem, const OccupancyGrid& g) { io::write_ros_map(stem.string(), g); },
      py::arg("stem"), py::arg("grid"), py::call_guard<py::gil_scoped_release>(),
      "Writes STEM.yaml and STEM.pgm as map_server reads them");
  m.def(
      "occupancy_grid_from_scans",
      [](const std::vector<LaserScan>& scans, double resolution) {
        OccupancyGridConfig c;
        c.resolution = resolution;
        return build_occupancy_grid(scans, c);
      },
      py::arg("scans"), py::arg("resolution") = 0.05, py::call_guard<py::gil_scoped_release>(),
      "The occupancy grid of posed scans (each scan's pose is its laser pose), as `lshloc map to-grid`");

  py::class_<PyGlobalMap>(m, "GlobalMap",
                          "The global map mapper robots feed, one scan at a time; usable from several threads (writes "
                          "exclusive, reads shared)")
      .def(py::init([](const ConfigJson& config_json) {
             GlobalMapConfig c;
             const std::string text = config_text(config_json);
             if (!text.empty()) io::apply_config_patch(parse_config_json(text), c, "config_json");
             return PyGlobalMap{std::make_shared<GlobalMap>(c)};
           }),
           py::arg("config_json") = "",
           "config_json: a JSON object (text or dict) of GlobalMapConfig fields to change (the `map` part of `lshloc "
           "map build --print-config`), e.g. {\"database\": {\"L\": 16}}")
      .def(
          "set_query_settings",
          [](PyGlobalMap& g, const ConfigJson& config_json) {
            const nlohmann::json patch = parse_config_json(config_text(config_json));  // (a dict needs the GIL)
            const py::gil_scoped_release release;
            g.write([&](GlobalMap& map) {
              LshConfig asked = map.config().database;
              io::apply_config_patch(patch, asked, "config_json");
              if (nlohmann::json(with_query_settings(map.config().database, asked)) != nlohmann::json(asked))
                throw Error(
                    "config_json: a built map's database takes only max_candidates, rarest_buckets_first and "
                    "sketch_collision_weight (the others are part of its contents)");
              map.set_query_settings(asked);
            });
          },
          py::arg("config_json"),
          "Queries from now on read the map's database with these query-time settings, no rebuild: a JSON "
          "object (text or dict) of LshConfig fields (the map's `database` part), e.g. {\"max_candidates\": 1000}; "
          "localizers made before take them from their next scan")
      .def(
          "add_submap",
          [](PyGlobalMap& g, const std::string& name) {
            return g.write([&](GlobalMap& map) { return map.add_submap(name); });
          },
          py::arg("name"), py::call_guard<py::gil_scoped_release>(), "Opens a new submap; returns its id")
      .def(
          "add_scan",
          [](PyGlobalMap& g, std::uint32_t submap, const LaserScan& scan, const PoseTuple& pose) {
            const Pose2 laser_pose = to_pose(pose);
            if (const char* problem = io::scan_update_problem(scan, laser_pose))
              throw Error(std::string("GlobalMap.add_scan: expected ") + problem);
            return g.write([&](GlobalMap& map) { return map.add_scan(g.checked(submap), scan, laser_pose); });
          },
          py::arg("submap"), py::arg("scan"), py::arg("laser_pose"), py::call_guard<py::gil_scoped_release>(),
          "Adds a mapper scan at its laser pose in the submap's frame; returns the features it added. A scan the map "
          "cannot take raises lshloc.Error and leaves the map as it was")
      .def(
          "add_grid_submap",
          [](PyGlobalMap& g, const std::string& name, const OccupancyGrid& grid, double pose_spacing,
             std::size_t headings, std::size_t beams, double field_of_view, double max_range) {
            GridSubmapConfig c;
            c.pose_spacing = pose_spacing, c.headings = headings, c.beams = beams, c.field_of_view = field_of_view,
            c.max_range = max_range;
            GridSubmapStats st;
            std::uint32_t id = 0;
            {
              py::gil_scoped_release release;
              id = g.write([&](GlobalMap& map) { return add_grid_as_new_submap(map, name, grid, c, &st); });
            }
            return py::make_tuple(
                id, py::dict(py::arg("positions") = st.positions, py::arg("virtual_scans") = st.virtual_scans,
                             py::arg("features") = st.features, py::arg("cpu_s") = st.cpu_s));
          },
          py::arg("name"), py::arg("grid"), py::arg("pose_spacing") = GridSubmapConfig{}.pose_spacing,
          py::arg("headings") = GridSubmapConfig{}.headings, py::arg("beams") = GridSubmapConfig{}.beams,
          py::arg("field_of_view") = GridSubmapConfig{}.field_of_view,
          py::arg("max_range") = GridSubmapConfig{}.max_range,
          "Adds a submap built from an occupancy grid: virtual scans from free positions pose_spacing [m] apart, "
          "`headings` per position, each of `beams` beams over field_of_view [rad] reaching max_range [m]; returns "
          "(submap id, stats). A grid or setting that cannot make a submap raises lshloc.Error before the map "
          "changes")
      .def_property_readonly(
          "submap_count",
          [](const PyGlobalMap& g) { return g.read([](const GlobalMap& map) { return map.submap_count(); }); },
          "the number of submaps (ids 0 to submap_count - 1)")
      .def_property_readonly(
          "submap_names",
          [](const PyGlobalMap& g) {
            return g.read([](const GlobalMap& map) {
              std::vector<std::string> names;
              names.reserve(map.submap_count());
              for (std::uint32_t id = 0; id < map.submap_count(); ++id) names.push_back(map.submap_name(id));
              return names;
            });
          },
          "the submaps' names in id order (a new list on each access)")
      .def(
          "submap_name",
          [](const PyGlobalMap& g, std::uint32_t submap) {
            return g.read([&](const GlobalMap& map) { return map.submap_name(g.checked(submap)); });
          },
          py::arg("submap"), "The name the submap was opened with")
      .def(
          "submap_scans",
          [](const PyGlobalMap& g, std::uint32_t submap) {
            return g.read([&](const GlobalMap& map) { return map.submap_scans(g.checked(submap)); });
          },
          py::arg("submap"), "Scans (mapper or virtual) the submap holds")
      .def(
          "stats",
          [](const PyGlobalMap& g) {
            const GlobalMapStats s = g.read([](const GlobalMap& map) { return map.stats(); });
            return py::dict(py::arg("submaps") = s.submaps, py::arg("scans") = s.scans,
                            py::arg("features") = s.features, py::arg("bytes_per_feature") = s.bytes_per_feature());
          },
          "A dict: submaps, scans, features, bytes_per_feature")
      .def(
          "save",
          [](const PyGlobalMap& g, const std::filesystem::path& path) {
            g.read([&](const GlobalMap& map) { io::save_map(path.string(), map); });
          },
          py::arg("path"), py::call_guard<py::gil_scoped_release>(), "Saves the map (docs/map-format.md)")
      .def("__repr__", [](const PyGlobalMap& g) {
        return g.read([](const GlobalMap& map) {
          const GlobalMapStats st = map.stats();
          std::string text;
          io::append_format(text, "<lshloc.GlobalMap: %zu submaps, %zu scans, %zu features>", st.submaps, st.scans,
                            st.features);
          return text;
        });
      });
  m.def(
      "load_map",
      [](const std::filesystem::path& path) {
        io::LoadedMap loaded;
        {
          py::gil_scoped_release release;
          loaded = io::load_map(path.string());
        }
        // What lost nothing acknowledged (a torn last journal record) is a Python warning.
        for (const std::string& w : loaded.warnings)
          if (PyErr_WarnEx(PyExc_UserWarning, w.c_str(), 1) != 0) throw py::error_already_set();
        return PyGlobalMap{std::shared_ptr<GlobalMap>(std::move(loaded.map))};
      },
      py::arg("path"),
      "Loads a saved map (snapshot and journal); a torn last journal record is dropped with a UserWarning");

  m.def(
      "map_from_sources",
      [](const std::vector<std::string>& texts) {
        std::unique_ptr<GlobalMap> map;
        io::MapSourceMessages said;
        {
          py::gil_scoped_release release;
          RunConfig config;
          std::vector<io::MapSource> submaps;
          for (const std::string& text : texts) {
            const io::MapSource source = io::MapSource::parse(text);
            if (source.kind == io::MapSourceKind::kFleet)
              throw Error(text +
                          ": a fleet's live map needs `lshloc localize --map` or lshloc_ros_node (the Python "
                          "module follows no Redis map log)");
            if (source.kind != io::MapSourceKind::kSavedMap) {
              submaps.push_back(source);
              continue;
            }
            if (map) throw Error(text + ": only one saved map can be given");
            io::LoadedMap loaded = io::open_saved_map(source.path, config);
            said.warnings.insert(said.warnings.end(), loaded.warnings.begin(), loaded.warnings.end());
            map = std::move(loaded.map);
          }
          if (!map) map = std::make_unique<GlobalMap>(config.map);
          const io::MapSources added = io::add_map_sources(*map, submaps, false, {});
          said.warnings.insert(said.warnings.end(), added.messages.warnings.begin(), added.messages.warnings.end());
        }
        for (const std::string& w : said.warnings)
          if (PyErr_WarnEx(PyExc_UserWarning, w.c_str(), 1) != 0) throw py::error_already_set();
        return PyGlobalMap{std::shared_ptr<GlobalMap>(std::move(map))};
      },
      py::arg("sources"),
      "A GlobalMap from map sources in the grammar of `lshloc localize --map`: LOG, LOG,POSES, LOG,slam, "
      "MAP.yaml (a ROS occupancy grid), FILE.map (a saved map, at most one); one submap per log or grid, named "
      "after its file; what loading warns of is a UserWarning");

  py::class_<PyLocalizer>(m, "Localizer", "Localizes one target robot in a GlobalMap from no initial guess")
      .def(py::init([](const PyGlobalMap& map, const ConfigJson& config_json, const PoseTuple& laser_offset) {
             PyLocalizer l;
             const Pose2 offset = finite_pose(laser_offset, "laser_offset");
             const std::string text = config_text(config_json);
             l.localizer = map.read(
                 [&](const GlobalMap& g) { return std::make_unique<Localizer>(g, localizer_config(g, text, offset)); });
             l.map = map;
             return l;
           }),
           py::arg("map"), py::arg("config_json") = "", py::arg("laser_offset") = PoseTuple{0, 0, 0},
           "map: the GlobalMap (kept alive by the localizer); config_json: a JSON object (text or dict) of "
           "LocalizerConfig fields to change (the `localizer` part of `lshloc localize --print-config`; the feature "
           "settings are the map's); "
           "laser_offset: the target's laser pose (x, y, theta) on the robot, which its odometry moves")
      .def(
          "add_scan",
          [](PyLocalizer& l, const LaserScan& scan) {
            LocalizationEstimate e;
            std::string submap_name;
            {
              py::gil_scoped_release release;
              const std::lock_guard mine(*l.busy);
              l.map.read([&](const GlobalMap& map) {
                e = l.localizer->add_scan(scan);
                if (e.has_estimate) submap_name = map.submap_name(e.submap);
              });
            }
            py::dict d;
            d["has_estimate"] = e.has_estimate;
            d["localized"] = e.localized;
            d["confidence"] = e.confidence;
            d["stamp_clash"] = e.stamp_clash;
            d["confident"] = e.confident();
            d["submap"] = e.has_estimate ? py::cast(e.submap) : py::none();
            d["submap_name"] = e.has_estimate ? py::cast(submap_name) : py::none();
            d["pose"] = e.has_estimate ? py::cast(to_tuple(e.pose)) : py::none();
            // The robot's pose: the laser's with the mount (laser_offset) taken off, what a robot publishes.
            const Pose2 robot_from_laser = l.localizer->config().scan_matcher.laser_offset.inverse();
            d["robot_pose"] = e.has_estimate ? py::cast(to_tuple(e.pose * robot_from_laser)) : py::none();
            d["mean_score"] = e.mean_score;
            d["margin"] = e.margin;
            py::list because;
            for (const char* name : e.flag_down_because.names()) because.append(name);
            d["not_confident_because"] = because;
            return d;
          },
          py::arg("scan"),
          "Localizes one target scan (odometry in scan.odometry); returns a dict: has_estimate, localized "
          "(the confidence flag), confidence (the calibrated value in [0, 1]; at least flag_threshold, 0.9 by "
          "default, exactly when localized), stamp_clash (an earlier scan stamped "
          "within 5 ms is estimated elsewhere), confident (localized and no stamp clash: the pose can be used by "
          "its time stamp), submap, submap_name, pose (x, y, theta of the laser in the submap), robot_pose (the "
          "robot's: pose with the "
          "laser_offset taken off), mean_score (C/N of the best hypothesis), margin (its C/N lead over the best "
          "place elsewhere), "
          "not_confident_because (the parts of the flag's test that keep it down, by name: unstable, weak_support, "
          "few_points, look_alike, newest_misfit, young_hypothesis, contradicted; empty while it "
          "is up, and without an estimate)")
      .def(
          "stats",
          [](const PyLocalizer& l) {
            LocalizerStats s;
            {
              py::gil_scoped_release release;  // an add_scan on another thread may hold the localizer
              const std::lock_guard mine(*l.busy);
              s = l.localizer->stats();
            }
            return py::dict(py::arg("scans") = s.scans, py::arg("features") = s.features,
                            py::arg("hypotheses") = s.hypotheses, py::arg("data_points") = s.data_points,
                            py::arg("scan_matching_s") = s.scan_matching_s, py::arg("extract_s") = s.extract_s,
                            py::arg("query_s") = s.query_s, py::arg("ransac_s") = s.ransac_s,
                            py::arg("candidates_touched") = s.candidates_touched,
                            py::arg("us_query_per_feature") = s.us_query_per_feature());
          },
          "A dict of the localizer's counts and costs so far: scans, features (extracted), hypotheses, data_points "
          "(added to iRANSAC), scan_matching_s, extract_s, query_s, ransac_s (this thread's CPU seconds), "
          "candidates_touched (database entries read), us_query_per_feature")
      .def(
          "config_json", [](const PyLocalizer& l) { return io::json_text(nlohmann::json(l.localizer->config())); },
          "The settings the localizer runs with, as JSON (the map's descriptor settings, the laser_offset and "
          "config_json applied): the `localizer` shape `lshloc localize --print-config` writes");
}
