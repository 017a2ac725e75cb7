// The map store: snapshots restore maps bit for bit, journals replay to the
// same map, durable appends survive, and every damaged file is refused with
// an error that names the file and the section.
#include "lshloc/io/map_store.hpp"

#include <gtest/gtest.h>
#include <sys/resource.h>
#include <unistd.h>

#include <zlib.h>

#include <csignal>
#include <filesystem>
#include <fstream>
#include <random>

#include "lshloc/common/error.hpp"
#include "lshloc/eval/dataset_catalog.hpp"
#include "lshloc/eval/scenario_runner.hpp"
#include "lshloc/io/config_json.hpp"
#include "lshloc/localization/localizer.hpp"
#include "lshloc/sim/synthetic_scenario.hpp"
#include "test_support.hpp"

namespace lshloc {
namespace {

const Scenario& world() {
  static const Scenario sc = sim::synthetic_scenario(test::small_world(600, 120));
  return sc;
}

/// Feeds scans [from, to) of every submap, one of each in turn.
void feed(GlobalMap& map, const Scenario& sc, std::size_t from, std::size_t to) {
  for (std::size_t i = from; i < to; ++i)
    for (std::uint32_t s = 0; s < sc.submaps.size(); ++s)
      if (i < sc.submaps[s].scans.size()) map.add_scan(s, sc.submaps[s].scans[i], sc.submaps[s].scans[i].pose);
}

std::unique_ptr<GlobalMap> map_of_first(std::size_t scans) {
  auto map = std::make_unique<GlobalMap>();
  for (const Submap& s : world().submaps) map->add_submap(s.name);
  feed(*map, world(), 0, scans);
  return map;
}

std::vector<MapSectionView> views(const std::vector<MapSection>& sections) {
  std::vector<MapSectionView> out;
  for (const MapSection& s : sections) out.push_back({s.name, s.bytes});
  return out;
}

std::vector<LocalizationEstimate> localize(const GlobalMap& map) {
  return localize_target(map, world().target, LocalizerConfig{}).estimates;
}

void expect_same_estimates(const std::vector<LocalizationEstimate>& a, const std::vector<LocalizationEstimate>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].has_estimate, b[i].has_estimate) << "scan " << i;
    EXPECT_EQ(a[i].localized, b[i].localized) << "scan " << i;
    EXPECT_EQ(a[i].submap, b[i].submap) << "scan " << i;
    EXPECT_EQ(a[i].pose.x, b[i].pose.x) << "scan " << i;
    EXPECT_EQ(a[i].pose.y, b[i].pose.y) << "scan " << i;
    EXPECT_EQ(a[i].pose.theta, b[i].pose.theta) << "scan " << i;
    EXPECT_EQ(a[i].mean_score, b[i].mean_score) << "scan " << i;
  }
}

std::vector<std::uint8_t> read_bytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(f), {}};
}

void write_bytes(const std::string& path, const std::vector<std::uint8_t>& bytes) {
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  f.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
}

