#include "lshloc/matching/pose_grid_scorer.hpp"

#include "lshloc/common/error.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace lshloc {

namespace {
/// Lookups are prefetched this many hypotheses ahead, far enough to cover a
/// DRAM miss (the distance was measured: BENCHMARKS.md, speed-ups).
constexpr std::size_t kAhead = 40;

/// A cell of the free-space grid is a map wall when it holds a map return
/// that map rays never crossed: people and doors leave cells marked both
/// occupied and free, and a dilated neighbour of a wall is where the target's
/// rays along that wall pass (a corridor the map saw only from far away:
/// RESULTS.md).
constexpr CellFlags kWallBits = cell_flags::kReturn | cell_flags::kFree;
/// ... free space when map rays crossed it and no return nor its dilation
/// marked it occupied ...
constexpr CellFlags kFreeBits = cell_flags::kOccupied | cell_flags::kFree;
/// ... and a bare return when it is a wall without a map surface normal.
constexpr CellFlags kBareReturnBits = kWallBits | cell_flags::kNormal;

/// floor() to int for |v| < 2^31, branch-free and inlined (std::floor on
/// float is a library call without SSE4.1). Values beyond +-1e6 cells are
/// clamped first; pack_xy() rejects them as outside the grid anyway.
inline std::int32_t floor_to_int(float v) {
  v = v < -1e6f ? -1e6f : v;  // (not std::min/max: these compile to minss/maxss)
  v = v <= 1e6f ? v : 1e6f;   // NaN too, as floor_to_int4 does
  const auto i = static_cast<std::int32_t>(v);
  return i - static_cast<std::int32_t>(v < static_cast<float>(i));
}

#if defined(__SSE2__)
/// floor_to_int() of four floats (NaN, like +1e6, becomes 1e6: outside the grid).
inline __m128i floor_to_int4(__m128 v) {
  v = _mm_max_ps(_mm_min_ps(v, _mm_set1_ps(1e6f)), _mm_set1_ps(-1e6f));
  const __m128i i = _mm_cvttps_epi32(v);
  // v < float(i) only where truncation rounded up (negative non-integers): -1 there.
  return _mm_add_epi32(i, _mm_castps_si128(_mm_cmplt_ps(v, _mm_cvtepi32_ps(i))));
}
#endif
}  // namespace

/// The local point of hypothesis j: one for the whole batch (operator()) ...
struct PoseGridScorer::OnePoint {
  float px, py, pt;
  float x(std::size_t) const { return px; }
  float y(std::size_t) const { return py; }
  float theta(std::size_t) const { return pt; }
#if defined(__SSE2__)
  __m128 x4(std::size_t) const { return _mm_set1_ps(px); }
  __m128 y4(std::size_t) const { return _mm_set1_ps(py); }
  __m128 theta4(std::size_t) const { return _mm_set1_ps(pt); }
#endif
};

/// ... or one each (score_pairs()).
struct PoseGridScorer::PointEach {
  const float* __restrict px;
  const float* __restrict py;
  const float* __restrict pt;
  float x(std::size_t j) const { return px[j]; }
  float y(std::size_t j) const { return py[j]; }
  float theta(std::size_t j) const { return pt[j]; }
#if defined(__SSE2__)
  __m128 x4(std::size_t j) const { return _mm_loadu_ps(px + j); }
  __m128 y4(std::size_t j) const { return _mm_loadu_ps(py + j); }
  __m128 theta4(std::size_t j) const { return _mm_loadu_ps(pt + j); }
#endif
};

void PoseGridScorerConfig::validate() const {
  // (Full names: a scorer is made per duel, and the check should cost no allocation.)
  for (const auto& [name, v] : {std::pair{"PoseGridScorerConfig.hit", hit},
                                {"PoseGridScorerConfig.free", free},
                                {"PoseGridScorerConfig.unknown", unknown},
                                {"PoseGridScorerConfig.ray_through_wall", ray_through_wall},
                                {"PoseGridScorerConfig.ray_through_free", ray_through_free},
                                {"PoseGridScorerConfig.ray_through_contested", ray_through_contested},
                                {"PoseGridScorerConfig.surface_on_return", surface_on_return}}) {
    require(std::isfinite(v), name, "a finite score", v);
  }
}

