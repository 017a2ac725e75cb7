#pragma once
// Every component's config struct as JSON, field by field under its C++
// name, and a reader that applies a JSON document onto a config: keys it
// leaves out keep their values, unknown keys and values of the wrong type
// are errors naming the file and the key's path. Enums are written by name.
// Lengths [m], angles [rad] except fields ending in _deg; see each struct.
// Stateless; safe from any thread.
#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

#include "lshloc/appearance/feature_extractor.hpp"
#include "lshloc/appearance/lsh_database.hpp"
#include "lshloc/localization/global_map.hpp"
#include "lshloc/localization/localizer.hpp"
#include "lshloc/matching/incremental_ransac.hpp"
#include "lshloc/matching/pose_grid.hpp"
#include "lshloc/runtime/localize_run.hpp"
#include "lshloc/runtime/session.hpp"
#include "lshloc/slam/correlative_matcher.hpp"
#include "lshloc/slam/pose_graph.hpp"
#include "lshloc/slam/pose_graph_slam.hpp"
#include "lshloc/slam/scan_matcher.hpp"

/// Defines (not inline) to_json and from_json of a config struct from the
/// list of its members, each under its C++ name: for a .cpp file, after the
/// functions were declared in a header.
#define LSHLOC_JSON_FIELDS(Type, ...)                                            \
  void to_json(nlohmann::json& nlohmann_json_j, const Type& nlohmann_json_t) {   \
    NLOHMANN_JSON_EXPAND(NLOHMANN_JSON_PASTE(NLOHMANN_JSON_TO, __VA_ARGS__))     \
  }                                                                              \
  void from_json(const nlohmann::json& nlohmann_json_j, Type& nlohmann_json_t) { \
    NLOHMANN_JSON_EXPAND(NLOHMANN_JSON_PASTE(NLOHMANN_JSON_FROM, __VA_ARGS__))   \
  }

namespace lshloc {

void to_json(nlohmann::json& j, const Pose2& p);
void from_json(const nlohmann::json& j, Pose2& p);
void to_json(nlohmann::json& j, ToleranceMode v);
void from_json(const nlohmann::json& j, ToleranceMode& v);
void to_json(nlohmann::json& j, DataPointOrderRule v);
void from_json(const nlohmann::json& j, DataPointOrderRule& v);
void to_json(nlohmann::json& j, HypothesisSource v);
void from_json(const nlohmann::json& j, HypothesisSource& v);
void to_json(nlohmann::json& j, const FeatureExtractorConfig& c);
void from_json(const nlohmann::json& j, FeatureExtractorConfig& c);
void to_json(nlohmann::json& j, const LshConfig& c);
void from_json(const nlohmann::json& j, LshConfig& c);
void to_json(nlohmann::json& j, const PoseGridConfig& c);
void from_json(const nlohmann::json& j, PoseGridConfig& c);
void to_json(nlohmann::json& j, const IncrementalRansacConfig& c);
void from_json(const nlohmann::json& j, IncrementalRansacConfig& c);
void to_json(nlohmann::json& j, const ScanMatcherConfig::Experimental& c);
void from_json(const nlohmann::json& j, ScanMatcherConfig::Experimental& c);
void to_json(nlohmann::json& j, const ScanMatcherConfig& c);
void from_json(const nlohmann::json& j, ScanMatcherConfig& c);
void to_json(nlohmann::json& j, const PoseGraphConfig& c);
void from_json(const nlohmann::json& j, PoseGraphConfig& c);
void to_json(nlohmann::json& j, const CorrelativeMatcherConfig& c);
void from_json(const nlohmann::json& j, CorrelativeMatcherConfig& c);
void to_json(nlohmann::json& j, const PoseGraphSlamConfig& c);
void from_json(const nlohmann::json& j, PoseGraphSlamConfig& c);
void to_json(nlohmann::json& j, const GlobalMapConfig& c);
void from_json(const nlohmann::json& j, GlobalMapConfig& c);
void to_json(nlohmann::json& j, const ConfidenceConfig& c);
void from_json(const nlohmann::json& j, ConfidenceConfig& c);
void to_json(nlohmann::json& j, const PlaceConfig& c);
void from_json(const nlohmann::json& j, PlaceConfig& c);
void to_json(nlohmann::json& j, const LocalizerConfig& c);
void from_json(const nlohmann::json& j, LocalizerConfig& c);
void to_json(nlohmann::json& j, const RunConfig& c);
void from_json(const nlohmann::json& j, RunConfig& c);
void to_json(nlohmann::json& j, const SessionConfig& c);
void from_json(const nlohmann::json& j, SessionConfig& c);

}  // namespace lshloc

namespace lshloc::io {

[[noreturn]] void throw_config_error(const std::string& source, const std::string& what);

/// Checks `patch` against `current` (the JSON of the config it will be
/// applied to): every key must exist there and every value must have its
/// type (objects recursively; any number where a float is expected, a
/// non-negative integer where an unsigned one is). Throws lshloc::Error
/// "SOURCE: PATH.KEY: expected ..., got ..." on the first mismatch.
void check_config_patch(const nlohmann::json& patch, const nlohmann::json& current, const std::string& source,
                        const std::string& path = "");

/// `patch` with settings under a former name (iRANSAC's new_features_per_scan
/// and max_features, the scan matcher's scan_voxel) under their current one, where `current` has it, so
/// that older config files still apply; likewise the localizer's former
/// "report": {"confidence": {...}} split into "place" and "report" (a
/// setting of the flag's former rules that is gone throws, naming it). Both
/// names at once throw lshloc::Error naming `source`.
nlohmann::json with_current_names(const nlohmann::json& patch, const nlohmann::json& current, const std::string& source,
                                  const std::string& path = "");

/// `j` as a Config; errors (an enum's unknown name) name `source`.
template <class Config>
Config config_from_json(const nlohmann::json& j, const std::string& source) {
  try {
    return j.get<Config>();
  } catch (const nlohmann::json::exception& e) {
    throw_config_error(source, e.what());
  } catch (const std::exception& e) {
    throw_config_error(source, e.what());
  }
}

/// Applies the JSON object `patch` onto `config` (RFC 7386 merge: what the
/// patch leaves out keeps its value). `source` names the patch in errors.
template <class Config>
void apply_config_patch(const nlohmann::json& patch, Config& config, const std::string& source) {
  nlohmann::json merged = config;
  const nlohmann::json renamed = with_current_names(patch, merged, source);
  check_config_patch(renamed, merged, source);
  merged.merge_patch(renamed);
  config = config_from_json<Config>(merged, source);
}

/// Caps on a JSON settings file, checked before its contents are built.
inline constexpr std::uintmax_t kMaxJsonFileBytes = std::uintmax_t{16} << 20;
inline constexpr int kMaxJsonDepth = 64;

/// Reads a JSON file (throws lshloc::Error naming the file, and the line and
/// column of a syntax error; a file over kMaxJsonFileBytes, or nested deeper
/// than kMaxJsonDepth, is refused naming the cap).
nlohmann::json read_json_file(const std::string& path);

/// `j` as JSON text (one line, or indented by `indent` spaces). Strings that
/// are not UTF-8 (file names are bytes) get U+FFFD in place of each bad byte
/// instead of failing the whole output.
std::string json_text(const nlohmann::json& j, int indent = -1);

}  // namespace lshloc::io
