// Config structs as JSON: a round trip keeps every value, a partial document
// changes only what it names (nested defaults kept, e.g. the localizer's own
// scan-matcher settings), and mistakes are errors naming the source and key.
#include <gtest/gtest.h>

#include <string>

#include "lshloc/common/error.hpp"
#include "lshloc/eval/run_config_json.hpp"
#include "lshloc/io/config_json.hpp"
#include "test_support.hpp"

namespace lshloc {
namespace {

std::string error_of(const nlohmann::json& patch) {
  RunConfig c;
  try {
    io::apply_config_patch(patch, c, "cfg.json");
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(ConfigJson, RoundTripKeepsEveryValue) {
  RunConfig c;
  c.map.occupancy.cell_size = 0.3;
  c.map.database.bucket_capacity = 32;
  c.localizer.ransac.order_rule = DataPointOrderRule::kUniform;
  c.localizer.place.duel_z = 2.5;
  c.localizer.place.young_place_scans = 7;  // was once left out of the JSON
  c.localizer.place.young_refined_margin = 0.2;
  c.localizer.place.refine_rounds = 3;
  c.localizer.report.stable_scans = 9;
  c.localizer.report.rival_twin_turn_deg = 75.0;
  c.localizer.report.strong_lead = 0.35;
  c.localizer.report.min_whole_map_lead = 0.3;
  c.localizer.report.flag_threshold = 0.8;
  c.localizer.report.weak_support_min_scored = 2000;
  c.localizer.report.weak_support_max_newest_evidence = 0.02;
  c.localizer.report.relative_support_min_scored = 450;
  c.localizer.report.relative_support_min_margin = 0.07;
  c.localizer.trace_evidence = true;
  c.localizer.scan_matcher.match_stalled_odometry = false;
  c.localizer.scan_matcher.laser_offset = Pose2(-0.04, 0.01, 0.02);
  c.localizer.hypothesis_source = HypothesisSource::kRandomMapFeatures;
  c.localizer.newly_mapped_touched = 300;
  c.localizer.newly_mapped_halvings = 2;
  c.map_share_before_target = 0.5;
  const nlohmann::json j = c;
  const RunConfig back = j.get<RunConfig>();
  EXPECT_EQ(nlohmann::json(back), j);
  EXPECT_EQ(back.map.occupancy.cell_size, 0.3);
  EXPECT_EQ(back.map.database.bucket_capacity, 32u);
  EXPECT_EQ(back.localizer.ransac.order_rule, DataPointOrderRule::kUniform);
  EXPECT_EQ(back.localizer.place.duel_z, 2.5);
  EXPECT_EQ(back.localizer.place.young_place_scans, 7u);
  EXPECT_EQ(back.localizer.place.young_refined_margin, 0.2);
  EXPECT_EQ(back.localizer.place.refine_rounds, 3u);
  EXPECT_EQ(back.localizer.report.stable_scans, 9u);
  EXPECT_EQ(back.localizer.report.rival_twin_turn_deg, 75.0);
  EXPECT_EQ(back.localizer.report.strong_lead, 0.35);
  EXPECT_EQ(back.localizer.report.min_whole_map_lead, 0.3);
  EXPECT_EQ(back.localizer.report.flag_threshold, 0.8);
  EXPECT_EQ(back.localizer.report.weak_support_min_scored, 2000u);
  EXPECT_EQ(back.localizer.report.weak_support_max_newest_evidence, 0.02);
  EXPECT_EQ(back.localizer.report.relative_support_min_scored, 450u);
  EXPECT_EQ(back.localizer.report.relative_support_min_margin, 0.07);
  EXPECT_TRUE(back.localizer.trace_evidence);
  EXPECT_FALSE(back.localizer.scan_matcher.match_stalled_odometry);
  EXPECT_EQ(back.localizer.scan_matcher.laser_offset.y, 0.01);
  EXPECT_EQ(back.localizer.hypothesis_source, HypothesisSource::kRandomMapFeatures);
  EXPECT_EQ(back.localizer.newly_mapped_touched, 300u);
  EXPECT_EQ(back.localizer.newly_mapped_halvings, 2u);
  EXPECT_EQ(j["localizer"]["ransac"]["order_rule"], "uniform");
}

TEST(ConfigJson, APatchChangesOnlyWhatItNames) {
  RunConfig c;
  const RunConfig defaults;
  io::apply_config_patch(nlohmann::json::parse(R"({"localizer": {"scan_matcher": {"max_range": 20},
                                                                  "ransac": {"order_rule": "fresh"}}})"),
                         c, "cfg.json");
  EXPECT_EQ(c.localizer.scan_matcher.max_range, 20.0);
  EXPECT_EQ(c.localizer.ransac.order_rule, DataPointOrderRule::kFreshFirst);
  // The localizer's own matcher setting (not ScanMatcherConfig's default) stays.
  EXPECT_EQ(c.localizer.scan_matcher.scan_point_spacing, defaults.localizer.scan_matcher.scan_point_spacing);
  EXPECT_NE(c.localizer.scan_matcher.scan_point_spacing, ScanMatcherConfig{}.scan_point_spacing);
  EXPECT_EQ(c.localizer.ransac.recent_window, defaults.localizer.ransac.recent_window);
  nlohmann::json expected = defaults;
  expected["localizer"]["scan_matcher"]["max_range"] = 20.0;
  expected["localizer"]["ransac"]["order_rule"] = "fresh";
  EXPECT_EQ(nlohmann::json(c), expected);
}

// Config files written before iRANSAC's settings were named after data-points still apply.
TEST(ConfigJson, FormerNamesOfSettingsStillApply) {
  RunConfig c;
  io::apply_config_patch(nlohmann::json::parse(R"({"localizer": {"ransac": {"max_features": 16000,
                                                                             "new_features_per_scan": 25}}})"),
                         c, "old.json");
  EXPECT_EQ(c.localizer.ransac.max_data_points, 16000u);
  EXPECT_EQ(c.localizer.ransac.new_data_points_per_scan, 25u);
  io::apply_config_patch(nlohmann::json::parse(R"({"localizer": {"scan_matcher": {"scan_voxel": 0.07}}})"), c,
                         "old.json");
  EXPECT_EQ(c.localizer.scan_matcher.scan_point_spacing, 0.07);
  const std::string both =
      error_of({{"localizer", {{"ransac", {{"max_features", 16000}, {"max_data_points", 20000}}}}}});
  EXPECT_NE(both.find("cfg.json: localizer.ransac.max_features and max_data_points name one setting"),
            std::string::npos)
      << both;
  // Only where the current name lives: elsewhere the former one is unknown.
  EXPECT_NE(error_of({{"map", {{"max_features", 3}}}}).find("cfg.json: map.max_features: unknown setting"),
            std::string::npos);
}