std::string load_error(const std::string& path) {
  try {
    io::load_map(path);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(MapSnapshot, RestoresTheMapBitForBit) {
  const auto map = map_of_first(600);
  const auto sections = map->snapshot();
  const auto restored = GlobalMap::from_snapshot(map->config(), views(sections), "test");
  const auto again = restored->snapshot();
  ASSERT_EQ(sections.size(), again.size());
  for (std::size_t i = 0; i < sections.size(); ++i)
    EXPECT_TRUE(sections[i].bytes == again[i].bytes) << sections[i].name;
  EXPECT_EQ(restored->stats().features, map->stats().features);
  EXPECT_EQ(restored->stats().scans, map->stats().scans);
  EXPECT_GT(restored->stats().features, 1000u);
  expect_same_estimates(localize(*map), localize(*restored));
}

TEST(MapSnapshot, KeepsTheFingerprintsOfItsScansAndReadsAFileWithout) {
  const auto map = map_of_first(300);
  const Submap& first = world().submaps[0];
  const std::span<const LaserScan> mapped(first.scans.data(), 300), later(first.scans.data() + 300, 200);
  EXPECT_EQ(map->scans_held(mapped), 300u);
  EXPECT_EQ(map->scans_held(later), 0u);
  EXPECT_EQ(map->scans_held(world().target.scans), 0u) << "the target's own tour is no mapper's";

  const auto sections = map->snapshot();
  const auto restored = GlobalMap::from_snapshot(map->config(), views(sections), "test");
  EXPECT_TRUE(restored->knows_every_scan());
  EXPECT_EQ(restored->scans_held(mapped), 300u);
  EXPECT_EQ(restored->scans_held(later), 0u);

  // A file written before maps kept fingerprints (format version 2): read, and only scans added since are known.
  std::vector<MapSectionView> older;
  for (const MapSectionView& v : views(sections))
    if (v.name != "scan_prints") older.push_back(v);
  const auto old = GlobalMap::from_snapshot(map->config(), older, "test");
  EXPECT_FALSE(old->knows_every_scan());
  EXPECT_EQ(old->scans_held(mapped), 0u);
  expect_same_estimates(localize(*map), localize(*old));
  old->add_scan(0, later[0], later[0].pose);
  EXPECT_EQ(old->scans_held(later.first(1)), 1u);
}

TEST(MapSnapshot, ARestoredMapGrowsExactlyAsTheOriginal) {
  // Half the scans, snapshot, restore; the rest fed to both: same contents,
  // and the same as a map fed everything at once.
  auto original = map_of_first(300);
  const auto sections = original->snapshot();
  auto restored = GlobalMap::from_snapshot(original->config(), views(sections), "test");
  feed(*original, world(), 300, 600);
  feed(*restored, world(), 300, 600);
  test::expect_same_map_contents(*original, *restored);
  test::expect_same_map_contents(*map_of_first(600), *restored);
}

TEST(MapSnapshot, RejectsInconsistentSections) {
  const auto map = map_of_first(50);
  auto sections = map->snapshot();
  auto bad = sections;
  bad[1].bytes.pop_back();  // locations one byte short
  EXPECT_THROW(GlobalMap::from_snapshot(map->config(), views(bad), "m"), Error);
  bad = sections;
  bad.erase(bad.begin() + 2);
  try {
    GlobalMap::from_snapshot(map->config(), views(bad), "m");
    ADD_FAILURE() << "a missing section was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("section database is missing"), std::string::npos) << e.what();
  }
  // Every prefix of every section fails cleanly (no crash, no silent map).
  for (std::size_t s = 0; s < sections.size(); ++s) {
    for (std::size_t cut : {std::size_t{0}, sections[s].bytes.size() / 3, sections[s].bytes.size() - 1}) {
      bad = sections;
      bad[s].bytes.resize(cut);
      EXPECT_THROW(GlobalMap::from_snapshot(map->config(), views(bad), "m"), Error) << sections[s].name << " " << cut;
    }
  }
}

TEST(MapStore, SaveAndLoadGiveTheSameMapAndEstimates) {
  const auto map = map_of_first(600);
  const std::string path = test::temp_path(".map");
  io::save_map(path, *map, {{"made_by", "test"}});
  const io::LoadedMap loaded = io::load_map(path);
  EXPECT_TRUE(loaded.warnings.empty());
  EXPECT_EQ(loaded.info.format_version, io::kMapFormatVersion);
  EXPECT_EQ(loaded.info.meta.at("made_by"), "test");
  EXPECT_EQ(loaded.info.journal_scans, 0u);
  test::expect_same_map_contents(*map, *loaded.map);
  expect_same_estimates(localize(*map), localize(*loaded.map));
  // Saving the loaded map writes the same bytes.
  const std::string again = test::temp_path(".map");
  io::save_map(again, *loaded.map, {{"made_by", "test"}});
  EXPECT_TRUE(read_bytes(path) == read_bytes(again));
}

TEST(MapStore, AppendedScansAreReplayedToTheSameMap) {
  const std::string path = test::temp_path(".map");
  io::save_map(path, *map_of_first(200));
  {
    io::MapAppender appender(path, {.sync_every = 7});
    for (std::size_t i = 200; i < 600; ++i)
      for (std::uint32_t s = 0; s < world().submaps.size(); ++s)
        if (i < world().submaps[s].scans.size())
          appender.add_scan(s, world().submaps[s].scans[i], world().submaps[s].scans[i].pose);
    const std::uint32_t extra = appender.add_submap("extra building");
    for (std::size_t i = 0; i < 50; ++i)
      appender.add_scan(extra, world().submaps[0].scans[i], world().submaps[0].scans[i].pose);
    appender.sync();
    EXPECT_EQ(appender.acknowledged_scans(), appender.map().stats().scans);
  }
  const io::LoadedMap loaded = io::load_map(path);
  EXPECT_EQ(loaded.info.journal_scans, map_of_first(600)->stats().scans - map_of_first(200)->stats().scans + 50);
  EXPECT_EQ(loaded.info.journal_submaps, 1u);
  auto expected = map_of_first(600);
  const std::uint32_t extra = expected->add_submap("extra building");
  for (std::size_t i = 0; i < 50; ++i)
    expected->add_scan(extra, world().submaps[0].scans[i], world().submaps[0].scans[i].pose);
  test::expect_same_map_contents(*expected, *loaded.map);

  // Compaction folds the journal into the snapshot: same map, no journal.
  {
    io::MapAppender appender(path);
    appender.compact({{"made_by", "compact"}});
  }
  const io::LoadedMap compacted = io::load_map(path);
  EXPECT_EQ(compacted.info.journal_bytes, 0u);
  test::expect_same_map_contents(*expected, *compacted.map);
}

// A scan the map refuses whole (beyond the grids' limits) leaves map and
// journal as they were: the scans after it append, and the reload equals a
// map that never saw it.
TEST(MapStore, AScanTheMapRefusesIsNotJournaledAndAppendingGoesOn) {
  const std::string path = test::temp_path(".map");
  io::save_map(path, *map_of_first(100));
  const std::unique_ptr<GlobalMap> expected = io::load_map(path).map;
  const GlobalMapConfig& config = expected->config();
  const double edge = 65536.0 * std::min(config.occupancy.cell_size, config.free_space.cell_size);
  {
    io::MapAppender appender(path, {.sync_every = 3});
    for (std::size_t i = 100; i < 110; ++i) {
      const LaserScan& scan = world().submaps[0].scans[i];
      if (i == 104) {
        EXPECT_THROW(appender.add_scan(0, scan, Pose2(edge + 50.0, 0.0, 0.0)), Error);
      }
      appender.add_scan(0, scan, scan.pose);
      expected->add_scan(0, scan, scan.pose);
    }
    appender.sync();
    EXPECT_EQ(appender.acknowledged_scans(), expected->stats().scans);
  }
  const io::LoadedMap loaded = io::load_map(path);
  EXPECT_EQ(loaded.info.journal_scans, 10u);
  test::expect_same_map_contents(*expected, *loaded.map);
  {
    io::MapAppender appender(path);
    appender.compact({{"made_by", "compact"}});
  }
  test::expect_same_map_contents(*expected, *io::load_map(path).map);
}

TEST(MapStore, ATornLastRecordIsDroppedWithAWarningAndCutOffOnAppend) {
  const std::string path = test::temp_path(".map");
  io::save_map(path, *map_of_first(100));
  {
    io::MapAppender appender(path);
    for (std::size_t i = 100; i < 110; ++i)
      appender.add_scan(0, world().submaps[0].scans[i], world().submaps[0].scans[i].pose);
  }
  auto bytes = read_bytes(path);
  const std::size_t full = bytes.size();
  bytes.resize(full - 100);  // the last record loses its end, as a crash mid-write leaves it
  write_bytes(path, bytes);
  const io::LoadedMap loaded = io::load_map(path);
  ASSERT_EQ(loaded.warnings.size(), 1u);
  EXPECT_NE(loaded.warnings[0].find("torn"), std::string::npos) << loaded.warnings[0];
  EXPECT_NE(loaded.warnings[0].find("at byte "), std::string::npos) << loaded.warnings[0];
  EXPECT_EQ(loaded.info.journal_scans, 9u);
  {
    io::MapAppender appender(path);  // cuts the torn record off, then appends after the last good one
    EXPECT_EQ(appender.warnings().size(), 1u);
    appender.add_scan(0, world().submaps[0].scans[109], world().submaps[0].scans[109].pose);
  }
  const io::LoadedMap repaired = io::load_map(path);
  EXPECT_TRUE(repaired.warnings.empty());
  EXPECT_EQ(repaired.info.journal_scans, 10u);
  auto expected = map_of_first(100);
  for (std::size_t i = 100; i < 110; ++i)
    expected->add_scan(0, world().submaps[0].scans[i], world().submaps[0].scans[i].pose);
  test::expect_same_map_contents(*expected, *repaired.map);
}

TEST(MapStore, ASyncThatFailedPartWayIsRetriedWithoutDamagingTheJournal) {
  const std::string path = test::temp_path(".map");
  io::save_map(path, *map_of_first(50));
  const auto scan = [](std::size_t i) -> const LaserScan& { return world().submaps[0].scans[i]; };
  {
    io::MapAppender appender(path, {.sync_every = 100});
    appender.add_scan(0, scan(50), scan(50).pose);
    appender.sync();
    for (std::size_t i = 51; i < 54; ++i) appender.add_scan(0, scan(i), scan(i).pose);
    // A full disk: writes beyond 40 more bytes fail (EFBIG, as ENOSPC would).
    const auto size = std::filesystem::file_size(path);
    rlimit old{};
    ASSERT_EQ(::getrlimit(RLIMIT_FSIZE, &old), 0);
    const auto old_handler = std::signal(SIGXFSZ, SIG_IGN);
    rlimit small = old;
    small.rlim_cur = size + 40;
    ASSERT_EQ(::setrlimit(RLIMIT_FSIZE, &small), 0);
    EXPECT_THROW(appender.sync(), Error);
    ASSERT_EQ(::setrlimit(RLIMIT_FSIZE, &old), 0);
    std::signal(SIGXFSZ, old_handler);
    EXPECT_EQ(std::filesystem::file_size(path), size + 40);  // part of a record was written
    EXPECT_EQ(appender.acknowledged_scans(), map_of_first(50)->stats().scans + 1);
    appender.sync();  // space again: the part is cut off and the records written whole
    EXPECT_EQ(appender.acknowledged_scans(), map_of_first(50)->stats().scans + 4);
  }
  const io::LoadedMap loaded = io::load_map(path);
  EXPECT_TRUE(loaded.warnings.empty());
  EXPECT_EQ(loaded.info.journal_scans, 4u);
  auto expected = map_of_first(50);
  for (std::size_t i = 50; i < 54; ++i) expected->add_scan(0, scan(i), scan(i).pose);
  test::expect_same_map_contents(*expected, *loaded.map);
}

TEST(MapStore, ASecondWriterIsRefused) {
  const std::string path = test::temp_path(".map");
  io::save_map(path, *map_of_first(10));
  io::MapAppender first(path);
  try {
    io::MapAppender second(path);
    ADD_FAILURE() << "two writers at once";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("another process is appending"), std::string::npos) << e.what();
  }
}

TEST(MapStore, AMapUnderAppendIsNotReplacedBySave) {
  const std::string path = test::temp_path(".map");
  io::save_map(path, *map_of_first(10));
  {
    io::MapAppender appender(path);
    appender.add_scan(0, world().submaps[0].scans[10], world().submaps[0].scans[10].pose);
    try {
      io::save_map(path, *map_of_first(5));
      ADD_FAILURE() << "a map under append was replaced";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("another process is appending to this map"), std::string::npos) << e.what();
    }
  }
  EXPECT_EQ(io::load_map(path).info.journal_scans, 1u);  // the acknowledged scan is there
  io::save_map(path, *map_of_first(5));                  // no appender: replaced
  EXPECT_EQ(io::load_map(path).info.journal_scans, 0u);
}

