#include "lshloc/io/map_store.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>

#include "lshloc/common/error.hpp"
#include "lshloc/common/huge_page_allocator.hpp"
#include "lshloc/io/atomic_file.hpp"
#include "lshloc/io/config_json.hpp"
#include "lshloc/io/scan_record.hpp"

namespace lshloc::io {

namespace {

static_assert(std::numeric_limits<float>::is_iec559 && std::numeric_limits<double>::is_iec559,
              "the map format stores IEEE-754 binary32 and binary64 values");

constexpr std::array<char, 8> kMagic = {'L', 'S', 'H', 'L', 'O', 'C', 'M', 'P'};
constexpr std::uint32_t kByteOrderMark = 0x01020304;
constexpr std::size_t kHeaderBytes = 64;
constexpr std::uint32_t kSectionMagic = 0x54434553;  // "SECT"
constexpr std::size_t kSectionNameBytes = 16;
constexpr std::size_t kSectionHeaderBytes = 4 + kSectionNameBytes + 8 + 4 + 4;
constexpr std::uint32_t kRecordMagic = 0x4345524a;  // "JREC"
constexpr std::size_t kRecordHeaderBytes = 16;
constexpr std::uint64_t kMaxRecordBytes = 1u << 24;
enum RecordKind : std::uint8_t { kSubmapRecord = 1, kScanRecord = 2 };

std::uint32_t crc_of(std::span<const std::uint8_t> data) {
  return static_cast<std::uint32_t>(crc32_z(crc32_z(0L, Z_NULL, 0), data.data(), data.size()));
}

/// A file's bytes in one buffer, not zero-filled first, on huge pages when
/// large (a 100 MB map loads in fewer page faults).
class FileBytes {
 public:
  explicit FileBytes(std::size_t capacity)
      : capacity_(capacity), data_(capacity ? alloc_.allocate(capacity) : nullptr) {}
  ~FileBytes() {
    if (data_ != nullptr) alloc_.deallocate(data_, capacity_);
  }
  FileBytes(const FileBytes&) = delete;
  FileBytes& operator=(const FileBytes&) = delete;
  std::uint8_t* data() { return data_; }
  std::span<const std::uint8_t> bytes() const { return {data_, size_}; }
  void set_size(std::size_t n) { size_ = n; }

 private:
  HugePageAllocator<std::uint8_t> alloc_;
  std::size_t capacity_ = 0, size_ = 0;
  std::uint8_t* data_ = nullptr;
};

std::unique_ptr<FileBytes> read_whole_file(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) throw FileError(system_error(path, "cannot open the map"));
  struct stat st {};
  if (::fstat(fd, &st) != 0) {
    ::close(fd);
    throw FileError(system_error(path, "cannot stat the map"));
  }
  if (!S_ISREG(st.st_mode)) {
    ::close(fd);
    throw Error(path + ": not a regular file; expected an lshloc map file");
  }
  auto file = std::make_unique<FileBytes>(static_cast<std::size_t>(st.st_size));
  const std::size_t size = static_cast<std::size_t>(st.st_size);
  std::size_t done = 0;
  while (done < size) {
    const ssize_t n = ::read(fd, file->data() + done, size - done);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      ::close(fd);
      throw FileError(system_error(path, "cannot read the map"));
    }
    if (n == 0) break;  // shrank while reading: judge what was read
    done += static_cast<std::size_t>(n);
  }
  ::close(fd);
  file->set_size(done);
  return file;
}

// --- Encoding ---

void put_section(ByteWriter& out, const std::string& name, std::span<const std::uint8_t> payload) {
  ByteWriter header;
  header.u32(kSectionMagic);
  std::array<std::uint8_t, kSectionNameBytes> padded{};
  std::memcpy(padded.data(), name.data(), std::min(name.size(), padded.size()));
  header.raw(padded);
  header.u64(payload.size());
  header.u32(crc_of(payload));
  header.u32(crc_of(header.bytes()));
  out.raw(header.bytes());
  out.raw(payload);
}

