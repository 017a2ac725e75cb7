#include "lshloc/io/ros_map.hpp"

#include <cstdio>
#include <filesystem>
#include <fstream>

#include "lshloc/common/error.hpp"

namespace lshloc::io {

namespace {
// map_server's trinary convention: p = (255 - value) / 255 against the thresholds.
constexpr unsigned char kOccupiedGrey = 0, kFreeGrey = 254, kUnknownGrey = 205;
}  // namespace

void write_ros_map(const std::string& stem, const OccupancyGrid& grid) {
  const std::string pgm = stem + ".pgm", yaml = stem + ".yaml";
  {
    std::ofstream out(pgm, std::ios::binary);
    if (!out) throw Error(pgm + ": cannot write");
    out << "P5\n# lshloc occupancy grid, " << grid.resolution << " m/cell\n"
        << grid.width << ' ' << grid.height << "\n255\n";
    std::vector<unsigned char> row(grid.width);
    for (std::size_t r = grid.height; r-- > 0;) {
      for (std::size_t c = 0; c < grid.width; ++c) {
        const std::int8_t v = grid.at(c, r);
        row[c] = v == occupancy::kOccupied ? kOccupiedGrey : v == occupancy::kFree ? kFreeGrey : kUnknownGrey;
      }
      out.write(reinterpret_cast<const char*>(row.data()), static_cast<std::streamsize>(row.size()));
    }
    if (!out) throw Error(pgm + ": cannot write");
  }
  std::ofstream out(yaml);
  if (!out) throw Error(yaml + ": cannot write");
  char origin[96];
  std::snprintf(origin, sizeof origin, "[%.6f, %.6f, 0.0]", grid.origin.x(), grid.origin.y());
  out << "image: " << std::filesystem::path(pgm).filename().string()
      << "\nmode: trinary\nresolution: " << grid.resolution << "\norigin: " << origin
      << "\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.25\n";
  if (!out) throw Error(yaml + ": cannot write");
}

}  // namespace lshloc::io
