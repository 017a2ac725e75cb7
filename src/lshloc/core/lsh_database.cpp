#include "lshloc/core/lsh_database.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <numeric>
#include <random>
#include <string>

#include "lshloc/core/error.hpp"

namespace lshloc {

namespace {

void require(bool ok, const char* field, const std::string& expected) {
  if (!ok) throw Error(std::string("LshConfig.") + field + ": expected " + expected);
}

std::uint64_t mix64(std::uint64_t x) {
  x ^= x >> 30;
  x *= 0xBF58476D1CE4E5B9ULL;
  x ^= x >> 27;
  x *= 0x94D049BB133111EBULL;
  x ^= x >> 31;
  return x;
}

}  // namespace

void LshConfig::validate() const {
  require(K >= 1 && K <= 64, "K", "1..64 projections per table");
  require(L >= 1 && L <= 256, "L", "1..256 tables");
  require(std::isfinite(w) && w > 0.0, "w", "a bucket width > 0");
  require(bucket_capacity >= 1, "bucket_capacity", ">= 1");
  require(max_candidates >= 1 && max_candidates <= (1u << 24), "max_candidates", "1..2^24");
  require(initial_slots >= 1 && initial_slots <= (std::size_t{1} << 30), "initial_slots", "1..2^30");
}

LshQuery::LshQuery(const LshDatabase& db) {
  const LshConfig& c = db.config_;
  projections_.resize(static_cast<Eigen::Index>(c.K * c.L));
  const std::size_t slots = std::bit_ceil(2 * std::min(c.max_candidates, c.L * c.bucket_capacity));
  slot_id_.assign(slots, 0);
  slot_count_.assign(slots, 0);
  slot_stamp_.assign(slots, 0);
  found_.reserve(slots);
  mask_ = static_cast<std::uint32_t>(slots - 1);
  shift_ = 32 - std::countr_zero(slots);
  ranked_.reserve(slots);
  histogram_.assign(c.L + 1, 0);
}

namespace {
LshConfig validated(LshConfig c) {
  c.validate();
  return c;
}
}  // namespace

LshDatabase::LshDatabase(LshConfig config) : config_(validated(config)), own_query_(*this) {
  const auto rows = static_cast<Eigen::Index>(config_.K * config_.L);
  a_.resize(rows, static_cast<Eigen::Index>(kDescriptorSize));
  b_.resize(rows);
  std::mt19937_64 rng(config_.seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  // a / w and b / w, so that h = floor(a'.v + b').
  for (Eigen::Index r = 0; r < rows; ++r) {
    for (Eigen::Index c = 0; c < a_.cols(); ++c) a_(r, c) = static_cast<float>(gauss(rng) / config_.w);
    b_(r) = static_cast<float>(uniform(rng));
  }
  table_seed_.resize(config_.L);
  for (auto& s : table_seed_) s = rng();
  tables_.resize(config_.L);
  const std::size_t slots = std::bit_ceil(std::max<std::size_t>(config_.initial_slots, 2));
  for (Table& t : tables_) {
    t.slots.assign(slots, Slot{});
    t.bits = std::countr_zero(slots);
  }
  insert_projections_.resize(rows);
}

void LshDatabase::project(const Descriptor& descriptor, Eigen::VectorXf& out) const {
  const Eigen::Map<const Eigen::Matrix<float, static_cast<int>(kDescriptorSize), 1>> v(descriptor.data());
  out.noalias() = a_ * v;
  out += b_;
}

std::uint32_t LshDatabase::table_tag(const Eigen::VectorXf& projections, std::size_t table) const {
  std::uint64_t h = table_seed_[table];
  const float* p = projections.data() + table * config_.K;
  for (std::size_t i = 0; i < config_.K; ++i) {
    const auto cell = static_cast<std::int64_t>(std::floor(p[i]));
    h = mix64(h ^ static_cast<std::uint64_t>(cell));
  }
  return static_cast<std::uint32_t>(h >> 32);
}

void LshDatabase::grow(Table& t) {
  std::vector<Slot> old = std::move(t.slots);
  t.bits += 1;
  t.slots.assign(std::size_t{1} << t.bits, Slot{});
  const std::size_t mask = t.slots.size() - 1;
  for (const Slot& s : old) {
    if (s.head == kNone) continue;
    std::size_t i = home(s.tag, t.bits);
    while (t.slots[i].head != kNone) i = (i + 1) & mask;
    t.slots[i] = s;
  }
}

void LshDatabase::insert(const Descriptor& descriptor, std::uint32_t id) {
  if (entries_ >= kNone - 1) throw Error("LshDatabase: full (at most 2^32 - 2 entries)");
  project(descriptor, insert_projections_);
  const auto entry = static_cast<std::uint32_t>(entries_);
  for (std::size_t t = 0; t < tables_.size(); ++t) {
    Table& table = tables_[t];
    if (2 * (table.used + 1) > table.slots.size()) grow(table);
    const std::uint32_t tag = table_tag(insert_projections_, t);
    const std::size_t mask = table.slots.size() - 1;
    std::size_t i = home(tag, table.bits);
    while (table.slots[i].head != kNone && table.slots[i].tag != tag) i = (i + 1) & mask;
    Slot& slot = table.slots[i];
    if (slot.head == kNone) {
      slot.tag = tag;
      ++table.used;
    }
    table.nodes.push_back({id, slot.head});
    slot.head = entry;
  }
  ++entries_;
}

void LshDatabase::query(const Descriptor& descriptor, std::size_t k, std::vector<std::uint32_t>& out) {
  query(descriptor, k, out, own_query_);
}

void LshDatabase::query(const Descriptor& descriptor, std::size_t k, std::vector<std::uint32_t>& out,
                        LshQuery& scratch) const {
  thread_local std::vector<std::uint16_t> counts;
  query_counts(descriptor, k, out, counts, scratch);
}

void LshDatabase::query_counts(const Descriptor& descriptor, std::size_t k, std::vector<std::uint32_t>& out,
                               std::vector<std::uint16_t>& counts, LshQuery& q) const {
  out.clear();
  counts.clear();
  if (q.mask_ + 1 < 2 * std::min(config_.max_candidates, config_.L * config_.bucket_capacity))
    throw Error("LshDatabase::query: the LshQuery was made for another database configuration");
  project(descriptor, q.projections_);
  if (++q.stamp_ == 0) {  // stamps wrapped: clear once every 2^32 queries
    std::fill(q.slot_stamp_.begin(), q.slot_stamp_.end(), 0u);
    q.stamp_ = 1;
  }
  q.found_.clear();
  std::size_t touched = 0;
  for (std::size_t t = 0; t < tables_.size() && touched < config_.max_candidates; ++t) {
    const Table& table = tables_[t];
    const std::uint32_t tag = table_tag(q.projections_, t);
    const std::size_t mask = table.slots.size() - 1;
    std::size_t i = home(tag, table.bits);
    while (table.slots[i].head != kNone && table.slots[i].tag != tag) i = (i + 1) & mask;
    std::uint32_t e = table.slots[i].head;
    for (std::size_t n = 0; e != kNone && n < config_.bucket_capacity && touched < config_.max_candidates;
         ++n, ++touched) {
      const Node& node = table.nodes[e];
      e = node.next;
      // Count the id in the open-addressing counting hash.
      std::uint32_t s = (node.id * 0x9E3779B1u) >> q.shift_;
      while (q.slot_stamp_[s] == q.stamp_ && q.slot_id_[s] != node.id) s = (s + 1) & q.mask_;
      if (q.slot_stamp_[s] != q.stamp_) {
        q.slot_stamp_[s] = q.stamp_;
        q.slot_id_[s] = node.id;
        q.slot_count_[s] = 0;
        q.found_.push_back(s);
      }
      ++q.slot_count_[s];
    }
  }
  q.queries += 1;
  q.candidates_touched += touched;
  q.distinct_candidates += q.found_.size();
  // Rank by collision count with a counting sort (counts <= L): O(found + L)
  // and stable, so ties keep first-seen order.
  std::fill(q.histogram_.begin(), q.histogram_.end(), 0u);
  for (std::uint32_t s : q.found_) ++q.histogram_[q.slot_count_[s]];
  std::uint32_t start = 0;  // highest count first
  for (std::size_t c = q.histogram_.size(); c-- > 0;) {
    const std::uint32_t here = q.histogram_[c];
    q.histogram_[c] = start;
    start += here;
  }
  q.ranked_.resize(q.found_.size());
  for (std::uint32_t s : q.found_) q.ranked_[q.histogram_[q.slot_count_[s]]++] = s;
  const std::size_t n = std::min(k, q.ranked_.size());
  out.reserve(n);
  counts.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    out.push_back(q.slot_id_[q.ranked_[i]]);
    counts.push_back(q.slot_count_[q.ranked_[i]]);
  }
}

LshStats LshDatabase::stats() const {
  LshStats s;
  s.entries = entries_;
  for (const Table& t : tables_) {
    s.buckets += t.used;
    s.bytes += t.slots.capacity() * sizeof(Slot) + t.nodes.capacity() * sizeof(Node);
  }
  s.bytes += static_cast<std::size_t>(a_.size() + b_.size()) * sizeof(float) + table_seed_.size() * sizeof(std::uint64_t);
  s.queries = own_query_.queries;
  s.candidates_touched = own_query_.candidates_touched;
  s.distinct_candidates = own_query_.distinct_candidates;
  return s;
}

}  // namespace lshloc