TEST(ConfigJson, MistakesNameTheSourceAndTheKey) {
  EXPECT_NE(error_of({{"localizer", {{"ransac", {{"blok_size", 3}}}}}})
                .find("cfg.json: localizer.ransac.blok_size: "
                      "unknown setting"),
            std::string::npos);
  EXPECT_NE(error_of({{"localizer", {{"ransac", {{"block_size", -3}}}}}})
                .find("cfg.json: localizer.ransac.block_size: expected a non-negative integer, got -3"),
            std::string::npos);
  EXPECT_NE(error_of({{"map", {{"occupancy", {{"cell_size", "0.2"}}}}}})
                .find("cfg.json: map.occupancy.cell_size: expected a number"),
            std::string::npos);
  EXPECT_NE(error_of({{"map", 3}}).find("cfg.json: map: expected an object"), std::string::npos);
  const std::string bad_enum = error_of({{"localizer", {{"ransac", {{"order_rule", "newest"}}}}}});
  EXPECT_NE(bad_enum.find("cfg.json"), std::string::npos);
  EXPECT_NE(bad_enum.find("\"uniform\", \"recent\", \"fresh\""), std::string::npos) << bad_enum;
  // An array for a number: the key and what it wants, not the JSON library's words.
  EXPECT_NE(error_of({{"localizer", {{"report", {{"min_margin", {1, 2, 3}}}}}}})
                .find("cfg.json: localizer.report.min_margin: expected a number, got [1,2,3]"),
            std::string::npos)
      << error_of({{"localizer", {{"report", {{"min_margin", {1, 2, 3}}}}}}});
  // A float where an integer is expected is a mistake too, not a silent cut.
  EXPECT_NE(error_of({{"localizer", {{"candidates_per_feature", 2.5}}}}).find("expected a non-negative integer"),
            std::string::npos);
}

