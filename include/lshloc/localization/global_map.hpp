#pragma once
// The global map the mapper robots feed (docs/design.md section 2.1): submaps,
// the appearance database, the location store and the occupancy and
// free-space pose grids.
// Poses [m, rad] in each submap's frame; times [s] of CPU.
// Thread safety: const methods (what localizers read) may run concurrently
// with each other: several localizers on their own threads share one map.
// Writes (add_submap, add_scan, mark_*) must not run concurrently with
// anything: feed and query from one thread, or guard the map with one lock
// (a shared_mutex, exclusive for each write, shared for each target scan:
// eval/live_replay.hpp, fleet/map_follower.hpp).
#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <unordered_set>
#include <vector>

#include "lshloc/appearance/feature_extractor.hpp"
#include "lshloc/geometry/laser_scan.hpp"
#include "lshloc/appearance/location_store.hpp"
#include "lshloc/appearance/lsh_database.hpp"
#include "lshloc/matching/free_space_grid.hpp"
#include "lshloc/matching/pose_grid.hpp"

namespace lshloc {

/// Settings of the global map that mapper robots feed.
struct GlobalMapConfig {
  FeatureExtractorConfig features;  ///< keypoints and descriptors (the localizer must use the same)
  LshConfig database;               ///< the appearance database
  /// Occupancy of the (x, y, normal direction) grid: every scan endpoint is
  /// marked with the direction of its surface normal (towards the sensor),
  /// so a hypothesis can be checked against many points, not only keypoints.
  PoseGridConfig occupancy;
  /// Negative evidence: a 2-D grid of cells that mapper rays saw free.
  PoseGridConfig free_space{.cell_size = 0.25, .theta_bins = 1, .xy_tolerance = 0, .theta_tolerance = 0};
  double endpoint_spacing = 0.1;    ///< [m] endpoints closer than this along a scan are marked once
  std::size_t free_ray_stride = 3;  ///< every this many beams marks its ray as free space
  double free_ray_margin = 0.3;  ///< [m] at least this last part of a ray is not marked free (more at shallow angles)
  double free_ray_max_range = 12.0;  ///< [m] rays are marked free up to this range
  /// [m] how far a beam without a return is marked free. 0: not at all, as
  /// glass and dark surfaces return nothing too, and a free run through them
  /// turns rooms the mappers never saw into "seen free", where they
  /// contradict a target's true pose (RESULTS.md, "Design choices, measured").
  double free_ray_no_return_range = 0.0;
  std::size_t context_scans = 8;  ///< recent scans of a submap whose surface enters descriptors
  double context_spacing = 0.3;   ///< [m] a scan joins the context after this much travel
  /// The LSH keys (table tags) of this many of the newest map features are
  /// kept, so that a localizer can look what was mapped since its last scan
  /// up among the features it has already seen (recent_key(); Localizer's
  /// newly mapped features). 0: none. Costs 4 L bytes each.
  std::size_t recent_keys = 16384;

  void validate() const;
};

/// Counts, sizes and costs of the global map; times are the feeding thread's
/// CPU seconds (cpu_time.hpp).
struct GlobalMapStats {
  std::size_t submaps = 0;
  std::size_t scans = 0;
  std::size_t features = 0;        ///< map features (locations = database entries)
  double extract_s = 0.0;          ///< [s] keypoints and descriptors
  double database_insert_s = 0.0;  ///< [s] LSH inserts only
  double grid_s = 0.0;             ///< [s] occupancy and free-space marking
  LshStats database;
  PoseGridStats occupancy;
  PoseGridStats free_space;
  std::size_t location_bytes = 0;
  std::size_t recent_key_bytes = 0;  ///< the newest features' LSH keys (GlobalMapConfig::recent_keys)
  /// [bytes] everything the global map holds per map feature.
  double bytes_per_feature() const;
  double us_insert_per_feature() const {
    return features ? 1e6 * database_insert_s / static_cast<double>(features) : 0.0;
  }
  double us_update_per_feature() const {
    return features ? 1e6 * (extract_s + database_insert_s + grid_s) / static_cast<double>(features) : 0.0;
  }
};

/// One named part of a GlobalMap's snapshot (docs/map-format.md).
struct MapSection {
  std::string name;
  std::vector<std::uint8_t> bytes;
};
/// A MapSection read in place (e.g. from a loaded file).
struct MapSectionView {
  std::string_view name;
  std::span<const std::uint8_t> bytes;
};

/// The global map G = {G_1..G_R}: submaps in their own frames, the appearance
/// database, the location store and the pose grids. Mapper robots feed it one
/// scan at a time (in any interleaving across submaps); nothing is rebuilt.
/// Thread safety: see the top of this file (concurrent reads, exclusive writes).
class GlobalMap {
 public:
  explicit GlobalMap(GlobalMapConfig config = {});

