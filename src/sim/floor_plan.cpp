#include "lshloc/sim/floor_plan.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>
#include <queue>
#include <random>
#include <string>
#include <utility>

#include "lshloc/common/error.hpp"

namespace lshloc::sim {

namespace {

using Rng = std::mt19937_64;

double uniform(Rng& rng, double lo, double hi) {
  return lo < hi ? std::uniform_real_distribution<double>(lo, hi)(rng) : lo;
}
int uniform_int(Rng& rng, int lo, int hi) { return lo < hi ? std::uniform_int_distribution<int>(lo, hi)(rng) : lo; }
bool chance(Rng& rng, double p) { return std::uniform_real_distribution<double>(0.0, 1.0)(rng) < p; }
int poisson(Rng& rng, double mean) { return mean > 0.0 ? std::poisson_distribution<int>(mean)(rng) : 0; }

/// Cells [i0, i1) x [j0, j1) of the layout raster.
struct CellRect {
  int i0 = 0, j0 = 0, i1 = 0, j1 = 0;
  int w() const { return i1 - i0; }
  int h() const { return j1 - j0; }
};

enum Side { kLeft = 0, kRight = 1, kBottom = 2, kTop = 3 };
using Sides = std::array<bool, 4>;  ///< which sides of a block border a corridor

constexpr int kOutside = -1;
constexpr int kCorridorLabel = 0;  ///< all corridors share one label: no walls where they cross

/// A shared stretch of boundary between two labels: edges [start, end) along
/// grid line `line` (a horizontal line y = line, or a vertical line x = line).
struct BoundaryRun {
  bool vertical = false;
  int line = 0, start = 0, end = 0;
};

/// A convex obstacle polygon (pillar or furniture), counter-clockwise.
using Polygon = std::vector<Point2>;

bool inside_convex(const Polygon& poly, const Point2& p) {
  for (std::size_t k = 0; k < poly.size(); ++k) {
    const Point2& a = poly[k];
    const Point2& b = poly[(k + 1) % poly.size()];
    const Point2 e = b - a, q = p - a;
    if (e.x() * q.y() - e.y() * q.x() < 0.0) return false;
  }
  return true;
}

/// Distance from point p to rectangle r (0 inside).
double distance_to_rect(const Rect& r, const Point2& p) {
  const double dx = std::max({r.x0 - p.x(), 0.0, p.x() - r.x1});
  const double dy = std::max({r.y0 - p.y(), 0.0, p.y() - r.y1});
  return std::hypot(dx, dy);
}

bool rects_overlap(const Rect& a, const Rect& b, double gap) {
  return a.x0 < b.x1 + gap && b.x0 < a.x1 + gap && a.y0 < b.y1 + gap && b.y0 < a.y1 + gap;
}

/// Exact squared Euclidean distance transform of one line (Felzenszwalb and
/// Huttenlocher 2012): d[q] = min_p (q - p)^2 + f[p], with f = kFar where
/// there is no obstacle. The lower envelope of parabolas, in O(n).
constexpr double kFar = 1e20;

void distance_transform_1d(const std::vector<double>& f, std::vector<double>& d, std::vector<int>& v,
                           std::vector<double>& z) {
  const int n = static_cast<int>(f.size());
  constexpr double kInf = std::numeric_limits<double>::infinity();
  v.assign(static_cast<std::size_t>(n), 0);
  z.assign(static_cast<std::size_t>(n) + 1, 0.0);
  d.assign(static_cast<std::size_t>(n), 0.0);
  int k = 0;
  z[0] = -kInf, z[1] = kInf;
  const auto intersection = [&](int q, int p) {
    return ((f[q] + static_cast<double>(q) * q) - (f[p] + static_cast<double>(p) * p)) / (2.0 * (q - p));
  };
  for (int q = 1; q < n; ++q) {
    double s = intersection(q, v[k]);
    while (s <= z[k]) s = intersection(q, v[--k]);
    ++k;
    v[k] = q, z[k] = s, z[k + 1] = kInf;
  }
  k = 0;
  for (int q = 0; q < n; ++q) {
    while (z[k + 1] < q) ++k;
    const double dq = q - v[k];
    d[q] = dq * dq + f[v[k]];
  }
}

class PlanBuilder {
 public:
  explicit PlanBuilder(const FloorPlanConfig& config) : c_(config), rng_(config.seed) {}

