// lshloc's LshDatabase side by side with hnswlib, FAISS (IndexHNSWFlat,
// IndexLSH) and FLANN (kd-tree with addPoints) on one descriptor stream, in
// one invocation. Peers are optional: each is compiled in only where CMake
// found it (LSHLOC_HAVE_*), and skipped with a note otherwise.
//
// Stream: the map features of intel and fr101 (scenario start 2000, length
// 1000, R = 1: the places the queries must find), then real features of the
// other buildings, then noisy copies of those other buildings' features (the
// "synthetic buildings" of a growing map: each copy gets Gaussian noise of
// --copy-noise per dimension, about 0.55 in distance at 0.05, and its own
// submap id, so it can only be a distractor) until the largest size.
// Queries: the target features of those two windows at their true poses
// whose true location has a map feature within 0.5 m (docs/design.md section 6).
//
// Each index is fed the same stream one entry at a time, with one query after
// every `--query-every` inserts (interleaved; timed with the inserts' own
// clock kept apart). At each checkpoint size all queries run: query time and
// place recall@100 (a returned location within 0.5 m and 20 degrees of the
// truth, in the right submap), and bytes per entry: the heap's growth (malloc
// statistics, so it includes each index's copy of the vectors where it keeps
// one), lshloc's own count for its rows (its big tables are mapped outside
// malloc).
//
// Indexes: lshloc (its defaults), lshloc-fine (K = 20, 2000 candidates, 256-bit sketch: the
// setting for maps of 1e6 entries and more), hnswlib, faiss-hnsw, faiss-lsh, flann.
//
//   lsh_peers_bench [--sizes 10000,100000,1000000] [--only lshloc,lshloc-fine,hnswlib,...]
//                   [--query-every 100] [--hnsw-ef 100] [--flann-checks 1500]
//                   [--lsh-k K --lsh-l L --lsh-w W --lsh-cap C --lsh-max-candidates M]   (defaults: LshConfig)
#include <malloc.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <memory>
#include <numbers>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "lshloc/common/error.hpp"
#include "lshloc/appearance/location_store.hpp"
#include "lshloc/appearance/lsh_database.hpp"
#include "lshloc/eval/dataset_catalog.hpp"
#include "lshloc/eval/appearance.hpp"

#ifdef LSHLOC_HAVE_HNSWLIB
#include <hnswlib/hnswlib.h>
#endif
#ifdef LSHLOC_HAVE_FAISS
#include <faiss/IndexHNSW.h>
#include <faiss/IndexLSH.h>
#include <omp.h>
#endif
#ifdef LSHLOC_HAVE_FLANN
#include <flann/flann.hpp>
#endif

namespace {

using lshloc::Descriptor;
using lshloc::kDescriptorSize;
constexpr int kDim = static_cast<int>(kDescriptorSize);

struct Query {
  Descriptor descriptor;
  std::uint32_t submap = 0;
  lshloc::Pose2 pose;
};

struct Options {
  std::vector<std::size_t> sizes = {10000, 100000, 1000000};
  std::vector<std::string> only;
  std::size_t query_every = 100;
  std::size_t hnsw_ef = 100;
  std::size_t hnsw_m = 16;
  std::size_t hnsw_ef_construction = 100;
  int flann_checks = 1500;
  int faiss_lsh_bits = 512;
  double copy_noise = 0.03;
  lshloc::LshConfig lsh;  ///< per-dimension Gaussian noise of synthetic copies (before renormalizing)
};

/// The common front of every index in the comparison.
class Index {
 public:
  virtual ~Index() = default;
  virtual std::string name() const = 0;
  virtual std::string params() const = 0;
  virtual void add(const Descriptor& d, std::uint32_t id) = 0;
  /// Makes every added entry searchable; the caller times it as insert time.
  virtual void flush() {}
  virtual void search(const Descriptor& q, std::size_t k, std::vector<std::uint32_t>& out) = 0;
  /// Bytes the index holds, where it counts them itself (0: use the heap's
  /// growth, which misses blocks mapped outside malloc).
  virtual std::size_t own_bytes() const { return 0; }
};

class LshlocIndex : public Index {
 public:
  LshlocIndex(const lshloc::LshConfig& c, std::string name) : db_(c), q_(db_), name_(std::move(name)) {}
  std::string name() const override { return name_; }
  std::string params() const override {
    const auto& c = db_.config();
    std::ostringstream s;
    s << "K=" << c.K << " L=" << c.L << " w=" << c.w << " cap=" << c.bucket_capacity << " max_cand=" << c.max_candidates
      << " sketch=" << c.sketch_bits << "/" << c.sketch_collision_weight;
    return s.str();
  }
  void add(const Descriptor& d, std::uint32_t id) override { db_.insert(d, id); }
  void search(const Descriptor& q, std::size_t k, std::vector<std::uint32_t>& out) override {
    db_.query(q, k, out, q_);
  }
  // The database maps its big tables itself (HugePageAllocator), out of
  // malloc's sight: its own count is the one that sees them.
  std::size_t own_bytes() const override { return db_.stats().bytes; }
  double mean_candidates() const {
    return q_.queries ? static_cast<double>(q_.candidates_touched) / static_cast<double>(q_.queries) : 0.0;
  }

