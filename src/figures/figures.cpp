#include "lshloc/figures/figures.hpp"

#include <unistd.h>

#include <cairo-svg.h>
#include <cairo.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <cstdio>
#include <limits>
#include <memory>

#include "lshloc/common/error.hpp"

namespace lshloc::io {

namespace {

constexpr double kWidth = 900, kHeight = 600;
constexpr double kLeft = 80, kRight = 30, kTop = 50, kBottom = 60;

struct Rgb {
  double r, g, b;
};
constexpr Rgb kPalette[] = {{0.12, 0.47, 0.71}, {0.84, 0.15, 0.16}, {0.17, 0.63, 0.17}, {1.0, 0.5, 0.05},
                            {0.58, 0.4, 0.74},  {0.55, 0.34, 0.29}, {0.89, 0.47, 0.76}, {0.5, 0.5, 0.5}};

bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

/// A cairo surface for `path` (PNG or SVG), finished and checked on close().
/// It is drawn into a temporary file that close() renames to `path`: a
/// failed write (a full disk) leaves no partial figure under the final name.
class Figure {
 public:
  explicit Figure(std::string path) : path_(std::move(path)) {
    svg_ = ends_with(path_, ".svg");
    if (!svg_ && !ends_with(path_, ".png")) throw Error(path_ + ": figures are written as .png or .svg");
    temp_ = path_ + ".tmp." + std::to_string(::getpid());
    surface_ =
        svg_ ? cairo_svg_surface_create(temp_.c_str(), kWidth, kHeight)
             : cairo_image_surface_create(CAIRO_FORMAT_ARGB32, static_cast<int>(kWidth), static_cast<int>(kHeight));
    if (cairo_surface_status(surface_) != CAIRO_STATUS_SUCCESS) throw Error(path_ + ": cannot create the figure");
    cr_ = cairo_create(surface_);
    cairo_set_source_rgb(cr_, 1, 1, 1);
    cairo_paint(cr_);
    cairo_select_font_face(cr_, "sans-serif", CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_NORMAL);
  }
  ~Figure() {
    if (cr_) cairo_destroy(cr_);
    if (surface_) cairo_surface_destroy(surface_);
    std::error_code ec;
    std::filesystem::remove(temp_, ec);  // left only when close() failed or never ran
  }
  Figure(const Figure&) = delete;
  Figure& operator=(const Figure&) = delete;

  cairo_t* cr() { return cr_; }

  void text(double x, double y, const std::string& s, double size = 13, double align = 0.0, bool vertical = false) {
    cairo_set_source_rgb(cr_, 0, 0, 0);
    cairo_set_font_size(cr_, size);
    cairo_text_extents_t ext;
    cairo_text_extents(cr_, s.c_str(), &ext);
    cairo_save(cr_);
    cairo_move_to(cr_, x, y);
    if (vertical) cairo_rotate(cr_, -M_PI / 2);
    cairo_rel_move_to(cr_, -ext.width * align, 0);
    cairo_show_text(cr_, s.c_str());
    cairo_restore(cr_);
  }

  void close() {
    cairo_destroy(cr_);
    cr_ = nullptr;
    cairo_surface_flush(surface_);
    cairo_status_t st = CAIRO_STATUS_SUCCESS;
    if (svg_) {
      cairo_surface_finish(surface_);
      st = cairo_surface_status(surface_);
    } else {
      st = cairo_surface_write_to_png(surface_, temp_.c_str());
    }
    if (st != CAIRO_STATUS_SUCCESS) throw Error(path_ + ": cannot write the figure: " + cairo_status_to_string(st));
    std::error_code ec;
    std::filesystem::rename(temp_, path_, ec);
    if (ec) throw Error(path_ + ": cannot write the figure: " + ec.message());
  }

