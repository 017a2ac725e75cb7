#include "lshloc/eval/dataset_catalog.hpp"

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>

#include "lshloc/common/byte_codec.hpp"
#include "lshloc/common/error.hpp"
#include "lshloc/io/atomic_file.hpp"
#include "lshloc/io/ground_truth.hpp"

namespace fs = std::filesystem;

namespace lshloc::io {

namespace {

struct KnownBuilding {
  const char* name;
  const char* raw;
  const char* corrected;
  const char* poses;
  const char* relations;
  std::optional<double> laser_offset_x = std::nullopt;
};

// Paths relative to the data directory and the laser offsets of the raw
// logs, as ../shared/data/README.md lists them.
constexpr KnownBuilding kKnown[] = {
    {"fr079", "fr079/fr079.recon-from-bag.log.gz", "fr079/fr079-complete.gfs.log.gz",
     "fr079/fr079.gfs-poses-at-bag-stamps.txt", "fr079/fr079.relations", -0.04},
    {"fr101", "fr101/fr101.carmen.log.gz", "fr101/fr101.carmen.gfs.log.gz", "fr101/fr101.gfs-poses-at-raw-stamps.txt",
     "", -0.04},
    {"intel", "intel/intel.recon-from-bag.log.gz", "intel/intel.gfs.log.gz", "intel/intel.gfs-poses-at-bag-stamps.txt",
     "intel/intel.relations"},
    {"aces", "aces/aces.recon-from-bag.log.gz", "aces/aces-corrected.log.gz", "aces/aces.gfs-poses-at-bag-stamps.txt",
     "aces/aces.relations"},
    {"mit-csail", "mit-csail/mit-csail.clf.gz", "mit-csail/csail.corrected.log.gz",
     "mit-csail/csail.gfs-poses-at-clf-stamps.txt", "mit-csail/mit-csail.relations"},
    {"fr-clinic", "fr-clinic/fr-clinic.recon-from-bag.log.gz", "", "", "fr-clinic/fr-clinic.relations"},
    {"mit-killian", "mit-killian/mit-killian.recon-from-bag.log.gz", "", "", ""},
    {"acapulco", "", "radish-gfs-corrected/acapulco-corrected.log.gz", "", ""},
    {"belgioioso", "", "radish-gfs-corrected/belgioioso-corrected.log.gz", "", ""},
    {"edmonton", "", "radish-gfs-corrected/edmonton-corrected.log.gz", "", ""},
    {"fhw", "", "radish-gfs-corrected/fhw-corrected.log.gz", "", ""},
    {"freiburg-campus", "", "radish-gfs-corrected/freiburg-campus-corrected.log.gz", "", ""},
    {"infinite-corridor", "", "radish-gfs-corrected/infinite-corridor-corrected.log.gz", "", ""},
    {"orebro", "", "radish-gfs-corrected/orebro-corrected.log.gz", "", ""},
    {"seattle", "", "radish-gfs-corrected/seattle-corrected.log.gz", "", ""},
};

std::string join(const std::string& dir, const char* rel) { return *rel ? (fs::path(dir) / rel).string() : ""; }

void require_file(const std::string& path, const std::string& building, const char* what) {
  if (path.empty()) throw Error(building + " has no " + what + " in the catalog");
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) {
    throw Error(path + ": missing " + what + " of building " + building +
                "; check the data directory (--data DIR or LSHLOC_DATA)");
  }
}

}  // namespace

DatasetCatalog::DatasetCatalog(std::string data_dir) : dir_(std::move(data_dir)) {
  std::error_code ec;
  if (!fs::is_directory(dir_, ec)) {
    throw Error("data directory '" + dir_ +
                "' does not exist; give it with --data DIR or the LSHLOC_DATA environment variable");
  }
  dir_ = fs::canonical(dir_, ec).string();
  for (const auto& k : kKnown) {
    buildings_.push_back({k.name, join(dir_, k.raw), join(dir_, k.corrected), join(dir_, k.poses),
                          join(dir_, k.relations), k.laser_offset_x});
  }
}

std::string DatasetCatalog::resolve_data_dir(const std::string& cli_value, const std::string& fallback) {
  if (!cli_value.empty()) return cli_value;
  if (const char* env = std::getenv("LSHLOC_DATA"); env != nullptr && *env != '\0') return env;
  std::error_code ec;
  if (!fallback.empty() && fs::is_directory(fallback, ec)) return fs::weakly_canonical(fallback, ec).string();
  return "../shared/data";
}

