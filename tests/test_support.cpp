#include "test_support.hpp"

#include <gtest/gtest.h>
#include <zlib.h>

#include <atomic>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <stdexcept>

#include <unistd.h>

namespace lshloc::test {

sim::SyntheticScenarioConfig small_world(std::size_t map_scans, std::size_t target_scans) {
  sim::SyntheticScenarioConfig c;
  c.seed = 11;
  c.buildings = 3;
  c.target_building = 1;
  c.map_scans = map_scans;
  c.target_scans = target_scans;
  return c;
}

std::optional<std::string> data_dir() {
  std::error_code ec;
  if (const char* env = std::getenv("LSHLOC_DATA"); env && *env && std::filesystem::is_directory(env, ec)) return env;
  const auto p = std::filesystem::path(LSHLOC_SOURCE_DIR) / ".." / "shared" / "data";
  if (std::filesystem::is_directory(p, ec)) return p.string();
  return std::nullopt;
}

namespace {
// One folder per test process, removed with everything in it when the process
// exits (a forked child that exits does not remove its parent's folder).
class TestTempDir {
 public:
  TestTempDir()
      : owner_(::getpid()), dir_(std::filesystem::temp_directory_path() / ("lshloc-test-" + std::to_string(owner_))) {
    std::filesystem::create_directories(dir_);
  }
  TestTempDir(const TestTempDir&) = delete;
  TestTempDir& operator=(const TestTempDir&) = delete;
  ~TestTempDir() {
    std::error_code ec;
    if (::getpid() == owner_) std::filesystem::remove_all(dir_, ec);
  }
  const std::filesystem::path& dir() const { return dir_; }

 private:
  pid_t owner_;
  std::filesystem::path dir_;
};
}  // namespace

std::string temp_path(const std::string& suffix) {
  static TestTempDir folder;
  static std::atomic<int> counter{0};
  return (folder.dir() / (std::to_string(counter++) + suffix)).string();
}

std::string read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void write_file(const std::string& path, const std::string& text) {
  if (path.size() > 3 && path.compare(path.size() - 3, 3, ".gz") == 0) {
    gzFile f = gzopen(path.c_str(), "wb");
    if (!f) throw std::runtime_error("cannot write " + path);
    gzwrite(f, text.data(), static_cast<unsigned>(text.size()));
    gzclose(f);
  } else {
    std::ofstream(path) << text;
  }
}

std::vector<MapSection> map_contents(const GlobalMap& map) {
  std::vector<MapSection> out = map.snapshot();
  for (MapSection& s : out)
    if (s.name == "counters") s.bytes.resize(s.bytes.size() - 24);  // three f64 times at the end
  return out;
}

void expect_same_map_contents(const GlobalMap& a, const GlobalMap& b) {
  const auto sa = map_contents(a), sb = map_contents(b);
  ASSERT_EQ(sa.size(), sb.size());
  for (std::size_t i = 0; i < sa.size(); ++i) {
    EXPECT_EQ(sa[i].name, sb[i].name);
    EXPECT_TRUE(sa[i].bytes == sb[i].bytes) << "section " << sa[i].name << " differs";
  }
}

}  // namespace lshloc::test
