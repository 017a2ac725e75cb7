#pragma once
// The incremental E2LSH appearance database (docs/design.md section 2.1):
// descriptors in, location ids out, with no rebuild as the map grows.
// Descriptor units (L2-normalized, distances in [0, 2]); no physical units.
// Thread safety: insert() alone; concurrent queries each with their own
// LshQuery (see LshDatabase).
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "lshloc/appearance/feature.hpp"
#include "lshloc/common/byte_codec.hpp"
#include "lshloc/common/huge_page_allocator.hpp"

namespace lshloc {

/// Settings of the E2LSH appearance database (docs/design.md section 2, paper
/// section IV-A). Descriptors are L2-normalized, so distances lie in [0, 2];
/// w is in those units.
struct LshConfig {
  std::size_t K = 12;  ///< projections concatenated per table (paper: 30; with w fit to the data 8..30 recall alike)
  std::size_t L = 24;  ///< hash tables (paper: 20)
  double w = 2.0;      ///< bucket width of h(v) = floor((a.v + b) / w), descriptor units
  std::uint64_t seed = 0x5eed5eedULL;  ///< seeds the Gaussian a and uniform b
  /// A bucket keeps (and a query reads) at most this many ids (rounded up to
  /// a power of two): a hot bucket cannot slow queries or grow. A full
  /// bucket keeps a uniform sample of every id it was given (reservoir
  /// sampling seeded from `seed`: deterministic per insertion order), so old
  /// places stay findable.
  std::size_t bucket_capacity = 64;
  /// A query counts at most this many bucket entries over all tables.
  std::size_t max_candidates = 600;
  /// Read the query's buckets least-filled first (by ids ever given), not in
  /// table order: when max_candidates stops the reading, the buckets left
  /// unread are the crowded ones, where a full bucket's sample is least
  /// likely to hold the true place.
  bool rarest_buckets_first = true;
  /// 0: candidates are ranked by collision count alone (buckets hold ids
  /// only). Else each entry also keeps a sign sketch of this many bits
  /// (multiple of 64; random Gaussian hyperplanes, seeded) under its id, and
  /// candidates are ranked by the sketches' Hamming distance to the query's
  /// (an angle estimate), ties by collision count. Costs sketch_bits / 8
  /// bytes per id (ids should be dense, e.g. LocationStore indices).
  std::size_t sketch_bits = 128;
  /// With sketches, the ranking key is the Hamming distance plus this many
  /// bits for every table the candidate did not collide in (0: sketch only).
  std::size_t sketch_collision_weight = 1;
  /// Once the buckets keep at most this many ids per inserted descriptor (0:
  /// never; L or more: from the first insert), every bucket entry gets a copy
  /// of its id's sketch and the per-id sketch array is dropped. A query then
  /// reads its ~600 candidates' sketches from the ~24 blocks it reads
  /// anyway, not from ~600 random places, which is most of its time once
  /// the map outgrows the caches. The copies cost sketch_bits / 8 bytes per
  /// kept id: up to L per descriptor in a small map, fewer as buckets fill,
  /// until they cost less than the array (BENCHMARKS.md, "Sketches beside
  /// the ids in the buckets"). Rankings are the same either way for ids
  /// inserted once (an id inserted again keeps, in each bucket, the sketch it
  /// came with; the array keeps the last one).
  double max_sketch_copies = 3.0;
  std::size_t initial_slots = 1024;  ///< slots per table at start (rounded up to a power of two)

