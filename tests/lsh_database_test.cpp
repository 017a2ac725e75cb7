// LshDatabase against brute-force nearest neighbours on seeded synthetic
// descriptors; bucket cap, determinism and id validity.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <numeric>
#include <random>
#include <set>

#include "lshloc/common/byte_codec.hpp"
#include "lshloc/common/error.hpp"
#include "lshloc/appearance/location_store.hpp"
#include "lshloc/appearance/lsh_database.hpp"

namespace lshloc {
namespace {

Descriptor normalized(Descriptor d) {
  double n = 0;
  for (float v : d) n += double(v) * v;
  const float inv = static_cast<float>(1.0 / std::sqrt(n));
  for (float& v : d) v *= inv;
  return d;
}

/// Clustered unit vectors: `centres` random directions, each point a centre
/// plus Gaussian noise of `noise` per dimension, normalized (a shape of
/// distances like real descriptors: near neighbours at ~0.3, others at ~1.4).
std::vector<Descriptor> clustered(std::size_t n, std::size_t centres, double noise, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<float> g(0.0f, 1.0f);
  std::vector<Descriptor> c(centres);
  for (auto& d : c) {
    for (float& v : d) v = g(rng);
    d = normalized(d);
  }
  std::vector<Descriptor> out(n);
  const auto s = static_cast<float>(noise);
  for (std::size_t i = 0; i < n; ++i) {
    Descriptor d = c[i % centres];
    for (float& v : d) v += s * g(rng);
    out[i] = normalized(d);
  }
  return out;
}

double dist(const Descriptor& a, const Descriptor& b) {
  double s = 0;
  for (std::size_t i = 0; i < a.size(); ++i) s += double(a[i] - b[i]) * (a[i] - b[i]);
  return std::sqrt(s);
}

TEST(LshDatabase, FindsTheExactNearestNeighbourMostOfTheTime) {
  // 5 noisy copies of each of 4000 centres; the queries are a 6th copy of 400 of them.
  auto data = clustered(20400, 4000, 0.02, 7);
  const std::vector<Descriptor> queries(data.end() - 400, data.end());
  data.resize(20000);
  LshConfig cfg;
  cfg.K = 12, cfg.L = 24, cfg.w = 2.0;
  LshDatabase db(cfg);
  for (std::size_t i = 0; i < data.size(); ++i) db.insert(data[i], static_cast<std::uint32_t>(i));
  EXPECT_EQ(db.size(), data.size());
  std::vector<std::uint32_t> got;
  std::size_t hits = 0;
  for (const auto& q : queries) {
    std::uint32_t best = 0;
    double best_d = 1e9;
    for (std::size_t i = 0; i < data.size(); ++i)
      if (double d = dist(q, data[i]); d < best_d) best_d = d, best = static_cast<std::uint32_t>(i);
    db.query(q, 100, got);
    EXPECT_LE(got.size(), 100u);
    for (auto id : got) EXPECT_LT(id, data.size());
    hits += std::find(got.begin(), got.end(), best) != got.end();
  }
  const double recall = double(hits) / double(queries.size());
  EXPECT_GE(recall, 0.9) << "exact nearest neighbour in the top 100 for " << recall << " of queries";
  const LshStats s = db.stats();
  EXPECT_EQ(s.entries, data.size());
  EXPECT_EQ(s.queries, queries.size());
  // Bounded work: far fewer candidates than the database holds.
  EXPECT_LT(s.mean_candidates_touched(), 0.05 * double(data.size()));
  EXPECT_GT(s.bytes_per_entry(), 8.0 * double(cfg.L));
}

TEST(LshDatabase, RanksByCollisionCountAndReturnsTheQueryItselfFirst) {
  const auto data = clustered(2000, 2000, 0.0, 3);
  LshConfig cfg;
  cfg.sketch_bits = 0;  // rank by collision count alone
  LshDatabase db(cfg);
  for (std::size_t i = 0; i < data.size(); ++i) db.insert(data[i], static_cast<std::uint32_t>(1000 + i));
  LshQuery q(db);
  std::vector<std::uint32_t> ids;
  std::vector<std::uint16_t> counts;
  for (std::size_t i = 0; i < 50; ++i) {
    db.query_counts(data[i], 10, ids, counts, q);
    ASSERT_FALSE(ids.empty());
    EXPECT_EQ(ids[0], 1000 + i);
    EXPECT_EQ(counts[0], db.config().L);  // collides in every table with itself
    EXPECT_TRUE(std::is_sorted(counts.rbegin(), counts.rend()));
  }
  EXPECT_EQ(q.queries, 50u);
}

TEST(LshDatabase, SaysWhenInsertsWouldNotFitItsIdPools) {
  // Checked before a scan enters a map, so that a full pool refuses the scan whole.
  const auto data = clustered(4, 4, 0.0, 5);
  LshDatabase db(LshConfig{});
  for (std::uint32_t id = 0; id < data.size(); ++id) db.insert(data[id], id);
  EXPECT_TRUE(db.has_room_for(1000));
  EXPECT_FALSE(db.has_room_for(std::size_t{1} << 32));
}

TEST(LshDatabase, AnIdInsertedTwiceCountsAtMostLTimes) {
  // Ids need not be unique (a caller may give every feature of a place one
  // id): the ranking's counting sort must stay within its L + 1 counts.
  const auto data = clustered(20, 20, 0.0, 5);
  for (const std::size_t L : {std::size_t{1}, std::size_t{4}}) {
    LshConfig cfg;
    cfg.L = L, cfg.sketch_bits = 0;
    LshDatabase db(cfg);
    for (int k = 0; k < 3; ++k) db.insert(data[0], 7);
    db.insert(data[1], 8);
    LshQuery q(db);
    std::vector<std::uint32_t> ids;
    std::vector<std::uint16_t> counts;
    db.query_counts(data[0], 10, ids, counts, q);
    ASSERT_FALSE(ids.empty());
    EXPECT_EQ(ids[0], 7u);
    EXPECT_EQ(counts[0], L);
    EXPECT_EQ(std::count(ids.begin(), ids.end(), 7u), 1);
  }
}

TEST(LshDatabase, SketchRankingPutsTheTrueMatchAboveLookAlikes) {
  // Per place: one true copy near the query (~0.2 away) among 30 look-alikes
  // (~0.45 away) that collide almost as often. Collision counts barely tell
  // them apart; sign sketches (an angle estimate) should.
  std::mt19937_64 rng(21);
  std::normal_distribution<float> g(0.0f, 1.0f);
  auto noisy = [&](const Descriptor& c, float s) {
    Descriptor d = c;
    for (float& v : d) v += s * g(rng);
    return normalized(d);
  };
  constexpr std::size_t kPlaces = 200, kLookAlikes = 30;
  std::vector<Descriptor> centres(kPlaces), queries(kPlaces);
  std::vector<std::pair<Descriptor, std::uint32_t>> entries;  // (descriptor, id); true copy of place p: id p
  for (std::size_t p = 0; p < kPlaces; ++p) {
    for (float& v : centres[p]) v = g(rng);
    centres[p] = normalized(centres[p]);
    queries[p] = noisy(centres[p], 0.012f);
    entries.emplace_back(noisy(centres[p], 0.012f), static_cast<std::uint32_t>(p));
    for (std::size_t j = 0; j < kLookAlikes; ++j)
      entries.emplace_back(noisy(centres[p], 0.03f), static_cast<std::uint32_t>(kPlaces + p * kLookAlikes + j));
  }
  std::size_t first[2] = {0, 0};
  for (std::size_t bits : {std::size_t{0}, std::size_t{128}}) {
    LshConfig cfg;
    cfg.sketch_bits = bits;
    cfg.sketch_collision_weight = 1;
    LshDatabase db(cfg);
    for (const auto& [d, id] : entries) db.insert(d, id);
    std::vector<std::uint32_t> got;
    for (std::size_t p = 0; p < kPlaces; ++p) {
      ASSERT_LT(dist(queries[p], entries[p * (kLookAlikes + 1)].first), 0.3);
      db.query(queries[p], 1, got);
      first[bits ? 1 : 0] += !got.empty() && got[0] == p;
    }
  }
  EXPECT_GT(first[1], first[0] + 15) << "true match first: " << first[0] << " by counts, " << first[1]
                                     << " by sketches";
  EXPECT_GE(first[1], kPlaces * 7 / 10);
}

TEST(LshDatabase, HotBucketSamplingKeepsOldAndNewEntries) {
  LshConfig cfg;
  cfg.bucket_capacity = 64;
  cfg.L = 1;
  LshDatabase db(cfg);
  const Descriptor same = clustered(1, 1, 0.0, 1)[0];
  for (std::uint32_t i = 0; i < 6400; ++i) db.insert(same, i);
  std::vector<std::uint32_t> got;
  db.query(same, 1000, got);
  ASSERT_EQ(got.size(), 64u);
  // A uniform sample of 0..6399: about a quarter from each quarter of the stream.
  std::size_t first_quarter = 0;
  for (auto id : got) first_quarter += id < 1600;
  EXPECT_GE(first_quarter, 6u);
  EXPECT_LE(first_quarter, 28u);
  EXPECT_EQ(std::set<std::uint32_t>(got.begin(), got.end()).size(), 64u);
}

TEST(LshDatabase, MaxCandidatesBoundsTheWork) {
  LshConfig cfg;
  cfg.bucket_capacity = 100;  // rounded up to 128
  cfg.L = 10;
  cfg.max_candidates = 250;
  LshDatabase db(cfg);
  const Descriptor same = clustered(1, 1, 0.0, 1)[0];
  for (std::uint32_t i = 0; i < 1000; ++i) db.insert(same, i);
  std::vector<std::uint32_t> got;
  db.query(same, 1000, got);
  EXPECT_EQ(db.stats().candidates_touched, 250u);
  // Two tables' buckets read (128 + 122 entries), each a sample of 0..999.
  EXPECT_GE(got.size(), 128u);
  EXPECT_LE(got.size(), 250u);
  EXPECT_EQ(std::set<std::uint32_t>(got.begin(), got.end()).size(), got.size());
  EXPECT_LT(*std::max_element(got.begin(), got.end()), 1000u);
}

TEST(LshDatabase, SameSeedSameAnswersOtherSeedOtherTables) {
  const auto data = clustered(3000, 600, 0.03, 11);
  LshConfig cfg;
  LshDatabase a(cfg), b(cfg);
  cfg.seed += 1;
  LshDatabase c(cfg);
  for (std::size_t i = 0; i < data.size(); ++i) {
    a.insert(data[i], static_cast<std::uint32_t>(i));
    b.insert(data[i], static_cast<std::uint32_t>(i));
    c.insert(data[i], static_cast<std::uint32_t>(i));
  }
  std::vector<std::uint32_t> ra, rb, rc;
  std::size_t differ = 0;
  for (std::size_t i = 0; i < 100; ++i) {
    a.query(data[i * 7], 20, ra);
    b.query(data[i * 7], 20, rb);
    c.query(data[i * 7], 20, rc);
    EXPECT_EQ(ra, rb);
    differ += ra != rc;
  }
  EXPECT_GT(differ, 0u);
  EXPECT_EQ(a.stats().buckets, b.stats().buckets);
}

TEST(LshDatabase, RejectsBadConfigs) {
  LshConfig cfg;
  cfg.w = 0.0;
  EXPECT_THROW(LshDatabase{cfg}, Error);
  cfg = {};
  cfg.K = 0;
  EXPECT_THROW(LshDatabase{cfg}, Error);
  cfg = {};
  cfg.bucket_capacity = 0;
  EXPECT_THROW(LshDatabase{cfg}, Error);
}

TEST(LshDatabase, QueryObjectFromAnotherConfigurationIsRefused) {
  LshConfig small;
  small.max_candidates = 4;
  LshDatabase a(small), b;
  LshQuery qa(a);
  std::vector<std::uint32_t> out;
  EXPECT_THROW(b.query(Descriptor{}, 5, out, qa), Error);
}

// A non-finite component is refused by name; a finite but huge one hashes to
// the edge cells (no overflowing cast) and still finds itself.
TEST(LshDatabase, NonFiniteDescriptorsAreRefusedAndHugeOnesHashToEdgeCells) {
  LshDatabase db;
  const std::vector<Descriptor> d = clustered(50, 5, 0.05, 11);
  for (std::uint32_t i = 0; i < d.size(); ++i) db.insert(d[i], i);
  Descriptor bad = d[0];
  bad[7] = std::numeric_limits<float>::quiet_NaN();
  std::vector<std::uint32_t> out;
  try {
    db.query(bad, 5, out);
    ADD_FAILURE() << "a NaN component was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("descriptor component 7"), std::string::npos) << e.what();
  }
  bad[7] = std::numeric_limits<float>::infinity();
  EXPECT_THROW(db.insert(bad, 50), Error);
  EXPECT_EQ(db.size(), d.size());

  Descriptor huge{};
  huge[0] = 1e30f, huge[1] = -1e30f;
  db.insert(huge, 51);
  db.query(huge, 5, out);
  ASSERT_FALSE(out.empty());
  EXPECT_EQ(out[0], 51u);
}

TEST(LocationStore, IdsAreIndicesAndUnknownIdsThrow) {
  LocationStore store;
  EXPECT_EQ(store.append(2, Pose2(1.0, 2.0, 0.5)), 0u);
  EXPECT_EQ(store.append(MapLocation{3, 4.0f, 5.0f, -1.0f}), 1u);
  EXPECT_EQ(store.at(1).submap, 3u);
  EXPECT_FLOAT_EQ(store.at(0).y, 2.0f);
  EXPECT_THROW(store.at(2), Error);
}

/// The candidates a query reads, by brute force: the query's buckets in
/// the given table order, each read from its first id (at most `capacity`),
/// until the budget.
std::set<std::uint32_t> candidates_read_in_order(const std::vector<std::vector<std::uint32_t>>& bucket_ids,
                                                 const std::vector<std::size_t>& order, std::size_t capacity,
                                                 std::size_t budget) {
  std::set<std::uint32_t> read;
  for (std::size_t t : order)
    for (std::size_t i = 0; i < std::min(capacity, bucket_ids[t].size()); ++i) {
      if (budget == 0) return read;
      read.insert(bucket_ids[t][i]), --budget;
    }
  return read;
}

TEST(LshDatabase, TheBudgetReadsTheLeastFilledBucketsFirst) {
  // Keys put known ids into the query's bucket of each table: random fills up
  // to the capacity, one table's bucket given far more ids than it keeps.
  // The ids read must be those of the buckets in ascending fill (ties: table
  // order), or in table order without rarest_buckets_first.
  std::mt19937_64 rng(31);
  for (int trial = 0; trial < 40; ++trial) {
    LshConfig cfg;
    cfg.L = 6;
    cfg.sketch_bits = 0;
    cfg.bucket_capacity = 16;
    cfg.rarest_buckets_first = trial % 2 == 0;
    const std::size_t hot = rng() % cfg.L;
    std::vector<std::size_t> given(cfg.L);
    for (std::size_t t = 0; t < cfg.L; ++t) given[t] = t == hot ? 200 : rng() % 17;
    std::size_t kept_outside_hot = 0;
    for (std::size_t t = 0; t < cfg.L; ++t) kept_outside_hot += t == hot ? 0 : given[t];
    cfg.max_candidates = 1 + rng() % std::max<std::size_t>(kept_outside_hot, 1);
    LshDatabase db(cfg);
    std::vector<std::uint32_t> query_tags(cfg.L), tags(cfg.L);
    for (std::size_t t = 0; t < cfg.L; ++t) query_tags[t] = 1000 + static_cast<std::uint32_t>(t);
    std::vector<std::vector<std::uint32_t>> bucket_ids(cfg.L);
    std::uint32_t id = 0;
    for (std::size_t t = 0; t < cfg.L; ++t)
      for (std::size_t i = 0; i < given[t]; ++i, ++id) {
        // The query's tag in table t, a tag of its own everywhere else.
        for (std::size_t u = 0; u < cfg.L; ++u) tags[u] = u == t ? query_tags[t] : 1u << 20 | id;
        db.insert(LshKeyView{tags, {}}, id);
        bucket_ids[t].push_back(id);
      }
    std::vector<std::size_t> order(cfg.L);
    std::iota(order.begin(), order.end(), 0);
    if (cfg.rarest_buckets_first)
      std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return given[a] < given[b]; });
    const std::set<std::uint32_t> expected = candidates_read_in_order(bucket_ids, order, 16, cfg.max_candidates);
    LshQuery q(db);
    std::vector<std::uint32_t> got;
    std::vector<std::uint16_t> counts;
    db.query_counts(LshKeyView{query_tags, {}}, 10000, got, counts, q);
    // Reading up to the hot bucket (table order only: the budget never reaches
    // it least-filled first) takes a sample of its 200 ids, not its first 16.
    std::size_t budget = cfg.max_candidates, hot_read = 0;
    for (std::size_t t : order) {
      const std::size_t n = std::min({budget, given[t], std::size_t{16}});
      if (t == hot) hot_read = n;
      budget -= n;
    }
    if (hot_read > 0) {
      ASSERT_FALSE(cfg.rarest_buckets_first);
      std::size_t from_hot = 0;
      for (std::uint32_t g : got) {
        const bool in_hot = std::find(bucket_ids[hot].begin(), bucket_ids[hot].end(), g) != bucket_ids[hot].end();
        from_hot += in_hot;
        if (!in_hot) {
          EXPECT_TRUE(expected.count(g)) << "trial " << trial << ": id " << g;
        }
      }
      EXPECT_EQ(from_hot, hot_read) << "trial " << trial;
      EXPECT_EQ(got.size(), cfg.max_candidates) << "trial " << trial;
      continue;
    }
    EXPECT_EQ(std::set<std::uint32_t>(got.begin(), got.end()), expected) << "trial " << trial;
    EXPECT_EQ(q.candidates_touched, expected.size());
  }
}

