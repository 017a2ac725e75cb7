#include "lshloc/fleet/map_log.hpp"

#include <zlib.h>

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <thread>

#include <nlohmann/json.hpp>

#include "lshloc/common/byte_codec.hpp"
#include "lshloc/common/error.hpp"
#include "lshloc/io/config_json.hpp"
#include "lshloc/io/scan_record.hpp"

namespace lshloc::fleet {

namespace {

constexpr std::uint8_t kRecordVersion = 1;
constexpr std::string_view kSettingsField = "settings";
constexpr std::string_view kSubmapFieldPrefix = "submap:";

std::uint32_t crc_of(std::string_view bytes) {
  return static_cast<std::uint32_t>(
      crc32_z(crc32_z(0L, Z_NULL, 0), reinterpret_cast<const Bytef*>(bytes.data()), bytes.size()));
}

std::uint64_t parse_u64(std::string_view text, const std::string& what) {
  std::uint64_t v = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (ec != std::errc() || end != text.data() + text.size())
    throw Error(what + ": expected a non-negative integer, got '" + std::string(text) + "'");
  return v;
}

/// The value of `field` in a stream entry's [field, value, ...] list, or null.
const std::string* field_of(const Reply& fields, std::string_view field) {
  for (std::size_t i = 0; i + 1 < fields.elements.size(); i += 2)
    if (fields.elements[i].text == field) return &fields.elements[i + 1].text;
  return nullptr;
}

}  // namespace

std::string MapLogConfig::stream_key(std::string_view submap) const {
  return prefix + ":{" + std::string(submap) + "}:log";
}

std::string encode_update(std::uint64_t seq, const LaserScan& scan) {
  ByteWriter w;
  w.reserve(1 + 8 + 7 * 8 + 10 + 4 * scan.ranges.size() + 4);
  w.u8(kRecordVersion);
  w.u64(seq);
  io::write_scan_update(w, scan, scan.pose);
  const auto& body = w.bytes();
  w.u32(crc_of(std::string_view(reinterpret_cast<const char*>(body.data()), body.size())));
  const auto& all = w.bytes();
  return {reinterpret_cast<const char*>(all.data()), all.size()};
}

void decode_update(std::string_view record, const std::string& where, MapUpdate& out) {
  if (record.size() < 1 + 8 + 4)
    throw Error(where + ": a map log record of at least 13 bytes, got " + std::to_string(record.size()));
  const std::string_view body = record.substr(0, record.size() - 4);
  ByteReader tail(std::span(reinterpret_cast<const std::uint8_t*>(record.data()) + body.size(), 4), where);
  if (tail.u32() != crc_of(body)) throw Error(where + ": checksum mismatch; the record is damaged");
  ByteReader in(std::span(reinterpret_cast<const std::uint8_t*>(body.data()), body.size()), where);
  const std::uint8_t version = in.u8();
  if (version != kRecordVersion)
    in.fail("record version " + std::to_string(kRecordVersion) + ", got " + std::to_string(version));
  out.seq = in.u64();
  io::read_scan_update(in, out.scan);
  in.expect_done();
}

// --- Writer ---

void register_map(RedisClient& redis, const GlobalMapConfig& settings, std::span<const std::string> submaps,
                  const MapLogConfig& config) {
  for (const std::string& name : submaps)
    if (name.empty() || name.size() > 200 || name.find_first_of("{}") != std::string::npos)
      throw Error("submap name '" + name + "': expected 1..200 characters without { or }");
  const std::string registry = config.registry_key();
  const std::string mine = nlohmann::json(settings).dump();
  redis.command({"HSETNX", registry, kSettingsField, mine});
  const Reply theirs = redis.command({"HGET", registry, kSettingsField});
  if (theirs.text != mine) {
    const nlohmann::json a = nlohmann::json::parse(theirs.text, nullptr, false), b = nlohmann::json::parse(mine);
    std::string differs = "?";
    if (a.is_object())
      for (const auto& [k, v] : b.items())
        if (!a.contains(k) || a[k] != v) {
          differs = k;
          break;
        }
    throw Error(redis.address().url() + " " + registry +
                ": the map's registered settings differ from this "
                "mapper's (first in '" +
                differs + "'); a map takes one set of settings");
  }
  // One script, so that it runs atomically: mappers registering the same list
  // at once agree on its order (and so on every localizer's submap ids).
  static constexpr std::string_view kRegister = R"(
for _, name in ipairs(ARGV) do
  local field = 'submap:' .. name
  if redis.call('HEXISTS', KEYS[1], field) == 0 then
    redis.call('HSET', KEYS[1], field, redis.call('HINCRBY', KEYS[1], 'submap_count', 1))
  end
end
return 0)";
  std::vector<std::string_view> words = {"EVAL", kRegister, "1", registry};
  words.insert(words.end(), submaps.begin(), submaps.end());
  redis.command(words);
}

