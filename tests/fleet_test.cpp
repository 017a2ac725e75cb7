// The fleet's map log on Redis: records round-trip and refuse damage, a map
// fed through a real redis-server (the test's own, on a loopback port) equals
// the map built directly, duplicates are skipped and gaps refused, a
// restarted mapper resumes its sequence, and other settings are refused. On
// a 3-master Redis Cluster of the test's own (scripts/redis_cluster.sh): key
// slots equal the server's, the map equals the one built directly, and MOVED
// and ASK redirects are followed while a submap's slot migrates.
// Skips with a message when redis-server is not installed.
#include <gtest/gtest.h>

#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <random>
#include <set>
#include <shared_mutex>
#include <filesystem>
#include <thread>

#include "lshloc/common/error.hpp"
#include "lshloc/eval/localization_metrics.hpp"
#include "lshloc/eval/scenario_runner.hpp"
#include "lshloc/fleet/map_follower.hpp"
#include "lshloc/fleet/map_log.hpp"
#include "lshloc/sim/synthetic_scenario.hpp"
#include "test_support.hpp"

namespace lshloc {
namespace {

using fleet::MapLogConfig;
using fleet::MapLogReader;
using fleet::MapLogWriter;
using fleet::RedisAddress;
using fleet::RedisClient;
using fleet::RedisConnection;

/// A redis-server of the test's own: a free loopback port, no persistence,
/// a temporary directory; stopped (SIGTERM, then waited for) at destruction.
class LocalRedis {
 public:
  LocalRedis() {
    if (std::system("command -v redis-server >/dev/null 2>&1") != 0) return;
    port_ = free_port();
    dir_ = test::temp_path("-redis");
    std::filesystem::create_directories(dir_);
    pid_ = fork();
    if (pid_ == 0) {
      const std::string port = std::to_string(port_);
      execlp("redis-server", "redis-server", "--port", port.c_str(), "--bind", "127.0.0.1", "--save", "",
             "--appendonly", "no", "--dir", dir_.c_str(), "--logfile", "redis.log", static_cast<char*>(nullptr));
      _exit(127);
    }
    for (int i = 0; i < 100; ++i) {  // up to 5 s for the server to answer
      try {
        RedisConnection probe(address(), 1.0);
        probe.command({"PING"});
        running_ = true;
        return;
      } catch (const Error&) {
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
      }
    }
  }
  ~LocalRedis() {
    if (pid_ > 0) {
      kill(pid_, SIGTERM);
      waitpid(pid_, nullptr, 0);
    }
    std::error_code ec;
    if (!dir_.empty()) std::filesystem::remove_all(dir_, ec);
  }
  bool running() const { return running_; }
  RedisAddress address() const { return {"127.0.0.1", port_}; }

 private:
  static int free_port() {
    const int s = socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    bind(s, reinterpret_cast<sockaddr*>(&a), sizeof a);
    socklen_t n = sizeof a;
    getsockname(s, reinterpret_cast<sockaddr*>(&a), &n);
    close(s);
    return ntohs(a.sin_port);
  }
  int port_ = 0;
  pid_t pid_ = -1;
  std::string dir_;
  bool running_ = false;
};

/// A 3-master Redis Cluster of the test's own (scripts/redis_cluster.sh, on
/// free loopback ports), taken down at destruction.
class LocalRedisCluster {
 public:
  LocalRedisCluster() {
    if (std::system("command -v redis-server >/dev/null 2>&1 && command -v redis-cli >/dev/null 2>&1") != 0) return;
    dir_ = test::temp_path("-cluster");
    FILE* p = popen((script() + " start " + dir_).c_str(), "r");
    if (!p) return;
    char line[256] = {};
    const bool got = std::fgets(line, sizeof line, p) != nullptr;
    if (pclose(p) != 0 || !got) return;
    std::string url(line);
    while (!url.empty() && std::isspace(static_cast<unsigned char>(url.back()))) url.pop_back();
    seed_ = RedisAddress::parse(url);
    running_ = true;
  }
  ~LocalRedisCluster() {
    if (dir_.empty()) return;
    [[maybe_unused]] const int rc = std::system((script() + " stop " + dir_).c_str());
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }
  bool running() const { return running_; }
  RedisAddress address() const { return seed_; }

