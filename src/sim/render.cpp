#include "lshloc/sim/render.hpp"

#include <cstdio>

namespace lshloc::sim {

namespace {

void append(std::string& out, const char* format, double a, double b, double c = 0.0, double d = 0.0) {
  char text[256];
  std::snprintf(text, sizeof text, format, a, b, c, d);
  out += text;
}

}  // namespace

std::string floor_plan_svg(const FloorPlan& plan, std::span<const Pose2> path, const SvgStyle& style) {
  const double s = style.pixels_per_metre, m = style.margin;
  const double width = (plan.width + 2 * m) * s, height = (plan.height + 2 * m) * s;
  std::string out;
  append(out, "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"%.0f\" height=\"%.0f\">\n", width, height);
  out += "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
  // Flip y so that the building frame's +y points up.
  append(out, "<g transform=\"translate(%.3f,%.3f) scale(%.3f,%.3f)\" stroke-linecap=\"round\">\n", m * s,
         height - m * s, s, -s);
  const std::size_t pillars_end = plan.wall_segments + plan.pillar_segments;
  for (std::size_t k = 0; k < plan.segments.size(); ++k) {
    const char* colour = k < plan.wall_segments ? "black" : k < pillars_end ? "#666666" : "#8b5a2b";
    const auto& seg = plan.segments[k];
    append(out, "<line x1=\"%.3f\" y1=\"%.3f\" x2=\"%.3f\" y2=\"%.3f\" ", seg.a.x(), seg.a.y(), seg.b.x(), seg.b.y());
    out += "stroke=\"";
    out += colour;
    out += "\" stroke-width=\"0.1\"/>\n";
  }
  if (!path.empty()) {
    out += "<polyline fill=\"none\" stroke=\"red\" stroke-width=\"0.08\" points=\"";
    for (const auto& p : path) append(out, "%.3f,%.3f ", p.x, p.y);
    out += "\"/>\n";
    append(out, "<circle cx=\"%.3f\" cy=\"%.3f\" r=\"0.4\" fill=\"blue\"/>\n", path.front().x, path.front().y);
  }
  out += "</g>\n</svg>\n";
  return out;
}

}  // namespace lshloc::sim