MapLogWriter::MapLogWriter(RedisClient& redis, std::string submap, const GlobalMapConfig& settings, MapLogConfig config)
    : redis_(redis), submap_(std::move(submap)), config_(std::move(config)), key_(config_.stream_key(submap_)) {
  register_map(redis_, settings, std::span(&submap_, 1), config_);
  resync();
}

void MapLogWriter::resync() {
  next_seq_ = 0;
  const Reply last = redis_.command({"XREVRANGE", key_, "+", "-", "COUNT", "1"});
  if (last.elements.empty()) return;
  const Reply& entry = last.elements[0];
  const std::string* record = entry.elements.size() == 2 ? field_of(entry.elements[1], "rec") : nullptr;
  if (!record) throw Error(redis_.address().url() + " " + key_ + ": its last entry has no rec field");
  MapUpdate u;
  decode_update(*record, redis_.address().url() + " " + key_ + " entry " + entry.elements[0].text, u);
  next_seq_ = u.seq + 1;
}

void MapLogWriter::publish(std::span<const LaserScan> scans) {
  // Every follower would stop at a record it cannot read: refuse it here, before anything is sent.
  for (std::size_t k = 0; k < scans.size(); ++k)
    if (const char* problem = io::scan_update_problem(scans[k], scans[k].pose))
      throw Error(key_ + ": scan " + std::to_string(next_seq_ + k) + " (t=" + std::to_string(scans[k].timestamp) +
                  ") cannot be published: expected " + problem);
  std::vector<std::vector<std::string>> batch;
  for (std::size_t i = 0; i < scans.size(); i += config_.batch) {
    batch.clear();
    const std::size_t end = std::min(scans.size(), i + config_.batch);
    for (std::size_t k = i; k < end; ++k) {
      const std::uint64_t seq = next_seq_ + (k - i);
      batch.push_back({"XADD", key_, "*", "seq", std::to_string(seq), "rec", encode_update(seq, scans[k])});
    }
    redis_.pipeline(batch);
    next_seq_ += end - i;
  }
}

// --- Reader ---

MapLogReader::MapLogReader(RedisClient& redis, MapLogConfig config) : redis_(redis), config_(std::move(config)) {}

GlobalMapConfig MapLogReader::settings() {
  const std::string registry = config_.registry_key();
  const Reply r = redis_.command({"HGET", registry, kSettingsField});
  const std::string where = redis_.address().url() + " " + registry;
  if (r.is_nil()) throw Error(where + ": no map settings registered (no mapper has published under this prefix)");
  try {
    GlobalMapConfig c = nlohmann::json::parse(r.text).get<GlobalMapConfig>();
    c.validate();
    return c;
  } catch (const nlohmann::json::exception& e) {
    throw Error(where + ": settings this lshloc cannot use: " + e.what());
  }
}

