#include "lshloc/localization/localizer.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <span>
#include <utility>

#include "lshloc/common/error.hpp"
#include "lshloc/common/cpu_time.hpp"
#include "lshloc/matching/pose_grid_scorer.hpp"

namespace lshloc {

namespace {


/// Whether two hypotheses put the robot's current pose `local` (in the local
/// frame) at the same place: compared at the robot, not at the local frame's
/// origin, which may lie far away and turn small heading differences into
/// large translations.
bool same_place(const Hypothesis& a, const Hypothesis& b, const Pose2& local, double dist_m, double angle_rad) {
  if (a.submap != b.submap) return false;
  const Pose2 pa = a.T_submap_local * local, pb = b.T_submap_local * local;
  return translation_distance(pa, pb) <= dist_m && angle_distance(pa.theta, pb.theta) <= angle_rad;
}

/// `h` moved by +-step_m along x and y and +-step_rad in heading about the
/// robot's local pose P: T' = T * P * d * P^-1, so that a small move of the
/// robot's global pose stays small however far the local origin lies.
std::array<Hypothesis, 6> moves_about_robot(const Hypothesis& h, const Pose2& P, double step_m, double step_rad) {
  std::array<Hypothesis, 6> out;
  std::size_t k = 0;
  for (const Pose2& d : {Pose2(step_m, 0, 0), Pose2(-step_m, 0, 0), Pose2(0, step_m, 0), Pose2(0, -step_m, 0),
                         Pose2(0, 0, step_rad), Pose2(0, 0, -step_rad)}) {
    out[k++] = {h.submap, h.T_submap_local * (P * d * P.inverse())};
  }
  return out;
}

}  // namespace

void LocalizerConfig::validate() const {
  scan_matcher.validate();
  features.validate();
  ransac.validate();
  if (candidates_per_feature == 0) throw Error("LocalizerConfig: candidates_per_feature must be >= 1");
  if (!(free_space_penalty >= 0.0)) throw Error("LocalizerConfig: free_space_penalty must be >= 0");
  if (!(return_support >= 0.0)) throw Error("LocalizerConfig: return_support must be >= 0");
  if (confidence.stable_scans == 0) throw Error("LocalizerConfig: confidence.stable_scans must be >= 1");
  if (refine_points > 0 && !(refine_step_m > 0.0 && refine_step_deg > 0.0)) {
    throw Error("LocalizerConfig: refine_step_m and refine_step_deg must be > 0 when refine_points > 0");
  }
}

Localizer::Localizer(const GlobalMap& map, LocalizerConfig config)
    : map_(map),
      config_((config.validate(), config)),
      matcher_(config_.scan_matcher),
      extractor_(config_.features),
      ransac_(config_.ransac),
      query_(map.database()),
      scorer_(map.occupancy(), map.free_space(), scorer_config()),
      rng_(config_.seed) {}

PoseGridScorerConfig Localizer::scorer_config() const {
  return {.hit = 1.0f,
          .free = -static_cast<float>(config_.free_space_penalty),
          .unknown = 0.0f,
          .ray_through_wall = -static_cast<float>(config_.free_space_penalty),
          .ray_through_free = static_cast<float>(config_.free_space_agreement),
          .ray_through_contested = -static_cast<float>(config_.contested_penalty),
          .surface_on_return = static_cast<float>(config_.return_support)};
}

void Localizer::generate_hypotheses(const std::vector<Feature>& features) {
  candidates_.clear();
  hypotheses_.clear();
  const LocationStore& store = map_.locations();
  if (features.empty() || store.empty()) return;
  if (config_.hypothesis_source == HypothesisSource::kRandomMapFeatures) {
    const std::size_t budget =
        std::min(features.size() * config_.candidates_per_feature, config_.ransac.new_hypotheses_per_scan);
    std::uniform_int_distribution<std::uint32_t> any_location(0, static_cast<std::uint32_t>(store.size() - 1));
    for (std::size_t i = 0; i < budget; ++i) {
      const MapLocation& loc = store[any_location(rng_)];
      hypotheses_.push_back(hypothesis_from_correspondence(loc.submap, loc.pose(), features[i % features.size()].pose));
    }
    stats_.hypotheses += hypotheses_.size();
    return;
  }
  for (std::size_t f = 0; f < features.size(); ++f) {
    map_.database().query_counts(features[f].descriptor, config_.candidates_per_feature, ids_, counts_, query_);
    for (std::size_t k = 0; k < ids_.size(); ++k) {
      candidates_.push_back({counts_[k], static_cast<std::uint32_t>(f), ids_[k]});
    }
  }
  // Most colliding tables first; keeps each feature's own ranking on ties.
  // A counting sort: counts are at most the number of tables, and a
  // comparison sort of up to k candidates per feature cost as much as the
  // queries themselves (and grew as the buckets filled).
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
}

void Localizer::sample_data_points(const LaserScan& scan, const ScanSurface& surface) {
  data_points_.clear();
  const Pose2& sensor_pose = surface.sensor_pose;
  const Point2 sensor = sensor_pose.translation();
  Point2 last(1e18, 1e18);
  for (const SurfacePoint& p : surface.points) {
    if ((p.position - last).norm() < config_.data_point_spacing) continue;
    last = p.position;
    data_points_.push_back({static_cast<float>(p.position.x()), static_cast<float>(p.position.y()),
                            static_cast<float>(normal_towards(p.position, p.tangent, sensor)),
                            LocalPoint::Kind::kSurface});
  }
  // Free-space points on evenly spread beams, as many as surface points.
  const auto wanted = static_cast<std::size_t>(config_.free_points_per_surface_point *
                                               static_cast<double>(data_points_.size()));
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

LocalizationEstimate Localizer::add_scan(const LaserScan& scan) {
  ++stats_.scans;
  CpuStopwatch watch;
  const ScanMatchResult match = matcher_.add_scan(scan);
  stats_.scan_matching_s += watch.seconds();

  // Features of this scan in the local frame, with recent local scans as context.
  watch = CpuStopwatch();
  const ScanSurface surface = extractor_.surface(scan, match.laser_pose);
  const std::vector<Feature> features =
      extractor_.extract(surface, context_);
  stats_.extract_s += watch.seconds();
  stats_.features += features.size();
  if (context_.empty() || translation_distance(last_context_pose_, match.laser_pose) >= config_.context_spacing) {
    context_.push_back(surface);
    last_context_pose_ = match.laser_pose;
    if (context_.size() > config_.context_scans) context_.erase(context_.begin());
  }

  watch = CpuStopwatch();
  generate_hypotheses(features);
  stats_.query_s += watch.seconds();

  if (config_.track_reported && reported_) {
    // Children of the reported hypothesis, perturbed about the robot's pose;
    // first in line: iRANSAC keeps only the first |V_new| of a scan.
    const auto children = moves_about_robot(*reported_, match.laser_pose, config_.track_step_m,
                                            config_.track_step_deg * M_PI / 180.0);
    hypotheses_.insert(hypotheses_.begin(), children.begin(), children.end());
  }
  sample_data_points(scan, surface);
  watch = CpuStopwatch();
  ransac_.add_scan(data_points_, hypotheses_);
  stats_.data_points += std::min(data_points_.size(), config_.ransac.new_features_per_scan);
  ransac_.run(scorer_);
  stats_.ransac_s += watch.seconds();

  last_local_pose_ = match.laser_pose;
  return estimate(match.laser_pose);
}

LocalizationEstimate Localizer::estimate(const Pose2& local_pose) {
  const ConfidenceConfig& cc = config_.confidence;
  const double same_angle = cc.same_place_deg * M_PI / 180.0;
  LocalizationEstimate e;
  e.local_pose = local_pose;
  std::optional<ScoredHypothesis> best = ransac_.best();
  const std::vector<ScoredHypothesis> active = best ? ransac_.active() : std::vector<ScoredHypothesis>{};
  // Hysteresis: keep reporting the place of the last estimate while its best
  // hypothesis is within switch_margin of the overall best.
  const double z = config_.ransac.preference_z;
  // The confidence test's absolute part: iRANSAC has scored the hypothesis
  // on enough data-points, at a high enough mean.
  const auto supported = [&cc](const ScoredHypothesis& h) {
    return h.scored >= cc.min_scored && h.mean_score() >= cc.min_mean_score;
  };
  if (best && reported_) {
    const ScoredHypothesis* incumbent = nullptr;
    for (const ScoredHypothesis& h : active) {
      if (h.score < config_.ransac.min_score || h.scored == 0) continue;
      if (!same_place(h.hypothesis, *reported_, local_pose, cc.same_place_m, same_angle)) continue;
      if (incumbent == nullptr || h.preference(z) > incumbent->preference(z)) incumbent = &h;
    }
    if (incumbent != nullptr) anchor_ = incumbent->hypothesis;
    if (incumbent != nullptr && best->preference(z) - incumbent->preference(z) <= cc.switch_margin) {
      best = *incumbent;
    } else if (cc.duel_points > 0 && !same_place(best->hypothesis, *reported_, local_pose, cc.same_place_m, same_angle)) {
      ++stats_.duels;
      std::array<Hypothesis, 2> held{*reported_, {}};
      std::size_t held_count = 1;
      if (anchor_ && same_place(*anchor_, *reported_, local_pose, cc.same_place_m, same_angle)) {
        held[held_count++] = *anchor_;
      }
      const std::span<const Hypothesis> incumbents(held.data(), held_count);
      const auto wins = [&](const Duel& duel_result, double margin) {
        const double lead = duel_result.challenger_mean - duel_result.incumbent_mean;
        return lead > margin && lead > cc.duel_z * duel_result.lead_stderr;
      };
      const bool may_win = !reported_supported_ || !cc.challenger_needs_support || supported(*best);
      const Duel d = duel(best->hypothesis, incumbents, 0);
      bool won = may_win && wins(d, cc.duel_margin);
      if (!won && may_win && incumbent == nullptr && cc.duel_recent_margin > 0.0) {
        // iRANSAC dropped every hypothesis at the reported place: only the
        // duel holds it there, on old scans that the local map's drift may
        // have bent. A clear lead on the recent data-points then suffices,
        // unless the place was once well supported and its map knows almost
        // nothing about the recent points.
        const Duel recent = duel(best->hypothesis, incumbents, config_.ransac.recent_window);
        won = wins(recent, cc.duel_recent_margin) &&
              (!reported_supported_ || recent.incumbent_evidence >= cc.duel_recent_min_evidence);
      }
      if (won) {
        ++stats_.duels_won;
        anchor_ = best->hypothesis;
      } else if (incumbent != nullptr) {
        best = *incumbent;
      } else {
        const auto n = static_cast<std::uint32_t>(sample_.size());
        best = ScoredHypothesis{incumbents[d.incumbent], d.incumbent_mean * n, n};
      }
    }
  }
  recent_best_.push_back(best ? std::optional<Hypothesis>(best->hypothesis) : std::nullopt);
  if (recent_best_.size() > cc.stable_scans) recent_best_.pop_front();
  if (!best) return e;
  // Tracking: the reported place follows the local map's drift by a small
  // search on recent data-points, from the last report when the place is
  // kept (or iRANSAC's hypothesis there, whichever fits better).
  const bool kept = reported_ && same_place(best->hypothesis, *reported_, local_pose, cc.same_place_m, same_angle);
  if (config_.refine_points > 0) {
    reported_ = kept ? refine(*reported_, best->hypothesis, local_pose) : refine(best->hypothesis, std::nullopt, local_pose);
  } else {
    reported_ = best->hypothesis;
  }
  reported_supported_ = (kept && reported_supported_) || supported(*best);
  e.has_estimate = true;
  e.submap = reported_->submap;
  e.T_submap_local = reported_->T_submap_local;
  e.pose = e.T_submap_local * local_pose;
  e.mean_score = best->mean_score();
  e.scored = best->scored;

  // The best competitor elsewhere: another submap, or more than 2 m away.
  double rival = 0.0;
  for (const ScoredHypothesis& h : active) {
    if (h.score < config_.ransac.min_score || h.scored == 0) continue;
    if (same_place(h.hypothesis, best->hypothesis, local_pose, 2.0, M_PI)) continue;
    rival = std::max(rival, h.mean_score());
  }
  e.margin = e.mean_score - rival;

  bool stable = recent_best_.size() >= cc.stable_scans;
  for (const auto& h : recent_best_) stable = stable && h && same_place(*h, best->hypothesis, local_pose, cc.same_place_m, same_angle);
  e.localized = stable && supported(*best) && e.margin >= cc.min_margin;
  return e;
}

void Localizer::sample_points(std::size_t window, std::size_t n) {
  const std::size_t size = ransac_.features().size();
  sample_.clear();
  if (size == 0 || n == 0) return;
  const std::size_t first = window > 0 && window < size ? size - window : 0;
  std::uniform_int_distribution<std::size_t> any(first, size - 1);
  for (std::size_t k = 0; k < n; ++k) sample_.push_back(static_cast<std::uint32_t>(any(rng_)));
}

void Localizer::score_on_sample(std::span<const Hypothesis> hypotheses, std::vector<double>& sums,
                                PairSums* pair) {
  const std::size_t m = hypotheses.size();
  batch_submap_.resize(m), batch_tx_.resize(m), batch_ty_.resize(m), batch_cos_.resize(m), batch_sin_.resize(m),
      batch_theta_.resize(m), batch_out_.resize(m);
  for (std::size_t j = 0; j < m; ++j) {
    const Pose2& T = hypotheses[j].T_submap_local;
    batch_submap_[j] = hypotheses[j].submap;
    batch_tx_[j] = static_cast<float>(T.x);
    batch_ty_[j] = static_cast<float>(T.y);
    batch_cos_[j] = static_cast<float>(std::cos(T.theta));
    batch_sin_[j] = static_cast<float>(std::sin(T.theta));
    batch_theta_[j] = static_cast<float>(T.theta);
  }
  const HypothesisBatch batch{batch_submap_.data(), batch_tx_.data(), batch_ty_.data(), batch_cos_.data(),
                              batch_sin_.data(),    batch_theta_.data(), m};
  sums.assign(m, 0.0);
  PairSums two;
  const std::span<const LocalPoint> points = ransac_.features();
  for (std::uint32_t i : sample_) {
    scorer_(points[i], batch, batch_out_.data());
    for (std::size_t j = 0; j < m; ++j) sums[j] += batch_out_[j];
    if (pair != nullptr) {
      const double d = double(batch_out_[0]) - double(batch_out_[1]);
      two.squared_difference += d * d;
      two.second_absolute += std::abs(double(batch_out_[1]));
    }
  }
  if (pair != nullptr) *pair = two;
}

Localizer::Duel Localizer::duel(const Hypothesis& challenger, std::span<const Hypothesis> incumbents,
                                std::size_t window) {
  sample_points(window, config_.confidence.duel_points);
  if (sample_.empty() || incumbents.empty()) return {};
  // The incumbent place is represented by whichever of its hypotheses fits
  // the whole local map best: the tracked report follows the recent drift,
  // iRANSAC's hypothesis there may fit the older scans better.
  std::size_t chosen = 0;
  if (incumbents.size() > 1) {
    score_on_sample(incumbents, sums_);
    chosen = static_cast<std::size_t>(std::max_element(sums_.begin(), sums_.end()) - sums_.begin());
  }
  const std::array<Hypothesis, 2> pair{challenger, incumbents[chosen]};
  PairSums pair_sums;
  score_on_sample(pair, sums_, &pair_sums);
  const auto n = static_cast<double>(sample_.size());
  Duel d{.challenger_mean = sums_[0] / n,
         .incumbent_mean = sums_[1] / n,
         .incumbent_evidence = pair_sums.second_absolute / n,
         .incumbent = chosen};
  const double lead = d.challenger_mean - d.incumbent_mean;
  if (n > 1.0) {
    d.lead_stderr = std::sqrt(std::max(0.0, (pair_sums.squared_difference / n - lead * lead) / (n - 1.0)));
  }
  return d;
}

Hypothesis Localizer::refine(Hypothesis h, const std::optional<Hypothesis>& alternative, const Pose2& local_pose) {
  sample_points(config_.refine_window, config_.refine_points);
  if (sample_.empty()) return h;
  // h's sum over the sample carries from one step to the next: scores do
  // not depend on which other hypotheses share a batch.
  double h_sum = 0.0;
  if (alternative) {
    const std::array<Hypothesis, 2> starts{h, *alternative};
    score_on_sample(starts, sums_);
    h_sum = sums_[0];
    if (sums_[1] - sums_[0] > config_.refine_min_gain * static_cast<double>(sample_.size())) {
      h = *alternative;
      h_sum = sums_[1];
    }
  } else {
    score_on_sample(std::span<const Hypothesis>(&h, 1), sums_);
    h_sum = sums_[0];
  }
  double m = config_.refine_step_m, a = config_.refine_step_deg * M_PI / 180.0;
  for (std::size_t round = 0; round < config_.refine_rounds; ++round) {
    const auto moves = moves_about_robot(h, local_pose, m, a);
    score_on_sample(moves, sums_);
    const auto best = static_cast<std::size_t>(std::max_element(sums_.begin(), sums_.end()) - sums_.begin());
    // Where the map knows little (most points score 0) every move looks
    // alike; a move must win by a clear share of the points, or the pose
    // would wander on noise.
    const double gain = sums_[best] - h_sum;
    if (gain <= 0.0 || gain < config_.refine_min_gain * static_cast<double>(sample_.size())) {
      m *= 0.5, a *= 0.5;
    } else {
      h = moves[best];
      h_sum = sums_[best];
      ++stats_.refine_moves;
    }
  }
  return h;
}

double Localizer::mean_score_of(const Hypothesis& h, std::size_t window) const {
  const std::span<const LocalPoint> points = ransac_.features();
  const std::size_t first = window > 0 && window < points.size() ? points.size() - window : 0;
  if (first >= points.size()) return 0.0;
  PoseGridScorer scorer(map_.occupancy(), map_.free_space(), scorer_config());
  const auto submap = h.submap;
  const auto tx = static_cast<float>(h.T_submap_local.x), ty = static_cast<float>(h.T_submap_local.y);
  const auto c = static_cast<float>(std::cos(h.T_submap_local.theta)), s = static_cast<float>(std::sin(h.T_submap_local.theta));
  const auto theta = static_cast<float>(h.T_submap_local.theta);
  const HypothesisBatch batch{&submap, &tx, &ty, &c, &s, &theta, 1};
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
  return s;
}

}  // namespace lshloc
