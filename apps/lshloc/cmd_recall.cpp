// `lshloc recall`: place recall@k of the appearance database on a scenario
// (DESIGN.md section 5, "Descriptor + database quality").
//
// Map side: every scan of every submap, placed at its map pose, gives
// features; each goes to the location store and the LSH database. Target
// side: each target scan with ground truth is placed at its true pose (its
// descriptor context: the earlier target scans placed by odometry relative
// to it) and each of its features queries the database. A query is covered
// when the target submap has a map feature within 0.5 m of it; it is a hit at
// k when one of the first k locations returned lies in the target submap
// within 0.5 m and 20 degrees of the query feature's true pose. Exact-L2
// recall (brute force over all map descriptors) is reported beside it.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <unordered_map>
#include <unordered_set>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "lshloc/core/error.hpp"
#include "lshloc/core/location_store.hpp"
#include "lshloc/core/lsh_database.hpp"
#include "lshloc/io/dataset_catalog.hpp"
#include "lshloc/pipeline/appearance.hpp"

namespace lshloc::app {

namespace {

struct RecallOptions {
  ScenarioConfig scenario;
  std::size_t k = 100;
  bool json = false;
  bool exact = true;
  double match_distance = 0.5;  ///< [m]
  double match_angle_deg = 20.0;  ///< [deg]
  double thin_cell = 0.0;         ///< [m] map thinning cell (0: insert every map feature)
  double thin_angle = 0.35;       ///< [rad] map thinning cell in heading
  FeatureExtractorConfig extractor;
  DescriptorContextConfig context;
  LshConfig lsh;
};

/// Map feature positions of one submap on a uniform grid, for "is there a
/// map feature within r of this pose" (coverage and hit tests).
class PositionGrid {
 public:
  explicit PositionGrid(double cell) : cell_(cell) {}
  void add(std::uint32_t id, const MapLocation& loc) { cells_[key(loc.x, loc.y)].push_back(id); }
  template <class F>
  void for_near(double x, double y, F&& f) const {
    const auto cx = static_cast<std::int64_t>(std::floor(x / cell_)), cy = static_cast<std::int64_t>(std::floor(y / cell_));
    for (std::int64_t dx = -1; dx <= 1; ++dx)
      for (std::int64_t dy = -1; dy <= 1; ++dy)
        if (auto it = cells_.find(pack(cx + dx, cy + dy)); it != cells_.end())
          for (std::uint32_t id : it->second) f(id);
  }

