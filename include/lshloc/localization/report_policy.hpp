#pragma once
// The localizer's report policy: after each scan it turns iRANSAC's
// hypotheses into the reported estimate and its confidence flag. It holds
// the reported place against look-alikes (hysteresis and the two duels), lets
// it follow the local map's drift (tracking children and a pattern search),
// and says "localized" only on strong, stable, unrivalled support.
// Poses [m, rad]; config fields ending in _deg are degrees.
// Not thread-safe: one policy per localizer, called from its thread.
#include <array>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "lshloc/matching/incremental_ransac.hpp"

namespace lshloc {

/// How the reported place is chosen and follows the local map (docs/design.md
/// section 2.3): the hysteresis and the duels that hold it against
/// look-alikes, and the tracking that follows the local map's drift. Which
/// place is reported; whether to trust it is ConfidenceConfig's.
struct PlaceConfig {
  double same_place_m = 1.0;     ///< [m] two hypotheses closer than this at the robot are one place ...
  double same_place_deg = 10.0;  ///< [deg] ... and turned less than this
  /// Hysteresis of the reported estimate: the best hypothesis near the last
  /// reported one stays reported unless a hypothesis elsewhere beats its C/N
  /// by more than this.
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
  /// errors): over a long history the local map bends, and a true place
  /// whose older scans the drift has moved loses the whole-map duel to a
  /// stale report; a kidnapped robot, too. 0: off.
  double duel_recent_margin = 0.15;
  /// ... but a reported place that was once well supported loses so only
  /// where its map scores at least this share of the recent data-points:
  /// where the map holds almost nothing about the reported place, the recent
  /// scans are no evidence against it ...
  double duel_recent_min_evidence = 0.1;
  /// ... unless the challenger leads it there by this much: a wrong place
  /// the robot drove out of, silent about where it is now, must yield to a
  /// supported true place that fits the recent scans outright. Above 2: never.
  double duel_recent_silent_margin = 0.4;
  /// A reported place that was once well supported is given up, by either
  /// duel, only for a challenger that iRANSAC supports as well (the
  /// confidence test's min_scored and min_mean_score) ...
  bool challenger_needs_support = true;
  /// ... or for one that leads it by this much in the whole-map duel (a
  /// place whose fit has decayed otherwise holds against a true place in a
  /// thinly mapped building). Above 2 (scores lie in [-1, 1]): never.
  double unsupported_challenger_margin = 0.1;
  /// While the reported place is young (never supported, and kept fewer
  /// than `young_place_scans` scans), iRANSAC's best hypotheses at up to
  /// `young_place_rivals` other places challenge it each scan, past the
  /// hysteresis: on the few data-points each was scored on, C/N ranks a
  /// look-alike over the true place as often as not, while the whole local
  /// map tells them apart. 0 rivals: only the overall best challenges.
  /// A place older than young_place_scans that was never supported also
  /// needs support on 3 scans in a row for the flag to rise.
  std::size_t young_place_rivals = 3;
  std::uint32_t young_place_scans = 20;
  /// A young place's challenger that loses as iRANSAC proposed it is refined
  /// and dueled once more, and then wins only by this lead. Above 2: never.
  double young_refined_margin = 0.1;
  /// Tracking: each scan, the reported hypothesis spawns children moved by
  /// +-track_step_m along x and y and +-track_step_deg in heading about the
  /// robot's current pose, so that a correct place keeps a hypothesis that
  /// follows the local map's drift even when the database proposes none.
  bool track_reported = true;
  double track_step_m = 0.1;    ///< [m]
  double track_step_deg = 1.0;  ///< [deg]
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

