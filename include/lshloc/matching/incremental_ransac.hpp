#pragma once
// Incremental preemptive RANSAC (iRANSAC; paper §III-B/C and §IV-B,
// docs/design.md section 2). The data-point set U (the paper's features:
// oriented points of the local map) and the hypothesis set V grow while the
// robot moves; each iteration scores one data-point against every active
// hypothesis and the preemption function halves the active set every B-th
// iteration, so the work per scan stays constant however long the task runs.
// Thread safety: none; one IncrementalRansac per localization task.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <random>
#include <span>
#include <vector>

#include "lshloc/appearance/feature.hpp"

namespace lshloc {

/// A data-point of U: an oriented point (position and heading, e.g. the
/// surface normal) in the local-map frame. Floats: it is read in the hot loop.
struct LocalPoint {
  /// What the point says about the world: a surface (a scan endpoint with
  /// its normal) or free space (a point a local ray passed through, which
  /// must not lie on a map wall: negative evidence, docs/design.md section 2.4).
  enum class Kind : std::uint8_t { kSurface, kFreeSpace };
  float x = 0.0f;      ///< [m]
  float y = 0.0f;      ///< [m]
  float theta = 0.0f;  ///< [rad] (unused for kFreeSpace)
  Kind kind = Kind::kSurface;
};

/// Which data-point iteration i scores (the order rule f_o).
enum class DataPointOrderRule : std::uint8_t {
  /// The paper's rule: cycle through U, which random insertion keeps randomly
  /// permuted, so every data-point old or new is equally likely.
  kUniform,
  /// Uniform over the newest `recent_window` data-points: recent ones
  /// carry the decision, as old ones drift away from the map (paper §V).
  kRecentWindow,
  /// Each new data-point is scored once against the active set before any
  /// other (every survivor is rescored against each scan's new data-points; a
  /// backlog older than `recent_window` of them is skipped); when none is
  /// waiting, uniform over the newest `recent_window` data-points.
  kFreshFirst,
};

struct IncrementalRansacConfig {
  // The defaults are the localizer's (docs/design.md section 2.3); the
  // paper's synthetic setting is B = 10, |U_new| = 10, 10 iterations.
  std::size_t block_size = 50;                 ///< B: the active set halves every B-th iteration
  std::size_t new_data_points_per_scan = 40;   ///< |U_new|: add_scan() keeps a random subset this large
  std::size_t new_hypotheses_per_scan = 1000;  ///< |V_new|: add_scan() keeps the first this many
  std::size_t iterations_per_scan = 50;        ///< iterations run() does per scan (= B: steady state 2|V_new|)
  double min_score = 30.0;                     ///< C_o: best() ignores hypotheses with C_j below it
  /// best() ranks by C_j/N_j - preference_z / sqrt(N_j): a lower confidence
  /// bound, so that a young hypothesis with a lucky streak does not outrank
  /// one with long support (per-point scores lie in [-1, 1]). 0 gives the
  /// paper's C_j/N_j.
  double preference_z = 2.0;
  /// kRecentWindow: only the newest recent_window data-points (about 200
  /// scans) decide, as older ones have drifted with the local map
  /// (RESULTS.md, "iRANSAC order rules"; docs/results/matching.md).
  DataPointOrderRule order_rule = DataPointOrderRule::kRecentWindow;
  std::size_t recent_window = 8000;  ///< [data-points] window of kRecentWindow / kFreshFirst
  /// U keeps at most this many data-points: past it the oldest half is
  /// dropped, so that a day-long run's memory stays bounded (2e6 points:
  /// about 14 hours of 40 points per scan at 1 Hz, 32 MB); every window
  /// anything reads is far smaller.
  std::size_t max_data_points = 2'000'000;
  /// N_j stays at most this: every max_scored / 2 iterations, a hypothesis
  /// scored max_scored / 2 times or more has C_j and N_j halved, which keeps
  /// C_j / N_j. The 32-bit N_j would otherwise wrap after 2^32 scores, 25
  /// days of one hypothesis held at 50 iterations per scan and 40 Hz.
  std::uint32_t max_scored = 1u << 31;
  std::uint64_t seed = 0x5eed0002;  ///< random insertion and data-point sampling

