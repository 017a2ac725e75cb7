#include "lshloc/slam/occupancy_grid.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "lshloc/common/error.hpp"

namespace lshloc {

void OccupancyGridConfig::validate() const {
  require(resolution > 0.0 && std::isfinite(resolution), "OccupancyGridConfig.resolution", "> 0 m", resolution);
  require(max_range > min_range, "OccupancyGridConfig.max_range", "> min_range", max_range);
  require(min_range >= 0.0, "OccupancyGridConfig.min_range", ">= 0 m", min_range);
  require(occupied_at > 0.0 && occupied_at <= 1.0, "OccupancyGridConfig.occupied_at", "in (0, 1]", occupied_at);
  require(free_below >= 0.0 && free_below <= occupied_at, "OccupancyGridConfig.free_below", "in [0, occupied_at]",
          free_below);
  require(margin >= 0.0, "OccupancyGridConfig.margin", ">= 0 m", margin);
}

bool OccupancyGrid::cell_of(const Point2& p, std::size_t& col, std::size_t& row) const {
  return cell_of_in_grid(origin_yaw == 0.0 ? Point2(p - origin) : origin_pose().inverse().transform(p), col, row);
}

bool OccupancyGrid::cell_of_in_grid(const Point2& q, std::size_t& col, std::size_t& row) const {
  const double c = std::floor(q.x() / resolution), r = std::floor(q.y() / resolution);
  if (!(c >= 0 && r >= 0 && c < static_cast<double>(width) && r < static_cast<double>(height))) return false;
  col = static_cast<std::size_t>(c), row = static_cast<std::size_t>(r);
  return true;
}

OccupancyGrid build_occupancy_grid(std::span<const LaserScan> scans, const OccupancyGridConfig& config) {
  config.validate();
  const auto usable = [&](const LaserScan& s, std::size_t i) {
    return s.status(i) == BeamStatus::kValid && s.ranges[i] >= config.min_range && s.ranges[i] < config.max_range;
  };
  // The extent: every sensor and every used endpoint, plus the margin.
  double x0 = std::numeric_limits<double>::infinity(), y0 = x0, x1 = -x0, y1 = -x0;
  std::size_t returns = 0;
  for (const LaserScan& s : scans) {
    const Point2 sensor = s.pose.translation();
    x0 = std::min(x0, sensor.x()), x1 = std::max(x1, sensor.x()), y0 = std::min(y0, sensor.y()),
    y1 = std::max(y1, sensor.y());
    for (std::size_t i = 0; i < s.size(); ++i) {
      if (!usable(s, i)) continue;
      const Point2 p = s.pose.transform(s.endpoint(i));
      x0 = std::min(x0, p.x()), x1 = std::max(x1, p.x()), y0 = std::min(y0, p.y()), y1 = std::max(y1, p.y());
      ++returns;
    }
  }
  if (returns == 0) throw Error("occupancy grid: the scans have no valid return within the range limits");
  OccupancyGrid g;
  g.resolution = config.resolution;
  g.origin = {std::floor((x0 - config.margin) / config.resolution) * config.resolution,
              std::floor((y0 - config.margin) / config.resolution) * config.resolution};
  const double w = std::ceil((x1 + config.margin - g.origin.x()) / config.resolution) + 1;
  const double h = std::ceil((y1 + config.margin - g.origin.y()) / config.resolution) + 1;
  if (w * h > static_cast<double>(1u << 28))
    throw Error("occupancy grid: " + std::to_string(static_cast<long long>(w)) + " x " +
                std::to_string(static_cast<long long>(h)) + " cells exceed 2^28; use a coarser resolution");
  g.width = static_cast<std::size_t>(w), g.height = static_cast<std::size_t>(h);
  std::vector<std::uint32_t> hits(g.width * g.height, 0), misses(g.width * g.height, 0);
  for (const LaserScan& s : scans) {
    const Point2 sensor = s.pose.translation();
    for (std::size_t i = 0; i < s.size(); ++i) {
      if (!usable(s, i)) continue;
      const Point2 p = s.pose.transform(s.endpoint(i));
      // The cells the ray crosses before its end, sampled at half a cell.
      const Point2 d = p - sensor;
      const double length = d.norm();
      const auto steps = static_cast<std::size_t>(length / (0.5 * config.resolution));
      std::size_t end_col = 0, end_row = 0;
      if (!g.cell_of(p, end_col, end_row)) continue;  // (a non-finite pose: no cell)
      std::size_t last = std::numeric_limits<std::size_t>::max();
      for (std::size_t k = 0; k < steps; ++k) {
        std::size_t c = 0, r = 0;
        if (!g.cell_of(sensor + d * (static_cast<double>(k) / static_cast<double>(steps)), c, r)) continue;
        const std::size_t cell = r * g.width + c;
        if (cell == last || (c == end_col && r == end_row)) continue;
        ++misses[cell];
        last = cell;
      }
      ++hits[end_row * g.width + end_col];
    }
  }
  g.cells.assign(g.width * g.height, occupancy::kUnknown);
  for (std::size_t k = 0; k < g.cells.size(); ++k) {
    const double n = hits[k] + misses[k];
    if (n == 0) continue;
    const double p = hits[k] / n;
    if (p >= config.occupied_at)
      g.cells[k] = occupancy::kOccupied;
    else if (p < config.free_below)
      g.cells[k] = occupancy::kFree;
  }
  return g;
}

}  // namespace lshloc