  const GlobalMapConfig& config() const { return config_; }

  /// The longest submap name a map holds (and a saved map reads).
  static constexpr std::size_t kMaxSubmapNameBytes = 4096;

  /// Opens a new, empty submap and returns its id (0, 1, ...). Throws
  /// lshloc::Error, the map unchanged, for a name longer than
  /// kMaxSubmapNameBytes or beyond PoseGridHashMap::kMaxSubmaps submaps.
  std::uint32_t add_submap(std::string name);

  /// What add_scan() does with a scan besides its features.
  enum class ScanGrids : std::uint8_t {
    kMark,  ///< marks its endpoints and rays in the occupancy and free-space grids
    kSkip,  ///< features only: the caller marks the grids itself (maps from occupancy grids)
  };

  /// Adds one mapper scan to `submap`; `laser_pose` is the scan's laser pose
  /// in the submap's frame. Returns the number of features it added; with
  /// `added`, also appends them there (for evaluations that need the
  /// descriptors, which the map itself does not keep). A scan the map cannot
  /// take throws lshloc::Error and leaves the map as it was (an unknown
  /// submap, marks beyond the grids' +-65,536 cells, a full location store,
  /// database id pool or pose grid); only running out of memory part-way can
  /// leave part of a scan in.
  std::size_t add_scan(std::uint32_t submap, const LaserScan& scan, const Pose2& laser_pose,
                       ScanGrids grids = ScanGrids::kMark, std::vector<Feature>* added = nullptr);

  // --- The grid marks add_scan() makes, one point at a time (for maps whose
  // surface and free space come from elsewhere, e.g. an occupancy grid).
  /// A surface point at `p` [m] whose normal points along `normal` [rad].
  void mark_surface_point(std::uint32_t submap, const Point2& p, double normal);
  /// A laser return at `p`: its free-space cell and the 8 around it read as occupied.
  void mark_return(std::uint32_t submap, const Point2& p);
  /// Free space seen at `p`.
  void mark_free(std::uint32_t submap, const Point2& p);

  std::size_t submap_count() const { return submaps_.size(); }
  const std::string& submap_name(std::uint32_t submap) const { return submaps_.at(submap).name; }
  /// Mapper scans added to `submap` so far.
  std::size_t submap_scans(std::uint32_t submap) const { return submaps_.at(submap).scans; }
  /// The id of the first submap named `name`, if any.
  std::optional<std::uint32_t> find_submap(std::string_view name) const;

  /// How many of `scans` the map holds already: mapper scans with the same
  /// readings (scan_fingerprint), as when a map is built from the very log a
  /// robot is localized with. Counts only scans whose fingerprints the map
  /// knows: see knows_every_scan().
  std::size_t scans_held(std::span<const LaserScan> scans) const;
  /// false for a map loaded from a file written before maps kept their
  /// scans' fingerprints (format version 2 and older): it knows those of the
  /// scans added since only.
  bool knows_every_scan() const { return scan_prints_complete_; }

  /// The names of the snapshot's sections, in the order snapshot() writes them.
  static const std::vector<std::string>& snapshot_sections();
  /// The map's whole state as sections, in snapshot_sections() order:
  /// "submaps" (names, scan counts, descriptor contexts), "locations",
  /// "database", "occupancy", "free_space", "counters" (counts and the
  /// build's CPU times) and "scan_prints" (the mapper scans' fingerprints;
  /// optional when read). Canonical: maps with equal contents write equal
  /// sections whatever their tables' layout (the times in "counters" aside).
  std::vector<MapSection> snapshot() const;
  /// The map snapshot() wrote, given the writer's config; add_scan() then
  /// continues exactly as it would have on the written map. Bulk reads, no
  /// feature extraction or hashing of descriptors. Throws lshloc::Error
  /// naming `source` and the section on a missing section or anything
  /// inconsistent.
  static std::unique_ptr<GlobalMap> from_snapshot(const GlobalMapConfig& config,
                                                  std::span<const MapSectionView> sections, const std::string& source);

