#include "lshloc/localization/localizer.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <span>

#include "lshloc/common/cpu_time.hpp"
#include "lshloc/common/error.hpp"
#include "lshloc/geometry/voxel_thinning.hpp"
#include "lshloc/geometry/line_fit.hpp"

namespace lshloc {

/// The report policy's samples: uniform draws from iRANSAC's data-points U,
/// scored by the pose-grid scorer.
class Localizer::DataPointSample final : public SampleScorer {
 public:
  DataPointSample(const IncrementalRansac& ransac, PoseGridScorer& scorer, std::mt19937_64& rng)
      : ransac_(ransac), scorer_(scorer), rng_(rng) {}

  std::size_t draw(std::size_t window, std::size_t n) override {
    const std::size_t size = ransac_.data_points().size();
    sample_.clear();
    if (size == 0 || n == 0) return 0;
    const std::size_t first = window > 0 && window < size ? size - window : 0;
    std::uniform_int_distribution<std::size_t> any(first, size - 1);
    for (std::size_t k = 0; k < n; ++k) sample_.push_back(static_cast<std::uint32_t>(any(rng_)));
    return sample_.size();
  }

  std::size_t take_newest(std::size_t n) override {
    const std::size_t size = ransac_.data_points().size();
    sample_.clear();
    for (std::size_t i = size - std::min(n, size); i < size; ++i) sample_.push_back(static_cast<std::uint32_t>(i));
    return sample_.size();
  }

  std::size_t take_spread(std::size_t n) override {
    const std::size_t size = ransac_.data_points().size();
    sample_.clear();
    const std::size_t m = std::min(n, size);
    for (std::size_t k = 0; k < m; ++k) sample_.push_back(static_cast<std::uint32_t>(k * size / m));
    return sample_.size();
  }

  void score(std::span<const Hypothesis> hypotheses, std::vector<double>& sums, PairSums* pair) override {
    const HypothesisBatch batch = batch_.assign(hypotheses);
    const std::size_t m = hypotheses.size();
    sums.assign(m, 0.0);
    // Every (data-point, hypothesis) pair in one batch: a few hypotheses
    // scored one point at a time leave each grid lookup waiting alone.
    const std::span<const LocalPoint> points = ransac_.data_points();
    pair_points_.clear(), pair_hypotheses_.clear();
    for (std::uint32_t i : sample_) {
      for (std::size_t j = 0; j < m; ++j) {
        pair_points_.push_back(points[i]);
        pair_hypotheses_.push_back(static_cast<std::uint32_t>(j));
      }
    }
    out_.resize(pair_points_.size());
    if (!out_.empty()) scorer_.score_pairs(pair_points_, pair_hypotheses_, batch, out_.data());
    PairSums two;
    for (std::size_t k = 0; k < sample_.size(); ++k) {
      const float* o = out_.data() + k * m;
      for (std::size_t j = 0; j < m; ++j) sums[j] += o[j];
      if (pair != nullptr) {
        const double d = double(o[0]) - double(o[1]);
        two.squared_difference += d * d;
        two.second_absolute += std::abs(double(o[1]));
      }
    }
    if (pair != nullptr) *pair = two;
  }

