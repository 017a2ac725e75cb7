#include "lshloc/io/estimate_csv.hpp"

#include <numbers>

#include "lshloc/io/atomic_file.hpp"

namespace lshloc::io {

std::string csv_field(const std::string& text) {
  if (text.find_first_of(",\"\r\n") == std::string::npos) return text;
  std::string out = "\"";
  for (const char c : text) out += c == '"' ? std::string("\"\"") : std::string(1, c);
  return out + "\"";
}

void append_estimate_row(std::string& out, std::size_t scan, std::size_t log_scan, double time,
                         const std::string& submap_name, const LocalizationEstimate& e) {
  append_format(out, "%zu,%zu,%.6f,", scan, log_scan, time);
  // No estimate: no pose (empty fields, not a pose at the origin of submap 0).
  if (e.has_estimate)
    append_format(out, "%s,%u,%.4f,%.4f,%.3f,", csv_field(submap_name).c_str(), e.submap, e.pose.x, e.pose.y,
                  e.pose.theta * 180.0 / std::numbers::pi);
  else
    out += ",,,,,";
  append_format(out, "%d,%.4f,%.4f,%u,%.4f,%d,%d,%d,%u,%.4f,%.4f,%d,%d,%s,", e.confident() ? 1 : 0, e.confidence,
                e.mean_score, e.scored, e.margin, e.stable ? 1 : 0, e.supported ? 1 : 0, e.place_supported ? 1 : 0,
                e.kept_scans, e.newest_fit, e.newest_evidence, e.localized ? 1 : 0, e.stamp_clash ? 1 : 0,
                e.flag_down_because.joined().c_str());
  append_format(out, "%.4f,%.4f,%.4f,", e.whole_map_fit, e.whole_map_lead, e.rise_margin);
  if (e.has_rival)
    append_format(out, "%u,%.4f,%.4f,%.5f,%.4f,%u,", e.rival_submap, e.rival_pose.x, e.rival_pose.y, e.rival_pose.theta,
                  e.rival_mean_score, e.rival_scored);
  else
    out += ",,,,,,";
  append_format(out, "%.4f", e.newest_lead);
}

}  // namespace lshloc::io