class DamagedMap : public ::testing::Test {
 protected:
  void SetUp() override {
    path_ = test::temp_path(".map");
    io::save_map(path_, *map_of_first(60));
    {
      io::MapAppender appender(path_);
      appender.add_scan(0, world().submaps[0].scans[60], world().submaps[0].scans[60].pose);
    }
    good_ = read_bytes(path_);
    info_ = io::load_map(path_).info;
  }
  /// The error loading `bytes` gives (empty: it loaded).
  std::string error_of(const std::vector<std::uint8_t>& bytes) {
    const std::string path = test::temp_path(".map");
    write_bytes(path, bytes);
    return load_error(path);
  }
  std::string path_;
  std::vector<std::uint8_t> good_;
  io::MapFileInfo info_;
};

TEST_F(DamagedMap, EveryFlippedByteOfEverySectionIsCaughtAndNamed) {
  ASSERT_EQ(info_.sections.size(), 2 + GlobalMap::snapshot_sections().size());
  for (const auto& s : info_.sections) {
    for (const std::uint64_t at : {s.offset, s.offset + s.bytes / 2, s.offset + s.bytes - 1}) {
      auto bytes = good_;
      bytes[at] ^= 0x10;
      const std::string e = error_of(bytes);
      EXPECT_NE(e.find("section " + s.name), std::string::npos) << "byte " << at << ": " << e;
      EXPECT_NE(e.find("checksum mismatch"), std::string::npos) << e;
    }
  }
  // Header, section headers and the journal record too.
  for (const std::uint64_t at :
       {std::uint64_t{30}, std::uint64_t{64 + 25}, info_.snapshot_bytes + 5, info_.file_bytes - 3}) {
    auto bytes = good_;
    bytes[at] ^= 0x01;
    const std::string e = error_of(bytes);
    EXPECT_NE(e.find("checksum mismatch"), std::string::npos) << "byte " << at << ": " << e;
  }
}