std::vector<std::uint8_t> lsh_snapshot(const LshDatabase& db) {
  ByteWriter w;
  db.write_snapshot(w);
  return w.take();
}

/// Every query's ids and collision counts, one after the other (a
/// separator after each answer), from a fresh LshQuery; `touched` gets the
/// bucket entries those queries read.
std::vector<std::uint32_t> every_answer(const LshDatabase& db, const std::vector<Descriptor>& queries, std::size_t k,
                                        std::size_t* touched = nullptr) {
  LshQuery q(db);
  std::vector<std::uint32_t> ids, all;
  std::vector<std::uint16_t> counts;
  for (const Descriptor& d : queries) {
    db.query_counts(d, k, ids, counts, q);
    all.insert(all.end(), ids.begin(), ids.end());
    all.insert(all.end(), counts.begin(), counts.end());
    all.push_back(0xFFFFFFFFu);  // ends a query's answer
  }
  if (touched != nullptr) *touched = q.candidates_touched;
  return all;
}

TEST(LshDatabase, SketchesInTheBucketsRankAsThePerIdArrayDoes) {
  // Full buckets (3 hashes a table, capacity 8: evictions and block moves); the sketches live
  // in the per-id array, move into the buckets part-way, or from the first
  // insert. Every answer is the same, and so is every answer after a
  // snapshot reload.
  const auto data = clustered(6000, 40, 0.2, 23);
  const auto queries = clustered(150, 40, 0.2, 24);
  std::vector<std::unique_ptr<LshDatabase>> dbs;
  for (const double copies : {0.0, 3.0, 24.0}) {  // never, once buckets fill, from the first insert
    LshConfig cfg;
    cfg.K = 3;  // few buckets a table: they fill
    cfg.bucket_capacity = 8;
    cfg.max_sketch_copies = copies;
    dbs.push_back(std::make_unique<LshDatabase>(cfg));
  }
  std::size_t moved_at = 0;
  for (std::size_t i = 0; i < data.size(); ++i) {
    for (auto& db : dbs) db->insert(data[i], static_cast<std::uint32_t>(i));
    if (moved_at == 0 && dbs[1]->sketches_in_buckets()) moved_at = i + 1;
    EXPECT_TRUE(dbs[2]->sketches_in_buckets()) << i;
  }
  // 24 tables of buckets keeping at most 8 ids: the copies come down to 3
  // per descriptor part-way.
  EXPECT_GT(moved_at, 100u);
  EXPECT_LT(moved_at, 5000u);
  EXPECT_FALSE(dbs[0]->sketches_in_buckets());
  EXPECT_TRUE(dbs[2]->sketches_in_buckets());
  const LshStats moved = dbs[1]->stats();
  EXPECT_TRUE(moved.sketches_in_buckets);
  EXPECT_LE(moved.kept, 3 * moved.entries);
  EXPECT_EQ(moved.kept, dbs[0]->stats().kept);
  EXPECT_LE(dbs[1]->stats().bytes, dbs[0]->stats().bytes + 2 * 16 * data.size())
      << "at most 2 more copies a descriptor";
  const auto answers = [&](const LshDatabase& db) { return every_answer(db, queries, 50); };
  const auto expected = answers(*dbs[0]);
  ASSERT_GT(expected.size(), 150u * 40) << "the queries find candidates";
  for (std::size_t k = 1; k < dbs.size(); ++k) EXPECT_EQ(answers(*dbs[k]), expected) << k;
  // Reloads: either snapshot into either layout answers the same; a
  // layout's snapshot reloads into its own layout bit for bit.
  for (std::size_t from_db = 0; from_db < dbs.size(); ++from_db) {
    const auto bytes = lsh_snapshot(*dbs[from_db]);
    for (std::size_t into = 0; into < dbs.size(); ++into) {
      LshDatabase back(dbs[into]->config());
      ByteReader in(bytes, "lsh");
      back.read_snapshot(in, data.size());
      EXPECT_EQ(back.sketches_in_buckets(), dbs[into]->sketches_in_buckets());
      EXPECT_EQ(answers(back), expected) << from_db << " into " << into;
      if (into == from_db) {
        EXPECT_EQ(lsh_snapshot(back), bytes) << into;
      }
    }
  }
}

