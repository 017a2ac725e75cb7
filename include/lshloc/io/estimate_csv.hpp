#pragma once
// The estimate's evidence columns that every per-scan CSV shares (eval's
// trace and localize's --out CSV), written by one function so that the two
// cannot drift. Poses [m, rad]; scores are means in [-1, 1].
// Thread safety: stateless, safe from any thread.
#include <string>

#include "lshloc/localization/report_policy.hpp"

namespace lshloc::io {

/// The header of the evidence columns, comma-separated, without a leading or
/// trailing comma: the whole-map fit and lead, the rise margin, the rival
/// elsewhere (submap id, the scan's laser pose there, its C/N and N) and the
/// newest lead.
inline constexpr const char* kEstimateEvidenceColumns =
    "whole_map_fit,whole_map_lead,rise_margin,rival_submap,rival_x,rival_y,rival_theta,rival_mean_score,"
    "rival_scored,newest_lead";

/// Appends `e`'s evidence fields in the order of kEstimateEvidenceColumns,
/// without a trailing comma; the rival's fields are empty when there is none.
void append_estimate_evidence(std::string& out, const LocalizationEstimate& e);

}  // namespace lshloc::io