std::vector<std::uint8_t> encode_snapshot(const GlobalMap& map, const nlohmann::json& meta) {
  std::vector<std::pair<std::string, std::vector<std::uint8_t>>> sections;
  const std::string settings = io::json_text(nlohmann::json(map.config()));
  const std::string meta_text = io::json_text(meta);
  sections.emplace_back("settings", std::vector<std::uint8_t>(settings.begin(), settings.end()));
  sections.emplace_back("meta", std::vector<std::uint8_t>(meta_text.begin(), meta_text.end()));
  for (MapSection& s : map.snapshot()) sections.emplace_back(s.name, std::move(s.bytes));
  std::uint64_t total = kHeaderBytes;
  for (const auto& s : sections) total += kSectionHeaderBytes + s.second.size();

  ByteWriter header;
  header.raw({reinterpret_cast<const std::uint8_t*>(kMagic.data()), kMagic.size()});
  header.u32(kMapFormatVersion);
  header.u32(kByteOrderMark);
  header.u8(sizeof(float)), header.u8(sizeof(double)), header.u8(0), header.u8(0);
  header.u32(static_cast<std::uint32_t>(sections.size()));
  header.u64(total);
  while (header.size() < kHeaderBytes - 4) header.u8(0);
  header.u32(crc_of(header.bytes()));

  ByteWriter out;
  out.raw(header.bytes());
  for (const auto& [name, bytes] : sections) put_section(out, name, bytes);
  return out.take();
}

/// What ties a journal to its snapshot (format version 2): the CRC-32 of the
/// file header and every section header, each without its own checksum (the
/// section headers hold their payloads' CRCs). Each journal record's payload checksum starts from it, so a record
/// written after another snapshot fails its checksum here.
std::uint32_t snapshot_tie(std::span<const std::uint8_t> snapshot) {
  // Each header without its own trailing CRC: a CRC run over bytes followed by their CRC ends in a constant.
  auto tie = static_cast<std::uint32_t>(crc32_z(0L, snapshot.data(), kHeaderBytes - 4));
  for (std::uint64_t at = kHeaderBytes; at + kSectionHeaderBytes <= snapshot.size();) {
    const auto head = snapshot.subspan(at, kSectionHeaderBytes);
    tie = static_cast<std::uint32_t>(crc32_z(tie, head.data(), head.size() - 4));
    at += kSectionHeaderBytes + ByteReader(head.subspan(4 + kSectionNameBytes, 8), "a section header").u64();
  }
  return tie;
}

/// A record payload's checksum, started from the snapshot's tie (0 in format version 1: a plain CRC-32).
std::uint32_t record_crc(std::uint32_t tie, std::span<const std::uint8_t> payload) {
  return static_cast<std::uint32_t>(crc32_z(tie, payload.data(), payload.size()));
}

void put_record(std::vector<std::uint8_t>& out, std::span<const std::uint8_t> payload, std::uint32_t tie) {
  ByteWriter header;
  header.u32(kRecordMagic);
  header.u32(static_cast<std::uint32_t>(payload.size()));
  header.u32(record_crc(tie, payload));
  header.u32(crc_of(header.bytes()));
  out.insert(out.end(), header.bytes().begin(), header.bytes().end());
  out.insert(out.end(), payload.begin(), payload.end());
}

std::vector<std::uint8_t> encode_scan(std::uint32_t submap, const LaserScan& scan, const Pose2& laser_pose) {
  ByteWriter w;
  w.u8(kScanRecord);
  w.varint(submap);
  write_scan_update(w, scan, laser_pose);
  return w.take();
}

// --- Decoding ---

struct ParsedFile {
  MapFileInfo info;
  GlobalMapConfig config;
  std::vector<MapSectionView> sections;
  std::vector<std::pair<std::uint64_t, std::span<const std::uint8_t>>> records;  ///< (offset, payload)
  std::uint64_t journal_end = 0;                                                 ///< end of the last complete record
  std::uint32_t journal_tie = 0;  ///< snapshot_tie() from format version 2 on, else 0
  std::vector<std::string> warnings;
};

std::string hex_bytes(std::span<const std::uint8_t> bytes) {
  std::string out;
  char buf[4];
  for (const std::uint8_t b : bytes) {
    std::snprintf(buf, sizeof buf, "%02x", b);
    out += buf;
  }
  return out;
}