void MapLogReader::refresh_registry() {
  const Reply all = redis_.command({"HGETALL", config_.registry_key()});
  std::vector<std::pair<std::uint64_t, std::string>> found;
  for (std::size_t i = 0; i + 1 < all.elements.size(); i += 2) {
    const std::string& field = all.elements[i].text;
    if (!field.starts_with(kSubmapFieldPrefix)) continue;
    const std::string name = field.substr(kSubmapFieldPrefix.size());
    if (positions_.contains(name)) continue;
    found.emplace_back(parse_u64(all.elements[i + 1].text, config_.registry_key() + " field " + field), name);
  }
  std::sort(found.begin(), found.end());
  for (auto& [index, name] : found)
    order_.push_back(name), positions_[name] = {}, submap_of_key_[config_.stream_key(name)] = name;
  stats_.submaps = order_.size();
}

std::vector<MapUpdate> MapLogReader::poll(double block_s) {
  for (;;) {  // each read moves past its duplicates: this ends
    bool duplicates_only = false;
    std::vector<MapUpdate> out = read_once(block_s, duplicates_only);
    if (!duplicates_only) return out;
  }
}

std::vector<MapUpdate> MapLogReader::read_once(double block_s, bool& duplicates_only) {
  refresh_registry();
  std::vector<MapUpdate> out;
  if (order_.empty()) return out;
  auto xread = [&](std::span<const std::string> names, double wait_s) {
    std::vector<std::string> words = {"XREAD", "COUNT", std::to_string(config_.batch)};
    if (wait_s > 0) words.insert(words.end(), {"BLOCK", std::to_string(std::max<long>(1, std::lround(wait_s * 1e3)))});
    words.push_back("STREAMS");
    for (const auto& name : names) words.push_back(config_.stream_key(name));
    for (const auto& name : names) words.push_back(positions_[name].last_id);
    return words;
  };
  // One server reads every stream with one XREAD; a cluster one per stream
  // (a command's keys must share a slot), each node's pipelined.
  std::vector<std::vector<std::string>> reads;
  if (redis_.is_cluster())
    for (std::size_t i = 0; i < order_.size(); ++i) reads.push_back(xread(std::span(order_).subspan(i, 1), 0.0));
  else
    reads.push_back(xread(order_, 0.0));
  auto nothing = [](const std::vector<Reply>& replies) {
    return std::all_of(replies.begin(), replies.end(), [](const Reply& r) { return r.is_nil(); });
  };
  std::vector<Reply> replies = redis_.pipeline(reads);
  if (nothing(replies) && block_s > 0) {
    if (!redis_.is_cluster()) {
      replies = redis_.pipeline({xread(order_, block_s)});
    } else {
      const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(block_s);
      while (nothing(replies) && std::chrono::steady_clock::now() < until) {
        std::this_thread::sleep_for(std::chrono::duration<double>(config_.cluster_poll_s));
        replies = redis_.pipeline(reads);
      }
    }
  }
  // Each stream's new updates, streams in registration order. A gap or an
  // entry that cannot be decoded stops the reading there: what came before
  // it is handed out, and the next poll meets it again and throws. Positions
  // and counters move only with what this poll hands out, so a throw loses
  // nothing that was read.
  std::map<std::string, Position> positions = positions_;
  stats_.stopped.clear();
  std::vector<std::vector<MapUpdate>> streams;
  std::size_t collected = 0, duplicates = 0;
  bool stop = false;
  for (const Reply& r : replies) {
    for (const Reply& stream : r.elements) {
      if (stop || stream.elements.size() != 2) continue;
      const std::string& key = stream.elements[0].text;
      const auto known = submap_of_key_.find(key);
      if (known == submap_of_key_.end()) continue;
      const std::string& name = known->second;
      Position& pos = positions[name];
      std::vector<MapUpdate>& mine = streams.emplace_back();
      for (const Reply& entry : stream.elements[1].elements) {
        if (entry.elements.size() != 2) continue;
        const std::string where = redis_.address().url() + " " + key + " entry " + entry.elements[0].text;
        MapUpdate u;
        u.submap = name;
        try {
          const std::string* record = field_of(entry.elements[1], "rec");
          if (!record) throw Error(where + ": expected a rec field");
          decode_update(*record, where, u);
          if (u.seq > pos.next_seq)
            throw Error(where + ": sequence number " + std::to_string(u.seq) + " after " +
                        std::to_string(pos.next_seq) + " was expected: updates of submap " + name + " are missing");
        } catch (const Error& e) {
          if (collected == 0) throw MapLogRecordError(e.what());
          stats_.stopped = e.what();
          stop = true;
          break;
        }
        pos.last_id = entry.elements[0].text;
        if (u.seq < pos.next_seq) {
          ++duplicates;
          continue;
        }
        ++pos.next_seq;
        ++collected;
        mine.push_back(std::move(u));
      }
    }
  }
  positions_ = std::move(positions);
  stats_.duplicates += duplicates;
  stats_.updates += collected;
  duplicates_only = collected == 0 && duplicates > 0;
  // Round robin, one update of each submap in turn: the order in which a map
  // built from files is fed (eval/scenario_runner.hpp MapFeeder), so that a
  // localizer that catches up on a finished map gets the same map.
  out.reserve(collected);
  for (std::size_t i = 0; out.size() < collected; ++i)
    for (auto& mine : streams)
      if (i < mine.size()) out.push_back(std::move(mine[i]));
  return out;
}

