#include "lshloc/appearance/lsh_database.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <numeric>
#include <optional>
#include <random>
#include <string>

#include "lshloc/common/error.hpp"
#include "lshloc/common/saturated_cell.hpp"

namespace lshloc {

namespace {

std::uint64_t mix64(std::uint64_t x) {
  x ^= x >> 30;
  x *= 0xBF58476D1CE4E5B9ULL;
  x ^= x >> 27;
  x *= 0x94D049BB133111EBULL;
  x ^= x >> 31;
  return x;
}

/// What the ranking's distance loop reads (LshDatabase::rerank_by_sketch).
struct SketchDistances {
  const std::uint64_t* const* slot_sketch;  ///< per counting slot: the candidate's sketch (null: none)
  std::size_t words;
  const std::uint64_t* query;
  std::size_t weight;  ///< bits per table missed
  std::size_t L;
  std::uint32_t no_sketch;  ///< the distance of an id without a sketch: last
};

/// Each ranked candidate's sketch distance, counted into `histogram`.
[[gnu::always_inline]] inline void sketch_distances(const SketchDistances& job, const std::uint32_t* ranked,
                                                    std::size_t n, const std::uint16_t* slot_count,
                                                    std::uint32_t* distance, std::uint32_t* histogram) {
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint64_t* e = job.slot_sketch[ranked[i]];
    std::uint32_t d = job.no_sketch;
    if (e != nullptr) {
      d = 0;
      for (std::size_t w = 0; w < job.words; ++w) d += static_cast<std::uint32_t>(std::popcount(e[w] ^ job.query[w]));
      // Each table the candidate missed costs `weight` bits.
      d += static_cast<std::uint32_t>(job.weight * (job.L - std::min<std::size_t>(slot_count[ranked[i]], job.L)));
    }
    distance[i] = d;
    ++histogram[d];
  }
}

void sketch_distances_portable(const SketchDistances& job, const std::uint32_t* ranked, std::size_t n,
                               const std::uint16_t* slot_count, std::uint32_t* distance, std::uint32_t* histogram) {
  sketch_distances(job, ranked, n, slot_count, distance, histogram);
}

// The build targets baseline x86-64, where a popcount is a library call;
// this copy uses the CPU's popcnt instruction, chosen at run time.
#if defined(__x86_64__) && defined(__GNUC__)
[[gnu::target("popcnt")]] void sketch_distances_popcnt(const SketchDistances& job, const std::uint32_t* ranked,
                                                       std::size_t n, const std::uint16_t* slot_count,
                                                       std::uint32_t* distance, std::uint32_t* histogram) {
  sketch_distances(job, ranked, n, slot_count, distance, histogram);
}
bool cpu_has_popcount() { return __builtin_cpu_supports("popcnt"); }
#else
constexpr auto sketch_distances_popcnt = sketch_distances_portable;
bool cpu_has_popcount() { return false; }
#endif

}  // namespace

void LshConfig::validate() const {
  require(K >= 1 && K <= 64, "LshConfig.K", "1..64 projections per table", K);
  require(L >= 1 && L <= 256, "LshConfig.L", "1..256 tables", L);
  require(std::isfinite(w) && w > 0.0, "LshConfig.w", "a bucket width > 0", w);
  require(bucket_capacity >= 1 && bucket_capacity <= (1u << 16), "LshConfig.bucket_capacity", "1..65536",
          bucket_capacity);
  require(max_candidates >= 1 && max_candidates <= (1u << 24), "LshConfig.max_candidates", "1..2^24", max_candidates);
  require(sketch_bits % 64 == 0 && sketch_bits <= 1024, "LshConfig.sketch_bits", "0 or a multiple of 64 up to 1024",
          sketch_bits);
  require(sketch_collision_weight <= 64, "LshConfig.sketch_collision_weight", "0..64 bits per table",
          sketch_collision_weight);
  require(std::isfinite(max_sketch_copies) && max_sketch_copies >= 0.0, "LshConfig.max_sketch_copies",
          "a number of sketch copies per descriptor >= 0", max_sketch_copies);
  require(initial_slots >= 1 && initial_slots <= (std::size_t{1} << 30), "LshConfig.initial_slots", "1..2^30",
          initial_slots);
}

