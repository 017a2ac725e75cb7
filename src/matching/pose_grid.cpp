#include "lshloc/matching/pose_grid.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <random>
#include <string>

#include "lshloc/common/error.hpp"

namespace lshloc {

namespace {
constexpr double kTwoPi = 2.0 * std::numbers::pi;
}  // namespace

void PoseGridConfig::validate() const {
  require(cell_size > 0.0 && std::isfinite(cell_size), "PoseGridConfig.cell_size", "> 0 m", cell_size);
  require(theta_bins >= 1 && theta_bins <= 255, "PoseGridConfig.theta_bins", "1..255", theta_bins);
  require(xy_tolerance >= 0 && xy_tolerance <= 8, "PoseGridConfig.xy_tolerance", "0..8 cells", xy_tolerance);
  require(theta_tolerance >= 0 && theta_tolerance <= 8, "PoseGridConfig.theta_tolerance", "0..8 bins", theta_tolerance);
  require(max_load_factor > 0.05 && max_load_factor <= 0.9, "PoseGridConfig.max_load_factor",
          "in (0.05, 0.9] for linear probing", max_load_factor);
  require(initial_capacity >= 2 && initial_capacity <= (std::size_t{1} << 30), "PoseGridConfig.initial_capacity",
          "2..2^30 cells", initial_capacity);
}

PoseGridHashMap::PoseGridHashMap(PoseGridConfig config) : config_(config) {
  config_.validate();
  inv_cell_ = 1.0 / config_.cell_size;
  bins_per_rad_ = config_.theta_bins / kTwoPi;
  probe_neighbours_ = config_.tolerance_mode == ToleranceMode::kProbeNeighbours &&
                      (config_.xy_tolerance > 0 || (config_.theta_tolerance > 0 && config_.theta_bins > 1));
  contiguous_theta_ = probe_neighbours_ && config_.theta_tolerance > 0 && config_.theta_bins > 1;
  std::mt19937_64 rng(config_.seed);
  hash_a_ = rng() | 1u;  // odd multiplier: multiply-shift is universal only for odd a
  hash_b_ = rng();
  set_capacity(std::bit_ceil(config_.initial_capacity));
}

void PoseGridHashMap::throw_outside_grid(const char* who, const PoseCell& c, double cell_size) {
  throw Error(std::string(who) + ": cell (" + std::to_string(c.ix) + ", " + std::to_string(c.iy) + ") of submap " +
              std::to_string(c.submap) + " is outside the grid (submap < " + std::to_string(kMaxSubmaps) +
              ", |x|, |y| < " + std::to_string(kCoordBias) + " cells of " + std::to_string(cell_size) + " m)");
}

void PoseGridHashMap::set_capacity(std::size_t capacity) {
  slots_.assign(capacity, 0);
  grow_at_ = grow_threshold(config_.max_load_factor, capacity);
  mask_ = capacity - 1;
  shift_ = 64u - static_cast<unsigned>(std::countr_zero(capacity));
}

void PoseGridHashMap::mark(std::uint32_t submap, double x, double y, double theta, CellFlags flags) {
  if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(theta))
    throw Error("pose grid: mark() of a non-finite pose in submap " + std::to_string(submap));
  planned_.clear();
  plan_mark(cell_of(submap, x, y, theta), flags, planned_);
  mark_planned(planned_);
}

void PoseGridHashMap::plan_mark(const PoseCell& c, CellFlags flags, MarkPlan& plan) const {
  if (flags == 0) throw Error("pose grid: mark() needs non-zero flags");
  const int t = config_.xy_tolerance;
  if (pack_xy(c.submap, c.ix - t, c.iy - t) == kInvalidXy || pack_xy(c.submap, c.ix + t, c.iy + t) == kInvalidXy)
    throw_outside_grid("pose grid", c, config_.cell_size);
  plan.cells.push_back(c);
  std::vector<CellMark>& out = plan.writes;
  if (config_.tolerance_mode == ToleranceMode::kProbeNeighbours) {
    out.push_back({pack_xy(c.submap, c.ix, c.iy), c.itheta, flags});
    return;
  }
  const ThetaRuns w = theta_runs(c.itheta);
  for (int dx = -t; dx <= t; ++dx)
    for (int dy = -t; dy <= t; ++dy) {
      const std::uint64_t xy = pack_xy(c.submap, c.ix + dx, c.iy + dy);
      for (int r = 0; r < w.runs; ++r)
        for (int k = 0; k < w.count[r]; ++k) out.push_back({xy, w.first[r] + k, flags});
    }
}

