#include "lshloc/core/pose_grid_scorer.hpp"

#include <algorithm>

namespace lshloc {

namespace {
/// floor() to int for |v| < 2^31, branch-free and inlined (std::floor on
/// float is a library call without SSE4.1). Values beyond +-1e6 cells are
/// clamped first; pack() rejects them as outside the grid anyway.
inline std::int32_t floor_to_int(float v) {
  v = std::min(std::max(v, -1e6f), 1e6f);
  const auto i = static_cast<std::int32_t>(v);
  return i - static_cast<std::int32_t>(v < static_cast<float>(i));
}
}  // namespace

PoseGridScorer::PoseGridScorer(const PoseGridHashMap& grid, PoseGridScorerConfig config)
    : grid_(grid), config_(config) {
  value_[0] = config_.unknown;
  value_[cell_flags::kOccupied] = config_.hit;
  value_[cell_flags::kFree] = config_.free;
  value_[cell_flags::kOccupied | cell_flags::kFree] = config_.hit;  // a map point beats a ray through its cell
}

PoseGridScorer::PoseGridScorer(const PoseGridHashMap& grid, const PoseGridHashMap& free_space,
                               PoseGridScorerConfig config)
    : PoseGridScorer(grid, config) {
  free_space_ = &free_space;
}

void PoseGridScorer::score_free_space(const HypothesisBatch& v, float* scores) {
  const float inv = static_cast<float>(free_space_->inv_cell_size());
  std::size_t misses = 0;
  // Only the points that missed the map need the second grid.
  for (std::size_t j = 0; j < v.size; ++j) {
    if (flags_[j] & cell_flags::kOccupied) continue;
    keys_[misses] = PoseGridHashMap::pack(v.submap[j], floor_to_int(gx_[j] * inv), floor_to_int(gy_[j] * inv), 0);
    miss_index_[misses++] = static_cast<std::uint32_t>(j);
  }
  constexpr std::size_t kAhead = 16;
  for (std::size_t k = 0; k < std::min(kAhead, misses); ++k) free_space_->prefetch(keys_[k]);
  for (std::size_t k = 0; k < misses; ++k) {
    if (k + kAhead < misses) free_space_->prefetch(keys_[k + kAhead]);
    scores[miss_index_[k]] = free_space_->lookup_key(keys_[k]) == cell_flags::kFree ? config_.free : config_.unknown;
  }
  lookups_ += misses;
}

void PoseGridScorer::score_free_space_point(const LocalPoint& x, const HypothesisBatch& v, float* scores) {
  const std::size_t n = v.size;
  const float inv = static_cast<float>(free_space_->inv_cell_size());
  std::uint64_t* keys = keys_.data();
  for (std::size_t j = 0; j < n; ++j) {
    const float gx = v.tx[j] + v.cos[j] * x.x - v.sin[j] * x.y;
    const float gy = v.ty[j] + v.sin[j] * x.x + v.cos[j] * x.y;
    keys[j] = PoseGridHashMap::pack(v.submap[j], floor_to_int(gx * inv), floor_to_int(gy * inv), 0);
  }
  constexpr std::size_t kAhead = 16;
  for (std::size_t j = 0; j < std::min(kAhead, n); ++j) free_space_->prefetch(keys[j]);
  for (std::size_t j = 0; j < n; ++j) {
    if (j + kAhead < n) free_space_->prefetch(keys[j + kAhead]);
    // Only cells that map rays never crossed count as walls: people and doors
    // leave cells marked both occupied and free.
    scores[j] = free_space_->lookup_key(keys[j]) == cell_flags::kOccupied ? config_.ray_through_wall : 0.0f;
  }
  lookups_ += n;
}

PoseCell PoseGridScorer::cell_of(const LocalPoint& x, const HypothesisBatch& v, std::size_t j) const {
  const float inv = static_cast<float>(grid_.inv_cell_size());
  const float bpr = static_cast<float>(grid_.bins_per_radian());
  const std::int32_t bins = grid_.theta_bins();
  const float gx = v.tx[j] + v.cos[j] * x.x - v.sin[j] * x.y;
  const float gy = v.ty[j] + v.sin[j] * x.x + v.cos[j] * x.y;
  std::int32_t it = floor_to_int((v.theta[j] + x.theta) * bpr);
  it += it < 0 ? bins : 0;
  it -= it >= bins ? bins : 0;
  return {v.submap[j], floor_to_int(gx * inv), floor_to_int(gy * inv), it};
}

void PoseGridScorer::compute_keys(const HypothesisBatch& v, int dx, int dy, int dtheta, bool absolute_theta) {
  const std::size_t n = v.size;
  const std::int32_t bins = grid_.theta_bins();
  const std::int32_t* ix = ix_.data();
  const std::int32_t* iy = iy_.data();
  const std::int32_t* it = it_.data();
  std::uint64_t* keys = keys_.data();
  for (std::size_t j = 0; j < n; ++j) {
    std::int32_t t = absolute_theta ? dtheta : it[j] + dtheta;
    t += t < 0 ? bins : 0;
    t -= t >= bins ? bins : 0;
    keys[j] = PoseGridHashMap::pack(v.submap[j], ix[j] + dx, iy[j] + dy, t);
  }
}

void PoseGridScorer::operator()(const LocalPoint& x, const HypothesisBatch& v, float* scores) {
  const std::size_t n = v.size;
  if (keys_.size() < n) {
    keys_.resize(n), ix_.resize(n), iy_.resize(n), it_.resize(n), flags_.resize(n);
    if (free_space_) gx_.resize(n), gy_.resize(n), miss_index_.resize(n);
  }
  if (x.kind == LocalPoint::Kind::kFreeSpace) {
    if (free_space_) score_free_space_point(x, v, scores);
    else std::fill_n(scores, n, 0.0f);
    return;
  }
  // 1. Transform x by every hypothesis and compute its cell (vectorizable).
  {
    const float inv = static_cast<float>(grid_.inv_cell_size());
    const float bpr = static_cast<float>(grid_.bins_per_radian());
    const std::int32_t bins = grid_.theta_bins();
    const float px = x.x, py = x.y, pt = x.theta;
    std::int32_t* ix = ix_.data();
    std::int32_t* iy = iy_.data();
    std::int32_t* it = it_.data();
    for (std::size_t j = 0; j < n; ++j) {
      const float gx = v.tx[j] + v.cos[j] * px - v.sin[j] * py;
      const float gy = v.ty[j] + v.sin[j] * px + v.cos[j] * py;
      std::int32_t t = floor_to_int((v.theta[j] + pt) * bpr);
      t += t < 0 ? bins : 0;
      t -= t >= bins ? bins : 0;
      ix[j] = floor_to_int(gx * inv), iy[j] = floor_to_int(gy * inv), it[j] = t;
    }
    if (free_space_) {
      for (std::size_t j = 0; j < n; ++j) {
        gx_[j] = v.tx[j] + v.cos[j] * px - v.sin[j] * py;
        gy_[j] = v.ty[j] + v.sin[j] * px + v.cos[j] * py;
      }
    }
  }
  // 2. For each cell of the tolerance window (one cell unless the grid probes
  //    neighbours): pack the keys, then look them up, prefetching ahead.
  std::fill_n(flags_.data(), n, CellFlags{0});
  int xy = 0, dtheta_first = 0, dtheta_count = 1;
  bool absolute_theta = false;
  if (grid_.probes_neighbours()) {
    // The same window as PoseGridHashMap::probe(): bins it-u..it+u, or the
    // whole circle when that is no wider.
    const int u = grid_.config().theta_tolerance, bins = grid_.theta_bins();
    xy = grid_.config().xy_tolerance;
    if (2 * u + 1 >= bins) {
      absolute_theta = true, dtheta_first = 0, dtheta_count = bins;
    } else {
      dtheta_first = -u, dtheta_count = 2 * u + 1;
    }
  }
  constexpr std::size_t kAhead = 16;
  for (int dx = -xy; dx <= xy; ++dx)
    for (int dy = -xy; dy <= xy; ++dy)
      for (int k = 0; k < dtheta_count; ++k) {
        compute_keys(v, dx, dy, dtheta_first + k, absolute_theta);
        const std::uint64_t* keys = keys_.data();
        CellFlags* flags = flags_.data();
        for (std::size_t j = 0; j < std::min(kAhead, n); ++j) grid_.prefetch(keys[j]);
        for (std::size_t j = 0; j < n; ++j) {
          if (j + kAhead < n) grid_.prefetch(keys[j + kAhead]);
          flags[j] |= grid_.lookup_key(keys[j]);
        }
        lookups_ += n;
      }
  // 3. Flags to scores.
  const CellFlags* flags = flags_.data();
  for (std::size_t j = 0; j < n; ++j) scores[j] = value_[flags[j] & 3];
  if (free_space_) score_free_space(v, scores);
}

}  // namespace lshloc
