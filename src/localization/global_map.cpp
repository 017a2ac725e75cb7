#include "lshloc/localization/global_map.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>

#include "lshloc/common/error.hpp"
#include "lshloc/geometry/voxel_thinning.hpp"
#include "lshloc/geometry/line_fit.hpp"
#include "lshloc/common/cpu_time.hpp"

namespace lshloc {

void GlobalMapConfig::validate() const {
  features.validate();
  database.validate();
  occupancy.validate();
  free_space.validate();
  require(free_space.theta_bins == 1, "GlobalMapConfig.free_space.theta_bins", "1 (a 2-D grid)", free_space.theta_bins);
  require(free_space.xy_tolerance == 0, "GlobalMapConfig.free_space.xy_tolerance", "0 (exact cells)",
          free_space.xy_tolerance);
  require(endpoint_spacing >= 0.0, "GlobalMapConfig.endpoint_spacing", ">= 0 m", endpoint_spacing);
  require(free_ray_stride >= 1, "GlobalMapConfig.free_ray_stride", ">= 1 beam", free_ray_stride);
  require(free_ray_margin >= 0.0, "GlobalMapConfig.free_ray_margin", ">= 0 m", free_ray_margin);
  require(free_ray_max_range > 0.0, "GlobalMapConfig.free_ray_max_range", "> 0 m", free_ray_max_range);
  require(free_ray_no_return_range >= 0.0, "GlobalMapConfig.free_ray_no_return_range", ">= 0 m",
          free_ray_no_return_range);
  require(recent_keys <= (std::size_t{1} << 24), "GlobalMapConfig.recent_keys", "0..2^24 features", recent_keys);
}

double GlobalMapStats::bytes_per_feature() const {
  if (features == 0) return 0.0;
  const double bytes = static_cast<double>(database.bytes + occupancy.memory_bytes + free_space.memory_bytes +
                                           location_bytes + recent_key_bytes);
  return bytes / static_cast<double>(features);
}

GlobalMap::GlobalMap(GlobalMapConfig config)
    : config_((config.validate(), config)),
      extractor_(config_.features),
      database_(config_.database),
      occupancy_(config_.occupancy),
      free_space_(config_.free_space) {
  free_space_.track_pose_cells(config_.occupancy.cell_size);
}

std::uint32_t GlobalMap::add_submap(std::string name) {
  // The pose grids' cells hold a submap id of 14 bits, and a saved map names of at most kMaxSubmapNameBytes.
  if (submaps_.size() >= PoseGridHashMap::kMaxSubmaps)
    throw Error("GlobalMap::add_submap: the map holds " + std::to_string(submaps_.size()) +
                " submaps, as many as it can (" + std::to_string(PoseGridHashMap::kMaxSubmaps) + ")");
  if (name.size() > kMaxSubmapNameBytes)
    throw Error("GlobalMap::add_submap: a submap name of at most " + std::to_string(kMaxSubmapNameBytes) +
                " bytes expected, got " + std::to_string(name.size()));
  submaps_.push_back({std::move(name), ScanContext(config_.context_scans, config_.context_spacing), 0});
  return static_cast<std::uint32_t>(submaps_.size() - 1);
}

void GlobalMap::check_submap(std::uint32_t submap, const char* caller) const {
  if (submap >= submaps_.size()) {
    throw Error(std::string(caller) + ": unknown submap " + std::to_string(submap) + " (there are " +
                std::to_string(submaps_.size()) + ")");
  }
}

std::size_t GlobalMap::add_scan(std::uint32_t submap, const LaserScan& scan, const Pose2& laser_pose, ScanGrids grids,
                                std::vector<Feature>* added) {
  check_submap(submap, "GlobalMap::add_scan");
  SubmapState& state = submaps_[submap];

  // One CPU clock read per stage boundary: each is a system call.
  const double t0 = thread_cpu_seconds();
  const std::span<const Point2> directions = beam_directions_.of(scan);
  const ScanSurface surface = extractor_.surface(scan, laser_pose, directions);
  const std::vector<Feature> features = extractor_.extract(surface, state.context.surfaces());
  const double t1 = thread_cpu_seconds();

  // The grid marks are planned first: a scan beyond the grids' limits
  // throws here, before any of it enters the map.
  marking_scan_ = true;
  const std::unique_ptr<GlobalMap, void (*)(GlobalMap*)> end_scan(this, [](GlobalMap* m) {
    m->scan_marks_.stop();
    m->marking_scan_ = false;
    m->occupancy_plan_.clear();
    m->free_space_plan_.clear();
  });
  if (grids == ScanGrids::kMark) plan_grids(submap, scan, laser_pose, surface, directions);
  // So are the capacities: past one, a scan would enter the map in part (the journal relies on all or nothing).
  if (locations_.size() + features.size() >= std::numeric_limits<std::uint32_t>::max() ||
      !database_.has_room_for(features.size()) || !occupancy_.has_room_for(occupancy_plan_))
    throw Error("GlobalMap::add_scan: the map is full (2^32 features, database ids or pose-grid slots); scan " +
                std::to_string(state.scans) + " of submap " + std::to_string(submap) + " was not added");
  const double t2 = thread_cpu_seconds();
  for (const Feature& f : features) {
    const std::uint32_t id = locations_.append(submap, f.pose);
    database_.insert(f.descriptor, id);
    keep_recent_key(id);
  }
  const double t3 = thread_cpu_seconds();
  stats_.features += features.size();
  make_planned_marks();
  const double t4 = thread_cpu_seconds();
  stats_.extract_s += t1 - t0;
  stats_.grid_s += (t2 - t1) + (t4 - t3);
  stats_.database_insert_s += t3 - t2;
  ++state.scans;
  ++stats_.scans;
  if (grids == ScanGrids::kMark) scan_prints_.insert(scan_fingerprint(scan));
  state.context.offer(surface);
  if (added) added->insert(added->end(), features.begin(), features.end());
  return features.size();
}

void GlobalMap::keep_recent_key(std::uint32_t id) {
  const std::size_t ring = config_.recent_keys;
  if (ring == 0) return;
  const std::span<const std::uint32_t> tags = database_.last_insert_tags();
  const std::span<const std::uint64_t> sketch = database_.last_insert_sketch();
  if (recent_tags_.empty()) {
    recent_tags_.resize(ring * tags.size());
    recent_sketches_.resize(ring * sketch.size());
  }
  std::copy(tags.begin(), tags.end(), recent_tags_.begin() + static_cast<std::ptrdiff_t>((id % ring) * tags.size()));
  std::copy(sketch.begin(), sketch.end(),
            recent_sketches_.begin() + static_cast<std::ptrdiff_t>((id % ring) * sketch.size()));
}

void GlobalMap::set_query_settings(const LshConfig& asked) {
  database_.set_query_settings(asked);
  config_.database = database_.config();
}

std::optional<LshKeyView> GlobalMap::recent_key(std::uint32_t id) const {
  const std::size_t ring = config_.recent_keys, size = locations_.size();
  if (ring == 0 || recent_tags_.empty() || id < recent_first_ || id >= size || size - id > ring) return std::nullopt;
  const std::size_t L = config_.database.L;
  const std::size_t words = database_.last_insert_sketch().size();
  return LshKeyView{{recent_tags_.data() + (id % ring) * L, L}, {recent_sketches_.data() + (id % ring) * words, words}};
}

void GlobalMap::ScanMarks::start(std::int32_t cx, std::int32_t cy, std::int32_t half_width) {
  width_ = 2 * half_width + 1;
  x0_ = cx - half_width, y0_ = cy - half_width;
  const auto cells = static_cast<std::size_t>(width_) * static_cast<std::size_t>(width_);
  if (cells_.size() < cells || ++generation_ == (1u << 24)) {
    cells_.assign(std::max(cells, cells_.size()), 0);
    generation_ = 1;
  }
}

inline bool GlobalMap::ScanMarks::seen(std::int32_t ix, std::int32_t iy, CellFlags flags) {
  const auto dx = static_cast<std::uint32_t>(ix - x0_), dy = static_cast<std::uint32_t>(iy - y0_);
  const auto w = static_cast<std::uint32_t>(width_);
  if (dx >= w || dy >= w) return false;  // outside the window (or no scan started): mark it
  std::uint32_t& cell = cells_[static_cast<std::size_t>(dy) * w + dx];
  const std::uint32_t marked = (cell >> 8) == generation_ ? cell & 0xff : 0;
  if ((marked & flags) == flags) return true;
  cell = (generation_ << 8) | marked | flags;
  return false;
}

void GlobalMap::mark_free_space(std::uint32_t submap, const Point2& p, CellFlags flags) {
  if (!std::isfinite(p.x()) || !std::isfinite(p.y()))
    throw Error("GlobalMap: a non-finite point to mark in submap " + std::to_string(submap));
  const PoseCell c = free_space_.cell_of(submap, p.x(), p.y());
  if (scan_marks_.seen(c.ix, c.iy, flags)) return;
  free_space_.plan_mark(c, flags, free_space_plan_);
}

void GlobalMap::make_planned_marks() {
  occupancy_.mark_planned(occupancy_plan_);
  if (free_space_.tracks_pose_cells()) {
    std::uint64_t previous = PoseGridHashMap::kInvalidXy;  // a mark's heading bins come in a row
    for (const PoseGridHashMap::CellMark& m : occupancy_plan_.writes) {
      if (m.xy == previous) continue;
      previous = m.xy;
      const PoseCell c = PoseGridHashMap::unpack_xy(m.xy);
      free_space_.note_pose_cell(c.submap, c.ix, c.iy);
    }
  }
  free_space_.mark_planned(free_space_plan_);
  occupancy_plan_.clear();
  free_space_plan_.clear();
}

void GlobalMap::plan_grids(std::uint32_t submap, const LaserScan& scan, const Pose2& laser_pose,
                           const ScanSurface& surface, std::span<const Point2> directions) {
  const Point2 sensor = laser_pose.translation();
  // Every mark lies within the longest range (returns and their neighbours) of
  // the sensor; a window wider than 1025 cells is not worth clearing per scan.
  const PoseCell centre = free_space_.cell_of(submap, sensor.x(), sensor.y());
  const double longest = std::max(config_.features.max_range, config_.free_ray_max_range);
  scan_marks_.start(centre.ix, centre.iy,
                    static_cast<std::int32_t>(std::min(512.0, std::ceil(longest * free_space_.inv_cell_size()) + 2.0)));
  // Occupancy: endpoints with their normal direction, thinned along the scan;
  // the free-space grid notes where the map has a normal (kNormal).
  for_each_spaced(surface.points, config_.endpoint_spacing, position_of_surface_point, [&](const SurfacePoint& p) {
    mark_surface_point(submap, p.position, normal_angle_towards(p.position, p.tangent, sensor));
  });
  // Free space: cells the beams crossed, stopping short of the endpoint; the
  // endpoints' cells and their neighbours are marked occupied in the same 2-D
  // grid so that walls never read as free.
  const double step = config_.free_space.cell_size;
  const double c = std::cos(laser_pose.theta), s = std::sin(laser_pose.theta);
  // Every beam's endpoint in the laser frame, computed once for both passes.
  beam_endpoints_.resize(scan.size());
  for (std::size_t i = 0; i < scan.size(); ++i) beam_endpoints_[i] = scan.endpoint(i, directions[i]);
  const auto valid = [&](std::size_t i) { return i < scan.size() && scan.status(i) == BeamStatus::kValid; };
  for (std::size_t i = 0; i < scan.size(); i += config_.free_ray_stride) {
    const BeamStatus status = scan.status(i);
    if (status == BeamStatus::kInvalid) continue;
    const double r = scan.ranges[i];
    double reach = config_.free_ray_no_return_range;
    if (status == BeamStatus::kValid) {
      // A ray that meets its wall at a shallow angle runs beside it, within
      // a cell, for cell / sin(angle) before the endpoint: walls seen only
      // from far down a corridor would read as free between the sparse
      // endpoints. The angle comes from the neighbouring beams' endpoints
      // (the shallower side, as the wall may end at either).
      const Point2& p = beam_endpoints_[i];
      const Point2 ray = p / r;
      double sin_incidence = 1.0;
      for (const std::size_t j : {i - 1, i + 1}) {
        if (!valid(j)) continue;  // also i - 1 wrapped below 0
        const Point2 along = beam_endpoints_[j] - p;
        const double length = along.norm();
        if (length > 0.0) {
          sin_incidence = std::min(sin_incidence, std::abs(ray.x() * along.y() - ray.y() * along.x()) / length);
        }
      }
      const double margin = std::max(config_.free_ray_margin, step / std::max(sin_incidence, 1e-3));
      reach = r - margin;
    }
    reach = std::min(reach, config_.free_ray_max_range);
    const Point2& u = directions[i];  // cos and sin of the beam's bearing
    const double dx = c * u.x() - s * u.y(), dy = s * u.x() + c * u.y();
    for (double d = 0.0; d < reach; d += step)
      mark_free_space(submap, {sensor.x() + d * dx, sensor.y() + d * dy}, cell_flags::kFree);
  }
  // Every return (not only the smooth segments' points: sparse returns from
  // far walls are no segments) marks its cell and neighbours occupied, and
  // its own cell as holding a return: a local ray through the map's wall is
  // judged on those alone, as the neighbours of a wall seen only from far
  // away (never crossed by map rays) are often free space.
  for (std::size_t i = 0; i < scan.size(); ++i) {
    if (!valid(i) || scan.ranges[i] < config_.features.min_range || scan.ranges[i] >= config_.features.max_range)
      continue;
    plan_return(submap, laser_pose.transform(beam_endpoints_[i]));
  }
}

void GlobalMap::mark_surface_point(std::uint32_t submap, const Point2& p, double normal) {
  check_submap(submap, "GlobalMap::mark_surface_point");
  if (!std::isfinite(p.x()) || !std::isfinite(p.y()) || !std::isfinite(normal))
    throw Error("GlobalMap::mark_surface_point: a non-finite point or normal in submap " + std::to_string(submap));
  occupancy_.plan_mark(occupancy_.cell_of(submap, p.x(), p.y(), normal), cell_flags::kOccupied, occupancy_plan_);
  mark_free_space(submap, p, cell_flags::kNormal);
  if (!marking_scan_) make_planned_marks();
}

void GlobalMap::mark_return(std::uint32_t submap, const Point2& p) {
  check_submap(submap, "GlobalMap::mark_return");
  plan_return(submap, p);
  if (!marking_scan_) make_planned_marks();
}

void GlobalMap::plan_return(std::uint32_t submap, const Point2& p) {
  const double step = config_.free_space.cell_size;
  for (int ix = -1; ix <= 1; ++ix) {
    for (int iy = -1; iy <= 1; ++iy) {
      const bool own = ix == 0 && iy == 0;
      mark_free_space(submap, {p.x() + ix * step, p.y() + iy * step},
                      own ? cell_flags::kOccupied | cell_flags::kReturn : cell_flags::kOccupied);
    }
  }
}

void GlobalMap::mark_free(std::uint32_t submap, const Point2& p) {
  check_submap(submap, "GlobalMap::mark_free");
  mark_free_space(submap, p, cell_flags::kFree);
  if (!marking_scan_) make_planned_marks();
}

std::optional<std::uint32_t> GlobalMap::find_submap(std::string_view name) const {
  for (std::size_t i = 0; i < submaps_.size(); ++i)
    if (submaps_[i].name == name) return static_cast<std::uint32_t>(i);
  return std::nullopt;
}

const std::vector<std::string>& GlobalMap::snapshot_sections() {
  static const std::vector<std::string> names = {"submaps",    "locations", "database",   "occupancy",
                                                 "free_space", "counters",  "scan_prints"};
  return names;
}

std::vector<MapSection> GlobalMap::snapshot() const {
  std::vector<MapSection> out;
  for (const std::string& name : snapshot_sections()) {
    ByteWriter w;
    if (name == "submaps") {
      w.varint(submaps_.size());
      for (const SubmapState& s : submaps_) {
        w.string(s.name);
        w.varint(s.scans);
        s.context.write_snapshot(w);
      }
    } else if (name == "locations") {
      locations_.write_snapshot(w);
    } else if (name == "database") {
      database_.write_snapshot(w);
    } else if (name == "occupancy") {
      occupancy_.write_snapshot(w);
    } else if (name == "free_space") {
      free_space_.write_snapshot(w);
    } else if (name == "scan_prints") {
      // Sorted, as deltas: canonical whatever the set's layout.
      std::vector<std::uint64_t> prints(scan_prints_.begin(), scan_prints_.end());
      std::sort(prints.begin(), prints.end());
      w.varint(prints.size());
      std::uint64_t last = 0;
      for (const std::uint64_t p : prints) w.varint(p - last), last = p;
    } else {
      w.varint(stats_.scans);
      w.varint(stats_.features);
      w.f64(stats_.extract_s), w.f64(stats_.database_insert_s), w.f64(stats_.grid_s);
    }
    out.push_back({name, w.take()});
  }
  return out;
}

std::unique_ptr<GlobalMap> GlobalMap::from_snapshot(const GlobalMapConfig& config,
                                                    std::span<const MapSectionView> sections,
                                                    const std::string& source) {
  auto map = std::make_unique<GlobalMap>(config);
  for (const std::string& name : snapshot_sections()) {
    const MapSectionView* section = nullptr;
    for (const MapSectionView& s : sections)
      if (s.name == name) section = &s;
    if (section == nullptr && name == "scan_prints") {  // a file written before maps kept them
      map->scan_prints_complete_ = false;
      continue;
    }
    if (section == nullptr) throw Error(source + ": section " + name + " is missing");
    ByteReader in(section->bytes, source + ": section " + name);
    const auto submaps = static_cast<std::uint32_t>(map->submaps_.size());
    if (name == "submaps") {
      const auto count = in.varint_at_most(PoseGridHashMap::kMaxSubmaps, "a submap count");
      for (std::uint64_t i = 0; i < count; ++i) {
        const std::uint32_t id = map->add_submap(in.string(kMaxSubmapNameBytes));
        SubmapState& s = map->submaps_[id];
        s.scans = static_cast<std::size_t>(in.varint());
        s.context.read_snapshot(in);
      }
    } else if (name == "locations") {
      map->locations_.read_snapshot(in, submaps);
    } else if (name == "database") {
      map->database_.read_snapshot(in, map->locations_.size());
    } else if (name == "occupancy") {
      map->occupancy_.read_snapshot(in, submaps);
    } else if (name == "free_space") {
      map->free_space_.read_snapshot(in, submaps);
    } else if (name == "scan_prints") {
      const auto count = in.varint_at_most(map->stats_.scans, "a scan fingerprint count (at most one per scan)");
      map->scan_prints_.reserve(static_cast<std::size_t>(count));
      std::uint64_t last = 0;
      for (std::uint64_t i = 0; i < count; ++i) {
        const std::uint64_t delta = in.varint();
        if (i > 0 && delta == 0) in.fail("fingerprints in ascending order, each once");
        map->scan_prints_.insert(last += delta);
      }
    } else {
      map->stats_.scans = static_cast<std::size_t>(in.varint());
      map->stats_.features = static_cast<std::size_t>(in.varint());
      map->stats_.extract_s = in.f64(), map->stats_.database_insert_s = in.f64(), map->stats_.grid_s = in.f64();
      std::size_t scans = 0;
      for (const SubmapState& sub : map->submaps_) scans += sub.scans;
      if (map->stats_.scans != scans)
        in.fail(std::to_string(scans) + " scans (the submaps' sum), got " + std::to_string(map->stats_.scans));
      if (map->stats_.features != map->locations_.size())
        in.fail(std::to_string(map->locations_.size()) + " features (one per location), got " +
                std::to_string(map->stats_.features));
    }
    in.expect_done();
  }
  if (map->database_.size() != map->locations_.size())
    throw Error(source + ": section database holds " + std::to_string(map->database_.size()) +
                " entries; expected one per location (" + std::to_string(map->locations_.size()) + ")");
  if (map->free_space_.tracks_pose_cells())
    map->occupancy_.for_each_bin([&](std::uint32_t submap, std::int32_t ix, std::int32_t iy) {
      map->free_space_.note_pose_cell(submap, ix, iy);
    });
  map->recent_first_ = static_cast<std::uint32_t>(map->locations_.size());
  return map;
}

std::size_t GlobalMap::scans_held(std::span<const LaserScan> scans) const {
  std::size_t held = 0;
  for (const LaserScan& scan : scans) held += scan_prints_.count(scan_fingerprint(scan));
  return held;
}

GlobalMapStats GlobalMap::stats() const {
  GlobalMapStats s = stats_;
  s.submaps = submaps_.size();
  s.database = database_.stats();
  s.occupancy = occupancy_.stats();
  s.free_space = free_space_.stats();
  s.location_bytes = locations_.bytes();
  s.recent_key_bytes =
      recent_tags_.capacity() * sizeof(std::uint32_t) + recent_sketches_.capacity() * sizeof(std::uint64_t);
  return s;
}

}  // namespace lshloc