  void validate() const;
};

/// The confidence value's features, in the order of its weights.
inline constexpr std::size_t kValueFeatures = 10;
/// The weights of src/localization/confidence_value.json (compiled in): while the flag is down, or up.
std::array<double, kValueFeatures> default_value_weights(bool flag_up);
/// That file's names of the features ("log1p:scored" is ln(1 + N)); the library refuses to build
/// when they are not the features it computes.
std::array<const char*, kValueFeatures> value_feature_names();

/// When the localizer says "localized" (docs/design.md section 2.3: say it
/// only when the evidence is strong; a confident answer should never be
/// wrong). The flag is a state machine over named evidence tests
/// (FlagTests): it rises when every rise test passes and is held while the
/// place is kept and the hold tests pass; the tests that fail are the
/// estimate's flag_down_because. Scores are means in [-1, 1].
struct ConfidenceConfig {
  /// Support: iRANSAC's best hypothesis scored on at least min_scored
  /// data-points (about 10 scans) at a mean (C/N) of min_mean_score.
  std::uint32_t min_scored = 500;
  double min_mean_score = 0.35;
  /// The lead a rise needs over the best place elsewhere (another submap or
  /// more than 2 m away): a C/N margin of min_margin; or, on the same
  /// whole_map_points data-points spread over the whole local map, a lead of
  /// min_whole_map_lead (strong_lead over a rival scored on fewer than
  /// min_scored / 2 points, which may have displaced a well-scored one), or
  /// of min_margin paired with strong_lead on the newest_points newest ones.
  /// A lead counts only where the place itself fits those whole-map points
  /// by min_margin: a lead over a rival the map contradicts is none.
  double min_margin = 0.15;
  double min_whole_map_lead = 0.2;
  double strong_lead = 0.25;
  /// The best stayed in one place this many scans; a rival iRANSAC dropped
  /// stands this long after it was last seen (its active set flickers).
  std::size_t stable_scans = 5;
  /// [deg] A remembered rival that has come within 2 m of the reported
  /// place but is turned more than this from it is the place's mirror
  /// image: it stands while it stays so. >= 180: off.
  double rival_twin_turn_deg = 90.0;
  /// The newest-scan fit: the reported place scored on the newest
  /// `newest_points` data-points (about two scans). A rise needs a newest fit
  /// of min_newest_fit, or a map silent there (it scores at most
  /// silent_newest_evidence of them) that is not negative on balance.
  std::size_t newest_points = 100;
  double min_newest_fit = 0.1;
  double silent_newest_evidence = 0.05;
  /// The hold: the newest points' mean penalty ((newest_evidence -
  /// newest_fit) / 2) at most hold_max_contradiction on one scan and
  /// hold_max_mean_contradiction as an exponential mean (weight
  /// contradiction_smoothing per scan), and the whole-map fit >= 0.
  double hold_max_contradiction = 0.13;
  double hold_max_mean_contradiction = 0.1;
  double contradiction_smoothing = 0.3;
  std::size_t whole_map_points = 1000;
  /// Weak support, for a thin map: N >= weak_support_min_scored, a
  /// whole-map lead of min_margin over a standing rival, and the map scoring
  /// at most weak_support_max_newest_evidence of the newest points.
  std::uint32_t weak_support_min_scored = 3000;
  double weak_support_max_newest_evidence = 0.2;
  /// Relative support, for a place the map scores under min_mean_score while
  /// it clearly fits better than its rival: N >= relative_support_min_scored,
  /// C/N >= relative_support_min_mean_score, a C/N margin of
  /// relative_support_min_margin, a whole-map lead of min_whole_map_lead and
  /// a newest lead of min_newest_fit over a standing rival.
  std::uint32_t relative_support_min_scored = 300;
  double relative_support_min_mean_score = 0.2;
  double relative_support_min_margin = 0.05;
  /// The flag is the value at or above this: a flagged estimate's value is
  /// raised to it, an unflagged one's held at least 0.001 below it (the CSVs
  /// print 4 decimals), so that a value of 0.9 or more always comes with the
  /// flag. In (0.001, 1]. The value's weights: src/localization/confidence_value.json.
  double flag_threshold = 0.9;

  void validate() const;
};

/// The report policy's settings: which place, and whether to trust it.
struct ReportPolicyConfig {
  PlaceConfig place;
  ConfidenceConfig confidence;
  /// The value's weights, while the flag is down and while it is up (not
  /// settings: fitted, src/localization/confidence_value.json).
  std::array<double, kValueFeatures> value_weights = default_value_weights(false);
  std::array<double, kValueFeatures> flagged_value_weights = default_value_weights(true);
  /// Score the whole-map comparison on every scan (traces), not only where a
  /// test reads it (about 0.2 ms per scan).
  bool always_score_whole_map = false;