  FloorPlan build() {
    const double width = uniform(rng_, c_.min_size, c_.max_size);
    const double height = uniform(rng_, c_.min_size, c_.max_size);
    nx_ = cells(width), ny_ = cells(height);
    plan_.width = nx_ * c_.layout_cell, plan_.height = ny_ * c_.layout_cell;
    label_.assign(static_cast<std::size_t>(nx_) * ny_, kOutside);
    split_root();
    carve_niches();
    place_doors();
    extract_walls();
    add_pillars();
    add_furniture();
    compute_clearance();
    choose_waypoints();
    return std::move(plan_);
  }

 private:
  int cells(double m) const { return static_cast<int>(std::lround(m / c_.layout_cell)); }
  double metres(int n) const { return n * c_.layout_cell; }
  Rect to_rect(const CellRect& r) const { return {metres(r.i0), metres(r.j0), metres(r.i1), metres(r.j1)}; }
  int& label(int i, int j) { return label_[static_cast<std::size_t>(j) * nx_ + i]; }
  int label_or_outside(int i, int j) const {
    return (i < 0 || j < 0 || i >= nx_ || j >= ny_) ? kOutside : label_[static_cast<std::size_t>(j) * nx_ + i];
  }

  void fill(const CellRect& r, int value) {
    for (int j = r.j0; j < r.j1; ++j)
      for (int i = r.i0; i < r.i1; ++i) label(i, j) = value;
  }

  void add_region(const CellRect& r, RegionKind kind) {
    plan_.regions.push_back({kind, to_rect(r), kind == RegionKind::kCorridor});
    fill(r, kind == RegionKind::kCorridor ? kCorridorLabel : static_cast<int>(plan_.regions.size()));
  }

  /// Splits `block` by a corridor of width cw across `vertical` (a corridor
  /// running along y at some x when true); returns the two side blocks.
  std::pair<CellRect, CellRect> corridor_split(const CellRect& block, bool vertical, int cw) {
    const int extent = vertical ? block.w() : block.h();
    const int margin = std::max(cells(c_.room_min), (extent - cw) / 4);
    const int at = uniform_int(rng_, margin, extent - cw - margin);
    CellRect a = block, corridor = block, b = block;
    if (vertical) {
      a.i1 = block.i0 + at, corridor.i0 = a.i1, corridor.i1 = a.i1 + cw, b.i0 = corridor.i1;
    } else {
      a.j1 = block.j0 + at, corridor.j0 = a.j1, corridor.j1 = a.j1 + cw, b.j0 = corridor.j1;
    }
    add_region(corridor, RegionKind::kCorridor);
    return {a, b};
  }

  int corridor_width() { return cells(uniform(rng_, c_.corridor_min_width, c_.corridor_max_width)); }

  /// The main corridor runs along the building's long side. An L-shaped
  /// outline cuts one end off one of the two wings; a shortened main
  /// corridor leaves a room at its end.
  void split_root() {
    const CellRect all{0, 0, nx_, ny_};
    const bool vertical = nx_ < ny_;  // the corridor runs along the long side
    const int cw = corridor_width();
    // Optionally stop the corridor short of one end, with an end room there.
    CellRect body = all;
    if (chance(rng_, 0.4)) {
      const int depth = cells(uniform(rng_, c_.room_min + 1.0, c_.room_max));
      const bool at_start = chance(rng_, 0.5);
      CellRect end_strip = all;
      if (vertical) {
        if (at_start)
          end_strip.j1 = depth, body.j0 = depth;
        else
          end_strip.j0 = ny_ - depth, body.j1 = ny_ - depth;
      } else {
        if (at_start)
          end_strip.i1 = depth, body.i0 = depth;
        else
          end_strip.i0 = nx_ - depth, body.i1 = nx_ - depth;
      }
      // The end strip is a row of rooms across the building.
      Sides s{};
      s[vertical ? (at_start ? kTop : kBottom) : (at_start ? kRight : kLeft)] = true;
      split(end_strip, s, 0);
    }
    auto [a, b] = corridor_split(body, vertical, cw);
    if (chance(rng_, c_.l_shape_probability)) {
      CellRect& wing = chance(rng_, 0.5) ? a : b;
      const int length = vertical ? wing.h() : wing.w();
      const int cut = static_cast<int>(uniform(rng_, 0.3, 0.55) * length);
      const bool cut_start = chance(rng_, 0.5);
      if (vertical) {
        if (cut_start)
          wing.j0 += cut;
        else
          wing.j1 -= cut;
      } else {
        if (cut_start)
          wing.i0 += cut;
        else
          wing.i1 -= cut;
      }
    }
    Sides sa{}, sb{};
    sa[vertical ? kRight : kTop] = true;
    sb[vertical ? kLeft : kBottom] = true;
    split(a, sa, 1);
    split(b, sb, 1);
  }