  /// Throws lshloc::Error naming the first field out of range.
  void validate() const;
};

/// True when databases with these settings hash every descriptor alike (K,
/// L, w, seed and sketch_bits equal): a key one of them computed can query
/// the other.
bool same_hashing(const LshConfig& a, const LshConfig& b);

/// `built` with the settings of `asked` that only queries read
/// (max_candidates, rarest_buckets_first, sketch_collision_weight): a
/// database built with `built` answers with these as one built with them
/// would.
LshConfig with_query_settings(LshConfig built, const LshConfig& asked);
/// The same, but only for the settings in which `asked` differs from
/// `defaults` (a setting left at its default keeps `built`'s); without
/// `defaults`, with_query_settings().
LshConfig with_query_settings_off(LshConfig built, const LshConfig& asked, const std::optional<LshConfig>& defaults);

/// A descriptor as the database hashes it: its L table tags and its sign
/// sketch (sketch_bits / 64 words). Lets a caller that kept the key of an
/// inserted descriptor (LshDatabase::last_insert_tags, last_insert_sketch) query a
/// database of the same hashing without the descriptor.
struct LshKeyView {
  std::span<const std::uint32_t> tags;
  std::span<const std::uint64_t> sketch;
};

/// Sizes and work counters of the database.
struct LshStats {
  std::size_t entries = 0;           ///< inserted descriptors
  std::size_t buckets = 0;           ///< non-empty buckets over all tables
  std::size_t kept = 0;              ///< ids the buckets keep over all tables (at most L per entry)
  bool sketches_in_buckets = false;  ///< the sketches are copied beside the ids (LshConfig::max_sketch_copies)
  std::size_t bytes = 0;             ///< heap bytes held (tables, bucket lists, projections)
  /// Query counters of the database's own scratch (queries made with a
  /// caller's LshQuery are counted in that LshQuery).
  std::size_t queries = 0;
  std::size_t candidates_touched = 0;   ///< bucket entries read by those queries
  std::size_t distinct_candidates = 0;  ///< distinct ids those queries found
  double mean_candidates_touched() const {
    return queries ? static_cast<double>(candidates_touched) / static_cast<double>(queries) : 0.0;
  }
  double bytes_per_entry() const { return entries ? static_cast<double>(bytes) / static_cast<double>(entries) : 0.0; }
};

class LshDatabase;

/// Scratch space and statistics of queries: reusing one makes a query
/// allocation-free. One per thread.
class LshQuery {
 public:
  explicit LshQuery(const LshDatabase& db);
  /// The key of the descriptor last queried by descriptor with this scratch.
  LshKeyView last_key() const { return {tags_, sketch_}; }
  /// Sizes this scratch for `db`'s settings now (after
  /// LshDatabase::set_query_settings); the counters below stay.
  void fit_to(const LshDatabase& db);
  std::size_t queries = 0;
  std::size_t candidates_touched = 0;
  std::size_t distinct_candidates = 0;

 private:
  friend class LshDatabase;
  Eigen::VectorXf projections_;
  std::vector<std::uint32_t> tags_;                              ///< per table
  std::vector<std::pair<std::uint32_t, std::uint32_t>> blocks_;  ///< per table: (table, slot index) hit
  std::vector<std::uint32_t> slot_id_;                           ///< counting hash: id per slot
  std::vector<std::uint16_t> slot_count_;                        ///< collisions per slot
  std::vector<std::uint32_t> slot_stamp_;                        ///< slot valid when equal to stamp_
  std::vector<const std::uint64_t*> slot_sketch_;  ///< the id's sketch in the bucket it was first read from
  std::vector<std::uint32_t> found_;               ///< slots in first-seen order
  std::vector<std::uint32_t> ranked_;              ///< slots by collision count
  std::vector<std::uint32_t> histogram_;           ///< ids per collision count, then rank offsets
  std::vector<std::uint64_t> sketch_;              ///< the query's sign sketch
  Eigen::VectorXf signs_;                          ///< the sketch's projections before their signs
  std::vector<std::uint16_t> counts_;              ///< query()'s collision counts (query_counts() returns them)
  std::vector<std::uint32_t> hamming_;             ///< per ranked candidate
  std::vector<std::uint32_t> sketch_histogram_;    ///< counting sort by Hamming distance
  std::vector<std::uint32_t> reranked_;
  std::uint32_t stamp_ = 0;
  std::uint32_t mask_ = 0;
  int shift_ = 0;
};

/// The incremental E2LSH appearance database: L tables, each keyed by K
/// concatenated p-stable hashes h(v) = floor((a.v + b) / w) with Gaussian a
/// and b uniform in [0, w). Buckets hold location ids (and, in a big map,
/// their sketches); the descriptor is not stored (only an optional 128-bit
/// sign sketch per id).
///
/// Buckets: each bucket keeps its ids in one contiguous block of a per-table
/// pool, doubling from 1 id up to bucket_capacity (rounded up to a power of
/// two); a full bucket then keeps a uniform random sample of all the ids it
/// was given (reservoir sampling),
/// so a hot bucket (a long corridor seen a thousand times) holds and returns
/// at most bucket_capacity ids and neither memory nor query time grows
/// without bound.
///
/// Cost: insert = one (K L x 120) float matrix-vector product plus L bucket
/// pushes (O(1); a block doubling copies at most bucket_capacity ids, and a
/// table's slot array doubles at 70% load: amortized O(1)). Query = the same
/// product plus at most min(L * bucket_capacity, max_candidates) ids read
/// from L contiguous blocks, whatever the database size.
///
/// Memory per entry: 4 bytes per table for the id (up to 2x while a block is
/// half full), plus 16 bytes per slot for each bucket it opens (slots at most
/// 70% full): about 4L..(8L + 23L) bytes, so roughly 100..750 bytes at L = 24
/// depending on how many buckets hold a single id (less as buckets fill up),
/// plus sketch_bits / 8 bytes per id for the sign sketch (16 at the default),
/// or per kept bucket entry once the sketches move into the buckets;
/// LshStats::bytes measures it all (docs/results/appearance.md). The
/// descriptor itself is never stored.
///
/// Ranking: candidates are the ids of the L buckets the query falls in; they
/// are ranked by the Hamming distance of their sign sketch to the query's
/// (sketch_bits > 0), else by how many tables they collided in.
///
/// Thread-safety: insert() must not run concurrently with anything else.
/// Concurrent queries are safe when each thread passes its own LshQuery;
/// the query overload without one uses the database's own scratch and is
/// not thread-safe.
class LshDatabase {
 public:
  explicit LshDatabase(LshConfig config = {});

