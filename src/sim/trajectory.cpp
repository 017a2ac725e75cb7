#include "lshloc/sim/trajectory.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <queue>
#include <random>
#include <string>

#include "lshloc/common/error.hpp"

namespace lshloc::sim {

namespace {

/// A* on the clearance grid (8-connected, cells with clearance >= the robot
/// radius), then a greedy straightening that never lowers the clearance
/// below what the grid path had (up to the preferred clearance).
class PathPlanner {
 public:
  PathPlanner(const ClearanceGrid& grid, const TrajectoryConfig& config)
      : grid_(grid),
        config_(config),
        cost_(static_cast<std::size_t>(grid.nx) * grid.ny, std::numeric_limits<double>::infinity()),
        parent_(cost_.size(), -1),
        closed_(cost_.size(), 0) {}

  /// Appends the straightened path from `from` to `to` (without `from`) to
  /// `route`; false when no path exists.
  bool plan(const Point2& from, const Point2& to, std::vector<Point2>& route) {
    const int start = index_of(from), goal = index_of(to);
    if (start < 0 || goal < 0 || !free(start) || !free(goal)) return false;
    if (!search(start, goal)) return false;
    std::vector<int> cells;
    for (int c = goal; c != -1; c = parent_[c]) cells.push_back(c);
    std::reverse(cells.begin(), cells.end());
    reset();
    std::vector<Point2> points;
    std::vector<double> clearance;
    for (const int c : cells) points.push_back(centre(c)), clearance.push_back(grid_.units[c] * grid_.step);
    points.front() = from, points.back() = to;
    straighten(points, clearance, route);
    return true;
  }

 private:
  int index_of(const Point2& p) const {
    const int i = static_cast<int>(std::floor(p.x() / grid_.cell)),
              j = static_cast<int>(std::floor(p.y() / grid_.cell));
    return grid_.inside(i, j) ? j * grid_.nx + i : -1;
  }
  Point2 centre(int c) const { return {(c % grid_.nx + 0.5) * grid_.cell, (c / grid_.nx + 0.5) * grid_.cell}; }
  double clearance(int c) const { return grid_.units[static_cast<std::size_t>(c)] * grid_.step; }
  bool free(int c) const { return clearance(c) >= config_.robot_radius; }

  bool search(int start, int goal) {
    using Entry = std::pair<double, int>;
    std::priority_queue<Entry, std::vector<Entry>, std::greater<>> open;
    const Point2 target = centre(goal);
    const auto heuristic = [&](int c) { return (centre(c) - target).norm(); };
    cost_[start] = 0.0;
    touched_.push_back(start);
    open.push({heuristic(start), start});
    const double pref = config_.preferred_clearance;
    while (!open.empty()) {
      const int c = open.top().second;
      open.pop();
      if (closed_[c]) continue;
      if (c == goal) return true;
      closed_[c] = 1;
      const int ci = c % grid_.nx, cj = c / grid_.nx;
      for (int dj = -1; dj <= 1; ++dj) {
        for (int di = -1; di <= 1; ++di) {
          if (di == 0 && dj == 0) continue;
          const int ni = ci + di, nj = cj + dj;
          if (!grid_.inside(ni, nj)) continue;
          const int n = nj * grid_.nx + ni;
          if (closed_[n] || !free(n)) continue;
          // No squeezing diagonally between two blocked cells.
          if (di != 0 && dj != 0 && (!free(cj * grid_.nx + ni) || !free(nj * grid_.nx + ci))) continue;
          const double step = (di != 0 && dj != 0 ? std::sqrt(2.0) : 1.0) * grid_.cell;
          const double penalty = 1.0 + 2.0 * std::max(0.0, pref - clearance(n)) / pref;
          const double cost = cost_[c] + step * penalty;
          if (cost < cost_[n]) {
            if (cost_[n] == std::numeric_limits<double>::infinity()) touched_.push_back(n);
            cost_[n] = cost, parent_[n] = c;
            open.push({cost + heuristic(n), n});
          }
        }
      }
    }
    reset();
    return false;
  }

