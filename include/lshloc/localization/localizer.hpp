#pragma once
#include <cstdint>
#include <deque>
#include <optional>
#include <random>
#include <span>
#include <utility>
#include <vector>

#include "lshloc/appearance/feature_extractor.hpp"
#include "lshloc/matching/incremental_ransac.hpp"
#include "lshloc/geometry/laser_scan.hpp"
#include "lshloc/appearance/lsh_database.hpp"
#include "lshloc/matching/pose_grid_scorer.hpp"
#include "lshloc/slam/scan_matcher.hpp"
#include "lshloc/localization/global_map.hpp"

namespace lshloc {

/// When the localizer says "localized" (DESIGN.md: say it only when the
/// evidence is strong; a confident answer should never be wrong).
struct ConfidenceConfig {
  std::uint32_t min_scored = 500;    ///< N of the best hypothesis at least this (about 10 scans of support)
  double min_mean_score = 0.35;      ///< C/N of the best hypothesis at least this
  double min_margin = 0.15;          ///< C/N lead over the best hypothesis elsewhere (other submap or > 2 m away)
  std::size_t stable_scans = 5;      ///< the best stayed in one place (1 m, 10 deg) this many scans
  /// Hysteresis of the reported estimate: the best hypothesis near the last
  /// reported one (within `same_place_m`, `same_place_deg`) stays reported
  /// unless a hypothesis elsewhere beats its C/N by more than this.
  double switch_margin = 0.02;
  /// Before the estimate moves elsewhere, the challenger and the incumbent
  /// are scored on the same `duel_points` data-points drawn uniformly from
  /// the whole local map, and the move happens only if the challenger's mean
  /// score is higher by more than `duel_margin` and by more than `duel_z`
  /// standard errors of the paired difference. iRANSAC's C/N compares
  /// hypotheses scored on different points: a young look-alike scored only
  /// where the target left the mapped area otherwise beats the true place,
  /// whose support lies in the older scans. 0 disables the duel.
  std::size_t duel_points = 1000;
  double duel_margin = 0.03;
  double duel_z = 3.0;
  /// When iRANSAC holds no hypothesis at the reported place any more (only
  /// the duel keeps it), the challenger also wins by leading on the newest
  /// ransac.recent_window data-points by this much (and duel_z standard
  /// errors). Over a long history the local map bends, and a true place
  /// whose older scans the drift has moved loses the whole-map duel to a
  /// stale report; a kidnapped robot, too. 0: off.
  double duel_recent_margin = 0.15;
  /// ... but a reported place that was once well supported (iRANSAC gave
  /// it min_scored data-points at a mean of min_mean_score) loses so only
  /// where the map knows its surroundings: on at least this share of the
  /// recent data-points, its map scores them (hit, or local walls in space
  /// the map saw free, local rays through map walls). Where the map holds
  /// almost nothing about the reported place, the recent scans are no
  /// evidence against it (aces: the robot drives from a junction into a
  /// corridor the mappers saw only from far away, and a fully mapped
  /// look-alike fits those scans better).
  double duel_recent_min_evidence = 0.1;
  /// A reported place that was once well supported is given up, by either
  /// duel, only for a challenger that iRANSAC supports as well (min_scored
  /// data-points at a mean of min_mean_score). A look-alike that fits the
  /// local map only where the true place's map is thin (the robot drives
  /// where the mappers barely went) otherwise takes over on a small lead
  /// without ever being well supported itself (RESULTS.md, aces 1341).
  bool challenger_needs_support = true;
  double same_place_m = 1.0;    ///< [m]
  double same_place_deg = 10.0;  ///< [deg]
};

/// Where hypotheses come from.
enum class HypothesisSource : std::uint8_t {
  kDatabase,           ///< the appearance database's candidates (LSH-RANSAC)
  kRandomMapFeatures,  ///< uniformly random map features at the same budget (the ablation control)
};

struct LocalizerConfig {
  /// The target's local map. It keeps far walls' sparse returns (line
  /// normals from 3 points) and matches more scan points (5 cm apart): over
  /// 1000-scan windows its heading drifts 0.9 instead of 2.4 degrees on
  /// aces (median of 20), 0.8 instead of 1.3 on fr079
  /// (docs/results/local-map.md). Mapping (PoseGraphSlam) keeps the
  /// ScanMatcherConfig defaults: its loop closures got worse with these.
  ScanMatcherConfig scan_matcher{.laser_offset = {}, .scan_voxel = 0.05, .normal_min_points = 3};
  FeatureExtractorConfig features;  ///< must equal the global map's
  /// iRANSAC as measured best on real logs (RESULTS.md): 40 data-points per
  /// scan (surface and free-space), 50 iterations per scan halving once per
  /// scan, features drawn from the newest 8000 (about 200 scans: older ones
  /// have drifted), and best = argmax C/N - 2/sqrt(N).
  IncrementalRansacConfig ransac{.block_size = 50,
                                 .new_features_per_scan = 40,
                                 .iterations_per_scan = 50,
                                 .min_score = 30.0,
                                 .preference_z = 2.0,
                                 .order_rule = FeatureOrderRule::kRecentWindow,
                                 .recent_window = 8000};
  std::size_t candidates_per_feature = 100;  ///< k of each database query
  double free_space_penalty = 1.0;  ///< c(p, x) for a local point in space the map saw free
  /// c(p, x) for a local surface point on a map return that has no surface
  /// normal and that map rays never crossed (PoseGridScorerConfig::
  /// surface_on_return): walls the mappers saw only from far away, as sparse
  /// returns, otherwise could only contradict the true place (through their
  /// free space), never support it (RESULTS.md, aces).
  double return_support = 1.0;
  /// -c(p, x) for a local free-space point on a map return that map rays
  /// also crossed (PoseGridScorerConfig::ray_through_contested): the map
  /// holds a wall and free space in one cell. In a consistent map such cells
  /// are doors and people; where a SLAM map's passes disagree (mit-killian,
  /// lshloc's SLAM of 17,480 raw scans) whole corridors are, and a
  /// look-alike whose local rays crossed them was never contradicted
  /// (RESULTS.md, aces).
  double contested_penalty = 0.5;
  double free_space_agreement = 0.0;  ///< c(p, x) for a free-space point in space the map saw free
  std::size_t context_scans = 8;    ///< recent local scans whose surface enters descriptors
  double context_spacing = 0.3;     ///< [m] a scan joins the context after this much travel
  double data_point_spacing = 0.1;  ///< [m] endpoints thinned along a scan before sampling data-points
  /// Free-space data-points per surface data-point: points on local rays
  /// (`free_point_fraction` of the way to the endpoint, at least
  /// `free_point_margin` short of it) that must not land on map walls.
  double free_points_per_surface_point = 1.0;
  double free_point_fraction = 0.5;
  double free_point_margin = 0.6;  ///< [m]
  ConfidenceConfig confidence;
  HypothesisSource hypothesis_source = HypothesisSource::kDatabase;
  /// Tracking: each scan, the reported hypothesis spawns children moved by
  /// +-track_step_m along x and y and +-track_step_deg in heading about the
  /// robot's current pose, so that a correct place keeps a hypothesis that
  /// follows the local map's drift even when the database proposes none.
  bool track_reported = true;
  double track_step_m = 0.1;     ///< [m]
  double track_step_deg = 1.0;   ///< [deg]
  /// Each scan the reported hypothesis is refined by a pattern search (moves
  /// of +-refine_step_m along x and y and +-refine_step_deg about the
  /// robot, halved when none helps, refine_rounds rounds) on refine_points
  /// data-points drawn from the newest refine_window: iRANSAC's hypotheses
  /// keep the pose they were born with, while the local map drifts under
  /// them. 0 points: report iRANSAC's hypothesis as it is.
  std::size_t refine_points = 400;
  std::size_t refine_window = 4000;
  std::size_t refine_rounds = 4;
  double refine_step_m = 0.1;     ///< [m]
  double refine_step_deg = 1.0;   ///< [deg]
  double refine_min_gain = 0.02;  ///< a move must raise the mean score on the sample by this much
  std::uint64_t seed = 0x10ca112e;  ///< the random control's choices

