#include "lshloc/matching/pose_grid.hpp"

#include <gtest/gtest.h>

#include <map>
#include <numbers>
#include <random>
#include <set>
#include <vector>

#include "lshloc/common/error.hpp"
#include "lshloc/matching/pose_grid_scorer.hpp"
#include "test_support.hpp"

namespace lshloc {
namespace {

using test::kPi;

/// The brute-force reference: cell -> flags in a std::map, the tolerance
/// window enumerated cell by cell.
class BruteForceGrid {
 public:
  explicit BruteForceGrid(const PoseGridHashMap& shape) : shape_(shape) {}
  void mark(const PoseCell& c, CellFlags f) { cells_[c] |= f; }
  std::vector<PoseCell> window(const PoseCell& c) const {
    const auto& cfg = shape_.config();
    std::set<PoseCell> out;
    for (int dx = -cfg.xy_tolerance; dx <= cfg.xy_tolerance; ++dx)
      for (int dy = -cfg.xy_tolerance; dy <= cfg.xy_tolerance; ++dy)
        for (int dt = -cfg.theta_tolerance; dt <= cfg.theta_tolerance; ++dt) {
          const int bins = cfg.theta_bins;
          out.insert({c.submap, c.ix + dx, c.iy + dy, ((c.itheta + dt) % bins + bins) % bins});
        }
    return {out.begin(), out.end()};
  }
  CellFlags window_or(const PoseCell& c) const {
    CellFlags f = 0;
    for (const PoseCell& w : window(c)) {
      auto it = cells_.find(w);
      if (it != cells_.end()) f |= it->second;
    }
    return f;
  }
  std::size_t size() const { return cells_.size(); }

