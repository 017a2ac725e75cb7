#pragma once
// How well the descriptors and the LSH database find the right place: recall
// of target features against the map's features.
// Lengths [m], angles [rad] except fields named *_deg; descriptor distances in
// descriptor units; timings [us] of wall clock.
// Thread safety: evaluate_place_recall builds its own extractor, store and
// database and is safe from any thread; its timings only mean something on an
// otherwise idle machine. A PlaceRecallProbe is used from one thread.
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "lshloc/appearance/feature_extractor.hpp"
#include "lshloc/appearance/location_store.hpp"
#include "lshloc/appearance/lsh_database.hpp"
#include "lshloc/eval/appearance.hpp"
#include "lshloc/eval/scenario.hpp"

namespace lshloc {

/// Settings of the place-recall evaluation (docs/design.md section 6,
/// "Descriptor + database quality").
struct PlaceRecallConfig {
  std::size_t k = 100;            ///< locations retrieved per query (recall_at_k)
  bool exact = true;              ///< also brute-force exact-L2 recall (the descriptor's own limit)
  double match_distance = 0.5;    ///< [m] covered / hit radius
  double match_angle_deg = 20.0;  ///< [deg] hit heading tolerance
  double thin_cell = 0.0;         ///< [m] insert one map feature per (x, y, theta) cell of this size (0: all)
  double thin_angle = 0.35;       ///< [rad] heading size of that cell
  FeatureExtractorConfig extractor;
  DescriptorContextConfig context;
  LshConfig lsh;

  /// Throws lshloc::Error naming the first field out of range.
  void validate() const;
};

/// What the evaluation measured. Recalls are over covered queries.
struct PlaceRecallResult {
  std::size_t map_scans = 0;
  std::size_t target_scans_with_truth = 0;
  std::size_t queries = 0;    ///< target features (of scans with truth)
  std::size_t covered = 0;    ///< queries with a map feature of the target submap within match_distance
  std::size_t matchable = 0;  ///< covered queries with a map feature that would count as a hit
  std::size_t map_features = 0;
  std::size_t map_features_thinned = 0;  ///< left out by thinning
  double recall_at_1 = 0, recall_at_10 = 0, recall_at_100 = 0, recall_at_k = 0;
  double exact_recall_at_1 = 0, exact_recall_at_10 = 0, exact_recall_at_100 = 0, exact_recall_at_k = 0;
  /// Medians over covered queries of the descriptor distance to the nearest
  /// correct map feature, to the nearest of all, and to the k-th nearest.
  double median_true_match_distance = 0, median_nearest_distance = 0, median_kth_distance = 0;
  double insert_us_per_feature = 0;  ///< [us] wall clock, LshDatabase::insert only
  double query_us_per_feature = 0;   ///< [us] wall clock, LshDatabase::query only
  double mean_candidates_touched = 0;
  double mean_distinct_candidates = 0;
  LshStats lsh;
};

/// Inserts the features of every map scan of `scenario` (location store and
/// LSH database), queries with the features of every target scan that has
/// ground truth (placed at its true pose; descriptor context from earlier
/// target scans placed by odometry relative to it) and scores the answers.
PlaceRecallResult evaluate_place_recall(const Scenario& scenario, const PlaceRecallConfig& config);

/// A target feature placed at its true pose in `submap`: a recall query.
struct RecallQuery {
  std::uint32_t submap = 0;
  Feature feature;
};

/// Recall@k of a map that grows one submap at a time, for a sample of
/// queries, without keeping the map's descriptors: each batch of map features
/// updates every query's exact k nearest (brute force) and whether its place
/// is covered; the database is asked at the end. A hit lies in the query's
/// submap within match_distance and match_angle_deg of its true pose; recalls
/// are over covered queries, as in evaluate_place_recall().
class PlaceRecallProbe {
 public:
  PlaceRecallProbe(std::vector<RecallQuery> queries, const PlaceRecallConfig& config);
  /// Map features as the map adds them (poses in `submap`'s frame).
  void add_map_features(std::uint32_t submap, std::span<const Feature> features);

  struct Result {
    std::size_t queries = 0, covered = 0;
    double lsh_recall_at_k = 0.0;    ///< the database's first k locations
    double exact_recall_at_k = 0.0;  ///< the exact k nearest descriptors (L2)
  };
  /// Asks `database` (whose ids index `store`) for each query's k locations.
  Result finish(const LshDatabase& database, const LocationStore& store) const;

 private:
  struct Neighbour {
    float distance2;
    MapLocation location;
  };
  bool hit(const RecallQuery& q, const MapLocation& l) const;

  std::vector<RecallQuery> queries_;
  PlaceRecallConfig config_;
  std::vector<char> covered_;
  std::vector<std::vector<Neighbour>> nearest_;  ///< per query, at most k, unordered
};

}  // namespace lshloc
