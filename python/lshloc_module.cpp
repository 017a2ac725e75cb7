// Python bindings (`import lshloc`): the global map, the localizer, the map
// store, CARMEN logs and ROS occupancy grids. Scans are numpy arrays of ranges with their beam
// angles; poses are (x, y, theta) tuples [m, m, rad]. The heavy calls
// (adding scans, localizing, loading and saving maps) release the GIL.
// Thread safety: as the C++ classes (docs/design.md section 5): a GlobalMap
// and the Localizers reading it belong to one thread at a time.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <memory>
#include <string>
#include <tuple>

#include "lshloc/common/error.hpp"
#include "lshloc/eval/scenario_runner.hpp"
#include "lshloc/io/carmen_reader.hpp"
#include "lshloc/io/scan_record.hpp"
#include "lshloc/io/config_json.hpp"
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

LaserScan make_scan(const py::array_t<float, py::array::c_style | py::array::forcecast>& ranges, double angle_min,
                    double angle_increment, double max_range, double timestamp, const PoseTuple& pose,
                    const PoseTuple& odometry) {
  if (ranges.ndim() != 1)
    throw Error("LaserScan: ranges must be a 1-D array, got " + std::to_string(ranges.ndim()) + "-D");
  LaserScan s;
  s.ranges.assign(ranges.data(), ranges.data() + ranges.size());
  s.angle_min = angle_min, s.angle_increment = angle_increment, s.max_range = max_range, s.timestamp = timestamp;
  s.pose = to_pose(pose), s.odometry = to_pose(odometry);
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

/// A localizer that keeps its map alive and knows its config.
struct PyLocalizer {
  std::shared_ptr<GlobalMap> map;
  std::unique_ptr<Localizer> localizer;
};

LocalizerConfig localizer_config(const GlobalMap& map, const std::string& config_json, const PoseTuple& laser_offset) {
  LocalizerConfig c;
  if (!config_json.empty()) io::apply_config_patch(nlohmann::json::parse(config_json), c, "config_json");
  c.features = map.config().features;  // the map's, as every command does
  return with_target_laser_offset(c, to_pose(laser_offset));
}

}  // namespace

