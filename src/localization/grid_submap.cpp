#include "lshloc/localization/grid_submap.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <limits>
#include <vector>

#include "lshloc/common/cpu_time.hpp"
#include "lshloc/common/error.hpp"

namespace lshloc {

void GridSubmapConfig::validate() const {
  require(pose_spacing > 0.0 && std::isfinite(pose_spacing), "GridSubmapConfig.pose_spacing", "> 0 m", pose_spacing);
  require(headings >= 1 && headings <= 360, "GridSubmapConfig.headings", "in 1..360", headings);
  require(clearance >= 0.0 && std::isfinite(clearance), "GridSubmapConfig.clearance", ">= 0 m", clearance);
  require(beams >= 2 && beams <= 100000, "GridSubmapConfig.beams", "in 2..100000", beams);
  require(field_of_view > 0.0 && field_of_view <= 2.0 * std::numbers::pi, "GridSubmapConfig.field_of_view",
          "in (0, 2 pi] rad", field_of_view);
  require(max_range > 0.0 && max_range <= 1000.0, "GridSubmapConfig.max_range", "in (0, 1000] m", max_range);
  require(free_margin >= 0.0 && std::isfinite(free_margin), "GridSubmapConfig.free_margin", ">= 0 m", free_margin);
  require(normal_radius > 0.0 && normal_radius <= 10.0, "GridSubmapConfig.normal_radius", "in (0, 10] m",
          normal_radius);
  require(max_virtual_scans >= 1, "GridSubmapConfig.max_virtual_scans", ">= 1", max_virtual_scans);
}

GridSubmapConfig with_laser_of(GridSubmapConfig config, const LaserScan& like) {
  if (like.size() >= 2) {
    config.beams = like.size();
    config.field_of_view = std::abs(like.angle_increment) * static_cast<double>(like.size() - 1);
  }
  if (like.max_range > 0.0 && std::isfinite(like.max_range)) config.max_range = std::min(like.max_range, 1000.0);
  return config;
}

namespace {

/// Per-cell distances [cells] to the nearest cell matching a predicate, by a
/// two-pass chamfer transform (steps 1 and sqrt 2: within 8% of Euclidean).
/// Cells beyond the grid's edge count as matching when `edge_matches`.
template <class Matches>
std::vector<float> chamfer_distance(const OccupancyGrid& g, Matches matches, bool edge_matches) {
  const std::size_t w = g.width, h = g.height;
  constexpr float kFar = std::numeric_limits<float>::max() / 4, kDiagonal = 1.41421356f;
  std::vector<float> d(w * h);
  for (std::size_t r = 0; r < h; ++r) {
    for (std::size_t c = 0; c < w; ++c) {
      float v = matches(g.at(c, r)) ? 0.0f : kFar;
      if (edge_matches) {
        const auto to_edge = static_cast<float>(std::min(std::min(c, w - 1 - c), std::min(r, h - 1 - r)) + 1);
        v = std::min(v, to_edge);
      }
      d[r * w + c] = v;
    }
  }
  const auto relax = [&](std::size_t c, std::size_t r, long dc, long dr, float step) {
    const long cc = static_cast<long>(c) + dc, rr = static_cast<long>(r) + dr;
    if (cc < 0 || rr < 0 || cc >= static_cast<long>(w) || rr >= static_cast<long>(h)) return;
    float& here = d[r * w + c];
    here = std::min(here, d[static_cast<std::size_t>(rr) * w + static_cast<std::size_t>(cc)] + step);
  };
  for (std::size_t r = 0; r < h; ++r) {
    for (std::size_t c = 0; c < w; ++c) {
      relax(c, r, -1, 0, 1.0f), relax(c, r, 0, -1, 1.0f), relax(c, r, -1, -1, kDiagonal), relax(c, r, 1, -1, kDiagonal);
    }
  }
  for (std::size_t r = h; r-- > 0;) {
    for (std::size_t c = w; c-- > 0;) {
      relax(c, r, 1, 0, 1.0f), relax(c, r, 0, 1, 1.0f), relax(c, r, 1, 1, kDiagonal), relax(c, r, -1, 1, kDiagonal);
    }
  }
  return d;
}

/// Range [m] along the unit vector (dx, dy) from `o` (grid frame, metres),
/// or `max_range` for a no-return. Amanatides-Woo traversal of the cells.
double cast_ray(const OccupancyGrid& g, const Point2& o, double dx, double dy, double max_range) {
  const double ox = o.x() / g.resolution, oy = o.y() / g.resolution;
  long cx = static_cast<long>(std::floor(ox)), cy = static_cast<long>(std::floor(oy));
  const long w = static_cast<long>(g.width), h = static_cast<long>(g.height);
  const double inf = std::numeric_limits<double>::infinity();
  const long step_x = dx > 0 ? 1 : -1, step_y = dy > 0 ? 1 : -1;
  const double delta_x = dx != 0 ? 1.0 / std::abs(dx) : inf, delta_y = dy != 0 ? 1.0 / std::abs(dy) : inf;
  double next_x =
      dx != 0 ? (dx > 0 ? (static_cast<double>(cx) + 1 - ox) : (ox - static_cast<double>(cx))) * delta_x : inf;
  double next_y =
      dy != 0 ? (dy > 0 ? (static_cast<double>(cy) + 1 - oy) : (oy - static_cast<double>(cy))) * delta_y : inf;
  const double limit = max_range / g.resolution;
  double entry = 0.0;
  while (entry < limit && cx >= 0 && cy >= 0 && cx < w && cy < h) {
    const std::int8_t v = g.cells[static_cast<std::size_t>(cy * w + cx)];
    if (v == occupancy::kOccupied) {
      // The wall lies somewhere in the cell: its centre's distance along the ray.
      const double along = (static_cast<double>(cx) + 0.5 - ox) * dx + (static_cast<double>(cy) + 0.5 - oy) * dy;
      const double range = std::max(entry, along) * g.resolution;
      return range < max_range ? range : max_range;
    }
    if (v == occupancy::kUnknown) break;
    if (next_x < next_y) {
      entry = next_x, next_x += delta_x, cx += step_x;
    } else {
      entry = next_y, next_y += delta_y, cy += step_y;
    }
  }
  return max_range;
}

}  // namespace

LaserScan cast_virtual_scan(const OccupancyGrid& grid, const Pose2& laser_pose, const GridSubmapConfig& config) {
  LaserScan scan;
  scan.max_range = config.max_range;
  scan.angle_increment = config.field_of_view / static_cast<double>(config.beams - 1);
  if (config.field_of_view >= 2.0 * std::numbers::pi - 1e-9)
    scan.angle_increment = config.field_of_view / static_cast<double>(config.beams);  // no beam twice
  scan.angle_min = -0.5 * scan.angle_increment * static_cast<double>(config.beams - 1);
  scan.pose = laser_pose;
  scan.odometry = laser_pose;
  scan.ranges.resize(config.beams);
  const Pose2 in_grid = grid.origin_pose().inverse() * laser_pose;
  for (std::size_t i = 0; i < config.beams; ++i) {
    const double a = in_grid.theta + scan.bearing(i);
    scan.ranges[i] =
        static_cast<float>(cast_ray(grid, in_grid.translation(), std::cos(a), std::sin(a), config.max_range));
  }
  return scan;
}

namespace {

/// add_grid_submap() into the submap `open_submap` returns, called once
/// every check has passed: a grid or config that cannot make a submap
/// throws before the map changes.
GridSubmapStats fill_grid_submap(GlobalMap& map, const std::function<std::uint32_t()>& open_submap,
                                 const std::string& name, const OccupancyGrid& grid, const GridSubmapConfig& config) {
  config.validate();
  if (grid.width == 0 || grid.height == 0 || grid.cells.size() != grid.width * grid.height)
    throw Error("occupancy grid " + name + ": expected width x height cells, got " + std::to_string(grid.cells.size()));
  if (!(grid.resolution > 0.0) || !std::isfinite(grid.resolution) || !std::isfinite(grid.origin.x()) ||
      !std::isfinite(grid.origin.y()) || !std::isfinite(grid.origin_yaw))
    throw Error("occupancy grid " + name + ": expected a finite resolution > 0 m and a finite origin");
  const CpuStopwatch total;
  GridSubmapStats stats;
  const Pose2 origin = grid.origin_pose();
  const double res = grid.resolution;
  const std::size_t w = grid.width, h = grid.height;

  // Virtual laser positions: lattice points in free cells with clearance
  // from walls, unknown cells and the grid's edge.
  const std::vector<float> to_blocked = chamfer_distance(
      grid, [](std::int8_t v) { return v != occupancy::kFree; }, true);
  const auto columns = static_cast<std::size_t>(static_cast<double>(w) * res / config.pose_spacing) + 1;
  const auto row_count = static_cast<std::size_t>(static_cast<double>(h) * res / config.pose_spacing) + 1;
  const auto free_position = [&](std::size_t i, std::size_t j, Point2& p) {
    p = Point2((static_cast<double>(i) + 0.5) * config.pose_spacing,
               (static_cast<double>(j) + 0.5) * config.pose_spacing);
    const auto c = static_cast<std::size_t>(p.x() / res), r = static_cast<std::size_t>(p.y() / res);
    return c < w && r < h && grid.at(c, r) == occupancy::kFree &&
           static_cast<double>(to_blocked[r * w + c]) * res >= config.clearance;
  };
  // Counted before any is stored: a huge extent (a wrong resolution) is refused before it takes memory.
  Point2 position;
  for (std::size_t j = 0; j < row_count; ++j)
    for (std::size_t i = 0; i < columns; ++i) stats.positions += free_position(i, j, position);
  if (stats.positions == 0)
    throw Error("occupancy grid " + name + ": no free position " + std::to_string(config.clearance) +
                " m from occupied and unknown cells on a " + std::to_string(config.pose_spacing) + " m lattice");
  if (stats.positions * config.headings > config.max_virtual_scans)
    throw Error("occupancy grid " + name + ": " + std::to_string(stats.positions * config.headings) +
                " virtual scans exceed GridSubmapConfig.max_virtual_scans (" +
                std::to_string(config.max_virtual_scans) +
                "); use a wider pose_spacing or fewer headings (the "
                "commands' --grid-spacing, --grid-headings)");
  std::vector<std::vector<Point2>> rows;
  for (std::size_t j = 0; j < row_count; ++j) {
    std::vector<Point2> row;
    for (std::size_t i = 0; i < columns; ++i)
      if (free_position(i, j, position)) row.push_back(position);
    if (j % 2 == 1) std::reverse(row.begin(), row.end());  // boustrophedon: neighbours follow each other
    rows.push_back(std::move(row));
  }
  // Every cell the submap marks lies within the grid's rectangle: its corners must fit the map's pose grids
  // (cells within +-2^16 of their origin), or marking would fail with the submap half-built.
  for (const Point2& corner :
       {Point2(0.0, 0.0), Point2(static_cast<double>(w) * res, 0.0), Point2(0.0, static_cast<double>(h) * res),
        Point2(static_cast<double>(w) * res, static_cast<double>(h) * res)}) {
    const Point2 p = origin.transform(corner);
    const PoseCell wall = map.occupancy().cell_of(0, p.x(), p.y(), 0.0),
                   free = map.free_space().cell_of(0, p.x(), p.y());
    if (PoseGridHashMap::pack_xy(0, wall.ix, wall.iy) == PoseGridHashMap::kInvalidXy ||
        PoseGridHashMap::pack_xy(0, free.ix, free.iy) == PoseGridHashMap::kInvalidXy)
      throw Error("occupancy grid " + name + ": its corner at x " + std::to_string(p.x()) + " m, y " +
                  std::to_string(p.y()) + " m lies beyond the map's pose grids (about " +
                  std::to_string(static_cast<int>(map.config().occupancy.cell_size * (1 << 16) / 1000.0)) +
                  " km from the origin); give the grid an origin near 0 (e.g. shift a UTM-framed map)");
  }
  const std::uint32_t submap = open_submap();

  for (std::size_t k = 0; k < config.headings; ++k) {
    const double heading = 2.0 * std::numbers::pi * static_cast<double>(k) / static_cast<double>(config.headings);
    for (const std::vector<Point2>& row : rows) {
      for (const Point2& p : row) {
        const Pose2 pose = origin * Pose2(p.x(), p.y(), heading);
        const CpuStopwatch cast;
        LaserScan scan = cast_virtual_scan(grid, pose, config);
        stats.cast_s += cast.seconds();
        scan.timestamp = static_cast<double>(stats.virtual_scans++);
        stats.features += map.add_scan(submap, scan, pose, GlobalMap::ScanGrids::kSkip);
      }
    }
  }

  // The pose grid: occupied cells next to free ones, with the normal of the
  // wall's direction (a fit over nearby occupied cells) on each side that
  // faces free space.
  const auto occupied = [&](long c, long r) {
    return c >= 0 && r >= 0 && c < static_cast<long>(w) && r < static_cast<long>(h) &&
           grid.at(static_cast<std::size_t>(c), static_cast<std::size_t>(r)) == occupancy::kOccupied;
  };
  const auto free_at = [&](const Point2& q) {
    std::size_t c = 0, r = 0;
    return grid.cell_of_in_grid(q, c, r) && grid.at(c, r) == occupancy::kFree;
  };
  const long window = std::max(1L, static_cast<long>(std::ceil(config.normal_radius / res)));
  const double window2 = static_cast<double>(window * window);
  const std::vector<float> to_occupied = chamfer_distance(
      grid, [](std::int8_t v) { return v == occupancy::kOccupied; }, false);
  for (std::size_t r = 0; r < h; ++r) {
    for (std::size_t c = 0; c < w; ++c) {
      const std::int8_t v = grid.at(c, r);
      const Point2 centre = grid.cell_centre_in_grid(c, r);
      if (v == occupancy::kFree) {
        if (static_cast<double>(to_occupied[r * w + c]) * res >= config.free_margin) {
          map.mark_free(submap, origin.transform(centre));
          ++stats.free_cells;
        }
        continue;
      }
      if (v != occupancy::kOccupied) continue;
      ++stats.occupied_cells;
      map.mark_return(submap, origin.transform(centre));
      Point2 free_sum(0.0, 0.0);
      int free_neighbours = 0;
      for (long dr = -1; dr <= 1; ++dr) {
        for (long dc = -1; dc <= 1; ++dc) {
          const long cc = static_cast<long>(c) + dc, rr = static_cast<long>(r) + dr;
          if (cc >= 0 && rr >= 0 && cc < static_cast<long>(w) && rr < static_cast<long>(h) &&
              grid.at(static_cast<std::size_t>(cc), static_cast<std::size_t>(rr)) == occupancy::kFree) {
            free_sum += Point2(static_cast<double>(dc), static_cast<double>(dr));
            ++free_neighbours;
          }
        }
      }
      if (free_neighbours == 0) continue;  // inside a wall, or seen only from unknown space
      double sxx = 0, syy = 0, sxy = 0, n = 0;
      for (long dr = -window; dr <= window; ++dr) {
        for (long dc = -window; dc <= window; ++dc) {
          if (static_cast<double>(dr * dr + dc * dc) > window2 ||
              !occupied(static_cast<long>(c) + dc, static_cast<long>(r) + dr))
            continue;
          sxx += static_cast<double>(dc * dc), syy += static_cast<double>(dr * dr), sxy += static_cast<double>(dc * dr);
          n += 1;
        }
      }
      std::array<double, 2> normals{};
      std::size_t count = 0;
      // The occupied cells' principal direction (about the cell itself); a
      // blob with none (a lone cell, a square) faces its free neighbours.
      const double spread = std::hypot(sxx - syy, 2.0 * sxy);
      if (n >= 3 && spread > 0.25 * (sxx + syy)) {
        const double tangent = 0.5 * std::atan2(2.0 * sxy, sxx - syy);
        for (const double normal : {tangent + 0.5 * std::numbers::pi, tangent - 0.5 * std::numbers::pi}) {
          const Point2 step(std::cos(normal) * res, std::sin(normal) * res);
          if (free_at(centre + step) || free_at(centre + 2.0 * step)) normals[count++] = normal;
        }
      }
      if (count == 0) normals[count++] = std::atan2(free_sum.y(), free_sum.x());
      for (std::size_t k = 0; k < count; ++k) {
        map.mark_surface_point(submap, origin.transform(centre), origin.transform_angle(normals[k]));
        ++stats.surface_marks;
      }
    }
  }
  stats.cpu_s = total.seconds();
  return stats;
}

}  // namespace

GridSubmapStats add_grid_submap(GlobalMap& map, std::uint32_t submap, const OccupancyGrid& grid,
                                const GridSubmapConfig& config) {
  const std::string name = submap < map.submap_count() ? map.submap_name(submap) : std::to_string(submap);
  if (submap >= map.submap_count() || map.submap_scans(submap) != 0)
    throw Error("occupancy grid for submap " + name + ": expected a new, empty submap of the map");
  return fill_grid_submap(
      map, [submap] { return submap; }, name, grid, config);
}

std::uint32_t add_grid_as_new_submap(GlobalMap& map, const std::string& name, const OccupancyGrid& grid,
                                     const GridSubmapConfig& config, GridSubmapStats* stats) {
  std::uint32_t id = 0;
  const GridSubmapStats st = fill_grid_submap(
      map, [&] { return id = map.add_submap(name); }, name, grid, config);
  if (stats) *stats = st;
  return id;
}

}  // namespace lshloc
