#include "lshloc/fleet/fleet_map.hpp"

#include <chrono>

#include "lshloc/common/error.hpp"
#include "lshloc/common/wall_time.hpp"
#include "lshloc/fleet/map_log.hpp"
#include "lshloc/io/config_json.hpp"
#include "lshloc/io/map_source.hpp"
#include "lshloc/io/map_store.hpp"

namespace lshloc::fleet {

FleetMap open_fleet_map(const std::string& url, const std::string& prefix, const std::string& snapshot,
                        RunConfig& config, std::vector<std::string>& warnings) {
  const auto t0 = std::chrono::steady_clock::now();
  FleetMap f;
  f.follower = std::make_unique<MapFollower>(RedisAddress::parse(url), MapFollowerConfig{.log = {.prefix = prefix}});
  io::adopt_map_settings(f.follower->settings(), config, url);
  if (snapshot.empty()) {
    f.map = std::make_unique<GlobalMap>(config.map);
  } else {
    io::LoadedMap loaded = io::load_map(snapshot);
    warnings.insert(warnings.end(), loaded.warnings.begin(), loaded.warnings.end());
    const nlohmann::json& meta = loaded.info.meta;
    if (!meta.contains("map_log") || !meta["map_log"].is_object() || !meta["map_log"].contains("positions"))
      throw Error(snapshot +
                  ": not a snapshot of a fleet's map (no map_log stream positions in its meta; "
                  "`lshloc map from-redis` writes them)");
    if (meta["map_log"].value("prefix", "") != prefix)
      throw Error(snapshot + ": a snapshot of the map under prefix '" + meta["map_log"].value("prefix", "") +
                  "', not '" + prefix + "'");
    loaded.map->set_query_settings(config.map.database);
    if (nlohmann::json(loaded.map->config()) != nlohmann::json(config.map))
      throw Error(snapshot + ": its map settings differ from the fleet's registered settings at " + url);
    f.follower->resume(positions_from_json(meta["map_log"]["positions"], snapshot + ": meta map_log"));
    f.map = std::move(loaded.map);
  }
  f.follower->catch_up(*f.map);
  f.catch_up_s = seconds_since(t0);
  return f;
}

nlohmann::json fleet_map_json(const FleetMap& fleet, const GlobalMap& map) {
  const MapFollowerStats st = fleet.follower->stats();
  return {{"history_updates", st.history_updates}, {"live_updates", st.live_updates},  {"duplicates", st.duplicates},
          {"reconnects", st.reconnects},           {"catch_up_s", fleet.catch_up_s},   {"submaps", map.submap_count()},
          {"map_scans", map.stats().scans},        {"refused_scans", st.refused_scans}};
}

}  // namespace lshloc::fleet
