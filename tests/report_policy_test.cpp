// The report policy against a fake sample scorer: the confidence test, the
// hysteresis, the duels and their support rule, tracking and refinement,
// each checked on hypotheses whose scores the test sets.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <numbers>
#include <optional>
#include <string>
#include <vector>

#include "lshloc/common/error.hpp"
#include "lshloc/localization/report_policy.hpp"

namespace lshloc {
namespace {

/// Every data-point of a sample scores `score_of(h)` for hypothesis h: the
/// test sets which place the local map fits.
class FakeSample final : public SampleScorer {
 public:
  std::function<double(const Hypothesis&)> score_of = [](const Hypothesis&) { return 0.0; };
  /// The newest data-points' scores, when they differ from the rest.
  std::function<double(const Hypothesis&)> newest_score_of;
  std::size_t draws = 0;  ///< samples drawn at random (not taken newest or spread)

  /// The recent window's data-points' scores (a draw from a window), when they differ.
  std::function<double(const Hypothesis&)> recent_score_of;
  std::size_t draw(std::size_t window, std::size_t n) override {
    ++draws;
    recent_ = window > 0;
    return take(n, false);
  }
  std::size_t take_newest(std::size_t n) override {
    recent_ = false;
    return take(n, true);
  }
  std::size_t take_spread(std::size_t n) override {
    recent_ = false;
    return take(n, false);
  }
  void score(std::span<const Hypothesis> hypotheses, std::vector<double>& sums, PairSums* pair) override {
    const auto& of = newest_ && newest_score_of   ? newest_score_of
                     : recent_ && recent_score_of ? recent_score_of
                                                  : score_of;
    sums.assign(hypotheses.size(), 0.0);
    for (std::size_t j = 0; j < hypotheses.size(); ++j) sums[j] = of(hypotheses[j]) * static_cast<double>(n_);
    if (pair != nullptr) {
      const double d = of(hypotheses[0]) - of(hypotheses[1]);
      pair->squared_difference = d * d * static_cast<double>(n_);
      pair->second_absolute = std::abs(of(hypotheses[1])) * static_cast<double>(n_);
    }
  }