TEST_F(DamagedMap, TruncatedEmptyWrongMagicAndNewerVersionAreRefused) {
  for (const std::size_t size :
       {std::size_t{10}, std::size_t{63}, std::size_t{64}, std::size_t{200},
        static_cast<std::size_t>(info_.snapshot_bytes / 2), static_cast<std::size_t>(info_.snapshot_bytes - 1)}) {
    auto bytes = good_;
    bytes.resize(size);
    const std::string e = error_of(bytes);
    EXPECT_NE(e.find("truncated"), std::string::npos) << size << ": " << e;
    EXPECT_NE(e.find(".map: "), std::string::npos) << "names the file: " << e;
  }
  EXPECT_NE(error_of({}).find("empty file"), std::string::npos);
  auto bytes = good_;
  bytes[0] = 'X';
  EXPECT_NE(error_of(bytes).find("not an lshloc map"), std::string::npos);
  bytes = good_;
  const auto newer = static_cast<std::uint8_t>(io::kMapFormatVersion + 1);
  const std::string says = "format version " + std::to_string(newer) + " is newer";
  bytes[8] = newer;  // the header's checksum not resealed: newer, or damaged
  EXPECT_NE(error_of(bytes).find(says), std::string::npos) << error_of(bytes);
  EXPECT_NE(error_of(bytes).find("or the header is damaged"), std::string::npos) << error_of(bytes);
  // Resealed (a writer of a newer version keeping this header's layout): newer only.
  const std::uint32_t crc = static_cast<std::uint32_t>(crc32_z(crc32_z(0L, Z_NULL, 0), bytes.data(), 60));
  for (int i = 0; i < 4; ++i) bytes[60 + i] = static_cast<std::uint8_t>(crc >> (8 * i));
  EXPECT_NE(error_of(bytes).find(says + " than this lshloc reads (" + std::to_string(io::kMapFormatVersion) +
                                 "); use a newer lshloc"),
            std::string::npos)
      << error_of(bytes);
}

