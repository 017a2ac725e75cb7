#include "lshloc/figures/figures.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <limits>
#include <sstream>

#include "lshloc/common/error.hpp"
#include "test_support.hpp"

namespace lshloc::io {
namespace {

TEST(Figures, WritesPngAndSvg) {
  ErrorSeries s{"R = 1", {}, {}};
  for (int i = 0; i < 200; ++i) {
    s.viewpoint.push_back(i);
    s.error_m.push_back(i < 30 ? std::numeric_limits<double>::infinity() : (i % 10 == 0 ? NAN : 0.1 + 0.001 * i));
  }
  const std::string png = test::temp_path(".png"), svg = test::temp_path(".svg");
  plot_error_curves(png, "fr079", {s, s});
  plot_error_curves(svg, "fr079", {s});
  EXPECT_EQ(test::read_file(png).substr(1, 3), "PNG");
  EXPECT_NE(test::read_file(svg).find("<svg"), std::string::npos);

  MapFigure m;
  m.title = "map";
  for (int i = 0; i < 100; ++i) m.map_points.emplace_back(std::cos(i * 0.1) * 10, std::sin(i * 0.1) * 5);
  m.true_trajectory = {{0, 0}, {1, 1}, {2, 1}};
  m.estimated_trajectory = {{0, 0.1}, {1, 1.1}};
  m.inlier_points = {{0.5, 0.5}};
  m.outlier_points = {{3, 3}};
  const std::string map_png = test::temp_path(".png");
  plot_map_figure(map_png, m);
  EXPECT_GT(test::read_file(map_png).size(), 1000u);

  const std::string cost_svg = test::temp_path(".svg");
  plot_cost_curves(cost_svg, "costs", "us per feature", {{"update", {1e3, 1e5, 1e6}, {2.0, 2.1, 2.2}}});
  EXPECT_NE(test::read_file(cost_svg).find("<svg"), std::string::npos);
}

TEST(Figures, DrawsAReliabilityDiagram) {
  const Calibration c = calibrate({0.05, 0.55, 0.95, 0.97}, {false, true, true, true}, 10);
  const std::string png = test::temp_path(".png"), svg = test::temp_path(".svg");
  plot_reliability_diagram(png, "calibration", c);
  plot_reliability_diagram(svg, "calibration", c);
  EXPECT_EQ(test::read_file(png).substr(1, 3), "PNG");
  EXPECT_NE(test::read_file(svg).find("<svg"), std::string::npos);
}

TEST(Figures, DrawsTheConfidenceOverARun) {
  ConfidenceSeries s;
  s.flag_threshold = 0.9;
  for (int i = 0; i < 100; ++i) {
    s.scan.push_back(i);
    s.value.push_back(i < 40 ? 0.01 * i : 0.97);
    s.mean_score.push_back(0.005 * i);
    s.confident.push_back(i >= 40);
  }
  const std::string png = test::temp_path(".png"), svg = test::temp_path(".svg");
  plot_confidence(png, "confidence over the run", s);
  plot_confidence(svg, "confidence over the run", s);
  EXPECT_EQ(test::read_file(png).substr(1, 3), "PNG");
  EXPECT_NE(test::read_file(svg).find("<svg"), std::string::npos);
  // An empty run still makes a figure, not a crash.
  const std::string empty = test::temp_path(".png");
  plot_confidence(empty, "no scans", ConfidenceSeries{});
  EXPECT_EQ(test::read_file(empty).substr(1, 3), "PNG");
}

TEST(Figures, RejectsUnknownFormatsAndUnwritablePaths) {
  EXPECT_THROW(plot_error_curves(test::temp_path(".jpg"), "t", {}), Error);
  EXPECT_THROW(plot_error_curves("/nonexistent/dir/x.png", "t", {}), Error);
}

}  // namespace
}  // namespace lshloc::io
