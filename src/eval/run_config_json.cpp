#include "lshloc/eval/run_config_json.hpp"

namespace lshloc {

LSHLOC_JSON_FIELDS(DescriptorContextConfig, scans, min_step, min_turn, max_distance)
LSHLOC_JSON_FIELDS(PlaceRecallConfig, k, exact, match_distance, match_angle_deg, thin_cell, thin_angle, extractor,
                   context, lsh)

}  // namespace lshloc
