#pragma once
// A floor plan (and optionally a path over it) as SVG text: no I/O and no
// graphics library, for quick looks and for documents.
// Plan coordinates [m]; the SVG is in pixels (pixels_per_metre).
// Stateless; safe from any thread.
#include <span>
#include <string>

#include "lshloc/sim/floor_plan.hpp"

namespace lshloc::sim {

struct SvgStyle {
  double pixels_per_metre = 10.0;  ///< drawing scale
  double margin = 1.0;             ///< [m] around the building
};

/// The plan's segments (walls black, pillars grey, furniture brown) with
/// `path` as a red polyline and its first pose as a blue dot; +y points up.
std::string floor_plan_svg(const FloorPlan& plan, std::span<const Pose2> path = {}, const SvgStyle& style = {});

}  // namespace lshloc::sim
