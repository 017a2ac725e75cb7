#pragma once
// The target robot's localizer (docs/design.md section 2.2): local map,
// features, retrieval, hypotheses, iRANSAC, report, one scan at a time.
// Poses [m, rad]; times [s] of CPU.
// Thread safety: not thread-safe; one localizer per target robot, reading a
// GlobalMap that does not change during add_scan().
#include <array>
#include <cstdint>
#include <deque>
#include <memory>
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
#include "lshloc/localization/report_policy.hpp"
#include "lshloc/localization/stamp_clash.hpp"

namespace lshloc {

/// Where hypotheses come from.
enum class HypothesisSource : std::uint8_t {
  kDatabase,           ///< the appearance database's candidates (LSH-RANSAC)
  kRandomMapFeatures,  ///< uniformly random map features at the same budget (the ablation control)
};

/// The scan matcher of the target's local map: denser points (5 cm) and line
/// normals from 3 points, so that far walls' sparse returns still match; and
/// where stamps run back or bunch, a per-scan velocity guess and turn
/// retries, so that odometry read at such stamps does not leave a heading
/// error of tens of degrees in the local map; and scans whose odometry
/// stalls while the robot drives on are matched (docs/results/local-map.md
/// and live-map.md).
inline ScanMatcherConfig local_map_matcher() {
  ScanMatcherConfig c;
  c.scan_point_spacing = 0.05;
  c.normal_min_points = 3;
  c.turn_retries = true;
  c.per_scan_velocity_on_odd_stamps = true;
  c.match_stalled_odometry = true;
  return c;
}

struct LocalizerConfig {
  /// The target's local map keeps far walls' sparse returns and matches
  /// denser scan points: its heading drifts less over a window. Mapping
  /// (PoseGraphSlam) keeps the ScanMatcherConfig defaults, with which its
  /// loop closures do better (docs/results/local-map.md).
  ScanMatcherConfig scan_matcher = local_map_matcher();
  FeatureExtractorConfig features;           ///< must equal the global map's
  IncrementalRansacConfig ransac;            ///< its defaults are the localizer's
  std::size_t candidates_per_feature = 100;  ///< k of each database query
  double free_space_penalty = 1.0;           ///< c(p, x) for a local point in space the map saw free
  /// c(p, x) for a local surface point on a map return that has no surface
  /// normal and that map rays never crossed (PoseGridScorerConfig::
  /// surface_on_return): walls the mappers saw only from far away, as sparse
  /// returns, otherwise could only contradict the true place (through their
  /// free space), never support it (RESULTS.md, "Design choices, measured").
  double return_support = 1.0;
  /// -c(p, x) for a local free-space point on a map return that map rays
  /// also crossed (PoseGridScorerConfig::ray_through_contested): the map
  /// holds a wall and free space in one cell. In a consistent map such cells
  /// are doors and people; where a SLAM map's passes disagree whole
  /// corridors are, and a look-alike whose local rays crossed them was never
  /// contradicted (RESULTS.md, "Design choices, measured").
  double contested_penalty = 0.5;
  std::size_t context_scans = 8;    ///< recent local scans whose surface enters descriptors
  double context_spacing = 0.3;     ///< [m] a scan joins the context after this much travel
  double data_point_spacing = 0.1;  ///< [m] endpoints thinned along a scan before sampling data-points
  /// Free-space data-points per surface data-point: points on local rays
  /// (`free_point_fraction` of the way to the endpoint, at least
  /// `free_point_margin` short of it) that must not land on map walls.
  double free_points_per_surface_point = 1.0;
  double free_point_fraction = 0.5;
  double free_point_margin = 0.6;  ///< [m]
  HypothesisSource hypothesis_source = HypothesisSource::kDatabase;
  /// Newly mapped features (hypotheses from the map's side too): at each
  /// scan, the map features added since the last scan are looked up among
  /// the target's own recent features, so that a place the mappers reach
  /// after the target saw it still proposes hypotheses. k of each lookup
  /// (0: off). A map complete before the first scan never adds any.
  std::size_t newly_mapped_candidates = 10;
  std::size_t newly_mapped_per_scan = 50;  ///< at most this many (the newest) are looked up per scan
  /// Each lookup reads at most this many ids of the target's features (the
  /// map database's `max_candidates` for its own queries).
  std::size_t newly_mapped_touched = 75;
  /// Of iRANSAC's |V_new| per scan, at most this share goes to newly mapped
  /// candidates, and at least the rest to the current scan's (the current
  /// scan's many candidates would otherwise crowd them out).
  double newly_mapped_share = 0.05;
  /// Each newly mapped hypothesis enters iRANSAC scored on up to
  /// `newly_mapped_points` data-points of the scans within this many of the
  /// one whose feature proposed it (the newest data-points may lie elsewhere).
  std::size_t newly_mapped_scan_window = 100;
  std::size_t newly_mapped_points = 400;
  /// ... by successive halving: all of them on 1/2^(h+1) of those points,
  /// the better half on as many more, ..., the last survivors on the rest.
  std::size_t newly_mapped_halvings = 3;
  /// For this many scans after newly mapped hypotheses arrive, iRANSAC's
  /// order rule reaches back to the data-points they were scored on (which
  /// the recent window may have left behind).
  std::size_t newly_mapped_reach_scans = 200;
  /// The target's newest features kept for those lookups, in two halves (the
  /// older half is dropped whole when the newer one is full).
  std::size_t seen_features_kept = 20000;
  /// Which place is reported: the hysteresis and duels, and how it follows
  /// the local map's drift.
  PlaceConfig place;
  /// Whether to trust it: the confidence flag's tests (the value's weights
  /// are src/localization/confidence_value.json's).
  ConfidenceConfig report;
  /// Score the flag's whole-map evidence on every scan, not only where a
  /// test reads it (eval --trace; about 0.2 ms per scan). No estimate changes.
  bool trace_evidence = false;
  /// Not confident() where scans stamped together disagree (bunched driver stamps).
  StampClashConfig stamp_clash;
  std::uint64_t seed = 0x10ca112e;  ///< the random control's choices