 private:
  lshloc::LshDatabase db_;
  lshloc::LshQuery q_;
  std::string name_;
};

/// lshloc's settings for a map of a million features or more
/// (examples/config/large-map.json): finer buckets (K = 20 instead of 12)
/// overflow far less, so a place's entries survive in them, a larger
/// candidate budget reads them, and a finer sketch ranks them
/// (docs/results/appearance.md "Recall at a million entries").
lshloc::LshConfig fine_buckets(lshloc::LshConfig c) {
  c.K = 20;
  c.max_candidates = 2000;
  c.sketch_bits = 256;
  return c;
}

#ifdef LSHLOC_HAVE_HNSWLIB
class HnswlibIndex : public Index {
 public:
  HnswlibIndex(std::size_t max_elements, const Options& o)
      : space_(kDescriptorSize), index_(&space_, max_elements, o.hnsw_m, o.hnsw_ef_construction, 100), o_(o) {
    index_.setEf(o.hnsw_ef);
  }
  std::string name() const override { return "hnswlib"; }
  std::string params() const override {
    return "M=" + std::to_string(o_.hnsw_m) + " efC=" + std::to_string(o_.hnsw_ef_construction) +
           " ef=" + std::to_string(o_.hnsw_ef);
  }
  void add(const Descriptor& d, std::uint32_t id) override { index_.addPoint(d.data(), id); }
  void search(const Descriptor& q, std::size_t k, std::vector<std::uint32_t>& out) override {
    auto heap = index_.searchKnn(q.data(), k);
    out.resize(heap.size());
    for (std::size_t i = heap.size(); i-- > 0; heap.pop()) out[i] = static_cast<std::uint32_t>(heap.top().second);
  }

 private:
  hnswlib::L2Space space_;
  hnswlib::HierarchicalNSW<float> index_;
  Options o_;
};
#endif

#ifdef LSHLOC_HAVE_FAISS
/// FAISS indexes number vectors in insertion order, which is the id order here.
/// With `batched`, adds are buffered and handed to FAISS in one add() call
/// before the next search: IndexHNSWFlat::add sets up one lock per stored
/// vector on every call, so one-vector adds cost O(n) each and the stream
/// would not reach 1e6 (measured: over 900 s). The batch is at most
/// --query-every vectors, so every search still sees every earlier insert.
class FaissIndex : public Index {
 public:
  FaissIndex(std::unique_ptr<faiss::Index> index, std::string name, std::string params, bool batched)
      : index_(std::move(index)), name_(std::move(name)), params_(std::move(params)), batched_(batched) {}
  std::string name() const override { return name_; }
  std::string params() const override { return params_ + (batched_ ? " (adds batched up to each query)" : ""); }
  void add(const Descriptor& d, std::uint32_t) override {
    if (!batched_) {
      index_->add(1, d.data());
      return;
    }
    pending_.insert(pending_.end(), d.begin(), d.end());
  }
  void flush() override {
    if (pending_.empty()) return;
    index_->add(static_cast<faiss::Index::idx_t>(pending_.size() / kDescriptorSize), pending_.data());
    pending_.clear();
  }
  void search(const Descriptor& q, std::size_t k, std::vector<std::uint32_t>& out) override {
    labels_.resize(k);
    distances_.resize(k);
    index_->search(1, q.data(), static_cast<faiss::Index::idx_t>(k), distances_.data(), labels_.data());
    out.clear();
    for (auto l : labels_)
      if (l >= 0) out.push_back(static_cast<std::uint32_t>(l));
  }

