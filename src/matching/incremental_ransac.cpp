#include "lshloc/matching/incremental_ransac.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "lshloc/common/error.hpp"

namespace lshloc {

namespace {

/// Halves C and N, keeping C/N (to rounding): an odd N first drops one mean
/// score. N >= 2 stays >= 1.
void halve(double& score, std::uint32_t& scored) {
  if (scored % 2 == 1) score -= score / scored, scored -= 1;
  score *= 0.5;
  scored /= 2;
}

}  // namespace

void IncrementalRansacConfig::validate() const {
  require(block_size >= 1, "IncrementalRansacConfig.block_size", ">= 1 (B)", block_size);
  require(new_data_points_per_scan >= 1, "IncrementalRansacConfig.new_data_points_per_scan", ">= 1 (|U_new|)",
          new_data_points_per_scan);
  require(new_hypotheses_per_scan >= 1, "IncrementalRansacConfig.new_hypotheses_per_scan", ">= 1 (|V_new|)",
          new_hypotheses_per_scan);
  require(std::isfinite(min_score), "IncrementalRansacConfig.min_score", "a finite C_o", min_score);
  require(iterations_per_scan >= 1, "IncrementalRansacConfig.iterations_per_scan", ">= 1 (no hypothesis is scored)",
          iterations_per_scan);
  require(std::isfinite(preference_z) && preference_z >= 0.0, "IncrementalRansacConfig.preference_z", "finite and >= 0",
          preference_z);
  require(recent_window >= 1, "IncrementalRansacConfig.recent_window", ">= 1 data-point", recent_window);
  require(max_data_points >= 2 * recent_window, "IncrementalRansacConfig.max_data_points", ">= 2 recent_window",
          max_data_points);
  // Data-points are indexed by 32 bits.
  require(max_data_points <= std::numeric_limits<std::uint32_t>::max(), "IncrementalRansacConfig.max_data_points",
          "<= 2^32 - 1", max_data_points);
  require(max_scored >= 4, "IncrementalRansacConfig.max_scored", ">= 4 (N_j is halved every max_scored / 2 iterations)",
          max_scored);
}

IncrementalRansac::IncrementalRansac(IncrementalRansacConfig config) : config_(config), rng_(config.seed) {
  config_.validate();
}

void IncrementalRansac::add_scan(std::span<const LocalPoint> data_points, std::span<const Hypothesis> hypotheses) {
  const std::size_t nu = config_.new_data_points_per_scan;
  if (data_points.size() <= nu) {
    add_data_points(data_points);
  } else {
    // A uniform subset of |U_new| data-points (partial Fisher-Yates on indices).
    std::vector<LocalPoint> pick(data_points.begin(), data_points.end());
    for (std::size_t k = 0; k < nu; ++k) std::swap(pick[k], pick[k + random_below(pick.size() - k)]);
    add_data_points(std::span<const LocalPoint>(pick.data(), nu));
    stats_.data_points_over_budget += data_points.size() - nu;
  }
  const std::size_t nv = std::min(hypotheses.size(), config_.new_hypotheses_per_scan);
  add_hypotheses(hypotheses.first(nv));
  stats_.hypotheses_over_budget += hypotheses.size() - nv;
}

void IncrementalRansac::add_data_points(std::span<const LocalPoint> data_points) {
  for (const LocalPoint& f : data_points) {
    if (!std::isfinite(f.x) || !std::isfinite(f.y) || !std::isfinite(f.theta))
      throw Error("iRANSAC: a data-point has a non-finite pose");
    const auto index = static_cast<std::uint32_t>(data_points_.size());
    data_points_.push_back({f.x, f.y, static_cast<float>(wrap_angle(f.theta)), f.kind});
    // Inside-out Fisher-Yates: put the new index at a uniform position j of the
    // permutation and move the element that was there to the end. The
    // permutation stays uniformly random at O(1) per insertion.
    const std::size_t j = random_below(permutation_.size() + 1);
    if (j == permutation_.size()) {
      permutation_.push_back(index);
    } else {
      permutation_.push_back(permutation_[j]);
      permutation_[j] = index;
    }
  }
  if (data_points_.size() > config_.max_data_points) drop_oldest_data_points();
}

void IncrementalRansac::drop_oldest_data_points() {
  const std::size_t n = data_points_.size() / 2;
  data_points_.erase(data_points_.begin(), data_points_.begin() + static_cast<std::ptrdiff_t>(n));
  dropped_ += n;
  stats_.data_points_dropped = dropped_;
  fresh_next_ = fresh_next_ > n ? fresh_next_ - n : 0;
  // A new uniform permutation of what is left (kUniform's order).
  permutation_.resize(data_points_.size());
  for (std::size_t i = 0; i < permutation_.size(); ++i) permutation_[i] = static_cast<std::uint32_t>(i);
  std::shuffle(permutation_.begin(), permutation_.end(), rng_);
  cursor_ = 0;
}

void IncrementalRansac::move_hypothesis(std::size_t from, std::size_t to) {
  submap_[to] = submap_[from];
  tx_[to] = tx_[from], ty_[to] = ty_[from];
  cos_[to] = cos_[from], sin_[to] = sin_[from], theta_[to] = theta_[from];
  score_[to] = score_[from], scored_[to] = scored_[from];
  serial_[to] = serial_[from], pose_[to] = pose_[from];
}

HypothesisBatch HypothesisBatchBuffer::assign(std::span<const Hypothesis> hypotheses) {
  const std::size_t m = hypotheses.size();
  submap_.resize(m), tx_.resize(m), ty_.resize(m), cos_.resize(m), sin_.resize(m), theta_.resize(m);
  for (std::size_t j = 0; j < m; ++j) {
    const Pose2& T = hypotheses[j].T_submap_local;
    submap_[j] = hypotheses[j].submap;
    tx_[j] = static_cast<float>(T.x);
    ty_[j] = static_cast<float>(T.y);
    cos_[j] = static_cast<float>(std::cos(T.theta));
    sin_[j] = static_cast<float>(std::sin(T.theta));
    theta_[j] = static_cast<float>(T.theta);
  }
  return {submap_.data(), tx_.data(), ty_.data(), cos_.data(), sin_.data(), theta_.data(), m};
}

void IncrementalRansac::add_hypotheses(std::span<const Hypothesis> hypotheses) {
  for (const Hypothesis& h : hypotheses) insert_hypothesis(h, 0.0, 0);
}

void IncrementalRansac::add_scored_hypotheses(std::span<const ScoredHypothesis> hypotheses) {
  for (const ScoredHypothesis& h : hypotheses) insert_hypothesis(h.hypothesis, h.score_sum, h.scored);
}

void IncrementalRansac::insert_hypothesis(const Hypothesis& h, double score, std::uint32_t scored) {
  const Pose2& T = h.T_submap_local;
  if (!std::isfinite(T.x) || !std::isfinite(T.y) || !std::isfinite(T.theta))
    throw Error("iRANSAC: a hypothesis of submap " + std::to_string(h.submap) + " has a non-finite pose");
  // A caller's N counts as iterations' do: within max_scored / 2 on arrival.
  while (scored > config_.max_scored / 2) halve(score, scored), ++stats_.hypotheses_halved;
  const std::size_t m = tx_.size();
  const std::size_t j = random_below(m + 1);
  // Grow every column by one, move the element at j to the end (inside-out
  // Fisher-Yates, as for U), then write the new hypothesis at j.
  submap_.emplace_back(), tx_.emplace_back(), ty_.emplace_back(), cos_.emplace_back(), sin_.emplace_back();
  theta_.emplace_back(), score_.emplace_back(), scored_.emplace_back(), serial_.emplace_back(), pose_.emplace_back();
  if (j != m) move_hypothesis(j, m);
  submap_[j] = h.submap;
  tx_[j] = static_cast<float>(T.x), ty_[j] = static_cast<float>(T.y);
  cos_[j] = static_cast<float>(std::cos(T.theta)), sin_[j] = static_cast<float>(std::sin(T.theta));
  theta_[j] = static_cast<float>(wrap_angle(T.theta));
  score_[j] = score, scored_[j] = scored;
  serial_[j] = next_serial_++;
  pose_[j] = T;
  ++stats_.hypotheses_added;
  stats_.active_hypotheses_max = std::max(stats_.active_hypotheses_max, tx_.size());
}

std::size_t IncrementalRansac::next_data_point() {
  const std::size_t n = data_points_.size();
  const std::size_t window = std::min(n, std::max(config_.recent_window, reach_back_));
  switch (config_.order_rule) {
    case DataPointOrderRule::kUniform: {
      if (cursor_ >= n) cursor_ = 0;
      return permutation_[cursor_++];
    }
    case DataPointOrderRule::kFreshFirst:
      // A backlog (more new data-points than iterations) never reaches back
      // past the recent window: stale "fresh" data-points are skipped.
      fresh_next_ = std::max(fresh_next_, n - window);
      if (fresh_next_ < n) return fresh_next_++;
      [[fallthrough]];
    case DataPointOrderRule::kRecentWindow:
      break;
  }
  return n - window + random_below(window);
}

void IncrementalRansac::halve_long_scored() {
  // Called every max_scored / 2 iterations, each adding at most 1 to N_j:
  // N_j <= max_scored / 2 after this, so it stays within max_scored until the next call.
  const std::uint32_t limit = config_.max_scored / 2;
  for (std::size_t j = 0; j < tx_.size(); ++j) {
    if (scored_[j] < limit) continue;
    halve(score_[j], scored_[j]);
    ++stats_.hypotheses_halved;
  }
}

void IncrementalRansac::preempt(std::size_t keep) {
  const std::size_t m = tx_.size();
  if (keep >= m) return;
  // The rank of each hypothesis, computed once; ties go to the older one, so
  // the order is total and the survivors are the same whatever V's order.
  rank_.resize(m);
  for (std::size_t j = 0; j < m; ++j) {
    rank_[j] = scored_[j] > 0 ? score_[j] / scored_[j] : 0.0;
  }
  auto better = [&](std::uint32_t a, std::uint32_t b) {
    return rank_[a] != rank_[b] ? rank_[a] > rank_[b] : serial_[a] < serial_[b];
  };
  order_.resize(m);
  for (std::size_t j = 0; j < m; ++j) order_[j] = static_cast<std::uint32_t>(j);
  if (keep > 0)
    std::nth_element(order_.begin(), order_.begin() + static_cast<std::ptrdiff_t>(keep - 1), order_.end(), better);
  keep_.assign(m, 0);
  for (std::size_t k = 0; k < keep; ++k) keep_[order_[k]] = 1;
  // Compact in place, keeping the survivors' relative (random) order.
  std::size_t w = 0;
  for (std::size_t j = 0; j < m; ++j) {
    if (!keep_[j]) continue;
    if (w != j) move_hypothesis(j, w);
    ++w;
  }
  submap_.resize(w), tx_.resize(w), ty_.resize(w), cos_.resize(w), sin_.resize(w), theta_.resize(w);
  score_.resize(w), scored_.resize(w), serial_.resize(w), pose_.resize(w);
  stats_.hypotheses_preempted += m - w;
}

std::optional<ScoredHypothesis> IncrementalRansac::best() const {
  std::optional<std::size_t> best;
  double best_mean = 0.0;
  for (std::size_t j = 0; j < tx_.size(); ++j) {
    if (scored_[j] == 0 || score_[j] < config_.min_score) continue;
    const double mean = score_[j] / scored_[j] - config_.preference_z / std::sqrt(static_cast<double>(scored_[j]));
    if (best) {
      const std::size_t b = *best;
      if (mean < best_mean) continue;
      if (mean == best_mean && (scored_[j] < scored_[b] || (scored_[j] == scored_[b] && serial_[j] > serial_[b])))
        continue;
    }
    best = j, best_mean = mean;
  }
  if (!best) return std::nullopt;
  const std::size_t j = *best;
  return ScoredHypothesis{{submap_[j], pose_[j]}, score_[j], scored_[j]};
}

std::vector<ScoredHypothesis> IncrementalRansac::active() const {
  std::vector<ScoredHypothesis> out;
  out.reserve(tx_.size());
  for (std::size_t j = 0; j < tx_.size(); ++j) out.push_back({{submap_[j], pose_[j]}, score_[j], scored_[j]});
  return out;
}

IncrementalRansacStats IncrementalRansac::stats() const {
  IncrementalRansacStats s = stats_;
  s.active_hypotheses = tx_.size();
  s.data_points = data_points_.size();
  if (const auto b = best())
    s.best_score = b->score_sum, s.best_mean_score = b->mean_score(), s.best_scored = b->scored;
  return s;
}

}  // namespace lshloc