bool same_hashing(const LshConfig& a, const LshConfig& b) {
  return a.K == b.K && a.L == b.L && a.w == b.w && a.seed == b.seed && a.sketch_bits == b.sketch_bits;
}

LshConfig with_query_settings(LshConfig built, const LshConfig& asked) {
  return with_query_settings_off(built, asked, std::nullopt);
}

LshConfig with_query_settings_off(LshConfig built, const LshConfig& asked, const std::optional<LshConfig>& defaults) {
  const auto take = [&](auto LshConfig::*field) {
    if (!defaults || asked.*field != (*defaults).*field) built.*field = asked.*field;
  };
  take(&LshConfig::max_candidates);
  take(&LshConfig::rarest_buckets_first);
  take(&LshConfig::sketch_collision_weight);
  return built;
}

void LshDatabase::set_query_settings(const LshConfig& asked) {
  const LshConfig next = with_query_settings(config_, asked);
  next.validate();
  config_ = next;
  own_query_.fit_to(*this);
}

void LshQuery::fit_to(const LshDatabase& db) {
  LshQuery fresh(db);
  fresh.queries = queries;
  fresh.candidates_touched = candidates_touched;
  fresh.distinct_candidates = distinct_candidates;
  *this = std::move(fresh);
}

LshQuery::LshQuery(const LshDatabase& db) {
  const LshConfig& c = db.config_;
  projections_.resize(static_cast<Eigen::Index>(c.K * c.L));
  tags_.resize(c.L);
  blocks_.reserve(c.L);
  const std::size_t slots = std::bit_ceil(2 * std::min(c.max_candidates, c.L * c.bucket_capacity));
  slot_id_.assign(slots, 0);
  slot_count_.assign(slots, 0);
  slot_stamp_.assign(slots, 0);
  slot_sketch_.assign(slots, nullptr);
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

LshDatabase::LshDatabase(LshConfig config)
    : config_(validated(config)), hardware_popcount_(cpu_has_popcount()), own_query_(*this) {
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
  tuple_multipliers_.resize(config_.K * config_.L);
  for (auto& m : tuple_multipliers_) m = rng() | 1u;
  rng_state_ = rng();
  sketch_words_ = config_.sketch_bits / 64;
  sketch_a_.resize(static_cast<Eigen::Index>(config_.sketch_bits), static_cast<Eigen::Index>(kDescriptorSize));
  for (Eigen::Index r = 0; r < sketch_a_.rows(); ++r)
    for (Eigen::Index c = 0; c < sketch_a_.cols(); ++c) sketch_a_(r, c) = static_cast<float>(gauss(rng));
  tables_.resize(config_.L);
  const std::size_t slots = std::bit_ceil(std::max<std::size_t>(config_.initial_slots, 2));
  for (Table& t : tables_) {
    t.slots.assign(slots, Slot{});
    t.bits = std::countr_zero(slots);
  }
  insert_projections_.resize(rows);
  insert_tags_.resize(config_.L);
  insert_sketch_.resize(sketch_words_);
  insert_slots_.resize(config_.L);
  capacity_class_ = static_cast<std::uint32_t>(std::countr_zero(std::bit_ceil(config_.bucket_capacity)));
  for (Table& t : tables_) t.free_blocks.resize(capacity_class_ + 1);
}

void LshDatabase::project(const Descriptor& descriptor, Eigen::VectorXf& out) const {
  const Eigen::Map<const Eigen::Matrix<float, static_cast<int>(kDescriptorSize), 1>> v(descriptor.data());
  out.noalias() = a_ * v;
  out += b_;
}

void LshDatabase::hash(const Descriptor& descriptor, Eigen::VectorXf& projections,
                       std::vector<std::uint32_t>& tags) const {
  project(descriptor, projections);
  const std::size_t k = config_.K;
  for (std::size_t t = 0; t < tables_.size(); ++t) {
    // Universal hash of the K-tuple of cells: a dot product with random odd
    // 64-bit multipliers (independent terms, so it pipelines), then one mix.
    const float* p = projections.data() + t * k;
    const std::uint64_t* m = tuple_multipliers_.data() + t * k;
    std::uint64_t h = table_seed_[t];
    for (std::size_t i = 0; i < k; ++i)
      h += static_cast<std::uint64_t>(static_cast<std::uint32_t>(saturated_cell(p[i]))) * m[i];
    tags[t] = static_cast<std::uint32_t>(mix64(h) >> 32);
  }
}

void LshDatabase::grow(Table& t) {
  auto old = std::move(t.slots);
  t.bits += 1;
  t.slots.assign(std::size_t{1} << t.bits, Slot{});
  const std::size_t mask = t.slots.size() - 1;
  for (const Slot& s : old) {
    if (s.inserted == 0) continue;
    std::size_t i = home(s.tag, t.bits);
    while (t.slots[i].inserted != 0) i = (i + 1) & mask;
    t.slots[i] = s;
  }
}

std::uint32_t LshDatabase::allocate(Table& t, std::uint32_t size_class) const {
  std::vector<std::uint32_t>& free = t.free_blocks[size_class];
  if (!free.empty()) {
    const std::uint32_t offset = free.back();
    free.pop_back();
    return offset;
  }
  const std::size_t offset = t.pool.size();
  if (offset + (std::size_t{1} << size_class) > kNone) throw Error("LshDatabase: a table's id pool is full (2^32 ids)");
  t.pool.resize(offset + (std::size_t{1} << size_class));
  if (sketches_in_buckets_) t.sketch_pool.resize(t.pool.size() * sketch_words_);
  return static_cast<std::uint32_t>(offset);
}

void LshDatabase::push(Table& t, Slot& slot, std::uint32_t id, const std::uint64_t* sketch) {
  const std::size_t words = sketches_in_buckets_ ? sketch_words_ : 0;
  const std::uint32_t cap = 1u << capacity_class_;
  if (slot.inserted == 0) {
    slot.size_class = 0;
    slot.offset = allocate(t, 0);
  } else if (slot.inserted == (1u << slot.size_class) && slot.size_class < capacity_class_) {
    // Block full but below the cap: move to a block twice as large.
    const std::uint32_t bigger = allocate(t, slot.size_class + 1);
    std::copy_n(t.pool.begin() + slot.offset, slot.inserted, t.pool.begin() + bigger);
    std::copy_n(t.sketch_pool.begin() + std::size_t{slot.offset} * words, slot.inserted * words,
                t.sketch_pool.begin() + std::size_t{bigger} * words);
    t.free_blocks[slot.size_class].push_back(slot.offset);
    slot.offset = bigger;
    slot.size_class += 1;
  }
  if (slot.inserted < cap) {
    ++kept_;
    t.pool[slot.offset + slot.inserted] = id;
    std::copy_n(sketch, words, t.sketch_pool.begin() + (std::size_t{slot.offset} + slot.inserted) * words);
    slot.inserted += 1;
  } else {
    // Reservoir sampling: the bucket stays a uniform sample of all its ids.
    rng_state_ = mix64(rng_state_ + 0x9E3779B97F4A7C15ULL);
    const std::uint64_t j = rng_state_ % (static_cast<std::uint64_t>(slot.inserted) + 1);
    if (j < cap) {
      t.pool[slot.offset + j] = id;
      std::copy_n(sketch, words, t.sketch_pool.begin() + (slot.offset + j) * words);
    }
    if (slot.inserted < 0xFFFFFFFFu) slot.inserted += 1;
  }
}

void LshDatabase::insert(const Descriptor& descriptor, std::uint32_t id) {
  check_descriptor(descriptor, "LshDatabase::insert");
  hash(descriptor, insert_projections_, insert_tags_);
  if (sketch_words_ > 0) sketch(descriptor, insert_sketch_.data(), insert_signs_);
  place(id);
}

bool LshDatabase::has_room_for(std::size_t inserts) const {
  const std::size_t block = std::size_t{1} << capacity_class_;
  for (const Table& t : tables_)
    if (t.pool.size() + inserts * block > kNone) return false;
  return true;
}

void LshDatabase::check_descriptor(const Descriptor& descriptor, const char* caller) {
  for (std::size_t i = 0; i < descriptor.size(); ++i)
    if (!std::isfinite(descriptor[i]))
      throw Error(std::string(caller) + ": descriptor component " + std::to_string(i) + " is " +
                  std::to_string(descriptor[i]) + ", expected a finite number");
}

void LshDatabase::check_key(LshKeyView key, const char* caller) const {
  if (key.tags.size() != config_.L || key.sketch.size() != sketch_words_) {
    throw Error(std::string(caller) + ": a key of " + std::to_string(key.tags.size()) + " tags and " +
                std::to_string(key.sketch.size()) + " sketch words, expected " + std::to_string(config_.L) + " and " +
                std::to_string(sketch_words_));
  }
}

void LshDatabase::insert(LshKeyView key, std::uint32_t id) {
  check_key(key, "LshDatabase::insert");
  std::copy(key.tags.begin(), key.tags.end(), insert_tags_.begin());
  std::copy(key.sketch.begin(), key.sketch.end(), insert_sketch_.begin());
  place(id);
}

bool LshDatabase::copies_are_cheap() const {
  return sketch_words_ > 0 && !sketches_in_buckets_ &&
         static_cast<double>(kept_) <= config_.max_sketch_copies * static_cast<double>(entries_);
}

template <class EntryFn>
void LshDatabase::for_each_kept(const Table& t, EntryFn&& fn) const {
  const std::uint32_t cap = 1u << capacity_class_;
  for (const Slot& s : t.slots)
    for (std::uint32_t n = 0; n < std::min(s.inserted, cap); ++n) fn(std::size_t{s.offset} + n);
}

void LshDatabase::move_sketches_into_buckets() {
  const std::size_t words = sketch_words_;
  for (Table& t : tables_) {
    t.sketch_pool.assign(t.pool.size() * words, 0);
    for_each_kept(t, [&](std::size_t entry) {
      std::copy_n(sketches_.begin() + std::size_t{t.pool[entry]} * words, words, t.sketch_pool.begin() + entry * words);
    });
  }
  decltype(sketches_)().swap(sketches_);
  sketches_in_buckets_ = true;
}

std::uint64_t* LshDatabase::sketch_slot(std::uint32_t id) {
  if (id >= sketch_ids_) {
    sketch_ids_ = static_cast<std::size_t>(id) + 1;
    sketches_.resize(sketch_ids_ * sketch_words_, 0);
  }
  return sketches_.data() + static_cast<std::size_t>(id) * sketch_words_;
}

void LshDatabase::place(std::uint32_t id) {
  // Three passes over the tables so that their cache misses overlap: find
  // the home slots (prefetching them), find the buckets (prefetching where
  // the id goes), then write.
  for (std::size_t t = 0; t < tables_.size(); ++t) {
    Table& table = tables_[t];
    if (10 * (table.used + 1) > 7 * table.slots.size()) grow(table);
    insert_slots_[t] = home(insert_tags_[t], table.bits);
    __builtin_prefetch(&table.slots[insert_slots_[t]]);
  }
  const std::uint32_t cap_mask = (1u << capacity_class_) - 1;
  for (std::size_t t = 0; t < tables_.size(); ++t) {
    Table& table = tables_[t];
    const std::size_t mask = table.slots.size() - 1;
    std::size_t i = insert_slots_[t];
    while (table.slots[i].inserted != 0 && table.slots[i].tag != insert_tags_[t]) i = (i + 1) & mask;
    insert_slots_[t] = i;
    const Slot& slot = table.slots[i];
    if (slot.inserted != 0) __builtin_prefetch(table.pool.data() + slot.offset + (slot.inserted & cap_mask), 1);
  }
  for (std::size_t t = 0; t < tables_.size(); ++t) {
    Table& table = tables_[t];
    Slot& slot = table.slots[insert_slots_[t]];
    if (slot.inserted == 0) {
      slot.tag = insert_tags_[t];
      ++table.used;
    }
    push(table, slot, id, insert_sketch_.data());
  }
  if (sketch_words_ > 0) {
    if (sketches_in_buckets_)
      sketch_ids_ = std::max(sketch_ids_, static_cast<std::size_t>(id) + 1);
    else
      std::copy(insert_sketch_.begin(), insert_sketch_.end(), sketch_slot(id));
  }
  ++entries_;
  if (copies_are_cheap()) move_sketches_into_buckets();
}

void LshDatabase::query(const Descriptor& descriptor, std::size_t k, std::vector<std::uint32_t>& out) {
  query(descriptor, k, out, own_query_);
}

void LshDatabase::query(const Descriptor& descriptor, std::size_t k, std::vector<std::uint32_t>& out,
                        LshQuery& scratch) const {
  query_counts(descriptor, k, out, scratch.counts_, scratch);
}

void LshDatabase::query_counts(const Descriptor& descriptor, std::size_t k, std::vector<std::uint32_t>& out,
                               std::vector<std::uint16_t>& counts, LshQuery& q) const {
  check_scratch(q);
  check_descriptor(descriptor, "LshDatabase::query");
  hash(descriptor, q.projections_, q.tags_);
  q.sketch_.resize(sketch_words_);
  if (sketch_words_ > 0) sketch(descriptor, q.sketch_.data(), q.signs_);
  query_tags(q.tags_, q.sketch_, k, out, counts, q);
}

void LshDatabase::query_counts(LshKeyView key, std::size_t k, std::vector<std::uint32_t>& out,
                               std::vector<std::uint16_t>& counts, LshQuery& q) const {
  check_key(key, "LshDatabase::query");
  check_scratch(q);
  query_tags(key.tags, key.sketch, k, out, counts, q);
}

bool LshDatabase::serves(const LshQuery& q) const {
  return q.mask_ + 1 >= 2 * std::min(config_.max_candidates, config_.L * config_.bucket_capacity) &&
         q.tags_.size() == config_.L;
}

void LshDatabase::check_scratch(const LshQuery& q) const {
  if (!serves(q)) throw Error("LshDatabase::query: the LshQuery was made for another database configuration");
}

void LshDatabase::query_tags(std::span<const std::uint32_t> tags, std::span<const std::uint64_t> query_sketch,
                             std::size_t k, std::vector<std::uint32_t>& out, std::vector<std::uint16_t>& counts,
                             LshQuery& q) const {
  out.clear();
  counts.clear();
  if (++q.stamp_ == 0) {  // stamps wrapped: clear once every 2^32 queries
    std::fill(q.slot_stamp_.begin(), q.slot_stamp_.end(), 0u);
    q.stamp_ = 1;
  }
  q.found_.clear();
  // As in insert(): find all buckets first (prefetching), then read them.
  for (std::size_t t = 0; t < tables_.size(); ++t)
    __builtin_prefetch(&tables_[t].slots[home(tags[t], tables_[t].bits)]);
  q.blocks_.clear();
  for (std::size_t t = 0; t < tables_.size(); ++t) {
    const Table& table = tables_[t];
    const std::uint32_t tag = tags[t];
    const std::size_t mask = table.slots.size() - 1;
    std::size_t i = home(tag, table.bits);
    while (table.slots[i].inserted != 0 && table.slots[i].tag != tag) i = (i + 1) & mask;
    if (table.slots[i].inserted == 0) continue;
    q.blocks_.emplace_back(static_cast<std::uint32_t>(t), static_cast<std::uint32_t>(i));
  }
  if (config_.rarest_buckets_first) {
    // At most L blocks: an insertion sort (stable, so ties keep table order;
    // no allocation, unlike std::stable_sort).
    const auto given = [&](std::pair<std::uint32_t, std::uint32_t> block) {
      return tables_[block.first].slots[block.second].inserted;
    };
    for (std::size_t a = 1; a < q.blocks_.size(); ++a) {
      const auto block = q.blocks_[a];
      std::size_t b = a;
      for (; b > 0 && given(q.blocks_[b - 1]) > given(block); --b) q.blocks_[b] = q.blocks_[b - 1];
      q.blocks_[b] = block;
    }
  }
  // Every cache line of the ids (and sketches) the budget will read, and
  // no more: in a big map the blocks are in memory, and the budget leaves
  // most of their lines unread.
  std::size_t budget = config_.max_candidates;
  for (const auto& [t, i] : q.blocks_) {
    if (budget == 0) break;
    const Table& table = tables_[t];
    const Slot& slot = table.slots[i];
    const std::size_t count = std::min(held_ids(slot), budget);
    budget -= count;
    for (std::size_t n = 0; n < count; n += 16) __builtin_prefetch(table.pool.data() + slot.offset + n);
    if (const std::uint64_t* sketches = block_sketches(table, slot))
      for (std::size_t n = 0; n < count * sketch_words_; n += 8) __builtin_prefetch(sketches + n);
  }
  std::size_t touched = 0;
  for (const auto& [t, i] : q.blocks_) {
    if (touched >= config_.max_candidates) break;
    const Table& table = tables_[t];
    const Slot& slot = table.slots[i];
    const std::size_t count = std::min(held_ids(slot), config_.max_candidates - touched);
    const std::uint32_t* ids = table.pool.data() + slot.offset;
    const std::uint64_t* sketches = block_sketches(table, slot);
    touched += count;
    for (std::size_t n = 0; n < count; ++n) {
      const std::uint32_t id = ids[n];
      // Count the id in the open-addressing counting hash.
      std::uint32_t s = (id * 0x9E3779B1u) >> q.shift_;
      while (q.slot_stamp_[s] == q.stamp_ && q.slot_id_[s] != id) s = (s + 1) & q.mask_;
      if (q.slot_stamp_[s] != q.stamp_) {
        q.slot_stamp_[s] = q.stamp_;
        q.slot_id_[s] = id;
        q.slot_count_[s] = 0;
        q.found_.push_back(s);
        const std::uint64_t* sketch = nullptr;
        if (sketches != nullptr) {
          sketch = sketches + n * sketch_words_;
        } else if (id < sketch_ids_) {
          // Read when ranking: asked for now, the miss overlaps the counting.
          sketch = sketches_.data() + std::size_t{id} * sketch_words_;
          __builtin_prefetch(sketch);
        }
        q.slot_sketch_[s] = sketch;
      }
      ++q.slot_count_[s];
    }
  }
  q.queries += 1;
  q.candidates_touched += touched;
  q.distinct_candidates += q.found_.size();
  // Rank by collision count with a counting sort (counts <= L): O(found + L)
  // and stable, so ties keep first-seen order. An id inserted twice into one
  // bucket would count twice: counts are capped at L.
  const auto L = static_cast<std::uint16_t>(config_.L);
  for (std::uint32_t s : q.found_) q.slot_count_[s] = std::min(q.slot_count_[s], L);
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
  if (sketch_words_ > 0) rerank_by_sketch(query_sketch, q);
  const std::size_t n = std::min(k, q.ranked_.size());
  out.reserve(n);
  counts.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    out.push_back(q.slot_id_[q.ranked_[i]]);
    counts.push_back(q.slot_count_[q.ranked_[i]]);
  }
}