PoseGridScorer::PoseGridScorer(const PoseGridHashMap& grid, PoseGridScorerConfig config)
    : grid_(grid), config_(config) {
  config_.validate();
  value_[0] = config_.unknown;
  value_[cell_flags::kOccupied] = config_.hit;
  value_[cell_flags::kFree] = config_.free;
  value_[cell_flags::kOccupied | cell_flags::kFree] = config_.hit;  // a map point beats a ray through its cell
  for (CellFlags f = 0; f < 16; ++f) {
    ray_value_[f] = (f & kWallBits) == cell_flags::kReturn ? config_.ray_through_wall
                    : (f & kFreeBits) == cell_flags::kFree ? config_.ray_through_free
                    : (f & kWallBits) == kWallBits         ? config_.ray_through_contested
                                                           : 0.0f;
    surface_value_[f] = (f & kFreeBits) == cell_flags::kFree           ? config_.free
                        : (f & kBareReturnBits) == cell_flags::kReturn ? config_.surface_on_return
                                                                       : config_.unknown;
  }
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

PoseGridScorer::PoseGridScorer(const PoseGridHashMap& grid, const FreeSpaceGrid& free_space,
                               PoseGridScorerConfig config)
    : PoseGridScorer(grid, config) {
  free_space_ = &free_space;
}

template <class Points>
void PoseGridScorer::free_space_offsets(const Points& x, const HypothesisBatch& v) {
  const std::size_t n = v.size;
  const FreeSpaceGrid::View grid = free_space_->view();
  transform_cells<false>(x, v, static_cast<float>(free_space_->inv_cell_size()), 0.0f, 1, fx_.data(), fy_.data(),
                         nullptr);
  for (std::size_t j = 0; j < n; ++j) offset_[j] = grid.offset(v.submap[j], fx_[j], fy_[j]);
}

void PoseGridScorer::operator()(const LocalPoint& x, const HypothesisBatch& v, float* scores) {
  score(OnePoint{x.x, x.y, x.theta}, x.kind, v, scores);
}

void PoseGridScorer::score_pairs(std::span<const LocalPoint> points, std::span<const std::uint32_t> hypotheses,
                                 const HypothesisBatch& v, float* scores) {
  if (points.size() != hypotheses.size()) {
    throw Error("PoseGridScorer::score_pairs: " + std::to_string(points.size()) + " points for " +
                std::to_string(hypotheses.size()) + " hypotheses");
  }
  for (const std::uint32_t h : hypotheses)
    if (h >= v.size)
      throw Error("PoseGridScorer::score_pairs: hypothesis " + std::to_string(h) + " of a batch of " +
                  std::to_string(v.size));
  // Each kind as one batch of its own, gathered: the lookups of all pairs
  // overlap as operator()'s do, where one small batch per point would not.
  for (const LocalPoint::Kind kind : {LocalPoint::Kind::kSurface, LocalPoint::Kind::kFreeSpace}) {
    Gathered& g = gathered_;
    g.index.clear();
    for (std::size_t j = 0; j < points.size(); ++j)
      if (points[j].kind == kind) g.index.push_back(static_cast<std::uint32_t>(j));
    const std::size_t m = g.index.size();
    if (m == 0) continue;
    g.submap.resize(m), g.tx.resize(m), g.ty.resize(m), g.cos.resize(m), g.sin.resize(m), g.theta.resize(m);
    g.px.resize(m), g.py.resize(m), g.pt.resize(m), g.scores.resize(m);
    for (std::size_t k = 0; k < m; ++k) {
      const std::uint32_t j = g.index[k], h = hypotheses[j];
      g.submap[k] = v.submap[h], g.tx[k] = v.tx[h], g.ty[k] = v.ty[h];
      g.cos[k] = v.cos[h], g.sin[k] = v.sin[h], g.theta[k] = v.theta[h];
      g.px[k] = points[j].x, g.py[k] = points[j].y, g.pt[k] = points[j].theta;
    }
    const HypothesisBatch sub{g.submap.data(), g.tx.data(), g.ty.data(), g.cos.data(), g.sin.data(), g.theta.data(), m};
    score(PointEach{g.px.data(), g.py.data(), g.pt.data()}, kind, sub, g.scores.data());
    for (std::size_t k = 0; k < m; ++k) scores[g.index[k]] = g.scores[k];
  }
}

template <class Points>
void PoseGridScorer::score(const Points& x, LocalPoint::Kind kind, const HypothesisBatch& v, float* scores) {
  const std::size_t n = v.size;
  if (xy_.size() < n) {
    xy_.resize(n), home_.resize(n), ix_.resize(n), iy_.resize(n), it_.resize(n), flags_.resize(n), pending_.resize(n);
    fx_.resize(n), fy_.resize(n), offset_.resize(n);
  }
  if (free_space_ == nullptr) {
    if (kind == LocalPoint::Kind::kFreeSpace)
      std::fill_n(scores, n, 0.0f);
    else
      score_surface(x, v, scores);
    return;
  }
  free_space_offsets(x, v);
  const FreeSpaceGrid::View grid = free_space_->view();
  if (kind == LocalPoint::Kind::kFreeSpace) {
    for (std::size_t j = 0; j < std::min(kAhead, n); ++j) grid.prefetch(offset_[j]);
    for (std::size_t j = 0; j < n; ++j) {
      if (j + kAhead < n) grid.prefetch(offset_[j + kAhead]);
      scores[j] = ray_value_[grid.at(offset_[j]) & 15];
    }
    stats_.lookups += n;
    return;
  }
  if (score_surface(x, v, scores)) return;  // it read the free-space grid too
  const float hit = config_.hit;
  std::size_t misses = 0;
  for (std::size_t j = 0; j < n; ++j) {
    if (scores[j] == hit) continue;
    scores[j] = surface_value_[grid.at(offset_[j]) & 15];
    ++misses;
  }
  stats_.lookups += misses;
}

void PoseGridScorer::score_surface_hinted(const HypothesisBatch& v, float* scores) {
  // The free-space cells first (a small dense grid, mostly cached): only the
  // points whose cell holds the pose-cell hint can hit the pose grid, whose
  // lookups are random reads of a big table. The others score as a lookup
  // that found nothing would have them score.
  const std::size_t n = v.size;
  const FreeSpaceGrid::View free = free_space_->view();
  const std::size_t* __restrict offset = offset_.data();
  CellFlags* __restrict flags = flags_.data();
  std::uint32_t* __restrict pending = pending_.data();
  for (std::size_t j = 0; j < std::min(kAhead, n); ++j) free.prefetch(offset[j]);
  // What a lookup that found nothing scores, and whether it then reads the free-space cell.
  const float hit = config_.hit, empty = value_[0];
  const bool empty_misses = empty != hit;
  std::size_t m = 0, misses = 0;
  for (std::size_t j = 0; j < n; ++j) {
    if (j + kAhead < n) free.prefetch(offset[j + kAhead]);
    const CellFlags f = free.at(offset[j]);
    flags[j] = f;
    if ((f & cell_flags::kPoseCell) != 0) {
      pending[m++] = static_cast<std::uint32_t>(j);
    } else {
      scores[j] = empty_misses ? surface_value_[f & 15] : empty;
      misses += empty_misses;
    }
  }
  const PoseGridHashMap::TableView table = grid_.table_view();
  const std::int32_t* __restrict ix = ix_.data();
  const std::int32_t* __restrict iy = iy_.data();
  const std::int32_t* __restrict it = it_.data();
  std::uint64_t* __restrict xy = xy_.data();
  std::uint32_t* __restrict home = home_.data();
  for (std::size_t k = 0; k < m; ++k) {
    const std::uint32_t j = pending[k];
    xy[k] = PoseGridHashMap::pack_xy(v.submap[j], ix[j], iy[j]);
    home[k] = static_cast<std::uint32_t>(table.home(xy[k], it[j]));
  }
  for (std::size_t k = 0; k < std::min(kAhead, m); ++k) table.prefetch(home[k]);
  for (std::size_t k = 0; k < m; ++k) {
    if (k + kAhead < m) table.prefetch(home[k + kAhead]);
    const std::uint32_t j = pending[k];
    const float s = value_[table.lookup_run(xy[k], home[k], it[j], 1) & 3];
    const bool miss = s != hit;
    scores[j] = miss ? surface_value_[flags[j] & 15] : s;
    misses += miss;
  }
  stats_.lookups += n + misses;
}

template <bool WithTheta, class Points>
void PoseGridScorer::transform_cells(const Points& x, const HypothesisBatch& v, float inv, float bpr, std::int32_t bins,
                                     std::int32_t* __restrict ix, std::int32_t* __restrict iy,
                                     std::int32_t* __restrict it) {
  const std::size_t n = v.size;
  const float* __restrict tx = v.tx;
  const float* __restrict ty = v.ty;
  const float* __restrict co = v.cos;
  const float* __restrict si = v.sin;
  const float* __restrict th = v.theta;
  std::size_t j = 0;
#if defined(__SSE2__)
  // Four hypotheses at a time: the same float operations in the same order
  // as the scalar loop below, so both give identical cells.
  const __m128 vinv = _mm_set1_ps(inv), vbpr = _mm_set1_ps(bpr);
  const __m128i vbins = _mm_set1_epi32(bins), vbins1 = _mm_set1_epi32(bins - 1), zero = _mm_setzero_si128();
  for (; j + 4 <= n; j += 4) {
    const __m128 vpx = x.x4(j), vpy = x.y4(j);
    const __m128 c = _mm_loadu_ps(co + j), sn = _mm_loadu_ps(si + j);
    const __m128 gx = _mm_sub_ps(_mm_add_ps(_mm_loadu_ps(tx + j), _mm_mul_ps(c, vpx)), _mm_mul_ps(sn, vpy));
    const __m128 gy = _mm_add_ps(_mm_add_ps(_mm_loadu_ps(ty + j), _mm_mul_ps(sn, vpx)), _mm_mul_ps(c, vpy));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(ix + j), floor_to_int4(_mm_mul_ps(gx, vinv)));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(iy + j), floor_to_int4(_mm_mul_ps(gy, vinv)));
    if constexpr (WithTheta) {
      __m128i t = floor_to_int4(_mm_mul_ps(_mm_add_ps(_mm_loadu_ps(th + j), x.theta4(j)), vbpr));
      t = _mm_add_epi32(t, _mm_and_si128(_mm_cmplt_epi32(t, zero), vbins));
      t = _mm_sub_epi32(t, _mm_and_si128(_mm_cmpgt_epi32(t, vbins1), vbins));
      _mm_storeu_si128(reinterpret_cast<__m128i*>(it + j), t);
    }
  }