TEST(LshDatabase, AKeyInsertsAndQueriesAsItsDescriptorDoes) {
  // A second database of the same hashing, fed only the first one's keys,
  // answers every query as the first does; queries by key equal queries by
  // descriptor.
  const auto data = clustered(3000, 300, 0.15, 17);
  LshDatabase a, b;
  ASSERT_TRUE(same_hashing(a.config(), b.config()));
  for (std::size_t i = 0; i < data.size(); ++i) {
    const auto id = static_cast<std::uint32_t>(i);
    a.insert(data[i], id);
    const std::vector<std::uint32_t> tags(a.last_insert_tags().begin(), a.last_insert_tags().end());
    b.insert(LshKeyView{tags, a.last_insert_sketch()}, id);
  }
  LshQuery qa(a), qb(b), qk(a);
  std::vector<std::uint32_t> ia, ib, ik;
  std::vector<std::uint16_t> ca, cb, ck;
  const auto queries = clustered(200, 300, 0.15, 18);
  std::size_t found = 0;
  for (const Descriptor& d : queries) {
    a.query_counts(d, 20, ia, ca, qa);
    b.query_counts(d, 20, ib, cb, qb);
    EXPECT_EQ(ia, ib);
    EXPECT_EQ(ca, cb);
    const std::vector<std::uint32_t> tags(qa.last_key().tags.begin(), qa.last_key().tags.end());
    const std::vector<std::uint64_t> sketch(qa.last_key().sketch.begin(), qa.last_key().sketch.end());
    a.query_counts(LshKeyView{tags, sketch}, 20, ik, ck, qk);
    EXPECT_EQ(ia, ik);
    EXPECT_EQ(ca, ck);
    found += ia.size();
  }
  EXPECT_GT(found, 200u) << "the queries find something to compare";
  const std::vector<std::uint32_t> short_tags(3, 0);
  EXPECT_THROW(a.query_counts(LshKeyView{short_tags, {}}, 5, ik, ck, qk), Error);
  EXPECT_THROW(b.insert(LshKeyView{short_tags, {}}, 0), Error);
  LshConfig other;
  other.seed += 1;
  EXPECT_FALSE(same_hashing(a.config(), other));
}

