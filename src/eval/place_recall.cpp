#include "lshloc/eval/place_recall.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <string>
#include <unordered_map>
#include <unordered_set>

#include <Eigen/Core>

#include "lshloc/appearance/location_store.hpp"
#include "lshloc/common/error.hpp"

namespace lshloc {

namespace {

/// Map feature positions of one submap on a uniform grid, for "is there a
/// map feature within r of this pose" (coverage and hit tests).
class PositionGrid {
 public:
  explicit PositionGrid(double cell) : cell_(cell) {}
  void add(std::uint32_t id, const MapLocation& loc) { cells_[key(loc.x, loc.y)].push_back(id); }
  template <class F>
  void for_near(double x, double y, F&& f) const {
    const auto cx = static_cast<std::int64_t>(std::floor(x / cell_)),
               cy = static_cast<std::int64_t>(std::floor(y / cell_));
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

double median(std::vector<float> v) {
  if (v.empty()) return 0.0;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
  return static_cast<double>(v[v.size() / 2]);
}

/// Whether map location `l` is a right answer for a query at `pose` in `submap`.
bool is_hit(const MapLocation& l, std::uint32_t submap, const Pose2& pose, const PlaceRecallConfig& config) {
  return l.submap == submap && std::hypot(l.x - pose.x, l.y - pose.y) <= config.match_distance &&
         angle_distance(l.theta, pose.theta) <= config.match_angle_deg * std::numbers::pi / 180.0;
}

using RowMatrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

/// The exact L2 baseline: |q - m|^2 - |q|^2 (the same for every map row of a
/// query) from each of `n_queries` descriptors to every row of `map`, by a
/// matrix product over blocks of 256 queries. visit(query, row of distances).
template <class DescriptorOf, class Visit>
void for_each_query_distances(const Eigen::Ref<const RowMatrix>& map, std::size_t n_queries, DescriptorOf descriptor_of,
                              Visit visit) {
  const Eigen::VectorXf m_norm = map.rowwise().squaredNorm();
  const Eigen::Index dim = map.cols();
  constexpr std::size_t kBlock = 256;
  RowMatrix qb(static_cast<Eigen::Index>(kBlock), dim);
  for (std::size_t b = 0; b < n_queries; b += kBlock) {
    const std::size_t nb = std::min(kBlock, n_queries - b);
    for (std::size_t j = 0; j < nb; ++j) {
      const auto& descriptor = descriptor_of(b + j);
      for (Eigen::Index c = 0; c < dim; ++c)
        qb(static_cast<Eigen::Index>(j), c) = descriptor[static_cast<std::size_t>(c)];
    }
    const RowMatrix d =
        (-2.0f * qb.topRows(static_cast<Eigen::Index>(nb)) * map.transpose()).rowwise() + m_norm.transpose();
    for (std::size_t j = 0; j < nb; ++j) visit(b + j, d.row(static_cast<Eigen::Index>(j)));
  }
}

}  // namespace

void PlaceRecallConfig::validate() const {
  require(k >= 1, "PlaceRecallConfig.k", ">= 1 location per query", k);
  require(match_distance > 0.0 && std::isfinite(match_distance), "PlaceRecallConfig.match_distance", "finite and > 0 m",
          match_distance);
  require(match_angle_deg >= 0.0 && std::isfinite(match_angle_deg), "PlaceRecallConfig.match_angle_deg",
          "finite and >= 0 deg", match_angle_deg);
  require(thin_cell >= 0.0 && std::isfinite(thin_cell), "PlaceRecallConfig.thin_cell", "finite and >= 0 m (0: all)",
          thin_cell);
  require(thin_angle > 0.0 && std::isfinite(thin_angle), "PlaceRecallConfig.thin_angle", "finite and > 0 rad",
          thin_angle);
  extractor.validate();
  lsh.validate();
}

PlaceRecallResult evaluate_place_recall(const Scenario& scenario, const PlaceRecallConfig& config) {
  config.validate();
  FeatureExtractor extractor(config.extractor);

  // Map side: features, locations, and (for the exact baseline) descriptors.
  LocationStore store;
  LshDatabase db(config.lsh);
  std::vector<Descriptor> map_descriptors;
  std::vector<std::vector<ScanFeatures>> per_submap;
  for (const Submap& submap : scenario.submaps)
    per_submap.push_back(extract_submap_features(submap, extractor, config.context));
  const std::size_t map_scans = extractor.stats().scans;
  // Optional thinning: a feature whose (x, y, theta) cell already holds one
  // of its submap is not inserted (the map then grows with area, not time).
  std::unordered_set<std::uint64_t> seen_cells;
  std::size_t thinned = 0;
  for (std::size_t r = 0; r < per_submap.size(); ++r)
    for (const ScanFeatures& sf : per_submap[r])
      for (const Feature& f : sf.features) {
        if (config.thin_cell > 0.0) {
          const auto cx = static_cast<std::int64_t>(std::floor(f.pose.x / config.thin_cell));
          const auto cy = static_cast<std::int64_t>(std::floor(f.pose.y / config.thin_cell));
          const auto ct = static_cast<std::int64_t>(std::floor((f.pose.theta + std::numbers::pi) / config.thin_angle));
          const std::uint64_t key =
              (static_cast<std::uint64_t>(r) << 56) ^ (static_cast<std::uint64_t>(cx & 0xFFFFFF) << 32) ^
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
  PositionGrid grid(config.match_distance);
  for (std::uint32_t id = 0; id < store.size(); ++id)
    if (store[id].submap == target_submap) grid.add(id, store[id]);

  // Target side.
  const std::vector<ScanFeatures> target = extract_target_features_at_truth(scenario.target, extractor, config.context);
  std::vector<Feature> queries;
  for (const ScanFeatures& sf : target) queries.insert(queries.end(), sf.features.begin(), sf.features.end());

  auto matches = [&](const Feature& q, std::uint32_t id) { return is_hit(store[id], target_submap, q.pose, config); };
  std::vector<char> covered(queries.size(), 0);
  std::size_t n_matchable = 0;  // covered queries with a map feature that would count as a hit
  for (std::size_t i = 0; i < queries.size(); ++i) {
    bool matchable = false;
    grid.for_near(queries[i].pose.x, queries[i].pose.y, [&](std::uint32_t id) {
      if (std::hypot(store[id].x - queries[i].pose.x, store[id].y - queries[i].pose.y) <= config.match_distance)
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
  const std::size_t k_eval = std::max<std::size_t>(config.k, 100);
  const std::vector<std::size_t> ks = {1, 10, 100, config.k};

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
  if (config.exact && !map_descriptors.empty()) {
    const auto n_map = static_cast<Eigen::Index>(map_descriptors.size());
    const Eigen::Map<const RowMatrix> m(map_descriptors[0].data(), n_map, static_cast<Eigen::Index>(kDescriptorSize));
    std::vector<std::size_t> covered_ids;
    for (std::size_t i = 0; i < queries.size(); ++i)
      if (covered[i]) covered_ids.push_back(i);
    std::vector<std::pair<float, std::uint32_t>> row(map_descriptors.size());
    std::vector<std::uint32_t> ranked;
    for_each_query_distances(
        m, covered_ids.size(), [&](std::size_t i) -> const Descriptor& { return queries[covered_ids[i]].descriptor; },
        [&](std::size_t i, const auto& d) {
          for (Eigen::Index c = 0; c < n_map; ++c)
            row[static_cast<std::size_t>(c)] = {d(c), static_cast<std::uint32_t>(c)};
          const Feature& q = queries[covered_ids[i]];
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
          const std::size_t r = first_hit(q, ranked);
          for (std::size_t x = 0; x < ks.size(); ++x) exact_hits[x] += r < ks[x];
        });
  }

  auto ratio = [&](std::size_t hits) {
    return n_covered ? static_cast<double>(hits) / static_cast<double>(n_covered) : 0.0;
  };
  const double n_map_f = static_cast<double>(std::max<std::size_t>(map_descriptors.size(), 1));
  const double n_q_f = static_cast<double>(std::max<std::size_t>(queries.size(), 1));
  PlaceRecallResult r;
  r.map_scans = map_scans;
  r.target_scans_with_truth = target.size();
  r.queries = queries.size();
  r.covered = n_covered;
  r.matchable = n_matchable;
  r.map_features = map_descriptors.size();
  r.map_features_thinned = thinned;
  r.recall_at_1 = ratio(lsh_hits[0]);
  r.recall_at_10 = ratio(lsh_hits[1]);
  r.recall_at_100 = ratio(lsh_hits[2]);
  r.recall_at_k = ratio(lsh_hits[3]);
  if (config.exact) {
    r.exact_recall_at_1 = ratio(exact_hits[0]);
    r.exact_recall_at_10 = ratio(exact_hits[1]);
    r.exact_recall_at_100 = ratio(exact_hits[2]);
    r.exact_recall_at_k = ratio(exact_hits[3]);
    r.median_true_match_distance = median(true_match_distance);
    r.median_nearest_distance = median(nearest_distance);
    r.median_kth_distance = median(hundredth_distance);
  }
  r.insert_us_per_feature = insert_us / n_map_f;
  r.query_us_per_feature = query_us / n_q_f;
  r.mean_candidates_touched = static_cast<double>(scratch.candidates_touched) / n_q_f;
  r.mean_distinct_candidates = static_cast<double>(scratch.distinct_candidates) / n_q_f;
  r.lsh = db.stats();
  return r;
}

PlaceRecallProbe::PlaceRecallProbe(std::vector<RecallQuery> queries, const PlaceRecallConfig& config)
    : queries_(std::move(queries)), config_(config), covered_(queries_.size(), 0), nearest_(queries_.size()) {
  config_.validate();
}

bool PlaceRecallProbe::hit(const RecallQuery& q, const MapLocation& l) const {
  return is_hit(l, q.submap, q.feature.pose, config_);
}

void PlaceRecallProbe::add_map_features(std::uint32_t submap, std::span<const Feature> features) {
  if (features.empty() || queries_.empty()) return;
  const auto n = static_cast<Eigen::Index>(features.size());
  const auto dim = static_cast<Eigen::Index>(kDescriptorSize);
  RowMatrix m(n, dim);
  for (Eigen::Index i = 0; i < n; ++i)
    for (Eigen::Index c = 0; c < dim; ++c)
      m(i, c) = features[static_cast<std::size_t>(i)].descriptor[static_cast<std::size_t>(c)];
  const std::size_t k = config_.k;
  for_each_query_distances(
      m, queries_.size(), [&](std::size_t j) -> const Descriptor& { return queries_[j].feature.descriptor; },
      [&](std::size_t j, const auto& d) {
        const RecallQuery& q = queries_[j];
        auto& best = nearest_[j];
        for (Eigen::Index i = 0; i < n; ++i) {
          const Feature& f = features[static_cast<std::size_t>(i)];
          const MapLocation l{submap, static_cast<float>(f.pose.x), static_cast<float>(f.pose.y),
                              static_cast<float>(f.pose.theta)};
          if (submap == q.submap &&
              std::hypot(f.pose.x - q.feature.pose.x, f.pose.y - q.feature.pose.y) <= config_.match_distance)
            covered_[j] = 1;
          best.push_back({d(i), l});
          // Keep the k nearest: trim once the list doubles.
          if (best.size() >= 2 * k) {
            std::nth_element(best.begin(), best.begin() + static_cast<std::ptrdiff_t>(k - 1), best.end(),
                             [](const Neighbour& a, const Neighbour& c) { return a.distance2 < c.distance2; });
            best.resize(k);
          }
        }
      });
}

PlaceRecallProbe::Result PlaceRecallProbe::finish(const LshDatabase& database, const LocationStore& store) const {
  Result r;
  r.queries = queries_.size();
  std::size_t lsh_hits = 0, exact_hits = 0;
  LshQuery scratch(database);
  std::vector<std::uint32_t> ids;
  for (std::size_t i = 0; i < queries_.size(); ++i) {
    if (!covered_[i]) continue;
    ++r.covered;
    const RecallQuery& q = queries_[i];
    database.query(q.feature.descriptor, config_.k, ids, scratch);
    lsh_hits += std::any_of(ids.begin(), ids.end(), [&](std::uint32_t id) { return hit(q, store[id]); });
    auto best = nearest_[i];
    const std::size_t top = std::min(config_.k, best.size());
    std::partial_sort(best.begin(), best.begin() + static_cast<std::ptrdiff_t>(top), best.end(),
                      [](const Neighbour& a, const Neighbour& c) { return a.distance2 < c.distance2; });
    exact_hits += std::any_of(best.begin(), best.begin() + static_cast<std::ptrdiff_t>(top),
                              [&](const Neighbour& n) { return hit(q, n.location); });
  }
  if (r.covered) {
    r.lsh_recall_at_k = static_cast<double>(lsh_hits) / static_cast<double>(r.covered);
    r.exact_recall_at_k = static_cast<double>(exact_hits) / static_cast<double>(r.covered);
  }
  return r;
}

}  // namespace lshloc