GlobalMapConfig settings_from(std::span<const std::uint8_t> bytes, const std::string& source) {
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(bytes.begin(), bytes.end());
  } catch (const nlohmann::json::exception& e) {
    throw Error(source + ": expected the map's settings as JSON: " + e.what());
  }
  if (!j.is_object()) throw Error(source + ": expected the map's settings as a JSON object");
  GlobalMapConfig config;
  // Every key must be one this lshloc knows: a setting it would ignore
  // could change what the map means.
  apply_config_patch(j, config, source);
  try {
    config.validate();
  } catch (const Error& e) {
    throw Error(source + ": settings this lshloc cannot use: " + e.what());
  }
  return config;
}

ParsedFile parse_map_file(std::span<const std::uint8_t> file, const std::string& path) {
  ParsedFile p;
  p.info.file_bytes = file.size();
  if (file.empty())
    throw Error(path + ": empty file (0 bytes); expected an lshloc map, which starts with a 64-byte header");
  if (file.size() < kMagic.size() || std::memcmp(file.data(), kMagic.data(), kMagic.size()) != 0)
    throw Error(path + ": not an lshloc map: it starts with bytes " +
                hex_bytes(file.subspan(0, std::min<std::size_t>(file.size(), 8))) + ", expected \"LSHLOCMP\"");
  if (file.size() < kHeaderBytes)
    throw Error(path + ": truncated: " + std::to_string(file.size()) + " bytes, shorter than the " +
                std::to_string(kHeaderBytes) + "-byte header");
  ByteReader header(file.subspan(0, kHeaderBytes), path + ": header");
  header.raw(kMagic.size());
  const std::uint32_t version = header.u32();
  const bool header_intact =
      crc_of(file.subspan(0, kHeaderBytes - 4)) == ByteReader(file.subspan(kHeaderBytes - 4, 4), path).u32();
  // A newer format may lay its header out otherwise, so a checksum that fails there may still be intact;
  // one that holds says the version is real.
  if (version > kMapFormatVersion)
    throw Error(path + ": format version " + std::to_string(version) + " is newer than this lshloc reads (" +
                std::to_string(kMapFormatVersion) + ")" +
                (header_intact ? "; use a newer lshloc, or rebuild the map"
                               : ", or the header is damaged (its checksum does not match as version " +
                                     std::to_string(kMapFormatVersion) +
                                     " lays it out): use a newer lshloc if one wrote the map, else rebuild it"));
  if (!header_intact) throw Error(path + ": header: checksum mismatch; the file is damaged");
  if (version == 0)
    throw Error(path + ": header: expected format version 1.." + std::to_string(kMapFormatVersion) + ", got 0");
  p.info.format_version = version;
  if (header.u32() != kByteOrderMark) header.fail("the little-endian byte-order mark 04 03 02 01");
  if (header.u8() != sizeof(float) || header.u8() != sizeof(double)) header.fail("4-byte floats and 8-byte doubles");
  header.u8(), header.u8();
  const std::uint32_t section_count = header.u32();
  const std::uint64_t snapshot_end = header.u64();
  if (snapshot_end > file.size())
    throw Error(path + ": truncated: the header says the snapshot ends at byte " + std::to_string(snapshot_end) +
                ", the file has " + std::to_string(file.size()) + " bytes");
  if (section_count > 64) header.fail("at most 64 sections, got " + std::to_string(section_count));
  p.info.snapshot_bytes = snapshot_end;

  std::uint64_t at = kHeaderBytes;
  for (std::uint32_t s = 0; s < section_count; ++s) {
    const std::string where = path + ": section " + std::to_string(s) + " at byte " + std::to_string(at);
    if (snapshot_end - at < kSectionHeaderBytes)
      throw Error(where + ": expected a " + std::to_string(kSectionHeaderBytes) +
                  "-byte section header before the snapshot's end at byte " + std::to_string(snapshot_end));
    const auto head = file.subspan(at, kSectionHeaderBytes);
    ByteReader r(head, where);
    const std::uint32_t magic = r.u32();
    const auto name_bytes = r.raw(kSectionNameBytes);
    std::string name(reinterpret_cast<const char*>(name_bytes.data()), kSectionNameBytes);
    name.resize(std::strlen(name.c_str()));
    const std::uint64_t length = r.u64();
    const std::uint32_t payload_crc = r.u32();
    const std::uint32_t header_crc = r.u32();
    if (magic != kSectionMagic || crc_of(head.subspan(0, kSectionHeaderBytes - 4)) != header_crc)
      throw Error(where + ": section header checksum mismatch; the file is damaged");
    at += kSectionHeaderBytes;
    const std::string named = path + ": section " + name;
    if (length > snapshot_end - at)
      throw Error(named + ": " + std::to_string(length) + " bytes from byte " + std::to_string(at) +
                  " run past the snapshot's end at byte " + std::to_string(snapshot_end));
    const auto payload = file.subspan(at, length);
    if (crc_of(payload) != payload_crc)
      throw Error(named + " (" + std::to_string(length) + " bytes at byte " + std::to_string(at) +
                  "): checksum mismatch; the file is damaged");
    for (const auto& other : p.sections)
      if (other.name == name) throw Error(named + ": appears twice");
    p.sections.push_back({std::string_view(reinterpret_cast<const char*>(name_bytes.data()), name.size()), payload});
    p.info.sections.push_back({name, at, length});
    at += length;
  }
  if (at != snapshot_end)
    throw Error(path + ": the sections end at byte " + std::to_string(at) + ", expected the snapshot's end at byte " +
                std::to_string(snapshot_end));
  const auto section = [&](std::string_view name) -> std::span<const std::uint8_t> {
    for (const auto& s : p.sections)
      if (s.name == name) return s.bytes;
    throw Error(path + ": section " + std::string(name) + " is missing");
  };
  for (const auto& s : p.sections) {
    const auto& known = GlobalMap::snapshot_sections();
    if (s.name != "settings" && s.name != "meta" && std::find(known.begin(), known.end(), s.name) == known.end())
      throw Error(path + ": unknown section \"" + std::string(s.name) + "\" for format version " +
                  std::to_string(version));
  }
  p.config = settings_from(section("settings"), path + ": section settings");
  const auto meta = section("meta");
  try {
    p.info.meta = nlohmann::json::parse(meta.begin(), meta.end());
  } catch (const nlohmann::json::exception& e) {
    throw Error(path + ": section meta: expected a JSON object: " + e.what());
  }

  // The journal: complete records up to a possibly torn last one.
  if (version >= 2) p.journal_tie = snapshot_tie(file.subspan(0, snapshot_end));
  std::uint64_t j = snapshot_end;
  while (j < file.size()) {
    const std::string where =
        path + ": journal record " + std::to_string(p.records.size() + 1) + " at byte " + std::to_string(j);
    const std::uint64_t left = file.size() - j;
    if (left < kRecordHeaderBytes) {
      p.info.torn_bytes = left;
      p.warnings.push_back(where + " is torn (" + std::to_string(left) + " bytes of a " +
                           std::to_string(kRecordHeaderBytes) + "-byte header); dropped");
      break;
    }
    const auto head = file.subspan(j, kRecordHeaderBytes);
    ByteReader r(head, where);
    const std::uint32_t magic = r.u32();
    const std::uint32_t length = r.u32();
    const std::uint32_t payload_crc = r.u32();
    if (magic != kRecordMagic || crc_of(head.subspan(0, 12)) != r.u32())
      throw Error(where + ": record header checksum mismatch; the file is damaged");
    if (length > kMaxRecordBytes) throw Error(where + ": expected a record of at most 16 MiB");
    if (length > left - kRecordHeaderBytes) {
      p.info.torn_bytes = left;
      p.warnings.push_back(where + " is torn (" + std::to_string(left - kRecordHeaderBytes) + " of " +
                           std::to_string(length) + " payload bytes); dropped");
      break;
    }
    const auto payload = file.subspan(j + kRecordHeaderBytes, length);
    if (record_crc(p.journal_tie, payload) != payload_crc)
      throw Error(where + ": checksum mismatch; the file is damaged" +
                  (version >= 2 ? std::string(", or the record was written after another snapshot (a journal "
                                              "spliced from another map file)")
                                : std::string()));
    p.records.emplace_back(j, payload);
    j += kRecordHeaderBytes + length;
  }
  p.journal_end = j;
  p.info.journal_bytes = j - snapshot_end;
  return p;
}