 private:
  static std::string script() { return std::string(LSHLOC_SOURCE_DIR) + "/scripts/redis_cluster.sh"; }
  std::string dir_;
  RedisAddress seed_;
  bool running_ = false;
};

#define LSHLOC_REQUIRE_REDIS_CLUSTER(cluster)                                \
  LocalRedisCluster cluster;                                                 \
  if (!cluster.running())                                                    \
  GTEST_SKIP() << "redis-server/redis-cli not found or the cluster did not " \
                  "start: scripts/setup.sh installs them"

#define LSHLOC_REQUIRE_REDIS(server)                          \
  LocalRedis server;                                          \
  if (!server.running())                                      \
  GTEST_SKIP() << "redis-server not found or did not start: " \
                  "scripts/setup.sh installs it"

LaserScan scan_at(double x) {
  LaserScan s;
  s.timestamp = x;
  s.angle_min = -1.5;
  s.angle_increment = 0.01;
  s.max_range = 30.0;
  s.ranges.assign(301, static_cast<float>(2.0 + x));
  s.pose = Pose2(x, 2.0 * x, 0.1);
  return s;
}

TEST(FleetRecords, RoundTripAndRefuseDamage) {
  const LaserScan s = scan_at(1.5);
  const std::string rec = fleet::encode_update(42, s);
  fleet::MapUpdate u;
  fleet::decode_update(rec, "test", u);
  EXPECT_EQ(u.seq, 42u);
  EXPECT_EQ(u.scan.ranges, s.ranges);
  EXPECT_EQ(u.scan.pose.x, s.pose.x);
  EXPECT_EQ(u.scan.pose.theta, s.pose.theta);
  EXPECT_EQ(u.scan.timestamp, s.timestamp);
  for (std::size_t i = 0; i < rec.size(); i += 7) {
    std::string bad = rec;
    bad[i] = static_cast<char>(bad[i] ^ 0x10);
    EXPECT_THROW(fleet::decode_update(bad, "test", u), Error) << "byte " << i;
  }
  EXPECT_THROW(fleet::decode_update(rec.substr(0, 10), "test", u), Error);
}

TEST(FleetRecords, AddressesParseOrSayWhatWasExpected) {
  EXPECT_EQ(RedisAddress::parse("redis://127.0.0.1:7001").port, 7001);
  EXPECT_EQ(RedisAddress::parse("redis://localhost").port, 6379);
  EXPECT_EQ(RedisAddress::parse("redis://localhost").host, "localhost");
  for (const char* bad : {"http://x:1", "redis://", "redis://h:0", "redis://h:99999", "redis://h:12ab"}) {
    try {
      RedisAddress::parse(bad);
      ADD_FAILURE() << bad << " was accepted";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("expected redis://HOST[:PORT]"), std::string::npos) << e.what();
    }
  }
}

TEST(FleetMapLog, AMapFedThroughRedisEqualsTheMapBuiltDirectly) {
  LSHLOC_REQUIRE_REDIS(server);
  const Scenario sc = sim::synthetic_scenario(test::small_world(300, 50));
  const GlobalMapConfig settings;
  {
    RedisClient redis(server.address());
    for (const Submap& s : sc.submaps) MapLogWriter(redis, s.name, settings).publish(s.scans);
  }
  // Reads of 7 updates per stream, handed out round robin, as MapFeeder
  // feeds a map from files: the same map, bit for bit.
  RedisClient redis(server.address());
  MapLogReader reader(redis, MapLogConfig{.batch = 7});
  GlobalMap through_redis(reader.settings());
  std::size_t applied = 0, polls = 0;
  for (auto updates = reader.poll(); !updates.empty(); updates = reader.poll())
    applied += fleet::apply_updates(through_redis, reader.submaps(), updates).added, ++polls;
  GlobalMap direct(settings);
  MapFeeder(direct, sc.submaps).feed_until(1.0);
  std::size_t scans = 0;
  for (const Submap& s : sc.submaps) scans += s.scans.size();
  EXPECT_EQ(applied, scans);
  EXPECT_GT(polls, 2u);
  for (std::uint32_t i = 0; i < direct.submap_count(); ++i) {
    EXPECT_EQ(direct.submap_name(i), through_redis.submap_name(i));
    EXPECT_EQ(direct.submap_scans(i), through_redis.submap_scans(i));
  }
  EXPECT_EQ(reader.stats().duplicates, 0u);
  EXPECT_EQ(reader.submaps().size(), sc.submaps.size());
  test::expect_same_map_contents(direct, through_redis);
}

TEST(FleetMapLog, AScanTheMapRefusesIsSkippedAndTheUpdatesAfterItApply) {
  LSHLOC_REQUIRE_REDIS(server);
  const Scenario sc = sim::synthetic_scenario(test::small_world(300, 50));
  const GlobalMapConfig settings;
  const Submap& first = sc.submaps.front();
  // A scan 100 km out (beyond the grids' limits) in the middle of the first submap's stream.
  std::vector<LaserScan> scans = first.scans;
  LaserScan far = scans[scans.size() / 2];
  far.pose = Pose2(1e5, 0.0, 0.0);
  scans.insert(scans.begin() + static_cast<std::ptrdiff_t>(scans.size() / 2), far);
  {
    RedisClient redis(server.address());
    MapLogWriter(redis, first.name, settings).publish(scans);
  }
  RedisClient redis(server.address());
  MapLogReader reader(redis, MapLogConfig{.batch = 1000});
  GlobalMap through_redis(reader.settings());
  fleet::AppliedUpdates total;
  for (auto updates = reader.poll(); !updates.empty(); updates = reader.poll()) {
    const fleet::AppliedUpdates a = fleet::apply_updates(through_redis, reader.submaps(), updates);
    total.added += a.added, total.refused += a.refused;
    if (a.refused) total.last_refusal = a.last_refusal;
  }
  EXPECT_EQ(total.added, first.scans.size());
  EXPECT_EQ(total.refused, 1u);
  EXPECT_NE(total.last_refusal.find("submap " + first.name + " scan " + std::to_string(first.scans.size() / 2)),
            std::string::npos)
      << total.last_refusal;
  EXPECT_NE(total.last_refusal.find("outside the grid"), std::string::npos) << total.last_refusal;
  GlobalMap direct(settings);
  direct.add_submap(first.name);
  for (const LaserScan& s : first.scans) direct.add_scan(0, s, s.pose);
  test::expect_same_map_contents(direct, through_redis);
}

TEST(FleetMapLog, AReaderResumedFromASnapshotsPositionsReachesTheSameMap) {
  LSHLOC_REQUIRE_REDIS(server);
  const Scenario sc = sim::synthetic_scenario(test::small_world(300, 50));
  RedisClient redis(server.address());
  const GlobalMapConfig settings;
  // First half of every submap, then a snapshot (map + positions) ...
  std::vector<MapLogWriter> writers;
  for (const Submap& s : sc.submaps) writers.emplace_back(redis, s.name, settings);
  auto half = [](const Submap& s, bool second) {
    const std::size_t h = s.scans.size() / 2;
    return second ? std::span(s.scans).subspan(h) : std::span(s.scans).first(h);
  };
  for (std::size_t i = 0; i < sc.submaps.size(); ++i) writers[i].publish(half(sc.submaps[i], false));
  MapLogReader first(redis);
  GlobalMap snapshot(first.settings());
  for (auto u = first.poll(); !u.empty(); u = first.poll()) fleet::apply_updates(snapshot, first.submaps(), u);
  fleet::apply_updates(snapshot, first.submaps(), {});
  const nlohmann::json saved = fleet::positions_to_json(first.positions());
  // ... the rest is published; a reader resumed at the snapshot's positions
  // applies only the rest, and ends with the map of one that read it all.
  for (std::size_t i = 0; i < sc.submaps.size(); ++i) writers[i].publish(half(sc.submaps[i], true));
  RedisClient redis2(server.address());
  MapLogReader resumed(redis2);
  resumed.resume(fleet::positions_from_json(saved, "test"));
  std::size_t rest = 0;
  for (auto u = resumed.poll(); !u.empty(); u = resumed.poll())
    rest += fleet::apply_updates(snapshot, resumed.submaps(), u).added;
  MapLogReader whole(redis2, MapLogConfig{});
  GlobalMap full(whole.settings());
  for (auto u = whole.poll(); !u.empty(); u = whole.poll()) fleet::apply_updates(full, whole.submaps(), u);
  std::size_t second_halves = 0;
  for (const Submap& s : sc.submaps) second_halves += half(s, true).size();
  EXPECT_EQ(rest, second_halves);
  EXPECT_EQ(snapshot.stats().scans, full.stats().scans);
  ASSERT_EQ(snapshot.submap_count(), full.submap_count());
  for (std::uint32_t i = 0; i < full.submap_count(); ++i) {
    EXPECT_EQ(snapshot.submap_name(i), full.submap_name(i));
    EXPECT_EQ(snapshot.submap_scans(i), full.submap_scans(i));
  }
  EXPECT_THROW(fleet::positions_from_json(nlohmann::json::object(), "test"), Error);
}

TEST(FleetMapLog, DuplicatesAreSkippedGapsRefusedAndAMapperResumes) {
  LSHLOC_REQUIRE_REDIS(server);
  RedisClient redis(server.address());
  std::vector<LaserScan> scans;
  for (int i = 0; i < 10; ++i) scans.push_back(scan_at(i));
  MapLogWriter(redis, "hall", GlobalMapConfig{}).publish(scans);
  // A restarted mapper continues the sequence.
  MapLogWriter again(redis, "hall", GlobalMapConfig{});
  EXPECT_EQ(again.next_seq(), 10u);
  again.publish(std::span(scans).first(2));
  MapLogReader reader(redis);
  EXPECT_EQ(reader.poll().size(), 12u);
  // A repeated entry (a retried XADD) is skipped ...
  const std::string key = MapLogConfig{}.stream_key("hall");
  redis.command({"XADD", key, "*", "seq", "11", "rec", fleet::encode_update(11, scans[1])});
  EXPECT_TRUE(reader.poll().empty());
  EXPECT_EQ(reader.stats().duplicates, 1u);
  // ... and a gap (a lost update) is refused, naming the submap.
  redis.command({"XADD", key, "*", "seq", "13", "rec", fleet::encode_update(13, scans[3])});
  try {
    reader.poll();
    ADD_FAILURE() << "a gap was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("updates of submap hall are missing"), std::string::npos) << e.what();
  }
}

TEST(FleetMapLog, ADamagedEntryStopsItsStreamWithoutLosingWhatOtherStreamsHold) {
  LSHLOC_REQUIRE_REDIS(server);
  RedisClient redis(server.address());
  std::vector<LaserScan> scans;
  for (int i = 0; i < 6; ++i) scans.push_back(scan_at(i));
  fleet::register_map(redis, GlobalMapConfig{}, std::vector<std::string>{"a", "b"});
  MapLogWriter(redis, "a", GlobalMapConfig{}).publish(scans);
  MapLogWriter b(redis, "b", GlobalMapConfig{});
  b.publish(std::span(scans).first(2));
  // Stream b's third entry is damaged (one byte of its record flipped), then b goes on.
  std::string damaged = fleet::encode_update(2, scans[2]);
  damaged[damaged.size() / 2] = static_cast<char>(damaged[damaged.size() / 2] ^ 0x10);
  const std::string key = MapLogConfig{}.stream_key("b");
  redis.command({"XADD", key, "*", "seq", "2", "rec", damaged});
  redis.command({"XADD", key, "*", "seq", "3", "rec", fleet::encode_update(3, scans[3])});
  MapLogReader reader(redis);
  // The first poll hands out all of a and b's first two, and says where it stopped ...
  const std::vector<fleet::MapUpdate> first = reader.poll();
  EXPECT_EQ(first.size(), 8u);
  EXPECT_EQ(std::count_if(first.begin(), first.end(), [](const fleet::MapUpdate& u) { return u.submap == "a"; }), 6);
  EXPECT_NE(reader.stats().stopped.find(key), std::string::npos) << reader.stats().stopped;
  // ... the next meets the damaged entry again, names it, and loses nothing.
  const std::vector<fleet::StreamPosition> before = reader.positions();
  try {
    reader.poll();
    ADD_FAILURE() << "a damaged entry was accepted";
  } catch (const fleet::MapLogRecordError& e) {
    EXPECT_NE(std::string(e.what()).find(key + " entry"), std::string::npos) << e.what();
  }
  const std::vector<fleet::StreamPosition> after = reader.positions();
  ASSERT_EQ(before.size(), after.size());
  for (std::size_t i = 0; i < before.size(); ++i) {
    EXPECT_EQ(before[i].last_id, after[i].last_id);
    EXPECT_EQ(before[i].next_seq, after[i].next_seq);
  }
  EXPECT_EQ(after[1].next_seq, 2u);
  EXPECT_EQ(reader.stats().updates, 8u);
  // A follower says so at once, after applying what came before: no reconnecting for give_up_s (60 s), as a
  // lost server would get.
  fleet::MapFollower follower(server.address(), fleet::MapFollowerConfig{.log = {}, .block_s = 0.05});
  GlobalMap map(follower.settings());
  const auto start = std::chrono::steady_clock::now();
  try {
    follower.catch_up(map);
    ADD_FAILURE() << "a damaged entry was applied";
  } catch (const fleet::MapLogRecordError& e) {
    EXPECT_NE(std::string(e.what()).find(key + " entry"), std::string::npos) << e.what();
  }
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 10.0);
  EXPECT_EQ(map.stats().scans, 8u);
}