TEST(ConfigJson, AFileTooDeepOrTooLargeIsRefusedBeforeItIsBuilt) {
  const std::string path = test::temp_path(".json");
  // 300,000 levels once overflowed the stack; 65 is past the cap, 64 is read.
  for (const std::size_t depth : {std::size_t{300000}, std::size_t{65}}) {
    test::write_file(path, std::string(depth, '[') + std::string(depth, ']'));
    try {
      io::read_json_file(path);
      ADD_FAILURE() << depth << " levels were read";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(".json: nested deeper than 64 levels"), std::string::npos) << e.what();
    }
  }
  test::write_file(path, std::string(64, '[') + std::string(64, ']'));
  EXPECT_TRUE(io::read_json_file(path).is_array());
  test::write_file(path, "{\"x\": \"" + std::string(io::kMaxJsonFileBytes, 'a') + "\"}");
  try {
    io::read_json_file(path);
    ADD_FAILURE() << "a file over the cap was read";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("a JSON settings file holds at most 16777216 bytes"), std::string::npos)
        << e.what();
  }
}

TEST(ConfigJson, CountsThatOnlyExhaustMemoryOrTimeAreRefused) {
  for (const auto& [patch, field] :
       {std::pair{nlohmann::json{{"localizer", {{"place", {{"duel_points", 4294967296u}}}}}}, "duel_points"},
        std::pair{nlohmann::json{{"localizer", {{"place", {{"refine_points", 4294967296u}}}}}}, "refine_points"},
        std::pair{nlohmann::json{{"localizer", {{"place", {{"refine_rounds", 4294967296u}}}}}}, "refine_rounds"},
        std::pair{nlohmann::json{{"localizer", {{"scan_matcher", {{"max_iterations", 4294967296u}}}}}},
                  "max_iterations"},
        std::pair{nlohmann::json{{"map", {{"occupancy", {{"initial_capacity", 4294967296u}}}}}}, "initial_capacity"}}) {
    RunConfig c;
    io::apply_config_patch(patch, c, "cfg.json");  // well-typed: applied, then refused by the check of use
    std::string e;
    try {
      c.validate();
    } catch (const Error& err) {
      e = err.what();
    }
    EXPECT_NE(e.find(field), std::string::npos) << patch.dump() << ": " << e;
  }
}

TEST(ConfigJson, TheLargeMapExampleSetsTheFinerHashAndSketchAndNothingElse) {
  RunConfig c;
  const std::string path = std::string(LSHLOC_SOURCE_DIR) + "/examples/config/large-map.json";
  io::apply_config_patch(io::read_json_file(path), c, path);
  EXPECT_EQ(c.map.database.K, 20u);
  EXPECT_EQ(c.map.database.max_candidates, 2000u);
  EXPECT_EQ(c.map.database.sketch_bits, 256u);
  EXPECT_NO_THROW(c.map.database.validate());
  nlohmann::json expected = RunConfig{};
  expected["map"]["database"]["K"] = 20;
  expected["map"]["database"]["max_candidates"] = 2000;
  expected["map"]["database"]["sketch_bits"] = 256;
  EXPECT_EQ(nlohmann::json(c), expected);
}