void PoseGridHashMap::mark_planned(const MarkPlan& plan) {
  for (const PoseCell& c : plan.cells) {
    ++marks_;
    if (c.submap >= boxes_.size()) boxes_.resize(c.submap + 1);
    boxes_[c.submap].add(c.ix, c.iy);
  }
  // Far enough ahead that a slot's cache line arrives before its write, near
  // enough that the table rarely grows in between (a stale prefetch only wastes a load).
  constexpr std::size_t kAhead = 8;
  const std::span<const CellMark> marks = plan.writes;
  for (std::size_t i = 0; i < marks.size(); ++i) {
    if (i + kAhead < marks.size()) {
      const TableView table = table_view();
      table.prefetch(table.home(marks[i + kAhead].xy, marks[i + kAhead].itheta));
    }
    mark_cell(marks[i].xy, marks[i].itheta, marks[i].flags);
  }
}

void PoseGridHashMap::mark_cell(std::uint64_t xy, int itheta, CellFlags flags) {
  if (used_ + 1 > grow_at_) grow();
  const std::uint64_t tagged = (xy << 16) | (static_cast<std::uint64_t>(itheta) << 8);
  const TableView table = table_view();
  std::size_t i = table.home(xy, itheta);
  for (;;) {
    std::uint64_t& s = slots_[i];
    if ((s & 0xff) == 0) {
      s = tagged | flags;
      ++used_;
      return;
    }
    if ((s & ~std::uint64_t{0xff}) == tagged) {
      s |= flags;
      return;
    }
    i = (i + 1) & mask_;
  }
}

bool PoseGridHashMap::has_room_for(const MarkPlan& plan) const {
  return used_ + plan.writes.size() <= grow_threshold(config_.max_load_factor, std::size_t{1} << 32);
}

void PoseGridHashMap::grow() {
  if (slots_.size() >= (std::size_t{1} << 32))
    throw Error("pose grid: table would exceed 2^32 slots (32 GiB); use larger cells or fewer submaps");
  Slots old;
  old.swap(slots_);
  set_capacity(old.size() * 2);
  const TableView table = table_view();
  for (const std::uint64_t s : old) {
    if ((s & 0xff) == 0) continue;
    std::size_t i = table.home(s >> 16, static_cast<int>((s >> 8) & 0xff));
    while (slots_[i] != 0) i = (i + 1) & mask_;
    slots_[i] = s;
  }
  ++rehashes_;
}

CellFlags PoseGridHashMap::lookup(const PoseCell& cell) const {
  if (cell.itheta < 0 || cell.itheta >= config_.theta_bins) return 0;
  const std::uint64_t xy = pack_xy(cell.submap, cell.ix, cell.iy);
  const TableView table = table_view();
  return table.lookup_run(xy, table.home(xy, cell.itheta), cell.itheta, 1);
}

CellFlags PoseGridHashMap::probe(std::uint32_t submap, double x, double y, double theta) const {
  const PoseCell c = cell_of(submap, x, y, theta);
  if (!probe_neighbours_) return lookup(c);
  const int t = config_.xy_tolerance;
  const ThetaRuns w = theta_runs(c.itheta);
  const TableView table = table_view();
  CellFlags out = 0;
  for (int dx = -t; dx <= t; ++dx)
    for (int dy = -t; dy <= t; ++dy) {
      const std::uint64_t xy = pack_xy(submap, c.ix + dx, c.iy + dy);
      for (int r = 0; r < w.runs; ++r) out |= table.lookup_run(xy, table.home(xy, w.first[r]), w.first[r], w.count[r]);
    }
  return out;
}

void GridSnapshot::write(ByteWriter& out) const {
  out.u8(static_cast<std::uint8_t>(table_bits));
  out.varint(rehashes);
  out.varint(marks);
  out.varint(boxes.size());
  for (const CellBox& b : boxes) {
    for (const std::int32_t v : {b.x0, b.x1, b.y0, b.y1}) out.signed_varint(v);
  }
  out.varint(cells.size());
  std::uint64_t previous = 0;
  for (const std::uint64_t s : cells) {
    out.varint((s >> 8) - previous);
    previous = s >> 8;
    out.u8(static_cast<std::uint8_t>(s & 0xff));
  }
}