  void validate() const;
};

/// The localizer's answer for one target scan.
struct LocalizationEstimate {
  bool has_estimate = false;
  bool localized = false;       ///< the confidence state
  std::uint32_t submap = 0;
  Pose2 pose;                   ///< the scan's laser pose in the submap frame
  Pose2 T_submap_local;
  double mean_score = 0.0;      ///< C/N of the best hypothesis
  std::uint32_t scored = 0;     ///< N of the best hypothesis
  double margin = 0.0;          ///< C/N lead over the best hypothesis elsewhere
  Pose2 local_pose;             ///< the scan's laser pose in the local frame
};

/// Counts and costs of the localizer; times are the calling thread's CPU
/// seconds (cpu_time.hpp).
struct LocalizerStats {
  std::size_t scans = 0;
  std::size_t features = 0;       ///< local features extracted
  std::size_t hypotheses = 0;     ///< hypotheses generated
  std::size_t data_points = 0;    ///< data-points added to iRANSAC
  double scan_matching_s = 0.0;   ///< [s]
  double extract_s = 0.0;         ///< [s]
  double query_s = 0.0;           ///< [s] database retrieval
  double ransac_s = 0.0;          ///< [s] iRANSAC iterations (scoring)
  std::size_t duels = 0;          ///< challenger-incumbent duels run
  std::size_t duels_won = 0;      ///< duels the challenger won (the estimate moved)
  std::size_t refine_moves = 0;   ///< accepted moves of the tracking refinement
  IncrementalRansacStats ransac;
  ScanMatcherStats scan_matcher;
  double us_query_per_feature() const { return features ? 1e6 * query_s / static_cast<double>(features) : 0.0; }
  double ns_per_score() const {
    return ransac.scores ? 1e9 * ransac_s / static_cast<double>(ransac.scores) : 0.0;
  }
};

/// The target robot's localizer (DESIGN.md section 3): for each scan it
/// updates the local map by scan matching, extracts features in the local
/// frame, queries the appearance database, turns the candidates into
/// hypotheses and runs iRANSAC against the global map's pose grids.
/// It reads the global map at each scan, so mapper scans added between two
/// target scans count from the next one. Not thread-safe.
class Localizer {
 public:
  Localizer(const GlobalMap& map, LocalizerConfig config = {});

