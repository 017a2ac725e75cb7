// Each config refuses an out-of-range field where it is used, naming the
// struct and the field: never a silently empty result or an undefined cast.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "lshloc/common/error.hpp"
#include "lshloc/eval/place_recall.hpp"
#include "lshloc/geometry/oriented_endpoints.hpp"
#include "lshloc/sim/floor_plan.hpp"
#include "lshloc/sim/ray_caster.hpp"
#include "lshloc/sim/sensors.hpp"
#include "lshloc/sim/trajectory.hpp"
#include "lshloc/slam/relations_metric.hpp"

namespace lshloc {
namespace {

/// The message `fn` throws (empty when it does not).
std::string error_of(const std::function<void()>& fn) {
  try {
    fn();
  } catch (const Error& e) {
    return e.what();
  }
  return {};
}

template <class Config>
void expect_refused(Config config, const std::function<void(Config&)>& spoil, const std::string& field) {
  EXPECT_NO_THROW(config.validate()) << field;
  spoil(config);
  const std::string what = error_of([&] { config.validate(); });
  EXPECT_NE(what.find(field + ": expected"), std::string::npos) << "wanted " << field << ", got: " << what;
}

constexpr double kNan = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

TEST(ConfigValidation, EachConfigNamesTheFieldOutOfRange) {
  expect_refused<OrientedEndpointConfig>(
      {}, [](auto& c) { c.min_points = -1; }, "OrientedEndpointConfig.min_points");
  expect_refused<OrientedEndpointConfig>(
      {}, [](auto& c) { c.normal_radius = kNan; }, "OrientedEndpointConfig.normal_radius");
  expect_refused<RelationsMetricConfig>(
      {}, [](auto& c) { c.time_tolerance = kNan; }, "RelationsMetricConfig.time_tolerance");
  expect_refused<PlaceRecallConfig>(
      {}, [](auto& c) { c.match_distance = 0.0; }, "PlaceRecallConfig.match_distance");
  expect_refused<PlaceRecallConfig>(
      {}, [](auto& c) { c.k = 0; }, "PlaceRecallConfig.k");
  expect_refused<sim::FloorPlanConfig>(
      {}, [](auto& c) { c.hall_probability = 1.5; }, "FloorPlanConfig.hall_probability");
  expect_refused<sim::FloorPlanConfig>(
      {}, [](auto& c) { c.max_size = c.min_size - 1.0; }, "FloorPlanConfig.max_size");
  expect_refused<sim::TrajectoryConfig>(
      {}, [](auto& c) { c.turn_rate = kInf; }, "TrajectoryConfig.turn_rate");
  expect_refused<sim::TrajectoryConfig>(
      {}, [](auto& c) { c.goal_choices = 0; }, "TrajectoryConfig.goal_choices");
  expect_refused<sim::LaserConfig>(
      {}, [](auto& c) { c.dropout_probability = 2.0; }, "LaserConfig.dropout_probability");
  expect_refused<sim::LaserConfig>(
      {}, [](auto& c) { c.beams = 1; }, "LaserConfig.beams");
  expect_refused<sim::RayCasterConfig>(
      {}, [](auto& c) { c.cell = 0.0; }, "RayCasterConfig.cell");
}

TEST(ConfigValidation, TheFunctionsThatTakeAConfigCheckIt) {
  LaserScan scan;
  scan.ranges.assign(10, 1.0f);
  OrientedEndpointConfig negative;
  negative.min_points = -3;  // a huge size_t once cast: every endpoint would be dropped
  EXPECT_NE(error_of([&] { oriented_endpoints(scan, negative); }).find("OrientedEndpointConfig.min_points"),
            std::string::npos);
  sim::LaserConfig one_beam;
  one_beam.beams = 1;
  EXPECT_NE(error_of([&] { sim::set_beam_layout(one_beam, scan); }).find("LaserConfig.beams"), std::string::npos);
  sim::RayCasterConfig no_cell;
  no_cell.cell = kNan;
  EXPECT_NE(error_of([&] { sim::RayCaster caster({}, no_cell); }).find("RayCasterConfig.cell"), std::string::npos);
  RelationsMetricConfig no_tolerance;
  no_tolerance.time_tolerance = -1.0;
  EXPECT_NE(error_of([&] { relation_errors({}, {}, no_tolerance); }).find("RelationsMetricConfig.time_tolerance"),
            std::string::npos);
}

}  // namespace
}  // namespace lshloc