void LshDatabase::sketch(const Descriptor& descriptor, std::uint64_t* words, Eigen::VectorXf& signs) const {
  const Eigen::Map<const Eigen::Matrix<float, static_cast<int>(kDescriptorSize), 1>> v(descriptor.data());
  signs.noalias() = sketch_a_ * v;
  for (std::size_t w = 0; w < sketch_words_; ++w) {
    std::uint64_t bits = 0;
    for (std::size_t b = 0; b < 64; ++b)
      bits |= static_cast<std::uint64_t>(signs(static_cast<Eigen::Index>(64 * w + b)) > 0.0f) << b;
    words[w] = bits;
  }
}

void LshDatabase::rerank_by_sketch(std::span<const std::uint64_t> query_sketch, LshQuery& q) const {
  // The Hamming distance between sign sketches estimates the angle between
  // descriptors (unit vectors: monotone in L2). A stable counting sort by it
  // keeps the collision-count order among equal distances.
  const std::size_t n = q.ranked_.size();
  q.hamming_.resize(n);
  const std::size_t weight = config_.sketch_collision_weight;
  const std::size_t max_distance = 64 * sketch_words_ + weight * config_.L;
  q.sketch_histogram_.assign(max_distance + 2, 0u);
  const SketchDistances job{.slot_sketch = q.slot_sketch_.data(),
                            .words = sketch_words_,
                            .query = query_sketch.data(),
                            .weight = weight,
                            .L = config_.L,
                            .no_sketch = static_cast<std::uint32_t>(max_distance + 1)};
  (hardware_popcount_ ? sketch_distances_popcnt : sketch_distances_portable)(
      job, q.ranked_.data(), n, q.slot_count_.data(), q.hamming_.data(), q.sketch_histogram_.data());
  std::uint32_t start = 0;
  for (auto& h : q.sketch_histogram_) {
    const std::uint32_t here = h;
    h = start;
    start += here;
  }
  q.reranked_.resize(n);
  for (std::size_t i = 0; i < n; ++i) q.reranked_[q.sketch_histogram_[q.hamming_[i]]++] = q.ranked_[i];
  q.ranked_.swap(q.reranked_);
}