  const LshConfig& config() const { return config_; }

  /// Adds `descriptor` under location id `id`.
  void insert(const Descriptor& descriptor, std::uint32_t id);
  /// The same for a descriptor given by its key (from a database of the same
  /// hashing). Throws lshloc::Error on a key of other sizes.
  void insert(LshKeyView key, std::uint32_t id);

  /// Answers from now on with `asked`'s query-time settings
  /// (with_query_settings(); the contents and the rest of the config stay).
  /// Not concurrently with queries; an LshQuery made before serves only if
  /// max_candidates did not grow (serves(); query() throws otherwise).
  /// Throws lshloc::Error naming a setting out of range.
  void set_query_settings(const LshConfig& asked);
  /// Whether `q` can serve this database's queries: made for its number of
  /// tables, and for a max_candidates at least as large (else
  /// LshQuery::fit_to).
  bool serves(const LshQuery& q) const;

  /// Up to k ids, most colliding tables first (ties: the first seen, which is
  /// the newest entry of the first tables), into `out` (cleared first).
  void query(const Descriptor& descriptor, std::size_t k, std::vector<std::uint32_t>& out, LshQuery& scratch) const;
  void query(const Descriptor& descriptor, std::size_t k, std::vector<std::uint32_t>& out);

  /// Like query(), with the collision count of each id returned (same order).
  void query_counts(const Descriptor& descriptor, std::size_t k, std::vector<std::uint32_t>& out,
                    std::vector<std::uint16_t>& counts, LshQuery& scratch) const;
  /// The same for a descriptor given by its key (from a database of the same
  /// hashing): equal results. Throws lshloc::Error on a key of other sizes.
  void query_counts(LshKeyView key, std::size_t k, std::vector<std::uint32_t>& out, std::vector<std::uint16_t>& counts,
                    LshQuery& scratch) const;
  /// The table tags of the descriptor the last insert() hashed (valid until
  /// the next insert()).
  std::span<const std::uint32_t> last_insert_tags() const { return insert_tags_; }
  /// The sign sketch of the descriptor the last insert() hashed (valid until
  /// the next insert(); empty without sketches).
  std::span<const std::uint64_t> last_insert_sketch() const { return insert_sketch_; }
  /// True once every bucket entry keeps its sketch
  /// (LshConfig::max_sketch_copies).
  bool sketches_in_buckets() const { return sketches_in_buckets_; }

  /// Whether `inserts` more ids fit every table's id pool (2^32 ids), were
  /// each to need a new bucket block: checked before a scan enters the map.
  bool has_room_for(std::size_t inserts) const;
  std::size_t size() const { return entries_; }
  LshStats stats() const;

  /// The database's contents (every bucket's ids in order, the sketches and
  /// the reservoir sampler's state) in a canonical form: equal contents
  /// write equal bytes whatever the tables' layout (docs/map-format.md).
  void write_snapshot(ByteWriter& out) const;
  /// Restores what write_snapshot() wrote into this database, which must be
  /// empty and have the writer's config; it then answers and grows exactly
  /// as the written one would. Ids must be below `id_limit`. Throws
  /// lshloc::Error naming `in`'s source on anything inconsistent.
  void read_snapshot(ByteReader& in, std::uint64_t id_limit);

 private:
  friend class LshQuery;
  static constexpr std::uint32_t kNone = 0xFFFFFFFFu;
  struct Slot {
    std::uint32_t tag = 0;         ///< 32-bit hash of the K-tuple
    std::uint32_t offset = 0;      ///< first id of the bucket's block in the table's pool
    std::uint32_t inserted = 0;    ///< ids ever pushed (0: empty slot), saturating at 2^32 - 1
    std::uint32_t size_class = 0;  ///< the block holds 2^size_class ids
  };
  struct Table {
    std::vector<Slot, HugePageAllocator<Slot>> slots;  ///< open addressing, linear probing, power-of-two size
    std::vector<std::uint32_t, HugePageAllocator<std::uint32_t>> pool;  ///< the buckets' id blocks
    /// Each pool entry's sketch (sketch_words_ per entry, at the same
    /// index): a query reads its candidates' sketches from the blocks it
    /// already reads, not from one random place per candidate.
    std::vector<std::uint64_t, HugePageAllocator<std::uint64_t>> sketch_pool;
    std::vector<std::vector<std::uint32_t>> free_blocks;  ///< per size class: offsets of released blocks
    std::size_t used = 0;                                 ///< non-empty slots
    int bits = 0;
  };