  void validate() const;
};

/// `config` with the descriptor settings (features, context_scans,
/// context_spacing) of a map built with `map`: the Localizer refuses others,
/// since descriptors made otherwise match nothing.
LocalizerConfig with_map_descriptor_settings(LocalizerConfig config, const GlobalMapConfig& map);

/// Counts and costs of the localizer; times are the calling thread's CPU
/// seconds (cpu_time.hpp).
struct LocalizerStats {
  std::size_t scans = 0;
  std::size_t features = 0;               ///< local features extracted
  std::size_t hypotheses = 0;             ///< hypotheses generated
  std::size_t data_points = 0;            ///< data-points added to iRANSAC
  double scan_matching_s = 0.0;           ///< [s]
  double extract_s = 0.0;                 ///< [s]
  double query_s = 0.0;                   ///< [s] database retrieval
  double ransac_s = 0.0;                  ///< [s] iRANSAC iterations (scoring)
  std::size_t newly_mapped_features = 0;  ///< map features added during the run, looked up among the target's
  std::size_t newly_mapped_missed = 0;    ///< ... not looked up (over the per-scan cap, or gone from the map's ring)
  std::size_t newly_mapped_pairs = 0;     ///< (map feature, target feature) candidates they gave
  std::size_t candidates_touched = 0;     ///< database bucket entries the features' queries read
  std::size_t distinct_candidates = 0;    ///< ... distinct map features among them (each sketch-ranked)
  ReportPolicyStats report;
  StampClashStats stamp_clash;  ///< scans that clash with the scans before them
  IncrementalRansacStats ransac;
  ScanMatcherStats scan_matcher;
  double us_query_per_feature() const { return features ? 1e6 * query_s / static_cast<double>(features) : 0.0; }
  double ns_per_score() const { return ransac.scores ? 1e9 * ransac_s / static_cast<double>(ransac.scores) : 0.0; }
};

/// The target robot's localizer (LSH-RANSAC's loop, docs/design.md 2.2):
/// for each scan it updates the local map by scan matching, extracts features
/// in the local frame with recent scans as context, retrieves look-alike map
/// features from the appearance database, turns them into pose hypotheses,
/// verifies them by iRANSAC against the global map's pose grids, and lets
/// the report policy decide what to report. It reads the global map at each
/// scan, so mapper scans added between two target scans count from the next
/// one. Poses [m, rad]. Not thread-safe, and the map must not change during
/// add_scan().
class Localizer {
 public:
  Localizer(const GlobalMap& map, LocalizerConfig config = {});
  ~Localizer();

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
  class DataPointSample;
  PoseGridScorerConfig scorer_config() const;
  // The steps of add_scan(), in order.
  Pose2 update_local_map(const LaserScan& scan);
  std::vector<Feature> extract_features(const LaserScan& scan, const Pose2& local_pose);
  void retrieve_hypotheses(const std::vector<Feature>& features);
  void random_hypotheses(const std::vector<Feature>& features);
  /// Candidates from the map features added since the last scan (their
  /// target-side features go to newly_mapped_seen_, indexed after `current`).
  void look_up_newly_mapped(std::size_t current);
  /// Adds the scan's newly mapped hypotheses to iRANSAC, scored near their scans.
  void prescore_newly_mapped();
  /// Keeps the first |V_new| sorted candidates, newly mapped ones up to their share.
  void keep_within_budget(std::size_t current);
  /// The scan's features join the target's seen features (after the lookups).
  void remember_features(const std::vector<Feature>& features);
  void sample_data_points(const LaserScan& scan);
  void verify_hypotheses();