  /// Throws lshloc::Error when a field is out of range.
  void validate() const;
};

struct IncrementalRansacStats {
  std::size_t active_hypotheses = 0;      ///< |V| now
  std::size_t active_hypotheses_max = 0;  ///< largest |V| seen
  std::size_t data_points = 0;            ///< |U| now
  std::size_t data_points_dropped = 0;    ///< the oldest data-points dropped past max_data_points
  std::size_t iterations = 0;             ///< iterations done (those with data-points and hypotheses)
  std::size_t scores = 0;                 ///< data-point-hypothesis pairs scored
  std::size_t hypotheses_added = 0;
  std::size_t hypotheses_preempted = 0;     ///< cut by the preemption function
  std::size_t hypotheses_over_budget = 0;   ///< dropped by add_scan() beyond |V_new|
  std::size_t data_points_over_budget = 0;  ///< dropped by add_scan() beyond |U_new|
  std::size_t hypotheses_halved = 0;        ///< C_j and N_j halved at max_scored
  double best_score = 0.0;                  ///< C of best() (0 when none qualifies)
  double best_mean_score = 0.0;             ///< C / N of best()
  std::uint32_t best_scored = 0;            ///< N of best()
};

/// The active hypotheses as structure-of-arrays, the way scorers read them:
/// hypothesis j maps a local point (x, y, theta) to
/// (tx[j] + cos[j] x - sin[j] y, ty[j] + sin[j] x + cos[j] y, theta[j] + theta).
struct HypothesisBatch {
  const std::uint32_t* submap = nullptr;
  const float* tx = nullptr;
  const float* ty = nullptr;
  const float* cos = nullptr;
  const float* sin = nullptr;
  const float* theta = nullptr;  ///< [rad] in (-pi, pi]
  std::size_t size = 0;
};

/// Hypotheses laid out as a HypothesisBatch, in buffers reused from call to
/// call (headings as given, not wrapped). Not thread-safe.
class HypothesisBatchBuffer {
 public:
  /// The batch of `hypotheses`; valid until the next call.
  HypothesisBatch assign(std::span<const Hypothesis> hypotheses);

 private:
  std::vector<std::uint32_t> submap_;
  std::vector<float> tx_, ty_, cos_, sin_, theta_;
};

/// A hypothesis with its accumulated score C and the number N of data-points it
/// was scored against.
struct ScoredHypothesis {
  Hypothesis hypothesis;
  double score_sum = 0.0;    ///< C_j, the sum of its scores
  std::uint32_t scored = 0;  ///< N_j, how many data-points it was scored on
  double mean_score() const { return scored > 0 ? score_sum / scored : 0.0; }
  /// The preference value of best(): mean_score() - z / sqrt(N).
  double preference(double z) const { return scored > 0 ? mean_score() - z / std::sqrt(double(scored)) : -1e30; }
};

/// iRANSAC. A Scorer is any callable
///   void(const LocalPoint& x, const HypothesisBatch& v, float* c)
/// that writes c[j] = c(p_j, x) for every j < v.size: one call per iteration
/// for the whole active set, so a scorer can batch its memory accesses, and
/// scores may be any real number (negative evidence: +1 / 0 / -penalty).
///
/// Not thread-safe; one instance per localization task.
class IncrementalRansac {
 public:
  explicit IncrementalRansac(IncrementalRansacConfig config = {});

  const IncrementalRansacConfig& config() const { return config_; }

  /// Adds one scan's data: a random subset of at most |U_new| data-points and the
  /// first |V_new| hypotheses (pass them ranked best first).
  void add_scan(std::span<const LocalPoint> data_points, std::span<const Hypothesis> hypotheses);
  /// Adds every data-point, each at a random position of U (O(1) each).
  void add_data_points(std::span<const LocalPoint> data_points);
  /// Adds every hypothesis, each at a random position of V (O(1) each), with
  /// C = N = 0. Throws lshloc::Error on a non-finite pose.
  void add_hypotheses(std::span<const Hypothesis> hypotheses);
  /// The same with the C and N each was already scored to by the caller
  /// (e.g. on the data-points of the scans that proposed it).
  void add_scored_hypotheses(std::span<const ScoredHypothesis> hypotheses);

  /// Widens the order rule's window (kRecentWindow, kFreshFirst) to at least
  /// the newest `points` data-points, until called again (0: the configured
  /// recent_window): for old data-points a caller knows newer hypotheses need.
  void reach_back(std::size_t points) { reach_back_ = points; }

  /// Runs config().iterations_per_scan iterations.
  template <class Scorer>
  void run(Scorer&& scorer) {
    iterate(scorer, config_.iterations_per_scan);
  }