// Per table: its size (log2), then its buckets by ascending tag, each as
// the tag's difference to the previous one, the count of ids it was given
// and the ids it keeps, in order, as differences (ids in a bucket mostly
// ascend: 1-3 bytes instead of 4).
void LshDatabase::write_snapshot(ByteWriter& out) const {
  const std::uint32_t cap = 1u << capacity_class_;
  out.varint(entries_);
  out.u64(rng_state_);
  std::vector<const Slot*> buckets;
  for (const Table& t : tables_) {
    out.u8(static_cast<std::uint8_t>(t.bits));
    buckets.clear();
    for (const Slot& s : t.slots)
      if (s.inserted != 0) buckets.push_back(&s);
    std::sort(buckets.begin(), buckets.end(), [](const Slot* a, const Slot* b) { return a->tag < b->tag; });
    out.varint(buckets.size());
    std::uint32_t previous_tag = 0;
    for (const Slot* s : buckets) {
      out.varint(s->tag - previous_tag);
      previous_tag = s->tag;
      out.varint(s->inserted);
      std::int64_t previous_id = 0;
      const std::uint32_t* ids = t.pool.data() + s->offset;
      for (std::uint32_t n = 0; n < std::min(s->inserted, cap); ++n) {
        out.signed_varint(static_cast<std::int64_t>(ids[n]) - previous_id);
        previous_id = ids[n];
      }
    }
  }
  out.varint(sketch_ids_);
  if (!sketches_in_buckets_) {
    for (const std::uint64_t w : sketches_) out.u64(w);
    return;
  }
  // Gathered from the buckets; an id no bucket keeps any more has lost its
  // sketch, and is written as zeros (no query can reach it).
  std::vector<std::uint64_t> per_id(sketch_ids_ * sketch_words_, 0);
  for (const Table& t : tables_) {
    for_each_kept(t, [&](std::size_t entry) {
      std::copy_n(t.sketch_pool.begin() + entry * sketch_words_, sketch_words_,
                  per_id.begin() + std::size_t{t.pool[entry]} * sketch_words_);
    });
  }
  for (const std::uint64_t w : per_id) out.u64(w);
}

