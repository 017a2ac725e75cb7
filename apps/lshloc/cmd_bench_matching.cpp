// `lshloc bench matching`: the map-matching cost at steady state (docs/design.md
// section 6, speed). A pose grid is filled with a map (synthetic walls, or
// every scan endpoint of a corrected log with --map), then a simulated target
// robot feeds iRANSAC |U_new| local features and |V_new| hypotheses per
// viewpoint (a share of them from true correspondences, the rest from random
// map points) and runs iterations_per_scan iterations. Prints the score cost,
// the per-viewpoint time early and late (flat = constant per-scan work), the
// largest active set and, with --map, the grid's size against the dense grid.
#include <algorithm>
#include <chrono>
#include <ctime>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "lshloc/common/error.hpp"
#include "lshloc/common/wall_time.hpp"
#include "lshloc/matching/incremental_ransac.hpp"
#include "lshloc/geometry/oriented_endpoints.hpp"
#include "lshloc/matching/pose_grid.hpp"
#include "lshloc/matching/pose_grid_scorer.hpp"
#include "lshloc/io/carmen_reader.hpp"
#include "lshloc/io/config_json.hpp"
#include "option_checks.hpp"

namespace lshloc::app {

namespace {

constexpr double kPi = std::numbers::pi;

/// The pose grid and iRANSAC under test; --config sets any of their fields.
struct MatchingSettings {
  // The paper's synthetic setting (BENCHMARKS.md's matching rows), not the
  // localizer's defaults.
  PoseGridConfig grid{.cell_size = 0.1};
  IncrementalRansacConfig ransac{.block_size = 10,
                                 .new_data_points_per_scan = 10,
                                 .iterations_per_scan = 10,
                                 .min_score = 3.0,
                                 .preference_z = 0.0,
                                 .order_rule = DataPointOrderRule::kFreshFirst,
                                 .recent_window = 200};
};
LSHLOC_JSON_FIELDS(MatchingSettings, grid, ransac)

struct BenchMatchingOptions {
  bool json = false;
  std::string map_log;  ///< corrected CARMEN log; empty: synthetic walls
  std::size_t viewpoints = 10000;
  std::size_t warm_up = 100;     ///< viewpoints before the "first 100" window
  std::size_t window = 100;      ///< viewpoints averaged at the start and the end
  double inlier_share = 0.01;    ///< share of hypotheses from true correspondences
  double drift_xy = 0.0;         ///< [m] std. dev. of the local map's drift per viewpoint (random walk)
  double drift_theta_deg = 0.0;  ///< [deg] same, heading
  MatchingSettings settings;
  bool print_config = false;
};

/// A synthetic building: 400 random walls in a 100 x 100 m square, an
/// oriented point every 5 cm (like scan endpoints), normals to one side.
std::vector<Pose2> synthetic_map_points(std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> pos(0.0, 100.0), len(2.0, 15.0), u01(0.0, 1.0);
  std::vector<Pose2> out;
  for (int w = 0; w < 400; ++w) {
    const double x0 = pos(rng), y0 = pos(rng), l = len(rng);
    const double a = u01(rng) < 0.5 ? 0.0 : kPi / 2;  // walls along the axes
    const double normal = a + (u01(rng) < 0.5 ? kPi / 2 : -kPi / 2);
    for (double d = 0.0; d < l; d += 0.05) out.emplace_back(x0 + d * std::cos(a), y0 + d * std::sin(a), normal);
  }
  return out;
}

/// Every valid endpoint of every scan of a corrected log, in the map frame,
/// oriented by its surface normal; one vector per scan.
std::vector<std::vector<Pose2>> log_map_points(const std::string& path, std::size_t& valid_endpoints) {
  const io::CarmenLog log = io::read_carmen_log(path);
  if (log.scans.empty()) throw Error("bench matching: " + path + " holds no laser scans");
  std::vector<std::vector<Pose2>> out;
  out.reserve(log.scans.size());
  valid_endpoints = 0;
  for (const LaserScan& scan : log.scans) {
    for (std::size_t i = 0; i < scan.size(); ++i) valid_endpoints += scan.status(i) == BeamStatus::kValid;
    std::vector<Pose2> pts = oriented_endpoints(scan);
    for (Pose2& p : pts) p = scan.pose * p;  // the corrected laser pose: map frame
    out.push_back(std::move(pts));
  }
  return out;
}

/// [s] CPU time of this thread: unlike wall time, it does not count the time
/// other processes hold the core (the machines here are shared).
double thread_cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

double mean(const std::vector<double>& v, std::size_t from, std::size_t count) {
  double s = 0.0;
  for (std::size_t i = from; i < from + count; ++i) s += v[i];
  return s / static_cast<double>(count);
}

nlohmann::json run_bench(const BenchMatchingOptions& o) {
  const PoseGridConfig& grid_config = o.settings.grid;
  const IncrementalRansacConfig& ransac_config = o.settings.ransac;
  if (o.viewpoints < o.warm_up + 2 * o.window)
    throw Error("bench matching: --viewpoints must be at least warm-up + 2 x 100 = " +
                std::to_string(o.warm_up + 2 * o.window));

  // 1. The map: its oriented points, grouped by scan (synthetic: one group).
  std::vector<std::vector<Pose2>> groups;
  std::size_t valid_endpoints = 0;
  if (o.map_log.empty()) {
    groups.push_back(synthetic_map_points(ransac_config.seed));
  } else {
    groups = log_map_points(o.map_log, valid_endpoints);
  }
  std::vector<Pose2> map_points;
  for (const auto& g : groups) map_points.insert(map_points.end(), g.begin(), g.end());
  if (map_points.empty()) throw Error("bench matching: the map has no oriented endpoints");

  PoseGridHashMap grid(grid_config);
  const auto t_fill0 = std::chrono::steady_clock::now();
  for (const Pose2& p : map_points) grid.insert(0, p.x, p.y, p.theta);
  const double fill_s = seconds_since(t_fill0);

  // 2. The target robot: its local frame is the map frame moved by T_true;
  //    each viewpoint sees |U_new| map points (from one scan of the log in
  //    turn, or anywhere in the synthetic map), with a little noise.
  //    With drift, the local map's frame wanders: at viewpoint k the true
  //    T_submap_local is T_true * D_k, D_k a random walk, so old features and
  //    hypotheses disagree with new ones (the case the order rules differ on).
  const Pose2 T_true(12.5, -7.25, 0.6);  // T_submap_local at viewpoint 0
  Pose2 drift;                           // D_k
  std::mt19937_64 rng(ransac_config.seed + 1);
  std::normal_distribution<double> dxy(0.0, o.drift_xy), dth(0.0, o.drift_theta_deg * kPi / 180.0);
  std::vector<double> error_m(o.viewpoints, std::numeric_limits<double>::infinity()), error_deg(o.viewpoints, 180.0);
  std::normal_distribution<double> nxy(0.0, 0.02), nth(0.0, 0.01);
  std::uniform_int_distribution<std::size_t> any_map(0, map_points.size() - 1);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  std::vector<Pose2> local_truth;  // the map point behind each local feature
  std::vector<Pose2> local_seen;   // the local feature (noisy, local frame)

  IncrementalRansac ransac(ransac_config);
  PoseGridScorer scorer(grid);
  std::vector<double> viewpoint_ms(o.viewpoints), viewpoint_ms_wall(o.viewpoints);
  double scoring_s = 0.0, scoring_wall_s = 0.0;
  std::size_t scores = 0;
  std::vector<LocalPoint> fresh;
  std::vector<Hypothesis> hyps;
  for (std::size_t vp = 0; vp < o.viewpoints; ++vp) {
    fresh.clear(), hyps.clear();
    if (o.drift_xy > 0.0 || o.drift_theta_deg > 0.0) {
      // Drawn in sequence (last argument first, as g++ did): the same run with every compiler.
      const double th = dth(rng), y = dxy(rng), x = dxy(rng);
      drift = drift * Pose2(x, y, th);
    }
    const Pose2 T_now = T_true * drift;
    const Pose2 T_local_submap = T_now.inverse();
    const auto& group = groups[vp % groups.size()];
    for (std::size_t k = 0; k < ransac_config.new_data_points_per_scan; ++k) {
      const Pose2& g = group.empty() ? map_points[any_map(rng)]
                                     : group[std::uniform_int_distribution<std::size_t>(0, group.size() - 1)(rng)];
      const Pose2 l = T_local_submap * g;
      local_truth.push_back(g);
      const double noise_theta = nth(rng), noise_y = nxy(rng), noise_x = nxy(rng);
      local_seen.emplace_back(l.x + noise_x, l.y + noise_y, l.theta + noise_theta);
      fresh.push_back({static_cast<float>(local_seen.back().x), static_cast<float>(local_seen.back().y),
                       static_cast<float>(local_seen.back().theta)});
    }
    // Hypotheses from correspondences of this viewpoint's features: the true
    // partner with probability inlier_share, else a random map point.
    const std::size_t first = local_seen.size() - fresh.size();
    for (std::size_t h = 0; h < ransac_config.new_hypotheses_per_scan; ++h) {
      const std::size_t i = first + h % fresh.size();
      const Pose2& g = u01(rng) < o.inlier_share ? local_truth[i] : map_points[any_map(rng)];
      hyps.push_back(hypothesis_from_correspondence(0, g, local_seen[i]));
    }
    // Timed: what iRANSAC does per viewpoint (generating the hypotheses is
    // the appearance database's work, not timed here).
    const std::size_t scores_before = ransac.stats().scores;
    const double c0 = thread_cpu_seconds();
    const auto t0 = std::chrono::steady_clock::now();
    ransac.add_scan(fresh, hyps);
    const double c1 = thread_cpu_seconds();
    const auto t1 = std::chrono::steady_clock::now();
    ransac.run(scorer);
    const double c2 = thread_cpu_seconds();
    const auto t2 = std::chrono::steady_clock::now();
    const auto best_now = ransac.best();  // (the localizer's output; not timed)
    if (best_now) {
      error_m[vp] = translation_distance(best_now->hypothesis.T_submap_local, T_now);
      error_deg[vp] = angle_distance(best_now->hypothesis.T_submap_local.theta, T_now.theta) * 180.0 / kPi;
    }
    scoring_s += c2 - c1;
    scoring_wall_s += std::chrono::duration<double>(t2 - t1).count();
    scores += ransac.stats().scores - scores_before;
    viewpoint_ms[vp] = 1e3 * (c2 - c0);
    viewpoint_ms_wall[vp] = std::chrono::duration<double, std::milli>(t2 - t0).count();
  }

  const auto stats = ransac.stats();
  const auto best = ransac.best();
  const auto gs = grid.stats();
  std::vector<double> sorted_ms(viewpoint_ms.begin() + static_cast<std::ptrdiff_t>(o.warm_up), viewpoint_ms.end());
  std::sort(sorted_ms.begin(), sorted_ms.end());
  nlohmann::json out;
  out["ns_per_score"] = 1e9 * scoring_s / static_cast<double>(std::max<std::size_t>(scores, 1));
  out["viewpoint_ms_first100"] = mean(viewpoint_ms, o.warm_up, o.window);
  out["viewpoint_ms_last100"] = mean(viewpoint_ms, o.viewpoints - o.window, o.window);
  out["viewpoint_ms_median"] = sorted_ms[sorted_ms.size() / 2];
  out["timing"] = "thread CPU time (the *_wall fields: wall clock, inflated when other processes share the core)";
  out["ns_per_score_wall"] = 1e9 * scoring_wall_s / static_cast<double>(std::max<std::size_t>(scores, 1));
  out["viewpoint_ms_first100_wall"] = mean(viewpoint_ms_wall, o.warm_up, o.window);
  out["viewpoint_ms_last100_wall"] = mean(viewpoint_ms_wall, o.viewpoints - o.window, o.window);
  out["active_hypotheses_max"] = stats.active_hypotheses_max;
  out["viewpoints"] = o.viewpoints;
  out["scores"] = stats.scores;
  out["data_points"] = stats.data_points;
  out["map"] = o.map_log.empty() ? std::string("synthetic") : o.map_log;
  out["map_points"] = map_points.size();
  if (!o.map_log.empty()) out["valid_endpoints"] = valid_endpoints;
  out["grid_contents"] = "scan endpoints with a surface normal (oriented_endpoints), heading = normal";
  out["tolerance_mode"] = grid_config.tolerance_mode;
  out["xy_tolerance"] = grid_config.xy_tolerance;
  out["theta_tolerance"] = grid_config.theta_tolerance;
  out["cell_size"] = grid_config.cell_size;
  out["theta_bins"] = grid_config.theta_bins;
  out["order_rule"] = ransac_config.order_rule;
  out["grid_fill_s"] = fill_s;
  out["grid_capacity"] = gs.capacity;
  out["grid_memory_bytes"] = gs.memory_bytes;
  out["grid_rehashes"] = gs.rehashes;
  out["grid_max_load"] = grid_config.max_load_factor;
  out["table_fraction"] = gs.table_fraction;
  if (!o.map_log.empty()) {
    out["grid_bins"] = gs.bins_used;
    out["dense_cells"] = gs.dense_cells;
    out["grid_fraction"] = gs.grid_fraction;
  }
  // Localization quality over the viewpoints after warm-up: the share whose
  // best hypothesis lies within 0.5 m and 5 degrees of the current truth.
  std::size_t correct = 0;
  for (std::size_t vp = o.warm_up; vp < o.viewpoints; ++vp) correct += error_m[vp] < 0.5 && error_deg[vp] < 5.0;
  out["correct_share"] = static_cast<double>(correct) / static_cast<double>(o.viewpoints - o.warm_up);
  out["drift_xy"] = o.drift_xy;
  out["drift_theta_deg"] = o.drift_theta_deg;
  if (best) {
    out["best_error_m"] = error_m.back();
    out["best_error_deg"] = error_deg.back();
    out["best_mean_score"] = best->mean_score();
  }
  return out;
}

}  // namespace

void add_bench_matching_command(CLI::App& bench, GlobalOptions& global) {
  (void)global;
  auto o = std::make_shared<BenchMatchingOptions>();
  auto* cmd = bench.add_subcommand(
      "matching",
      "Map-matching cost at steady state: fills a pose grid with a map (synthetic walls, or every\n"
      "scan endpoint of a corrected log with --map), then feeds iRANSAC |U_new| features and |V_new|\n"
      "hypotheses per viewpoint (1% true correspondences) and runs B iterations per viewpoint.\n"
      "Prints ns_per_score, viewpoint_ms_first100 (after warm-up), viewpoint_ms_last100,\n"
      "active_hypotheses_max and, with --map, grid_bins, dense_cells and grid_fraction.");
  cmd->add_flag("--json", o->json, "print one JSON line (default: readable lines)");
  cmd->add_option("--map", o->map_log, "corrected CARMEN log (e.g. fr079/fr079-complete.gfs.log.gz)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--viewpoints", o->viewpoints, "viewpoints to simulate")
      ->capture_default_str()
      ->check(within(1, 1e7));
  cmd->add_option("--warm-up", o->warm_up, "viewpoints before the first-100 window")
      ->capture_default_str()
      ->check(within(0, 1e7));
  cmd->add_option("--inlier-share", o->inlier_share, "share of hypotheses from true correspondences")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  cmd->add_option("--drift-xy", o->drift_xy, "[m] local-map drift per viewpoint (std. dev., random walk)")
      ->capture_default_str()
      ->check(within(0, 10));
  cmd->add_option("--drift-theta", o->drift_theta_deg, "[deg] local-map heading drift per viewpoint (std. dev.)")
      ->capture_default_str()
      ->check(within(0, 180));
  // Applied while parsing, like every --config of the tool.
  cmd->add_option_function<std::string>(
         "--config",
         [o](const std::string& path) { io::apply_config_patch(io::read_json_file(path), o->settings, path); },
         "JSON file of the pose grid's and iRANSAC's settings ({\"grid\": PoseGridConfig, \"ransac\": "
         "IncrementalRansacConfig}, any subset; --print-config shows them); default: the paper's synthetic setting")
      ->trigger_on_parse();
  cmd->add_flag("--print-config", o->print_config, "print the effective settings as JSON and exit");
  cmd->callback([o] {
    if (o->print_config) {
      std::printf("%s\n", io::json_text(nlohmann::json(o->settings), 2).c_str());
      return;
    }
    const nlohmann::json out = run_bench(*o);
    if (o->json) {
      std::printf("%s\n", io::json_text(out).c_str());
    } else {
      for (const auto& [k, v] : out.items()) std::printf("%-24s %s\n", k.c_str(), io::json_text(v).c_str());
    }
    std::fflush(stdout);
  });
}

}  // namespace lshloc::app