 private:
  std::string path_;
  std::string temp_;  ///< drawn here until close()
  bool svg_ = false;
  cairo_surface_t* surface_ = nullptr;
  cairo_t* cr_ = nullptr;
};

std::string format_number(double v) {
  char buf[32];
  if (v != 0 && (std::abs(v) >= 1e5 || std::abs(v) < 1e-2))
    std::snprintf(buf, sizeof buf, "%.0e", v);
  else
    std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

/// Axes with a linear or log scale on each side; maps data to pixels.
struct Axes {
  double x0, x1, y0, y1;
  bool log_x = false, log_y = false;
  double tx(double x) const {
    const double a = log_x ? std::log10(x0) : x0, b = log_x ? std::log10(x1) : x1, v = log_x ? std::log10(x) : x;
    return kLeft + (v - a) / (b - a) * (kWidth - kLeft - kRight);
  }
  double ty(double y) const {
    const double a = log_y ? std::log10(y0) : y0, b = log_y ? std::log10(y1) : y1, v = log_y ? std::log10(y) : y;
    return kHeight - kBottom - (v - a) / (b - a) * (kHeight - kTop - kBottom);
  }
  static std::vector<double> ticks(double lo, double hi, bool log) {
    std::vector<double> t;
    if (log) {
      for (double v = std::pow(10.0, std::floor(std::log10(lo))); v <= hi * 1.0001; v *= 10)
        if (v >= lo * 0.9999) t.push_back(v);
      return t;
    }
    const double span = hi - lo, raw = span / 6, mag = std::pow(10.0, std::floor(std::log10(raw)));
    const double step = raw / mag < 2 ? 2 * mag : raw / mag < 5 ? 5 * mag : 10 * mag;
    // A tick at zero is 0, not "-0" (ceil of a small negative) or "1e-17" (sums of steps).
    for (double v = std::ceil(lo / step) * step; v <= hi + 1e-9 * span; v += step)
      t.push_back(std::abs(v) < 1e-9 * step ? 0.0 : v);
    return t;
  }
  void draw(Figure& f, const std::string& title, const std::string& xlabel, const std::string& ylabel) const {
    cairo_t* cr = f.cr();
    cairo_set_line_width(cr, 1);
    for (double v : ticks(y0, y1, log_y)) {
      cairo_set_source_rgb(cr, 0.9, 0.9, 0.9);
      cairo_move_to(cr, kLeft, ty(v)), cairo_line_to(cr, kWidth - kRight, ty(v)), cairo_stroke(cr);
      f.text(kLeft - 6, ty(v) + 4, format_number(v), 11, 1.0);
    }
    for (double v : ticks(x0, x1, log_x)) {
      cairo_set_source_rgb(cr, 0.9, 0.9, 0.9);
      cairo_move_to(cr, tx(v), kTop), cairo_line_to(cr, tx(v), kHeight - kBottom), cairo_stroke(cr);
      f.text(tx(v), kHeight - kBottom + 16, format_number(v), 11, 0.5);
    }
    cairo_set_source_rgb(cr, 0, 0, 0);
    cairo_rectangle(cr, kLeft, kTop, kWidth - kLeft - kRight, kHeight - kTop - kBottom);
    cairo_stroke(cr);
    f.text(kWidth / 2, 30, title, 15, 0.5);
    f.text((kLeft + kWidth - kRight) / 2, kHeight - 18, xlabel, 13, 0.5);
    f.text(22, (kTop + kHeight - kBottom) / 2, ylabel, 13, 0.5, true);
  }
};

void legend(Figure& f, const std::vector<std::string>& labels) {
  cairo_t* cr = f.cr();
  double y = kTop + 18;
  for (std::size_t i = 0; i < labels.size(); ++i, y += 18) {
    const Rgb c = kPalette[i % std::size(kPalette)];
    cairo_set_source_rgb(cr, c.r, c.g, c.b);
    cairo_set_line_width(cr, 2.5);
    cairo_move_to(cr, kWidth - kRight - 150, y - 4), cairo_line_to(cr, kWidth - kRight - 125, y - 4), cairo_stroke(cr);
    f.text(kWidth - kRight - 118, y, labels[i], 12);
  }
}

}  // namespace

void plot_error_curves(const std::string& path, const std::string& title, const std::vector<ErrorSeries>& series,
                       double max_error_m) {
  Figure f(path);
  double xmax = 1;
  for (const auto& s : series)
    for (double x : s.viewpoint) xmax = std::max(xmax, x);
  const Axes ax{0, xmax, 0.01, max_error_m, false, true};
  ax.draw(f, title, "viewpoint (target scan)", "position error [m] (top: wrong building / none)");
  cairo_t* cr = f.cr();
  std::vector<std::string> labels;
  for (std::size_t k = 0; k < series.size(); ++k) {
    const auto& s = series[k];
    labels.push_back(s.label);
    const Rgb c = kPalette[k % std::size(kPalette)];
    cairo_set_source_rgb(cr, c.r, c.g, c.b);
    cairo_set_line_width(cr, 1.6);
    bool pen = false;
    for (std::size_t i = 0; i < s.viewpoint.size() && i < s.error_m.size(); ++i) {
      const double e = s.error_m[i];
      if (std::isnan(e)) continue;
      const double y = ax.ty(std::clamp(e, ax.y0, ax.y1));
      if (pen)
        cairo_line_to(cr, ax.tx(s.viewpoint[i]), y);
      else
        cairo_move_to(cr, ax.tx(s.viewpoint[i]), y), pen = true;
    }
    cairo_stroke(cr);
  }
  legend(f, labels);
  f.close();
}

void plot_confidence(const std::string& path, const std::string& title, const ConfidenceSeries& s) {
  Figure f(path);
  double xmax = 1, ymax = 1;
  for (double x : s.scan) xmax = std::max(xmax, x);
  for (double y : s.mean_score) ymax = std::max(ymax, y);
  const Axes ax{0, xmax, 0, ymax * 1.1, false, false};
  ax.draw(f, title, "target scan", "confidence value, mean score (green band: confident)");
  cairo_t* cr = f.cr();
  cairo_set_source_rgb(cr, 0.1, 0.6, 0.1);
  const double step = (ax.tx(xmax) - ax.tx(0)) / std::max<double>(1.0, static_cast<double>(s.scan.size()));
  for (std::size_t i = 0; i < s.scan.size() && i < s.confident.size(); ++i)
    if (s.confident[i]) cairo_rectangle(cr, ax.tx(s.scan[i]) - step / 2, ax.ty(ax.y1), step + 0.5, 8);
  cairo_fill(cr);
  // The flag threshold: the value lies on or above it exactly where the flag is up.
  cairo_set_source_rgb(cr, 0.2, 0.2, 0.2);
  cairo_set_line_width(cr, 1.0);
  const double dash = 5;
  cairo_set_dash(cr, &dash, 1, 0);
  cairo_move_to(cr, ax.tx(0), ax.ty(s.flag_threshold));
  cairo_line_to(cr, ax.tx(xmax), ax.ty(s.flag_threshold));
  cairo_stroke(cr);
  cairo_set_dash(cr, nullptr, 0, 0);
  char label[64];
  std::snprintf(label, sizeof label, "flag threshold %.2f", s.flag_threshold);
  f.text(ax.tx(0) + 6, ax.ty(s.flag_threshold) - 5, label, 11);
  const std::array<const std::vector<double>*, 2> lines{&s.value, &s.mean_score};
  for (std::size_t k = 0; k < lines.size(); ++k) {
    const std::vector<double>& y = *lines[k];
    cairo_set_source_rgb(cr, kPalette[k].r, kPalette[k].g, kPalette[k].b);
    cairo_set_line_width(cr, k == 0 ? 1.6 : 1.0);
    for (std::size_t i = 0; i < s.scan.size() && i < y.size(); ++i) {
      if (i == 0)
        cairo_move_to(cr, ax.tx(s.scan[i]), ax.ty(y[i]));
      else
        cairo_line_to(cr, ax.tx(s.scan[i]), ax.ty(y[i]));
    }
    cairo_stroke(cr);
  }
  legend(f, {"confidence value", "mean score C/N"});
  f.close();
}

void plot_cost_curves(const std::string& path, const std::string& title, const std::string& y_label,
                      const std::vector<CostSeries>& series) {
  Figure f(path);
  double xmin = std::numeric_limits<double>::infinity(), xmax = 0, ymax = 0;
  for (const auto& s : series) {
    for (double x : s.map_features) xmin = std::min(xmin, x), xmax = std::max(xmax, x);
    for (double y : s.cost) ymax = std::max(ymax, y);
  }
  if (!(xmax > 0)) xmin = 1, xmax = 10;
  xmin = std::pow(10.0, std::floor(std::log10(std::max(xmin, 1.0))));
  xmax = std::pow(10.0, std::ceil(std::log10(std::max(xmax, xmin * 10))));
  const Axes ax{xmin, xmax, 0, ymax > 0 ? ymax * 1.25 : 1, true, false};
  ax.draw(f, title, "map features", y_label);
  cairo_t* cr = f.cr();
  std::vector<std::string> labels;
  for (std::size_t k = 0; k < series.size(); ++k) {
    labels.push_back(series[k].label);
    const Rgb c = kPalette[k % std::size(kPalette)];
    cairo_set_source_rgb(cr, c.r, c.g, c.b);
    cairo_set_line_width(cr, 2);
    for (std::size_t i = 0; i < series[k].map_features.size() && i < series[k].cost.size(); ++i) {
      const double x = ax.tx(series[k].map_features[i]), y = ax.ty(series[k].cost[i]);
      if (i == 0)
        cairo_move_to(cr, x, y);
      else
        cairo_line_to(cr, x, y);
    }
    cairo_stroke(cr);
    for (std::size_t i = 0; i < series[k].map_features.size() && i < series[k].cost.size(); ++i) {
      cairo_arc(cr, ax.tx(series[k].map_features[i]), ax.ty(series[k].cost[i]), 3.5, 0, 2 * M_PI);
      cairo_fill(cr);
    }
  }
  legend(f, labels);
  f.close();
}

void plot_map_figure(const std::string& path, const MapFigure& fig) {
  Figure f(path);
  double x0 = std::numeric_limits<double>::infinity(), y0 = x0, x1 = -x0, y1 = -x0;
  const auto grow = [&](const std::vector<Point2>& pts) {
    for (const auto& p : pts)
      x0 = std::min(x0, p.x()), x1 = std::max(x1, p.x()), y0 = std::min(y0, p.y()), y1 = std::max(y1, p.y());
  };
  grow(fig.map_points), grow(fig.true_trajectory), grow(fig.estimated_trajectory), grow(fig.guesses);
  if (!(x1 > x0)) x0 = -1, x1 = 1;
  if (!(y1 > y0)) y0 = -1, y1 = 1;
  // Equal scale on both axes.
  const double w = kWidth - kLeft - kRight, h = kHeight - kTop - kBottom;
  const double scale = std::min(w / (x1 - x0), h / (y1 - y0));
  const double cx = (x0 + x1) / 2, cy = (y0 + y1) / 2;
  Axes ax{cx - w / scale / 2, cx + w / scale / 2, cy - h / scale / 2, cy + h / scale / 2};
  ax.draw(f, fig.title, "x [m]", "y [m]");
  cairo_t* cr = f.cr();
  cairo_rectangle(cr, kLeft, kTop, w, h);
  cairo_clip(cr);
  const auto dots = [&](const std::vector<Point2>& pts, Rgb c, double r) {
    cairo_set_source_rgb(cr, c.r, c.g, c.b);
    for (const auto& p : pts) cairo_rectangle(cr, ax.tx(p.x()) - r, ax.ty(p.y()) - r, 2 * r, 2 * r);
    cairo_fill(cr);
  };
  const auto line = [&](const std::vector<Point2>& pts, Rgb c, double width) {
    cairo_set_source_rgb(cr, c.r, c.g, c.b);
    cairo_set_line_width(cr, width);
    for (std::size_t i = 0; i < pts.size(); ++i) {
      if (i == 0)
        cairo_move_to(cr, ax.tx(pts[i].x()), ax.ty(pts[i].y()));
      else
        cairo_line_to(cr, ax.tx(pts[i].x()), ax.ty(pts[i].y()));
    }
    cairo_stroke(cr);
  };
  const Rgb truth{0.1, 0.55, 0.1}, estimate{0.12, 0.47, 0.71}, guess{0.95, 0.6, 0.2};
  dots(fig.map_points, {0.6, 0.6, 0.6}, 0.6);
  dots(fig.guesses, guess, 1.2);
  dots(fig.estimated_trajectory, estimate, 2.0);
  line(fig.true_trajectory, truth, 1.2);  // on top, thin: visible beside and under the estimate
  dots(fig.outlier_points, {0.84, 0.15, 0.16}, 1.5);
  dots(fig.inlier_points, {0.12, 0.3, 0.9}, 1.5);
  cairo_reset_clip(cr);
  std::vector<std::pair<const char*, Rgb>> keys;
  if (!fig.true_trajectory.empty()) keys.push_back({"true trajectory", truth});
  keys.push_back({"confident estimate", estimate});
  if (!fig.guesses.empty()) keys.push_back({"guess, not confident", guess});
  if (!fig.inlier_points.empty()) keys.push_back({"inlier local points", {0.12, 0.3, 0.9}});
  if (!fig.outlier_points.empty()) keys.push_back({"outlier local points", {0.84, 0.15, 0.16}});
  cairo_set_source_rgb(cr, 1, 1, 1);
  cairo_rectangle(cr, kWidth - kRight - 160, kTop + 4, 156, 10 + 17 * static_cast<double>(keys.size()));
  cairo_fill(cr);
  double y = kTop + 20;
  for (const auto& [label, c] : keys) {
    cairo_set_source_rgb(cr, c.r, c.g, c.b);
    cairo_rectangle(cr, kWidth - kRight - 152, y - 8, 10, 6);
    cairo_fill(cr);
    f.text(kWidth - kRight - 136, y, label, 11);
    y += 17;
  }
  f.close();
}

void plot_reliability_diagram(const std::string& path, const std::string& title, const Calibration& c) {
  Figure f(path);
  const Axes ax{0, 1, 0, 1, false, false};
  ax.draw(f, title, "confidence value (bins)", "share of right estimates (bars); dots: the bin's mean value");
  cairo_t* cr = f.cr();
  for (const ReliabilityBin& b : c.bins) {
    if (b.count == 0) continue;
    const double x0 = ax.tx(b.lo) + 2, x1 = ax.tx(b.hi) - 2;
    cairo_set_source_rgba(cr, kPalette[0].r, kPalette[0].g, kPalette[0].b, 0.75);
    cairo_rectangle(cr, x0, ax.ty(b.share_right), x1 - x0, ax.ty(0) - ax.ty(b.share_right));
    cairo_fill(cr);
    f.text((x0 + x1) / 2, ax.ty(b.share_right) - 6, "n=" + std::to_string(b.count), 10, 0.5);
  }
  // Perfect calibration, over the bars.
  cairo_set_source_rgb(cr, 0.2, 0.2, 0.2);
  cairo_set_line_width(cr, 1.2);
  const double dash = 5;
  cairo_set_dash(cr, &dash, 1, 0);
  cairo_move_to(cr, ax.tx(0), ax.ty(0));
  cairo_line_to(cr, ax.tx(1), ax.ty(1));
  cairo_stroke(cr);
  cairo_set_dash(cr, nullptr, 0, 0);
  cairo_set_source_rgb(cr, kPalette[1].r, kPalette[1].g, kPalette[1].b);
  for (const ReliabilityBin& b : c.bins) {
    if (b.count == 0) continue;
    cairo_arc(cr, (ax.tx(b.lo) + ax.tx(b.hi)) / 2, ax.ty(b.mean_value), 4, 0, 2 * M_PI);
    cairo_fill(cr);
  }
  f.close();
}

}  // namespace lshloc::io