 private:
  static std::uint64_t pack(std::int64_t cx, std::int64_t cy) {
    return (static_cast<std::uint64_t>(cx) << 32) ^ static_cast<std::uint64_t>(cy & 0xFFFFFFFF);
  }
  std::uint64_t key(double x, double y) const {
    return pack(static_cast<std::int64_t>(std::floor(x / cell_)), static_cast<std::int64_t>(std::floor(y / cell_)));
  }
  double cell_;
  std::unordered_map<std::uint64_t, std::vector<std::uint32_t>> cells_;
};

using Clock = std::chrono::steady_clock;
double micros(Clock::duration d) { return std::chrono::duration<double, std::micro>(d).count(); }

nlohmann::json run_recall(const GlobalOptions& global, const RecallOptions& opt) {
  const io::DatasetCatalog catalog(io::DatasetCatalog::resolve_data_dir(global.data_dir));
  const Scenario scenario = io::load_scenario(catalog, opt.scenario);
  FeatureExtractor extractor(opt.extractor);

  // Map side: features, locations, and (for the exact baseline) descriptors.
  LocationStore store;
  LshDatabase db(opt.lsh);
  std::vector<Descriptor> map_descriptors;
  std::vector<std::vector<ScanFeatures>> per_submap;
  for (const Submap& submap : scenario.submaps) per_submap.push_back(extract_submap_features(submap, extractor, opt.context));
  const std::size_t map_scans = extractor.stats().scans;
  // Optional thinning: a feature whose (x, y, theta) cell already holds one
  // of its submap is not inserted (the map then grows with area, not time).
  std::unordered_set<std::uint64_t> seen_cells;
  std::size_t thinned = 0;
  for (std::size_t r = 0; r < per_submap.size(); ++r)
    for (const ScanFeatures& sf : per_submap[r])
      for (const Feature& f : sf.features) {
        if (opt.thin_cell > 0.0) {
          const auto cx = static_cast<std::int64_t>(std::floor(f.pose.x / opt.thin_cell));
          const auto cy = static_cast<std::int64_t>(std::floor(f.pose.y / opt.thin_cell));
          const auto ct = static_cast<std::int64_t>(std::floor((f.pose.theta + std::numbers::pi) / opt.thin_angle));
          const std::uint64_t key = (static_cast<std::uint64_t>(r) << 56) ^ (static_cast<std::uint64_t>(cx & 0xFFFFFF) << 32) ^
                                    (static_cast<std::uint64_t>(cy & 0xFFFFFF) << 8) ^ static_cast<std::uint64_t>(ct & 0xFF);
          if (!seen_cells.insert(key).second) {
            ++thinned;
            continue;
          }
        }
        store.append(static_cast<std::uint32_t>(r), f.pose);
        map_descriptors.push_back(f.descriptor);
      }
  const auto t0 = Clock::now();
  for (std::uint32_t id = 0; id < map_descriptors.size(); ++id) db.insert(map_descriptors[id], id);
  const double insert_us = micros(Clock::now() - t0);

  const auto target_submap = static_cast<std::uint32_t>(scenario.target_submap);
  PositionGrid grid(opt.match_distance);
  for (std::uint32_t id = 0; id < store.size(); ++id)
    if (store[id].submap == target_submap) grid.add(id, store[id]);

  // Target side.
  const std::vector<ScanFeatures> target = extract_target_features_at_truth(scenario.target, extractor, opt.context);
  std::vector<Feature> queries;
  for (const ScanFeatures& sf : target) queries.insert(queries.end(), sf.features.begin(), sf.features.end());

  const double max_angle = opt.match_angle_deg * std::numbers::pi / 180.0;
  auto matches = [&](const Feature& q, std::uint32_t id) {
    const MapLocation& loc = store[id];
    return loc.submap == target_submap && std::hypot(loc.x - q.pose.x, loc.y - q.pose.y) <= opt.match_distance &&
           angle_distance(loc.theta, q.pose.theta) <= max_angle;
  };
  std::vector<char> covered(queries.size(), 0);
  std::size_t n_matchable = 0;  // covered queries with a map feature that would count as a hit
  for (std::size_t i = 0; i < queries.size(); ++i) {
    bool matchable = false;
    grid.for_near(queries[i].pose.x, queries[i].pose.y, [&](std::uint32_t id) {
      if (std::hypot(store[id].x - queries[i].pose.x, store[id].y - queries[i].pose.y) <= opt.match_distance)
        covered[i] = 1;
      matchable = matchable || matches(queries[i], id);
    });
    n_matchable += matchable;
  }
  const std::size_t n_covered = static_cast<std::size_t>(std::count(covered.begin(), covered.end(), 1));

  // The rank of the first correct location in a ranked list (or npos).
  auto first_hit = [&](const Feature& q, const std::vector<std::uint32_t>& ids) {
    for (std::size_t r = 0; r < ids.size(); ++r)
      if (matches(q, ids[r])) return r;
    return std::string::npos;
  };
  const std::size_t k_eval = std::max<std::size_t>(opt.k, 100);
  const std::vector<std::size_t> ks = {1, 10, 100, opt.k};

  // LSH queries (timed over all queries, scored over the covered ones).
  LshQuery scratch(db);
  std::vector<std::vector<std::uint32_t>> answers(queries.size());
  const auto t1 = Clock::now();
  for (std::size_t i = 0; i < queries.size(); ++i) db.query(queries[i].descriptor, k_eval, answers[i], scratch);
  const double query_us = micros(Clock::now() - t1);
  std::vector<std::size_t> lsh_hits(ks.size(), 0);
  for (std::size_t i = 0; i < queries.size(); ++i) {
    if (!covered[i]) continue;
    const std::size_t r = first_hit(queries[i], answers[i]);
    for (std::size_t j = 0; j < ks.size(); ++j) lsh_hits[j] += r < ks[j];
  }

  // Exact L2 baseline: brute force in blocks with a matrix product.
  std::vector<std::size_t> exact_hits(ks.size(), 0);
  std::vector<float> true_match_distance, nearest_distance, hundredth_distance;
  if (opt.exact && !map_descriptors.empty()) {
    using Matrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
    const auto n_map = static_cast<Eigen::Index>(map_descriptors.size());
    const Eigen::Map<const Matrix> m(map_descriptors[0].data(), n_map, static_cast<Eigen::Index>(kDescriptorSize));
    const Eigen::VectorXf m_norm = m.rowwise().squaredNorm();
    std::vector<std::size_t> covered_ids;
    for (std::size_t i = 0; i < queries.size(); ++i)
      if (covered[i]) covered_ids.push_back(i);
    constexpr std::size_t kBlock = 256;
    Matrix qb(static_cast<Eigen::Index>(kBlock), static_cast<Eigen::Index>(kDescriptorSize));
    std::vector<std::pair<float, std::uint32_t>> row(map_descriptors.size());
    std::vector<std::uint32_t> ranked;
    for (std::size_t b = 0; b < covered_ids.size(); b += kBlock) {
      const std::size_t nb = std::min(kBlock, covered_ids.size() - b);
      for (std::size_t j = 0; j < nb; ++j)
        for (std::size_t c = 0; c < kDescriptorSize; ++c)
          qb(static_cast<Eigen::Index>(j), static_cast<Eigen::Index>(c)) = queries[covered_ids[b + j]].descriptor[c];
      const Matrix d = (-2.0f * qb.topRows(static_cast<Eigen::Index>(nb)) * m.transpose()).rowwise() +
                       m_norm.transpose();
      for (std::size_t j = 0; j < nb; ++j) {
        for (Eigen::Index c = 0; c < n_map; ++c)
          row[static_cast<std::size_t>(c)] = {d(static_cast<Eigen::Index>(j), c), static_cast<std::uint32_t>(c)};
        const Feature& q = queries[covered_ids[b + j]];
        float best_true = std::numeric_limits<float>::infinity();
        grid.for_near(q.pose.x, q.pose.y, [&](std::uint32_t id) {
          if (matches(q, id)) best_true = std::min(best_true, row[id].first);
        });
        const std::size_t top = std::min(k_eval, row.size());
        std::partial_sort(row.begin(), row.begin() + static_cast<std::ptrdiff_t>(top), row.end());
        ranked.clear();
        for (std::size_t t = 0; t < top; ++t) ranked.push_back(row[t].second);
        // Squared distances plus |q|^2 = 1 give the distances.
        if (std::isfinite(best_true)) true_match_distance.push_back(std::sqrt(std::max(best_true + 1.0f, 0.0f)));
        nearest_distance.push_back(std::sqrt(std::max(row[0].first + 1.0f, 0.0f)));
        hundredth_distance.push_back(std::sqrt(std::max(row[top - 1].first + 1.0f, 0.0f)));
        const std::size_t r = first_hit(queries[covered_ids[b + j]], ranked);
        for (std::size_t x = 0; x < ks.size(); ++x) exact_hits[x] += r < ks[x];
      }
    }
  }

  const LshStats s = db.stats();
  auto ratio = [&](std::size_t hits) { return n_covered ? static_cast<double>(hits) / static_cast<double>(n_covered) : 0.0; };
  const double n_map_f = static_cast<double>(std::max<std::size_t>(map_descriptors.size(), 1));
  const double n_q_f = static_cast<double>(std::max<std::size_t>(queries.size(), 1));
  nlohmann::json out = {
      {"building", opt.scenario.building},
      {"start", opt.scenario.start},
      {"length", opt.scenario.length},
      {"submaps", scenario.submaps.size()},
      {"k", opt.k},
      {"map_scans", map_scans},
      {"target_scans_with_truth", target.size()},
      {"queries", queries.size()},
      {"covered", n_covered},
      {"matchable", n_matchable},
      {"recall_at_1", ratio(lsh_hits[0])},
      {"recall_at_10", ratio(lsh_hits[1])},
      {"recall_at_100", ratio(lsh_hits[2])},
      {"recall_at_k", ratio(lsh_hits[3])},
      {"map_features", map_descriptors.size()},
      {"map_features_thinned", thinned},
      {"insert_us_per_feature", insert_us / n_map_f},
      {"query_us_per_feature", query_us / n_q_f},
      {"mean_candidates_touched", static_cast<double>(scratch.candidates_touched) / n_q_f},
      {"mean_distinct_candidates", static_cast<double>(scratch.distinct_candidates) / n_q_f},
      {"lsh_buckets", s.buckets},
      {"lsh_bytes_per_entry", s.bytes_per_entry()},
      {"lsh", {{"K", opt.lsh.K}, {"L", opt.lsh.L}, {"w", opt.lsh.w}, {"bucket_capacity", opt.lsh.bucket_capacity},
               {"max_candidates", opt.lsh.max_candidates}, {"seed", opt.lsh.seed},
               {"sketch_bits", opt.lsh.sketch_bits}}},
  };
  if (opt.exact) {
    out["exact_recall_at_1"] = ratio(exact_hits[0]);
    out["exact_recall_at_10"] = ratio(exact_hits[1]);
    out["exact_recall_at_100"] = ratio(exact_hits[2]);
    out["exact_recall_at_k"] = ratio(exact_hits[3]);
    // Descriptor distances that set w: to the nearest correct map feature, to
    // the nearest and to the k-th nearest of all (medians over covered queries).
    auto median = [](std::vector<float> v) {
      if (v.empty()) return 0.0;
      std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
      return static_cast<double>(v[v.size() / 2]);
    };
    out["median_true_match_distance"] = median(true_match_distance);
    out["median_nearest_distance"] = median(nearest_distance);
    out["median_kth_distance"] = median(hundredth_distance);
  }
  return out;
}

}  // namespace

void add_recall_command(CLI::App& app, GlobalOptions& global) {
  auto* cmd = app.add_subcommand(
      "recall",
      "Place recall@k of the appearance database on a scenario: inserts the features of every map\n"
      "scan, queries with the features of every target scan that has ground truth (placed at its\n"
      "true pose), and prints recall@1/10/100 over covered queries (a map feature within 0.5 m),\n"
      "beside exact-L2 recall and the per-feature insert and query times.");
  auto opt = std::make_shared<RecallOptions>();
  cmd->add_option("--building", opt->scenario.building, "target building")->capture_default_str();
  cmd->add_option("--start", opt->scenario.start, "first raw scan of the target window")->capture_default_str();
  cmd->add_option("--length", opt->scenario.length, "raw scans in the target window")->capture_default_str();
  cmd->add_option("--submaps", opt->scenario.submaps, "R: submaps in the global map")->capture_default_str();
  cmd->add_option("--k", opt->k, "locations retrieved per query (recall_at_k)")->capture_default_str();
  cmd->add_flag("--json", opt->json, "print one JSON line (default: the same, indented)");
  cmd->add_flag("!--no-exact", opt->exact, "skip the brute-force exact-L2 baseline");
  cmd->add_option("--thin", opt->thin_cell, "[m] insert one map feature per (x, y, theta) cell of this size (0: all)")
      ->capture_default_str();
  auto* g = cmd->add_option_group("database", "LSH settings");
  g->add_option("--lsh-k", opt->lsh.K, "projections per table")->capture_default_str();
  g->add_option("--lsh-l", opt->lsh.L, "tables")->capture_default_str();
  g->add_option("--lsh-w", opt->lsh.w, "bucket width (L2-normalized descriptor units)")->capture_default_str();
  g->add_option("--lsh-seed", opt->lsh.seed, "seed of the projections")->capture_default_str();
  g->add_option("--bucket-capacity", opt->lsh.bucket_capacity, "ids a query reads per bucket")->capture_default_str();
  g->add_option("--max-candidates", opt->lsh.max_candidates, "bucket entries a query reads in all")->capture_default_str();
  g->add_option("--sketch-weight", opt->lsh.sketch_collision_weight, "sketch bits per missed table in the ranking")
      ->capture_default_str();
  g->add_option("--sketch-bits", opt->lsh.sketch_bits, "sign-sketch bits per entry ranking candidates (0: off)")
      ->capture_default_str();
  auto* f = cmd->add_option_group("features", "keypoints and descriptor");
  f->add_option("--keypoints", opt->extractor.max_keypoints, "|U_new|: keypoints per scan at most")->capture_default_str();
  f->add_option("--spacing", opt->extractor.keypoint_spacing, "[m] arc length between keypoints")->capture_default_str();
  f->add_option("--keypoint-range", opt->extractor.keypoint_max_range, "[m] keypoints this close to the sensor")
      ->capture_default_str();
  f->add_option("--radius", opt->extractor.descriptor_radius, "[m] descriptor radius")->capture_default_str();
  f->add_option("--inner-radius", opt->extractor.descriptor_inner_radius, "[m] innermost ring")->capture_default_str();
  f->add_option("--normal-window", opt->extractor.normal_half_window, "[m] half arc length of the normal fit")
      ->capture_default_str();
  f->add_option("--min-support", opt->extractor.min_descriptor_support, "[m] surface in the disc at least")
      ->capture_default_str();
  f->add_option("--edge-margin", opt->extractor.edge_margin, "[m] keypoints this far from segment ends")
      ->capture_default_str();
  f->add_option("--residual", opt->extractor.max_normal_residual, "[m] smoothness limit of a keypoint")
      ->capture_default_str();
  f->add_option("--bin-power", opt->extractor.bin_power, "per-bin magnitude compression")->capture_default_str();
  f->add_option("--prefer-structure", opt->extractor.prefer_structure, "keep the most structured keypoints")
      ->capture_default_str();
  f->add_option("--rim-taper", opt->extractor.rim_taper, "share of the radius over which points fade out")
      ->capture_default_str();
  f->add_option("--log-rings", opt->extractor.log_rings, "log-spaced rings (else even)")->capture_default_str();
  f->add_option("--rings", opt->extractor.rings, "radial bins")->capture_default_str();
  f->add_option("--sectors", opt->extractor.sectors, "angular bins")->capture_default_str();
  f->add_option("--occupancy", opt->extractor.occupancy_component, "a third component per bin: surface length")
      ->capture_default_str();
  f->add_option("--context", opt->context.scans, "earlier scans used as descriptor context")->capture_default_str();
  f->add_option("--context-step", opt->context.min_step, "[m] sensor motion between context scans")
      ->capture_default_str();
  cmd->callback([&global, opt] {
    const nlohmann::json out = run_recall(global, *opt);
    std::printf("%s\n", opt->json ? out.dump().c_str() : out.dump(2).c_str());
  });
}

}  // namespace lshloc::app