void LshDatabase::read_snapshot(ByteReader& in, std::uint64_t id_limit) {
  if (entries_ != 0) throw Error("LshDatabase::read_snapshot: the database is not empty");
  const std::uint32_t cap = 1u << capacity_class_;
  entries_ = static_cast<std::size_t>(in.varint_at_most(0xFFFFFFFFu, "a count of entries"));
  rng_state_ = in.u64();
  const std::uint64_t max_id = std::min<std::uint64_t>(id_limit, kNone);
  for (Table& t : tables_) {
    const int bits = in.u8();
    if (bits < t.bits || bits > 32)
      in.fail("a table size of 2^" + std::to_string(t.bits) + "..2^32 slots, got 2^" + std::to_string(bits));
    const std::size_t size = std::size_t{1} << bits;
    // At most 70% full, as insert() keeps it (linear probing must find an
    // empty slot), and about a third full once grown (a corrupt size
    // must not allocate gigabytes); a bucket takes 3 bytes or more.
    const auto count = static_cast<std::size_t>(
        in.varint_at_most(std::min(7 * size / 10, in.remaining() / 3), "a bucket count within the table's load"));
    if (bits > t.bits && 4 * count + 4 < size)
      in.fail("a table grown only past 70% load (" + std::to_string(count) + " buckets in 2^" + std::to_string(bits) +
              " slots)");
    t.bits = bits;
    t.slots.assign(size, Slot{});
    const std::size_t mask = size - 1;
    std::uint64_t tag = 0;
    for (std::size_t b = 0; b < count; ++b) {
      const std::uint64_t step = in.varint();
      if (b > 0 && step == 0) in.fail("bucket tags in ascending order");
      tag += step;
      if (tag > 0xFFFFFFFFu) in.fail("a 32-bit bucket tag");
      const auto inserted = static_cast<std::uint32_t>(in.varint_at_most(0xFFFFFFFFu, "a bucket's id count"));
      if (inserted == 0) in.fail("a non-empty bucket");
      const std::uint32_t kept = std::min(inserted, cap);
      const auto size_class = static_cast<std::uint32_t>(std::bit_width(kept - 1));
      if (kept > in.remaining()) in.fail(std::to_string(kept) + " bucket ids (at least a byte each)");
      const std::uint32_t offset = allocate(t, size_class);
      std::int64_t id = 0;
      for (std::uint32_t n = 0; n < kept; ++n) {
        id += in.signed_varint();
        if (id < 0 || static_cast<std::uint64_t>(id) >= max_id)
          in.fail("a location id below " + std::to_string(max_id) + ", got " + std::to_string(id));
        t.pool[offset + n] = static_cast<std::uint32_t>(id);
      }
      std::size_t i = home(static_cast<std::uint32_t>(tag), t.bits);
      while (t.slots[i].inserted != 0) i = (i + 1) & mask;
      t.slots[i] = {static_cast<std::uint32_t>(tag), offset, inserted, size_class};
      ++t.used;
      kept_ += kept;
    }
  }
  sketch_ids_ = static_cast<std::size_t>(in.varint_at_most(max_id, "a sketch count"));
  if (sketch_words_ == 0 && sketch_ids_ != 0) in.fail("no sketches (sketch_bits is 0)");
  const std::size_t words = sketch_ids_ * sketch_words_;
  if (words > in.remaining() / 8) in.fail(std::to_string(words) + " sketch words");
  sketches_.resize(words);
  for (std::uint64_t& w : sketches_) w = in.u64();
  if (sketch_words_ == 0) return;
  for (const Table& t : tables_) {
    for_each_kept(t, [&](std::size_t entry) {
      if (t.pool[entry] >= sketch_ids_)
        in.fail("a sketch for every bucket id (" + std::to_string(sketch_ids_) + " sketches, bucket id " +
                std::to_string(t.pool[entry]) + ")");
    });
  }
  if (copies_are_cheap()) move_sketches_into_buckets();
}

LshStats LshDatabase::stats() const {
  LshStats s;
  s.entries = entries_;
  s.kept = kept_;
  s.sketches_in_buckets = sketches_in_buckets_;
  for (const Table& t : tables_) {
    s.buckets += t.used;
    s.bytes += t.slots.capacity() * sizeof(Slot) + t.pool.capacity() * sizeof(std::uint32_t) +
               t.sketch_pool.capacity() * sizeof(std::uint64_t);
    for (const auto& f : t.free_blocks) s.bytes += f.capacity() * sizeof(std::uint32_t);
  }
  s.bytes += sketches_.capacity() * sizeof(std::uint64_t) + static_cast<std::size_t>(sketch_a_.size()) * sizeof(float);
  s.bytes += static_cast<std::size_t>(a_.size() + b_.size()) * sizeof(float) +
             (table_seed_.size() + tuple_multipliers_.size()) * sizeof(std::uint64_t);
  s.queries = own_query_.queries;
  s.candidates_touched = own_query_.candidates_touched;
  s.distinct_candidates = own_query_.distinct_candidates;
  return s;
}

}  // namespace lshloc