  const GlobalMap& map_;
  LocalizerConfig config_;
  ScanMatcher matcher_;
  FeatureExtractor extractor_;
  IncrementalRansac ransac_;
  LshQuery query_;
  PoseGridScorer scorer_;
  ReportPolicy policy_;
  StampClashGuard stamp_clash_;
  ScanContext context_;
  Pose2 last_local_pose_;
  LocalizerStats stats_;
  std::mt19937_64 rng_;  ///< the random control's choices and the policy's samples
  std::unique_ptr<DataPointSample> sample_;
  // Scratch reused between scans.
  std::vector<std::uint32_t> ids_;
  std::vector<Pose2> feature_inverses_;  ///< the current scan's feature poses, inverted
  std::vector<std::uint16_t> counts_;
  struct Candidate {
    std::uint16_t count;
    std::uint32_t feature;
    std::uint32_t id;
  };
  std::vector<Candidate> candidates_, sorted_candidates_;
  std::vector<std::uint32_t> count_start_;
  std::vector<Hypothesis> hypotheses_;
  ScanSurface surface_;  ///< the current scan's surface in the local frame
  std::vector<LocalPoint> data_points_;
  // The target's own features (local-frame poses), keyed with the map
  // database's hashing: [0] the newer half, [1] the older.
  struct SeenFeature {
    Pose2 pose;          ///< in the local frame
    std::uint32_t scan;  ///< the target scan (0, 1, ...) that saw it
  };
  struct SeenFeatures {
    explicit SeenFeatures(const LshConfig& config) : database(config) {}
    LshDatabase database;
    std::vector<SeenFeature> features;  ///< by id
  };
  std::array<std::unique_ptr<SeenFeatures>, 2> seen_;
  LshQuery seen_query_;
  std::optional<std::size_t> map_features_seen_;  ///< the map's feature count at the last scan
  std::vector<SeenFeature> newly_mapped_seen_;    ///< target side of this scan's newly mapped candidates
  std::vector<std::pair<Hypothesis, std::uint32_t>> newly_mapped_hypotheses_;  ///< with the scan that saw it
  std::vector<ScoredHypothesis> scored_newly_mapped_;
  std::vector<Hypothesis> prescore_hypotheses_;  ///< prescore_newly_mapped() scratch, and the next seven
  std::vector<LocalPoint> pair_points_;
  std::vector<std::uint32_t> pair_hypotheses_;
  struct PrescoreGroup {
    std::size_t begin, end;            ///< its hypotheses in scored_newly_mapped_
    std::size_t kept_begin, kept_end;  ///< the data-points of its scans still in iRANSAC's U
    std::size_t n;                     ///< how many of them it is scored on
  };
  std::vector<PrescoreGroup> prescore_groups_;
  std::vector<double> prescore_means_;
  std::vector<std::uint8_t> prescore_keep_;
  std::vector<std::vector<std::uint32_t>> round_points_;  ///< prescore_newly_mapped(): each round's data-point numbers
  std::vector<float> prescore_;
  /// Data-points added to iRANSAC's U by the end of each scan from scan
  /// `data_points_end_first_` on: older scans, all of whose data-points U has
  /// dropped, are let go, so that a long run's memory stays flat.
  std::deque<std::size_t> data_points_end_;
  std::size_t data_points_end_first_ = 0;
  /// data_points_end_'s entry for `scan`; 0 for a scan let go (U holds none of its data-points).
  std::size_t data_points_by_end_of(std::size_t scan) const;
  std::optional<std::size_t> reach_back_from_;  ///< the oldest data-point newly mapped hypotheses need
  std::size_t reach_back_until_ = 0;            ///< ... until this scan
  HypothesisBatchBuffer batch_;
  std::vector<std::uint32_t> feature_tags_;  ///< this scan's features' keys (from the forward queries)
  std::vector<std::uint64_t> feature_sketches_;
};

}  // namespace lshloc