 private:
  std::unique_ptr<faiss::Index> index_;
  std::string name_, params_;
  bool batched_;
  std::vector<float> pending_;
  std::vector<faiss::Index::idx_t> labels_;
  std::vector<float> distances_;
};
#endif

#ifdef LSHLOC_HAVE_FLANN
/// FLANN keeps pointers into the caller's rows: `rows` must outlive it and
/// not move (the stream is reserved up front).
class FlannIndex : public Index {
 public:
  FlannIndex(const std::vector<Descriptor>& rows, int checks) : rows_(rows), checks_(checks) {}
  std::string name() const override { return "flann-kdtree"; }
  std::string params() const override { return "trees=4 checks=" + std::to_string(checks_) + " addPoints(rebuild 2x)"; }
  void add(const Descriptor&, std::uint32_t id) override {
    flann::Matrix<float> m(const_cast<float*>(rows_[id].data()), 1, kDescriptorSize);
    if (!index_) {
      index_ = std::make_unique<flann::Index<flann::L2<float>>>(m, flann::KDTreeIndexParams(4));
      index_->buildIndex();
    } else {
      index_->addPoints(m, 2.0f);
    }
  }
  void search(const Descriptor& q, std::size_t k, std::vector<std::uint32_t>& out) override {
    const std::size_t n = std::min(k, index_->size());
    indices_.resize(n);
    dists_.resize(n);
    flann::Matrix<float> qm(const_cast<float*>(q.data()), 1, kDescriptorSize);
    flann::Matrix<std::size_t> im(indices_.data(), 1, n);
    flann::Matrix<float> dm(dists_.data(), 1, n);
    index_->knnSearch(qm, im, dm, n, flann::SearchParams(checks_));
    out.assign(indices_.begin(), indices_.end());
  }

 private:
  const std::vector<Descriptor>& rows_;
  int checks_;
  std::unique_ptr<flann::Index<flann::L2<float>>> index_;
  std::vector<std::size_t> indices_;
  std::vector<float> dists_;
};
#endif

std::size_t heap_bytes() {
  const struct mallinfo2 m = mallinfo2();
  return m.uordblks + m.hblkhd;
}

using Clock = std::chrono::steady_clock;

std::vector<std::size_t> parse_sizes(const std::string& s) {
  std::vector<std::size_t> out;
  std::stringstream ss(s);
  for (std::string item; std::getline(ss, item, ',');) out.push_back(static_cast<std::size_t>(std::stod(item)));
  return out;
}

std::vector<std::string> parse_list(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  for (std::string item; std::getline(ss, item, ',');) out.push_back(item);
  return out;
}

}  // namespace