  void validate() const;
};

/// Which parts of the flag's test kept it down at a scan (all false while
/// it is up, or without an estimate): what a robot's operator reads to know
/// what the localizer still waits for.
struct FlagDownReasons {
  bool unstable = false;          ///< iRANSAC's best moved within the last stable_scans scans
  bool weak_support = false;      ///< C/N under min_mean_score, and no weak or relative support instead
  bool few_points = false;        ///< N under min_scored (C/N high enough), and no weak or relative support
  bool look_alike = false;        ///< the margin over the best place elsewhere is short, and no lead passes it
  bool newest_misfit = false;     ///< the newest points fit the place under min_newest_fit
  bool young_hypothesis = false;  ///< a new hypothesis at a long-kept place, scored on too few points yet
  bool contradicted = false;      ///< the flag was up: the newest points contradict the map (the hold's limits)

  bool any() const {
    return unstable || weak_support || few_points || look_alike || newest_misfit || young_hypothesis || contradicted;
  }
  /// The set reasons' names (the field names above), in that order.
  std::vector<const char*> names() const;
  /// Those names joined by ';' (one CSV field, needing no quotes).
  std::string joined() const;
};

/// The flag's evidence tests at one scan, each true when it passes. The flag
/// is a two-state machine over them: down, it rises when every rise test
/// passes; up, it stays while every hold test passes (or the rise tests pass
/// anew). The tests that fail are the estimate's flag_down_because.
struct FlagTests {
  // The rise.
  bool stable = false;       ///< iRANSAC's best stayed at one place stable_scans scans
  bool supported = false;    ///< absolute support (min_scored, min_mean_score), or weak or relative support
  bool newest_fits = false;  ///< the newest points fit the place (or the map is silent there, not negative)
  bool unrivalled = false;   ///< the place leads the best place elsewhere (ConfidenceConfig: the lead)
  bool seasoned = false;     ///< the best hypothesis is scored on as many points as its place's age asks
  // The hold.
  bool kept = false;              ///< the reported place is the last scan's
  bool once_supported = false;    ///< ... and has been supported (or weakly or relatively) since it was found
  bool not_contradicted = false;  ///< neither the newest points nor the whole local map contradict it