GridSnapshot GridSnapshot::read(ByteReader& in, const PoseGridConfig& config, int min_bits,
                                std::uint32_t submap_limit) {
  GridSnapshot g;
  g.table_bits = in.u8();
  if (g.table_bits < min_bits || g.table_bits > 32)
    in.fail("a table of 2^" + std::to_string(min_bits) + "..2^32 slots, got 2^" + std::to_string(g.table_bits));
  const std::size_t size = std::size_t{1} << g.table_bits;
  g.rehashes = static_cast<std::size_t>(in.varint_at_most(64, "a rehash count"));
  g.marks = static_cast<std::size_t>(in.varint());
  g.boxes.resize(static_cast<std::size_t>(in.varint_at_most(submap_limit, "a submap count")));
  for (CellBox& b : g.boxes) {
    for (std::int32_t* v : {&b.x0, &b.x1, &b.y0, &b.y1}) {
      const std::int64_t value = in.signed_varint();
      if (value < -PoseGridHashMap::kCoordBias || value >= PoseGridHashMap::kCoordBias)
        in.fail("a cell index within +-65536");
      *v = static_cast<std::int32_t>(value);
    }
  }
  const auto max_cells = static_cast<std::size_t>(config.max_load_factor * static_cast<double>(size));
  const auto count = static_cast<std::size_t>(
      in.varint_at_most(std::min(max_cells, in.remaining() / 2), "a cell count within the load bound"));
  // A grown table holds more than max_load / 2 of its capacity: a corrupt
  // size must not allocate gigabytes.
  if (g.table_bits > min_bits &&
      static_cast<double>(count) < 0.5 * config.max_load_factor * static_cast<double>(size) - 1.0)
    in.fail("a table grown only past its load bound (" + std::to_string(count) + " cells in 2^" +
            std::to_string(g.table_bits) + " slots)");
  g.cells.reserve(count);
  std::uint64_t key = 0;
  for (std::size_t n = 0; n < count; ++n) {
    const std::uint64_t step = in.varint();
    if (n > 0 && step == 0) in.fail("cells in ascending order");
    key += step;
    const CellFlags flags = in.u8();
    if (key >= (std::uint64_t{1} << 56) || (key >> 42) >= std::min(submap_limit, PoseGridHashMap::kMaxSubmaps) ||
        static_cast<int>(key & 0xff) >= config.theta_bins || flags == 0)
      in.fail("a cell of a known submap with a heading bin below " + std::to_string(config.theta_bins) +
              " and non-zero flags");
    g.cells.push_back((key << 8) | flags);
  }
  return g;
}

void PoseGridHashMap::write_snapshot(ByteWriter& out) const {
  GridSnapshot g{std::countr_zero(slots_.size()), rehashes_, marks_, boxes_, {}};
  g.cells.reserve(used_);
  for (const std::uint64_t s : slots_)
    if ((s & 0xff) != 0) g.cells.push_back(s);
  std::sort(g.cells.begin(), g.cells.end());
  g.write(out);
}

void PoseGridHashMap::read_snapshot(ByteReader& in, std::uint32_t submap_limit) {
  if (used_ != 0 || marks_ != 0) throw Error("PoseGridHashMap::read_snapshot: the grid is not empty");
  GridSnapshot g = GridSnapshot::read(in, config_, std::countr_zero(slots_.size()), submap_limit);
  rehashes_ = g.rehashes;
  marks_ = g.marks;
  boxes_ = std::move(g.boxes);
  set_capacity(std::size_t{1} << g.table_bits);
  const TableView table = table_view();
  for (const std::uint64_t s : g.cells) {
    std::size_t i = table.home(s >> 16, static_cast<int>((s >> 8) & 0xff));
    while (slots_[i] != 0) i = (i + 1) & mask_;
    slots_[i] = s;
  }
  used_ = g.cells.size();
}

PoseGridStats grid_stats(std::size_t bins_used, std::size_t capacity, std::size_t memory_bytes, std::size_t marks,
                         std::size_t rehashes, std::span<const CellBox> boxes, int theta_bins) {
  PoseGridStats s;
  s.bins_used = bins_used;
  s.capacity = capacity;
  s.load = static_cast<double>(bins_used) / static_cast<double>(capacity);
  s.rehashes = rehashes;
  s.memory_bytes = memory_bytes;
  s.marks = marks;
  for (const CellBox& b : boxes) {
    s.submaps += b.empty() ? 0 : 1;
    s.dense_cells += b.cells() * static_cast<double>(theta_bins);
  }
  if (s.dense_cells > 0.0) {
    s.grid_fraction = static_cast<double>(s.bins_used) / s.dense_cells;
    s.table_fraction = static_cast<double>(s.capacity) / s.dense_cells;
  }
  return s;
}

PoseGridStats PoseGridHashMap::stats() const {
  return grid_stats(used_, slots_.size(), slots_.size() * sizeof(std::uint64_t), marks_, rehashes_, boxes_,
                    config_.theta_bins);
}

}  // namespace lshloc