TEST(FleetMapLog, AScanNoFollowerCouldReadIsNeverPublished) {
  LSHLOC_REQUIRE_REDIS(server);
  RedisClient redis(server.address());
  std::vector<LaserScan> scans = {scan_at(0), scan_at(1), scan_at(2)};
  scans[2].pose.x = std::nan("");
  MapLogWriter writer(redis, "hall", GlobalMapConfig{});
  try {
    writer.publish(scans);
    ADD_FAILURE() << "a NaN pose was published";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("scan 2 "), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("expected finite pose"), std::string::npos) << e.what();
  }
  const std::string key = MapLogConfig{}.stream_key("hall");
  EXPECT_EQ(redis.command({"XLEN", key}).integer, 0);  // nothing of the call was sent
  EXPECT_EQ(writer.next_seq(), 0u);
  writer.publish(std::span(scans).first(2));
  EXPECT_EQ(redis.command({"XLEN", key}).integer, 2);
}

TEST(FleetMapLog, AReadOfDuplicatesOnlyReadsOn) {
  LSHLOC_REQUIRE_REDIS(server);
  RedisClient redis(server.address());
  std::vector<LaserScan> scans;
  for (int i = 0; i < 301; ++i) scans.push_back(scan_at(0.01 * i));
  MapLogWriter(redis, "hall", GlobalMapConfig{}).publish(scans);
  // A reader resumed at sequence 300 but at the stream's start (a snapshot
  // whose stream was republished): its first read of 256 entries holds only
  // numbers it has seen, which must not read as "nothing new".
  MapLogReader reader(redis, MapLogConfig{.batch = 256});
  reader.resume({{"hall", "0-0", 300}});
  const std::vector<fleet::MapUpdate> got = reader.poll();
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].seq, 300u);
  EXPECT_EQ(reader.stats().duplicates, 300u);
  EXPECT_TRUE(reader.poll().empty());
}