 private:
  const PoseGridHashMap& shape_;
  std::map<PoseCell, CellFlags> cells_;
};

struct MarkedPose {
  std::uint32_t submap;
  double x, y, theta;
  CellFlags flags;
};

std::vector<MarkedPose> random_marks(std::size_t n, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> xy(-30.0, 30.0), th(-kPi, kPi);
  std::uniform_int_distribution<std::uint32_t> sub(0, 4), fl(1, 3);
  std::vector<MarkedPose> out;
  for (std::size_t i = 0; i < n; ++i)
    out.push_back({sub(rng), xy(rng), xy(rng), th(rng), static_cast<CellFlags>(fl(rng))});
  return out;
}

/// Random probe poses: half near marked poses (so both answers occur), half anywhere.
std::vector<MarkedPose> probe_poses(const std::vector<MarkedPose>& marks, std::size_t n, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> dxy(-0.4, 0.4), dth(-0.3, 0.3);
  std::uniform_int_distribution<std::size_t> pick(0, marks.size() - 1);
  auto out = random_marks(n, seed + 1);
  for (std::size_t i = 0; i < n; i += 2) {
    const auto& m = marks[pick(rng)];
    out[i] = {m.submap, m.x + dxy(rng), m.y + dxy(rng), m.theta + dth(rng), 0};
  }
  return out;
}

/// Cells the table must hold: the marked cells, or in kDilateAtInsert mode
/// the union of their tolerance windows.
std::size_t expected_bins(const BruteForceGrid& ref, const std::vector<PoseCell>& marked, ToleranceMode mode) {
  std::set<PoseCell> cells;
  for (const PoseCell& c : marked) {
    if (mode == ToleranceMode::kProbeNeighbours) {
      cells.insert(c);
    } else {
      for (const PoseCell& w : ref.window(c)) cells.insert(w);
    }
  }
  return cells.size();
}

void check_against_brute_force(PoseGridConfig cfg) {
  cfg.cell_size = 0.2;
  cfg.initial_capacity = 4;  // force many doublings
  PoseGridHashMap grid(cfg);
  BruteForceGrid ref(grid);  // holds the marked cells; probes OR over the window
  std::vector<PoseCell> marked;
  const auto marks = random_marks(6000, 11);
  for (const auto& m : marks) {
    grid.mark(m.submap, m.x, m.y, m.theta, m.flags);
    marked.push_back(grid.cell_of(m.submap, m.x, m.y, m.theta));
    ref.mark(marked.back(), m.flags);
  }
  const PoseGridStats s = grid.stats();
  EXPECT_EQ(s.bins_used, expected_bins(ref, marked, cfg.tolerance_mode));
  EXPECT_GE(s.rehashes, 8u);
  EXPECT_LE(s.load, cfg.max_load_factor);
  EXPECT_EQ(s.memory_bytes, s.capacity * 8);
  EXPECT_EQ(s.submaps, 5u);

  for (const auto& m : marks) {
    const PoseCell c = grid.cell_of(m.submap, m.x, m.y, m.theta);
    ASSERT_EQ(grid.probe(m.submap, m.x, m.y, m.theta), ref.window_or(c));
    ASSERT_NE(grid.probe(m.submap, m.x, m.y, m.theta), 0);
  }
  std::size_t nonzero = 0, zero = 0;
  for (const auto& q : probe_poses(marks, 20000, 12)) {
    const PoseCell c = grid.cell_of(q.submap, q.x, q.y, q.theta);
    const CellFlags f = grid.probe(q.submap, q.x, q.y, q.theta);
    ASSERT_EQ(f, ref.window_or(c)) << q.x << " " << q.y << " " << q.theta;
    (f != 0 ? nonzero : zero) += 1;
  }
  EXPECT_GT(nonzero, 150u);  // the probes do test both answers
  EXPECT_GT(zero, 1000u);
}

TEST(PoseGrid, MatchesBruteForceWithoutTolerance) {
  PoseGridConfig cfg;
  cfg.xy_tolerance = 0, cfg.theta_tolerance = 0;
  check_against_brute_force(cfg);
}

TEST(PoseGrid, MatchesBruteForceDilatingAtInsert) {
  PoseGridConfig cfg;
  cfg.xy_tolerance = 1, cfg.theta_tolerance = 1, cfg.tolerance_mode = ToleranceMode::kDilateAtInsert;
  check_against_brute_force(cfg);
}

TEST(PoseGrid, MatchesBruteForceProbingNeighbours) {
  PoseGridConfig cfg;
  cfg.xy_tolerance = 1, cfg.theta_tolerance = 1, cfg.tolerance_mode = ToleranceMode::kProbeNeighbours;
  check_against_brute_force(cfg);
}

TEST(PoseGrid, BothToleranceModesAnswerTheSame) {
  PoseGridConfig a, b;
  a.xy_tolerance = b.xy_tolerance = 2;
  a.theta_tolerance = b.theta_tolerance = 2;
  a.tolerance_mode = ToleranceMode::kDilateAtInsert;
  b.tolerance_mode = ToleranceMode::kProbeNeighbours;
  PoseGridHashMap ga(a), gb(b);
  for (const auto& m : random_marks(2000, 21))
    ga.mark(m.submap, m.x, m.y, m.theta, m.flags), gb.mark(m.submap, m.x, m.y, m.theta, m.flags);
  for (const auto& q : random_marks(20000, 22))
    ASSERT_EQ(ga.probe(q.submap, q.x, q.y, q.theta), gb.probe(q.submap, q.x, q.y, q.theta));
  EXPECT_GT(ga.stats().bins_used, 50 * gb.stats().bins_used);  // 5 x 5 x 5 window, few overlaps
}

TEST(PoseGrid, HeadingWrapsAroundInBothModes) {
  for (const auto mode : {ToleranceMode::kDilateAtInsert, ToleranceMode::kProbeNeighbours}) {
    PoseGridConfig cfg;
    cfg.theta_bins = 36, cfg.theta_tolerance = 1, cfg.tolerance_mode = mode;
    PoseGridHashMap grid(cfg);
    grid.insert(0, 1.1, 2.1, -0.01);        // bin 35 (headings are binned over [0, 2 pi))
    grid.insert(0, 5.1, 5.1, kPi - 0.001);  // bin 17
    EXPECT_EQ(grid.cell_of(0, 1.1, 2.1, -0.01).itheta, 35);
    EXPECT_EQ(grid.cell_of(0, 1.1, 2.1, 0.01).itheta, 0);
    EXPECT_TRUE(grid.probe(0, 1.1, 2.1, 0.01));  // bin 0 is next to bin 35
    EXPECT_TRUE(grid.probe(0, 1.1, 2.1, 2 * kPi - 0.01));
    EXPECT_FALSE(grid.probe(0, 1.1, 2.1, 0.2));          // bin 1: two bins away
    EXPECT_TRUE(grid.probe(0, 5.1, 5.1, -kPi + 0.001));  // +pi and -pi are neighbours
    EXPECT_TRUE(grid.probe(0, 5.1, 5.1, kPi + 0.05));
    EXPECT_FALSE(grid.probe(1, 5.1, 5.1, kPi));  // other submap
  }
  PoseGridConfig exact;
  exact.theta_tolerance = 0;
  PoseGridHashMap grid(exact);
  grid.insert(0, 5.1, 5.1, kPi - 0.001);
  EXPECT_FALSE(grid.probe(0, 5.1, 5.1, -kPi + 0.001));
  EXPECT_TRUE(grid.probe(0, 5.1, 5.1, -kPi - 0.001));
}

TEST(PoseGrid, OneHeadingBinIsAPlainTwoDimensionalGrid) {
  for (const auto mode : {ToleranceMode::kDilateAtInsert, ToleranceMode::kProbeNeighbours}) {
    PoseGridConfig cfg;
    cfg.theta_bins = 1, cfg.theta_tolerance = 3, cfg.xy_tolerance = 0, cfg.cell_size = 0.5;
    cfg.tolerance_mode = mode;
    PoseGridHashMap grid(cfg);
    grid.mark(2, 1.2, -0.7, 0.0, cell_flags::kFree);
    for (double th : {-3.0, -1.0, 0.0, 2.0, 3.1}) EXPECT_EQ(grid.probe(2, 1.4, -0.6, th), cell_flags::kFree);
    EXPECT_EQ(grid.probe(2, 1.6, -0.6, 0.0), 0);  // next cell in x
    EXPECT_EQ(grid.stats().bins_used, 1u);
    EXPECT_DOUBLE_EQ(grid.stats().dense_cells, 1.0);
  }
}

TEST(PoseGrid, FlagsAccumulateByOr) {
  PoseGridHashMap grid;
  grid.mark(0, 0.05, 0.05, 0.0, cell_flags::kFree);
  EXPECT_EQ(grid.lookup(grid.cell_of(0, 0.05, 0.05, 0.0)), cell_flags::kFree);
  grid.mark(0, 0.05, 0.05, 0.0, cell_flags::kOccupied);
  EXPECT_EQ(grid.lookup(grid.cell_of(0, 0.05, 0.05, 0.0)), cell_flags::kFree | cell_flags::kOccupied);
  EXPECT_EQ(grid.stats().marks, 2u);
}

TEST(PoseGrid, DenseCellsAreTheBoundingBoxesTimesHeadingBins) {
  PoseGridConfig cfg;
  cfg.cell_size = 1.0, cfg.theta_bins = 10, cfg.xy_tolerance = 1, cfg.theta_tolerance = 1;
  PoseGridHashMap grid(cfg);
  grid.insert(0, 0.5, 0.5, 0.0);
  grid.insert(0, 9.5, 4.5, 1.0);   // submap 0: 10 x 5 cells
  grid.insert(3, -2.5, 7.5, 0.0);  // submap 3: 1 cell
  const auto s = grid.stats();
  EXPECT_DOUBLE_EQ(s.dense_cells, (10.0 * 5.0 + 1.0) * 10.0);
  EXPECT_EQ(s.bins_used, 3u * 27u);  // dilated 3 x 3 x 3, disjoint windows
  EXPECT_DOUBLE_EQ(s.grid_fraction, 81.0 / 510.0);
  EXPECT_EQ(s.submaps, 2u);
}

TEST(PoseGrid, CellOfIsFloorOfTheScaledCoordinatesAndTheWrappedHeading) {
  PoseGridConfig cfg;
  cfg.cell_size = 0.25, cfg.theta_bins = 36;
  const PoseGridHashMap grid(cfg);
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> coord(-300.0, 300.0), angle(-40.0, 40.0);
  std::vector<double> xs = {0.0, -0.0, 0.25, -0.25, -0.5, 0.1, -0.1, -1e-300, 1e-300, 16383.75, -16384.0};
  for (int i = 0; i < 20000; ++i) xs.push_back(coord(rng));
  for (int i = 0; i < 200; ++i) xs.push_back(std::round(coord(rng)) * 0.25);  // exact cell borders
  const double two_pi = 2.0 * kPi;
  for (const double x : xs) {
    const double theta = angle(rng);
    const PoseCell c = grid.cell_of(7, x, -x, theta);
    EXPECT_EQ(c.ix, static_cast<std::int32_t>(std::floor(x * 4.0))) << x;
    EXPECT_EQ(c.iy, static_cast<std::int32_t>(std::floor(-x * 4.0))) << x;
    double t = std::fmod(theta, two_pi);
    if (t < 0.0) t += two_pi;
    EXPECT_EQ(c.itheta, std::min(static_cast<std::int32_t>(t * (36.0 / two_pi)), 35)) << theta;
  }
}

TEST(PoseGrid, PlannedMarksGiveTheGridOfMarksOneByOne) {
  for (const auto mode : {ToleranceMode::kDilateAtInsert, ToleranceMode::kProbeNeighbours}) {
    PoseGridConfig cfg;
    cfg.cell_size = 0.3, cfg.theta_bins = 12, cfg.xy_tolerance = 1, cfg.theta_tolerance = 1;
    cfg.tolerance_mode = mode, cfg.initial_capacity = 4;  // the table grows in the middle of a plan
    PoseGridHashMap one_by_one(cfg), planned(cfg);
    std::mt19937_64 rng(3);
    std::uniform_real_distribution<double> coord(-20.0, 20.0), angle(-7.0, 7.0);
    PoseGridHashMap::MarkPlan plan;
    for (int scan = 0; scan < 40; ++scan) {
      plan.clear();
      for (int i = 0; i < 150; ++i) {
        const auto submap = static_cast<std::uint32_t>(rng() % 3);
        const double x = coord(rng), y = coord(rng), theta = angle(rng);
        const auto flags = static_cast<CellFlags>(1u << (rng() % 4));
        one_by_one.mark(submap, x, y, theta, flags);
        planned.plan_mark(planned.cell_of(submap, x, y, theta), flags, plan);
      }
      if (scan % 10 == 9) {  // a cell beyond the limits: refused while planned, and nothing of the plan made
        const ByteWriter before = [&] {
          ByteWriter w;
          planned.write_snapshot(w);
          return w;
        }();
        EXPECT_THROW(planned.plan_mark(planned.cell_of(0, 1e5, 0.0, 0.0), 1, plan), Error);
        ByteWriter after;
        planned.write_snapshot(after);
        EXPECT_EQ(before.bytes(), after.bytes());
      }
      planned.mark_planned(plan);
    }
    ByteWriter a, b;
    one_by_one.write_snapshot(a);
    planned.write_snapshot(b);
    EXPECT_EQ(a.take(), b.take());  // the same cells, flags, counters and table size
    EXPECT_EQ(one_by_one.stats().rehashes, planned.stats().rehashes);
    EXPECT_GT(planned.stats().rehashes, 5u);
  }
}

TEST(PoseGrid, RejectsBadInput) {
  PoseGridConfig bad;
  bad.cell_size = 0.0;
  EXPECT_THROW(PoseGridHashMap{bad}, Error);
  bad = {};
  bad.theta_bins = 0;
  EXPECT_THROW(PoseGridHashMap{bad}, Error);
  bad = {};
  bad.max_load_factor = 1.0;
  EXPECT_THROW(PoseGridHashMap{bad}, Error);
  PoseGridHashMap grid;
  EXPECT_THROW(grid.insert(0, 1e5, 0.0, 0.0), Error);      // beyond 65536 cells
  EXPECT_THROW(grid.insert(16383, 0.0, 0.0, 0.0), Error);  // submap 16383 is reserved
  EXPECT_THROW(grid.insert(0, std::nan(""), 0.0, 0.0), Error);
  EXPECT_THROW(grid.mark(0, 0.0, 0.0, 0.0, 0), Error);
  EXPECT_EQ(grid.probe(0, 1e5, 0.0, 0.0), 0);  // out of range: nothing known
  EXPECT_EQ(grid.probe(0, std::nan(""), 0.0, 0.0), 0);
  EXPECT_EQ(grid.stats().bins_used, 0u);
}

/// The scorer must agree with a brute-force window OR over the same cells.
void check_scorer(ToleranceMode mode, int xy_tol, int theta_tol) {
  PoseGridConfig cfg;
  cfg.xy_tolerance = xy_tol, cfg.theta_tolerance = theta_tol, cfg.tolerance_mode = mode;
  cfg.cell_size = 0.5;
  PoseGridHashMap grid(cfg);
  BruteForceGrid ref(grid);
  const auto marks = random_marks(5000, 31);
  for (const auto& m : marks) {
    grid.mark(m.submap, m.x, m.y, m.theta, m.flags);
    ref.mark(grid.cell_of(m.submap, m.x, m.y, m.theta), m.flags);
  }
  // Hypotheses: half map a marked pose exactly onto the local point, half random.
  std::mt19937 rng(32);
  std::uniform_real_distribution<double> xy(-30.0, 30.0), th(-kPi, kPi);
  const LocalPoint x{1.5f, -0.75f, 0.3f};
  std::vector<std::uint32_t> submap;
  std::vector<float> tx, ty, co, si, theta;
  for (std::size_t j = 0; j < 3000; ++j) {
    Pose2 T(xy(rng), xy(rng), th(rng));
    std::uint32_t r = static_cast<std::uint32_t>(j % 5);
    if (j % 2 == 0) {
      const auto& m = marks[j];
      T = Pose2(m.x, m.y, m.theta) * Pose2(x.x, x.y, x.theta).inverse();
      r = m.submap;
    }
    submap.push_back(r), tx.push_back(static_cast<float>(T.x)), ty.push_back(static_cast<float>(T.y));
    co.push_back(static_cast<float>(std::cos(T.theta))), si.push_back(static_cast<float>(std::sin(T.theta)));
    theta.push_back(static_cast<float>(T.theta));
  }
  const HypothesisBatch v{submap.data(), tx.data(), ty.data(), co.data(), si.data(), theta.data(), tx.size()};
  PoseGridScorer scorer(grid, {1.0f, -0.5f, 0.0f});
  std::vector<float> scores(v.size);
  scorer(x, v, scores.data());
  std::size_t hits = 0, frees = 0;
  for (std::size_t j = 0; j < v.size; ++j) {
    const CellFlags f = ref.window_or(scorer.cell_of(x, v, j));
    const float expected = (f & cell_flags::kOccupied) ? 1.0f : (f & cell_flags::kFree) ? -0.5f : 0.0f;
    ASSERT_EQ(scores[j], expected) << "hypothesis " << j;
    hits += expected > 0, frees += expected < 0;
  }
  EXPECT_GT(hits, 600u);
  EXPECT_GT(frees, 100u);
}

TEST(PoseGridScorer, MatchesBruteForceWithoutTolerance) { check_scorer(ToleranceMode::kDilateAtInsert, 0, 0); }
TEST(PoseGridScorer, MatchesBruteForceDilatingAtInsert) { check_scorer(ToleranceMode::kDilateAtInsert, 1, 1); }
TEST(PoseGridScorer, MatchesBruteForceProbingNeighbours) { check_scorer(ToleranceMode::kProbeNeighbours, 1, 1); }
TEST(PoseGridScorer, MatchesBruteForceProbingHeadingOnly) { check_scorer(ToleranceMode::kProbeNeighbours, 0, 2); }

/// A scorer config whose every outcome has its own score.
PoseGridScorerConfig distinct_scores() {
  return {.hit = 1.0f,
          .free = -1.0f,
          .unknown = 0.0f,
          .ray_through_wall = -2.0f,
          .ray_through_free = 0.5f,
          .ray_through_contested = -0.25f,
          .surface_on_return = 0.75f};
}

/// score_pairs() must give each pair what operator() gives its point under
/// that one hypothesis, surface and free-space points mixed.
void check_score_pairs(ToleranceMode mode, int xy_tol, int theta_tol) {
  PoseGridConfig cfg;
  cfg.xy_tolerance = xy_tol, cfg.theta_tolerance = theta_tol, cfg.tolerance_mode = mode, cfg.cell_size = 0.5;
  PoseGridHashMap occupancy(cfg);
  FreeSpaceGrid free_space(PoseGridConfig{.cell_size = 0.5, .theta_bins = 1, .xy_tolerance = 0, .theta_tolerance = 0});
  const auto marks = random_marks(5000, 41);
  for (const auto& m : marks) {
    occupancy.mark(m.submap, m.x, m.y, m.theta, cell_flags::kOccupied);
    free_space.mark(m.submap, m.x + 0.7, m.y, m.flags | cell_flags::kReturn);
  }
  std::mt19937 rng(42);
  std::uniform_real_distribution<double> xy(-30.0, 30.0), th(-kPi, kPi), local(-3.0, 3.0);
  std::vector<Hypothesis> hypotheses;
  for (std::size_t j = 0; j < 37; ++j) {  // not a multiple of four: the scalar tail too
    const auto& m = marks[j];
    hypotheses.push_back({j % 3 == 0 ? m.submap : static_cast<std::uint32_t>(j % 5),
                          j % 3 == 0 ? Pose2(m.x, m.y, m.theta) : Pose2(xy(rng), xy(rng), th(rng))});
  }
  HypothesisBatchBuffer buffer;
  const HypothesisBatch v = buffer.assign(hypotheses);
  std::vector<LocalPoint> points;
  std::vector<std::uint32_t> of;
  for (std::size_t k = 0; k < 403; ++k) {
    const auto kind = k % 3 == 0 ? LocalPoint::Kind::kFreeSpace : LocalPoint::Kind::kSurface;
    const float near = k % 2 == 0 ? 0.0f : 1.0f;  // half of them on the hypothesis' own mark
    points.push_back({near * static_cast<float>(local(rng)), near * static_cast<float>(local(rng)),
                      near * static_cast<float>(th(rng)), kind});
    of.push_back(static_cast<std::uint32_t>(rng() % hypotheses.size()));
  }
  const PoseGridScorerConfig config = distinct_scores();
  PoseGridScorer pairs(occupancy, free_space, config), one(occupancy, free_space, config);
  std::vector<float> scores(points.size());
  pairs.score_pairs(points, of, v, scores.data());
  std::size_t nonzero = 0;
  for (std::size_t k = 0; k < points.size(); ++k) {
    const std::size_t h = of[k];
    const HypothesisBatch single{v.submap + h, v.tx + h, v.ty + h, v.cos + h, v.sin + h, v.theta + h, 1};
    float expected = 0.0f;
    one(points[k], single, &expected);
    ASSERT_EQ(scores[k], expected) << "pair " << k;
    nonzero += expected != 0.0f;
  }
  EXPECT_GT(nonzero, 30u);
  EXPECT_EQ(pairs.stats().lookups, one.stats().lookups);
  EXPECT_THROW(pairs.score_pairs(points, std::span(of).first(3), v, scores.data()), Error);
  of[5] = static_cast<std::uint32_t>(hypotheses.size());
  EXPECT_THROW(pairs.score_pairs(points, of, v, scores.data()), Error);
}

TEST(PoseGridScorer, ScorePairsEqualsOneCallPerPairExact) { check_score_pairs(ToleranceMode::kDilateAtInsert, 0, 0); }
TEST(PoseGridScorer, ScorePairsEqualsOneCallPerPairProbing) {
  check_score_pairs(ToleranceMode::kProbeNeighbours, 1, 1);
}

/// A free-space grid with pose-cell hints must score exactly as one without:
/// the hints only skip pose-grid lookups that would have found nothing.
void check_pose_cell_hints(int xy_tol, double origin) {
  PoseGridConfig cfg;
  cfg.xy_tolerance = xy_tol;
  PoseGridHashMap occupancy(cfg);
  const PoseGridConfig free_cfg{.cell_size = 0.25, .theta_bins = 1, .xy_tolerance = 0, .theta_tolerance = 0};
  FreeSpaceGrid plain(free_cfg), hinted(free_cfg);
  ASSERT_TRUE(hinted.track_pose_cells(cfg.cell_size));
  auto marks = random_marks(4000, 51);
  for (auto& m : marks) m.x += origin, m.y -= origin;
  PoseGridHashMap::MarkPlan plan;
  for (const auto& m : marks) {
    plan.clear();
    occupancy.plan_mark(occupancy.cell_of(m.submap, m.x, m.y, m.theta), cell_flags::kOccupied, plan);
    occupancy.mark_planned(plan);
    for (const auto& w : plan.writes) {
      const PoseCell c = PoseGridHashMap::unpack_xy(w.xy);
      hinted.note_pose_cell(c.submap, c.ix, c.iy);
    }
    for (FreeSpaceGrid* g : {&plain, &hinted}) {
      g->mark(m.submap, m.x, m.y, cell_flags::kReturn | cell_flags::kNormal);
      g->mark(m.submap, m.x + 0.9, m.y - 0.4, m.flags);
      g->mark(m.submap, m.x - 0.6, m.y + 0.5, cell_flags::kReturn);  // a bare return
    }
  }
  std::mt19937 rng(52);
  std::uniform_real_distribution<double> th(-kPi, kPi), local(-2.0, 2.0);
  std::vector<Hypothesis> hypotheses;
  for (std::size_t j = 0; j < 203; ++j) {  // on marks (hits), beside them and anywhere
    const auto& m = marks[j];
    const double off = j % 3 == 0 ? 0.0 : local(rng);
    hypotheses.push_back({m.submap, Pose2(m.x + off, m.y - off, j % 3 == 2 ? th(rng) : m.theta)});
  }
  HypothesisBatchBuffer buffer;
  const HypothesisBatch v = buffer.assign(hypotheses);
  const PoseGridScorerConfig config = distinct_scores();
  PoseGridScorer with(occupancy, hinted, config), without(occupancy, plain, config);
  std::vector<float> a(v.size), b(v.size);
  std::size_t hits = 0, surface_on_return = 0, other = 0;
  for (int k = 0; k < 300; ++k) {
    const float near = k % 2 == 0 ? 0.0f : 1.0f;  // half on the hypothesis' own mark
    const LocalPoint x{near * static_cast<float>(local(rng)), near * static_cast<float>(local(rng)),
                       near * static_cast<float>(th(rng)), LocalPoint::Kind::kSurface};
    with(x, v, a.data());
    without(x, v, b.data());
    for (std::size_t j = 0; j < v.size; ++j) {
      ASSERT_EQ(a[j], b[j]) << "point " << k << " hypothesis " << j;
      hits += a[j] == config.hit, surface_on_return += a[j] == config.surface_on_return, other += a[j] == 0.0f;
    }
  }
  EXPECT_GT(hits, 1000u);
  EXPECT_GT(surface_on_return, 100u);
  EXPECT_GT(other, 1000u);
  EXPECT_EQ(with.stats().lookups, without.stats().lookups);
}

TEST(PoseGridScorer, PoseCellHintsChangeNoScore) { check_pose_cell_hints(0, 0.0); }
TEST(PoseGridScorer, PoseCellHintsChangeNoScoreFarOut) { check_pose_cell_hints(0, 13000.0); }
TEST(PoseGridScorer, PoseCellHintsChangeNoScoreDilatingInXY) { check_pose_cell_hints(1, 0.0); }

TEST(PoseGridScorer, NegativeEvidenceFromAFreeSpaceGrid) {
  // Map of submap 0: a wall along x = 5 (normal heading pi), seen by rays that
  // crossed x = 0..4 freely. The free-space grid marks the wall's cells as
  // holding returns and, as GlobalMap dilates, the cells beyond it occupied.
  PoseGridHashMap occupancy(
      PoseGridConfig{.cell_size = 0.2, .theta_bins = 36, .xy_tolerance = 0, .theta_tolerance = 0});
  FreeSpaceGrid free_space(PoseGridConfig{.cell_size = 0.25, .theta_bins = 1, .xy_tolerance = 0, .theta_tolerance = 0});
  for (double y = -2.0; y <= 2.0; y += 0.05) {
    occupancy.insert(0, 5.01, y, kPi);
    free_space.mark(0, 5.01, y, cell_flags::kOccupied | cell_flags::kReturn | cell_flags::kNormal);
    free_space.mark(0, 5.26, y, cell_flags::kOccupied);
    for (double x = 0.01; x < 4.0; x += 0.1) free_space.mark(0, x, y, cell_flags::kFree);
  }
  // A cell both free and occupied (a person walked there): neither evidence.
  free_space.mark(0, 2.01, 0.01, cell_flags::kOccupied);
  // A return that map rays crossed too (a door, or two passes of a SLAM map
  // that disagree): no surface evidence, milder ray evidence.
  free_space.mark(0, 3.01, 1.01, cell_flags::kOccupied | cell_flags::kReturn);
  // A sparse return of a far wall: no normal, so not in `occupancy`.
  free_space.mark(0, 7.01, 1.01, cell_flags::kOccupied | cell_flags::kReturn);
  free_space.mark(0, 7.26, 1.01, cell_flags::kOccupied);
  const PoseGridScorerConfig config = distinct_scores();
  PoseGridScorer scorer(occupancy, free_space, config);
  // Hypotheses: identity in submap 0, identity in submap 1 (nothing mapped).
  const std::uint32_t submap[2] = {0, 1};
  const float zero[2] = {0, 0}, one[2] = {1, 1};
  const HypothesisBatch v{submap, zero, zero, one, zero, zero, 2};
  float c[2];
  const auto score = [&](LocalPoint x) {
    scorer(x, v, c);
    EXPECT_EQ(c[1], 0.0f) << "submap 1 knows nothing";
    return c[0];
  };
  using K = LocalPoint::Kind;
  EXPECT_EQ(score({5.01f, 0.51f, static_cast<float>(kPi), K::kSurface}), 1.0f);  // on the wall, right normal
  EXPECT_EQ(score({5.01f, 0.51f, 0.0f, K::kSurface}), 0.0f);                     // on the wall, wrong normal: unknown
  EXPECT_EQ(score({7.01f, 1.01f, 0.0f, K::kSurface}), 0.75f);  // on a return without a normal: any heading
  EXPECT_EQ(score({7.26f, 1.01f, 0.0f, K::kSurface}), 0.0f);   // beside it: unknown
  EXPECT_EQ(score({3.01f, 1.01f, 0.0f, K::kSurface}), 0.0f);   // a return map rays crossed: unknown
  EXPECT_EQ(score({1.01f, 0.51f, static_cast<float>(kPi), K::kSurface}), -1.0f);  // a surface in free space
  EXPECT_EQ(score({9.01f, 0.51f, static_cast<float>(kPi), K::kSurface}), 0.0f);   // beyond the map
  EXPECT_EQ(score({5.01f, 0.51f, 0.0f, K::kFreeSpace}), -2.0f);                   // a ray through the wall
  EXPECT_EQ(score({5.26f, 0.51f, 0.0f, K::kFreeSpace}), 0.0f);    // beside the wall's returns: no evidence
  EXPECT_EQ(score({1.01f, 0.51f, 0.0f, K::kFreeSpace}), 0.5f);    // a ray where map rays passed
  EXPECT_EQ(score({2.01f, 0.01f, 0.0f, K::kFreeSpace}), 0.0f);    // free and occupied: no evidence
  EXPECT_EQ(score({3.01f, 1.01f, 0.0f, K::kFreeSpace}), -0.25f);  // a return map rays crossed: contested
  EXPECT_EQ(score({9.01f, 0.51f, 0.0f, K::kFreeSpace}), 0.0f);    // beyond the map
}

}  // namespace
}  // namespace lshloc