  /// Recursive subdivision: corridors through big blocks (touching a
  /// corridor so the network stays connected), halls, then walls until the
  /// rooms are office-sized.
  void split(const CellRect& block, Sides sides, int depth) {
    if (block.w() <= 0 || block.h() <= 0) return;
    const double w = metres(block.w()), h = metres(block.h());
    const bool touches_corridor = sides[kLeft] || sides[kRight] || sides[kBottom] || sides[kTop];
    const bool hall_sized = std::min(w, h) >= 8.0 && std::max(w, h) <= 28.0;
    if (touches_corridor && hall_sized && depth > 0 && chance(rng_, c_.hall_probability) && halls_ < c_.max_halls) {
      add_region(block, RegionKind::kHall);
      ++halls_;
      return;
    }
    if (std::min(w, h) >= c_.corridor_split_min) {
      // A corridor along y has its ends on the bottom and top sides; one of
      // them must be a corridor for the new one to join the network.
      const bool along_y_ok = sides[kBottom] || sides[kTop];
      const bool along_x_ok = sides[kLeft] || sides[kRight];
      const bool prefer_y = w >= h;
      if (along_y_ok || along_x_ok) {
        const bool vertical = (prefer_y && along_y_ok) || !along_x_ok;
        auto [a, b] = corridor_split(block, vertical, corridor_width());
        Sides sa = sides, sb = sides;
        sa[vertical ? kRight : kTop] = true;
        sb[vertical ? kLeft : kBottom] = true;
        split(a, sa, depth + 1);
        split(b, sb, depth + 1);
        return;
      }
    }
    if (w <= c_.room_max && h <= c_.room_max) {
      add_region(block, RegionKind::kRoom);
      return;
    }
    // Wall split: prefer a wall that leaves both parts on the corridor.
    const bool x_keeps_access = sides[kBottom] || sides[kTop];
    const bool y_keeps_access = sides[kLeft] || sides[kRight];
    bool split_x;
    if (w > c_.room_max && h > c_.room_max) {
      split_x = x_keeps_access == y_keeps_access ? w >= h : x_keeps_access;
    } else {
      split_x = w > c_.room_max;
    }
    const int extent = split_x ? block.w() : block.h();
    const int at = uniform_int(rng_, cells(c_.room_min), extent - cells(c_.room_min));
    CellRect a = block, b = block;
    if (split_x)
      a.i1 = b.i0 = block.i0 + at;
    else
      a.j1 = b.j0 = block.j0 + at;
    Sides sa = sides, sb = sides;
    sa[split_x ? kRight : kTop] = false;
    sb[split_x ? kLeft : kBottom] = false;
    split(a, sa, depth + 1);
    split(b, sb, depth + 1);
  }

  /// Gives every room a door, breadth-first from the corridor network, so
  /// that every room with a long enough shared wall is reachable; adds some
  /// extra doors for loops.
  void place_doors() {
    std::map<std::pair<int, int>, std::vector<BoundaryRun>> runs;
    const auto add_edge = [&](int la, int lb, bool vertical, int line, int pos) {
      if (la == lb || la == kOutside || lb == kOutside) return;
      auto& list = runs[{std::min(la, lb), std::max(la, lb)}];
      if (!list.empty() && list.back().vertical == vertical && list.back().line == line && list.back().end == pos) {
        ++list.back().end;
      } else {
        list.push_back({vertical, line, pos, pos + 1});
      }
    };
    for (int j = 1; j < ny_; ++j)
      for (int i = 0; i < nx_; ++i) add_edge(label(i, j - 1), label(i, j), false, j, i);
    for (int i = 1; i < nx_; ++i)
      for (int j = 0; j < ny_; ++j) add_edge(label(i - 1, j), label(i, j), true, i, j);

    const int labels = static_cast<int>(plan_.regions.size()) + 1;
    std::vector<std::vector<int>> neighbours(static_cast<std::size_t>(labels));
    for (const auto& [pair, list] : runs) {
      neighbours[pair.first].push_back(pair.second);
      neighbours[pair.second].push_back(pair.first);
    }
    door_h_.assign(static_cast<std::size_t>(ny_ + 1) * nx_, 0);
    door_v_.assign(static_cast<std::size_t>(nx_ + 1) * ny_, 0);
    std::vector<bool> reached(static_cast<std::size_t>(labels), false);
    door_pairs_.clear();
    reached[kCorridorLabel] = true;
    std::queue<int> queue;
    queue.push(kCorridorLabel);
    while (!queue.empty()) {
      const int u = queue.front();
      queue.pop();
      for (const int v : neighbours[u]) {
        if (reached[v]) continue;
        if (cut_door(runs[{std::min(u, v), std::max(u, v)}])) {
          reached[v] = true;
          door_pairs_.push_back({std::min(u, v), std::max(u, v)});
          queue.push(v);
        }
      }
    }
    for (const auto& [pair, list] : runs) {
      if (!reached[pair.first] || !reached[pair.second]) continue;
      if (std::find(door_pairs_.begin(), door_pairs_.end(), pair) != door_pairs_.end()) continue;
      if (chance(rng_, c_.extra_door_probability)) cut_door(runs[pair]);
    }
    for (std::size_t r = 0; r < plan_.regions.size(); ++r) {
      if (plan_.regions[r].kind != RegionKind::kCorridor) plan_.regions[r].reachable = reached[r + 1];
    }
  }