 private:
  std::size_t take(std::size_t n, bool newest) {
    n_ = n;
    newest_ = newest;
    return n;
  }
  std::size_t n_ = 0;
  bool newest_ = false;
  bool recent_ = false;
};

Hypothesis at(std::uint32_t submap, double x, double y = 0.0, double theta = 0.0) {
  return {submap, Pose2(x, y, theta)};
}

ScoredHypothesis scored(const Hypothesis& h, double mean, std::uint32_t n) { return {h, mean * n, n}; }

ReportPolicyConfig plain() {
  ReportPolicyConfig c;
  c.place.refine_points = 0;  // report iRANSAC's hypothesis as it is
  c.place.track_reported = false;
  return c;
}

const RansacPreference kPreference{.preference_z = 2.0, .min_score = 30.0, .recent_window = 8000};

using Names = std::vector<std::string>;
/// The parts of the flag's test that keep it down, by name.
Names names(const LocalizationEstimate& e) {
  const auto n = e.flag_down_because.names();
  return Names(n.begin(), n.end());
}

LocalizationEstimate step(ReportPolicy& policy, const std::vector<ScoredHypothesis>& active, SampleScorer& sample,
                          const Pose2& local = {}) {
  std::optional<ScoredHypothesis> best;
  for (const auto& h : active) {
    if (h.score_sum < kPreference.min_score) continue;
    if (!best || h.preference(kPreference.preference_z) > best->preference(kPreference.preference_z)) best = h;
  }
  return policy.report(best, active, local, sample);
}

TEST(ReportPolicy, NoHypothesisNoEstimate) {
  ReportPolicy policy(plain(), kPreference);
  FakeSample sample;
  const LocalizationEstimate e = step(policy, {}, sample);
  EXPECT_FALSE(e.has_estimate);
  EXPECT_FALSE(e.localized);
  EXPECT_TRUE(policy.tracking_children(Pose2()).empty());
}

TEST(ReportPolicy, ConfidentOnlyAfterStableStrongUnrivalledSupport) {
  ReportPolicy policy(plain(), kPreference);
  FakeSample sample;
  sample.score_of = [](const Hypothesis&) { return 0.5; };  // the newest points fit the place
  const Hypothesis place = at(2, 10.0, 5.0, 0.3);
  const std::size_t stable = plain().confidence.stable_scans;
  for (std::size_t i = 0; i < stable; ++i) {
    const LocalizationEstimate e = step(policy, {scored(place, 0.6, 1000)}, sample);
    ASSERT_TRUE(e.has_estimate);
    EXPECT_EQ(e.submap, 2u);
    EXPECT_NEAR(e.pose.x, 10.0, 1e-12);
    EXPECT_EQ(e.localized, i + 1 == stable) << "scan " << i;
  }
  // Too few data-points (N below min_scored): not confident (relative
  // support, which asks for fewer, needs a rival to lead: its own test is below).
  ReportPolicy young(plain(), kPreference);
  for (std::size_t i = 0; i < stable + 2; ++i) EXPECT_FALSE(step(young, {scored(place, 0.6, 400)}, sample).localized);
  // A rival elsewhere within min_margin of C/N: not confident.
  ReportPolicy rivalled(plain(), kPreference);
  for (std::size_t i = 0; i < stable + 2; ++i) {
    const LocalizationEstimate e = step(rivalled, {scored(place, 0.6, 1000), scored(at(0, 3.0), 0.5, 1000)}, sample);
    EXPECT_FALSE(e.localized);
    EXPECT_NEAR(e.margin, 0.1, 1e-9);
  }
}

TEST(ReportPolicy, ARivalThatVanishesStandsForRivalMemoryScans) {
  // iRANSAC drops a rival for a few scans and proposes it again: the rise
  // reads the lead over its C/N when last seen for stable_scans scans.
  const Hypothesis place = at(2, 10.0, 5.0, 0.3), rival = at(0, 3.0);
  const auto replay = [&](std::size_t memory, double rival_whole_map_score) {
    ReportPolicyConfig config = plain();
    config.confidence.stable_scans = memory;
    ReportPolicy policy(config, kPreference);
    FakeSample sample;
    double rival_score = 0.5;  // as the place while iRANSAC holds the rival
    sample.score_of = [&](const Hypothesis& h) { return h.submap == rival.submap ? rival_score : 0.5; };
    for (std::size_t i = 0; i < config.confidence.stable_scans; ++i) {
      const LocalizationEstimate e = step(policy, {scored(place, 0.6, 1000), scored(rival, 0.5, 1000)}, sample);
      EXPECT_FALSE(e.localized);
      EXPECT_NEAR(e.rise_margin, e.margin, 1e-12);
    }
    rival_score = rival_whole_map_score;
    std::vector<LocalizationEstimate> alone;
    for (int i = 0; i < 8; ++i) alone.push_back(step(policy, {scored(place, 0.6, 1000)}, sample));
    return alone;
  };
  // The rival scores as well as the place on the whole local map (lead 0):
  // the flag rises only once the memory has passed.
  const std::vector<LocalizationEstimate> remembered = replay(5, 0.5);
  for (std::size_t i = 0; i < remembered.size(); ++i) {
    EXPECT_NEAR(remembered[i].margin, 0.6, 1e-12) << "iRANSAC holds no rival";
    EXPECT_NEAR(remembered[i].rise_margin, i < 5 ? 0.1 : 0.6, 1e-9) << "scan " << i;
    EXPECT_EQ(remembered[i].localized, i >= 5) << "scan " << i;
  }
  // With stable_scans 2 it stands 2 scans.
  const std::vector<LocalizationEstimate> brief = replay(2, 0.5);
  for (std::size_t i = 0; i < brief.size(); ++i) EXPECT_EQ(brief[i].localized, i >= 2) << "scan " << i;
  // A weaker rival that iRANSAC holds once the first is dropped does not
  // stand for it: the dropped one still does, for its stable_scans.
  {
    ReportPolicy policy(plain(), kPreference);
    FakeSample sample;
    sample.score_of = [](const Hypothesis&) { return 0.5; };
    const Hypothesis weak = at(1, -4.0);
    for (std::size_t i = 0; i < plain().confidence.stable_scans; ++i)
      step(policy, {scored(place, 0.6, 1000), scored(rival, 0.5, 1000)}, sample);
    EXPECT_NEAR(step(policy, {scored(place, 0.6, 1000)}, sample).rise_margin, 0.1, 1e-9);
    for (int i = 0; i < 3; ++i) {
      const LocalizationEstimate e = step(policy, {scored(place, 0.6, 1000), scored(weak, 0.2, 1000)}, sample);
      EXPECT_NEAR(e.margin, 0.4, 1e-9);
      EXPECT_NEAR(e.rise_margin, 0.1, 1e-9) << "scan " << i;
      EXPECT_FALSE(e.localized);
    }
    // A scan without a rival keeps the stronger one standing to its end ...
    EXPECT_NEAR(step(policy, {scored(place, 0.6, 1000)}, sample).rise_margin, 0.1, 1e-9);
    // ... after which the weaker one stands, and the flag rises on its lead.
    const LocalizationEstimate e = step(policy, {scored(place, 0.6, 1000)}, sample);
    EXPECT_NEAR(e.rise_margin, 0.4, 1e-9);
    EXPECT_TRUE(e.localized);
  }
  // A whole-map lead over the remembered rival of min_whole_map_lead
  // (0.3 >= 0.25 on the same points) passes the margin test at once.
  const std::vector<LocalizationEstimate> beaten = replay(5, 0.2);
  EXPECT_TRUE(beaten.front().localized);
  EXPECT_NEAR(beaten.front().whole_map_lead, 0.3, 1e-12);
}

TEST(ReportPolicy, ARivalThatMergesAsThePlacesMirrorImageStandsUntilTheyPart) {
  // The place's mirror image (turned 180 deg about the point the robot
  // nears): at local (x, y) the place reports (10 + x, 5 + y) and the mirror
  // (20 - x, 10 - y), 2 |(5, 2.5) - (x, y)| apart.
  const Hypothesis place = at(2, 10.0, 5.0), mirror = {2, Pose2(20.0, 10.0, std::numbers::pi)};
  const Pose2 apart(3.5, 2.5, 0.0), merged(4.5, 2.5, 0.0), parted(3.0, 2.5, 0.0);  // 3 m, 1 m, 4 m
  const auto replay = [&](double twin_turn_deg) {
    ReportPolicyConfig config = plain();
    config.confidence.rival_twin_turn_deg = twin_turn_deg;
    ReportPolicy policy(config, kPreference);
    FakeSample sample;
    sample.score_of = [](const Hypothesis&) { return 0.5; };  // no whole-map lead over the mirror
    for (std::size_t i = 0; i < config.confidence.stable_scans; ++i) {
      const LocalizationEstimate e = step(policy, {scored(place, 0.6, 1000), scored(mirror, 0.5, 1000)}, sample, apart);
      EXPECT_FALSE(e.localized);
      EXPECT_NEAR(e.margin, 0.1, 1e-9);
    }
    std::vector<LocalizationEstimate> out;
    // Within 2 m the mirror is no rival by position, even while iRANSAC holds it ...
    for (int i = 0; i < 12; ++i)
      out.push_back(step(policy, {scored(place, 0.6, 1000), scored(mirror, 0.5, 1000)}, sample, merged));
    // ... and 4 m apart again, iRANSAC no longer holds it.
    for (int i = 0; i < 8; ++i) out.push_back(step(policy, {scored(place, 0.6, 1000)}, sample, parted));
    return out;
  };
  const std::vector<LocalizationEstimate> mirrored = replay(90.0);
  const std::size_t memory = plain().confidence.stable_scans;
  for (std::size_t i = 0; i < mirrored.size(); ++i) {
    EXPECT_NEAR(mirrored[i].margin, 0.6, 1e-9) << "scan " << i << ": iRANSAC holds no rival by position";
    // The mirror stands while merged, then ages like any remembered rival.
    const bool stands = i < 12 + memory;
    EXPECT_NEAR(mirrored[i].rise_margin, stands ? 0.1 : 0.6, 1e-9) << "scan " << i;
    EXPECT_EQ(mirrored[i].localized, !stands) << "scan " << i;
    EXPECT_EQ(mirrored[i].has_rival, stands) << "scan " << i;
    if (stands) {
      EXPECT_NEAR(std::abs(mirrored[i].rival_pose.theta), std::numbers::pi, 1e-9);
    }
  }
  // Off (>= 180 deg), the merged mirror is the place and the flag rises at once.
  EXPECT_TRUE(replay(180.0).front().localized);
}

TEST(ReportPolicy, AMarginOverARivalScoredOnFewPointsNeedsTheWholeMapLeadToo) {
  const Hypothesis place = at(2, 10.0, 5.0, 0.3), rival = at(0, 3.0);
  const auto replay = [&](double rival_whole_map_score, std::uint32_t rival_n) {
    ReportPolicyConfig config = plain();
    ASSERT_EQ(config.confidence.min_scored / 2, 250u);  // a rival scored on fewer is young
    ReportPolicy policy(config, kPreference);
    FakeSample sample;
    sample.score_of = [&](const Hypothesis& h) { return h.submap == rival.submap ? rival_whole_map_score : 0.5; };
    for (std::size_t i = 0; i < config.confidence.stable_scans; ++i) {
      const LocalizationEstimate e = step(policy, {scored(place, 0.6, 1000), scored(rival, 0.4, rival_n)}, sample);
      EXPECT_NEAR(e.margin, 0.2, 1e-9);  // past min_margin (0.15) on iRANSAC's own points
      EXPECT_EQ(e.rival_scored, rival_n);
      EXPECT_EQ(e.localized, i + 1 == config.confidence.stable_scans && rival_n >= 250) << "scan " << i;
      if (i + 1 == config.confidence.stable_scans && rival_n < 250) {
        EXPECT_NEAR(e.whole_map_lead, 0.5 - rival_whole_map_score, 1e-9);
      }
    }
  };
  replay(0.5, 1000);  // scored on enough points: the margin suffices, whatever the whole map says
  replay(0.5, 100);   // on 100: the same spread points show no lead, so no rise
  // ... unless they show a lead of min_margin too.
  ReportPolicy policy(plain(), kPreference);
  FakeSample sample;
  sample.score_of = [&](const Hypothesis& h) { return h.submap == rival.submap ? 0.3 : 0.5; };
  LocalizationEstimate e;
  for (std::size_t i = 0; i < plain().confidence.stable_scans; ++i)
    e = step(policy, {scored(place, 0.6, 1000), scored(rival, 0.4, 100)}, sample);
  EXPECT_NEAR(e.whole_map_lead, 0.2, 1e-9);
  EXPECT_TRUE(e.localized);
}

TEST(ReportPolicy, AWholeMapLeadPairedWithALeadOnTheNewestPointsPassesTheMargin) {
  // iRANSAC's margin is 0.1 (< min_margin); on the whole-map points the
  // place leads the rival by 0.17 (< min_whole_map_lead alone).
  const Hypothesis place = at(2, 10.0, 5.0, 0.3), rival = at(0, 3.0);
  const auto replay = [&](double rival_newest_score, double paired_newest_lead, std::uint32_t rival_n = 1000) {
    ReportPolicyConfig config = plain();
    EXPECT_EQ(config.confidence.min_margin, 0.15);  // the paired whole-map lead
    config.confidence.strong_lead = paired_newest_lead;
    ReportPolicy policy(config, kPreference);
    FakeSample sample;
    sample.score_of = [&](const Hypothesis& h) { return h.submap == rival.submap ? 0.33 : 0.5; };
    sample.newest_score_of = [&](const Hypothesis& h) { return h.submap == rival.submap ? rival_newest_score : 0.5; };
    LocalizationEstimate e;
    for (std::size_t i = 0; i < config.confidence.stable_scans; ++i) {
      e = step(policy, {scored(place, 0.6, 1000), scored(rival, 0.5, rival_n)}, sample);
      EXPECT_NEAR(e.margin, 0.1, 1e-9);
      EXPECT_NEAR(e.newest_fit, 0.5, 1e-12);
      EXPECT_NEAR(e.newest_lead, 0.5 - rival_newest_score, 1e-12);
      if (i + 1 < config.confidence.stable_scans) {
        EXPECT_FALSE(e.localized) << "scan " << i;
      }
    }
    EXPECT_NEAR(e.whole_map_lead, 0.17, 1e-12);
    return e.localized;
  };
  EXPECT_TRUE(replay(0.2, 0.25));        // the newest points: a lead of 0.3
  EXPECT_FALSE(replay(0.4, 0.25));       // ... of 0.1: the rival fits where the robot went as well
  EXPECT_FALSE(replay(0.2, 3.0));        // the paired test off
  EXPECT_FALSE(replay(0.2, 0.25, 100));  // over a rival scored on 100 points the leads do not pass the margin
}

TEST(ReportPolicy, AtALongKeptPlaceANewHypothesisRisesOnlyOnceScoredOnEnoughPoints) {
  // It must be scored on a quarter of iRANSAC's points per scan (50) for each kept scan, up to 1.5
  // min_scored (750).
  const ReportPolicyConfig config = plain();
  ASSERT_EQ(kPreference.iterations_per_scan, 50u);
  ASSERT_EQ(config.confidence.min_scored, 500u);
  const Hypothesis place = at(2, 10.0, 5.0, 0.3), rival = at(0, 3.0);
  FakeSample sample;
  sample.score_of = [](const Hypothesis&) { return 0.5; };
  const auto after_80_rivalled = [&](const RansacPreference& preference) {
    auto policy = std::make_unique<ReportPolicy>(config, preference);
    // 80 scans at the place, its rival within min_margin: no rise.
    for (std::uint32_t i = 0; i < 80; ++i) {
      EXPECT_FALSE(step(*policy, {scored(place, 0.6, 1000 + 50 * i), scored(rival, 0.5, 1000)}, sample).localized);
    }
    return policy;
  };
  // Preemption cut the place's hypothesis; a new one there, scored on 550
  // data-points, leads alone once the dropped rival no longer stands
  // (stable_scans): 550 < min(12.5 * 85, 750), no rise ...
  auto policy = after_80_rivalled(kPreference);
  for (std::size_t i = 0; i < config.confidence.stable_scans; ++i) step(*policy, {scored(place, 0.6, 550)}, sample);
  LocalizationEstimate e = step(*policy, {scored(place, 0.6, 550)}, sample);
  EXPECT_EQ(e.kept_scans, 85u);
  EXPECT_FALSE(e.has_rival);
  EXPECT_TRUE(e.supported);
  EXPECT_FALSE(e.localized);
  EXPECT_EQ(names(e), Names{"young_hypothesis"});
  // ... until it has been scored on 750.
  EXPECT_FALSE(step(*policy, {scored(place, 0.6, 749)}, sample).localized);
  EXPECT_TRUE(step(*policy, {scored(place, 0.6, 750)}, sample).localized);
  // Where iRANSAC scores nothing per scan, the new hypothesis rises at once.
  RansacPreference none = kPreference;
  none.iterations_per_scan = 0;
  auto off = after_80_rivalled(none);
  for (std::size_t i = 0; i < config.confidence.stable_scans; ++i) step(*off, {scored(place, 0.6, 550)}, sample);
  EXPECT_TRUE(step(*off, {scored(place, 0.6, 550)}, sample).localized);
}

TEST(ReportPolicy, WeakSupportRaisesTheFlagWhereTheMapScoresEveryPlaceLow) {
  // A thin map: the true place scores C/N 0.25 (under min_mean_score) on
  // 3500 data-points, its rival elsewhere 0.04. Relative support, which
  // would pass at C/N 0.25 without the newest-evidence cap, off (a C/N
  // margin it can never reach).
  ReportPolicyConfig config = plain();
  config.confidence.relative_support_min_margin = 2.0;
  const ConfidenceConfig& cc = config.confidence;
  ASSERT_LT(0.25, cc.min_mean_score);
  const Hypothesis place = at(2, 10.0, 5.0, 0.3), rival = at(0, 3.0);
  const std::size_t stable = cc.stable_scans;
  // The flags over stable + 20 scans; the whole-map points score the place
  // `fit` and the rival `rival_fit`, the newest points the place `newest`
  // (the map knows that share of them), the place scored on `n`.
  const auto flags = [&](const ReportPolicyConfig& c, double fit, double rival_fit, std::uint32_t n,
                         double newest = 0.15) {
    FakeSample sample;
    sample.score_of = [&](const Hypothesis& h) { return h.submap == place.submap ? fit : rival_fit; };
    sample.newest_score_of = [&](const Hypothesis& h) { return h.submap == place.submap ? newest : 0.0; };
    ReportPolicy policy(c, kPreference);
    std::vector<bool> out;
    for (std::size_t i = 0; i < stable + 20; ++i)
      out.push_back(step(policy, {scored(place, 0.25, n), scored(rival, 0.04, 3500)}, sample).localized);
    return out;
  };
  // A whole-map lead of 0.2 (>= min_margin): up once
  // stable, and held on.
  const std::vector<bool> up = flags(config, 0.3, 0.1, 3500);
  for (std::size_t i = 0; i < up.size(); ++i) EXPECT_EQ(up[i], i + 1 >= stable) << "scan " << i;
  // A lead of 0.1 (< min_margin), N under weak_support_min_scored, or a map that knows
  // 30% of the newest points (> weak_support_max_newest_evidence: a
  // look-alike in a well-mapped building): never.
  ASSERT_LT(cc.weak_support_max_newest_evidence, 0.3);
  for (const auto& f : {flags(config, 0.3, 0.2, 3500), flags(config, 0.3, 0.1, cc.weak_support_min_scored - 100),
                        flags(config, 0.3, 0.1, 3500, 0.3)})
    EXPECT_EQ(std::count(f.begin(), f.end(), true), 0);
  // No rival standing (none in iRANSAC, none remembered): the "lead" would be the place's own fit. Never.
  FakeSample alone;
  alone.score_of = [](const Hypothesis&) { return 0.3; };
  alone.newest_score_of = [](const Hypothesis&) { return 0.15; };
  ReportPolicy policy(config, kPreference);
  for (std::size_t i = 0; i < stable + 20; ++i) {
    const LocalizationEstimate e = step(policy, {scored(place, 0.25, 3500)}, alone);
    EXPECT_FALSE(e.localized) << "scan " << i;
    EXPECT_FALSE(e.has_rival);
  }
}

TEST(ReportPolicy, TheFlagRisesOnANewestFitIsHeldWhileThePlaceIsKeptAndDropsOnContradiction) {
  const ReportPolicyConfig config = plain();
  const std::size_t stable = config.confidence.stable_scans;
  const Hypothesis place = at(2, 10.0, 5.0, 0.3), rival = at(0, 3.0);
  FakeSample sample;
  // Stable, strong, unrivalled support but the newest points score nothing
  // at the place (newest fit 0 < min_newest_fit): a map silent about the
  // newest points is no evidence against the place ...
  ReportPolicy silence_passes(config, kPreference);
  for (std::size_t i = 0; i < stable; ++i) {
    EXPECT_EQ(step(silence_passes, {scored(place, 0.6, 1000)}, sample).localized, i + 1 == stable) << "scan " << i;
  }
  // ... but not where the little the map says about them contradicts the place (a building the map
  // lacks, where a wall or two agree by chance).
  {
    FakeSample contradicted;
    contradicted.score_of = [](const Hypothesis&) { return 0.3; };
    contradicted.newest_score_of = [](const Hypothesis&) { return -0.02; };
    ReportPolicy policy(config, kPreference);
    for (std::size_t i = 0; i < stable + 3; ++i) {
      const LocalizationEstimate e = step(policy, {scored(place, 0.6, 1000)}, contradicted);
      EXPECT_FALSE(e.localized) << "scan " << i;
      EXPECT_LE(e.newest_evidence, config.confidence.silent_newest_evidence);
    }
  }
  // With a newest fit of 0.5 it rises ...
  ReportPolicy policy(config, kPreference);
  double newest = 0.5;
  // The whole local map fits the place, not its rival: the rival (kept standing by its memory) is no
  // look-alike there.
  sample.score_of = [&](const Hypothesis& h) { return h.submap == rival.submap ? 0.0 : 0.3; };
  sample.newest_score_of = [&](const Hypothesis&) { return newest; };
  LocalizationEstimate e;
  for (std::size_t i = 0; i < stable; ++i) e = step(policy, {scored(place, 0.6, 1000)}, sample);
  EXPECT_TRUE(e.localized);
  // ... and is held while the place is kept: a rival within min_margin, the
  // newest points scoring nothing (the map knows nothing there), ...
  newest = 0.0;
  for (int i = 0; i < 20; ++i) {
    e = step(policy, {scored(place, 0.6, 1000), scored(rival, 0.55, 1000)}, sample);
    EXPECT_TRUE(e.localized) << "scan " << i;
    EXPECT_LT(e.margin, config.confidence.min_margin);
  }
  // ... a penalty of 0.1 per newest point (below both limits) too ...
  newest = -0.1;
  e = step(policy, {scored(place, 0.6, 1000)}, sample);
  EXPECT_TRUE(e.localized);
  // ... but the map contradicting the newest points drops it (penalty 0.5 >
  // hold_max_contradiction), and it rises again only on the rise test.
  newest = -0.5;
  EXPECT_FALSE(step(policy, {scored(place, 0.6, 1000)}, sample).localized);
  newest = 0.5;
  EXPECT_TRUE(step(policy, {scored(place, 0.6, 1000)}, sample).localized);
  // A penalty of 0.12 each scan stays under the one-scan limit (0.13) but
  // its mean passes hold_max_mean_contradiction (0.1) after a few scans.
  newest = -0.12;
  std::size_t held = 0;
  while (held < 50 && step(policy, {scored(place, 0.6, 1000)}, sample).localized) ++held;
  EXPECT_GE(held, 1u);
  EXPECT_LT(held, 50u);
  // A move elsewhere (the rival wins the duel) drops it at once.
  newest = 0.5;
  EXPECT_TRUE(step(policy, {scored(place, 0.6, 1000)}, sample).localized);
  sample.score_of = [&](const Hypothesis& h) { return h.submap == rival.submap ? 0.9 : 0.0; };
  e = step(policy, {scored(rival, 0.9, 5000)}, sample);
  EXPECT_EQ(e.submap, rival.submap);
  EXPECT_FALSE(e.localized);
  sample.score_of = [&](const Hypothesis&) { return 0.3; };
  // So does a whole local map that contradicts the kept place on balance (its fit there < 0) ...
  ReportPolicy balance(config, kPreference);
  for (std::size_t i = 0; i < stable; ++i) e = step(balance, {scored(place, 0.6, 1000)}, sample);
  ASSERT_TRUE(e.localized);
  sample.score_of = [&](const Hypothesis&) { return -0.05; };
  e = step(balance, {scored(place, 0.6, 1000), scored(rival, 0.55, 1000)}, sample);  // no rise anew: a look-alike
  EXPECT_FALSE(e.localized);
  EXPECT_TRUE(e.flag_down_because.contradicted);
  EXPECT_LT(e.whole_map_fit, 0.0);
  sample.score_of = [&](const Hypothesis&) { return 0.3; };
  // ... and a scan without any hypothesis.
  ReportPolicy lost(config, kPreference);
  for (std::size_t i = 0; i < stable; ++i) e = step(lost, {scored(place, 0.6, 1000)}, sample);
  EXPECT_TRUE(e.localized);
  EXPECT_FALSE(step(lost, {}, sample).localized);
  EXPECT_FALSE(step(lost, {scored(place, 0.6, 1000)}, sample).localized);
}

TEST(ReportPolicy, TheWholeMapLeadComparesTheReportedPlaceAndItsRivalOnTheSamePoints) {
  const Hypothesis place = at(1, 4.0), rival = at(2, 0.0);
  FakeSample sample;
  sample.score_of = [&](const Hypothesis& h) { return h.submap == place.submap ? 0.5 : 0.2; };
  ReportPolicyConfig config = plain();
  config.confidence.whole_map_points = 500;
  config.always_score_whole_map = true;
  ReportPolicy policy(config, kPreference);
  LocalizationEstimate e = step(policy, {scored(place, 0.6, 1000), scored(rival, 0.4, 1000)}, sample);
  EXPECT_NEAR(e.whole_map_fit, 0.5, 1e-12);
  EXPECT_NEAR(e.whole_map_lead, 0.3, 1e-12);
  EXPECT_NEAR(e.margin, 0.2, 1e-12);  // iRANSAC's C/N lead, on whatever points each was scored
  // Without a rival the lead is the reported place's own fit, once the
  // last rival no longer stands (stable_scans) ...
  for (std::size_t i = 0; i < config.confidence.stable_scans; ++i) {
    e = step(policy, {scored(place, 0.6, 1000)}, sample);
    EXPECT_NEAR(e.whole_map_lead, 0.3, 1e-12) << "scan " << i;
  }
  e = step(policy, {scored(place, 0.6, 1000)}, sample);
  EXPECT_NEAR(e.whole_map_lead, 0.5, 1e-12);
  // By default it is scored only when the rise hinges on it: not for a
  // place whose C/N already supports it.
  ReportPolicy off(plain(), kPreference);
  e = step(off, {scored(place, 0.6, 1000), scored(rival, 0.4, 1000)}, sample);
  EXPECT_EQ(e.whole_map_fit, 0.0);
  EXPECT_EQ(e.whole_map_lead, 0.0);
}

/// The estimate after stable_scans + 2 scans of `active`, the sample scoring
/// every hypothesis in `place_submap` `place_score` and any other `other_score`
/// (on the newest points `other_newest_score`, where given).
LocalizationEstimate after_steady_scans(const ReportPolicyConfig& config, const std::vector<ScoredHypothesis>& active,
                                        std::uint32_t place_submap, double place_score, double other_score,
                                        std::optional<double> other_newest_score = std::nullopt) {
  ReportPolicy policy(config, kPreference);
  FakeSample sample;
  sample.score_of = [&](const Hypothesis& h) { return h.submap == place_submap ? place_score : other_score; };
  if (other_newest_score) {
    sample.newest_score_of = [&](const Hypothesis& h) {
      return h.submap == place_submap ? place_score : *other_newest_score;
    };
  }
  LocalizationEstimate e;
  for (std::size_t i = 0; i < config.confidence.stable_scans + 2; ++i) e = step(policy, active, sample);
  return e;
}

TEST(ReportPolicy, TheFlagRisesOnRelativeSupportWhereTheMapScoresThePlaceUnderTheAbsoluteTest) {
  // C/N 0.3 is under min_mean_score (0.35): the flag rises only on a lead of
  // min_whole_map_lead (0.2) over the rival on the same
  // whole-map points and of min_newest_fit (0.1) on the
  // newest ones, with N and C/N at least relative_support_min_*, over a rival
  // scored on min_scored / 2 points or more.
  const Hypothesis place = at(1, 4.0), rival = at(2, 0.0);
  const auto flag_after = [&](const ReportPolicyConfig& config, double place_mean, std::uint32_t scored_n,
                              double rival_score, std::optional<double> rival_newest = std::nullopt,
                              std::uint32_t rival_n = 1000, double rival_mean = 0.1) {
    const std::vector<ScoredHypothesis> active{scored(place, place_mean, scored_n), scored(rival, rival_mean, rival_n)};
    const LocalizationEstimate e =
        after_steady_scans(config, active, place.submap, place_mean, rival_score, rival_newest);
    EXPECT_FALSE(e.supported);
    EXPECT_FALSE(e.place_supported);
    return e;
  };
  const ConfidenceConfig& cc = plain().confidence;
  LocalizationEstimate e = flag_after(plain(), 0.3, 1000, 0.0);
  EXPECT_NEAR(e.whole_map_lead, 0.3, 1e-12);
  EXPECT_TRUE(e.localized);
  e = flag_after(plain(), 0.3, 1000, 0.15);  // a lead of 0.15 < min_whole_map_lead
  EXPECT_NEAR(e.whole_map_lead, 0.15, 1e-12);
  EXPECT_FALSE(e.localized);
  // C/N under relative_support_min_mean_score, or N under relative_support_min_scored: no rise on any lead.
  EXPECT_FALSE(flag_after(plain(), cc.relative_support_min_mean_score - 0.05, 1000, 0.0).localized);
  EXPECT_FALSE(flag_after(plain(), 0.3, cc.relative_support_min_scored - 50, 0.0).localized);
  // The rival fits the newest points about as well (a lead of 0.05 there): no rise.
  e = flag_after(plain(), 0.3, 1000, 0.0, 0.25);
  EXPECT_NEAR(e.newest_lead, 0.05, 1e-12);
  EXPECT_FALSE(e.localized);
  // Over a rival scored on 200 points (< min_scored / 2), C/N 0.2: no rise on any lead.
  ASSERT_GT(cc.min_scored / 2, 200u);
  e = flag_after(plain(), 0.3, 1000, 0.0, std::nullopt, 200, 0.2);
  EXPECT_EQ(e.rival_scored, 200u);
  EXPECT_NEAR(e.rise_margin, 0.1, 1e-9);
  EXPECT_FALSE(e.localized);
  // A place that does not itself fit the whole local map by min_margin: its lead stands for nothing.
  e = after_steady_scans(plain(), {scored(place, 0.3, 1000), scored(rival, 0.1, 1000)}, place.submap, 0.1, -0.2);
  EXPECT_NEAR(e.whole_map_lead, 0.3, 1e-12);
  EXPECT_NEAR(e.whole_map_fit, 0.1, 1e-12);
  EXPECT_FALSE(e.localized);
  // With no rival at all (none in iRANSAC, none remembered) there is no lead to stand for support.
  {
    const LocalizationEstimate lone =
        after_steady_scans(plain(), {scored(place, 0.3, 1000)}, place.submap, 0.3, 0.0, std::nullopt);
    EXPECT_FALSE(lone.has_rival);
    EXPECT_FALSE(lone.localized);
    EXPECT_TRUE(lone.flag_down_because.weak_support);
  }
}

TEST(ReportPolicy, TheMarginTestAlsoPassesOnAWholeMapLead) {
  // A supported place whose C/N leads a rival elsewhere by 0.05 only (under
  // min_margin, 0.15): the flag rises once the place leads the rival by
  // min_whole_map_lead (0.2) on the same whole-map points, or by
  // strong_lead (0.25) over a rival scored on few points.
  const Hypothesis place = at(1, 4.0), rival = at(2, 0.0);
  const auto flag_after = [&](const ReportPolicyConfig& config, double rival_score, std::uint32_t rival_n = 1000) {
    const std::vector<ScoredHypothesis> active{scored(place, 0.5, 1000), scored(rival, 0.45, rival_n)};
    const LocalizationEstimate e = after_steady_scans(config, active, place.submap, 0.5, rival_score);
    EXPECT_TRUE(e.supported);
    EXPECT_NEAR(e.margin, 0.05, 1e-9);
    return e;
  };
  const ConfidenceConfig& cc = plain().confidence;
  ASSERT_EQ(cc.min_whole_map_lead, 0.2);
  // Risen on the lead, then held (the hold does not need the comparison).
  EXPECT_TRUE(flag_after(plain(), 0.3).localized);
  LocalizationEstimate e = flag_after(plain(), 0.35);  // a lead of 0.15, compared on every scan
  EXPECT_NEAR(e.whole_map_lead, 0.15, 1e-12);
  EXPECT_FALSE(e.localized);
  // A rival scored on fewer than min_scored / 2: a lead of 0.2 is not enough, strong_lead (0.25) is.
  const std::uint32_t young = cc.min_scored / 2 - 150;
  e = flag_after(plain(), 0.3, young);
  EXPECT_NEAR(e.whole_map_lead, 0.2, 1e-12);
  EXPECT_FALSE(e.localized);
  EXPECT_TRUE(flag_after(plain(), 0.25, young).localized);
  // A lead over a rival the map contradicts, at a place that itself fits the whole local map under
  // min_margin, passes nothing (aces' mirror corridor): a lead of 0.3 at a fit of 0.1.
  {
    const std::vector<ScoredHypothesis> active{scored(place, 0.5, 1000), scored(rival, 0.45, 1000)};
    const LocalizationEstimate low = after_steady_scans(plain(), active, place.submap, 0.1, -0.2);
    EXPECT_NEAR(low.whole_map_lead, 0.3, 1e-12);
    EXPECT_NEAR(low.whole_map_fit, 0.1, 1e-12);
    EXPECT_FALSE(low.localized);
    EXPECT_TRUE(low.flag_down_because.look_alike);
  }
  ReportPolicyConfig never = plain();
  never.confidence.min_whole_map_lead = 3.0;
  never.confidence.strong_lead = 3.0;  // the newest points here lead as the whole map does
  EXPECT_FALSE(flag_after(never, 0.2).localized);
}

TEST(ReportPolicy, TheEstimateSaysWhichPartsOfTheTestKeepTheFlagDown) {
  const ReportPolicyConfig config = plain();
  const std::size_t stable = config.confidence.stable_scans;
  const Hypothesis place = at(2, 10.0, 5.0, 0.3), rival = at(0, 3.0);
  FakeSample sample;
  double newest = 0.5;
  sample.score_of = [&](const Hypothesis&) { return newest; };
  // Strong, unrivalled support: unstable until stable_scans, then up with no reason.
  ReportPolicy policy(config, kPreference);
  for (std::size_t i = 0; i + 1 < stable; ++i)
    EXPECT_EQ(names(step(policy, {scored(place, 0.6, 1000)}, sample)), Names{"unstable"}) << "scan " << i;
  LocalizationEstimate e = step(policy, {scored(place, 0.6, 1000)}, sample);
  EXPECT_TRUE(e.localized);
  EXPECT_FALSE(e.flag_down_because.any());
  // The map contradicting the newest points drops it: contradicted, and they do not fit.
  newest = -0.5;
  e = step(policy, {scored(place, 0.6, 1000)}, sample);
  EXPECT_FALSE(e.localized);
  EXPECT_EQ(names(e), (Names{"newest_misfit", "contradicted"}));
  // Next scan the flag was already down: only the misfit remains.
  EXPECT_EQ(names(step(policy, {scored(place, 0.6, 1000)}, sample)), Names{"newest_misfit"});
  newest = 0.5;
  // Each failing part alone, after a stable run at the place.
  const auto last_of_stable_run = [&](const std::vector<ScoredHypothesis>& active) {
    ReportPolicy fresh(config, kPreference);
    LocalizationEstimate last;
    for (std::size_t i = 0; i < stable + 2; ++i) last = step(fresh, active, sample);
    return last;
  };
  EXPECT_EQ(names(last_of_stable_run({scored(place, 0.2, 1000)})), (Names{"weak_support"}));
  EXPECT_EQ(names(last_of_stable_run({scored(place, 0.6, 400)})), (Names{"few_points"}));
  e = last_of_stable_run({scored(place, 0.6, 1000), scored(rival, 0.5, 1000)});
  EXPECT_EQ(names(e), (Names{"look_alike"}));
  EXPECT_TRUE(e.has_rival);
  EXPECT_EQ(e.rival_submap, rival.submap);
  // Two parts at once: weak and rivalled.
  EXPECT_EQ(names(last_of_stable_run({scored(place, 0.3, 1000), scored(rival, 0.25, 1000)})),
            (Names{"weak_support", "look_alike"}));
  // No estimate: no reasons (there is nothing to be confident about).
  EXPECT_FALSE(step(policy, {}, sample).flag_down_because.any());
}

TEST(ReportPolicy, ConfidenceValueIsTheLogisticModelOfTheReportsEvidence) {
  // Weights on the bias, C/N and the newest-scan fit only: the value is
  // 1 / (1 + exp(-(w0 + w1 C/N + w8 newest_fit))).
  ReportPolicyConfig config = plain();
  config.value_weights = {-2.0, 3.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 4.0, 0.0};
  ReportPolicy policy(config, kPreference);
  FakeSample sample;
  sample.score_of = [](const Hypothesis&) { return -0.25; };
  const Hypothesis place = at(1, 4.0);
  LocalizationEstimate e;
  for (int i = 0; i < 3; ++i) e = step(policy, {scored(place, 0.6, 1000)}, sample);
  EXPECT_NEAR(e.newest_fit, -0.25, 1e-12);
  EXPECT_NEAR(e.newest_evidence, 0.25, 1e-12);
  EXPECT_EQ(e.kept_scans, 2u);
  EXPECT_TRUE(e.supported);
  EXPECT_TRUE(e.place_supported);
  EXPECT_NEAR(e.confidence, 1.0 / (1.0 + std::exp(-(-2.0 + 3.0 * 0.6 + 4.0 * -0.25))), 1e-12);
  // While the flag is up the value takes the flagged weights.
  {
    ReportPolicyConfig up = plain();
    up.value_weights.fill(0.0);
    up.flagged_value_weights = {1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 2.0, 0.0};
    up.confidence.flag_threshold = 0.5;
    ReportPolicy policy(up, kPreference);
    FakeSample fits;
    fits.score_of = [](const Hypothesis&) { return 0.5; };
    LocalizationEstimate last;
    for (int i = 0; i < 10; ++i) last = step(policy, {scored(place, 0.6, 1000)}, fits);
    ASSERT_TRUE(last.localized);
    EXPECT_NEAR(last.confidence, 1.0 / (1.0 + std::exp(-(1.0 + 2.0 * 0.5))), 1e-12);
  }
  // The compiled-in weights are src/localization/confidence_value.json's, over the features report() computes.
  EXPECT_STREQ(value_feature_names()[3], "log1p:scored");
  EXPECT_EQ(ReportPolicyConfig{}.value_weights, default_value_weights(false));
  EXPECT_EQ(ReportPolicyConfig{}.flagged_value_weights, default_value_weights(true));
  EXPECT_NE(default_value_weights(false), default_value_weights(true));
  // The default weights: strong, stable, unrivalled support that the newest
  // scans confirm is worth more than the same support with the newest scans
  // contradicting it.
  ReportPolicy fits(plain(), kPreference), breaks(plain(), kPreference);
  FakeSample good, bad;
  good.score_of = [](const Hypothesis&) { return 0.5; };
  bad.score_of = [](const Hypothesis&) { return -1.0; };
  LocalizationEstimate eg, eb;
  for (int i = 0; i < 10; ++i) {
    eg = step(fits, {scored(place, 0.5, 5000)}, good);
    eb = step(breaks, {scored(place, 0.5, 5000)}, bad);
  }
  EXPECT_GT(eg.confidence, 0.9);
  EXPECT_LT(eb.confidence, 0.1);
  EXPECT_GE(eg.confidence, 0.0);
  EXPECT_LE(eg.confidence, 1.0);
}

TEST(ReportPolicy, TheFlagIsTheValueAtOrAboveTheFlagThreshold) {
  // The model rates every estimate high (bias +20) in one policy and low
  // (bias -20) in the other; the flag alone decides the side of the threshold.
  for (const double bias : {20.0, -20.0}) {
    ReportPolicyConfig config = plain();
    config.value_weights = {bias, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
    config.flagged_value_weights = config.value_weights;
    config.confidence.flag_threshold = 0.9;
    ReportPolicy policy(config, kPreference);
    FakeSample fits, breaks;
    fits.score_of = [](const Hypothesis&) { return 0.5; };
    breaks.score_of = [](const Hypothesis&) { return -1.0; };  // the map contradicts the newest points
    const Hypothesis place = at(1, 4.0);
    std::vector<bool> flags;
    for (int i = 0; i < 14; ++i) {
      const LocalizationEstimate e = step(policy, {scored(place, 0.6, 1000)}, i < 10 ? fits : breaks);
      flags.push_back(e.localized);
      EXPECT_EQ(e.localized, e.confidence >= 0.9) << "bias " << bias << " scan " << i;
      if (e.localized) {
        EXPECT_NEAR(e.confidence, bias > 0 ? 1.0 : 0.9, 1e-8);
      } else {
        EXPECT_LE(e.confidence, bias > 0 ? 0.899 + 1e-12 : 1e-8);
      }
    }
    // The run saw the flag rise and drop.
    EXPECT_FALSE(flags.front());
    EXPECT_TRUE(flags[9]);
    EXPECT_FALSE(flags.back());
  }
  ReportPolicyConfig bad = plain();
  bad.confidence.flag_threshold = 0.0005;
  EXPECT_THROW(bad.validate(), Error);
}

TEST(ReportPolicy, HysteresisKeepsTheReportedPlaceAgainstASmallLead) {
  ReportPolicy policy(plain(), kPreference);
  FakeSample sample;
  const Hypothesis a = at(0, 0.0), b = at(1, 0.0);
  step(policy, {scored(a, 0.5, 1000)}, sample);
  // b leads by 0.01 < switch_margin (0.02): a stays, and no duel is run.
  LocalizationEstimate e = step(policy, {scored(a, 0.5, 1000), scored(b, 0.51, 1000)}, sample);
  EXPECT_EQ(e.submap, 0u);
  EXPECT_EQ(policy.stats().duels, 0u);
  // b leads by 0.1 while a is still in iRANSAC: a duel on the sample decides;
  // the sample says b fits better, so the estimate moves.
  sample.score_of = [&](const Hypothesis& h) { return h.submap == 1 ? 0.8 : 0.2; };
  e = step(policy, {scored(a, 0.5, 1000), scored(b, 0.6, 1000)}, sample);
  EXPECT_EQ(e.submap, 1u);
  EXPECT_EQ(policy.stats().duels, 1u);
  EXPECT_EQ(policy.stats().duels_won, 1u);
}

TEST(ReportPolicy, AChallengerThatLosesTheDuelDoesNotMoveTheEstimate) {
  ReportPolicy policy(plain(), kPreference);
  FakeSample sample;
  const Hypothesis a = at(0, 0.0), b = at(1, 0.0);
  step(policy, {scored(a, 0.5, 1000)}, sample);
  // iRANSAC prefers b (it dropped a), but on the whole local map a fits better.
  sample.score_of = [&](const Hypothesis& h) { return h.submap == 0 ? 0.6 : 0.3; };
  const LocalizationEstimate e = step(policy, {scored(b, 0.7, 800)}, sample);
  EXPECT_EQ(e.submap, 0u);
  EXPECT_EQ(policy.stats().duels, 1u);
  EXPECT_EQ(policy.stats().duels_won, 0u);
  // With a no longer in iRANSAC, the report stands on the duel's sample.
  EXPECT_NEAR(e.mean_score, 0.6, 1e-9);
}

TEST(ReportPolicy, AWellSupportedPlaceYieldsToAnUnsupportedChallengerOnlyOnALargeLead) {
  // b wins the duel, but iRANSAC has scored it on 100 points only: with the
  // rule it needs a lead of unsupported_challenger_margin (0.1), not
  // duel_margin (0.03), to move the estimate; without it any win moves it.
  const Hypothesis a = at(0, 0.0), b = at(1, 0.0);
  for (const double lead : {0.08, 0.3}) {
    for (const bool rule : {true, false}) {
      FakeSample sample;
      sample.score_of = [&](const Hypothesis& h) { return h.submap == 1 ? 0.2 + lead : 0.2; };
      ReportPolicyConfig config = plain();
      config.place.challenger_needs_support = rule;
      ASSERT_EQ(config.place.unsupported_challenger_margin, 0.1);
      ReportPolicy policy(config, kPreference);
      step(policy, {scored(a, 0.5, 1000)}, sample);  // a is well supported
      const LocalizationEstimate e = step(policy, {scored(b, 0.9, 100)}, sample);
      const bool moves = !rule || lead > 0.1;
      EXPECT_EQ(e.submap, moves ? 1u : 0u) << "challenger_needs_support " << rule << ", lead " << lead;
    }
  }
}

TEST(ReportPolicy, AOnceSupportedPlaceWhoseMapIsSilentYieldsOnlyToALargeRecentLead) {
  // a was well supported; iRANSAC has dropped it and prefers the supported
  // b. On the whole local map they tie; on the recent data-points a's map
  // says nothing (scores 0) and b scores `recent`.
  const Hypothesis a = at(0, 0.0), b = at(1, 0.0);
  const auto moves = [&](double recent, double silent_margin) {
    ReportPolicyConfig config = plain();
    config.place.duel_recent_silent_margin = silent_margin;
    ReportPolicy policy(config, kPreference);
    FakeSample sample;
    sample.score_of = [](const Hypothesis&) { return 0.3; };
    sample.recent_score_of = [&](const Hypothesis& h) { return h.submap == 1 ? recent : 0.0; };
    step(policy, {scored(a, 0.5, 1000)}, sample);
    return step(policy, {scored(b, 0.5, 1000)}, sample).submap == 1;
  };
  ASSERT_EQ(plain().place.duel_recent_silent_margin, 0.4);
  EXPECT_TRUE(moves(0.45, 0.4));
  // A lead over duel_recent_margin but under the silent margin: a's silence is no evidence against it.
  EXPECT_FALSE(moves(0.3, 0.4));
  EXPECT_FALSE(moves(0.45, 9.0));  // off
}

TEST(ReportPolicy, APlaceNeverSupportedIsChallengedByTheRivalPlaceThatFitsTheWholeLocalMap) {
  // a is reported on weak support (C/N 0.3 on 200 points); iRANSAC ranks b
  // and c below it, but the whole local map fits c best. With
  // young_place_rivals the estimate moves to c past the hysteresis; without,
  // a stays (it is iRANSAC's best) and no duel is run.
  const Hypothesis a = at(0, 0.0), b = at(1, 0.0), c = at(2, 0.0), c_near = at(2, 0.3);
  const std::vector<ScoredHypothesis> active{scored(a, 0.30, 200), scored(b, 0.29, 200), scored(c, 0.28, 200),
                                             scored(c_near, 0.27, 200)};
  for (const std::size_t rivals : {std::size_t{3}, std::size_t{0}}) {
    ReportPolicyConfig config = plain();
    config.place.young_place_rivals = rivals;
    ReportPolicy policy(config, kPreference);
    FakeSample sample;
    step(policy, {scored(a, 0.30, 200)}, sample);
    sample.score_of = [&](const Hypothesis& h) { return h.submap == 2 ? 0.5 : h.submap == 1 ? 0.25 : 0.2; };
    const LocalizationEstimate e = step(policy, active, sample);
    EXPECT_EQ(e.submap, rivals > 0 ? 2u : 0u) << "young_place_rivals " << rivals;
    // c's place is represented by its most preferred hypothesis, not c_near.
    if (rivals > 0) {
      EXPECT_NEAR(e.pose.x, 0.0, 1e-12);
    }
    EXPECT_EQ(policy.stats().duels, rivals > 0 ? 1u : 0u);
  }
  // Only one rival place allowed: b, whose fit is no better than a's, loses.
  {
    ReportPolicyConfig config = plain();
    config.place.young_place_rivals = 1;
    ReportPolicy policy(config, kPreference);
    FakeSample sample;
    step(policy, {scored(a, 0.30, 200)}, sample);
    sample.score_of = [&](const Hypothesis& h) { return h.submap == 2 ? 0.5 : 0.2; };
    EXPECT_EQ(step(policy, active, sample).submap, 0u);
    EXPECT_EQ(policy.stats().duels_won, 0u);
  }
  // A place kept young_place_scans scans is no longer young: the hysteresis holds it.
  {
    ReportPolicyConfig config = plain();
    config.place.young_place_scans = 2;
    ReportPolicy policy(config, kPreference);
    FakeSample sample;
    for (int i = 0; i < 3; ++i) step(policy, {scored(a, 0.30, 200)}, sample);
    sample.score_of = [&](const Hypothesis& h) { return h.submap == 2 ? 0.5 : 0.2; };
    EXPECT_EQ(step(policy, active, sample).submap, 0u);
    EXPECT_EQ(policy.stats().duels, 0u);
  }
  // Once the reported place has been supported, only iRANSAC's best
  // challenges it, through the hysteresis: a (0.5 on 1000 points) stays.
  {
    ReportPolicy policy(plain(), kPreference);
    FakeSample sample;
    step(policy, {scored(a, 0.5, 1000)}, sample);
    sample.score_of = [&](const Hypothesis& h) { return h.submap == 2 ? 0.5 : 0.2; };
    EXPECT_EQ(step(policy, {scored(a, 0.5, 1000), scored(c, 0.45, 1000)}, sample).submap, 0u);
    EXPECT_EQ(policy.stats().duels, 0u);
  }
}

TEST(ReportPolicy, AYoungPlacesRivalThatLosesAsProposedIsRefinedAndMustThenLeadClearly) {
  // a is reported young and fits the local map at 0.28. The local map fits
  // submap 2 best with the robot at x = 0.3, but iRANSAC proposed it at x = 0:
  // it loses as proposed, and its refinement decides.
  const Hypothesis a = at(0, 0.0), c = at(2, 0.0);
  const std::vector<ScoredHypothesis> active{scored(a, 0.30, 200), scored(c, 0.28, 200)};
  const Pose2 place_c(0.3, 0.0, 0.0);
  struct Case {
    double c_peak;          // submap 2's fit at its best pose
    double refined_margin;  // young_refined_margin (above 2: no refined duel)
    std::uint32_t submap;   // the expected report
  };
  const auto run = [&](const Case& k) {
    ReportPolicyConfig config = plain();
    config.place.refine_points = 400;
    config.place.young_refined_margin = k.refined_margin;
    ReportPolicy policy(config, kPreference);
    FakeSample sample;
    sample.score_of = [&](const Hypothesis& h) {
      return h.submap == 2 ? k.c_peak - translation_distance(h.T_submap_local, place_c) : 0.28;
    };
    step(policy, {scored(a, 0.30, 200)}, sample);
    const LocalizationEstimate e = step(policy, active, sample);
    EXPECT_EQ(e.submap, k.submap) << "peak " << k.c_peak << " margin " << k.refined_margin;
    if (k.submap == 2) {
      EXPECT_NEAR(e.pose.x, 0.3, 0.0126);  // reported at the refined pose
      EXPECT_EQ(policy.stats().refined_duels_won, 1u);
    } else {
      EXPECT_EQ(policy.stats().duels_won, 0u);
    }
    return sample.draws;
  };
  run({0.5, 0.1, 2});
  // A lead of 0.07 after refinement is not enough, though 0.03 would be.
  const std::size_t draws_lost = run({0.35, 0.1, 0});
  // Without the refined duel: the same draws, so a refined challenger that
  // loses leaves every later estimate as it was.
  EXPECT_EQ(run({0.35, 3.0, 0}), draws_lost);
  run({0.5, 3.0, 0});
}

TEST(ReportPolicy, TrackingChildrenSurroundTheReportAtTheRobot) {
  ReportPolicyConfig config = plain();
  config.place.track_reported = true;
  ReportPolicy policy(config, kPreference);
  FakeSample sample;
  const Hypothesis a = at(3, 4.0, -2.0, 0.5);
  step(policy, {scored(a, 0.5, 1000)}, sample);
  const Pose2 robot(20.0, 5.0, 1.0);  // far from the local origin
  const auto children = policy.tracking_children(robot);
  ASSERT_EQ(children.size(), 6u);
  const Pose2 reported = a.T_submap_local * robot;
  for (const Hypothesis& c : children) {
    EXPECT_EQ(c.submap, 3u);
    const Pose2 moved = c.T_submap_local * robot;
    // Each child moves the robot's pose by one step: 0.1 m or 1 degree.
    const double dxy = translation_distance(moved, reported), dth = angle_distance(moved.theta, reported.theta);
    EXPECT_TRUE((std::abs(dxy - 0.1) < 1e-9 && dth < 1e-9) ||
                (dxy < 1e-9 && std::abs(dth - std::numbers::pi / 180.0) < 1e-9))
        << dxy << " " << dth;
  }
}

TEST(ReportPolicy, RefinementMovesTheReportTowardsWhatTheSampleFits) {
  ReportPolicyConfig config = plain();
  config.place.refine_points = 400;
  ReportPolicy policy(config, kPreference);
  FakeSample sample;
  // The sample fits best with the robot 0.15 m further along x than iRANSAC's hypothesis.
  const Pose2 truth(5.15, 1.0, 0.0);
  sample.score_of = [&](const Hypothesis& h) { return 1.0 - translation_distance(h.T_submap_local, truth); };
  const LocalizationEstimate e = step(policy, {scored(at(0, 5.0, 1.0), 0.5, 1000)}, sample);
  EXPECT_NEAR(e.pose.x, 5.15, 0.0126);  // steps 0.1, 0.05, 0.025, 0.0125
  EXPECT_NEAR(e.pose.y, 1.0, 1e-9);
  EXPECT_GE(policy.stats().refine_moves, 2u);
}

}  // namespace
}  // namespace lshloc
