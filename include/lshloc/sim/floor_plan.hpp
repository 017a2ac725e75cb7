#pragma once
// Procedural office floor plans for the simulator: rooms, corridors, halls,
// doors, pillars and clutter, all as line segments in one building frame.
// Lengths [m] in the building frame; probabilities and counts unitless.
// Thread safety: generate_floor_plan draws only from config.seed and is safe
// from any thread; a FloorPlan is a plain value (const methods may run
// concurrently while nobody mutates it).
#include <cmath>
#include <cstdint>
#include <vector>

#include "lshloc/geometry/pose2.hpp"

namespace lshloc::sim {

/// One straight obstacle edge: a wall face, a pillar side or a furniture side.
/// Walls have no thickness; a laser sees a segment from both sides.
struct Segment {
  Point2 a = Point2::Zero();  ///< [m] first end
  Point2 b = Point2::Zero();  ///< [m] second end
};

/// An axis-aligned rectangle [x0, x1] x [y0, y1] [m].
struct Rect {
  double x0 = 0.0, y0 = 0.0, x1 = 0.0, y1 = 0.0;
  double width() const { return x1 - x0; }
  double height() const { return y1 - y0; }
  Point2 centre() const { return {(x0 + x1) / 2.0, (y0 + y1) / 2.0}; }
};

enum class RegionKind : std::uint8_t {
  kCorridor,  ///< part of the connected corridor network
  kRoom,      ///< an office, possibly with furniture
  kHall,      ///< a large open room with a grid of pillars
};

/// A free region of the plan: a room, a hall or one straight corridor.
struct Region {
  RegionKind kind = RegionKind::kRoom;
  Rect bounds;
  bool reachable = true;  ///< false: no door leads in (a closed room)
};

/// A gap in a wall between two regions.
struct Door {
  Point2 centre = Point2::Zero();  ///< [m]
  double width = 0.0;              ///< [m] free opening
  bool in_vertical_wall = false;   ///< the wall runs along y (the door is passed along x)
};

/// Free-space clearance on a square grid over the building's bounding box:
/// the distance from each cell centre to the nearest obstacle (walls,
/// pillars, furniture, outside), quantized to `step` and capped at 255 steps.
struct ClearanceGrid {
  double cell = 0.1;                ///< [m] cell side
  double step = 0.02;               ///< [m] per stored unit
  int nx = 0, ny = 0;               ///< cells along x and y; cell (i, j) covers [i, i+1) x [j, j+1) cells from (0, 0)
  std::vector<std::uint8_t> units;  ///< row-major (j * nx + i)

  bool inside(int i, int j) const { return i >= 0 && j >= 0 && i < nx && j < ny; }
  /// [m] clearance of cell (i, j); 0 outside the grid.
  double at(int i, int j) const { return inside(i, j) ? units[static_cast<std::size_t>(j) * nx + i] * step : 0.0; }
  /// [m] clearance of the cell holding point p.
  double at(const Point2& p) const {
    return at(static_cast<int>(std::floor(p.x() / cell)), static_cast<int>(std::floor(p.y() / cell)));
  }
};

struct FloorPlanConfig {
  std::uint64_t seed = 1;                ///< every random choice of the plan derives from it
  double min_size = 30.0;                ///< [m] shortest allowed building side
  double max_size = 80.0;                ///< [m] longest allowed building side
  double l_shape_probability = 0.35;     ///< chance that one corner block is cut away (L-shaped outline)
  double corridor_split_min = 16.0;      ///< [m] blocks with both sides at least this long get a corridor through them
  double corridor_min_width = 1.8;       ///< [m]
  double corridor_max_width = 3.2;       ///< [m]
  double room_min = 2.8;                 ///< [m] shortest room side
  double room_max = 7.5;                 ///< [m] rooms longer than this are split further
  double hall_probability = 0.08;        ///< chance that a block of hall size stays one open hall
  int max_halls = 3;                     ///< at most this many halls per building
  double door_min_width = 0.9;           ///< [m]
  double door_max_width = 1.4;           ///< [m]
  double extra_door_probability = 0.2;   ///< chance of a second door between already connected neighbours
  double pillar_spacing_min = 3.5;       ///< [m] pillar grid pitch in halls
  double pillar_spacing_max = 6.0;       ///< [m]
  double clutter_per_room = 1.5;         ///< mean furniture boxes per room
  double corridor_clutter_per_m = 0.06;  ///< mean cabinets per metre of corridor
  double niches_per_m = 0.04;            ///< mean niches (bays into a room) per metre of corridor
  double layout_cell = 0.1;              ///< [m] resolution of the layout raster and of the clearance grid

  /// Throws lshloc::Error naming the first field out of range.
  void validate() const;
};

/// A generated floor plan. The building lies in [0, width] x [0, height]; all
/// obstacles are in `segments` (walls first, then pillars, then furniture).
struct FloorPlan {
  double width = 0.0;   ///< [m] bounding box
  double height = 0.0;  ///< [m]
  std::vector<Segment> segments;
  std::size_t wall_segments = 0;    ///< segments[0, wall_segments) are walls
  std::size_t pillar_segments = 0;  ///< then this many pillar sides; the rest is furniture
  std::vector<Region> regions;      ///< corridors, rooms and halls
  std::vector<Door> doors;
  /// Places a robot tour may visit: the most open point of every reachable
  /// room and hall, and points along every corridor.
  std::vector<Point2> waypoints;
  ClearanceGrid clearance;
};

/// Generates the floor plan of one office building. Different seeds give
/// different layouts (sizes, corridor network, rooms, doors, furniture), not
/// transformed copies of one another. Deterministic for a given config.
/// Throws lshloc::Error on an inconsistent config (e.g. min_size > max_size).
FloorPlan generate_floor_plan(const FloorPlanConfig& config);

}  // namespace lshloc::sim