TEST(FleetMapLog, SubmapsAreRegisteredInTheOrderOfTheFirstListAndOnce) {
  LSHLOC_REQUIRE_REDIS(server);
  RedisClient redis(server.address());
  const std::vector<std::string> scenario = {"c", "a", "b"}, later = {"a", "d", "c"};
  // Mappers of one scenario register its whole list: the first one fixes the order.
  fleet::register_map(redis, GlobalMapConfig{}, scenario);
  fleet::register_map(redis, GlobalMapConfig{}, later);
  MapLogWriter(redis, "b", GlobalMapConfig{});
  MapLogReader reader(redis);
  reader.poll();
  EXPECT_EQ(reader.submaps(), (std::vector<std::string>{"c", "a", "b", "d"}));
  EXPECT_EQ(redis.command({"HGET", MapLogConfig{}.registry_key(), "submap_count"}).text, "4");
  EXPECT_THROW(fleet::register_map(redis, GlobalMapConfig{}, std::vector<std::string>{"ok", "x}"}), Error);
}

TEST(FleetMapLog, AMapperWithOtherSettingsIsRefused) {
  LSHLOC_REQUIRE_REDIS(server);
  RedisClient redis(server.address());
  MapLogWriter(redis, "a", GlobalMapConfig{});
  GlobalMapConfig other;
  other.context_scans = 3;
  try {
    MapLogWriter(redis, "b", other);
    ADD_FAILURE() << "other settings were accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("settings differ"), std::string::npos) << e.what();
  }
  EXPECT_THROW(MapLogWriter(redis, "bad{name}", GlobalMapConfig{}), Error);
  RedisClient empty(server.address());
  MapLogReader reader(empty, MapLogConfig{.prefix = "nobody"});
  EXPECT_THROW(reader.settings(), Error);
}