  LocalizationEstimate add_scan(const LaserScan& scan);

  const LocalizerConfig& config() const { return config_; }
  LocalizerStats stats() const;
  const IncrementalRansac& ransac() const { return ransac_; }
  /// The last scan's laser pose in the local frame.
  const Pose2& last_local_pose() const { return last_local_pose_; }
  /// Mean score of `h` over every data-point of iRANSAC's U, or over its
  /// newest `window` (0: all), exactly (no sampling): for diagnostics, e.g.
  /// how the true pose fits the local map. Costs |U| scores.
  double mean_score_of(const Hypothesis& h, std::size_t window = 0) const;

 private:
  PoseGridScorerConfig scorer_config() const;
  void generate_hypotheses(const std::vector<Feature>& features);
  void sample_data_points(const LaserScan& scan, const ScanSurface& surface);
  LocalizationEstimate estimate(const Pose2& local_pose);
  struct Duel {
    double challenger_mean = 0.0;
    double incumbent_mean = 0.0;
    double lead_stderr = 0.0;  ///< standard error of the mean paired difference
    /// Mean |score| of the incumbent: the share of the points on which the
    /// map says anything at its place (scores are +-1 or 0).
    double incumbent_evidence = 0.0;
    std::size_t incumbent = 0;  ///< which of the incumbents stood for its place
  };
  /// Mean scores of `challenger` and the best of `incumbents` (hypotheses of
  /// one place) over the same duel_points data-points drawn uniformly from
  /// iRANSAC's U, or from its newest `window` (0: all).
  Duel duel(const Hypothesis& challenger, std::span<const Hypothesis> incumbents, std::size_t window);
  /// `h` (or `alternative`, if it fits the sample better) refined by the
  /// pattern search of refine_points about the robot's `local_pose`.
  Hypothesis refine(Hypothesis h, const std::optional<Hypothesis>& alternative, const Pose2& local_pose);
  /// Draws n indices of iRANSAC's U, uniformly from its newest `window`
  /// (0: all), into sample_.
  void sample_points(std::size_t window, std::size_t n);
  /// Sums over sample_ of two hypotheses' scores that a duel needs beyond
  /// their plain sums.
  struct PairSums {
    double squared_difference = 0.0;  ///< of the per-point scores of hypotheses 0 and 1
    double second_absolute = 0.0;     ///< of hypothesis 1's |score|
  };
  /// sums[j] = sum over sample_ of hypothesis j's score; with `pair`, also
  /// the PairSums of hypotheses 0 and 1 (at least two then).
  void score_on_sample(std::span<const Hypothesis> hypotheses, std::vector<double>& sums,
                       PairSums* pair = nullptr);

  const GlobalMap& map_;
  LocalizerConfig config_;
  ScanMatcher matcher_;
  FeatureExtractor extractor_;
  IncrementalRansac ransac_;
  LshQuery query_;
  PoseGridScorer scorer_;
  std::vector<ScanSurface> context_;  // a few scans: erasing the front is cheap
  Pose2 last_context_pose_;
  std::deque<std::optional<Hypothesis>> recent_best_;
  std::optional<Hypothesis> reported_;
  /// iRANSAC's last hypothesis at the reported place: it keeps the pose that
  /// fitted the older scans after preemption cut it and tracking moved on.
  std::optional<Hypothesis> anchor_;
  /// The reported place has met the confidence test's absolute part
  /// (min_scored, min_mean_score) since the estimate last moved elsewhere.
  bool reported_supported_ = false;
  Pose2 last_local_pose_;
  LocalizerStats stats_;
  // Scratch reused between scans.
  std::vector<std::uint32_t> ids_;
  std::vector<std::uint16_t> counts_;
  struct Candidate {
    std::uint16_t count;
    std::uint32_t feature;
    std::uint32_t id;
  };
  std::vector<Candidate> candidates_, sorted_candidates_;
  std::vector<std::uint32_t> count_start_;
  std::vector<Hypothesis> hypotheses_;
  std::vector<LocalPoint> data_points_;
  std::vector<std::uint32_t> sample_;
  std::vector<double> sums_;
  std::vector<std::uint32_t> batch_submap_;
  std::vector<float> batch_tx_, batch_ty_, batch_cos_, batch_sin_, batch_theta_, batch_out_;
  std::mt19937_64 rng_;
};

}  // namespace lshloc