  const LshDatabase& database() const { return database_; }
  /// The database answers from now on with `asked`'s query-time settings
  /// (LshDatabase::set_query_settings; config() reports them). A write: not
  /// concurrently with anything; a Localizer made before takes them from
  /// its next scan on.
  void set_query_settings(const LshConfig& asked);
  /// The LSH key of map feature `id` (a location id) while it is one of the
  /// newest `recent_keys` features add_scan() added; none for older ones and
  /// for those a snapshot brought.
  std::optional<LshKeyView> recent_key(std::uint32_t id) const;
  const LocationStore& locations() const { return locations_; }
  const PoseGridHashMap& occupancy() const { return occupancy_; }
  const FreeSpaceGrid& free_space() const { return free_space_; }

  GlobalMapStats stats() const;

 private:
  /// Fingerprints of the mapper scans added with their grid marks (not the
  /// virtual scans of occupancy grids).
  std::unordered_set<std::uint64_t> scan_prints_;
  bool scan_prints_complete_ = true;

  struct SubmapState {
    std::string name;
    ScanContext context;  ///< descriptor context of the submap's next scans
    std::size_t scans = 0;
  };

  /// The free-space flags already marked during the scan plan_grids() is
  /// planning, in a dense window of cells around its sensor: each cell is
  /// marked once per scan and flag set (rays near the sensor and the
  /// neighbours of adjacent returns cross the same cells many times). A
  /// skipped mark would have changed nothing, so the grid is the same.
  class ScanMarks {
   public:
    /// Starts a scan whose marks lie within `half_width` cells of (cx, cy).
    void start(std::int32_t cx, std::int32_t cy, std::int32_t half_width);
    void stop() { width_ = 0; }
    /// Whether `flags` were all marked at (ix, iy) this scan; records them if not.
    bool seen(std::int32_t ix, std::int32_t iy, CellFlags flags);

   private:
    std::vector<std::uint32_t> cells_;  ///< (generation << 8) | flags
    std::uint32_t generation_ = 0;
    std::int32_t x0_ = 0, y0_ = 0, width_ = 0;
  };

  void check_submap(std::uint32_t submap, const char* caller) const;
  /// Plans ORing `flags` into the free-space cell of `p`, unless scan_marks_ holds them.
  void mark_free_space(std::uint32_t submap, const Point2& p, CellFlags flags);
  /// Plans mark_return()'s marks.
  void plan_return(std::uint32_t submap, const Point2& p);
  /// Makes the planned marks of both grids (the mark_* calls make theirs at
  /// once, a scan's are made together after its features: prefetched ahead).
  void make_planned_marks();
  /// Plans every grid mark of a scan (nothing is marked; throws when one lies
  /// beyond the grids); the caller makes them or, on an error, clears them.
  /// `directions` are the beams' from BeamDirections::of(scan).
  void plan_grids(std::uint32_t submap, const LaserScan& scan, const Pose2& laser_pose, const ScanSurface& surface,
                  std::span<const Point2> directions);
  void keep_recent_key(std::uint32_t id);  ///< of the feature database_ inserted last

  GlobalMapConfig config_;
  FeatureExtractor extractor_;
  LshDatabase database_;
  LocationStore locations_;
  PoseGridHashMap occupancy_;
  FreeSpaceGrid free_space_;
  std::vector<SubmapState> submaps_;
  GlobalMapStats stats_;
  BeamDirections beam_directions_;            // scratch of add_scan
  std::vector<Point2> beam_endpoints_;        // scratch of plan_grids
  ScanMarks scan_marks_;                      // scratch of plan_grids
  bool marking_scan_ = false;                 // within add_scan: marks wait for its end
  PoseGridHashMap::MarkPlan occupancy_plan_;  // planned, not yet made
  FreeSpaceGrid::MarkPlan free_space_plan_;
  // A ring of the newest features' table tags: L per feature, slot id % recent_keys.
  std::vector<std::uint32_t> recent_tags_;
  std::vector<std::uint64_t> recent_sketches_;  ///< and their sign sketches, sketch_bits / 64 per feature
  std::uint32_t recent_first_ = 0;              ///< the first location id add_scan() added (a snapshot's come before)
};

}  // namespace lshloc