  /// Cuts a door into the longest run if it can hold one; true on success.
  bool cut_door(const std::vector<BoundaryRun>& list) {
    const BoundaryRun* best = nullptr;
    for (const auto& r : list)
      if (!best || r.end - r.start > best->end - best->start) best = &r;
    const int margin = cells(0.3);  // wall left beside the door frame
    if (!best || best->end - best->start < cells(c_.door_min_width) + 2 * margin) return false;
    const int max_width = std::min(cells(c_.door_max_width), best->end - best->start - 2 * margin);
    const int width = uniform_int(rng_, cells(c_.door_min_width), max_width);
    const int start = uniform_int(rng_, best->start + margin, best->end - margin - width);
    for (int k = start; k < start + width; ++k) {
      if (best->vertical)
        door_v_[static_cast<std::size_t>(best->line) * ny_ + k] = 1;
      else
        door_h_[static_cast<std::size_t>(best->line) * nx_ + k] = 1;
    }
    const double along = metres(start) + metres(width) / 2.0;
    const Point2 centre = best->vertical ? Point2(metres(best->line), along) : Point2(along, metres(best->line));
    plan_.doors.push_back({centre, metres(width), best->vertical});
    return true;
  }

  /// Walls are the grid edges between different labels (or a label and the
  /// outside), minus doors, merged into maximal straight segments.
  void extract_walls() {
    for (int j = 0; j <= ny_; ++j) {
      int run_start = -1;
      for (int i = 0; i <= nx_; ++i) {
        bool wall = false;
        if (i < nx_) {
          const int la = label_or_outside(i, j - 1), lb = label_or_outside(i, j);
          wall = la != lb && !door_h_[static_cast<std::size_t>(j) * nx_ + i];
        }
        if (wall && run_start < 0) run_start = i;
        if (!wall && run_start >= 0) {
          plan_.segments.push_back({{metres(run_start), metres(j)}, {metres(i), metres(j)}});
          run_start = -1;
        }
      }
    }
    for (int i = 0; i <= nx_; ++i) {
      int run_start = -1;
      for (int j = 0; j <= ny_; ++j) {
        bool wall = false;
        if (j < ny_) {
          const int la = label_or_outside(i - 1, j), lb = label_or_outside(i, j);
          wall = la != lb && !door_v_[static_cast<std::size_t>(i) * ny_ + j];
        }
        if (wall && run_start < 0) run_start = j;
        if (!wall && run_start >= 0) {
          plan_.segments.push_back({{metres(i), metres(run_start)}, {metres(i), metres(j)}});
          run_start = -1;
        }
      }
    }
    plan_.wall_segments = plan_.segments.size();
  }

  void add_polygon(const Polygon& poly) {
    for (std::size_t k = 0; k < poly.size(); ++k) plan_.segments.push_back({poly[k], poly[(k + 1) % poly.size()]});
    obstacles_.push_back(poly);
  }

  static Polygon box(const Point2& centre, double length, double depth, double angle) {
    const Pose2 frame(centre.x(), centre.y(), angle);
    Polygon p;
    for (const auto& [sx, sy] : {std::pair{-1, -1}, {1, -1}, {1, 1}, {-1, 1}})
      p.push_back(frame.transform({sx * length / 2.0, sy * depth / 2.0}));
    return p;
  }

  static Polygon octagon(const Point2& centre, double radius, double angle) {
    Polygon p;
    for (int k = 0; k < 8; ++k) {
      const double t = angle + k * std::numbers::pi / 4.0;
      p.push_back(centre + radius * Point2(std::cos(t), std::sin(t)));
    }
    return p;
  }