TEST(LshDatabase, QuerySettingsSetAfterTheBuildAnswerAsIfBuiltWithThem) {
  // Full buckets (so the budget binds); a database built with the defaults'
  // query settings, then given others, answers every query as one built
  // with the others does; layout settings in the asked config are ignored.
  const auto data = clustered(6000, 40, 0.2, 31);
  const auto queries = clustered(150, 40, 0.2, 32);
  LshConfig built;
  built.K = 3;
  built.bucket_capacity = 16;
  built.max_candidates = 100;
  LshConfig tuned = built;
  tuned.max_candidates = 300;
  tuned.rarest_buckets_first = false;
  tuned.sketch_collision_weight = 3;
  LshDatabase retuned(built), reference(tuned);
  for (std::size_t i = 0; i < data.size(); ++i) {
    retuned.insert(data[i], static_cast<std::uint32_t>(i));
    reference.insert(data[i], static_cast<std::uint32_t>(i));
  }
  const auto answers = [&](LshDatabase& db) {
    std::size_t touched = 0;
    auto all = every_answer(db, queries, 60, &touched);
    std::vector<std::uint32_t> ids;
    for (const Descriptor& d : queries) {  // the database's own scratch, resized with max_candidates
      db.query(d, 60, ids);
      all.insert(all.end(), ids.begin(), ids.end());
    }
    return std::pair{all, touched};
  };
  const auto before = answers(retuned);
  LshConfig asked = tuned;
  asked.K = 9;  // a layout setting: not taken
  retuned.set_query_settings(asked);
  EXPECT_EQ(retuned.config().K, 3u);
  EXPECT_EQ(retuned.config().max_candidates, 300u);
  const auto after = answers(retuned);
  const auto expected = answers(reference);
  EXPECT_EQ(after.first, expected.first);
  EXPECT_EQ(after.second, expected.second);
  EXPECT_LT(before.second, after.second) << "the larger budget reads more bucket entries";
  EXPECT_NE(before.first, after.first);
  LshConfig bad = tuned;
  bad.max_candidates = 0;
  EXPECT_THROW(retuned.set_query_settings(bad), Error);
  EXPECT_EQ(retuned.config().max_candidates, 300u) << "a refused setting changes nothing";
}

}  // namespace
}  // namespace lshloc