PYBIND11_MODULE(lshloc, m) {
  m.doc() = "lshloc: global localization of 2D-laser robots in large, growing maps (LSH-RANSAC)";
  py::register_exception<Error>(m, "Error", PyExc_ValueError);

  py::class_<LaserScan>(m, "LaserScan", "One planar laser scan: ranges [m] at angle_min + i * angle_increment [rad]")
      .def(py::init(&make_scan), py::arg("ranges"), py::arg("angle_min"), py::arg("angle_increment"),
           py::arg("max_range") = 81.0, py::arg("timestamp") = 0.0, py::arg("pose") = PoseTuple{0, 0, 0},
           py::arg("odometry") = PoseTuple{0, 0, 0})
      .def_property_readonly("ranges",
                             [](const LaserScan& s) { return py::array_t<float>(s.ranges.size(), s.ranges.data()); })
      .def_property_readonly("angles",
                             [](const LaserScan& s) {
                               py::array_t<double> a(s.ranges.size());
                               auto v = a.mutable_unchecked<1>();
                               for (std::size_t i = 0; i < s.ranges.size(); ++i) v(i) = s.bearing(i);
                               return a;
                             })
      .def_readwrite("timestamp", &LaserScan::timestamp)
      .def_readwrite("max_range", &LaserScan::max_range)
      .def_property(
          "pose", [](const LaserScan& s) { return to_tuple(s.pose); },
          [](LaserScan& s, const PoseTuple& p) { s.pose = to_pose(p); }, "laser pose the log gives (x, y, theta)")
      .def_property(
          "odometry", [](const LaserScan& s) { return to_tuple(s.odometry); },
          [](LaserScan& s, const PoseTuple& p) { s.odometry = to_pose(p); });

  py::class_<io::CarmenLog>(m, "CarmenLog", "A CARMEN log in memory")
      .def_readonly("path", &io::CarmenLog::path)
      .def_readonly("scans", &io::CarmenLog::scans)
      .def_property_readonly("laser_offset", [](const io::CarmenLog& l) { return to_tuple(l.front_laser_offset()); })
      .def_property_readonly("gmapping_corrected", &io::CarmenLog::gmapping_corrected)
      .def_readonly("warnings", &io::CarmenLog::warnings,
                    "what the reader noticed (time stamps backwards or repeated, bytes after the gzip stream), "
                    "each naming the file and line");
  m.def(
      "read_carmen_log", [](const std::string& path) { return io::read_carmen_log(path); }, py::arg("path"),
      py::call_guard<py::gil_scoped_release>(), "Reads a CARMEN log (plain or .gz)");

  py::class_<OccupancyGrid>(m, "OccupancyGrid",
                            "An occupancy grid as nav_msgs has it: cells[row, col] is -1 (unknown), 0 (free) or 100 "
                            "(occupied), row 0 at the origin's y")
      .def(py::init([](const py::array_t<std::int8_t, py::array::c_style | py::array::forcecast>& cells,
                       double resolution, const PoseTuple& origin) {
             if (cells.ndim() != 2)
               throw Error("OccupancyGrid: cells must be a 2-D array (rows, columns), got " +
                           std::to_string(cells.ndim()) + "-D");
             OccupancyGrid g;
             g.resolution = resolution;
             g.origin = {std::get<0>(origin), std::get<1>(origin)};
             g.origin_yaw = std::get<2>(origin);
             g.height = static_cast<std::size_t>(cells.shape(0)), g.width = static_cast<std::size_t>(cells.shape(1));
             g.cells.assign(cells.data(), cells.data() + cells.size());
             for (std::int8_t& v : g.cells)
               if (v != occupancy::kFree && v != occupancy::kOccupied) v = occupancy::kUnknown;
             if (!(resolution > 0.0)) throw Error("OccupancyGrid: resolution must be > 0 m");
             return g;
           }),
           py::arg("cells"), py::arg("resolution"), py::arg("origin") = PoseTuple{0, 0, 0},
           "cells: 2-D int8 array; values other than 0 and 100 read as unknown")
      .def_readonly("resolution", &OccupancyGrid::resolution)
      .def_property_readonly("origin",
                             [](const OccupancyGrid& g) {
                               return PoseTuple{g.origin.x(), g.origin.y(), g.origin_yaw};
                             })
      .def_property_readonly("cells", [](const OccupancyGrid& g) {
        return py::array_t<std::int8_t>({g.height, g.width}, g.cells.data());
      });
  m.def(
      "read_ros_map", [](const std::string& path) { return io::read_ros_map(path); }, py::arg("yaml_path"),
      py::call_guard<py::gil_scoped_release>(), "Reads a ROS map_server map (MAP.yaml and its PGM)");
  m.def(
      "write_ros_map", [](const std::string& stem, const OccupancyGrid& g) { io::write_ros_map(stem, g); },
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

  py::class_<GlobalMap, std::shared_ptr<GlobalMap>>(m, "GlobalMap",
                                                    "The global map mapper robots feed, one scan at a time")
      .def(py::init([](const std::string& config_json) {
             GlobalMapConfig c;
             if (!config_json.empty()) io::apply_config_patch(nlohmann::json::parse(config_json), c, "config_json");
             return std::make_shared<GlobalMap>(c);
           }),
           py::arg("config_json") = "")
      .def("add_submap", &GlobalMap::add_submap, py::arg("name"), "Opens a new submap; returns its id")
      .def(
          "add_scan",
          [](GlobalMap& g, std::uint32_t submap, const LaserScan& scan, const PoseTuple& pose) {
            return g.add_scan(submap, scan, to_pose(pose));
          },
          py::arg("submap"), py::arg("scan"), py::arg("laser_pose"), py::call_guard<py::gil_scoped_release>(),
          "Adds a mapper scan at its laser pose in the submap's frame; returns the features it added")
      .def(
          "add_grid_submap",
          [](GlobalMap& g, const std::string& name, const OccupancyGrid& grid, double pose_spacing,
             std::size_t headings, std::size_t beams, double field_of_view, double max_range) {
            GridSubmapConfig c;
            c.pose_spacing = pose_spacing, c.headings = headings, c.beams = beams, c.field_of_view = field_of_view,
            c.max_range = max_range;
            GridSubmapStats st;
            std::uint32_t id = 0;
            {
              py::gil_scoped_release release;
              id = g.add_submap(name);
              st = add_grid_submap(g, id, grid, c);
            }
            return py::make_tuple(
                id, py::dict(py::arg("positions") = st.positions, py::arg("virtual_scans") = st.virtual_scans,
                             py::arg("features") = st.features, py::arg("cpu_s") = st.cpu_s));
          },
          py::arg("name"), py::arg("grid"), py::arg("pose_spacing") = GridSubmapConfig{}.pose_spacing,
          py::arg("headings") = GridSubmapConfig{}.headings, py::arg("beams") = GridSubmapConfig{}.beams,
          py::arg("field_of_view") = GridSubmapConfig{}.field_of_view,
          py::arg("max_range") = GridSubmapConfig{}.max_range,
          "Adds a submap built from an occupancy grid (virtual scans of the given laser from free positions); "
          "returns (submap id, stats)")
      .def_property_readonly("submap_count", &GlobalMap::submap_count)
      .def("submap_name", &GlobalMap::submap_name, py::arg("submap"))
      .def("submap_scans", &GlobalMap::submap_scans, py::arg("submap"))
      .def("stats",
           [](const GlobalMap& g) {
             const GlobalMapStats s = g.stats();
             return py::dict(py::arg("submaps") = s.submaps, py::arg("scans") = s.scans,
                             py::arg("features") = s.features, py::arg("bytes_per_feature") = s.bytes_per_feature());
           })
      .def(
          "save", [](const GlobalMap& g, const std::string& path) { io::save_map(path, g); }, py::arg("path"),
          py::call_guard<py::gil_scoped_release>(), "Saves the map (docs/map-format.md)");
  m.def(
      "load_map",
      [](const std::string& path) {
        io::LoadedMap loaded = io::load_map(path);
        return std::shared_ptr<GlobalMap>(std::move(loaded.map));
      },
      py::arg("path"), py::call_guard<py::gil_scoped_release>(), "Loads a saved map (snapshot and journal)");

  py::class_<PyLocalizer>(m, "Localizer", "Localizes one target robot in a GlobalMap from no initial guess")
      .def(py::init([](std::shared_ptr<GlobalMap> map, const std::string& config_json, const PoseTuple& laser_offset) {
             PyLocalizer l;
             l.localizer = std::make_unique<Localizer>(*map, localizer_config(*map, config_json, laser_offset));
             l.map = std::move(map);
             return l;
           }),
           py::arg("map"), py::arg("config_json") = "", py::arg("laser_offset") = PoseTuple{0, 0, 0})
      .def(
          "add_scan",
          [](PyLocalizer& l, const LaserScan& scan) {
            LocalizationEstimate e;
            {
              py::gil_scoped_release release;
              e = l.localizer->add_scan(scan);
            }
            py::dict d;
            d["has_estimate"] = e.has_estimate;
            d["localized"] = e.localized;
            d["confidence"] = e.confidence;
            d["submap"] = e.has_estimate ? py::cast(e.submap) : py::none();
            d["submap_name"] = e.has_estimate ? py::cast(l.map->submap_name(e.submap)) : py::none();
            d["pose"] = e.has_estimate ? py::cast(to_tuple(e.pose)) : py::none();
            d["mean_score"] = e.mean_score;
            d["margin"] = e.margin;
            return d;
          },
          py::arg("scan"),
          "Localizes one target scan (odometry in scan.odometry); returns a dict: has_estimate, localized "
          "(the confidence flag), confidence (the calibrated value in [0, 1]), submap, submap_name, pose (x, y, theta "
          "of the laser in the submap), mean_score, margin");
}