/// Applies one journal record to `map`.
void replay(GlobalMap& map, std::span<const std::uint8_t> payload, const std::string& where, MapFileInfo& info) {
  ByteReader in(payload, where);
  const std::uint8_t kind = in.u8();
  if (kind == kSubmapRecord) {
    if (map.submap_count() >= PoseGridHashMap::kMaxSubmaps)
      in.fail("at most " + std::to_string(PoseGridHashMap::kMaxSubmaps) + " submaps");
    map.add_submap(in.string(GlobalMap::kMaxSubmapNameBytes));
    ++info.journal_submaps;
  } else if (kind == kScanRecord) {
    const std::uint64_t id = in.varint();  // range-checked before it narrows
    if (id >= map.submap_count())
      in.fail("a submap id below " + std::to_string(map.submap_count()) + ", got " + std::to_string(id));
    const auto submap = static_cast<std::uint32_t>(id);
    LaserScan scan;
    read_scan_update(in, scan);
    in.expect_done();
    map.add_scan(submap, scan, scan.pose);
    ++info.journal_scans;
  } else {
    in.fail("a record kind of 1 (submap) or 2 (scan), got " + std::to_string(kind));
  }
  in.expect_done();
}

LoadedMap load_parsed(const ParsedFile& p, const std::string& path) {
  LoadedMap out;
  out.info = p.info;
  out.warnings = p.warnings;
  out.map = GlobalMap::from_snapshot(p.config, p.sections, path);
  for (const auto& [offset, payload] : p.records) {
    const std::string where = path + ": journal record at byte " + std::to_string(offset);
    try {
      replay(*out.map, payload, where, out.info);
    } catch (const Error& e) {
      const std::string what = e.what();
      throw Error(what.rfind(where, 0) == 0 ? what : where + ": " + what);
    }
  }
  return out;
}

}  // namespace