  void reset() {
    for (const int c : touched_) cost_[c] = std::numeric_limits<double>::infinity(), parent_[c] = -1, closed_[c] = 0;
    touched_.clear();
  }

  /// True when every point of a-b lies in a cell of clearance >= need.
  bool line_clear(const Point2& a, const Point2& b, double need) const {
    const double length = (b - a).norm();
    const int steps = static_cast<int>(std::ceil(length / (grid_.cell / 2.0)));
    for (int k = 0; k <= steps; ++k) {
      const Point2 p = a + (b - a) * (steps ? static_cast<double>(k) / steps : 0.0);
      if (grid_.at(p) < need) return false;
    }
    return true;
  }

  void straighten(const std::vector<Point2>& points, const std::vector<double>& clearance,
                  std::vector<Point2>& route) const {
    const std::size_t n = points.size();
    std::size_t anchor = 0;
    while (anchor + 1 < n) {
      std::size_t j = anchor + 1;
      double lowest = std::min(clearance[anchor], clearance[j]);
      while (j + 1 < n && j - anchor < 300) {
        const double candidate_lowest = std::min(lowest, clearance[j + 1]);
        const double need = std::max(config_.robot_radius, std::min(config_.preferred_clearance, candidate_lowest));
        if (!line_clear(points[anchor], points[j + 1], need)) break;
        ++j, lowest = candidate_lowest;
      }
      route.push_back(points[j]);
      anchor = j;
    }
  }

  const ClearanceGrid& grid_;
  const TrajectoryConfig& config_;
  std::vector<double> cost_;
  std::vector<int> parent_;
  std::vector<std::uint8_t> closed_;
  std::vector<int> touched_;
};

/// The route as a growing polyline with arc-length lookup.
class Route {
 public:
  void add(const Point2& p) {
    arc_.push_back(points_.empty() ? 0.0 : arc_.back() + (p - points_.back()).norm());
    points_.push_back(p);
  }
  double length() const { return arc_.empty() ? 0.0 : arc_.back(); }
  const std::vector<Point2>& points() const { return points_; }

  /// The point at arc length s (clamped to the ends).
  Point2 at(double s) const {
    if (s <= 0.0) return points_.front();
    if (s >= length()) return points_.back();
    const auto k = static_cast<std::size_t>(std::upper_bound(arc_.begin(), arc_.end(), s) -
                                            arc_.begin());  // arc_[k-1] <= s < arc_[k]
    const double span = arc_[k] - arc_[k - 1];
    const double t = span > 0.0 ? (s - arc_[k - 1]) / span : 0.0;
    return points_[k - 1] + t * (points_[k] - points_[k - 1]);
  }

