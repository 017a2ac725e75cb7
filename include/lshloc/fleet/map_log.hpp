#pragma once
// The fleet's map log on Redis (docs/fleet.md): each submap's mapper updates
// are one Redis Stream, and a registry hash holds the map's settings and its
// submaps. Mapper robots append (MapLogWriter); localizers follow every
// stream, history first, then what arrives (MapLogReader), and feed their own
// in-memory GlobalMap with it.
// Poses [m, rad], times [s].
// Thread safety: writers and readers are one thread's objects, each over its
// own RedisClient; any number of them, in any processes, share a server or a
// Redis Cluster.
#include <cstdint>
#include <map>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "lshloc/fleet/redis_client.hpp"
#include "lshloc/geometry/laser_scan.hpp"
#include "lshloc/localization/global_map.hpp"

namespace lshloc::fleet {

/// Key names: "<prefix>:registry" (a hash) and "<prefix>:{<submap>}:log" (a
/// stream per submap; the braces are Redis Cluster's hash tag, so each
/// submap's stream lands on one node and submaps spread over the nodes).
struct MapLogConfig {
  std::string prefix = "lshloc";
  std::size_t batch = 256;        ///< updates per pipelined round trip (writer) or per stream read (reader)
  double cluster_poll_s = 0.005;  ///< [s] between a reader's polls while it waits on a cluster

  std::string registry_key() const { return prefix + ":registry"; }
  std::string stream_key(std::string_view submap) const;
};

/// One mapper update: a scan of `submap` (scan.pose its laser pose in the
/// submap's frame) with the submap's sequence number (0, 1, ...).
struct MapUpdate {
  std::string submap;
  std::uint64_t seq = 0;
  LaserScan scan;
};

/// A stream entry no reconnect can mend: a damaged record, or a gap in a
/// submap's sequence numbers. Its message names the stream and the entry id.
class MapLogRecordError : public Error {
 public:
  using Error::Error;
};

/// A stream entry's record: version (u8, 1), sequence number (u64), the scan
/// update (io/scan_record.hpp) and a CRC-32 of everything before it.
std::string encode_update(std::uint64_t seq, const LaserScan& scan);
/// Decodes a record into `out` (its submap is left as it is); throws
/// lshloc::Error naming `where` on a bad checksum, version or structure.
void decode_update(std::string_view record, const std::string& where, MapUpdate& out);

/// Registers the map's settings (the first mapper's; other settings are
/// refused with lshloc::Error saying which differ) and `submaps` in this
/// order, in one atomic step: mappers that register the same list at once
/// agree on its order. Names: 1..200 characters without braces.
void register_map(RedisClient& redis, const GlobalMapConfig& settings, std::span<const std::string> submaps,
                  const MapLogConfig& config = {});

/// A mapper robot's end of one submap's stream.
class MapLogWriter {
 public:
  /// Registers the submap and the map's settings (register_map()). Sequence
  /// numbers continue after the stream's last entry, so a restarted mapper
  /// resumes its submap.
  MapLogWriter(RedisClient& redis, std::string submap, const GlobalMapConfig& settings, MapLogConfig config = {});

  /// Appends the scans (scan.pose: laser pose in the submap's frame) in
  /// pipelined batches; when it returns, Redis has acknowledged every one.
  void publish(std::span<const LaserScan> scans);
  /// Reads the stream's last sequence number again (after a reconnect: a
  /// batch whose replies were lost may or may not be in the stream), so
  /// that publishing goes on without a duplicate or a gap.
  void resync();
  std::uint64_t next_seq() const { return next_seq_; }
  const std::string& submap() const { return submap_; }