namespace {}  // namespace

void save_map(const std::string& path, const GlobalMap& map, const nlohmann::json& meta) {
  // A map being appended to is never replaced under its appender: its lock is taken, and held over the rename.
  const int old = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (old >= 0 && ::flock(old, LOCK_EX | LOCK_NB) != 0) {
    ::close(old);
    throw Error(path + ": another process is appending to this map (its lock is held); it was not replaced");
  }
  try {
    ::close(replace_file(path, encode_snapshot(map, meta)));
  } catch (...) {
    if (old >= 0) ::close(old);
    throw;
  }
  if (old >= 0) ::close(old);
}

LoadedMap load_map(const std::string& path) {
  const auto file = read_whole_file(path);
  return load_parsed(parse_map_file(file->bytes(), path), path);
}

LoadedMap load_map_bytes(std::span<const std::uint8_t> bytes, const std::string& source) {
  return load_parsed(parse_map_file(bytes, source), source);
}

bool looks_like_map_file(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) return false;
  std::array<char, 8> head{};
  const ssize_t n = ::read(fd, head.data(), head.size());
  ::close(fd);
  return n == static_cast<ssize_t>(head.size()) && head == kMagic;
}

void MapAppenderConfig::validate() const {
  require(sync_every >= 1, "MapAppenderConfig.sync_every", ">= 1 scan per fsync", sync_every);
}

MapAppender::MapAppender(const std::string& path, MapAppenderConfig config) : path_(path), config_(config) {
  config_.validate();
  open_file();
}

void MapAppender::open_file() {
  fd_ = ::open(path_.c_str(), O_RDWR | O_CLOEXEC);
  if (fd_ < 0) throw FileError(system_error(path_, "cannot open the map for appending"));
  if (::flock(fd_, LOCK_EX | LOCK_NB) != 0) {
    ::close(fd_);
    fd_ = -1;
    throw Error(path_ + ": another process is appending to this map (its lock is held)");
  }
  try {
    const auto file = read_whole_file(path_);
    const ParsedFile parsed = parse_map_file(file->bytes(), path_);
    LoadedMap loaded = load_parsed(parsed, path_);
    map_ = std::move(loaded.map);
    opened_ = loaded.info;
    warnings_ = loaded.warnings;
    if (parsed.info.torn_bytes > 0) {
      // Cut the torn record off so that new records follow the last good one.
      if (::ftruncate(fd_, static_cast<off_t>(parsed.journal_end)) != 0 || ::fsync(fd_) != 0)
        throw FileError(system_error(path_, "cannot cut off the torn journal record"));
    }
    if (::lseek(fd_, static_cast<off_t>(parsed.journal_end), SEEK_SET) < 0)
      throw FileError(system_error(path_, "cannot seek to the journal's end"));
    journal_end_ = parsed.journal_end;
    journal_tie_ = parsed.journal_tie;  // a version 1 file's records stay untied, as its reader expects
    acknowledged_scans_ = map_->stats().scans;
  } catch (...) {
    ::close(fd_);
    fd_ = -1;
    throw;
  }
}