  bool rises() const { return stable && supported && newest_fits && unrivalled && seasoned; }
  bool holds() const { return kept && once_supported && not_contradicted; }
};

/// The localizer's answer for one target scan.
struct LocalizationEstimate {
  bool has_estimate = false;
  bool localized = false;   ///< the confidence flag (ConfidenceConfig: the rise test, then held)
  double confidence = 0.0;  ///< the calibrated value in [0, 1]; >= ConfidenceConfig::flag_threshold iff localized
  std::uint32_t submap = 0;
  Pose2 pose;  ///< the scan's laser pose in the submap frame
  Pose2 T_submap_local;
  double mean_score = 0.0;   ///< C/N of the best hypothesis
  std::uint32_t scored = 0;  ///< N of the best hypothesis
  double margin = 0.0;       ///< C/N lead over the best hypothesis elsewhere
  /// The margin the flag's rise test reads: `margin`, or the lead over the
  /// C/N of a rival iRANSAC dropped within stable_scans, when that
  /// one was stronger than any it holds now.
  double rise_margin = 0.0;
  /// The rival behind `rise_margin` (has_rival false: none): its submap, the
  /// scan's laser pose there, its C/N and N when last seen.
  bool has_rival = false;
  std::uint32_t rival_submap = 0;
  Pose2 rival_pose;
  double rival_mean_score = 0.0;
  std::uint32_t rival_scored = 0;
  /// The reported place's lead over that rival on the newest_points newest
  /// data-points (newest_fit when there is no rival).
  double newest_lead = 0.0;
  bool stable = false;     ///< iRANSAC's best stayed at one place the last stable_scans scans
  bool supported = false;  ///< the best hypothesis meets min_scored and min_mean_score
  /// The reported place has met min_scored and min_mean_score since the
  /// estimate last moved elsewhere.
  bool place_supported = false;
  std::uint32_t kept_scans = 0;  ///< scans in a row the reported place has been kept (0: it just moved)
  double newest_fit = 0.0;       ///< mean score of the reported place on the newest_points newest data-points
  double newest_evidence = 0.0;  ///< ... the share of them its map says anything about (|score| > 0)
  Pose2 local_pose;              ///< the scan's laser pose in the local frame
  /// The reported place and its best rival elsewhere (the hypothesis behind
  /// `rise_margin`) scored on the same whole_map_points data-points spread over
  /// the whole local map: the reported place's mean, and its lead over the
  /// rival (its mean when there is no rival). iRANSAC's margin compares
  /// means over different points; this one does not.
  double whole_map_fit = 0.0;
  double whole_map_lead = 0.0;
  bool whole_map_scored = false;  ///< the two above were scored at this scan (else 0: no test read them)
  /// Another scan stamped at the same time has an estimate elsewhere
  /// (localization/stamp_clash.hpp): this pose cannot be looked up by time.
  bool stamp_clash = false;
  FlagDownReasons flag_down_because;  ///< why `localized` is false (none while it is true)
  /// What outputs read by time stamp mark as confident: the flag, except at
  /// a stamp clash. The flag itself is the localizer's state and does not
  /// flicker with the stamps.
  bool confident() const { return localized && !stamp_clash; }
};

/// What the report policy needs of the localizer's data-points: the scores
/// of hypotheses on a random sample of them. The localizer implements it over
/// iRANSAC's data-points and the pose-grid scorer; tests use a fake.
class SampleScorer {
 public:
  /// Sums over the sample of two hypotheses' scores that a duel needs beyond
  /// their plain sums.
  struct PairSums {
    double squared_difference = 0.0;  ///< of the per-point scores of hypotheses 0 and 1
    double second_absolute = 0.0;     ///< of hypothesis 1's |score|
  };
  virtual ~SampleScorer() = default;
  /// Draws `n` data-points uniformly (with replacement) from the newest
  /// `window` (0: all) as the sample of the next score() calls; returns how
  /// many were drawn (0 when there are no data-points).
  virtual std::size_t draw(std::size_t window, std::size_t n) = 0;
  /// Takes the newest `n` data-points (all of them when fewer), in order, as
  /// the sample; draws nothing at random. Returns how many were taken.
  virtual std::size_t take_newest(std::size_t n) = 0;
  /// Takes `n` data-points spread evenly over all of them (every size/n-th,
  /// all when fewer) as the sample; draws nothing at random, so scoring it
  /// leaves the draws of the duels and the refinement as they were.
  virtual std::size_t take_spread(std::size_t n) = 0;
  /// sums[j] = the sum over the sample of hypothesis j's score; with `pair`,
  /// also the PairSums of hypotheses 0 and 1 (at least two then).
  virtual void score(std::span<const Hypothesis> hypotheses, std::vector<double>& sums, PairSums* pair = nullptr) = 0;
};

struct ReportPolicyStats {
  std::size_t duels = 0;              ///< challenger-incumbent duels run
  std::size_t duels_won = 0;          ///< duels the challenger won (the estimate moved)
  std::size_t refined_duels_won = 0;  ///< ... of them, by a young place's refined challenger
  std::size_t refine_moves = 0;       ///< accepted moves of the tracking refinement
};

/// iRANSAC's settings that the policy reads.
struct RansacPreference {
  double preference_z = 2.0;             ///< best = argmax C/N - z/sqrt(N)
  double min_score = 30.0;               ///< C_o: hypotheses below it are not candidates
  std::size_t recent_window = 8000;      ///< data-points of the recent-points duel
  std::size_t iterations_per_scan = 50;  ///< iterations iRANSAC runs per scan (points each hypothesis is scored on)
};

class ReportPolicy {
 public:
  ReportPolicy(ReportPolicyConfig config, RansacPreference ransac);

  /// The reported hypothesis moved about the robot's pose `local_pose`, for
  /// iRANSAC to verify this scan (tracking); empty before the first report
  /// or with tracking off. Valid until the next call.
  std::span<const Hypothesis> tracking_children(const Pose2& local_pose);

  /// The report for the scan whose laser pose in the local frame is
  /// `local_pose`, from iRANSAC's best and active hypotheses after it.
  LocalizationEstimate report(std::optional<ScoredHypothesis> best, std::span<const ScoredHypothesis> active,
                              const Pose2& local_pose, SampleScorer& sample);

  const ReportPolicyConfig& config() const { return config_; }
  const ReportPolicyStats& stats() const { return stats_; }

