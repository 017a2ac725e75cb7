#include "lshloc/appearance/feature_extractor.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>

#include <Eigen/Eigenvalues>

#include "lshloc/common/error.hpp"
#include "lshloc/geometry/fast_atan2.hpp"
#include "lshloc/geometry/line_fit.hpp"

namespace lshloc {

namespace {

constexpr double kPi = std::numbers::pi;

/// Index of the last point of segment `seg` plus one.
std::size_t segment_end(const ScanSurface& s, std::size_t seg) {
  return seg + 1 < s.segment_begin.size() ? s.segment_begin[seg + 1] : s.points.size();
}

/// Points per run in PointRuns: consecutive points lie close along the scan,
/// so a run's box is small and most runs lie wholly outside a descriptor disc.
constexpr std::size_t kRunPoints = 16;

}  // namespace

ScanSurface transformed(const ScanSurface& surface, const Pose2& T_new_old) {
  ScanSurface out = surface;
  out.sensor_pose = T_new_old * surface.sensor_pose;
  for (SurfacePoint& p : out.points) {
    p.position = T_new_old.transform(p.position);
    p.set_tangent(T_new_old.transform_angle(p.tangent));
  }
  return out;
}

void FeatureExtractorConfig::validate() const {
  require(min_range >= 0.0 && max_range > min_range, "FeatureExtractorConfig.max_range", "0 <= min_range < max_range",
          max_range);
  require(segment_gap > 0.0 && segment_gap_per_meter >= 0.0, "FeatureExtractorConfig.segment_gap",
          "> 0 (per metre >= 0)", segment_gap);
  require(min_segment_points >= 2, "FeatureExtractorConfig.min_segment_points", ">= 2", min_segment_points);
  require(tangent_half_window > 0.0, "FeatureExtractorConfig.tangent_half_window", "> 0 m", tangent_half_window);
  require(max_keypoints >= 1, "FeatureExtractorConfig.max_keypoints", ">= 1", max_keypoints);
  require(keypoint_spacing > 0.0, "FeatureExtractorConfig.keypoint_spacing", "> 0 m", keypoint_spacing);
  require(keypoint_max_range > 0.0, "FeatureExtractorConfig.keypoint_max_range", "> 0 m", keypoint_max_range);
  require(normal_half_window > 0.0, "FeatureExtractorConfig.normal_half_window", "> 0 m", normal_half_window);
  require(max_normal_residual > 0.0, "FeatureExtractorConfig.max_normal_residual", "> 0 m", max_normal_residual);
  require(edge_margin >= 0.0, "FeatureExtractorConfig.edge_margin", ">= 0 m", edge_margin);
  require(descriptor_radius > 0.0, "FeatureExtractorConfig.descriptor_radius", "> 0 m", descriptor_radius);
  require(descriptor_inner_radius > 0.0 && descriptor_inner_radius < descriptor_radius,
          "FeatureExtractorConfig.descriptor_inner_radius", "in (0, descriptor_radius)", descriptor_inner_radius);
  require(rings >= 2 && sectors >= 2 && rings * sectors * (occupancy_component ? 3 : 2) == kDescriptorSize,
          "FeatureExtractorConfig.rings/sectors",
          "rings x sectors x components (2, or 3 with occupancy_component) = 120, at least 2 each");
  require(rim_taper >= 0.0 && rim_taper <= 1.0, "FeatureExtractorConfig.rim_taper", "in [0, 1]", rim_taper);
  require(bin_power > 0.0 && bin_power <= 1.0, "FeatureExtractorConfig.bin_power", "in (0, 1]", bin_power);
  require(min_descriptor_support >= 0.0, "FeatureExtractorConfig.min_descriptor_support", ">= 0 m",
          min_descriptor_support);
}

FeatureExtractor::FeatureExtractor(FeatureExtractorConfig config) : config_(config) { config_.validate(); }

ScanSurface FeatureExtractor::surface(const LaserScan& scan, const Pose2& laser_pose_map,
                                      std::span<const Point2> directions) const {
  std::vector<Point2> pts;
  scan.endpoints(pts, config_.min_range, config_.max_range, directions);
  laser_pose_map.transform(pts, pts);
  return surface(pts, laser_pose_map);
}

ScanSurface FeatureExtractor::surface(std::span<const Point2> points_map, const Pose2& sensor_pose) const {
  ScanSurface out;
  out.sensor_pose = sensor_pose;
  out.points.reserve(points_map.size());
  out.range.reserve(points_map.size());
  const Point2 sensor = sensor_pose.translation();

  // 1. Keep usable points and cut the beam-ordered sequence where consecutive
  // endpoints jump (occlusion edges, gaps); the allowed step grows with range.
  std::vector<std::size_t> raw_begin;
  std::vector<Point2> kept;
  std::vector<double> kept_range;
  for (const Point2& p : points_map) {
    if (!p.allFinite()) continue;
    const double r = (p - sensor).norm();
    if (r < config_.min_range || r >= config_.max_range) continue;
    const bool new_segment =
        kept.empty() ||
        (p - kept.back()).norm() > config_.segment_gap + config_.segment_gap_per_meter * std::max(r, kept_range.back());
    if (new_segment) raw_begin.push_back(kept.size());
    kept.push_back(p);
    kept_range.push_back(r);
  }

  // 2. Per segment long enough: arc-length weights and tangents.
  std::vector<double> arc;
  for (std::size_t k = 0; k < raw_begin.size(); ++k) {
    const std::size_t b = raw_begin[k], e = k + 1 < raw_begin.size() ? raw_begin[k + 1] : kept.size();
    if (e - b < config_.min_segment_points) continue;
    const std::size_t n = e - b;
    if (n == 0) continue;  // (a caller-built surface may repeat a segment start)
    arc.assign(n, 0.0);
    for (std::size_t j = 1; j < n; ++j) arc[j] = arc[j - 1] + (kept[b + j] - kept[b + j - 1]).norm();
    out.segment_begin.push_back(out.points.size());
    // Tangent from the points about tangent_half_window away on each side
    // (the 1 cm range quantization makes neighbouring beams useless for it).
    std::size_t lo = 0, hi = 0;
    for (std::size_t j = 0; j < n; ++j) {
      while (arc[j] - arc[lo] > config_.tangent_half_window) ++lo;
      while (hi + 1 < n && arc[hi + 1] - arc[j] <= config_.tangent_half_window) ++hi;
      std::size_t a = lo, c = hi;
      if (a == c) a = j > 0 ? j - 1 : j, c = j + 1 < n ? j + 1 : j;
      const Point2 d = kept[b + c] - kept[b + a];
      const double before = j > 0 ? arc[j] - arc[j - 1] : 0.0;
      const double after = j + 1 < n ? arc[j + 1] - arc[j] : 0.0;
      SurfacePoint sp;
      sp.position = kept[b + j];
      sp.set_tangent(std::atan2(d.y(), d.x()));
      sp.weight = 0.5 * (before + after);
      out.points.push_back(sp);
      out.range.push_back(kept_range[b + j]);
    }
  }
  return out;
}

FeatureExtractor::PointRuns FeatureExtractor::point_runs(const ScanSurface& surface) {
  PointRuns out;
  out.reserve((surface.points.size() + kRunPoints - 1) / kRunPoints);
  for (std::size_t b = 0; b < surface.points.size(); b += kRunPoints) {
    RunBox box{std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity(),
               std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity()};
    for (std::size_t i = b; i < std::min(b + kRunPoints, surface.points.size()); ++i) {
      const Point2& p = surface.points[i].position;
      box.x0 = std::min(box.x0, p.x()), box.x1 = std::max(box.x1, p.x());
      box.y0 = std::min(box.y0, p.y()), box.y1 = std::max(box.y1, p.y());
    }
    out.push_back(box);
  }
  return out;
}

FeatureExtractor::Support FeatureExtractor::describe(const Pose2& keypoint, const ScanSurface& scan,
                                                     std::span<const ScanSurface> context, Descriptor& out) const {
  std::vector<PointRuns> runs;
  runs.reserve(1 + context.size());
  runs.push_back(point_runs(scan));
  for (const ScanSurface& ctx : context) runs.push_back(point_runs(ctx));
  return describe(keypoint, scan, context, runs, out);
}

namespace {

// What describe() and support() share: the disc's constants for one keypoint
// and the weight of one surface point in it, in one place so that both sum
// bit for bit the same support.
struct Disc {
  double radius, radius2, taper_width, c2, s2;
  Disc(const FeatureExtractorConfig& config, double theta)
      : radius(config.descriptor_radius),
        radius2(radius * radius),
        taper_width(std::max(config.rim_taper * radius, 1e-9)),
        c2(std::cos(2.0 * theta)),
        s2(std::sin(2.0 * theta)) {}
  /// The point's weight (its arc length, tapered towards the rim) and that
  /// weight times cos 2(t - theta), from its distance r to the keypoint.
  std::pair<double, double> weights(const SurfacePoint& sp, double r) const {
    const double taper = std::min(1.0, (radius - r) / taper_width);
    const double weight = sp.weight * taper;
    return {weight, (sp.cos2t * c2 + sp.sin2t * s2) * weight};
  }
};

}  // namespace

template <class Visit>
void FeatureExtractor::for_each_point_near(const Pose2& keypoint, const ScanSurface& scan,
                                           std::span<const ScanSurface> context, std::span<const PointRuns> runs,
                                           Visit&& visit) const {
  const double radius = config_.descriptor_radius;
  // A run is skipped only when its box lies beyond the disc by a margin far
  // above rounding: every point it holds would fail the caller's d2 test.
  const double skip2 = (radius + 1e-6) * (radius + 1e-6);
  auto visit_surface = [&](const ScanSurface& surf, const PointRuns& boxes) {
    for (std::size_t run = 0; run < boxes.size(); ++run) {
      const RunBox& box = boxes[run];
      const double bx = std::max({box.x0 - keypoint.x, 0.0, keypoint.x - box.x1});
      const double by = std::max({box.y0 - keypoint.y, 0.0, keypoint.y - box.y1});
      if (bx * bx + by * by > skip2) continue;
      const std::size_t end = std::min((run + 1) * kRunPoints, surf.points.size());
      for (std::size_t i = run * kRunPoints; i < end; ++i) visit(surf.points[i]);
    }
  };
  visit_surface(scan, runs[0]);
  for (std::size_t k = 0; k < context.size(); ++k) visit_surface(context[k], runs[1 + k]);
}

FeatureExtractor::Support FeatureExtractor::support(const Pose2& keypoint, const ScanSurface& scan,
                                                    std::span<const ScanSurface> context,
                                                    std::span<const PointRuns> runs) const {
  const Disc disc(config_, keypoint.theta);
  Support support;
  for_each_point_near(keypoint, scan, context, runs, [&](const SurfacePoint& sp) {
    const double dx = sp.position.x() - keypoint.x, dy = sp.position.y() - keypoint.y;
    const double d2 = dx * dx + dy * dy;
    if (d2 >= disc.radius2) return;
    const auto [weight, comp_c] = disc.weights(sp, std::sqrt(d2));
    support.surface += weight;
    support.across += 0.5 * (weight + comp_c);
  });
  return support;
}

FeatureExtractor::Support FeatureExtractor::describe(const Pose2& keypoint, const ScanSurface& scan,
                                                     std::span<const ScanSurface> context,
                                                     std::span<const PointRuns> runs, Descriptor& out) const {
  const Disc disc(config_, keypoint.theta);
  const double inner = config_.descriptor_inner_radius;
  const double log_span = std::log(disc.radius / inner);
  const double c = std::cos(keypoint.theta), s = std::sin(keypoint.theta);
  const int kRings = static_cast<int>(config_.rings), kSectors = static_cast<int>(config_.sectors);
  const bool occupancy = config_.occupancy_component;
  const std::size_t comps = occupancy ? 3 : 2;
  std::array<double, kDescriptorSize> hist{};
  Support support;

  for_each_point_near(keypoint, scan, context, runs, [&](const SurfacePoint& sp) {
    const double dx = sp.position.x() - keypoint.x, dy = sp.position.y() - keypoint.y;
    const double d2 = dx * dx + dy * dy;
    if (d2 >= disc.radius2) return;
    const double lx = c * dx + s * dy, ly = -s * dx + c * dy;
    const double r = std::sqrt(d2);
    // Continuous ring coordinate: [0, 1) inside `inner`, then log-spaced up to kRings.
    const double u = r < inner ? r / inner : 1.0 + (kRings - 1) * std::log(r / inner) / log_span;
    const double v = (fast_atan2(ly, lx) + kPi) / (2.0 * kPi) * kSectors;
    // Soft binning between the two nearest bin centres in each dimension, so
    // a point near a bin edge does not flip the descriptor.
    const double uc = std::clamp(u - 0.5, 0.0, kRings - 1.0);
    const int r0 = std::min(static_cast<int>(uc), kRings - 2);
    const double fr = uc - r0;
    const double vc = v - 0.5;
    const double vf = std::floor(vc);
    const double fa = vc - vf;
    // vf lies in [-1, kSectors - 1]: wrap without integer division (the hot loop's costliest step).
    int a0 = static_cast<int>(vf);
    if (a0 < 0) a0 += kSectors;
    if (a0 >= kSectors) a0 -= kSectors;
    const int a1 = a0 + 1 == kSectors ? 0 : a0 + 1;
    // Tangent relative to the keypoint normal, doubled: cos/sin(2(t - theta)).
    const auto [weight, comp_c] = disc.weights(sp, r);
    const double comp_s = (sp.sin2t * disc.c2 - sp.cos2t * disc.s2) * weight;
    const std::array<std::pair<int, double>, 4> bins{{{r0 * kSectors + a0, (1 - fr) * (1 - fa)},
                                                      {r0 * kSectors + a1, (1 - fr) * fa},
                                                      {(r0 + 1) * kSectors + a0, fr * (1 - fa)},
                                                      {(r0 + 1) * kSectors + a1, fr * fa}}};
    for (const auto& [bin, w] : bins) {
      double* h = &hist[comps * static_cast<std::size_t>(bin)];
      if (occupancy) *h++ += w * weight;
      h[0] += w * comp_c;
      h[1] += w * comp_s;
    }
    support.surface += weight;
    // comp_c / weight = cos 2(t - theta): -1 along the keypoint's wall, +1 across it.
    support.across += 0.5 * (weight + comp_c);
  });

  if (config_.bin_power != 1.0)
    for (std::size_t i = 0; i < kDescriptorSize; i += comps) {
      double len2 = 0.0;
      for (std::size_t j = i; j < i + comps; ++j) len2 += hist[j] * hist[j];
      if (len2 <= 0.0) continue;
      const double scale = std::pow(len2, 0.5 * (config_.bin_power - 1.0));
      for (std::size_t j = i; j < i + comps; ++j) hist[j] *= scale;
    }
  double norm2 = 0.0;
  for (double h : hist) norm2 += h * h;
  const double inv = norm2 > 0.0 ? 1.0 / std::sqrt(norm2) : 0.0;
  for (std::size_t i = 0; i < kDescriptorSize; ++i) out[i] = static_cast<float>(hist[i] * inv);
  return support;
}

std::vector<Feature> FeatureExtractor::extract(const ScanSurface& scan, std::span<const ScanSurface> context) {
  ++stats_.scans;
  stats_.segments += scan.segment_begin.size();
  const Point2 sensor = scan.sensor_pose.translation();
  std::vector<Pose2> candidates;
  std::vector<double> structure;  // Support::across per candidate
  std::vector<double> arc;
  std::vector<PointRuns> runs;
  runs.reserve(1 + context.size());
  runs.push_back(point_runs(scan));
  for (const ScanSurface& ctx : context) runs.push_back(point_runs(ctx));
  for (std::size_t seg = 0; seg < scan.segment_begin.size(); ++seg) {
    const std::size_t b = scan.segment_begin[seg], e = segment_end(scan, seg), n = e - b;
    arc.assign(n, 0.0);
    for (std::size_t j = 1; j < n; ++j)
      arc[j] = arc[j - 1] + (scan.points[b + j].position - scan.points[b + j - 1].position).norm();
    const double usable = arc[n - 1] - 2.0 * config_.edge_margin;
    if (usable < 0.0) continue;
    // Keypoints at fixed spacing, centred on the segment.
    const auto count = static_cast<std::size_t>(std::floor(usable / config_.keypoint_spacing)) + 1;
    const double first =
        config_.edge_margin + 0.5 * (usable - static_cast<double>(count - 1) * config_.keypoint_spacing);
    std::size_t lo = 0;
    for (std::size_t k = 0; k < count; ++k) {
      ++stats_.candidates;
      const double at = first + static_cast<double>(k) * config_.keypoint_spacing;
      // Fit a line to the points within normal_half_window of arc length.
      while (lo < n && arc[lo] < at - config_.normal_half_window) ++lo;
      Point2 mean = Point2::Zero();
      std::size_t m = 0;
      for (std::size_t j = lo; j < n && arc[j] <= at + config_.normal_half_window; ++j, ++m)
        mean += scan.points[b + j].position;
      if (m < 3) {
        ++stats_.rejected_rough;
        continue;
      }
      mean /= static_cast<double>(m);
      Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
      for (std::size_t j = lo; j < lo + m; ++j) {
        const Point2 d = scan.points[b + j].position - mean;
        cov += d * d.transpose();
      }
      cov /= static_cast<double>(m);
      const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(cov);
      if (std::sqrt(std::max(eig.eigenvalues()(0), 0.0)) > config_.max_normal_residual) {
        ++stats_.rejected_rough;
        continue;
      }
      const Point2 axis = eig.eigenvectors().col(0);
      const Point2 tangent = eig.eigenvectors().col(1);
      // The keypoint: the point at arc length `at`, projected onto the fitted line.
      std::size_t j1 = lo;
      while (j1 + 1 < n && arc[j1 + 1] < at) ++j1;
      const std::size_t j2 = std::min(j1 + 1, n - 1);
      const double t = arc[j2] > arc[j1] ? std::clamp((at - arc[j1]) / (arc[j2] - arc[j1]), 0.0, 1.0) : 0.0;
      const Point2 on_scan = (1.0 - t) * scan.points[b + j1].position + t * scan.points[b + j2].position;
      const Point2 position = mean + tangent * tangent.dot(on_scan - mean);
      if ((position - sensor).norm() > config_.keypoint_max_range) continue;
      const Point2 normal = facing(axis, sensor, position);  // the side the sensor saw
      const Pose2 keypoint(position.x(), position.y(), std::atan2(normal.y(), normal.x()));
      const Support s = support(keypoint, scan, context, runs);
      if (s.surface < config_.min_descriptor_support) {
        ++stats_.rejected_support;
        continue;
      }
      candidates.push_back(keypoint);
      structure.push_back(s.across);
    }
  }
  // Too many: keep the most structured ones (most surface across the
  // keypoint's own wall inside the disc: corners, doors, openings), in scan
  // order (deterministic and independent of the frame). Only those kept are
  // described: the histogram's atan2 and log per point cost the most.
  std::vector<std::size_t> order(candidates.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  if (candidates.size() > config_.max_keypoints) {
    std::stable_sort(order.begin(), order.end(),
                     [&](std::size_t a, std::size_t b) { return structure[a] > structure[b]; });
    order.resize(config_.max_keypoints);
    std::sort(order.begin(), order.end());
  }
  std::vector<Feature> out(order.size());
  for (std::size_t k = 0; k < order.size(); ++k) {
    out[k].pose = candidates[order[k]];
    describe(out[k].pose, scan, context, runs, out[k].descriptor);
  }
  stats_.features += out.size();
  return out;
}

void ScanContext::offer(const ScanSurface& surface) {
  if (!surfaces_.empty() && translation_distance(last_pose_, surface.sensor_pose) < spacing_ &&
      angle_distance(last_pose_.theta, surface.sensor_pose.theta) < min_turn_)
    return;
  surfaces_.push_back(surface);
  last_pose_ = surface.sensor_pose;
  if (surfaces_.size() > scans_) surfaces_.erase(surfaces_.begin());
}

std::vector<ScanSurface> ScanContext::near(const Pose2& sensor, double max_distance) const {
  std::vector<ScanSurface> out;
  for (const ScanSurface& s : surfaces_) {
    if (translation_distance(s.sensor_pose, sensor) <= max_distance) out.push_back(s);
  }
  return out;
}

void ScanContext::write_snapshot(ByteWriter& out) const {
  out.varint(surfaces_.size());
  for (const ScanSurface& s : surfaces_) {
    for (const double v : {s.sensor_pose.x, s.sensor_pose.y, s.sensor_pose.theta}) out.f64(v);
    out.varint(s.points.size());
    for (const SurfacePoint& p : s.points) {
      for (const double v : {p.position.x(), p.position.y(), p.tangent, p.weight, p.cos2t, p.sin2t}) out.f64(v);
    }
    for (const double r : s.range) out.f64(r);
    out.varint(s.segment_begin.size());
    for (const std::size_t b : s.segment_begin) out.varint(b);
  }
}

void ScanContext::read_snapshot(ByteReader& in) {
  if (!surfaces_.empty()) throw Error("ScanContext::read_snapshot: the context is not empty");
  const auto count = static_cast<std::size_t>(
      in.varint_at_most(std::min<std::size_t>(scans_, in.remaining() / 32), "a count of context scans"));
  surfaces_.resize(count);
  for (ScanSurface& s : surfaces_) {
    s.sensor_pose = {in.f64(), in.f64(), in.f64()};
    const auto points = static_cast<std::size_t>(in.varint_at_most(in.remaining() / 56, "a count of surface points"));
    s.points.resize(points);
    for (SurfacePoint& p : s.points) {
      p.position = {in.f64(), in.f64()};
      p.tangent = in.f64(), p.weight = in.f64(), p.cos2t = in.f64(), p.sin2t = in.f64();
    }
    s.range.resize(points);
    for (double& r : s.range) r = in.f64();
    const auto segments = static_cast<std::size_t>(in.varint_at_most(points, "a count of segments"));
    s.segment_begin.resize(segments);
    std::size_t previous = 0;
    for (std::size_t& b : s.segment_begin) {
      b = static_cast<std::size_t>(in.varint_at_most(points, "a segment start within the points"));
      if (b < previous) in.fail("segment starts in ascending order");
      previous = b;
    }
  }
  if (!surfaces_.empty()) last_pose_ = surfaces_.back().sensor_pose;
}

}  // namespace lshloc
