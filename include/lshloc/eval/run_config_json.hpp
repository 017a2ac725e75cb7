#pragma once
// The evaluation harness's config structs as JSON, in the form of
// io/config_json.hpp (every member under its C++ name; apply a partial
// document with io::apply_config_patch). Units as in each struct.
// Stateless; safe from any thread.
#include <nlohmann/json.hpp>

#include "lshloc/eval/appearance.hpp"
#include "lshloc/eval/place_recall.hpp"
#include "lshloc/io/config_json.hpp"

namespace lshloc {

void to_json(nlohmann::json& j, const DescriptorContextConfig& c);
void from_json(const nlohmann::json& j, DescriptorContextConfig& c);
void to_json(nlohmann::json& j, const PlaceRecallConfig& c);
void from_json(const nlohmann::json& j, PlaceRecallConfig& c);

}  // namespace lshloc