  /// Niches in corridor walls: a shallow bay taken from one room, so the
  /// corridor wall gets a notch (lockers, fire hoses, doorways set back).
  void carve_niches() {
    const std::size_t corridors = plan_.regions.size();
    for (std::size_t r = 0; r < corridors; ++r) {
      if (plan_.regions[r].kind != RegionKind::kCorridor) continue;
      const Rect b = plan_.regions[r].bounds;
      const bool along_x = b.width() >= b.height();
      const double length_total = along_x ? b.width() : b.height();
      const int count = poisson(rng_, c_.niches_per_m * length_total);
      for (int n = 0; n < count; ++n) {
        const double length = uniform(rng_, 1.0, 2.5), depth = uniform(rng_, 0.3, 0.8);
        const double at = uniform(rng_, 0.3, length_total - length - 0.3);
        const bool low_side = chance(rng_, 0.5);
        CellRect niche;
        if (along_x) {
          niche.i0 = cells(b.x0 + at), niche.i1 = cells(b.x0 + at + length);
          niche.j1 = low_side ? cells(b.y0) : cells(b.y1) + cells(depth);
          niche.j0 = niche.j1 - cells(depth);
        } else {
          niche.j0 = cells(b.y0 + at), niche.j1 = cells(b.y0 + at + length);
          niche.i1 = low_side ? cells(b.x0) : cells(b.x1) + cells(depth);
          niche.i0 = niche.i1 - cells(depth);
        }
        if (niche.i0 < 0 || niche.j0 < 0 || niche.i1 > nx_ || niche.j1 > ny_) continue;
        // All of it must come out of one room (not a hall, not the outside).
        const int room = label(niche.i0, niche.j0);
        if (room <= kCorridorLabel || plan_.regions[static_cast<std::size_t>(room - 1)].kind != RegionKind::kRoom)
          continue;
        bool one_room = true;
        for (int j = niche.j0; j < niche.j1 && one_room; ++j)
          for (int i = niche.i0; i < niche.i1 && one_room; ++i) one_room = label(i, j) == room;
        if (!one_room) continue;
        fill(niche, kCorridorLabel);
        furniture_.push_back(to_rect(niche));  // keeps furniture out of it
      }
    }
  }

  /// A grid of pillars (square or round, one kind per hall) inside each hall.
  void add_pillars() {
    for (const auto& region : plan_.regions) {
      if (region.kind != RegionKind::kHall) continue;
      const Rect& r = region.bounds;
      const double pitch = uniform(rng_, c_.pillar_spacing_min, c_.pillar_spacing_max);
      const bool round = chance(rng_, 0.5);
      const double size = round ? uniform(rng_, 0.15, 0.3) : uniform(rng_, 0.3, 0.6);
      const double margin = 1.6;
      const int cols = static_cast<int>((r.width() - 2 * margin) / pitch) + 1;
      const int rows = static_cast<int>((r.height() - 2 * margin) / pitch) + 1;
      if (r.width() < 2 * margin || r.height() < 2 * margin) continue;
      const double x_start = r.centre().x() - (cols - 1) * pitch / 2.0;
      const double y_start = r.centre().y() - (rows - 1) * pitch / 2.0;
      for (int a = 0; a < cols; ++a) {
        for (int b = 0; b < rows; ++b) {
          const Point2 c(x_start + a * pitch, y_start + b * pitch);
          if (round) {
            add_polygon(octagon(c, size, 0.0));
          } else {
            add_polygon(box(c, size, size, 0.0));
          }
        }
      }
    }
    plan_.pillar_segments = plan_.segments.size() - plan_.wall_segments;
  }

  bool clear_of_doors(const Rect& r, double margin) const {
    for (const auto& d : plan_.doors)
      if (distance_to_rect(r, d.centre) < d.width / 2.0 + margin) return false;
    return true;
  }

  bool clear_of_furniture(const Rect& r, double gap) const {
    for (const auto& f : furniture_)
      if (rects_overlap(f, r, gap)) return false;
    return true;
  }