#endif
  for (; j < n; ++j) {
    const float px = x.x(j), py = x.y(j);
    const float gx = tx[j] + co[j] * px - si[j] * py;
    const float gy = ty[j] + si[j] * px + co[j] * py;
    ix[j] = floor_to_int(gx * inv), iy[j] = floor_to_int(gy * inv);
    if constexpr (WithTheta) {
      std::int32_t t = floor_to_int((th[j] + x.theta(j)) * bpr);
      t += t < 0 ? bins : 0;
      t -= t >= bins ? bins : 0;
      it[j] = t;
    }
  }
}

template <class Points>
bool PoseGridScorer::score_surface(const Points& x, const HypothesisBatch& v, float* scores) {
  const std::size_t n = v.size;
  const PoseGridHashMap::TableView table = grid_.table_view();
  // 1. Transform x by every hypothesis and find its cell: float arithmetic
  //    only, four hypotheses at a time.
  transform_cells<true>(x, v, static_cast<float>(grid_.inv_cell_size()), static_cast<float>(grid_.bins_per_radian()),
                        grid_.theta_bins(), ix_.data(), iy_.data(), it_.data());
  // 2. For each (x, y) offset of the tolerance window (only (0, 0) unless
  //    the grid probes neighbours): pack and hash the (submap, ix, iy) keys,
  //    then look up the heading run of each, prefetching kAhead hypotheses
  //    ahead so that the cache misses of consecutive lookups overlap.
  const bool probe = grid_.probes_neighbours();
  const int xy_tol = probe ? grid_.config().xy_tolerance : 0;
  const bool theta_window = probe && grid_.config().theta_tolerance > 0 && grid_.theta_bins() > 1;
  if (!probe && free_space_ != nullptr && free_space_->tracks_pose_cells()) {
    score_surface_hinted(v, scores);
    return true;
  }
  const float lut[4] = {value_[0], value_[1], value_[2], value_[3]};  // local: no aliasing with scores
  const std::int32_t* __restrict ix = ix_.data();
  const std::int32_t* __restrict iy = iy_.data();
  const std::int32_t* __restrict it = it_.data();
  std::uint64_t* __restrict xy = xy_.data();
  std::uint32_t* __restrict home = home_.data();
  CellFlags* __restrict flags = flags_.data();
  for (int dx = -xy_tol; dx <= xy_tol; ++dx)
    for (int dy = -xy_tol; dy <= xy_tol; ++dy) {
      // The home slot of each cell; with a heading window, of its bin 0
      // (the window's runs start at home + first).
      for (std::size_t j = 0; j < n; ++j) {
        xy[j] = PoseGridHashMap::pack_xy(v.submap[j], ix[j] + dx, iy[j] + dy);
        home[j] = static_cast<std::uint32_t>(table.home(xy[j], theta_window ? 0 : it[j]));
      }
      const bool first_pass = dx == -xy_tol && dy == -xy_tol;
      const std::size_t mask = table.mask;
      auto slot_of = [&](std::size_t j) { return theta_window ? (home[j] + it[j]) & mask : home[j]; };
      for (std::size_t j = 0; j < std::min(kAhead, n); ++j) table.prefetch(slot_of(j));
      if (!theta_window && xy_tol == 0 && free_space_ != nullptr) {
        // The common case, one cell per hypothesis, and a miss's free-space
        // cell read in the same pass (its offset is known, its line prefetched).
        const FreeSpaceGrid::View free = free_space_->view();
        const std::size_t* __restrict offset = offset_.data();
        const float hit = config_.hit;
        for (std::size_t j = 0; j < std::min(kAhead, n); ++j) free.prefetch(offset[j]);
        std::size_t misses = 0;
        for (std::size_t j = 0; j < n; ++j) {
          if (j + kAhead < n) table.prefetch(home[j + kAhead]), free.prefetch(offset[j + kAhead]);
          const float s = lut[table.lookup_run(xy[j], home[j], it[j], 1) & 3];
          const bool miss = s != hit;
          scores[j] = miss ? surface_value_[free.at(offset[j]) & 15] : s;
          misses += miss;
        }
        stats_.lookups += n + misses;
        return true;
      }
      if (!theta_window && xy_tol == 0) {
        // The common case without a free-space grid: straight to scores.
        for (std::size_t j = 0; j < n; ++j) {
          if (j + kAhead < n) table.prefetch(home[j + kAhead]);
          scores[j] = lut[table.lookup_run(xy[j], home[j], it[j], 1) & 3];
        }
        stats_.lookups += n;
        return false;
      }
      if (theta_window && xy_tol == 0) {
        // One heading window per hypothesis: straight to scores; a window
        // that wraps at +-pi (2u+1 of theta_bins cases) takes two runs.
        const int u = grid_.config().theta_tolerance, bins = grid_.theta_bins(), count = 2 * u + 1;
        for (std::size_t j = 0; j < n; ++j) {
          if (j + kAhead < n) table.prefetch(slot_of(j + kAhead));
          const int first = it[j] - u;
          CellFlags f = 0;
          if (first >= 0 && first + count <= bins) {
            f = table.lookup_run(xy[j], (home[j] + static_cast<std::size_t>(first)) & mask, first, count);
          } else {
            const PoseGridHashMap::ThetaRuns w = grid_.theta_runs(it[j]);
            for (int r = 0; r < w.runs; ++r)
              f |= table.lookup_run(xy[j], (home[j] + static_cast<std::size_t>(w.first[r])) & mask, w.first[r],
                                    w.count[r]);
          }
          scores[j] = lut[f & 3];
        }
        stats_.lookups += n;
        return false;
      }
      for (std::size_t j = 0; j < n; ++j) {
        if (j + kAhead < n) table.prefetch(slot_of(j + kAhead));
        CellFlags f = 0;
        if (theta_window) {
          const PoseGridHashMap::ThetaRuns w = grid_.theta_runs(it[j]);
          for (int r = 0; r < w.runs; ++r)
            f |= table.lookup_run(xy[j], (home[j] + static_cast<std::size_t>(w.first[r])) & mask, w.first[r],
                                  w.count[r]);
        } else {
          f = table.lookup_run(xy[j], home[j], it[j], 1);
        }
        flags[j] = first_pass ? f : static_cast<CellFlags>(flags[j] | f);
      }
      stats_.lookups += n;
    }
  // 3. Flags to scores.
  for (std::size_t j = 0; j < n; ++j) scores[j] = lut[flags[j] & 3];
  return false;
}

}  // namespace lshloc
