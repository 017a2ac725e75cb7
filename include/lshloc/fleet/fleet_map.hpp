#pragma once
// A fleet's map on Redis (docs/fleet.md) as a map source (io/map_source.hpp,
// `redis://HOST:PORT`): its settings adopted into a run's config, the map
// restored from a snapshot when one is given, and the map log's history (or
// what came after the snapshot) applied; follower->start() then follows it.
// Thread safety: open_fleet_map and fleet_map_json run on the caller's
// thread; the follower's own contract is in map_follower.hpp.
#include <memory>
#include <string>

#include <nlohmann/json.hpp>

#include "lshloc/fleet/map_follower.hpp"
#include "lshloc/localization/global_map.hpp"
#include "lshloc/runtime/localize_run.hpp"

namespace lshloc::fleet {

struct FleetMap {
  std::unique_ptr<MapFollower> follower;
  std::unique_ptr<GlobalMap> map;
  double catch_up_s = 0.0;  ///< [s] wall time to load the snapshot and apply the rest
};

/// Opens the fleet's map at `url` under key `prefix`, from `snapshot` (a
/// file `lshloc map from-redis` wrote, with its stream positions; empty:
/// none). The snapshot's warnings go to `warnings`. Throws lshloc::Error
/// naming the URL or the file when the map cannot be had.
FleetMap open_fleet_map(const std::string& url, const std::string& prefix, const std::string& snapshot,
                        RunConfig& config, std::vector<std::string>& warnings);

/// JSON of the follower's counters and the map it fed (`fleet.map`, or where
/// the caller moved it) for a command's answer.
nlohmann::json fleet_map_json(const FleetMap& fleet, const GlobalMap& map);

}  // namespace lshloc::fleet