 private:
  const IncrementalRansac& ransac_;
  PoseGridScorer& scorer_;
  std::mt19937_64& rng_;
  std::vector<std::uint32_t> sample_;
  HypothesisBatchBuffer batch_;
  std::vector<LocalPoint> pair_points_;
  std::vector<std::uint32_t> pair_hypotheses_;
  std::vector<float> out_;  ///< the pairs' scores, data-point by data-point
};

void LocalizerConfig::validate() const {
  scan_matcher.validate();
  features.validate();
  ransac.validate();
  place.validate();
  report.validate();
  stamp_clash.validate();
  require(candidates_per_feature >= 1, "LocalizerConfig.candidates_per_feature", ">= 1", candidates_per_feature);
  // Scores of single points, next to a hit's 1.
  require(free_space_penalty >= 0.0 && free_space_penalty <= 100.0, "LocalizerConfig.free_space_penalty", "in [0, 100]",
          free_space_penalty);
  require(return_support >= 0.0 && return_support <= 100.0, "LocalizerConfig.return_support", "in [0, 100]",
          return_support);
  require(contested_penalty >= 0.0 && contested_penalty <= 100.0, "LocalizerConfig.contested_penalty", "in [0, 100]",
          contested_penalty);
  require(newly_mapped_halvings >= 1 && newly_mapped_halvings <= 8, "LocalizerConfig.newly_mapped_halvings", "1..8",
          newly_mapped_halvings);
  require(newly_mapped_touched >= 1, "LocalizerConfig.newly_mapped_touched", ">= 1", newly_mapped_touched);
  require(seen_features_kept >= 2, "LocalizerConfig.seen_features_kept", ">= 2", seen_features_kept);
  require(newly_mapped_share >= 0.0 && newly_mapped_share <= 1.0, "LocalizerConfig.newly_mapped_share", "in [0, 1]",
          newly_mapped_share);
  require(std::isfinite(context_spacing) && context_spacing >= 0.0, "LocalizerConfig.context_spacing",
          "finite and >= 0 m", context_spacing);
  require(data_point_spacing > 0.0 && data_point_spacing <= 10.0, "LocalizerConfig.data_point_spacing", "in (0, 10] m",
          data_point_spacing);
  // A count per surface point: each one costs a pose-grid score per hypothesis.
  require(free_points_per_surface_point >= 0.0 && free_points_per_surface_point <= 100.0,
          "LocalizerConfig.free_points_per_surface_point", "in [0, 100]", free_points_per_surface_point);
  require(free_point_fraction >= 0.0 && free_point_fraction <= 1.0, "LocalizerConfig.free_point_fraction", "in [0, 1]",
          free_point_fraction);
  require(std::isfinite(free_point_margin) && free_point_margin >= 0.0, "LocalizerConfig.free_point_margin",
          "finite and >= 0 m", free_point_margin);
}

LocalizerConfig with_map_descriptor_settings(LocalizerConfig config, const GlobalMapConfig& map) {
  config.features = map.features;
  config.context_scans = map.context_scans;
  config.context_spacing = map.context_spacing;
  return config;
}

namespace {
/// The target's descriptors must be made as the map's were, or no feature can match.
const LocalizerConfig& fitting_map(const LocalizerConfig& config, const GlobalMapConfig& map) {
  config.validate();
  if (!(config.features == map.features))
    throw Error(
        "LocalizerConfig.features: expected the global map's feature settings (its descriptors were made "
        "with them), got others");
  if (config.context_scans != map.context_scans || config.context_spacing != map.context_spacing)
    throw Error("LocalizerConfig.context_scans, context_spacing: expected the global map's (" +
                std::to_string(map.context_scans) + ", " + std::to_string(map.context_spacing) + " m), got " +
                std::to_string(config.context_scans) + ", " + std::to_string(config.context_spacing) + " m");
  return config;
}
}  // namespace

Localizer::Localizer(const GlobalMap& map, LocalizerConfig config)
    : map_(map),
      config_(fitting_map(config, map.config())),
      matcher_(config_.scan_matcher),
      extractor_(config_.features),
      ransac_(config_.ransac),
      query_(map.database()),
      scorer_(map.occupancy(), map.free_space(), scorer_config()),
      policy_({.place = config_.place, .confidence = config_.report, .always_score_whole_map = config_.trace_evidence},
              {.preference_z = config_.ransac.preference_z,
               .min_score = config_.ransac.min_score,
               .recent_window = config_.ransac.recent_window,
               .iterations_per_scan = config_.ransac.iterations_per_scan}),
      stamp_clash_(config_.stamp_clash),
      context_(config_.context_scans, config_.context_spacing),
      rng_(config_.seed),
      sample_(std::make_unique<DataPointSample>(ransac_, scorer_, rng_)),
      seen_query_(map.database()) {}

Localizer::~Localizer() = default;

PoseGridScorerConfig Localizer::scorer_config() const {
  return {.hit = 1.0f,
          .free = -static_cast<float>(config_.free_space_penalty),
          .unknown = 0.0f,
          .ray_through_wall = -static_cast<float>(config_.free_space_penalty),
          .ray_through_free = 0.0f,  // agreement on free space is no evidence (RESULTS.md)
          .ray_through_contested = -static_cast<float>(config_.contested_penalty),
          .surface_on_return = static_cast<float>(config_.return_support)};
}

LocalizationEstimate Localizer::add_scan(const LaserScan& scan) {
  ++stats_.scans;
  const Pose2 local_pose = update_local_map(scan);
  const std::vector<Feature> features = extract_features(scan, local_pose);
  retrieve_hypotheses(features);
  remember_features(features);
  // The reported place's tracking children go first: iRANSAC keeps only the
  // first |V_new| hypotheses of a scan.
  const std::span<const Hypothesis> children = policy_.tracking_children(local_pose);
  hypotheses_.insert(hypotheses_.begin(), children.begin(), children.end());
  sample_data_points(scan);
  verify_hypotheses();
  last_local_pose_ = local_pose;
  const std::optional<ScoredHypothesis> best = ransac_.best();
  const std::vector<ScoredHypothesis> active = best ? ransac_.active() : std::vector<ScoredHypothesis>{};
  LocalizationEstimate estimate = policy_.report(best, active, local_pose, *sample_);
  stamp_clash_.check(scan.timestamp, estimate);
  return estimate;
}

Pose2 Localizer::update_local_map(const LaserScan& scan) {
  CpuStopwatch watch;
  const ScanMatchResult match = matcher_.add_scan(scan);
  stats_.scan_matching_s += watch.seconds();
  return match.laser_pose;
}

std::vector<Feature> Localizer::extract_features(const LaserScan& scan, const Pose2& local_pose) {
  CpuStopwatch watch;
  surface_ = extractor_.surface(scan, local_pose);
  std::vector<Feature> features = extractor_.extract(surface_, context_.surfaces());
  stats_.extract_s += watch.seconds();
  stats_.features += features.size();
  context_.offer(surface_);
  return features;
}

void Localizer::retrieve_hypotheses(const std::vector<Feature>& features) {
  CpuStopwatch watch;
  candidates_.clear();
  hypotheses_.clear();
  newly_mapped_seen_.clear();
  newly_mapped_hypotheses_.clear();
  feature_tags_.clear();
  feature_sketches_.clear();
  const LocationStore& store = map_.locations();
  if (store.empty() || config_.hypothesis_source == HypothesisSource::kRandomMapFeatures) {
    if (!features.empty() && !store.empty()) random_hypotheses(features);
    map_features_seen_ = store.size();
    stats_.query_s += watch.seconds();
    return;
  }
  // The map's query-time settings may have changed since this localizer
  // was made (GlobalMap::set_query_settings).
  if (!map_.database().serves(query_)) query_.fit_to(map_.database());
  for (std::size_t f = 0; f < features.size(); ++f) {
    map_.database().query_counts(features[f].descriptor, config_.candidates_per_feature, ids_, counts_, query_);
    for (std::size_t k = 0; k < ids_.size(); ++k) {
      candidates_.push_back({counts_[k], static_cast<std::uint32_t>(f), ids_[k]});
    }
    const LshKeyView key = query_.last_key();
    feature_tags_.insert(feature_tags_.end(), key.tags.begin(), key.tags.end());
    feature_sketches_.insert(feature_sketches_.end(), key.sketch.begin(), key.sketch.end());
  }
  look_up_newly_mapped(features.size());
  // Most colliding tables first, each feature's own ranking kept on ties: a
  // counting sort, as counts are at most the number of tables.
  std::uint16_t max_count = 0;
  for (const Candidate& c : candidates_) max_count = std::max(max_count, c.count);
  count_start_.assign(static_cast<std::size_t>(max_count) + 2, 0);
  for (const Candidate& c : candidates_) ++count_start_[max_count - c.count + 1];
  for (std::size_t k = 1; k < count_start_.size(); ++k) count_start_[k] += count_start_[k - 1];
  sorted_candidates_.resize(candidates_.size());
  for (const Candidate& c : candidates_) sorted_candidates_[count_start_[max_count - c.count]++] = c;
  candidates_.swap(sorted_candidates_);
  keep_within_budget(features.size());
  const std::size_t budget = candidates_.size();
  // The candidates' locations lie anywhere in a store of millions: prefetch
  // ahead so that their cache misses overlap.
  constexpr std::size_t kAhead = 16;
  for (std::size_t i = 0; i < std::min(kAhead, budget); ++i) __builtin_prefetch(&store[candidates_[i].id]);
  feature_inverses_.clear();
  for (const Feature& feature : features) feature_inverses_.push_back(feature.pose.inverse());
  for (std::size_t i = 0; i < budget; ++i) {
    if (i + kAhead < budget) __builtin_prefetch(&store[candidates_[i + kAhead].id]);
    const MapLocation& loc = store[candidates_[i].id];
    const std::uint32_t f = candidates_[i].feature;
    if (f < features.size()) {
      hypotheses_.push_back(hypothesis_from_inverse(loc.submap, loc.pose(), feature_inverses_[f]));
    } else {
      const SeenFeature& seen = newly_mapped_seen_[f - features.size()];
      newly_mapped_hypotheses_.push_back(
          {hypothesis_from_correspondence(loc.submap, loc.pose(), seen.pose), seen.scan});
    }
  }
  stats_.hypotheses += hypotheses_.size() + newly_mapped_hypotheses_.size();
  stats_.query_s += watch.seconds();
}

void Localizer::keep_within_budget(std::size_t current) {
  // Newly mapped candidates are few and found nowhere else: they get their
  // share of |V_new| before the current scan's many take the rest.
  const std::size_t total = config_.ransac.new_hypotheses_per_scan;
  std::size_t newly = 0;
  for (const Candidate& c : candidates_) newly += c.feature >= current;
  const auto share = static_cast<std::size_t>(config_.newly_mapped_share * static_cast<double>(total));
  std::size_t newly_left = std::min(newly, share);
  std::size_t current_left = total - newly_left;
  std::size_t kept = 0;
  for (const Candidate& c : candidates_) {
    std::size_t& left = c.feature >= current ? newly_left : current_left;
    if (left == 0) continue;
    --left;
    candidates_[kept++] = c;
  }
  candidates_.resize(kept);
}

void Localizer::look_up_newly_mapped(std::size_t current) {
  const std::size_t now = map_.locations().size();
  std::size_t first = map_features_seen_.value_or(now);  // the first scan: the map as found is not new
  map_features_seen_ = now;
  if (first >= now || config_.newly_mapped_candidates == 0 || !seen_[0]) return;
  if (now - first > config_.newly_mapped_per_scan) {
    stats_.newly_mapped_missed += now - first - config_.newly_mapped_per_scan;
    first = now - config_.newly_mapped_per_scan;
  }
  for (std::size_t id = first; id < now; ++id) {
    const std::optional<LshKeyView> key = map_.recent_key(static_cast<std::uint32_t>(id));
    if (!key) {
      ++stats_.newly_mapped_missed;
      continue;
    }
    ++stats_.newly_mapped_features;
    for (const auto& seen : seen_) {
      if (!seen) continue;
      // The seen features' databases follow the map's query settings, which may change under a localizer.
      if (!seen->database.serves(seen_query_)) seen_query_.fit_to(seen->database);
      seen->database.query_counts(*key, config_.newly_mapped_candidates, ids_, counts_, seen_query_);
      for (std::size_t k = 0; k < ids_.size(); ++k) {
        const auto index = static_cast<std::uint32_t>(current + newly_mapped_seen_.size());
        candidates_.push_back({counts_[k], index, static_cast<std::uint32_t>(id)});
        newly_mapped_seen_.push_back(seen->features[ids_[k]]);
      }
      stats_.newly_mapped_pairs += ids_.size();
    }
  }
}

void Localizer::remember_features(const std::vector<Feature>& features) {
  if (config_.newly_mapped_candidates == 0 || features.empty()) return;
  if (!seen_[0] || seen_[0]->features.size() + features.size() > config_.seen_features_kept / 2) {
    seen_[1] = std::move(seen_[0]);
    LshConfig database = map_.config().database;
    database.max_candidates = std::min(database.max_candidates, config_.newly_mapped_touched);
    seen_[0] = std::make_unique<SeenFeatures>(database);
  }
  SeenFeatures& seen = *seen_[0];
  // The forward queries' keys when there were any (an empty map has none).
  const bool keyed = !feature_tags_.empty();
  const std::size_t L = feature_tags_.size() / features.size(), words = feature_sketches_.size() / features.size();
  const auto scan = static_cast<std::uint32_t>(stats_.scans - 1);
  for (std::size_t f = 0; f < features.size(); ++f) {
    const auto id = static_cast<std::uint32_t>(seen.features.size());
    if (keyed) {
      seen.database.insert(LshKeyView{{feature_tags_.data() + f * L, L}, {feature_sketches_.data() + f * words, words}},
                           id);
    } else {
      seen.database.insert(features[f].descriptor, id);
    }
    seen.features.push_back({features[f].pose, scan});
  }
}

void Localizer::random_hypotheses(const std::vector<Feature>& features) {
  const LocationStore& store = map_.locations();
  const std::size_t budget =
      std::min(features.size() * config_.candidates_per_feature, config_.ransac.new_hypotheses_per_scan);
  std::uniform_int_distribution<std::uint32_t> any_location(0, static_cast<std::uint32_t>(store.size() - 1));
  for (std::size_t i = 0; i < budget; ++i) {
    const MapLocation& loc = store[any_location(rng_)];
    hypotheses_.push_back(hypothesis_from_correspondence(loc.submap, loc.pose(), features[i % features.size()].pose));
  }
  stats_.hypotheses += hypotheses_.size();
}

void Localizer::sample_data_points(const LaserScan& scan) {
  data_points_.clear();
  const Pose2& sensor_pose = surface_.sensor_pose;
  const Point2 sensor = sensor_pose.translation();
  for_each_spaced(surface_.points, config_.data_point_spacing, position_of_surface_point, [&](const SurfacePoint& p) {
    data_points_.push_back({static_cast<float>(p.position.x()), static_cast<float>(p.position.y()),
                            static_cast<float>(normal_angle_towards(p.position, p.tangent, sensor)),
                            LocalPoint::Kind::kSurface});
  });
  // Free-space points on evenly spread beams, as many as surface points.
  const auto wanted =
      static_cast<std::size_t>(config_.free_points_per_surface_point * static_cast<double>(data_points_.size()));
  const std::size_t beams = scan.size();
  for (std::size_t k = 0; k < wanted && beams > 0; ++k) {
    const std::size_t i = (k * beams) / wanted;
    if (scan.status(i) != BeamStatus::kValid) continue;
    const double r = scan.ranges[i];
    const double d = std::min(config_.free_point_fraction * r, r - config_.free_point_margin);
    if (d <= 0.2 || r > config_.features.max_range) continue;
    const double a = scan.bearing(i);
    const Point2 q = sensor_pose.transform(Point2(d * std::cos(a), d * std::sin(a)));
    data_points_.push_back({static_cast<float>(q.x()), static_cast<float>(q.y()), 0.0f, LocalPoint::Kind::kFreeSpace});
  }
}

void Localizer::verify_hypotheses() {
  CpuStopwatch watch;
  ransac_.add_scan(data_points_, hypotheses_);
  data_points_end_.push_back(ransac_.data_points_dropped() + ransac_.data_points().size());
  while (data_points_end_.size() > 1 && data_points_end_.front() <= ransac_.data_points_dropped()) {
    data_points_end_.pop_front();
    ++data_points_end_first_;
  }
  prescore_newly_mapped();
  // The order rule reaches back to the data-points of the scans that saw
  // newly mapped places while those hypotheses are young.
  const std::size_t scan = data_points_end_first_ + data_points_end_.size() - 1, points = data_points_end_.back();
  if (reach_back_from_ && scan <= reach_back_until_ && *reach_back_from_ < points) {
    ransac_.reach_back(points - *reach_back_from_);
  } else {
    reach_back_from_.reset();
    ransac_.reach_back(0);
  }
  stats_.data_points += std::min(data_points_.size(), config_.ransac.new_data_points_per_scan);
  ransac_.run(scorer_);
  stats_.ransac_s += watch.seconds();
}

std::size_t Localizer::data_points_by_end_of(std::size_t scan) const {
  return scan < data_points_end_first_ ? 0 : data_points_end_[scan - data_points_end_first_];
}

void Localizer::prescore_newly_mapped() {
  // A newly mapped place was seen scans ago: the newest data-points, which
  // iRANSAC scores first, may all lie elsewhere. Each such hypothesis enters
  // with its score over data-points of the scans around the one that saw it
  // (hypotheses whose scans share a block of 10 share those data-points, and
  // are scored as one batch).
  if (newly_mapped_hypotheses_.empty()) return;
  constexpr std::uint32_t kBlock = 10;
  std::stable_sort(newly_mapped_hypotheses_.begin(), newly_mapped_hypotheses_.end(),
                   [](const auto& a, const auto& b) { return a.second / kBlock < b.second / kBlock; });
  const std::span<const LocalPoint> points = ransac_.data_points();
  const std::size_t w = config_.newly_mapped_scan_window, scans = data_points_end_first_ + data_points_end_.size();
  scored_newly_mapped_.clear();
  prescore_groups_.clear();
  for (std::size_t g = 0; g < newly_mapped_hypotheses_.size();) {
    const std::uint32_t block = newly_mapped_hypotheses_[g].second / kBlock;
    std::size_t e = g;
    for (; e < newly_mapped_hypotheses_.size() && newly_mapped_hypotheses_[e].second / kBlock == block; ++e)
      scored_newly_mapped_.push_back({newly_mapped_hypotheses_[e].first, 0.0, 0});
    const std::size_t first_scan = block * kBlock > w ? block * kBlock - w : 0;
    const std::size_t last_scan = std::min(scans - 1, std::size_t{block} * kBlock + kBlock - 1 + w);
    const std::size_t begin = first_scan > 0 ? data_points_by_end_of(first_scan - 1) : 0,
                      end = data_points_by_end_of(last_scan);
    // (absolute data-point numbers; U may have dropped its oldest: what is left of them)
    const std::size_t dropped = ransac_.data_points_dropped();
    const std::size_t kept_begin = std::max(begin, dropped) - dropped, kept_end = std::max(end, dropped) - dropped;
    const std::size_t n = kept_end > kept_begin ? std::min(kept_end - kept_begin, config_.newly_mapped_points) : 0;
    prescore_groups_.push_back({g, e, kept_begin, kept_end, n});
    if (n > 0) {
      reach_back_from_ = std::min(reach_back_from_.value_or(begin), begin);
      reach_back_until_ = scans - 1 + config_.newly_mapped_reach_scans;
    }
    g = e;
  }
  // Successive halving, as preemptive RANSAC does: every hypothesis on a
  // slice of its data-points (evenly spread over the scans), the better half
  // on the next slice, ..., the last survivors on the rest; the others are
  // iRANSAC's to preempt anyway, and the prescoring is most of a live scan's
  // extra cost. A round goes as one batch of pairs (small batches leave each
  // grid lookup waiting alone), summed in the order of its data-points.
  prescore_hypotheses_.clear();
  for (const ScoredHypothesis& h : scored_newly_mapped_) prescore_hypotheses_.push_back(h.hypothesis);
  const HypothesisBatch batch = batch_.assign(prescore_hypotheses_);
  std::size_t most_points = 0;
  for (const PrescoreGroup& pg : prescore_groups_) most_points = std::max(most_points, pg.n);
  const std::size_t halvings = config_.newly_mapped_halvings, slices = std::size_t{2} << halvings;
  // Each round's data-point numbers k, ascending: 1 in `slices` in the first
  // and the second round, twice as many in each round after, the rest in the
  // last (listed once: a scan's groups are many, often one hypothesis each).
  round_points_.resize(halvings + 1);
  for (auto& ks : round_points_) ks.clear();
  for (std::size_t k = 0; k < most_points; ++k) {
    const std::size_t slice = k % slices;
    round_points_[slice == 0 ? 0 : std::min(halvings, halvings + 1 - static_cast<std::size_t>(std::countr_zero(slice)))]
        .push_back(static_cast<std::uint32_t>(k));
  }
  prescore_keep_.assign(scored_newly_mapped_.size(), 1);
  for (std::size_t round = 0; round <= halvings; ++round) {
    if (round > 0) {  // the better half of those still in
      prescore_means_.clear();
      for (std::size_t i = 0; i < scored_newly_mapped_.size(); ++i) {
        const ScoredHypothesis& h = scored_newly_mapped_[i];
        if (prescore_keep_[i] && h.scored > 0) prescore_means_.push_back(h.mean_score());
      }
      if (prescore_means_.empty()) break;
      const auto middle = prescore_means_.begin() + static_cast<std::ptrdiff_t>((prescore_means_.size() - 1) / 2);
      std::nth_element(prescore_means_.begin(), middle, prescore_means_.end(), std::greater<>());
      const double median = *middle;
      for (std::size_t i = 0; i < scored_newly_mapped_.size(); ++i) {
        const ScoredHypothesis& h = scored_newly_mapped_[i];
        prescore_keep_[i] = prescore_keep_[i] && h.scored > 0 && h.mean_score() >= median;
      }
    }
    // Each hypothesis's pairs in ascending k: its sum adds up in that order.
    pair_points_.clear(), pair_hypotheses_.clear();
    for (const PrescoreGroup& pg : prescore_groups_) {
      if (std::none_of(prescore_keep_.begin() + static_cast<std::ptrdiff_t>(pg.begin),
                       prescore_keep_.begin() + static_cast<std::ptrdiff_t>(pg.end), [](std::uint8_t k) { return k; }))
        continue;  // none of its hypotheses is still in
      std::uint32_t count = 0;
      for (const std::uint32_t k : round_points_[round]) {
        if (k >= pg.n) break;
        ++count;
        const LocalPoint& point = points[pg.kept_begin + k * (pg.kept_end - pg.kept_begin) / pg.n];
        for (std::size_t i = pg.begin; i < pg.end; ++i) {
          if (!prescore_keep_[i]) continue;
          pair_points_.push_back(point);
          pair_hypotheses_.push_back(static_cast<std::uint32_t>(i));
        }
      }
      for (std::size_t i = pg.begin; i < pg.end; ++i)
        if (prescore_keep_[i]) scored_newly_mapped_[i].scored += count;
    }
    prescore_.resize(pair_points_.size());
    if (!prescore_.empty()) scorer_.score_pairs(pair_points_, pair_hypotheses_, batch, prescore_.data());
    for (std::size_t j = 0; j < pair_hypotheses_.size(); ++j)
      scored_newly_mapped_[pair_hypotheses_[j]].score_sum += prescore_[j];
  }
  ransac_.add_scored_hypotheses(scored_newly_mapped_);
}

double Localizer::mean_score_of(const Hypothesis& h, std::size_t window) const {
  const std::span<const LocalPoint> points = ransac_.data_points();
  const std::size_t first = window > 0 && window < points.size() ? points.size() - window : 0;
  if (first >= points.size()) return 0.0;
  PoseGridScorer scorer(map_.occupancy(), map_.free_space(), scorer_config());
  HypothesisBatchBuffer buffer;
  const HypothesisBatch batch = buffer.assign(std::span<const Hypothesis>(&h, 1));
  double sum = 0.0;
  float out = 0.0f;
  for (std::size_t i = first; i < points.size(); ++i) {
    scorer(points[i], batch, &out);
    sum += out;
  }
  return sum / static_cast<double>(points.size() - first);
}

LocalizerStats Localizer::stats() const {
  LocalizerStats s = stats_;
  s.ransac = ransac_.stats();
  s.scan_matcher = matcher_.stats();
  s.report = policy_.stats();
  s.stamp_clash = stamp_clash_.stats();
  s.candidates_touched = query_.candidates_touched;
  s.distinct_candidates = query_.distinct_candidates;
  return s;
}

}  // namespace lshloc