MapAppender::~MapAppender() {
  try {
    sync();
  } catch (const Error&) {
    // The destructor cannot report; callers who need to know call sync().
  }
  if (fd_ >= 0) ::close(fd_);
}

std::uint32_t MapAppender::add_submap(const std::string& name) {
  if (broken_) throw Error(path_ + ": an earlier append failed half-way; reopen the map to append again");
  if (name.size() > GlobalMap::kMaxSubmapNameBytes)
    throw Error(path_ + ": a submap name of at most " + std::to_string(GlobalMap::kMaxSubmapNameBytes) +
                " bytes expected");
  if (map_->submap_count() >= PoseGridHashMap::kMaxSubmaps)
    throw Error(path_ + ": the map holds " + std::to_string(PoseGridHashMap::kMaxSubmaps) + " submaps already");
  ByteWriter w;
  w.u8(kSubmapRecord);
  w.string(name);
  put_record(pending_, w.bytes(), journal_tie_);
  return map_->add_submap(name);
}

std::size_t MapAppender::add_scan(std::uint32_t submap, const LaserScan& scan, const Pose2& laser_pose) {
  if (submap >= map_->submap_count())
    throw Error(path_ + ": append to unknown submap " + std::to_string(submap) + " (the map has " +
                std::to_string(map_->submap_count()) + ")");
  if (const char* problem = scan_update_problem(scan, laser_pose))
    throw Error(path_ + ": a scan at t=" + std::to_string(scan.timestamp) + " cannot be appended: expected " + problem);
  const std::vector<std::uint8_t> payload = encode_scan(submap, scan, laser_pose);
  if (broken_) throw Error(path_ + ": an earlier append failed half-way; reopen the map to append again");
  LaserScan replayed = scan;  // exactly what a reload replays
  replayed.pose = laser_pose;
  std::size_t added = 0;
  try {
    added = map_->add_scan(submap, replayed, laser_pose);
  } catch (const Error&) {
    throw;  // refused whole (GlobalMap::add_scan): map and journal as they were, appending goes on
  } catch (...) {
    broken_ = true;  // out of memory part-way: the in-memory map may hold part of the scan; the file does not
    throw;
  }
  put_record(pending_, payload, journal_tie_);
  if (++pending_scans_ >= config_.sync_every) sync();
  return added;
}

void MapAppender::sync() {
  if (pending_.empty() || fd_ < 0) return;
  if (sync_failed_)
    throw Error(path_ + ": an earlier fsync of the journal failed; reopen the map (what it acknowledged is kept)");
  if (tail_dirty_) {  // an earlier write failed part-way: its bytes must not precede the records
    if (::ftruncate(fd_, static_cast<off_t>(journal_end_)) != 0 ||
        ::lseek(fd_, static_cast<off_t>(journal_end_), SEEK_SET) < 0)
      throw FileError(system_error(path_, "cannot cut off a failed write from the journal"));
    tail_dirty_ = false;
  }
  tail_dirty_ = true;
  write_all(fd_, pending_, path_);
  if (::fdatasync(fd_) != 0) {
    sync_failed_ = true;
    throw FileError(system_error(path_, "cannot sync the journal"));
  }
  tail_dirty_ = false;
  journal_end_ += pending_.size();
  pending_.clear();
  acknowledged_scans_ += pending_scans_;
  pending_scans_ = 0;
}

void MapAppender::compact(const nlohmann::json& meta) {
  // A map an append failed in may hold part of a scan: never make it the snapshot.
  if (broken_) throw Error(path_ + ": an earlier append failed half-way; reopen the map to compact it");
  sync();
  const std::vector<std::uint8_t> snapshot = encode_snapshot(*map_, meta);
  const int fd = replace_file(path_, snapshot);
  journal_tie_ = snapshot_tie(snapshot);
  ::close(fd_);
  fd_ = fd;  // locked, positioned at the end: the new, empty journal
  const off_t end = ::lseek(fd_, 0, SEEK_CUR);
  if (end < 0) throw FileError(system_error(path_, "cannot find the new journal's start"));
  journal_end_ = static_cast<std::uint64_t>(end);
}

}  // namespace lshloc::io