  /// Runs `n` iterations. Iteration i (counted over the whole task) first cuts
  /// the active set to f_b(i) = m(i-1)/2 when i mod B = 0 (else keeps all),
  /// then scores one data-point x_i (order rule) against every active hypothesis:
  /// C_j += c(p_j, x_i), N_j += 1. Does nothing while U or V is empty.
  template <class Scorer>
  void iterate(Scorer&& scorer, std::size_t n) {
    for (std::size_t k = 0; k < n; ++k) {
      if (data_points_.empty() || tx_.empty()) return;
      const std::size_t i = ++stats_.iterations;
      if (i % (config_.max_scored / 2) == 0) halve_long_scored();
      if (i % config_.block_size == 0) preempt(tx_.size() / 2);
      const LocalPoint& x = data_points_[next_data_point()];
      const std::size_t m = tx_.size();
      if (scratch_.size() < m) scratch_.resize(m);
      scorer(x, batch(), scratch_.data());
      double* c = score_.data();
      std::uint32_t* nn = scored_.data();
      const float* s = scratch_.data();
      for (std::size_t j = 0; j < m; ++j) c[j] += s[j], nn[j] += 1;
      stats_.scores += m;
    }
  }

  /// The preference rule: argmax of the lower confidence bound
  /// C_j / N_j - preference_z / sqrt(N_j) over active hypotheses with N_j > 0
  /// and C_j >= C_o (ties: more scores, then older). nullopt when none qualifies.
  std::optional<ScoredHypothesis> best() const;

  /// Cuts the active set to its best `keep` hypotheses by the preemption rank
  /// (ties: older first). Called by iterate(); public for tests and callers
  /// that bound the set themselves.
  void preempt(std::size_t keep);

  /// Every active hypothesis with its C and N, in V's current order.
  std::vector<ScoredHypothesis> active() const;
  /// The arrival number (0, 1, ...) of each active hypothesis, in V's order.
  std::span<const std::uint64_t> active_serials() const { return serial_; }

  HypothesisBatch batch() const {
    return {submap_.data(), tx_.data(), ty_.data(), cos_.data(), sin_.data(), theta_.data(), tx_.size()};
  }
  std::span<const LocalPoint> data_points() const { return data_points_; }
  /// Data-points dropped from U's front so far (max_data_points): data_points()[i]
  /// is the (data_points_dropped() + i)-th data-point ever added.
  std::size_t data_points_dropped() const { return dropped_; }

  /// Counters, plus best()'s scores (an O(|V|) scan).
  IncrementalRansacStats stats() const;

 private:
  std::size_t next_data_point();
  void halve_long_scored();
  void drop_oldest_data_points();
  std::size_t random_below(std::size_t n) { return std::uniform_int_distribution<std::size_t>(0, n - 1)(rng_); }
  void move_hypothesis(std::size_t from, std::size_t to);
  void insert_hypothesis(const Hypothesis& h, double score, std::uint32_t scored);

  IncrementalRansacConfig config_;
  std::mt19937_64 rng_;
  // U: data-points in arrival order, and a random permutation of their indices.
  std::vector<LocalPoint> data_points_;
  std::vector<std::uint32_t> permutation_;
  std::size_t cursor_ = 0;      ///< kUniform: next position in permutation_
  std::size_t fresh_next_ = 0;  ///< kFreshFirst: first data-point not yet scored on arrival
  std::size_t reach_back_ = 0;  ///< reach_back()
  std::size_t dropped_ = 0;     ///< data_points_dropped()
  // V: the active hypotheses, structure-of-arrays, randomly permuted.
  std::vector<std::uint32_t> submap_;
  std::vector<float> tx_, ty_, cos_, sin_, theta_;
  /// C_j, in double: a float sum stops growing at 2^24 (a hypothesis held
  /// for hours), and sums of the scorers' half-integers are exact in either.
  std::vector<double> score_;
  std::vector<std::uint32_t> scored_;  ///< N_j
  std::vector<std::uint64_t> serial_;  ///< arrival number (tie-break: older first)
  std::vector<Pose2> pose_;            ///< T_submap_local in double, for output
  std::uint64_t next_serial_ = 0;
  std::vector<float> scratch_;
  std::vector<std::uint32_t> order_;  ///< preempt() scratch
  std::vector<double> rank_;          ///< preempt() scratch
  std::vector<std::uint8_t> keep_;    ///< preempt() scratch
  IncrementalRansacStats stats_;
};

}  // namespace lshloc
