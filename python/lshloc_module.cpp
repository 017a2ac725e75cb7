// Python bindings (`import lshloc`): the global map, the localizer, the map
// store and CARMEN logs. Scans are numpy arrays of ranges with their beam
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
#include "lshloc/io/config_json.hpp"
#include "lshloc/io/map_store.hpp"
#include "lshloc/localization/global_map.hpp"
#include "lshloc/localization/localizer.hpp"

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
      .def_property_readonly("gmapping_corrected", &io::CarmenLog::gmapping_corrected);
  m.def(
      "read_carmen_log", [](const std::string& path) { return io::read_carmen_log(path); }, py::arg("path"),
      py::call_guard<py::gil_scoped_release>(), "Reads a CARMEN log (plain or .gz)");

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
            d["submap"] = e.has_estimate ? py::cast(e.submap) : py::none();
            d["submap_name"] = e.has_estimate ? py::cast(l.map->submap_name(e.submap)) : py::none();
            d["pose"] = e.has_estimate ? py::cast(to_tuple(e.pose)) : py::none();
            d["mean_score"] = e.mean_score;
            d["margin"] = e.margin;
            return d;
          },
          py::arg("scan"),
          "Localizes one target scan (odometry in scan.odometry); returns a dict: has_estimate, localized "
          "(confident), submap, submap_name, pose (x, y, theta of the laser in the submap), mean_score, margin");
}
