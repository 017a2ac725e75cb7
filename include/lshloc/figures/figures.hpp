#pragma once
// The paper's figures (error curves, map figures, cost curves), drawn with
// cairo and written as .png or .svg.
// Positions and errors [m] (map frame); costs in the caller's units.
// Thread safety: calls share no lshloc state (each draws on its own cairo
// surface); lshloc never calls them concurrently, so concurrent calls rest on
// cairo's own guarantees.
#include <string>
#include <vector>

#include "lshloc/common/calibration.hpp"
#include "lshloc/geometry/pose2.hpp"

namespace lshloc::io {

/// One curve of an error-per-viewpoint plot. NaN values are gaps; +inf (wrong
/// submap or no estimate) is drawn at the top of the axis.
struct ErrorSeries {
  std::string label;
  std::vector<double> viewpoint;  ///< x: target scan index
  std::vector<double> error_m;    ///< y: position error [m]
};

/// The paper's Fig. 8: error against viewpoint, log-scaled error axis. The
/// format follows the extension of `path` (.png or .svg). Throws lshloc::Error
/// if the file cannot be written.
void plot_error_curves(const std::string& path, const std::string& title, const std::vector<ErrorSeries>& series,
                       double max_error_m = 100.0);

/// Points, polylines and markers over a map (the paper's Figs. 5 and 6).
struct MapFigure {
  std::string title;
  std::vector<Point2> map_points;            ///< grey: the map (e.g. the target's submap)
  std::vector<Point2> true_trajectory;       ///< green
  std::vector<Point2> estimated_trajectory;  ///< blue: confident estimates in this submap
  std::vector<Point2> guesses;               ///< orange: estimates in this submap while not confident
  std::vector<Point2> inlier_points;         ///< blue dots: local features that agree with the map
  std::vector<Point2> outlier_points;        ///< red dots
};

void plot_map_figure(const std::string& path, const MapFigure& figure);

/// A localization run's confidence over time: per target scan the calibrated
/// confidence value, the mean score of the reported hypothesis, and whether
/// the answer was confident.
struct ConfidenceSeries {
  std::vector<double> scan;
  std::vector<double> value;  ///< the calibrated confidence value, in [0, 1]
  std::vector<double> mean_score;
  std::vector<bool> confident;
  double flag_threshold = 0.95;  ///< the value at or above which the flag is up (a dashed line)
};
/// The confidence value and the mean score against the scan (lines), the
/// flag threshold (dashed), and a green band along the top where the answer
/// was confident.
void plot_confidence(const std::string& path, const std::string& title, const ConfidenceSeries& series);

/// Per-feature cost against map size (the paper's Fig. 4): one series per cost.
struct CostSeries {
  std::string label;
  std::vector<double> map_features;  ///< x
  std::vector<double> cost;          ///< y
};
void plot_cost_curves(const std::string& path, const std::string& title, const std::string& y_label,
                      const std::vector<CostSeries>& series);

/// A reliability diagram: per bin, the share of right estimates (bars) against
/// the bin's mean confidence value (dots), the diagonal being perfect
/// calibration; the title should carry the ECE.
void plot_reliability_diagram(const std::string& path, const std::string& title, const Calibration& calibration);

}  // namespace lshloc::io