 private:
  std::vector<Point2> points_;
  std::vector<double> arc_;
};

}  // namespace

void TrajectoryConfig::validate() const {
  require(speed > 0.0 && speed <= 5.0, "TrajectoryConfig.speed", "in (0, 5] m/s", speed);
  require(turn_rate > 0.0 && std::isfinite(turn_rate), "TrajectoryConfig.turn_rate", "finite and > 0 [rad/s]",
          turn_rate);
  require(period > 0.0 && std::isfinite(period), "TrajectoryConfig.period", "finite and > 0 [s]", period);
  require(robot_radius > 0.1 && std::isfinite(robot_radius), "TrajectoryConfig.robot_radius", "finite and > 0.1 m",
          robot_radius);
  require(preferred_clearance >= robot_radius && std::isfinite(preferred_clearance),
          "TrajectoryConfig.preferred_clearance", "finite and >= robot_radius", preferred_clearance);
  require(lookahead > 0.0 && std::isfinite(lookahead), "TrajectoryConfig.lookahead", "finite and > 0 m", lookahead);
  require(stop_to_turn > 0.0 && std::isfinite(stop_to_turn), "TrajectoryConfig.stop_to_turn", "finite and > 0 rad",
          stop_to_turn);
  require(goal_choices >= 1, "TrajectoryConfig.goal_choices", ">= 1", goal_choices);
}

Trajectory drive_tour(const FloorPlan& plan, const TrajectoryConfig& config, std::size_t count, std::uint64_t seed) {
  config.validate();
  std::vector<Point2> goals;
  for (const auto& w : plan.waypoints)
    if (plan.clearance.at(w) >= config.robot_radius) goals.push_back(w);
  if (goals.size() < 2) {
    throw Error("the floor plan has " + std::to_string(goals.size()) + " waypoints a robot of radius " +
                std::to_string(config.robot_radius) + " m fits in; a tour needs at least 2");
  }
  std::mt19937_64 rng(seed);
  PathPlanner planner(plan.clearance, config);
  Trajectory out;
  Route route;
  std::vector<bool> visited(goals.size(), false);
  std::size_t current = std::uniform_int_distribution<std::size_t>(0, goals.size() - 1)(rng);
  visited[current] = true;
  route.add(goals[current]);

  // Plans one more leg: to one of the nearest unvisited goals.
  const auto extend = [&] {
    for (std::size_t attempt = 0; attempt < 2 * goals.size(); ++attempt) {
      std::vector<std::size_t> open;
      for (std::size_t g = 0; g < goals.size(); ++g)
        if (!visited[g]) open.push_back(g);
      if (open.empty()) {  // all seen: start another round
        std::fill(visited.begin(), visited.end(), false);
        visited[current] = true;
        continue;
      }
      const Point2 here = goals[current];
      const std::size_t choices = std::min(config.goal_choices, open.size());
      std::partial_sort(open.begin(), open.begin() + static_cast<std::ptrdiff_t>(choices), open.end(),
                        [&](std::size_t a, std::size_t b) {
                          return (goals[a] - here).squaredNorm() < (goals[b] - here).squaredNorm();
                        });
      const std::size_t next = open[std::uniform_int_distribution<std::size_t>(0, choices - 1)(rng)];
      visited[next] = true;
      std::vector<Point2> leg;
      if (planner.plan(goals[current], goals[next], leg) && !leg.empty()) {
        for (const auto& p : leg) route.add(p);
        current = next;
        ++out.goals_reached;
        return;
      }
      ++out.goals_unreachable;
    }
    throw Error("the robot found no path to any waypoint of the floor plan");
  };

  const double dt = config.period;
  const double max_step = config.speed * dt;
  double s = 0.0;
  while (route.length() < config.lookahead + max_step) extend();
  const Point2 first = route.at(0.0), ahead = route.at(config.lookahead);
  double heading = std::atan2(ahead.y() - first.y(), ahead.x() - first.x());
  out.poses.reserve(count);
  for (std::size_t k = 0; k < count; ++k) {
    while (route.length() < s + config.lookahead + max_step) extend();
    const Point2 position = route.at(s);
    out.poses.emplace_back(position.x(), position.y(), heading);
    // Turn towards a point a little ahead on the route, then move as far as
    // the remaining heading error allows.
    const Point2 target = route.at(s + config.lookahead) - position;
    double error = target.norm() > 1e-6 ? wrap_angle(std::atan2(target.y(), target.x()) - heading) : 0.0;
    const double turn = std::clamp(error, -config.turn_rate * dt, config.turn_rate * dt);
    heading = wrap_angle(heading + turn);
    error -= turn;
    const double step = max_step * std::max(0.0, 1.0 - std::abs(error) / config.stop_to_turn);
    s += step;
    out.length += step;
    out.rotation += std::abs(turn);
  }
  // Report the route up to where the robot got.
  for (const auto& p : route.points()) out.route.push_back(p);
  return out;
}

}  // namespace lshloc::sim