void put_u32(std::vector<std::uint8_t>& bytes, std::uint64_t at, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) bytes[at + static_cast<std::uint64_t>(i)] = static_cast<std::uint8_t>(v >> (8 * i));
}

std::uint32_t plain_crc(const std::uint8_t* data, std::size_t n) {
  return static_cast<std::uint32_t>(crc32_z(crc32_z(0L, Z_NULL, 0), data, n));
}

TEST_F(DamagedMap, AJournalSplicedFromAnotherMapIsRefused) {
  // Another map's snapshot (60 scans, another meta) with this map's journal behind it: every check but the tie
  // passes (the record is intact and would replay).
  const std::string other = test::temp_path(".map");
  io::save_map(other, *map_of_first(60), {{"made_by", "another run"}});
  auto spliced = read_bytes(other);
  const auto snapshot_end = static_cast<std::ptrdiff_t>(info_.snapshot_bytes);
  spliced.insert(spliced.end(), good_.begin() + snapshot_end, good_.end());
  const std::string e = error_of(spliced);
  EXPECT_NE(e.find("journal record 1 at byte"), std::string::npos) << "[" << e << "]";
  EXPECT_NE(e.find("written after another snapshot"), std::string::npos) << e;
  EXPECT_TRUE(error_of(good_).empty()) << error_of(good_);
}

