#pragma once
// The one per-scan estimate schema: every per-scan CSV (localize's --out CSV
// and its stdin stream, eval's --trace, which adds truth columns after these)
// writes its rows with append_estimate_row, so that the outputs cannot drift.
// Poses [m] and heading [deg]; scores are means in [-1, 1]; time [s].
// Thread safety: stateless, safe from any thread.
#include <cstddef>
#include <string>

#include "lshloc/localization/report_policy.hpp"

namespace lshloc::io {

/// The header of an estimate row, comma-separated, without a leading or
/// trailing comma: the scan (its index in the run and in the log, its time
/// stamp), the estimate (the submap's name and id, the laser pose), the flag
/// (`confident`: the flag where no stamp clash withholds it; `localized`: the
/// localizer's), the evidence the flag's tests read, and the rival elsewhere
/// (its submap id, the scan's laser pose there [rad], its C/N and N).
inline constexpr const char* kEstimateColumns =
    "scan,log_scan,time,submap,submap_id,x,y,heading_deg,confident,confidence,score,scored,margin,stable,"
    "supported,place_supported,kept_scans,newest_fit,newest_evidence,localized,stamp_clash,flag_down_because,"
    "whole_map_fit,whole_map_lead,rise_margin,rival_submap,rival_x,rival_y,rival_theta,rival_mean_score,"
    "rival_scored,newest_lead";

/// A CSV field as RFC 4180 quotes it: submap names may hold commas or quotes.
std::string csv_field(const std::string& text);

/// Appends `e`'s row in the order of kEstimateColumns, without a trailing
/// comma or newline. `submap_name` is the estimate's submap's name (unused
/// without an estimate, whose pose fields are empty).
void append_estimate_row(std::string& out, std::size_t scan, std::size_t log_scan, double time,
                         const std::string& submap_name, const LocalizationEstimate& e);

}  // namespace lshloc::io