  /// Desks and cabinets against room walls, a free-standing table in larger
  /// rooms, cabinets along corridor walls; none in front of a door.
  void add_furniture() {
    for (const auto& region : plan_.regions) {
      const Rect& r = region.bounds;
      if (region.kind == RegionKind::kRoom) {
        const int count = poisson(rng_, c_.clutter_per_room);
        for (int n = 0, tries = 0; n < count && tries < 20; ++tries) {
          const int side = uniform_int(rng_, 0, 3);
          const bool along_x = side >= kBottom;
          const double wall_length = along_x ? r.width() : r.height();
          const double room_depth = along_x ? r.height() : r.width();
          const double length = uniform(rng_, 0.6, std::min(1.8, wall_length - 0.4));
          const double depth = uniform(rng_, 0.4, std::min(0.8, 0.25 * room_depth));
          const double at = uniform(rng_, 0.0, wall_length - length);
          Rect f;
          if (along_x) {
            f.x0 = r.x0 + at, f.x1 = f.x0 + length;
            f.y0 = side == kBottom ? r.y0 : r.y1 - depth, f.y1 = f.y0 + depth;
          } else {
            f.y0 = r.y0 + at, f.y1 = f.y0 + length;
            f.x0 = side == kLeft ? r.x0 : r.x1 - depth, f.x1 = f.x0 + depth;
          }
          if (!clear_of_doors(f, 0.7) || !clear_of_furniture(f, 0.4)) continue;
          furniture_.push_back(f);
          add_polygon(box(f.centre(), f.width(), f.height(), 0.0));
          ++n;
        }
        if (r.width() >= 5.0 && r.height() >= 5.0 && chance(rng_, 0.5)) {
          // A table: rectangular at any angle, or round (an octagon).
          const bool round = chance(rng_, 0.4);
          const double length = uniform(rng_, 1.2, 2.0), depth = uniform(rng_, 0.7, 1.0);
          const double radius = uniform(rng_, 0.4, 0.6);
          const double reach = (round ? radius : std::hypot(length, depth) / 2.0) + 1.3;
          // Two statements fix the draw order (y first, as g++ evaluated the arguments), so a
          // seed gives the same building with every compiler.
          const double cy = uniform(rng_, r.y0 + reach, r.y1 - reach);
          const Point2 c(uniform(rng_, r.x0 + reach, r.x1 - reach), cy);
          const Rect bound{c.x() - reach + 1.3, c.y() - reach + 1.3, c.x() + reach - 1.3, c.y() + reach - 1.3};
          if (clear_of_doors(bound, 1.0) && clear_of_furniture(bound, 0.8)) {
            furniture_.push_back(bound);
            const double angle = uniform(rng_, -std::numbers::pi, std::numbers::pi);
            add_polygon(round ? octagon(c, radius, angle) : box(c, length, depth, angle));
          }
        }
      } else if (region.kind == RegionKind::kCorridor) {
        const bool along_x = r.width() >= r.height();
        const double length_total = along_x ? r.width() : r.height();
        const double width = along_x ? r.height() : r.width();
        const double max_depth = std::min(0.5, width - 1.5);
        if (max_depth < 0.3) continue;
        const int count = poisson(rng_, c_.corridor_clutter_per_m * length_total);
        for (int n = 0; n < count; ++n) {
          const double length = uniform(rng_, 0.8, 2.0), depth = uniform(rng_, 0.3, max_depth);
          const double at = uniform(rng_, 0.5, length_total - length - 0.5);
          const bool low_side = chance(rng_, 0.5);
          Rect f;
          if (along_x) {
            f.x0 = r.x0 + at, f.x1 = f.x0 + length;
            f.y0 = low_side ? r.y0 : r.y1 - depth, f.y1 = f.y0 + depth;
          } else {
            f.y0 = r.y0 + at, f.y1 = f.y0 + length;
            f.x0 = low_side ? r.x0 : r.x1 - depth, f.x1 = f.x0 + depth;
          }
          if (!clear_of_doors(f, 0.8) || !clear_of_furniture(f, 0.5) || !backed_by_wall(f, along_x, low_side)) continue;
          furniture_.push_back(f);
          add_polygon(box(f.centre(), f.width(), f.height(), 0.0));
        }
      }
    }
  }

  /// True when the cells just behind a corridor cabinet (with 0.6 m to
  /// spare at both ends) are not corridor: it stands against a wall, not in
  /// a crossing.
  bool backed_by_wall(const Rect& f, bool along_x, bool low_side) const {
    const int spare = cells(0.6);
    if (along_x) {
      const int j = low_side ? cells(f.y0) - 1 : cells(f.y1);
      for (int i = cells(f.x0) - spare; i < cells(f.x1) + spare; ++i)
        if (label_or_outside(i, j) == kCorridorLabel ||
            label_or_outside(i, cells(f.y0 + f.height() / 2)) != kCorridorLabel)
          return false;
    } else {
      const int i = low_side ? cells(f.x0) - 1 : cells(f.x1);
      for (int j = cells(f.y0) - spare; j < cells(f.y1) + spare; ++j)
        if (label_or_outside(i, j) == kCorridorLabel ||
            label_or_outside(cells(f.x0 + f.width() / 2), j) != kCorridorLabel)
          return false;
    }
    return true;
  }