TEST(ConfigJson, TheManyBuildingsExampleSetsOnlyAQueryTimeSetting) {
  // A larger candidate budget, nothing a map's layout depends on: a map
  // saved with the defaults can be given it without a rebuild.
  RunConfig c;
  const std::string path = std::string(LSHLOC_SOURCE_DIR) + "/examples/config/many-buildings.json";
  io::apply_config_patch(io::read_json_file(path), c, path);
  EXPECT_EQ(c.map.database.max_candidates, 1000u);
  nlohmann::json expected = RunConfig{};
  expected["map"]["database"]["max_candidates"] = 1000;
  EXPECT_EQ(nlohmann::json(c), expected);
  EXPECT_EQ(nlohmann::json(with_query_settings(LshConfig{}, c.map.database)), nlohmann::json(c.map.database));
}

TEST(ConfigJson, AConfigInTheReportPolicysFormerShapeStillApplies) {
  // Before the flag's rework every setting of the report policy sat under localizer.report.confidence
  // (tracking and refinement under localizer.report): they apply where they live now.
  RunConfig c;
  io::apply_config_patch({{"localizer",
                           {{"report",
                             {{"confidence", {{"duel_z", 2.5}, {"min_margin", 0.2}, {"rise_min_newest_fit", 0.05}}},
                              {"refine_points", 10u}}}}}},
                         c, "old.json");
  EXPECT_EQ(c.localizer.place.duel_z, 2.5);
  EXPECT_EQ(c.localizer.place.refine_points, 10u);
  EXPECT_EQ(c.localizer.report.min_margin, 0.2);
  EXPECT_EQ(c.localizer.report.min_newest_fit, 0.05);
  // A count of 2^32 there is refused as under its current name.
  io::apply_config_patch({{"localizer", {{"report", {{"confidence", {{"duel_points", 4294967296u}}}}}}}}, c,
                         "old.json");
  EXPECT_THROW(c.localizer.validate(), Error);
  // A setting of the former rules that is gone: named, with where the settings are now.
  try {
    RunConfig d;
    io::apply_config_patch({{"localizer", {{"report", {{"confidence", {{"rival_memory_scans", 50}}}}}}}}, d,
                           "old.json");
    ADD_FAILURE() << "a removed setting applied";
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("old.json: localizer.report.confidence.rival_memory_scans: a setting of the confidence "
                        "flag's former rules"),
              std::string::npos)
        << what;
    EXPECT_NE(what.find("localizer.place"), std::string::npos) << what;
  }
}

TEST(ConfigJson, TheReportPolicyHoldsTheFlagsTwentySettingsAndNoPlaceSetting) {
  // The flag's settings are "report"; which place is reported is "place"; the value's weights are not
  // settings (src/localization/confidence_value.json).
  const nlohmann::json j = RunConfig{};
  EXPECT_EQ(j["localizer"]["report"].size(), 20u) << j["localizer"]["report"].dump();
  for (const auto& [key, value] : j["localizer"]["report"].items()) EXPECT_FALSE(value.is_object()) << key;
  EXPECT_TRUE(j["localizer"]["place"].contains("duel_z"));
  EXPECT_FALSE(j["localizer"]["report"].contains("value_weights"));
}

TEST(ConfigJson, ReadingAFileNamesItOnSyntaxErrors) {
  const std::string path = test::temp_path("_bad_config.json");
  {
    std::FILE* f = std::fopen(path.c_str(), "w");
    ASSERT_NE(f, nullptr);
    std::fputs("{\"map\": {\n  \"occupancy\": ,\n}}\n", f);
    std::fclose(f);
  }
  try {
    io::read_json_file(path);
    FAIL() << "no error";
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(path), std::string::npos) << what;
    EXPECT_NE(what.find("line 2"), std::string::npos) << what;
  }
  EXPECT_THROW(io::read_json_file(path + ".missing"), Error);
  // A number beyond a double (found by fuzz/config_json_fuzz.cpp) is an Error, not an escaping exception.
  {
    std::FILE* f = std::fopen(path.c_str(), "w");
    ASSERT_NE(f, nullptr);
    std::fputs("88888e888888777777776;: {\" 2 d}}", f);
    std::fclose(f);
  }
  EXPECT_THROW(io::read_json_file(path), Error);
}

}  // namespace
}  // namespace lshloc