const BuildingFiles& DatasetCatalog::building(const std::string& name) const {
  for (const auto& b : buildings_) {
    if (b.name == name) return b;
  }
  std::string known;
  for (const auto& b : buildings_) known += (known.empty() ? "" : ", ") + b.name;
  throw Error("unknown building '" + name + "'; known buildings: " + known);
}

std::vector<std::string> DatasetCatalog::existing_logs() const {
  std::vector<std::string> out;
  std::error_code ec;
  for (const auto& b : buildings_) {
    for (const auto* p : {&b.raw_log, &b.corrected_log}) {
      if (!p->empty() && fs::is_regular_file(*p, ec)) out.push_back(*p);
    }
  }
  return out;
}

BuildingRecording load_building(const BuildingFiles& f, bool with_raw, const CarmenReaderConfig& reader) {
  const std::string& name = f.name;
  BuildingRecording rec;
  rec.name = name;
  if (with_raw || f.corrected_log.empty()) {
    require_file(f.raw_log, name, "raw log");
    CarmenLog raw = read_carmen_log(f.raw_log, reader);
    rec.laser_offset = raw.front_laser_offset();
    rec.raw_scans = std::move(raw.scans);
  }
  if (!f.corrected_log.empty()) {
    require_file(f.corrected_log, name, "corrected log");
    rec.corrected_scans = read_carmen_log(f.corrected_log, reader).scans;
  }
  if (!f.poses.empty()) {
    require_file(f.poses, name, "ground-truth poses file");
    rec.truth = read_pose_file(f.poses);
  }
  return rec;
}

BuildingRecording DatasetCatalog::load(const std::string& name, bool with_raw, const CarmenReaderConfig& reader) const {
  return load_building(building(name), with_raw, reader);
}

namespace {

/// FNV-1a, 64 bits: the cache's key and checksum (not a defence against
/// tampering, only against another log, another build and torn files).
class Fnv1a {
 public:
  void add(const void* data, std::size_t n) {
    const auto* p = static_cast<const unsigned char*>(data);
    for (std::size_t i = 0; i < n; ++i) h_ = (h_ ^ p[i]) * 1099511628211ull;
  }
  template <class T>
  void add(const T& v) {
    add(&v, sizeof v);
  }
  std::uint64_t value() const { return h_; }

 private:
  std::uint64_t h_ = 14695981039346656037ull;
};

constexpr char kSlamCacheMagic[] = "lshloc slam poses 1\n";

std::uint64_t slam_cache_key(const BuildingRecording& rec, const std::string& build_id) {
  Fnv1a h;
  h.add(build_id.data(), build_id.size());
  for (const double v : {rec.laser_offset.x, rec.laser_offset.y, rec.laser_offset.theta}) h.add(v);
  for (const LaserScan& s : rec.raw_scans) {
    for (const double v : {s.timestamp, s.angle_min, s.angle_increment, s.max_range, s.odometry.x, s.odometry.y,
                           s.odometry.theta, s.pose.x, s.pose.y, s.pose.theta})
      h.add(v);
    h.add(s.ranges.data(), s.ranges.size() * sizeof(float));
  }
  return h.value();
}

/// The cached poses of `rec`, if `path` holds a whole entry for `key` with one pose per raw scan.
std::optional<std::vector<Pose2>> read_slam_poses(const std::string& path, std::uint64_t key, std::size_t scans) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return std::nullopt;
  const std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::size_t magic = sizeof kSlamCacheMagic - 1;
  if (bytes.size() != magic + 16 + 24 * scans + 8 || std::memcmp(bytes.data(), kSlamCacheMagic, magic) != 0)
    return std::nullopt;
  Fnv1a sum;
  sum.add(bytes.data(), bytes.size() - 8);
  ByteReader r(std::span<const std::uint8_t>(bytes).subspan(magic), path);
  if (r.u64() != key || r.u64() != scans) return std::nullopt;
  std::vector<Pose2> poses(scans);
  for (Pose2& p : poses) p = {r.f64(), r.f64(), r.f64()};
  if (r.u64() != sum.value()) return std::nullopt;
  return poses;
}

