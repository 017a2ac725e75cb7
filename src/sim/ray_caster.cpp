#include "lshloc/sim/ray_caster.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>

#include "lshloc/common/error.hpp"

namespace lshloc::sim {

namespace {

/// True when segment a-b touches the axis-aligned box [x0, x1] x [y0, y1]
/// (separating-axis test: the box's two axes and the segment's normal).
bool segment_touches_box(const Point2& a, const Point2& b, double x0, double y0, double x1, double y1) {
  if (std::max(a.x(), b.x()) < x0 || std::min(a.x(), b.x()) > x1) return false;
  if (std::max(a.y(), b.y()) < y0 || std::min(a.y(), b.y()) > y1) return false;
  const Point2 e = b - a;
  const auto side = [&](double x, double y) { return e.x() * (y - a.y()) - e.y() * (x - a.x()); };
  const double s0 = side(x0, y0), s1 = side(x1, y0), s2 = side(x0, y1), s3 = side(x1, y1);
  const double lo = std::min({s0, s1, s2, s3}), hi = std::max({s0, s1, s2, s3});
  return lo <= 0.0 && hi >= 0.0;
}

}  // namespace

void RayCasterConfig::validate() const {
  require(cell > 0.0 && std::isfinite(cell), "RayCasterConfig.cell", "finite and > 0 m", cell);
}

RayCaster::RayCaster(std::span<const Segment> segments, const RayCasterConfig& config) : cell_(config.cell) {
  config.validate();
  double x1 = 0.0, y1 = 0.0;
  x0_ = y0_ = 0.0;
  bool first = true;
  for (std::size_t k = 0; k < segments.size(); ++k) {
    const auto& s = segments[k];
    if (!s.a.allFinite() || !s.b.allFinite()) {
      throw Error("ray caster: segment " + std::to_string(k) + " has a non-finite end point");
    }
    for (const Point2& p : {s.a, s.b}) {
      if (first) x0_ = x1 = p.x(), y0_ = y1 = p.y(), first = false;
      x0_ = std::min(x0_, p.x()), x1 = std::max(x1, p.x());
      y0_ = std::min(y0_, p.y()), y1 = std::max(y1, p.y());
    }
    segments_.push_back({s.a.x(), s.a.y(), s.b.x() - s.a.x(), s.b.y() - s.a.y()});
  }
  // A small margin so end points on the boundary fall inside the grid.
  x0_ -= cell_ / 2.0, y0_ -= cell_ / 2.0;
  nx_ = std::max(1, static_cast<int>(std::ceil((x1 - x0_) / cell_ + 0.5)));
  ny_ = std::max(1, static_cast<int>(std::ceil((y1 - y0_) / cell_ + 0.5)));
  if (static_cast<double>(nx_) * ny_ > 1e8) {
    throw Error("ray caster: the segments span " + std::to_string(nx_) + " x " + std::to_string(ny_) +
                " cells; use a larger cell");
  }
  // Two passes (count, then fill) into a compressed row layout.
  const std::size_t cells = static_cast<std::size_t>(nx_) * ny_;
  cell_start_.assign(cells + 1, 0);
  for (int pass = 0; pass < 2; ++pass) {
    std::vector<std::uint32_t> fill;
    if (pass == 1) {
      for (std::size_t c = 0; c < cells; ++c) cell_start_[c + 1] += cell_start_[c];
      cell_items_.resize(cell_start_[cells]);
      fill.assign(cell_start_.begin(), cell_start_.end() - 1);
    }
    for (std::size_t k = 0; k < segments.size(); ++k) {
      const auto& s = segments[k];
      const int i0 = static_cast<int>((std::min(s.a.x(), s.b.x()) - x0_) / cell_);
      const int i1 = static_cast<int>((std::max(s.a.x(), s.b.x()) - x0_) / cell_);
      const int j0 = static_cast<int>((std::min(s.a.y(), s.b.y()) - y0_) / cell_);
      const int j1 = static_cast<int>((std::max(s.a.y(), s.b.y()) - y0_) / cell_);
      for (int j = j0; j <= j1; ++j) {
        for (int i = i0; i <= i1; ++i) {
          const double bx = x0_ + i * cell_, by = y0_ + j * cell_;
          if (!segment_touches_box(s.a, s.b, bx, by, bx + cell_, by + cell_)) continue;
          const std::size_t c = static_cast<std::size_t>(j) * nx_ + i;
          if (pass == 0)
            ++cell_start_[c + 1];
          else
            cell_items_[fill[c]++] = static_cast<std::uint32_t>(k);
        }
      }
    }
  }
}

double RayCaster::nearest_in_cell(std::size_t cell, double ox, double oy, double dx, double dy, double best) const {
  for (std::uint32_t k = cell_start_[cell]; k < cell_start_[cell + 1]; ++k) {
    const PackedSegment& s = segments_[cell_items_[k]];
    // origin + t * d = a + u * e  =>  t = cross(a - o, e) / cross(d, e), u = cross(a - o, d) / cross(d, e)
    const double denom = dx * s.ey - dy * s.ex;
    if (std::abs(denom) < 1e-12) continue;  // parallel: a grazing ray sees no surface
    const double wx = s.ax - ox, wy = s.ay - oy;
    const double t = (wx * s.ey - wy * s.ex) / denom;
    if (t <= 0.0 || t >= best) continue;
    const double u = (wx * dy - wy * dx) / denom;
    if (u >= 0.0 && u <= 1.0) best = t;
  }
  return best;
}

double RayCaster::cast(const Point2& origin, double dx, double dy, double max_range) const {
  const double ox = origin.x(), oy = origin.y();
  // Clip the ray to the grid box: [t_enter, t_exit].
  double t_enter = 0.0, t_exit = max_range;
  const double gx1 = x0_ + nx_ * cell_, gy1 = y0_ + ny_ * cell_;
  for (const auto& [o, d, lo, hi] : {std::array{ox, dx, x0_, gx1}, std::array{oy, dy, y0_, gy1}}) {
    if (std::abs(d) < 1e-15) {
      if (o < lo || o > hi) return max_range;
      continue;
    }
    double ta = (lo - o) / d, tb = (hi - o) / d;
    if (ta > tb) std::swap(ta, tb);
    t_enter = std::max(t_enter, ta), t_exit = std::min(t_exit, tb);
  }
  if (t_enter > t_exit) return max_range;

  // Amanatides-Woo traversal of the cells the ray crosses, nearest first; stop
  // once the best hit lies before the current cell's far side.
  const double px = ox + t_enter * dx, py = oy + t_enter * dy;
  int i = std::clamp(static_cast<int>((px - x0_) / cell_), 0, nx_ - 1);
  int j = std::clamp(static_cast<int>((py - y0_) / cell_), 0, ny_ - 1);
  constexpr double kInf = std::numeric_limits<double>::infinity();
  const int step_i = dx > 0.0 ? 1 : -1, step_j = dy > 0.0 ? 1 : -1;
  const double delta_x = dx != 0.0 ? cell_ / std::abs(dx) : kInf;
  const double delta_y = dy != 0.0 ? cell_ / std::abs(dy) : kInf;
  double next_x = dx != 0.0 ? (x0_ + (i + (dx > 0.0 ? 1 : 0)) * cell_ - ox) / dx : kInf;
  double next_y = dy != 0.0 ? (y0_ + (j + (dy > 0.0 ? 1 : 0)) * cell_ - oy) / dy : kInf;
  double best = max_range;
  while (true) {
    best = nearest_in_cell(static_cast<std::size_t>(j) * nx_ + i, ox, oy, dx, dy, best);
    const double cell_exit = std::min(next_x, next_y);
    if (best <= cell_exit || cell_exit >= t_exit) break;
    if (next_x < next_y) {
      i += step_i, next_x += delta_x;
      if (i < 0 || i >= nx_) break;
    } else {
      j += step_j, next_y += delta_y;
      if (j < 0 || j >= ny_) break;
    }
  }
  return std::min(best, max_range);
}

}  // namespace lshloc::sim
