// `lshloc calibration TRACE...`: how well the localizer's confidence value is
// calibrated over `eval --trace` files: reliability bins, the expected
// calibration error, and the reliability diagram.
#include <algorithm>
#include <limits>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "lshloc/common/calibration.hpp"
#include "lshloc/common/error.hpp"
#include "lshloc/eval/localization_metrics.hpp"
#include "lshloc/figures/figures.hpp"
#include "lshloc/io/atomic_file.hpp"
#include "lshloc/io/config_json.hpp"
#include "lshloc/io/line_reader.hpp"

namespace lshloc::app {

namespace {

struct CalibrationOptions {
  std::vector<std::string> traces;
  std::size_t bins = 10;
  std::string out;
};

/// The trace files named, a directory standing for its *.csv files (not the
/// *.truth.csv beside them), sorted.
std::vector<std::string> trace_files(const std::vector<std::string>& args) {
  std::vector<std::string> files;
  for (const std::string& a : args) {
    if (!std::filesystem::is_directory(a)) {
      files.push_back(a);
      continue;
    }
    std::vector<std::string> in_dir;
    for (const auto& entry : std::filesystem::directory_iterator(a)) {
      const std::string p = entry.path().string();
      if (entry.is_regular_file() && p.ends_with(".csv") && !p.ends_with(".truth.csv")) in_dir.push_back(p);
    }
    if (in_dir.empty()) throw Error(a + ": no trace (*.csv) in this directory");
    std::sort(in_dir.begin(), in_dir.end());
    files.insert(files.end(), in_dir.begin(), in_dir.end());
  }
  return files;
}

/// Appends the (value, right) pair of every judged scan of one trace: with a
/// measured or interpolated truth, or estimated in another submap.
void read_trace(const std::string& path, const LocalizationMetricsConfig& rule, std::vector<double>& values,
                std::vector<bool>& right) {
  io::LineReader reader(path);
  std::string line;
  if (!reader.next(line)) throw Error(path + ": empty file; expected an `lshloc eval --trace` CSV");
  const io::CsvHeader header(line, reader.where(), "the header of an `lshloc eval --trace` CSV");
  // Every judged scan's errors (judged_*); traces written before every scan was judged have them at truth
  // scans only (error_m, heading_error_deg), and no interpolated truth.
  const bool dense = header.find("judged_error_m") < header.size();
  const std::size_t c_value = header.column("confidence"), c_submap = header.column("submap"),
                    c_err = header.column(dense ? "judged_error_m" : "error_m"),
                    c_heading = header.column(dense ? "judged_heading_error_deg" : "heading_error_deg");
  const std::size_t c_interpolated = header.find("interpolated_x");
  const std::size_t columns = header.size();
  while (reader.next(line)) {
    const auto f = header.row(line, reader.where());
    if (f[c_err].empty()) continue;  // not judged
    const double value = io::parse_double(f[c_value], reader.where(), c_value, "a confidence value in [0, 1]");
    if (!(value >= 0.0 && value <= 1.0))
      throw Error(reader.where() + ": confidence " + std::string(f[c_value]) + " is outside [0, 1]");
    const double err = io::parse_double(f[c_err], reader.where(), c_err, "a position error [m]");
    // No heading error where the estimate is in another submap (or there is none): not right.
    const double heading = f[c_heading].empty()
                               ? std::numeric_limits<double>::infinity()
                               : io::parse_double(f[c_heading], reader.where(), c_heading, "a heading error [deg]");
    const bool interpolated = c_interpolated < columns && !f[c_interpolated].empty();
    const double heading_limit = interpolated ? rule.wrong_confident_interpolated_deg : rule.wrong_confident_deg;
    values.push_back(value);
    right.push_back(!f[c_submap].empty() && err <= rule.wrong_confident_m && heading <= heading_limit);
  }
}

void run_calibration(const CalibrationOptions& opt) {
  const LocalizationMetricsConfig rule;
  std::vector<double> values;
  std::vector<bool> right;
  const std::vector<std::string> files = trace_files(opt.traces);
  for (const std::string& f : files) read_trace(f, rule, values, right);
  if (values.empty()) throw Error("calibration: the traces hold no judged scan (no error_m)");
  const Calibration c = calibrate(values, right, opt.bins);
  nlohmann::json bins = nlohmann::json::array();
  std::string csv = "lo,hi,count,mean_value,share_right\n";
  for (const ReliabilityBin& b : c.bins) {
    bins.push_back(
        {{"lo", b.lo}, {"hi", b.hi}, {"count", b.count}, {"mean_value", b.mean_value}, {"share_right", b.share_right}});
    io::append_format(csv, "%.3f,%.3f,%zu,%.6f,%.6f\n", b.lo, b.hi, b.count, b.mean_value, b.share_right);
  }
  const nlohmann::json j{{"traces", files.size()},
                         {"scans", c.samples},
                         {"right", std::count(right.begin(), right.end(), true)},
                         {"expected_calibration_error", c.expected_calibration_error},
                         {"max_calibration_error", c.max_calibration_error},
                         {"bins", bins}};
  std::printf("%s\n", io::json_text(j).c_str());
  if (!opt.out.empty()) {
    char title[160];
    std::snprintf(title, sizeof title, "confidence calibration: %zu scans of %zu traces, ECE %.3f", c.samples,
                  files.size(), c.expected_calibration_error);
    io::plot_reliability_diagram(opt.out + ".png", title, c);
    io::plot_reliability_diagram(opt.out + ".svg", title, c);
    io::write_file_atomically(opt.out + ".csv", csv);
  }
}

}  // namespace

void add_calibration_command(CLI::App& app, GlobalOptions&) {
  auto opt = std::make_shared<CalibrationOptions>();
  auto* cmd = app.add_subcommand(
      "calibration",
      "How well the confidence value is calibrated, over `eval --trace` files: prints a JSON line with the\n"
      "expected calibration error and the reliability bins over every judged scan (an estimate is right in\n"
      "the true submap within 2 m and 10 deg of a measured truth, 45 deg of an interpolated one: the\n"
      "confident-but-wrong rule); --out also draws the reliability diagram.");
  cmd->add_option("traces", opt->traces, "trace CSVs of `lshloc eval --trace`, or directories of them")->required();
  cmd->add_option("--bins", opt->bins, "equal-width bins over [0, 1]")
      ->capture_default_str()
      ->check(CLI::Range(1, 1000));
  cmd->add_option("--out", opt->out, "write the diagram as OUT.png and OUT.svg, the bins as OUT.csv");
  cmd->callback([opt] { run_calibration(*opt); });
}

}  // namespace lshloc::app