void write_slam_poses(const std::string& path, std::uint64_t key, const std::vector<LaserScan>& posed) {
  ByteWriter w;
  w.raw({reinterpret_cast<const std::uint8_t*>(kSlamCacheMagic), sizeof kSlamCacheMagic - 1});
  w.u64(key);
  w.u64(posed.size());
  for (const LaserScan& s : posed) w.f64(s.pose.x), w.f64(s.pose.y), w.f64(s.pose.theta);
  Fnv1a sum;
  sum.add(w.bytes().data(), w.bytes().size());
  w.u64(sum.value());
  const std::vector<std::uint8_t> bytes = w.take();
  write_file_atomically(path, {reinterpret_cast<const char*>(bytes.data()), bytes.size()});
}

}  // namespace

Submap whole_building_submap(const BuildingRecording& rec, const SlamPoseCache& cache) {
  if (cache.dir.empty() || !rec.corrected_scans.empty()) return lshloc::whole_building_submap(rec);
  const std::uint64_t key = slam_cache_key(rec, cache.build_id);
  char name[32];
  std::snprintf(name, sizeof name, "-%016llx.poses", static_cast<unsigned long long>(key));
  const std::string path = (fs::path(cache.dir) / (rec.name + name)).string();
  if (const auto poses = read_slam_poses(path, key, rec.raw_scans.size())) {
    Submap s;
    s.name = rec.name;
    s.poses_from_slam = true;
    s.scans = rec.raw_scans;
    for (std::size_t i = 0; i < s.scans.size(); ++i) s.scans[i].pose = (*poses)[i];
    return s;
  }
  Submap s = lshloc::whole_building_submap(rec);
  std::error_code ec;
  fs::create_directories(cache.dir, ec);
  if (ec) throw Error(cache.dir + ": cannot create the SLAM pose cache directory: " + ec.message());
  write_slam_poses(path, key, s.scans);
  return s;
}

Scenario load_scenario(const DatasetCatalog& catalog, const ScenarioConfig& config, const CarmenReaderConfig& reader,
                       const SlamPoseCache& slam_cache) {
  Scenario sc;
  sc.config = config;
  const auto others = other_buildings(config);
  Submap own;
  split_target_building(catalog.load(config.building, /*with_raw=*/true, reader), config, own, sc.target);
  sc.submaps.push_back(std::move(own));
  sc.target_submap = 0;
  for (const auto& name : others)
    sc.submaps.push_back(whole_building_submap(catalog.load(name, false, reader), slam_cache));
  return sc;
}

Scenario load_scenario_target(const DatasetCatalog& catalog, const ScenarioConfig& config,
                              const CarmenReaderConfig& reader) {
  Scenario sc;
  sc.config = config;
  Submap own;
  split_target_building(catalog.load(config.building, /*with_raw=*/true, reader), config, own, sc.target);
  return sc;
}

BuildingFiles write_building_recording(const BuildingRecording& rec, const std::string& dir,
                                       const CarmenWriterConfig& config) {
  if (rec.name.empty() || rec.name.find('/') != std::string::npos) {
    throw Error("cannot write a building named '" + rec.name + "': the name must be non-empty and have no '/'");
  }
  namespace fs = std::filesystem;
  const fs::path folder = fs::path(dir) / rec.name;
  std::error_code ec;
  fs::create_directories(folder, ec);
  if (ec) throw Error(folder.string() + ": cannot create directory: " + ec.message());
  BuildingFiles files;
  files.name = rec.name;
  if (!rec.raw_scans.empty()) {
    files.raw_log = (folder / (rec.name + ".log.gz")).string();
    write_carmen_log(files.raw_log, rec.raw_scans, /*with_odometry=*/true, rec.laser_offset, config);
  }
  if (!rec.corrected_scans.empty()) {
    files.corrected_log = (folder / (rec.name + "-corrected.log.gz")).string();
    write_carmen_log(files.corrected_log, rec.corrected_scans, /*with_odometry=*/false, rec.laser_offset, config);
  }
  if (!rec.truth.empty()) {
    files.poses = (folder / (rec.name + ".gfs-poses-at-raw-stamps.txt")).string();
    write_pose_file(files.poses, rec.truth, config);
  }
  return files;
}

}  // namespace lshloc::io