int main(int argc, char** argv) try {
  Options opt;
  std::string data_dir;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) throw lshloc::Error("option " + a + " needs a value");
      return argv[++i];
    };
    if (a == "--sizes")
      opt.sizes = parse_sizes(next());
    else if (a == "--only")
      opt.only = parse_list(next());
    else if (a == "--query-every")
      opt.query_every = std::stoul(next());
    else if (a == "--hnsw-ef")
      opt.hnsw_ef = std::stoul(next());
    else if (a == "--hnsw-ef-construction")
      opt.hnsw_ef_construction = std::stoul(next());
    else if (a == "--copy-noise")
      opt.copy_noise = std::stod(next());
    else if (a == "--flann-checks")
      opt.flann_checks = std::stoi(next());
    else if (a == "--data")
      data_dir = next();
    else if (a == "--lsh-k")
      opt.lsh.K = std::stoul(next());
    else if (a == "--lsh-l")
      opt.lsh.L = std::stoul(next());
    else if (a == "--lsh-w")
      opt.lsh.w = std::stod(next());
    else if (a == "--lsh-cap")
      opt.lsh.bucket_capacity = std::stoul(next());
    else if (a == "--lsh-max-candidates")
      opt.lsh.max_candidates = std::stoul(next());
    else if (a == "--lsh-rarest-first")
      opt.lsh.rarest_buckets_first = true;
    else if (a == "--lsh-sketch")
      opt.lsh.sketch_bits = std::stoul(next());
    else if (a == "--lsh-sketch-weight")
      opt.lsh.sketch_collision_weight = std::stoul(next());
    else
      throw lshloc::Error("unknown option " + a +
                          " (known: --sizes, --only, --query-every, --hnsw-ef, --hnsw-ef-construction, "
                          "--flann-checks, --data, --lsh-k, --lsh-l, --lsh-w, --lsh-cap, --lsh-max-candidates, "
                          "--lsh-rarest-first, --lsh-sketch, --lsh-sketch-weight)");
  }
  std::sort(opt.sizes.begin(), opt.sizes.end());
  const std::size_t total = opt.sizes.back();
  auto wanted = [&](const std::string& n) {
    return opt.only.empty() || std::find(opt.only.begin(), opt.only.end(), n) != opt.only.end();
  };

  // 1. The descriptor stream and the queries.
  const lshloc::io::DatasetCatalog catalog(
      lshloc::io::DatasetCatalog::resolve_data_dir(data_dir, LSHLOC_SOURCE_DIR "/../shared/data"));
  lshloc::FeatureExtractor extractor;
  const lshloc::DescriptorContextConfig context;
  std::vector<Descriptor> stream;
  stream.reserve(total);
  lshloc::LocationStore locations;
  std::vector<Query> queries;
  const std::vector<std::string> targets = {"intel", "fr101"};
  auto add_submap_features = [&](const lshloc::Submap& submap, std::uint32_t submap_id) {
    for (const auto& sf : lshloc::extract_submap_features(submap, extractor, context))
      for (const auto& f : sf.features) {
        if (stream.size() == total) return;
        stream.push_back(f.descriptor);
        locations.append(submap_id, f.pose);
      }
  };
  std::uint32_t submap_id = 0;
  for (const std::string& b : targets) {
    lshloc::ScenarioConfig sc;
    sc.building = b;
    const lshloc::Scenario s = lshloc::io::load_scenario(catalog, sc);
    const std::size_t first = stream.size();
    add_submap_features(s.submaps[s.target_submap], submap_id);
    for (const auto& sf : lshloc::extract_target_features_at_truth(s.target, extractor, context))
      for (const auto& f : sf.features) {
        bool covered = false;
        for (std::size_t id = first; id < stream.size() && !covered; ++id)
          covered = std::hypot(locations[static_cast<std::uint32_t>(id)].x - f.pose.x,
                               locations[static_cast<std::uint32_t>(id)].y - f.pose.y) <= 0.5;
        if (covered) queries.push_back({f.descriptor, submap_id, f.pose});
      }
    ++submap_id;
  }
  const std::size_t true_map = stream.size();
  for (const char* b : {"fr079", "aces", "mit-csail", "acapulco", "belgioioso", "edmonton", "fhw", "freiburg-campus",
                        "infinite-corridor", "orebro", "seattle"}) {
    if (stream.size() == total) break;
    try {
      const lshloc::BuildingRecording rec = catalog.load(b, false);
      add_submap_features(lshloc::whole_building_submap(rec), submap_id++);
    } catch (const lshloc::Error& e) {
      std::fprintf(stderr, "note: building %s left out: %s\n", b, e.what());
    }
  }
  const std::size_t real = stream.size();
  std::mt19937_64 rng(12345);
  std::normal_distribution<float> noise(0.0f, static_cast<float>(opt.copy_noise));
  // Copies of the other buildings only (a synthetic building is a noisy copy
  // of a real other one; the query buildings stay unique, as in a real map).
  const std::size_t pool = real - true_map;
  if (pool == 0 && stream.size() < total) throw lshloc::Error("no other buildings to copy: check the data directory");
  for (std::size_t i = 0; stream.size() < total; ++i) {
    const std::size_t src = true_map + i % pool;
    Descriptor d = stream[src];
    double n2 = 0.0;
    for (float& v : d) v += noise(rng), n2 += double(v) * v;
    const float inv = static_cast<float>(1.0 / std::sqrt(n2));
    for (float& v : d) v *= inv;
    stream.push_back(d);
    const auto& loc = locations[static_cast<std::uint32_t>(src)];
    locations.append(lshloc::MapLocation{1000u + static_cast<std::uint32_t>(i / pool), loc.x, loc.y, loc.theta});
  }
  std::printf("# stream: %zu entries (%zu of the query buildings' maps, %zu real, %zu noisy copies); %zu queries\n",
              stream.size(), true_map, real, stream.size() - real, queries.size());
  std::fflush(stdout);

  // 2. Each index over the same stream.
  auto hit = [&](const Query& q, const std::vector<std::uint32_t>& ids) {
    for (std::uint32_t id : ids) {
      const auto& loc = locations[id];
      if (loc.submap == q.submap && std::hypot(loc.x - q.pose.x, loc.y - q.pose.y) <= 0.5 &&
          lshloc::angle_distance(loc.theta, q.pose.theta) <= 20.0 * std::numbers::pi / 180.0)
        return true;
    }
    return false;
  };
  std::vector<std::function<std::unique_ptr<Index>()>> makers;
  if (wanted("lshloc")) makers.push_back([&] { return std::make_unique<LshlocIndex>(opt.lsh, "lshloc"); });
  if (wanted("lshloc-fine"))
    makers.push_back([&] { return std::make_unique<LshlocIndex>(fine_buckets(opt.lsh), "lshloc-fine"); });
#ifdef LSHLOC_HAVE_HNSWLIB
  if (wanted("hnswlib")) makers.push_back([&] { return std::make_unique<HnswlibIndex>(total, opt); });
#else
  std::printf("# hnswlib: not found at build time, skipped\n");