TEST(FleetCluster, HashSlotsAreTheServersOwn) {
  // The CRC-16/XMODEM check value of "123456789" is 0x31C3; Redis's
  // CLUSTER KEYSLOT documentation gives somekey 11058 and foo{hash_tag} 2515.
  EXPECT_EQ(fleet::hash_slot("123456789"), 0x31C3 % 16384);
  EXPECT_EQ(fleet::hash_slot("somekey"), 11058);
  EXPECT_EQ(fleet::hash_slot("foo{hash_tag}"), 2515);
  EXPECT_EQ(fleet::hash_slot("{user1000}.following"), fleet::hash_slot("{user1000}.followers"));
  EXPECT_NE(fleet::hash_slot("foo{}{bar}"), fleet::hash_slot("bar"));
  EXPECT_EQ(fleet::hash_slot("foo{{bar}}zap"), fleet::hash_slot("{bar"));
  EXPECT_EQ(fleet::hash_slot("foo{bar}{zap}"), fleet::hash_slot("bar"));
  EXPECT_EQ(fleet::routing_key(std::vector<std::string>{"XREAD", "COUNT", "5", "streams", "k1", "k2", "0", "0"}), "k1");
  EXPECT_EQ(fleet::routing_key(std::vector<std::string>{"HGET", "reg", "f"}), "reg");
  LSHLOC_REQUIRE_REDIS_CLUSTER(cluster);
  RedisConnection node(cluster.address());
  std::mt19937 rng(7);
  const std::string alphabet = "abcXYZ019{}:-_ ";
  for (int i = 0; i < 300; ++i) {
    std::string key(1 + rng() % 12, ' ');
    for (char& c : key) c = alphabet[rng() % alphabet.size()];
    const fleet::Reply r = node.command({"CLUSTER", "KEYSLOT", key});
    EXPECT_EQ(fleet::hash_slot(key), r.integer) << "key '" << key << "'";
  }
}

