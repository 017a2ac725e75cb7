#pragma once
// The map store (docs/map-format.md): a global map saved as one file, a
// checksummed snapshot of its structures followed by an append-only journal
// of mapper scans. Build once, load in a bulk read, append without a
// rebuild, and lose no acknowledged scan when the process dies.
// Poses [m, rad]; sizes [bytes].
// Thread safety: load_map, verify_map and save_map share no state; a
// MapAppender is one writer's object (not thread-safe), and holds an
// exclusive lock on its file so that a second writer, in any process, is
// refused. Readers may load a map while one writer appends: they see the
// scans acknowledged so far, and a record being written reads as a torn tail.
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "lshloc/localization/global_map.hpp"

namespace lshloc::io {

/// The file format version this lshloc writes; it reads 1 (whose journal
/// records are not tied to their snapshot) and 2 (no scan fingerprints) too:
/// docs/map-format.md.
inline constexpr std::uint32_t kMapFormatVersion = 3;

/// What a map file holds, as far as reading it found.
struct MapFileInfo {
  std::uint32_t format_version = 0;
  std::uint64_t file_bytes = 0;
  std::uint64_t snapshot_bytes = 0;  ///< header and sections; the journal follows
  std::uint64_t journal_bytes = 0;   ///< complete journal records
  std::size_t journal_submaps = 0;   ///< submaps the journal opened
  std::size_t journal_scans = 0;     ///< scans the journal added
  std::uint64_t torn_bytes = 0;      ///< an incomplete last record, dropped (0: none)
  struct Section {
    std::string name;
    std::uint64_t offset = 0;  ///< of its payload
    std::uint64_t bytes = 0;
  };
  std::vector<Section> sections;
  nlohmann::json meta;  ///< free-form: who built the map and from what
};

/// A loaded map: its settings, its structures, and what the file held.
struct LoadedMap {
  std::unique_ptr<GlobalMap> map;
  MapFileInfo info;
  /// Problems that lost nothing acknowledged (a torn last journal record),
  /// each naming the file and the byte offset.
  std::vector<std::string> warnings;
};

/// Writes `map` as a snapshot with an empty journal: to a temporary file in
/// the same directory, fsync'ed, then renamed over `path` (and the directory
/// fsync'ed), so `path` holds either its old content or the whole new map.
/// `meta` (a JSON object) is kept as the file's free-form description. A map
/// another process is appending to (its lock held) is refused, not replaced.
void save_map(const std::string& path, const GlobalMap& map, const nlohmann::json& meta = nlohmann::json::object());

/// Reads a map file: checks every checksum, restores the snapshot in bulk
/// and replays the journal. A torn last journal record is dropped with a
/// warning; anything else wrong (truncated snapshot, a changed byte, a wrong
/// magic number, a newer format version, settings this lshloc cannot use,
/// an empty file) throws lshloc::Error naming the file, the section or
/// record, and what was expected.
LoadedMap load_map(const std::string& path);

/// load_map() of a map file's bytes already in memory (e.g. received over
/// the network); `source` names them in errors.
LoadedMap load_map_bytes(std::span<const std::uint8_t> bytes, const std::string& source);

/// Whether the file starts with the map magic number (false when it cannot
/// be read or is shorter).
bool looks_like_map_file(const std::string& path);

/// How a MapAppender makes appends durable.
struct MapAppenderConfig {
  /// Scans per fsync: an append is acknowledged once its record and every
  /// record before it are written and fsync'ed; 1 syncs every scan, more
  /// batches them (higher throughput; a crash loses at most the scans of the
  /// unfinished batch, none of them acknowledged).
  std::size_t sync_every = 1;
  void validate() const;
};

/// Appends mapper updates to a map file's journal; nothing is rebuilt.
/// Opening loads the map (snapshot and journal), cuts off a torn last record
/// (with a warning) and takes an exclusive lock on the file. Each append is
/// applied to the in-memory map and written to the journal; durability as
/// MapAppenderConfig says. Not thread-safe.
class MapAppender {
 public:
  explicit MapAppender(const std::string& path, MapAppenderConfig config = {});
  ~MapAppender();  ///< syncs what is pending (errors are swallowed: call sync() to see them)
  MapAppender(const MapAppender&) = delete;
  MapAppender& operator=(const MapAppender&) = delete;

  const GlobalMap& map() const { return *map_; }
  const std::vector<std::string>& warnings() const { return warnings_; }
  /// What the file held when it was opened.
  const MapFileInfo& opened() const { return opened_; }

  /// Opens a new submap (journaled with the next scan's batch) and returns its id.
  std::uint32_t add_submap(const std::string& name);
  /// Adds one mapper scan to `submap` at `laser_pose` (its frame's pose);
  /// returns the features it added. Syncs when the batch is full. A scan the
  /// map refuses (lshloc::Error) is neither in the map nor journaled, and the
  /// next scans append as usual.
  std::size_t add_scan(std::uint32_t submap, const LaserScan& scan, const Pose2& laser_pose);
  /// Writes and fsyncs every pending record; afterwards every scan added so
  /// far is acknowledged. A failed write (a full disk) may be retried: the
  /// next sync() first cuts off what it left behind the journal. After a
  /// failed fsync the appender refuses to sync again (the kernel may have
  /// dropped the pages): reopen the map, which keeps what was acknowledged.
  void sync();
  /// Scans in the map that are durable (snapshot plus synced journal).
  std::size_t acknowledged_scans() const { return acknowledged_scans_; }
  /// Folds the journal into a new snapshot (atomically, as save_map does).
  void compact(const nlohmann::json& meta);

 private:
  void open_file();

  std::string path_;
  MapAppenderConfig config_;
  std::unique_ptr<GlobalMap> map_;
  MapFileInfo opened_;
  std::vector<std::string> warnings_;
  int fd_ = -1;
  std::vector<std::uint8_t> pending_;  ///< encoded records not yet written
  std::size_t pending_scans_ = 0;
  std::size_t acknowledged_scans_ = 0;
  std::uint64_t journal_end_ = 0;  ///< the file's end after the last good sync (or open/compact)
  std::uint32_t journal_tie_ = 0;  ///< the snapshot's tie its records' checksums start from (0: version 1)
  bool tail_dirty_ = false;        ///< a write failed part-way: bytes may lie beyond journal_end_
  bool sync_failed_ = false;       ///< an fdatasync failed
  bool broken_ = false;            ///< an add_scan() failed half-way in memory
};

}  // namespace lshloc::io