#endif
#ifdef LSHLOC_HAVE_FAISS
  omp_set_num_threads(1);  // one thread for every index
  if (wanted("faiss-hnsw"))
    makers.push_back([&] {
      auto idx = std::make_unique<faiss::IndexHNSWFlat>(kDim, static_cast<int>(opt.hnsw_m));
      idx->hnsw.efConstruction = static_cast<int>(opt.hnsw_ef_construction);
      idx->hnsw.efSearch = static_cast<int>(opt.hnsw_ef);
      const std::string p = "M=" + std::to_string(opt.hnsw_m) + " efC=" + std::to_string(opt.hnsw_ef_construction) +
                            " ef=" + std::to_string(opt.hnsw_ef);
      return std::make_unique<FaissIndex>(std::move(idx), "faiss-hnswflat", p, true);
    });
  if (wanted("faiss-lsh"))
    makers.push_back([&] {
      return std::make_unique<FaissIndex>(
          std::make_unique<faiss::IndexLSH>(kDim, opt.faiss_lsh_bits, true, false), "faiss-lsh",
          "nbits=" + std::to_string(opt.faiss_lsh_bits) + " (exhaustive Hamming scan)", false);
    });
#else
  std::printf("# FAISS: not found at build time, skipped\n");
#endif
#ifdef LSHLOC_HAVE_FLANN
  if (wanted("flann")) makers.push_back([&] { return std::make_unique<FlannIndex>(stream, opt.flann_checks); });
#else
  std::printf("# FLANN: not found at build time, skipped\n");
#endif

  std::printf("%-15s %9s %11s %11s %9s %9s  %s\n", "index", "entries", "insert_us", "query_us", "recall100",
              "bytes/ent", "params");
  std::vector<std::uint32_t> out;
  for (auto& make : makers) {
    const std::size_t heap0 = heap_bytes();
    std::unique_ptr<Index> index = make();
    double insert_s = 0.0, query_s = 0.0;
    std::size_t inserted_since = 0, queried_since = 0, next_query = 0, added = 0;
    for (std::size_t size : opt.sizes) {
      for (; added < size; ++added) {
        const auto t0 = Clock::now();
        index->add(stream[added], static_cast<std::uint32_t>(added));
        insert_s += std::chrono::duration<double>(Clock::now() - t0).count();
        ++inserted_since;
        if (opt.query_every && added % opt.query_every == opt.query_every - 1) {
          const auto tf = Clock::now();
          index->flush();
          insert_s += std::chrono::duration<double>(Clock::now() - tf).count();
          const auto t1 = Clock::now();
          index->search(queries[next_query++ % queries.size()].descriptor, 100, out);
          query_s += std::chrono::duration<double>(Clock::now() - t1).count();
          ++queried_since;
        }
      }
      {
        const auto tf = Clock::now();
        index->flush();
        insert_s += std::chrono::duration<double>(Clock::now() - tf).count();
      }
      std::size_t hits = 0;
      for (const Query& q : queries) {
        const auto t1 = Clock::now();
        index->search(q.descriptor, 100, out);
        query_s += std::chrono::duration<double>(Clock::now() - t1).count();
        ++queried_since;
        hits += hit(q, out);
      }
      const std::size_t held = index->own_bytes() > 0 ? index->own_bytes() : heap_bytes() - heap0;
      const double bytes = static_cast<double>(held) / static_cast<double>(size);
      std::string params = index->params();
      if (auto* l = dynamic_cast<LshlocIndex*>(index.get())) {
        params += " cand=" + std::to_string(static_cast<long>(l->mean_candidates()));
        // Recall if every candidate were returned: what a better ranking could reach.
        std::size_t any = 0;
        for (const Query& q : queries) {
          l->search(q.descriptor, opt.lsh.max_candidates, out);
          any += hit(q, out);
        }
        char buf[64];
        std::snprintf(buf, sizeof buf, " recall_all_cand=%.3f",
                      static_cast<double>(any) / static_cast<double>(queries.size()));
        params += buf;
      }
      std::printf("%-15s %9zu %11.2f %11.2f %9.3f %9.0f  %s\n", index->name().c_str(), size,
                  1e6 * insert_s / static_cast<double>(inserted_since),
                  1e6 * query_s / static_cast<double>(queried_since),
                  static_cast<double>(hits) / static_cast<double>(queries.size()), bytes, params.c_str());
      std::fflush(stdout);
      insert_s = query_s = 0.0;
      inserted_since = queried_since = 0;
    }
  }
  return 0;
} catch (const std::exception& e) {
  std::fprintf(stderr, "lsh_peers_bench: error: %s\n", e.what());
  return 1;
}