 private:
  RedisClient& redis_;
  std::string submap_;
  MapLogConfig config_;
  std::string key_;
  std::uint64_t next_seq_ = 0;
};

/// Where a reader stands in one submap's stream: the last entry read and the
/// next sequence number it expects. A snapshot of a map keeps them, so that
/// a localizer started from it replays only the rest.
struct StreamPosition {
  std::string submap;
  std::string last_id = "0-0";
  std::uint64_t next_seq = 0;
};
/// As JSON: [{"submap": ..., "last_id": ..., "next_seq": ...}, ...].
nlohmann::json positions_to_json(const std::vector<StreamPosition>& positions);
/// Throws lshloc::Error naming `source` on anything else.
std::vector<StreamPosition> positions_from_json(const nlohmann::json& j, const std::string& source);

/// What a reader has seen.
struct MapLogReaderStats {
  std::size_t updates = 0;     ///< updates returned (each once)
  std::size_t duplicates = 0;  ///< entries skipped because their sequence number was already seen
  std::size_t submaps = 0;     ///< submaps known from the registry
  /// Why the last poll stopped early, at a gap or an entry it cannot decode
  /// (empty: it did not); the poll after it meets that entry again.
  std::string stopped;
};

/// A localizer's follower of every submap's stream.
class MapLogReader {
 public:
  explicit MapLogReader(RedisClient& redis, MapLogConfig config = {});

  /// The map's settings from the registry; throws lshloc::Error when no
  /// mapper has registered any (an empty or wrong server / prefix).
  GlobalMapConfig settings();

  /// The updates that arrived since the last poll, each stream's in order,
  /// interleaved round robin: the first new update of each submap (in
  /// registration order), then the second, ... (the order a map built from
  /// files is fed in). When there are none, waits up to `block_s` for new
  /// ones (0: no wait): one XREAD BLOCK on one server; on a cluster, whose
  /// multi-stream reads cannot span slots, one XREAD per stream, pipelined
  /// per node, repeated every `cluster_poll_s`. A gap in a stream's sequence
  /// numbers throws lshloc::Error naming the submap and the numbers (an
  /// update was lost); an entry whose number was seen is skipped as a
  /// duplicate (a read of duplicates only reads on: an empty result means
  /// nothing new arrived).
  std::vector<MapUpdate> poll(double block_s = 0.0);

  /// Reads again from the server after a reconnect: positions are kept, so
  /// nothing is read twice nor missed.
  void reconnect() { redis_.reconnect(); }

  /// Submaps in registration order.
  const std::vector<std::string>& submaps() const { return order_; }
  /// Every stream's position, submaps in registration order.
  std::vector<StreamPosition> positions() const;
  /// Continues from `positions` (a snapshot's), before the first poll: those
  /// submaps first, in that order, each stream after its last entry read.
  void resume(const std::vector<StreamPosition>& positions);
  const MapLogReaderStats& stats() const { return stats_; }

 private:
  void refresh_registry();
  /// One read of poll(); `duplicates_only` when it read entries but all were duplicates.
  std::vector<MapUpdate> read_once(double block_s, bool& duplicates_only);
  struct Position {
    std::string last_id = "0-0";  ///< the last stream entry read
    std::uint64_t next_seq = 0;
  };
  RedisClient& redis_;
  MapLogConfig config_;
  std::vector<std::string> order_;
  std::map<std::string, Position> positions_;
  std::map<std::string, std::string> submap_of_key_;  ///< stream key -> submap name
  MapLogReaderStats stats_;
};

/// What apply_updates() did with its updates.
struct AppliedUpdates {
  std::size_t added = 0;
  /// Scans the map refused (GlobalMap::add_scan threw: e.g. a pose beyond the
  /// grids' limits). Each left the map as it was, and every follower of the
  /// log refuses the same ones.
  std::size_t refused = 0;
  std::string last_refusal;  ///< the submap, sequence number and reason of the last one
};

/// Applies updates to `map`: first every submap of `submaps` (registration
/// order, MapLogReader::submaps()) not in it yet is opened, so that submap ids
/// follow registration whether or not a submap has scans yet; then each scan
/// is added at its pose. A scan the map refuses is counted and skipped: the
/// updates after it still apply.
AppliedUpdates apply_updates(GlobalMap& map, std::span<const std::string> submaps, std::span<const MapUpdate> updates);

}  // namespace lshloc::fleet