nlohmann::json positions_to_json(const std::vector<StreamPosition>& positions) {
  nlohmann::json j = nlohmann::json::array();
  for (const auto& p : positions) j.push_back({{"submap", p.submap}, {"last_id", p.last_id}, {"next_seq", p.next_seq}});
  return j;
}

std::vector<StreamPosition> positions_from_json(const nlohmann::json& j, const std::string& source) {
  if (!j.is_array()) throw Error(source + ": expected the map log's stream positions as a JSON array");
  std::vector<StreamPosition> out;
  for (const auto& e : j) {
    if (!e.is_object() || !e.contains("submap") || !e["submap"].is_string() || !e.contains("last_id") ||
        !e["last_id"].is_string() || !e.contains("next_seq") || !e["next_seq"].is_number_unsigned())
      throw Error(source +
                  ": expected each stream position as {\"submap\": string, \"last_id\": string, "
                  "\"next_seq\": unsigned}, got " +
                  e.dump());
    out.push_back(
        {e["submap"].get<std::string>(), e["last_id"].get<std::string>(), e["next_seq"].get<std::uint64_t>()});
  }
  return out;
}

std::vector<StreamPosition> MapLogReader::positions() const {
  std::vector<StreamPosition> out;
  for (const auto& name : order_) {
    const Position& p = positions_.at(name);
    out.push_back({name, p.last_id, p.next_seq});
  }
  return out;
}

void MapLogReader::resume(const std::vector<StreamPosition>& positions) {
  if (!order_.empty()) throw Error("MapLogReader::resume: the reader has read already");
  for (const auto& p : positions) {
    if (positions_.contains(p.submap)) throw Error("stream positions name submap " + p.submap + " twice");
    order_.push_back(p.submap);
    positions_[p.submap] = {p.last_id, p.next_seq};
    submap_of_key_[config_.stream_key(p.submap)] = p.submap;
  }
  stats_.submaps = order_.size();
}

AppliedUpdates apply_updates(GlobalMap& map, std::span<const std::string> submaps, std::span<const MapUpdate> updates) {
  for (const std::string& name : submaps)
    if (!map.find_submap(name)) map.add_submap(name);
  AppliedUpdates out;
  for (const MapUpdate& u : updates) {
    const std::optional<std::uint32_t> found = map.find_submap(u.submap);
    const std::uint32_t id = found ? *found : map.add_submap(u.submap);
    try {
      map.add_scan(id, u.scan, u.scan.pose);
      ++out.added;
    } catch (const Error& e) {
      ++out.refused;
      out.last_refusal = "submap " + u.submap + " scan " + std::to_string(u.seq) + ": " + e.what();
    }
  }
  return out;
}

}  // namespace lshloc::fleet