  /// Clearance of every cell: an exact distance transform from obstacle
  /// cells (outside, cells any segment passes through, inside furniture).
  void compute_clearance() {
    std::vector<std::uint8_t> blocked(label_.size(), 0);
    for (std::size_t k = 0; k < label_.size(); ++k) blocked[k] = label_[k] == kOutside;
    const double cell = c_.layout_cell;
    const auto mark = [&](double x, double y) {
      const int i = static_cast<int>(std::floor(x / cell)), j = static_cast<int>(std::floor(y / cell));
      if (i >= 0 && j >= 0 && i < nx_ && j < ny_) blocked[static_cast<std::size_t>(j) * nx_ + i] = 1;
    };
    for (const auto& s : plan_.segments) {
      const double length = (s.b - s.a).norm();
      const int steps = static_cast<int>(std::ceil(length / (cell / 2.0))) + 1;
      for (int k = 0; k <= steps; ++k) {
        const Point2 p = s.a + (s.b - s.a) * (static_cast<double>(k) / steps);
        // Both cells beside a wall lying on a grid line are blocked.
        for (const double dx : {-cell / 4.0, cell / 4.0})
          for (const double dy : {-cell / 4.0, cell / 4.0}) mark(p.x() + dx, p.y() + dy);
      }
    }
    for (const auto& poly : obstacles_) {
      double x0 = 1e18, y0 = 1e18, x1 = -1e18, y1 = -1e18;
      for (const auto& p : poly)
        x0 = std::min(x0, p.x()), y0 = std::min(y0, p.y()), x1 = std::max(x1, p.x()), y1 = std::max(y1, p.y());
      for (int j = std::max(0, static_cast<int>(y0 / cell)); j < std::min(ny_, static_cast<int>(y1 / cell) + 1); ++j)
        for (int i = std::max(0, static_cast<int>(x0 / cell)); i < std::min(nx_, static_cast<int>(x1 / cell) + 1); ++i)
          if (inside_convex(poly, {(i + 0.5) * cell, (j + 0.5) * cell}))
            blocked[static_cast<std::size_t>(j) * nx_ + i] = 1;
    }
    std::vector<double> dist2(label_.size());
    for (std::size_t k = 0; k < blocked.size(); ++k) dist2[k] = blocked[k] ? 0.0 : kFar;
    std::vector<double> f, d, z;
    std::vector<int> v;
    for (int i = 0; i < nx_; ++i) {  // columns
      f.resize(static_cast<std::size_t>(ny_));
      for (int j = 0; j < ny_; ++j) f[j] = dist2[static_cast<std::size_t>(j) * nx_ + i];
      distance_transform_1d(f, d, v, z);
      for (int j = 0; j < ny_; ++j) dist2[static_cast<std::size_t>(j) * nx_ + i] = d[j];
    }
    for (int j = 0; j < ny_; ++j) {  // rows
      f.assign(dist2.begin() + static_cast<std::ptrdiff_t>(j) * nx_,
               dist2.begin() + static_cast<std::ptrdiff_t>(j + 1) * nx_);
      distance_transform_1d(f, d, v, z);
      std::copy(d.begin(), d.end(), dist2.begin() + static_cast<std::ptrdiff_t>(j) * nx_);
    }
    ClearanceGrid& g = plan_.clearance;
    g.cell = cell, g.nx = nx_, g.ny = ny_;
    g.units.resize(dist2.size());
    for (std::size_t k = 0; k < dist2.size(); ++k) {
      // Rounded down: stored clearance never exceeds the true one.
      const double units = std::floor(std::sqrt(std::min(dist2[k], 1e12)) * cell / g.step);
      g.units[k] = static_cast<std::uint8_t>(std::min(units, 255.0));
    }
  }

  /// The most open cell of each reachable room and hall; corridor points
  /// every 6 m along each corridor's centre line.
  void choose_waypoints() {
    const ClearanceGrid& g = plan_.clearance;
    constexpr double kMinClearance = 0.5;  // [m] a robot stands there with room to turn
    for (std::size_t r = 0; r < plan_.regions.size(); ++r) {
      const Region& region = plan_.regions[r];
      const Rect& b = region.bounds;
      if (region.kind == RegionKind::kCorridor) {
        const bool along_x = b.width() >= b.height();
        const double length = along_x ? b.width() : b.height();
        const int count = std::max(1, static_cast<int>(length / 6.0));
        for (int k = 0; k < count; ++k) {
          const double t = (k + 0.5) / count;
          const Point2 p =
              along_x ? Point2(b.x0 + t * b.width(), b.centre().y()) : Point2(b.centre().x(), b.y0 + t * b.height());
          if (g.at(p) >= kMinClearance) plan_.waypoints.push_back(p);
        }
        continue;
      }
      if (!region.reachable) continue;
      int best_i = -1, best_j = -1;
      double best = 0.0;
      for (int j = cells(b.y0); j < cells(b.y1); ++j)
        for (int i = cells(b.x0); i < cells(b.x1); ++i)
          if (label(i, j) == static_cast<int>(r) + 1 && g.at(i, j) > best) best = g.at(i, j), best_i = i, best_j = j;
      if (best >= kMinClearance) plan_.waypoints.push_back({(best_i + 0.5) * g.cell, (best_j + 0.5) * g.cell});
    }
  }

