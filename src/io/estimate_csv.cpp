#include "lshloc/io/estimate_csv.hpp"

#include "lshloc/io/atomic_file.hpp"

namespace lshloc::io {

void append_estimate_evidence(std::string& out, const LocalizationEstimate& e) {
  append_format(out, "%.4f,%.4f,%.4f,", e.whole_map_fit, e.whole_map_lead, e.rise_margin);
  if (e.has_rival)
    append_format(out, "%u,%.4f,%.4f,%.5f,%.4f,%u,", e.rival_submap, e.rival_pose.x, e.rival_pose.y, e.rival_pose.theta,
                  e.rival_mean_score, e.rival_scored);
  else
    out += ",,,,,,";
  append_format(out, "%.4f", e.newest_lead);
}

}  // namespace lshloc::io
