#include "lshloc/localization/report_policy.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>
#include <utility>

#include "lshloc/common/error.hpp"

namespace lshloc {

namespace {

double radians(double deg) { return deg * std::numbers::pi / 180.0; }

// An unflagged value stays this far under the flag threshold: the CSVs print 4 decimals.
constexpr double kUnflaggedValueGap = 0.001;

#include "confidence_value.inc"

constexpr bool same_name(const char* a, const char* b) {
  for (; *a != '\0' && *a == *b; ++a, ++b) {
  }
  return *a == *b;
}
constexpr std::array<const char*, kValueFeatures> kComputedFeatures{
    "bias",   "mean_score", "margin",     "log1p:scored",   "log1p:kept_scans", "place_supported",
    "stable", "supported",  "newest_fit", "newest_evidence"};
static_assert(std::size(kValueFeatureNames) == kValueFeatures && std::size(kValueWeights_flag_down) == kValueFeatures &&
                  std::size(kValueWeights_flag_up) == kValueFeatures,
              "confidence_value.json: expected 10 features and 10 weights for each flag state");
static_assert(
    [] {
      for (std::size_t i = 0; i < kValueFeatures; ++i)
        if (!same_name(kValueFeatureNames[i], kComputedFeatures[i])) return false;
      return true;
    }(),
    "confidence_value.json: its features are not the ones report() computes, in that order");

// The failed tests, as the operator reads them: support split into its two parts.
FlagDownReasons reasons_of(const FlagTests& t, const LocalizationEstimate& e, const ConfidenceConfig& cc, bool was_up) {
  FlagDownReasons why;
  why.unstable = !t.stable;
  why.weak_support = !t.supported && e.mean_score < cc.min_mean_score;
  why.few_points = !t.supported && !why.weak_support;
  why.look_alike = !t.unrivalled;
  why.newest_misfit = !t.newest_fits;
  why.young_hypothesis = t.stable && t.supported && t.newest_fits && t.unrivalled && !t.seasoned;
  why.contradicted = was_up && t.kept && !t.not_contradicted;
  return why;
}

}  // namespace

std::array<double, kValueFeatures> default_value_weights(bool flag_up) {
  std::array<double, kValueFeatures> w{};
  std::copy_n(flag_up ? kValueWeights_flag_up : kValueWeights_flag_down, kValueFeatures, w.begin());
  return w;
}

std::array<const char*, kValueFeatures> value_feature_names() { return kComputedFeatures; }

bool same_place(const Hypothesis& a, const RobotPlace& b, const Pose2& local, double dist_m, double angle_rad) {
  if (a.submap != b.submap) return false;
  const Pose2 pa = a.T_submap_local * local;
  return translation_distance(pa, b.robot) <= dist_m && angle_distance(pa.theta, b.robot.theta) <= angle_rad;
}

bool same_place(const Hypothesis& a, const Hypothesis& b, const Pose2& local, double dist_m, double angle_rad) {
  return a.submap == b.submap && same_place(a, RobotPlace(b, local), local, dist_m, angle_rad);
}

std::array<Hypothesis, 6> moves_about_robot(const Hypothesis& h, const Pose2& P, double step_m, double step_rad) {
  std::array<Hypothesis, 6> out;
  std::size_t k = 0;
  for (const Pose2& d : {Pose2(step_m, 0, 0), Pose2(-step_m, 0, 0), Pose2(0, step_m, 0), Pose2(0, -step_m, 0),
                         Pose2(0, 0, step_rad), Pose2(0, 0, -step_rad)}) {
    out[k++] = {h.submap, h.T_submap_local * (P * d * P.inverse())};
  }
  return out;
}

void PlaceConfig::validate() const {
  // Counts of points scored per duel and refinement rounds: beyond these caps a run only exhausts memory
  // or time (each point costs a score, a few ns, per round).
  require(duel_points <= 1000000, "PlaceConfig.duel_points", "<= 1e6", duel_points);
  require(refine_points <= 1000000, "PlaceConfig.refine_points", "<= 1e6", refine_points);
  require(refine_window <= 100000000, "PlaceConfig.refine_window", "<= 1e8", refine_window);
  require(refine_rounds <= 1000, "PlaceConfig.refine_rounds", "<= 1000", refine_rounds);
  require(young_place_rivals <= 64, "PlaceConfig.young_place_rivals", "<= 64", young_place_rivals);
  for (const auto& [name, v] : {std::pair{"unsupported_challenger_margin", unsupported_challenger_margin},
                                {"young_refined_margin", young_refined_margin}}) {
    require(v >= 0.0 && std::isfinite(v), std::string("PlaceConfig.") + name, ">= 0 and finite", v);
  }
  for (const auto& [name, v] : {std::pair{"switch_margin", switch_margin},
                                {"duel_margin", duel_margin},
                                {"duel_z", duel_z},
                                {"duel_recent_margin", duel_recent_margin},
                                {"duel_recent_min_evidence", duel_recent_min_evidence},
                                {"duel_recent_silent_margin", duel_recent_silent_margin},
                                {"refine_min_gain", refine_min_gain}}) {
    require(std::isfinite(v), std::string("PlaceConfig.") + name, "a finite number", v);
  }
  // Tracking and the same-place test move by and compare with these steps: 0 or NaN would never move or match.
  for (const auto& [name, v] : {std::pair{"same_place_m", same_place_m},
                                {"same_place_deg", same_place_deg},
                                {"track_step_m", track_step_m},
                                {"track_step_deg", track_step_deg}}) {
    require(v > 0.0 && std::isfinite(v), std::string("PlaceConfig.") + name, "> 0 and finite", v);
  }
  if (refine_points == 0) return;
  require(refine_step_m > 0.0 && std::isfinite(refine_step_m), "PlaceConfig.refine_step_m",
          "> 0 m and finite when refine_points > 0", refine_step_m);
  require(refine_step_deg > 0.0 && std::isfinite(refine_step_deg), "PlaceConfig.refine_step_deg",
          "> 0 deg and finite when refine_points > 0", refine_step_deg);
}

void ConfidenceConfig::validate() const {
  require(stable_scans >= 1, "ConfidenceConfig.stable_scans", ">= 1", stable_scans);
  require(newest_points <= 1000000, "ConfidenceConfig.newest_points", "<= 1e6", newest_points);
  require(whole_map_points <= 1000000, "ConfidenceConfig.whole_map_points", "<= 1e6", whole_map_points);
  require(rival_twin_turn_deg >= 0.0 && std::isfinite(rival_twin_turn_deg), "ConfidenceConfig.rival_twin_turn_deg",
          ">= 0 and finite", rival_twin_turn_deg);
  for (const auto& [name, v] : {std::pair{"min_mean_score", min_mean_score},
                                {"min_margin", min_margin},
                                {"min_whole_map_lead", min_whole_map_lead},
                                {"strong_lead", strong_lead},
                                {"min_newest_fit", min_newest_fit},
                                {"silent_newest_evidence", silent_newest_evidence},
                                {"hold_max_contradiction", hold_max_contradiction},
                                {"hold_max_mean_contradiction", hold_max_mean_contradiction},
                                {"weak_support_max_newest_evidence", weak_support_max_newest_evidence},
                                {"relative_support_min_mean_score", relative_support_min_mean_score},
                                {"relative_support_min_margin", relative_support_min_margin}}) {
    require(std::isfinite(v), std::string("ConfidenceConfig.") + name, "a finite number", v);
  }
  require(contradiction_smoothing > 0.0 && contradiction_smoothing <= 1.0, "ConfidenceConfig.contradiction_smoothing",
          "in (0, 1]", contradiction_smoothing);
  require(flag_threshold > kUnflaggedValueGap && flag_threshold <= 1.0, "ConfidenceConfig.flag_threshold",
          "in (0.001, 1]", flag_threshold);
}

void ReportPolicyConfig::validate() const {
  place.validate();
  confidence.validate();
  for (double w : value_weights) require(std::isfinite(w), "ReportPolicyConfig.value_weights", "finite numbers", w);
  for (double w : flagged_value_weights)
    require(std::isfinite(w), "ReportPolicyConfig.flagged_value_weights", "finite numbers", w);
}

ReportPolicy::ReportPolicy(ReportPolicyConfig config, RansacPreference ransac)
    : config_((config.validate(), config)), ransac_(ransac) {}

std::vector<const char*> FlagDownReasons::names() const {
  std::vector<const char*> out;
  const std::pair<bool, const char*> all[] = {{unstable, "unstable"},           {weak_support, "weak_support"},
                                              {few_points, "few_points"},       {look_alike, "look_alike"},
                                              {newest_misfit, "newest_misfit"}, {young_hypothesis, "young_hypothesis"},
                                              {contradicted, "contradicted"}};
  for (const auto& [set, name] : all)
    if (set) out.push_back(name);
  return out;
}

std::string FlagDownReasons::joined() const {
  std::string out;
  for (const char* name : names()) out += (out.empty() ? "" : ";") + std::string(name);
  return out;
}

bool ReportPolicy::supported(const ScoredHypothesis& h) const {
  // The confidence test's absolute part: iRANSAC has scored the hypothesis
  // on enough data-points, at a high enough mean.
  return h.scored >= config_.confidence.min_scored && h.mean_score() >= config_.confidence.min_mean_score;
}

std::span<const Hypothesis> ReportPolicy::tracking_children(const Pose2& local_pose) {
  if (!config_.place.track_reported || !reported_) return {};
  children_ =
      moves_about_robot(*reported_, local_pose, config_.place.track_step_m, radians(config_.place.track_step_deg));
  return children_;
}

std::optional<ScoredHypothesis> ReportPolicy::hold_or_move(std::optional<ScoredHypothesis> best,
                                                           std::span<const ScoredHypothesis> active,
                                                           const Pose2& local_pose, SampleScorer& sample) {
  const PlaceConfig& pc = config_.place;
  const double same_angle = radians(pc.same_place_deg);
  const double z = ransac_.preference_z;
  if (!best || !reported_) return best;
  // Hysteresis: keep reporting the place of the last estimate while its best
  // hypothesis is within switch_margin of the overall best.
  const ScoredHypothesis* incumbent = nullptr;
  const RobotPlace reported_place(*reported_, local_pose);
  for (const ScoredHypothesis& h : active) {
    if (h.score_sum < ransac_.min_score || h.scored == 0) continue;
    if (!same_place(h.hypothesis, reported_place, local_pose, pc.same_place_m, same_angle)) continue;
    if (incumbent == nullptr || h.preference(z) > incumbent->preference(z)) incumbent = &h;
  }
  if (incumbent != nullptr) anchor_ = incumbent->hypothesis;
  // A place never supported is challenged by the leading rival places, past the hysteresis.
  const bool young =
      !reported_supported_ && kept_scans_ < pc.young_place_scans && pc.young_place_rivals > 0 && pc.duel_points > 0;
  if (young) {
    // The most preferred hypothesis of each of the young_place_rivals most preferred other places.
    ranked_.clear();
    for (const ScoredHypothesis& h : active) {
      if (h.score_sum >= ransac_.min_score && h.scored > 0) ranked_.push_back(&h);
    }
    std::sort(ranked_.begin(), ranked_.end(), [&](const ScoredHypothesis* a, const ScoredHypothesis* b) {
      return a->preference(z) > b->preference(z);
    });
    rivals_.clear();
    for (const ScoredHypothesis* h : ranked_) {
      if (rivals_.size() == pc.young_place_rivals) break;
      if (same_place(h->hypothesis, reported_place, local_pose, pc.same_place_m, same_angle)) continue;
      const RobotPlace place(h->hypothesis, local_pose);
      const bool taken = std::any_of(rivals_.begin(), rivals_.end(), [&](const ScoredHypothesis* r) {
        return same_place(r->hypothesis, place, local_pose, pc.same_place_m, same_angle);
      });
      if (!taken) rivals_.push_back(h);
    }
    if (rivals_.empty()) return incumbent != nullptr ? std::optional(*incumbent) : best;
    // The rival that fits one sample best; a fresh sample then judges it.
    std::size_t chosen = 0;
    if (rivals_.size() > 1) {
      rival_hypotheses_.clear();
      for (const ScoredHypothesis* r : rivals_) rival_hypotheses_.push_back(r->hypothesis);
      if (sample.draw(0, pc.duel_points) > 0) {
        sample.score(rival_hypotheses_, sums_);
        chosen = static_cast<std::size_t>(std::max_element(sums_.begin(), sums_.end()) - sums_.begin());
      }
    }
    best = *rivals_[chosen];
  } else {
    if (incumbent != nullptr && best->preference(z) - incumbent->preference(z) <= pc.switch_margin) return *incumbent;
    if (pc.duel_points == 0 || same_place(best->hypothesis, *reported_, local_pose, pc.same_place_m, same_angle)) {
      return best;
    }
  }
  ++stats_.duels;
  std::array<Hypothesis, 2> held{*reported_, {}};
  std::size_t held_count = 1;
  if (anchor_ && same_place(*anchor_, *reported_, local_pose, pc.same_place_m, same_angle)) {
    held[held_count++] = *anchor_;
  }
  const std::span<const Hypothesis> incumbents(held.data(), held_count);
  const auto wins = [&](const Duel& duel_result, double margin) {
    const double lead = duel_result.challenger_mean - duel_result.incumbent_mean;
    return lead > margin && lead > pc.duel_z * duel_result.lead_stderr;
  };
  const bool may_win = !reported_supported_ || !pc.challenger_needs_support || supported(*best);
  const Duel d = duel(best->hypothesis, incumbents, 0, sample);
  bool won = wins(d, may_win ? pc.duel_margin : std::max(pc.duel_margin, pc.unsupported_challenger_margin));
  if (!won && may_win && incumbent == nullptr && pc.duel_recent_margin > 0.0) {
    // iRANSAC dropped every hypothesis at the reported place: only the duel
    // holds it there, on old scans that the local map's drift may have bent.
    // A clear lead on the recent data-points then suffices, unless the place
    // was once well supported and its map knows almost nothing about them.
    const Duel recent = duel(best->hypothesis, incumbents, ransac_.recent_window, sample);
    won = wins(recent, pc.duel_recent_margin) &&
          (!reported_supported_ || recent.incumbent_evidence >= pc.duel_recent_min_evidence ||
           wins(recent, pc.duel_recent_silent_margin));
  }
  // The fallback below stands for the incumbent on the duels' sample size, not the refined retry's.
  const auto n = static_cast<std::uint32_t>(last_drawn_);
  if (!won && young && pc.young_refined_margin <= 2.0 && pc.refine_points > 0) {
    // The challenger as iRANSAC proposed it may sit half a metre off its
    // place. Spread points, not drawn: a refined challenger that loses leaves
    // the later draws, and so the estimates, as they were.
    const Hypothesis refined = refine(best->hypothesis, std::nullopt, local_pose, sample, Points::spread);
    const Duel second = duel(refined, incumbents, 0, sample, Points::spread);
    if (wins(second, pc.young_refined_margin)) {
      best->hypothesis = refined;
      won = true;
      ++stats_.refined_duels_won;
    }
  }
  if (won) {
    ++stats_.duels_won;
    anchor_ = best->hypothesis;
    return best;
  }
  if (incumbent != nullptr) return *incumbent;
  return ScoredHypothesis{incumbents[d.incumbent], d.incumbent_mean * n, n};
}

LocalizationEstimate ReportPolicy::report(std::optional<ScoredHypothesis> best,
                                          std::span<const ScoredHypothesis> active, const Pose2& local_pose,
                                          SampleScorer& sample) {
  const ConfidenceConfig& cc = config_.confidence;
  const PlaceConfig& pc = config_.place;
  const double same_angle = radians(pc.same_place_deg);
  LocalizationEstimate e;
  e.local_pose = local_pose;
  best = hold_or_move(best, active, local_pose, sample);
  recent_best_.push_back(best ? std::optional<Hypothesis>(best->hypothesis) : std::nullopt);
  if (recent_best_.size() > cc.stable_scans) recent_best_.pop_front();
  if (!best) {
    flag_ = false;
    weakly_supported_place_ = false;
    last_rival_.reset();
    dropped_rival_.reset();
    return e;
  }
  // Tracking: the reported place follows the local map's drift by a small
  // search on recent data-points, from the last report when the place is
  // kept (or iRANSAC's hypothesis there, whichever fits better).
  const bool kept = reported_ && same_place(best->hypothesis, *reported_, local_pose, pc.same_place_m, same_angle);
  if (pc.refine_points > 0) {
    reported_ = kept ? refine(*reported_, best->hypothesis, local_pose, sample)
                     : refine(best->hypothesis, std::nullopt, local_pose, sample);
  } else {
    reported_ = best->hypothesis;
  }
  reported_supported_ = (kept && reported_supported_) || supported(*best);
  kept_scans_ = kept ? kept_scans_ + 1 : 0;
  e.has_estimate = true;
  e.submap = reported_->submap;
  e.T_submap_local = reported_->T_submap_local;
  e.pose = e.T_submap_local * local_pose;
  e.mean_score = best->mean_score();
  e.scored = best->scored;

  // The best competitor elsewhere: another submap, or more than 2 m away.
  // Only a positive mean score counts as a rival.
  const ScoredHypothesis* rival = nullptr;
  const RobotPlace best_place(best->hypothesis, local_pose);
  for (const ScoredHypothesis& h : active) {
    if (h.score_sum < ransac_.min_score || h.scored == 0) continue;
    if (same_place(h.hypothesis, best_place, local_pose, 2.0, std::numbers::pi)) continue;
    if (h.mean_score() > (rival ? rival->mean_score() : 0.0)) rival = &h;
  }
  e.margin = e.mean_score - (rival ? rival->mean_score() : 0.0);
  e.rise_margin = e.margin;
  // The rise reads the stronger of iRANSAC's rival and the one it last
  // dropped, for stable_scans scans after that one was last seen.
  ++reports_;
  std::optional<SeenRival> current;
  if (rival != nullptr) {
    current = SeenRival{rival->hypothesis, rival->mean_score(), rival->scored, reports_};
    last_rival_ = current;
  } else if (last_rival_ && (!dropped_rival_ || (last_rival_->seen_at > dropped_rival_->seen_at &&
                                                 (reports_ - dropped_rival_->seen_at > cc.stable_scans ||
                                                  last_rival_->mean >= dropped_rival_->mean)))) {
    dropped_rival_ = last_rival_;
  }
  const SeenRival* standing = current ? &*current : nullptr;
  if (dropped_rival_ && reports_ - dropped_rival_->seen_at <= cc.stable_scans) {
    const bool near = same_place(dropped_rival_->hypothesis, best_place, local_pose, 2.0, std::numbers::pi);
    const bool mirror =
        near && !same_place(dropped_rival_->hypothesis, best_place, local_pose, 2.0, radians(cc.rival_twin_turn_deg));
    if (mirror) dropped_rival_->seen_at = reports_;
    if ((!near || mirror) && (standing == nullptr || dropped_rival_->mean > standing->mean)) {
      standing = &*dropped_rival_;
    }
  }
  if (standing != nullptr) {
    e.rise_margin = e.mean_score - standing->mean;
    e.has_rival = true;
    e.rival_submap = standing->hypothesis.submap;
    e.rival_pose = standing->hypothesis.T_submap_local * local_pose;
    e.rival_mean_score = standing->mean;
    e.rival_scored = standing->scored;
  }
  bool stable = recent_best_.size() >= cc.stable_scans;
  for (const auto& h : recent_best_) {
    stable = stable && h && same_place(*h, best->hypothesis, local_pose, pc.same_place_m, same_angle);
  }
  bool newest_known = false;
  if (cc.newest_points > 0) {
    const std::size_t taken = sample.take_newest(cc.newest_points);
    newest_known = taken > 0;
    if (taken > 0) {
      // The place twice (its evidence comes as the pair's second), then the rival.
      const std::array<Hypothesis, 3> newest{*reported_, *reported_, standing ? standing->hypothesis : *reported_};
      SampleScorer::PairSums pair;
      sample.score(std::span(newest).first(standing ? 3 : 2), sums_, &pair);
      e.newest_fit = sums_[0] / static_cast<double>(taken);
      e.newest_evidence = pair.second_absolute / static_cast<double>(taken);
      e.newest_lead = standing ? (sums_[0] - sums_[2]) / static_cast<double>(taken) : e.newest_fit;
    }
  }
  e.stable = stable;
  e.supported = supported(*best);
  const auto score_whole_map = [&] {
    if (e.whole_map_scored || cc.whole_map_points == 0) return;
    const std::size_t taken = sample.take_spread(cc.whole_map_points);
    e.whole_map_scored = taken > 0;
    if (taken > 0) {
      const std::array<Hypothesis, 2> pair{*reported_, standing ? standing->hypothesis : *reported_};
      sample.score(std::span(pair).first(standing ? 2 : 1), sums_);
      e.whole_map_fit = sums_[0] / static_cast<double>(taken);
      e.whole_map_lead = standing ? (sums_[0] - sums_[1]) / static_cast<double>(taken) : e.whole_map_fit;
    }
  };
  if (config_.always_score_whole_map || flag_) score_whole_map();  // the hold reads the whole-map fit
  // A rival scored on few points may have displaced a well-scored one as the best elsewhere by C/N: a
  // margin over it needs the whole-map lead too, a lead alone must be strong, and relative support is off.
  const bool young_rival = standing != nullptr && standing->scored < cc.min_scored / 2;
  // The evidence tests, each named for what it asks of the place.
  FlagTests t;
  // Weak support (a thin map: it scores few of the newest points) and relative support (a clear lead)
  // stand in for the absolute test on their whole-map lead over a standing rival; with none standing
  // the "lead" is the place's own fit, and a robot outside a one-building map rose on it.
  const bool weak_candidate = !e.supported && standing != nullptr && best->scored >= cc.weak_support_min_scored &&
                              newest_known && e.newest_evidence <= cc.weak_support_max_newest_evidence;
  const bool relative_candidate =
      !e.supported && standing != nullptr && !young_rival && best->scored >= cc.relative_support_min_scored &&
      e.mean_score >= cc.relative_support_min_mean_score && e.rise_margin >= cc.relative_support_min_margin &&
      newest_known && e.newest_lead >= cc.min_newest_fit;
  if (weak_candidate || relative_candidate) score_whole_map();
  // A lead is evidence for the place only where the place itself explains the whole local map.
  const auto fits_whole_map = [&] { return e.whole_map_scored && e.whole_map_fit >= cc.min_margin; };
  const bool weakly_supported =
      e.whole_map_scored && ((weak_candidate && e.whole_map_lead >= cc.min_margin) ||
                             (relative_candidate && e.whole_map_lead >= cc.min_whole_map_lead && fits_whole_map()));
  weakly_supported_place_ = kept && (weakly_supported_place_ || weakly_supported);
  t.supported = e.supported || weakly_supported;
  t.stable = stable;
  // A silent map is no evidence against the place; one that contradicts the little it says is.
  t.newest_fits = !newest_known || e.newest_fit >= cc.min_newest_fit ||
                  (e.newest_evidence <= cc.silent_newest_evidence && e.newest_fit >= 0.0);
  // Unrivalled: the C/N margin (confirmed on the same whole-map points over a young rival), or a lead on
  // the whole-map points (strong over a young rival, or paired with a strong lead on the newest ones).
  const bool margin_passes = e.rise_margin >= cc.min_margin;
  const bool lead_decides = t.stable && t.newest_fits && t.supported;
  if (lead_decides && (!margin_passes || young_rival)) score_whole_map();
  if (margin_passes) {
    t.unrivalled = !young_rival || !lead_decides || (e.whole_map_scored && e.whole_map_lead >= cc.min_margin);
  } else {
    const double lead = young_rival ? cc.strong_lead : cc.min_whole_map_lead;
    const bool paired =
        newest_known && !young_rival && e.whole_map_lead >= cc.min_margin && e.newest_lead >= cc.strong_lead;
    t.unrivalled = lead_decides && fits_whole_map() && (e.whole_map_lead >= lead || paired);
  }
  // A hypothesis much younger than the place it stands for is judged once it has caught up: a quarter
  // of the points iRANSAC scores a hypothesis on per scan, per kept scan, up to 1.5 min_scored.
  t.seasoned = static_cast<double>(best->scored) >=
               std::min(0.25 * static_cast<double>(ransac_.iterations_per_scan) * kept_scans_, 1.5 * cc.min_scored);
  // The hold: kept, once supported, the newest points not contradicted (one scan and on average), and the
  // whole local map not contradicting the place on balance.
  const double contradiction = newest_known ? 0.5 * (e.newest_evidence - e.newest_fit) : 0.0;
  mean_contradiction_ =
      flag_ ? (1.0 - cc.contradiction_smoothing) * mean_contradiction_ + cc.contradiction_smoothing * contradiction
            : contradiction;
  t.kept = kept;
  t.once_supported = reported_supported_ || weakly_supported_place_;
  t.not_contradicted = contradiction <= cc.hold_max_contradiction &&
                       mean_contradiction_ <= cc.hold_max_mean_contradiction &&
                       (!e.whole_map_scored || e.whole_map_fit >= 0.0);
  const bool was_up = flag_;
  flag_ = t.rises() || (was_up && t.holds());
  e.localized = flag_;
  e.place_supported = reported_supported_;
  e.kept_scans = kept_scans_;
  if (!flag_) e.flag_down_because = reasons_of(t, e, cc, was_up);
  // The value, in the order of kComputedFeatures, with the weights of the flag's state.
  const std::array<double, kValueFeatures> f{1.0,
                                             e.mean_score,
                                             e.margin,
                                             std::log1p(static_cast<double>(e.scored)),
                                             std::log1p(static_cast<double>(e.kept_scans)),
                                             e.place_supported ? 1.0 : 0.0,
                                             e.stable ? 1.0 : 0.0,
                                             e.supported ? 1.0 : 0.0,
                                             e.newest_fit,
                                             e.newest_evidence};
  const auto& w = flag_ ? config_.flagged_value_weights : config_.value_weights;
  double z = 0.0;
  for (std::size_t i = 0; i < f.size(); ++i) z += w[i] * f[i];
  const double value = 1.0 / (1.0 + std::exp(-z));
  e.confidence = flag_ ? std::max(value, cc.flag_threshold) : std::min(value, cc.flag_threshold - kUnflaggedValueGap);
  return e;
}

ReportPolicy::Duel ReportPolicy::duel(const Hypothesis& challenger, std::span<const Hypothesis> incumbents,
                                      std::size_t window, SampleScorer& sample, Points points) {
  const std::size_t wanted = config_.place.duel_points;
  last_drawn_ = points == Points::spread ? sample.take_spread(wanted) : sample.draw(window, wanted);
  if (last_drawn_ == 0 || incumbents.empty()) return {};
  // The incumbent place is represented by whichever of its hypotheses fits
  // the whole local map best: the tracked report follows the recent drift,
  // iRANSAC's hypothesis there may fit the older scans better.
  std::size_t chosen = 0;
  if (incumbents.size() > 1) {
    sample.score(incumbents, sums_);
    chosen = static_cast<std::size_t>(std::max_element(sums_.begin(), sums_.end()) - sums_.begin());
  }
  const std::array<Hypothesis, 2> pair{challenger, incumbents[chosen]};
  SampleScorer::PairSums pair_sums;
  sample.score(pair, sums_, &pair_sums);
  const auto n = static_cast<double>(last_drawn_);
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

Hypothesis ReportPolicy::refine(Hypothesis h, const std::optional<Hypothesis>& alternative, const Pose2& local_pose,
                                SampleScorer& sample, Points points) {
  last_drawn_ = points == Points::spread ? sample.take_spread(config_.place.refine_points)
                                         : sample.draw(config_.place.refine_window, config_.place.refine_points);
  if (last_drawn_ == 0) return h;
  const double min_gain = config_.place.refine_min_gain * static_cast<double>(last_drawn_);
  // h's sum over the sample carries from one step to the next: scores do
  // not depend on which other hypotheses share a batch.
  double h_sum = 0.0;
  if (alternative) {
    const std::array<Hypothesis, 2> starts{h, *alternative};
    sample.score(starts, sums_);
    h_sum = sums_[0];
    if (sums_[1] - sums_[0] > min_gain) {
      h = *alternative;
      h_sum = sums_[1];
    }
  } else {
    sample.score(std::span<const Hypothesis>(&h, 1), sums_);
    h_sum = sums_[0];
  }
  double m = config_.place.refine_step_m, a = radians(config_.place.refine_step_deg);
  for (std::size_t round = 0; round < config_.place.refine_rounds; ++round) {
    const auto moves = moves_about_robot(h, local_pose, m, a);
    sample.score(moves, sums_);
    const auto best = static_cast<std::size_t>(std::max_element(sums_.begin(), sums_.end()) - sums_.begin());
    // Where the map knows little (most points score 0) every move looks
    // alike: a move must win by a clear share of the points, or the pose
    // would wander on noise.
    const double gain = sums_[best] - h_sum;
    if (gain <= 0.0 || gain < min_gain) {
      m *= 0.5, a *= 0.5;
    } else {
      h = moves[best];
      h_sum = sums_[best];
      ++stats_.refine_moves;
    }
  }
  return h;
}

}  // namespace lshloc
