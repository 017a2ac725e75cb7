#include "lshloc/localization/localizer.hpp"

#include <algorithm>
#include <cmath>
#include <span>

#include "lshloc/common/cpu_time.hpp"
#include "lshloc/common/error.hpp"
#include "lshloc/geometry/voxel_thinning.hpp"

namespace lshloc {

/// The report policy's samples: uniform draws from iRANSAC's data-points U,
/// scored by the pose-grid scorer.
class Localizer::DataPointSample final : public SampleScorer {
 public:
  DataPointSample(const IncrementalRansac& ransac, PoseGridScorer& scorer, std::mt19937_64& rng)
      : ransac_(ransac), scorer_(scorer), rng_(rng) {}

  std::size_t draw(std::size_t window, std::size_t n) override {
    const std::size_t size = ransac_.features().size();
    sample_.clear();
    if (size == 0 || n == 0) return 0;
    const std::size_t first = window > 0 && window < size ? size - window : 0;
    std::uniform_int_distribution<std::size_t> any(first, size - 1);
    for (std::size_t k = 0; k < n; ++k) sample_.push_back(static_cast<std::uint32_t>(any(rng_)));
    return sample_.size();
  }

  std::size_t take_newest(std::size_t n) override {
    const std::size_t size = ransac_.features().size();
    sample_.clear();
    for (std::size_t i = size - std::min(n, size); i < size; ++i) sample_.push_back(static_cast<std::uint32_t>(i));
    return sample_.size();
  }

  void score(std::span<const Hypothesis> hypotheses, std::vector<double>& sums, PairSums* pair) override {
    const HypothesisBatch batch = batch_.assign(hypotheses);
    const std::size_t m = hypotheses.size();
    out_.resize(m);
    sums.assign(m, 0.0);
    PairSums two;
    const std::span<const LocalPoint> points = ransac_.features();
    for (std::uint32_t i : sample_) {
      scorer_(points[i], batch, out_.data());
      for (std::size_t j = 0; j < m; ++j) sums[j] += out_[j];
      if (pair != nullptr) {
        const double d = double(out_[0]) - double(out_[1]);
        two.squared_difference += d * d;
        two.second_absolute += std::abs(double(out_[1]));
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
  std::vector<float> out_;
};

void LocalizerConfig::validate() const {
  scan_matcher.validate();
  features.validate();
  ransac.validate();
  report.validate();
  require(candidates_per_feature >= 1, "LocalizerConfig.candidates_per_feature", ">= 1", candidates_per_feature);
  require(free_space_penalty >= 0.0, "LocalizerConfig.free_space_penalty", ">= 0", free_space_penalty);
  require(return_support >= 0.0, "LocalizerConfig.return_support", ">= 0", return_support);
  require(contested_penalty >= 0.0, "LocalizerConfig.contested_penalty", ">= 0", contested_penalty);
}

Localizer::Localizer(const GlobalMap& map, LocalizerConfig config)
    : map_(map),
      config_((config.validate(), config)),
      matcher_(config_.scan_matcher),
      extractor_(config_.features),
      ransac_(config_.ransac),
      query_(map.database()),
      scorer_(map.occupancy(), map.free_space(), scorer_config()),
      policy_(config_.report, {.preference_z = config_.ransac.preference_z,
                               .min_score = config_.ransac.min_score,
                               .recent_window = config_.ransac.recent_window}),
      context_(config_.context_scans, config_.context_spacing),
      rng_(config_.seed),
      sample_(std::make_unique<DataPointSample>(ransac_, scorer_, rng_)) {}

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
  // The reported place's tracking children go first: iRANSAC keeps only the
  // first |V_new| hypotheses of a scan.
  const std::span<const Hypothesis> children = policy_.tracking_children(local_pose);
  hypotheses_.insert(hypotheses_.begin(), children.begin(), children.end());
  sample_data_points(scan);
  verify_hypotheses();
  last_local_pose_ = local_pose;
  const std::optional<ScoredHypothesis> best = ransac_.best();
  const std::vector<ScoredHypothesis> active = best ? ransac_.active() : std::vector<ScoredHypothesis>{};
  return policy_.report(best, active, local_pose, *sample_);
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
  const LocationStore& store = map_.locations();
  if (features.empty() || store.empty()) {
    stats_.query_s += watch.seconds();
    return;
  }
  if (config_.hypothesis_source == HypothesisSource::kRandomMapFeatures) {
    random_hypotheses(features);
    stats_.query_s += watch.seconds();
    return;
  }
  for (std::size_t f = 0; f < features.size(); ++f) {
    map_.database().query_counts(features[f].descriptor, config_.candidates_per_feature, ids_, counts_, query_);
    for (std::size_t k = 0; k < ids_.size(); ++k) {
      candidates_.push_back({counts_[k], static_cast<std::uint32_t>(f), ids_[k]});
    }
  }
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
  const std::size_t budget = std::min(candidates_.size(), config_.ransac.new_hypotheses_per_scan);
  // The candidates' locations lie anywhere in a store of millions: prefetch
  // ahead so that their cache misses overlap.
  constexpr std::size_t kAhead = 16;
  for (std::size_t i = 0; i < std::min(kAhead, budget); ++i) __builtin_prefetch(&store[candidates_[i].id]);
  for (std::size_t i = 0; i < budget; ++i) {
    if (i + kAhead < budget) __builtin_prefetch(&store[candidates_[i + kAhead].id]);
    const MapLocation& loc = store[candidates_[i].id];
    hypotheses_.push_back(
        hypothesis_from_correspondence(loc.submap, loc.pose(), features[candidates_[i].feature].pose));
  }
  stats_.hypotheses += hypotheses_.size();
  stats_.query_s += watch.seconds();
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
                            static_cast<float>(normal_towards(p.position, p.tangent, sensor)),
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
  stats_.data_points += std::min(data_points_.size(), config_.ransac.new_features_per_scan);
  ransac_.run(scorer_);
  stats_.ransac_s += watch.seconds();
}

double Localizer::mean_score_of(const Hypothesis& h, std::size_t window) const {
  const std::span<const LocalPoint> points = ransac_.features();
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
  return s;
}

}  // namespace lshloc
