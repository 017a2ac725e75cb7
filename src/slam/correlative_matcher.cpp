#include "lshloc/slam/correlative_matcher.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>

#include "lshloc/common/error.hpp"

namespace lshloc {

void CorrelativeMatcherConfig::validate() const {
  require(cell > 0.0, "CorrelativeMatcherConfig.cell", "> 0 m", cell);
  require(sigma > 0.0, "CorrelativeMatcherConfig.sigma", "> 0 m", sigma);
  require(block >= 1, "CorrelativeMatcherConfig.block", ">= 1 cell", block);
  require(angle_step_deg > 0.0, "CorrelativeMatcherConfig.angle_step_deg", "> 0 deg", angle_step_deg);
  require(max_query_points >= 1, "CorrelativeMatcherConfig.max_query_points", ">= 1", max_query_points);
  require(runner_up_distance >= 0.0, "CorrelativeMatcherConfig.runner_up_distance", ">= 0 m", runner_up_distance);
}

CorrelativeMatcher::CorrelativeMatcher(CorrelativeMatcherConfig config) : config_((config.validate(), config)) {}

float CorrelativeMatcher::fine_at(std::int32_t ix, std::int32_t iy) const {
  if (ix < 0 || iy < 0 || ix >= w_ || iy >= h_) return 0.0f;
  return fine_[static_cast<std::size_t>(iy) * static_cast<std::size_t>(w_) + static_cast<std::size_t>(ix)];
}

float CorrelativeMatcher::coarse_at(std::int32_t ix, std::int32_t iy) const {
  // coarse_ covers block starts from -(block - 1) to w - 1 (and h - 1).
  const std::int32_t b = config_.block - 1, cw = w_ + b, ch = h_ + b;
  ix += b, iy += b;
  if (ix < 0 || iy < 0 || ix >= cw || iy >= ch) return 0.0f;
  return coarse_[static_cast<std::size_t>(iy) * static_cast<std::size_t>(cw) + static_cast<std::size_t>(ix)];
}

void CorrelativeMatcher::build_grids(std::span<const Point2> reference) {
  const double margin = 3.0 * config_.sigma + config_.cell;
  double x0 = reference[0].x(), y0 = reference[0].y(), x1 = x0, y1 = y0;
  for (const Point2& p : reference) {
    x0 = std::min(x0, p.x()), x1 = std::max(x1, p.x());
    y0 = std::min(y0, p.y()), y1 = std::max(y1, p.y());
  }
  x0_ = x0 - margin, y0_ = y0 - margin;
  const double w = std::ceil((x1 + margin - x0_) / config_.cell) + 1,
               h = std::ceil((y1 + margin - y0_) / config_.cell) + 1;
  if (!(w * h <= static_cast<double>(kMaxGridCells))) {
    throw Error("CorrelativeMatcher: the reference scan spans " + std::to_string(x1 - x0) + " x " +
                std::to_string(y1 - y0) + " m, " + std::to_string(w) + " x " + std::to_string(h) +
                " cells of CorrelativeMatcherConfig.cell = " + std::to_string(config_.cell) +
                " m, above the cap of 2^25 cells (raise the cell size)");
  }
  w_ = static_cast<std::int32_t>(w);
  h_ = static_cast<std::int32_t>(h);
  fine_.assign(static_cast<std::size_t>(w_) * static_cast<std::size_t>(h_), 0.0f);
  const auto r = static_cast<std::int32_t>(std::ceil(3.0 * config_.sigma / config_.cell));
  const double inv2s2 = 1.0 / (2.0 * config_.sigma * config_.sigma);
  for (const Point2& p : reference) {
    const double u = (p.x() - x0_) / config_.cell, v = (p.y() - y0_) / config_.cell;
    const auto cx = static_cast<std::int32_t>(std::floor(u)), cy = static_cast<std::int32_t>(std::floor(v));
    for (std::int32_t iy = std::max(0, cy - r); iy <= std::min(h_ - 1, cy + r); ++iy) {
      for (std::int32_t ix = std::max(0, cx - r); ix <= std::min(w_ - 1, cx + r); ++ix) {
        // Distance from the point to the cell's centre.
        const double dx = (ix + 0.5 - u) * config_.cell, dy = (iy + 0.5 - v) * config_.cell;
        const auto value = static_cast<float>(std::exp(-(dx * dx + dy * dy) * inv2s2));
        float& cell = fine_[static_cast<std::size_t>(iy) * static_cast<std::size_t>(w_) + static_cast<std::size_t>(ix)];
        cell = std::max(cell, value);
      }
    }
  }
  // Max filter, separable: first along x into scratch_, then along y.
  const std::int32_t b = config_.block - 1, cw = w_ + b, ch = h_ + b;
  scratch_.assign(static_cast<std::size_t>(cw) * static_cast<std::size_t>(h_), 0.0f);
  for (std::int32_t iy = 0; iy < h_; ++iy) {
    for (std::int32_t sx = -b; sx < w_; ++sx) {
      float m = 0.0f;
      for (std::int32_t u = std::max(0, sx); u < std::min(w_, sx + config_.block); ++u) m = std::max(m, fine_at(u, iy));
      scratch_[static_cast<std::size_t>(iy) * static_cast<std::size_t>(cw) + static_cast<std::size_t>(sx + b)] = m;
    }
  }
  coarse_.assign(static_cast<std::size_t>(cw) * static_cast<std::size_t>(ch), 0.0f);
  for (std::int32_t sy = -b; sy < h_; ++sy) {
    for (std::int32_t cx = 0; cx < cw; ++cx) {
      float m = 0.0f;
      for (std::int32_t v = std::max(0, sy); v < std::min(h_, sy + config_.block); ++v) {
        m = std::max(
            m, scratch_[static_cast<std::size_t>(v) * static_cast<std::size_t>(cw) + static_cast<std::size_t>(cx)]);
      }
      coarse_[static_cast<std::size_t>(sy + b) * static_cast<std::size_t>(cw) + static_cast<std::size_t>(cx)] = m;
    }
  }
}

CorrelativeMatch CorrelativeMatcher::match(std::span<const Point2> reference, std::span<const Point2> query,
                                           const Pose2& guess, double window_m, double window_rad) {
  CorrelativeMatch result;
  if (reference.empty() || query.empty()) return result;
  build_grids(reference);

  // Evenly subsampled query points.
  std::vector<Point2> points;
  const std::size_t n = std::min(query.size(), config_.max_query_points);
  points.reserve(n);
  for (std::size_t k = 0; k < n; ++k) points.push_back(query[k * query.size() / n]);
  const double inv_n = 1.0 / static_cast<double>(n);

  const double step = config_.angle_step_deg * std::numbers::pi / 180.0;
  const auto angles = static_cast<std::int32_t>(std::floor(std::max(0.0, window_rad) / step));
  const auto reach = static_cast<std::int32_t>(std::ceil(std::max(0.0, window_m) / config_.cell));
  const std::int32_t B = config_.block;
  // Base cell of every point at every heading (translation offset 0).
  const std::size_t headings = static_cast<std::size_t>(2 * angles + 1);
  std::vector<std::int32_t> base_x(headings * n), base_y(headings * n);
  for (std::int32_t a = -angles; a <= angles; ++a) {
    const double th = guess.theta + a * step, c = std::cos(th), s = std::sin(th);
    const std::size_t row = static_cast<std::size_t>(a + angles) * n;
    for (std::size_t k = 0; k < n; ++k) {
      const double gx = guess.x + c * points[k].x() - s * points[k].y();
      const double gy = guess.y + s * points[k].x() + c * points[k].y();
      base_x[row + k] = static_cast<std::int32_t>(std::floor((gx - x0_) / config_.cell));
      base_y[row + k] = static_cast<std::int32_t>(std::floor((gy - y0_) / config_.cell));
    }
  }
  struct Block {
    double upper;
    std::int32_t heading, dx, dy;  // block of translations [dx, dx + B) x [dy, dy + B)
  };
  // Each sum is a chain of dependent additions, so kLanes translations are
  // summed side by side (each still point after point: the same sums).
  constexpr std::int32_t kLanes = 4;
  std::vector<Block> blocks;
  for (std::int32_t h = 0; h < static_cast<std::int32_t>(headings); ++h) {
    const std::size_t row = static_cast<std::size_t>(h) * n;
    for (std::int32_t dy = -reach; dy <= reach; dy += B) {
      for (std::int32_t dx0 = -reach; dx0 <= reach; dx0 += kLanes * B) {
        std::array<double, kLanes> sum{};
        for (std::size_t k = 0; k < n; ++k) {
          for (std::int32_t g = 0; g < kLanes; ++g)
            sum[g] += coarse_at(base_x[row + k] + dx0 + g * B, base_y[row + k] + dy);
        }
        for (std::int32_t g = 0; g < kLanes && dx0 + g * B <= reach; ++g)
          blocks.push_back({sum[g] * inv_n, h, dx0 + g * B, dy});
      }
    }
  }
  std::sort(blocks.begin(), blocks.end(), [](const Block& a, const Block& b) { return a.upper > b.upper; });

  // Branch and bound: blocks in order of their bound, each searched at full
  // resolution until no bound can beat the best. `keep` filters the poses a
  // pass may take (all, then only those far from the best).
  const auto search = [&](auto keep, double& best, std::int32_t& bh, std::int32_t& bx, std::int32_t& by) {
    for (const Block& blk : blocks) {
      if (blk.upper <= best) break;
      const std::size_t row = static_cast<std::size_t>(blk.heading) * n;
      const std::int32_t dx_end = std::min(blk.dx + B, reach + 1);
      for (std::int32_t dy = blk.dy; dy < std::min(blk.dy + B, reach + 1); ++dy) {
        for (std::int32_t dx0 = blk.dx; dx0 < dx_end; dx0 += kLanes) {
          std::array<double, kLanes> sum{};
          for (std::size_t k = 0; k < n; ++k) {
            for (std::int32_t g = 0; g < kLanes; ++g)
              sum[g] += fine_at(base_x[row + k] + dx0 + g, base_y[row + k] + dy);
          }
          for (std::int32_t g = 0; g < kLanes && dx0 + g < dx_end; ++g) {
            const std::int32_t dx = dx0 + g;
            if (!keep(dx, dy)) continue;
            ++result.evaluated;
            if (sum[g] * inv_n > best) best = sum[g] * inv_n, bh = blk.heading, bx = dx, by = dy;
          }
        }
      }
    }
  };
  double best = -1.0;
  std::int32_t bh = angles, bx = 0, by = 0;
  search([](std::int32_t, std::int32_t) { return true; }, best, bh, bx, by);
  const double far = config_.runner_up_distance / config_.cell;
  double runner = 0.0;
  std::int32_t rh = 0, rx = 0, ry = 0;
  search([&](std::int32_t dx, std::int32_t dy) { return std::hypot(dx - bx, dy - by) >= far; }, runner, rh, rx, ry);

  result.found = true;
  result.score = best;
  result.runner_up = runner;
  result.pose = Pose2(guess.x + bx * config_.cell, guess.y + by * config_.cell, guess.theta + (bh - angles) * step);
  return result;
}

}  // namespace lshloc
