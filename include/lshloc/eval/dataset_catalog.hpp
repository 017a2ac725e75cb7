#pragma once
// The buildings of the data directory: where their logs lie, loading them,
// building scenarios from them, and writing recordings as building directories.
// Lengths [m], angles [rad], times [s].
// Thread safety: a DatasetCatalog is immutable after construction (const
// methods may run concurrently); the free functions share no state
// (write_building_recording: distinct directories). resolve_data_dir reads
// $LSHLOC_DATA: not while another thread changes the environment.
#include <optional>
#include <string>
#include <vector>

#include "lshloc/io/carmen_reader.hpp"
#include "lshloc/io/carmen_writer.hpp"
#include "lshloc/eval/scenario.hpp"

namespace lshloc::io {

/// The files of one building in the data directory (absolute paths; empty
/// where the building has no such file).
struct BuildingFiles {
  std::string name;
  std::string raw_log;        ///< odometry + scans
  std::string corrected_log;  ///< GMapping-corrected log
  std::string poses;          ///< ground-truth poses of raw scans (`*.gfs-poses-at-*-stamps.txt`)
  std::string relations;      ///< Kümmerle benchmark relations
  /// [m] the front laser's mounting offset ahead of the robot's centre as the
  /// data README documents it, for raw logs that lack the PARAM line
  std::optional<double> laser_offset_x;
};

/// The 15 buildings of the shared data directory (see ../shared/data/README.md).
class DatasetCatalog {
 public:
  /// Opens a data directory; throws lshloc::Error if it is missing.
  explicit DatasetCatalog(std::string data_dir);

  /// The data directory to use: `cli_value` if not empty, else $LSHLOC_DATA,
  /// else `fallback` if it is a directory (the tool passes ../shared/data
  /// beside its source tree), else ../shared/data of the current directory.
  static std::string resolve_data_dir(const std::string& cli_value = "", const std::string& fallback = "");

  const std::string& data_dir() const { return dir_; }
  const std::vector<BuildingFiles>& buildings() const { return buildings_; }

  /// Throws lshloc::Error listing the known names if `name` is unknown.
  const BuildingFiles& building(const std::string& name) const;

  /// Every log file (raw and corrected) the catalog knows that exists on disk.
  std::vector<std::string> existing_logs() const;

  /// Reads what a building has: raw log (if `with_raw`), corrected log and
  /// ground-truth poses. Throws naming any expected file that is missing.
  BuildingRecording load(const std::string& name, bool with_raw, const CarmenReaderConfig& reader = {}) const;

 private:
  std::string dir_;
  std::vector<BuildingFiles> buildings_;
};

/// Reads what `files` has: the raw log (if `with_raw`, or when there is no
/// corrected log), the corrected log and the ground-truth poses. Throws
/// naming any listed file that is missing. Works for catalog buildings and
/// for any other building directory (e.g. one io::write_building_recording made).
BuildingRecording load_building(const BuildingFiles& files, bool with_raw, const CarmenReaderConfig& reader = {});

/// A directory where load_scenario() keeps the poses lshloc's SLAM gave the
/// other buildings that have no corrected log (their whole raw log: the same
/// in every scenario, and most of a scenario's loading time). An entry is
/// keyed by the raw scans, the laser offset and `build_id`, and checksummed;
/// one that does not match (another build or log, a torn or damaged file) is
/// recomputed and replaced (atomically: parallel runs may share the directory).
struct SlamPoseCache {
  std::string dir;       ///< empty: no cache
  std::string build_id;  ///< identifies the code that made the poses (e.g. the executable's size and time)
};

/// Loads the scenario of docs/design.md section 6 from the catalog: the target's
/// building split around the window, plus config.submaps - 1 other buildings.
Scenario load_scenario(const DatasetCatalog& catalog, const ScenarioConfig& config,
                       const CarmenReaderConfig& reader = {}, const SlamPoseCache& slam_cache = {});

/// whole_building_submap() through `cache` (see SlamPoseCache): poses read
/// from it when it holds this recording's, else made by SLAM and stored.
Submap whole_building_submap(const BuildingRecording& rec, const SlamPoseCache& cache);

/// The scenario's target run alone (its submaps left empty): for a run on a
/// map saved earlier, which reads only the target's building.
Scenario load_scenario_target(const DatasetCatalog& catalog, const ScenarioConfig& config,
                              const CarmenReaderConfig& reader = {});

/// Writes a recording as a building directory `dir/NAME/`: `NAME.log.gz`
/// (raw scans with ODOM lines), `NAME-corrected.log.gz` (corrected scans) and
/// `NAME.gfs-poses-at-raw-stamps.txt` (truth), each only when the recording
/// has it. Creates directories as needed. Returns the paths (empty where not
/// written), ready for load_building.
BuildingFiles write_building_recording(const BuildingRecording& recording, const std::string& dir,
                                       const CarmenWriterConfig& config = {});

}  // namespace lshloc::io