TEST_F(DamagedMap, AVersionOneFileLoadsAppendsAndCompactsIntoVersionTwo) {
  // The same map as format version 1 wrote it: version 1 in a resealed header, the journal record's payload
  // checksum a plain CRC-32.
  auto v1 = good_;
  put_u32(v1, 8, 1);
  put_u32(v1, 60, plain_crc(v1.data(), 60));
  const std::uint64_t record = info_.snapshot_bytes;
  const std::uint32_t length =
      static_cast<std::uint32_t>(v1[record + 4]) | (static_cast<std::uint32_t>(v1[record + 5]) << 8) |
      (static_cast<std::uint32_t>(v1[record + 6]) << 16) | (static_cast<std::uint32_t>(v1[record + 7]) << 24);
  put_u32(v1, record + 8, plain_crc(v1.data() + record + 16, length));
  put_u32(v1, record + 12, plain_crc(v1.data() + record, 12));
  const std::string path = test::temp_path(".map");
  write_bytes(path, v1);
  const io::LoadedMap loaded = io::load_map(path);
  EXPECT_EQ(loaded.info.format_version, 1u);
  test::expect_same_map_contents(*io::load_map(path_).map, *loaded.map);
  {
    io::MapAppender appender(path);  // appends untied records, as version 1 reads them
    appender.add_scan(0, world().submaps[0].scans[61], world().submaps[0].scans[61].pose);
  }
  const io::LoadedMap appended = io::load_map(path);
  EXPECT_EQ(appended.info.format_version, 1u);
  EXPECT_EQ(appended.info.journal_scans, 2u);
  {
    io::MapAppender appender(path);
    appender.compact({{"made_by", "compact"}});
    appender.add_scan(0, world().submaps[0].scans[62], world().submaps[0].scans[62].pose);  // tied to the new one
  }
  const io::LoadedMap compacted = io::load_map(path);
  EXPECT_EQ(compacted.info.format_version, io::kMapFormatVersion);
  EXPECT_EQ(compacted.info.journal_scans, 1u);
  auto expected = map_of_first(60);
  for (const std::size_t i : {60, 61, 62})
    expected->add_scan(0, world().submaps[0].scans[i], world().submaps[0].scans[i].pose);
  test::expect_same_map_contents(*expected, *compacted.map);
}