TEST(FleetCluster, AMapFedThroughAClusterEqualsTheMapBuiltDirectly) {
  LSHLOC_REQUIRE_REDIS_CLUSTER(cluster);
  const Scenario sc = sim::synthetic_scenario(test::small_world(300, 50));
  const GlobalMapConfig settings;
  RedisClient redis(cluster.address());
  ASSERT_TRUE(redis.is_cluster());
  std::set<std::size_t> nodes;
  for (const Submap& s : sc.submaps) {
    MapLogWriter(redis, s.name, settings).publish(s.scans);
    nodes.insert(redis.node_of(MapLogConfig{}.stream_key(s.name)));
  }
  EXPECT_GE(nodes.size(), 2u) << "the submaps' streams should spread over the masters";
  // The follower reads every stream (one XREAD per stream, pipelined per node).
  fleet::MapFollower follower(cluster.address(), fleet::MapFollowerConfig{.log = {.batch = 9}, .block_s = 0.05});
  GlobalMap through_cluster(follower.settings());
  GlobalMap direct(settings);
  MapFeeder(direct, sc.submaps).feed_until(1.0);
  std::size_t scans = 0;
  for (const Submap& s : sc.submaps) scans += s.scans.size();
  EXPECT_EQ(follower.catch_up(through_cluster), scans);
  test::expect_same_map_contents(direct, through_cluster);
  // What is published later arrives through the following thread's waits.
  std::shared_mutex mutex;
  follower.start(through_cluster, mutex);
  std::vector<LaserScan> more;
  for (int i = 0; i < 20; ++i) more.push_back(scan_at(i));
  MapLogWriter(redis, "annex", settings).publish(more);
  for (int i = 0; i < 500 && follower.stats().live_updates < more.size(); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  follower.stop();
  EXPECT_EQ(follower.stats().live_updates, more.size());
  EXPECT_EQ(through_cluster.stats().scans, scans + more.size());
}

TEST(FleetCluster, RedirectsAreFollowedWhileASubmapsSlotMigratesAndAfter) {
  LSHLOC_REQUIRE_REDIS_CLUSTER(cluster);
  RedisClient writer_client(cluster.address());
  RedisClient reader_client(cluster.address());
  const MapLogConfig config;
  const std::string key = config.stream_key("hall");
  ASSERT_NE(fleet::hash_slot(key), fleet::hash_slot(config.registry_key()));
  std::vector<LaserScan> scans;
  for (int i = 0; i < 30; ++i) scans.push_back(scan_at(i));
  MapLogWriter writer(writer_client, "hall", GlobalMapConfig{});
  MapLogReader reader(reader_client);
  writer.publish(std::span(scans).first(10));
  EXPECT_EQ(reader.poll().size(), 10u);
  // Move the stream's slot from its master to another, the way
  // redis-cli --cluster reshard does: both clients still hold the old table.
  const std::string slot = std::to_string(fleet::hash_slot(key));
  const std::vector<RedisAddress> masters = writer_client.nodes();
  ASSERT_EQ(masters.size(), 3u);
  const RedisAddress& from = masters[writer_client.node_of(key)];
  const RedisAddress& to = masters[(writer_client.node_of(key) + 1) % 3];
  RedisConnection src(from), dst(to);
  const std::string src_id = src.command({"CLUSTER", "MYID"}).text, dst_id = dst.command({"CLUSTER", "MYID"}).text;
  dst.command({"CLUSTER", "SETSLOT", slot, "IMPORTING", src_id});
  src.command({"CLUSTER", "SETSLOT", slot, "MIGRATING", dst_id});
  src.command({"MIGRATE", to.host, std::to_string(to.port), "", "0", "5000", "KEYS", key});
  // Mid-migration the old master answers ASK for the key that has gone.
  writer.publish(std::span(scans).subspan(10, 10));
  EXPECT_GE(writer_client.stats().asked, 1u);
  std::vector<fleet::MapUpdate> got = reader.poll();
  EXPECT_GE(reader_client.stats().asked, 1u);
  for (const RedisAddress& m : masters) RedisConnection(m).command({"CLUSTER", "SETSLOT", slot, "NODE", dst_id});
  // Now the slot has moved for good: MOVED, and both learn the new table.
  writer.publish(std::span(scans).subspan(20, 10));
  EXPECT_GE(writer_client.stats().moved, 1u);
  for (auto more = reader.poll(); !more.empty(); more = reader.poll()) got.insert(got.end(), more.begin(), more.end());
  EXPECT_GE(reader_client.stats().moved, 1u);
  ASSERT_EQ(got.size(), 20u);
  for (std::size_t i = 0; i < got.size(); ++i) {
    EXPECT_EQ(got[i].seq, 10 + i);
    EXPECT_EQ(got[i].scan.ranges, scans[10 + i].ranges);
  }
  EXPECT_EQ(reader.stats().duplicates, 0u);
  EXPECT_EQ(writer_client.node_of(key), reader_client.node_of(key));
  EXPECT_EQ(dst.command({"XLEN", key}).integer, 30);
}

// A localizer reads the map while the follower's thread writes what a mapper
// publishes meanwhile (ThreadSanitizer runs this: scripts/sanitize.sh --thread).
TEST(LiveFleet, AFollowerFeedsTheMapWhileALocalizerReadsIt) {
  LSHLOC_REQUIRE_REDIS(server);
  const Scenario sc = sim::synthetic_scenario(test::small_world());
  RedisClient redis(server.address());
  const GlobalMapConfig settings;
  std::vector<MapLogWriter> writers;
  for (const Submap& s : sc.submaps) writers.emplace_back(redis, s.name, settings);
  // Every building but the target's is mapped before the target starts.
  for (std::size_t i = 0; i < sc.submaps.size(); ++i)
    if (i != sc.target_submap) writers[i].publish(sc.submaps[i].scans);
  fleet::MapFollower follower(server.address(), fleet::MapFollowerConfig{.log = {}, .block_s = 0.05});
  GlobalMap map(follower.settings());
  follower.catch_up(map);
  std::shared_mutex mutex;
  follower.start(map, mutex);
  // The target's building is published while the target localizes.
  std::jthread mapper([&] {
    const std::span<const LaserScan> scans(sc.submaps[sc.target_submap].scans);
    for (std::size_t i = 0; i < scans.size(); i += 50) {
      writers[sc.target_submap].publish(scans.subspan(i, std::min<std::size_t>(50, scans.size() - i)));
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
  });
  const LocalizationRun run = localize_target(map, sc.target, LocalizerConfig{}, {}, {}, {}, &mutex);
  mapper.join();
  // Let the follower take the rest, then stop it.
  std::size_t total = 0;
  for (const Submap& s : sc.submaps) total += s.scans.size();
  for (int i = 0; i < 500; ++i) {
    {
      std::shared_lock lock(mutex);
      if (map.stats().scans == total) break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  follower.stop();
  EXPECT_EQ(map.stats().scans, total);
  EXPECT_GT(follower.stats().live_updates, 0u);
  EXPECT_EQ(follower.stats().duplicates, 0u);
  const std::optional<std::uint32_t> target = map.find_submap(sc.submaps[sc.target_submap].name);
  ASSERT_TRUE(target.has_value());
  const auto m = evaluate_localization(scan_estimates(run), sc.target.truth, *target);
  EXPECT_TRUE(m.success);
}

}  // namespace
}  // namespace lshloc