  void project(const Descriptor& descriptor, Eigen::VectorXf& out) const;
  /// The L table tags of a descriptor (32-bit hashes of each table's K-tuple).
  void hash(const Descriptor& descriptor, Eigen::VectorXf& projections, std::vector<std::uint32_t>& tags) const;
  static std::size_t home(std::uint32_t tag, int bits) {
    return static_cast<std::size_t>((tag * 0x9E3779B97F4A7C15ULL) >> (64 - bits));
  }
  static void grow(Table& t);
  std::uint32_t allocate(Table& t, std::uint32_t size_class) const;
  void push(Table& t, Slot& slot, std::uint32_t id, const std::uint64_t* sketch);
  /// `signs`: scratch for the projections (the caller's: a query's, or the inserting writer's).
  void sketch(const Descriptor& descriptor, std::uint64_t* words, Eigen::VectorXf& signs) const;
  /// Puts `id`, with the sketch in insert_sketch_, into the buckets of
  /// insert_tags_ and counts it as an entry.
  void place(std::uint32_t id);
  /// Where `id`'s sketch goes in the per-id array (grown to hold it).
  std::uint64_t* sketch_slot(std::uint32_t id);
  /// The ids `slot`'s block holds (all it was given, up to the block's size).
  static std::size_t held_ids(const Slot& slot) {
    return std::min<std::size_t>(slot.inserted, std::size_t{1} << slot.size_class);
  }
  /// The sketches beside the ids of `slot`'s block (null while they are in
  /// the per-id array).
  const std::uint64_t* block_sketches(const Table& t, const Slot& slot) const {
    return sketches_in_buckets_ ? t.sketch_pool.data() + std::size_t{slot.offset} * sketch_words_ : nullptr;
  }
  /// Calls fn(pool index) for every id a bucket of `t` keeps.
  template <class EntryFn>
  void for_each_kept(const Table& t, EntryFn&& fn) const;
  /// Whether the sketches should move into the buckets now
  /// (LshConfig::max_sketch_copies).
  bool copies_are_cheap() const;
  /// Copies every bucket entry's sketch from the per-id array into the
  /// buckets, then drops the array.
  void move_sketches_into_buckets();
  /// Throws unless serves(q).
  void check_scratch(const LshQuery& q) const;
  /// Throws lshloc::Error naming `caller` unless `key` has L tags and this database's sketch words.
  void check_key(LshKeyView key, const char* caller) const;
  /// Throws lshloc::Error naming `caller` and the component unless every component is finite.
  static void check_descriptor(const Descriptor& descriptor, const char* caller);
  /// query_counts() once the query's tags (and sketch) are known.
  void query_tags(std::span<const std::uint32_t> tags, std::span<const std::uint64_t> sketch, std::size_t k,
                  std::vector<std::uint32_t>& out, std::vector<std::uint16_t>& counts, LshQuery& q) const;
  void rerank_by_sketch(std::span<const std::uint64_t> query_sketch, LshQuery& q) const;

  LshConfig config_;
  bool hardware_popcount_ = false;  ///< the sketch distances use the popcnt instruction
  /// (K L x 120) Gaussian projections, already divided by w.
  Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> a_;
  Eigen::VectorXf b_;  ///< offsets / w, uniform in [0, 1)
  std::vector<std::uint64_t> table_seed_;
  std::vector<std::uint64_t> tuple_multipliers_;  ///< K L random odd multipliers hashing a K-tuple
  std::vector<Table> tables_;
  std::size_t entries_ = 0;
  std::size_t kept_ = 0;  ///< ids the buckets keep, over all tables
  std::uint32_t capacity_class_ = 0;
  std::uint64_t rng_state_ = 0;  ///< reservoir sampling
  std::size_t sketch_words_ = 0;
  std::size_t sketch_ids_ = 0;  ///< ids 0..sketch_ids_-1 were given a sketch
  /// sketch_words_ per id, until the sketches move into the buckets.
  std::vector<std::uint64_t, HugePageAllocator<std::uint64_t>> sketches_;
  bool sketches_in_buckets_ = false;
  Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>
      sketch_a_;  ///< bucket capacity = 2^capacity_class_
  Eigen::VectorXf insert_projections_;
  std::vector<std::uint32_t> insert_tags_;
  std::vector<std::uint64_t> insert_sketch_;
  Eigen::VectorXf insert_signs_;  ///< scratch of sketch() for inserts
  std::vector<std::size_t> insert_slots_;
  LshQuery own_query_;
};

}  // namespace lshloc