/// Rewrites the checksums of the section whose payload starts at `offset`
/// (header layout: docs/map-format.md) so that a changed payload passes them.
void reseal_section(std::vector<std::uint8_t>& bytes, std::uint64_t offset, std::uint64_t length) {
  const auto put_u32 = [&](std::uint64_t at, std::uint32_t v) {
    for (int i = 0; i < 4; ++i) bytes[at + i] = static_cast<std::uint8_t>(v >> (8 * i));
  };
  const auto crc = [&](std::uint64_t from, std::uint64_t n) {
    return static_cast<std::uint32_t>(crc32_z(crc32_z(0L, Z_NULL, 0), bytes.data() + from, n));
  };
  put_u32(offset - 8, crc(offset, length));
  put_u32(offset - 4, crc(offset - 36, 32));
}

TEST_F(DamagedMap, ContentDamagedBehindValidChecksumsIsRefusedNeverACrash) {
  // What a fuzzer does to the decoders: changed bytes the checksums do not
  // catch. Every outcome must be a clean lshloc::Error or a map that loads.
  std::mt19937_64 rng(2026);
  std::size_t refused = 0, loaded = 0;
  for (const auto& s : info_.sections) {
    if (s.bytes == 0) continue;
    for (int trial = 0; trial < 60; ++trial) {
      auto bytes = good_;
      const int changes = 1 + trial % 3;
      for (int c = 0; c < changes; ++c) {
        const std::uint64_t at = s.offset + rng() % s.bytes;
        bytes[at] = trial % 2 ? static_cast<std::uint8_t>(rng()) : static_cast<std::uint8_t>(bytes[at] ^ 0x80);
      }
      reseal_section(bytes, s.offset, s.bytes);
      try {
        io::load_map_bytes(bytes, "fuzzed");
        ++loaded;
      } catch (const Error& e) {
        ++refused;
        EXPECT_NE(std::string(e.what()).find("fuzzed"), std::string::npos) << e.what();
      }
    }
  }
  EXPECT_GT(refused, 0u);
  std::printf("damaged content: %zu refused, %zu loaded (changes a decoder cannot tell from data)\n", refused, loaded);
}

TEST_F(DamagedMap, ASavedMapKeepsTheDescriptorSettingsALocalizerMustTake) {
  GlobalMapConfig odd;
  odd.features.max_range = 12.0;
  odd.context_spacing = 0.5;
  GlobalMap map(odd);
  map.add_submap("a");
  const std::string path = test::temp_path(".map");
  io::save_map(path, map);
  const io::LoadedMap loaded = io::load_map(path);
  EXPECT_EQ(loaded.map->config().features.max_range, 12.0);
  try {
    Localizer refused(*loaded.map, LocalizerConfig{});
    ADD_FAILURE() << "a localizer with other feature settings was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("features"), std::string::npos) << e.what();
  }
  const LocalizerConfig fitting = with_map_descriptor_settings(LocalizerConfig{}, loaded.map->config());
  EXPECT_EQ(fitting.context_spacing, 0.5);
  EXPECT_NO_THROW(Localizer(*loaded.map, fitting));
}

TEST(MapStoreRealData, ASavedScenarioMapLocalizesExactlyAsTheBuiltOne) {
  LSHLOC_REQUIRE_DATA(data);
  const io::DatasetCatalog catalog(data);
  ScenarioConfig config;
  config.building = "intel";
  config.start = 5000;
  config.length = 130;  // the flag rises at scan 120
  config.submaps = 2;
  const Scenario sc = io::load_scenario(catalog, config);
  GlobalMap built;
  MapFeeder(built, sc.submaps).feed_until(1.0);
  const std::string path = test::temp_path(".map");
  io::save_map(path, built);
  const io::LoadedMap loaded = io::load_map(path);
  const auto a = localize_target(built, sc.target, LocalizerConfig{}).estimates;
  const auto b = localize_target(*loaded.map, sc.target, LocalizerConfig{}).estimates;
  expect_same_estimates(a, b);
  EXPECT_TRUE(a.back().localized) << "the scenario should localize, or the comparison says little";
}

}  // namespace
}  // namespace lshloc