 private:
  struct Duel {
    double challenger_mean = 0.0;
    double incumbent_mean = 0.0;
    double lead_stderr = 0.0;  ///< standard error of the mean paired difference
    /// Mean |score| of the incumbent: the share of the points on which the
    /// map says anything at its place (scores are +-1 or 0).
    double incumbent_evidence = 0.0;
    std::size_t incumbent = 0;  ///< which of the incumbents stood for its place
  };
  /// How a duel or a refinement takes its data-points: drawn at random, or
  /// spread evenly over the whole local map (no draw, so the later draws stay
  /// as they would have been).
  enum class Points { drawn, spread };
  /// Mean scores of `challenger` and the best of `incumbents` (hypotheses of
  /// one place) over the same duel_points data-points drawn uniformly from
  /// the newest `window` (0: all).
  Duel duel(const Hypothesis& challenger, std::span<const Hypothesis> incumbents, std::size_t window,
            SampleScorer& sample, Points points = Points::drawn);
  /// `h` (or `alternative`, if it fits the sample better) refined by the
  /// pattern search of refine_points about the robot's `local_pose`.
  Hypothesis refine(Hypothesis h, const std::optional<Hypothesis>& alternative, const Pose2& local_pose,
                    SampleScorer& sample, Points points = Points::drawn);
  /// The hysteresis and the duels: the hypothesis to report this scan.
  std::optional<ScoredHypothesis> hold_or_move(std::optional<ScoredHypothesis> best,
                                               std::span<const ScoredHypothesis> active, const Pose2& local_pose,
                                               SampleScorer& sample);
  bool supported(const ScoredHypothesis& h) const;

  ReportPolicyConfig config_;
  RansacPreference ransac_;
  std::deque<std::optional<Hypothesis>> recent_best_;
  std::optional<Hypothesis> reported_;
  /// iRANSAC's last hypothesis at the reported place: it keeps the pose that
  /// fitted the older scans after preemption cut it and tracking moved on.
  std::optional<Hypothesis> anchor_;
  /// A rival elsewhere, its C/N and the report it was last seen in: the last
  /// one iRANSAC held, and the one it held before its last scan without any.
  struct SeenRival {
    Hypothesis hypothesis;
    double mean = 0.0;
    std::uint32_t scored = 0;
    std::uint64_t seen_at = 0;
  };
  std::optional<SeenRival> last_rival_, dropped_rival_;
  std::uint64_t reports_ = 0;  ///< reports made
  /// The reported place has met the confidence test's absolute part
  /// (min_scored, min_mean_score) since the estimate last moved elsewhere.
  bool reported_supported_ = false;
  std::uint32_t kept_scans_ = 0;         ///< scans in a row the reported place has been kept
  bool weakly_supported_place_ = false;  ///< the kept place met the weak or the relative support test
  bool flag_ = false;                    ///< the confidence flag of the last report
  double mean_contradiction_ = 0.0;      ///< exponential mean of the newest points' penalty while flagged
  std::size_t last_drawn_ = 0;           ///< size of the sample last drawn
  std::array<Hypothesis, 6> children_;
  /// young_place_rivals' challengers (into the active list of one call) and their hypotheses
  std::vector<const ScoredHypothesis*> ranked_, rivals_;
  std::vector<Hypothesis> rival_hypotheses_;
  std::vector<double> sums_;
  ReportPolicyStats stats_;
};

/// `h` moved by +-step_m along x and y and +-step_rad in heading about the
/// robot's local pose P: T' = T * P * d * P^-1, so that a small move of the
/// robot's global pose stays small however far the local origin lies.
std::array<Hypothesis, 6> moves_about_robot(const Hypothesis& h, const Pose2& P, double step_m, double step_rad);

/// Whether two hypotheses put the robot's current pose `local` (in the local
/// frame) at the same place: compared at the robot, not at the local frame's
/// origin, which may lie far away and turn small heading differences into
/// large translations.
bool same_place(const Hypothesis& a, const Hypothesis& b, const Pose2& local, double dist_m, double angle_rad);

/// b of same_place() as it compares it: the robot's pose under b. A loop
/// that compares every active hypothesis with one place computes it once.
struct RobotPlace {
  std::uint32_t submap = 0;
  Pose2 robot;  ///< b.T_submap_local * local
  RobotPlace(const Hypothesis& b, const Pose2& local) : submap(b.submap), robot(b.T_submap_local * local) {}
};
bool same_place(const Hypothesis& a, const RobotPlace& b, const Pose2& local, double dist_m, double angle_rad);

}  // namespace lshloc