  const FloorPlanConfig& c_;
  Rng rng_;
  int nx_ = 0, ny_ = 0;
  int halls_ = 0;
  std::vector<int> label_;                     ///< kOutside, kCorridorLabel or 1 + region index
  std::vector<std::uint8_t> door_h_, door_v_;  ///< door edges on horizontal / vertical grid lines
  std::vector<std::pair<int, int>> door_pairs_;
  std::vector<Polygon> obstacles_;  ///< pillars and furniture, filled in the clearance grid
  std::vector<Rect> furniture_;     ///< footprints, to keep furniture apart
  FloorPlan plan_;
};

}  // namespace

void FloorPlanConfig::validate() const {
  require(layout_cell > 0.0 && layout_cell <= 0.5, "FloorPlanConfig.layout_cell", "in (0, 0.5] m", layout_cell);
  require(room_min >= 1.5, "FloorPlanConfig.room_min", ">= 1.5 m", room_min);
  require(room_max >= 2.0 * room_min, "FloorPlanConfig.room_max", ">= 2 room_min (rooms are split in two)", room_max);
  require(corridor_min_width >= 1.2, "FloorPlanConfig.corridor_min_width", ">= 1.2 m", corridor_min_width);
  require(corridor_max_width >= corridor_min_width, "FloorPlanConfig.corridor_max_width", ">= corridor_min_width",
          corridor_max_width);
  require(min_size >= 2.0 * room_min + corridor_max_width + 2.0, "FloorPlanConfig.min_size",
          ">= 2 room_min + corridor_max_width + 2 m", min_size);
  require(max_size >= min_size && max_size <= 500.0, "FloorPlanConfig.max_size", "in [min_size, 500] m", max_size);
  require(corridor_split_min >= 2.0 * room_min + corridor_max_width, "FloorPlanConfig.corridor_split_min",
          ">= 2 room_min + corridor_max_width (rooms on both sides of a corridor)", corridor_split_min);
  require(door_min_width >= 0.7, "FloorPlanConfig.door_min_width", ">= 0.7 m", door_min_width);
  require(door_max_width >= door_min_width, "FloorPlanConfig.door_max_width", ">= door_min_width", door_max_width);
  require(max_halls >= 0, "FloorPlanConfig.max_halls", ">= 0", max_halls);
  require(pillar_spacing_min >= 1.5, "FloorPlanConfig.pillar_spacing_min", ">= 1.5 m", pillar_spacing_min);
  require(pillar_spacing_max >= pillar_spacing_min && std::isfinite(pillar_spacing_max),
          "FloorPlanConfig.pillar_spacing_max", "finite and >= pillar_spacing_min", pillar_spacing_max);
  require(clutter_per_room >= 0.0 && std::isfinite(clutter_per_room), "FloorPlanConfig.clutter_per_room",
          "finite and >= 0", clutter_per_room);
  require(corridor_clutter_per_m >= 0.0 && std::isfinite(corridor_clutter_per_m),
          "FloorPlanConfig.corridor_clutter_per_m", "finite and >= 0", corridor_clutter_per_m);
  require(niches_per_m >= 0.0 && std::isfinite(niches_per_m), "FloorPlanConfig.niches_per_m", "finite and >= 0",
          niches_per_m);
  for (const auto& [p, field] : {std::pair{l_shape_probability, "FloorPlanConfig.l_shape_probability"},
                                 std::pair{hall_probability, "FloorPlanConfig.hall_probability"},
                                 std::pair{extra_door_probability, "FloorPlanConfig.extra_door_probability"}})
    require(p >= 0.0 && p <= 1.0, field, "a probability in [0, 1]", p);
}

FloorPlan generate_floor_plan(const FloorPlanConfig& config) {
  config.validate();
  return PlanBuilder(config).build();
}

}  // namespace lshloc::sim
