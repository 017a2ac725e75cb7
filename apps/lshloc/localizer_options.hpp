#pragma once
// Settings of the commands that run the localizer (eval, localize, demo,
// bench scale): the library's defaults, then --config FILE.json (any field of
// the map and the localizer, under its C++ name), then the few everyday
// flags. --print-config writes the effective settings as JSON.
#include <cstdio>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "lshloc/eval/scenario_runner.hpp"
#include "lshloc/eval/run_config_json.hpp"

namespace lshloc::app {

struct LocalizerOptions {
  RunConfig config;
  std::string config_file;  ///< the --config file (empty: none), named by errors in its settings
  bool print_config = false;
};

/// A CLI11 option for an enum field, by the names its JSON uses.
template <class Enum>
CLI::Option* add_enum_option(CLI::App& cmd, const std::string& name, Enum& value, std::initializer_list<Enum> values,
                             const std::string& help) {
  std::vector<std::string> names;
  for (Enum v : values) names.push_back(nlohmann::json(v).get<std::string>());
  return cmd
      .add_option_function<std::string>(
          name, [&value](const std::string& text) { value = nlohmann::json(text).get<Enum>(); }, help)
      ->check(CLI::IsMember(names))
      ->default_str(nlohmann::json(value).get<std::string>());
}

inline void add_localizer_options(CLI::App& cmd, LocalizerOptions& o, bool research_flags = false) {
  const std::string group = "Settings";
  cmd.add_option_function<std::string>(
         "--config",
         [&o](const std::string& path) {
           io::apply_config_patch(io::read_json_file(path), o.config, path);
           o.config_file = path;
         },
         "JSON file of settings (the shape --print-config writes; any subset): every field of the global map "
         "and the localizer, under its C++ name; a saved map keeps its own map settings but for the database's "
         "query-time ones (max_candidates, rarest_buckets_first, sketch_collision_weight; "
         "examples/config/many-buildings.json)")
      ->trigger_on_parse()
      ->group(group);
  cmd.add_flag("--print-config", o.print_config,
               "print the effective settings as JSON (defaults, --config, flags) and exit")
      ->group(group);
  if (!research_flags) return;
  auto& l = o.config.localizer;
  add_enum_option(cmd, "--order-rule", l.ransac.order_rule,
                  {DataPointOrderRule::kUniform, DataPointOrderRule::kRecentWindow, DataPointOrderRule::kFreshFirst},
                  "iRANSAC order rule: uniform (the paper: any data-point), recent (the newest "
                  "localizer.ransac.recent_window), fresh (new data-points first)")
      ->group(group);
  add_enum_option(cmd, "--hypotheses", l.hypothesis_source,
                  {HypothesisSource::kDatabase, HypothesisSource::kRandomMapFeatures},
                  "where hypotheses come from: database (LSH-RANSAC) or random map features (the ablation)")
      ->group(group);
}

/// The run configuration the options describe: the localizer's features are
/// the map's (they must match).
inline RunConfig make_run_config(const LocalizerOptions& o) try {
  RunConfig c = o.config;
  // The descriptors' settings are the map's: the localizer takes them from there, and one asked of the
  // localizer alone would be dropped without a word, so it is refused.
  const LocalizerConfig defaults{};
  if (!(c.localizer.features == defaults.features) && !(c.localizer.features == c.map.features))
    throw Error("localizer.features: the localizer uses the map's feature settings; set them under map.features");
  if ((c.localizer.context_scans != defaults.context_scans && c.localizer.context_scans != c.map.context_scans) ||
      (c.localizer.context_spacing != defaults.context_spacing && c.localizer.context_spacing != c.map.context_spacing))
    throw Error(
        "localizer.context_scans, localizer.context_spacing: the localizer uses the map's; set them under "
        "map.context_scans and map.context_spacing");
  c.localizer = with_map_descriptor_settings(c.localizer, c.map);
  c.validate();  // before any work, and before --print-config shows settings no run would take
  return c;
} catch (const Error& e) {
  if (o.config_file.empty()) throw;
  throw Error(o.config_file + ": " + e.what());
}

/// With --print-config: prints the effective settings and returns true (the
/// command then stops).
inline bool print_config_if_asked(const LocalizerOptions& o) {
  if (!o.print_config) return false;
  std::printf("%s\n", io::json_text(nlohmann::json(make_run_config(o)), 2).c_str());
  return true;
}

}  // namespace lshloc::app
