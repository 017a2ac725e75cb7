// Maps from occupancy grids: ROS map_server files read back as written and as
// map_server classifies them, virtual scans against the exact distances of a
// known room, and a robot localized (against the simulator's ground truth)
// in a global map whose submaps were all built from grids.
#include "lshloc/localization/grid_submap.hpp"

#include <gtest/gtest.h>
#include <png.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "lshloc/common/error.hpp"
#include "lshloc/eval/localization_metrics.hpp"
#include "lshloc/eval/scenario_runner.hpp"
#include "lshloc/io/ros_map.hpp"
#include "lshloc/matching/pose_grid.hpp"
#include "lshloc/sim/synthetic_scenario.hpp"
#include "test_support.hpp"

namespace lshloc {
namespace {

/// A 10 x 6 m room (inner walls at x = 0, 10 and y = 0, 6), walls one cell
/// thick, unknown outside, at 0.05 m per cell with the origin at (-1, -1).
OccupancyGrid room_grid(double yaw = 0.0) {
  OccupancyGrid g;
  g.resolution = 0.05;
  g.origin = {-1.0, -1.0};
  g.origin_yaw = yaw;
  g.width = 240, g.height = 160;  // 12 x 8 m
  g.cells.assign(g.width * g.height, occupancy::kUnknown);
  for (std::size_t r = 0; r < g.height; ++r) {
    for (std::size_t c = 0; c < g.width; ++c) {
      // Grid-frame coordinates of the cell centre relative to the room's corner.
      const double x = (static_cast<double>(c) + 0.5) * g.resolution - 1.0;
      const double y = (static_cast<double>(r) + 0.5) * g.resolution - 1.0;
      const bool inside = x > 0.0 && x < 10.0 && y > 0.0 && y < 6.0;
      const bool wall = !inside && x > -0.05 && x < 10.05 && y > -0.05 && y < 6.05;
      g.cells[r * g.width + c] = inside ? occupancy::kFree : wall ? occupancy::kOccupied : occupancy::kUnknown;
    }
  }
  return g;
}

std::string write_text(const std::string& suffix, const std::string& text) {
  const std::string path = test::temp_path(suffix);
  std::ofstream(path, std::ios::binary) << text;
  return path;
}

TEST(RosMap, ReadsBackWhatItWroteCellForCell) {
  for (const double yaw : {0.0, 0.3}) {
    const OccupancyGrid g = room_grid(yaw);
    const std::string stem = test::temp_path("");
    io::write_ros_map(stem, g);
    const OccupancyGrid back = io::read_ros_map(stem + ".yaml");
    EXPECT_EQ(back.width, g.width);
    EXPECT_EQ(back.height, g.height);
    EXPECT_DOUBLE_EQ(back.resolution, g.resolution);
    EXPECT_NEAR(back.origin.x(), g.origin.x(), 1e-9);
    EXPECT_NEAR(back.origin.y(), g.origin.y(), 1e-9);
    EXPECT_NEAR(back.origin_yaw, yaw, 1e-9);
    EXPECT_EQ(back.cells, g.cells);
  }
}

TEST(RosMap, ClassifiesPixelsAsMapServerDoes) {
  // One row of 4 pixels: black, white, map_server's unknown grey, mid grey.
  const std::string pgm = write_text(".pgm", "P2\n# plain PGM\n4 1\n255\n0 255 205 128\n");
  const std::string name = std::filesystem::path(pgm).filename().string();
  const auto read = [&](const std::string& extra) {
    return io::read_ros_map(
        write_text(".yaml", "image: " + name + "\nresolution: 0.1\norigin: [1.0, 2.0, 0.0]\n" + extra));
  };
  const OccupancyGrid plain = read("");
  ASSERT_EQ(plain.cells.size(), 4u);
  EXPECT_EQ(plain.cells, (std::vector<std::int8_t>{occupancy::kOccupied, occupancy::kFree, occupancy::kUnknown,
                                                   occupancy::kUnknown}));
  // negate: white is occupied; a low occupied threshold takes the mid grey.
  const OccupancyGrid negated = read("negate: 1\noccupied_thresh: 0.45\nfree_thresh: 0.1\n");
  EXPECT_EQ(negated.cells, (std::vector<std::int8_t>{occupancy::kFree, occupancy::kOccupied, occupancy::kOccupied,
                                                     occupancy::kOccupied}));
  // 16-bit binary PGM: values scale to 0..255 (65535 is white: free).
  std::string wide = "P5\n2 1\n65535\n";
  wide += std::string("\xff\xff\x00\x00", 4);
  const std::string wide_pgm = write_text(".pgm", wide);
  const OccupancyGrid w = io::read_ros_map(write_text(
      ".yaml", "image: " + wide_pgm + "\nresolution: 0.1\norigin: [0, 0, 0]\nmode: scale\nunknown_key: 3\n"));
  EXPECT_EQ(w.cells, (std::vector<std::int8_t>{occupancy::kFree, occupancy::kOccupied}));
}

TEST(RosMap, AnImageThatCannotBeReadIsNamedNotAnInternalError) {
  // /proc/self/mem stats as a regular file of 0 bytes and fails to read (EIO).
  const std::string yaml = test::temp_path(".yaml");
  test::write_file(yaml,
                   "image: /proc/self/mem\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\nnegate: 0\n"
                   "occupied_thresh: 0.65\nfree_thresh: 0.196\n");
  try {
    io::read_ros_map(yaml);
    FAIL() << "/proc/self/mem was read as an image";
  } catch (const Error& e) {
    // (Where the kernel lets it read as empty, it is refused as no image instead: named all the same.)
    EXPECT_NE(std::string(e.what()).find("/proc/self/mem"), std::string::npos) << e.what();
  }
}

TEST(RosMap, BadFilesNameTheFileTheKeyAndWhatWasExpected) {
  const std::string pgm = write_text(".pgm", "P5\n2 2\n255\n\x01\x02\x03\x04");
  const std::string name = std::filesystem::path(pgm).filename().string();
  const auto message = [&](const std::string& yaml) {
    const std::string path = write_text(".yaml", yaml);
    try {
      io::read_ros_map(path);
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message("image: " + name + "\norigin: [0, 0, 0]\n").find("expected the key 'resolution'"),
            std::string::npos);
  EXPECT_NE(message("image: " + name + "\nresolution: 0.05\norigin: [0, 0]\n").find(":3: origin: expected [x, y, yaw]"),
            std::string::npos);
  EXPECT_NE(message("image: " + name + "\nresolution: -1\norigin: [0, 0, 0]\n").find("expected > 0 m"),
            std::string::npos);
  EXPECT_NE(message("image: " + name + "\nresolution: abc\norigin: [0, 0, 0]\n").find("expected a finite number"),
            std::string::npos);
  EXPECT_NE(message("image: " + name + "\nresolution: 0.1\norigin: [0, 0, 0]\nmode: colour\n").find("mode"),
            std::string::npos);
  EXPECT_NE(message("image: missing.pgm\nresolution: 0.1\norigin: [0, 0, 0]\n").find("missing.pgm: cannot open"),
            std::string::npos);
  EXPECT_NE(message("image: [a\nresolution: 0.1\n").find("invalid YAML"), std::string::npos);
  const std::string png = write_text(".png", "\x89PNG\r\n");
  EXPECT_NE(message("image: " + png + "\nresolution: 0.1\norigin: [0, 0, 0]\n").find("expected a PGM image"),
            std::string::npos);
  const std::string short_pgm = write_text(".pgm", "P5\n20 20\n255\nabc");
  EXPECT_NE(message("image: " + short_pgm + "\nresolution: 0.1\norigin: [0, 0, 0]\n").find("expected 400 bytes"),
            std::string::npos);
  // A key a letter or two off one map_server reads would be ignored, and the default taken: refused by line.
  EXPECT_NE(message("image: " + name + "\nresolution: 0.1\norigin: [0, 0, 0]\nocupied_thresh: 0.5\n")
                .find(":4: unknown key 'ocupied_thresh'; expected 'occupied_thresh'"),
            std::string::npos);
  EXPECT_EQ(message("image: " + name + "\nresolution: 0.1\norigin: [0, 0, 0]\nmap_id: 7\nframe_id: map\n"), "no error");
  // Bytes after the raster (but whitespace) say the header's width or height is off.
  const std::string long_pgm = write_text(".pgm", "P5\n2 2\n255\n\x01\x02\x03\x04\x05\x06");
  EXPECT_NE(message("image: " + long_pgm + "\nresolution: 0.1\norigin: [0, 0, 0]\n").find("2 bytes follow the 2 x 2"),
            std::string::npos);
  const std::string newline_pgm = write_text(".pgm", "P5\n2 2\n255\n\x01\x02\x03\x04\n");
  EXPECT_EQ(message("image: " + newline_pgm + "\nresolution: 0.1\norigin: [0, 0, 0]\n"), "no error");
  // A plain PGM whose header claims 2^28 pixels in a few bytes: refused before anything is allocated.
  const std::string huge_plain = write_text(".pgm", "P2\n16384 16384\n255\n0 0 0\n");
  EXPECT_NE(message("image: " + huge_plain + "\nresolution: 0.1\norigin: [0, 0, 0]\n")
                .find("expected 268435456 plain pixel values after the header, but only 7 bytes follow"),
            std::string::npos);
}

// What map_server writers and readers put in files besides the basics: a
// stem with YAML syntax in it, a UTM origin kept to the last bit, a 16-bit
// image thresholded at full precision, negate as a boolean, a CR LF header
// refused, a directory named as the YAML, and an upper-case extension.
TEST(RosMap, ReadsWhatOtherToolsWriteAndWritesWhatTheyRead) {
  OccupancyGrid g = room_grid(0.123456789012);
  g.origin = {4512345.678, 5412345.6789};
  const std::string stem = test::temp_path("-map #2: \"quoted\"");
  io::write_ros_map(stem, g);
  const OccupancyGrid back = io::read_ros_map(stem + ".yaml");
  EXPECT_EQ(back.cells, g.cells);
  EXPECT_EQ(back.origin.x(), g.origin.x());
  EXPECT_EQ(back.origin.y(), g.origin.y());
  EXPECT_EQ(back.origin_yaw, g.origin_yaw);
  EXPECT_EQ(back.resolution, g.resolution);

  // p = (65535 - 22938) / 65535 = 0.64999: under occupied_thresh 0.65, so unknown (8-bit rounding made it occupied).
  std::string wide = "P5\n2 1\n65535\n";
  wide += std::string("\x59\x9a\x00\x00", 4);  // 22938, then 0 (black)
  const std::string wide_pgm = write_text(".pgm", wide);
  const auto yaml = [](const std::string& image, const std::string& extra) {
    return write_text(".yaml", "image: " + image + "\nresolution: 0.1\norigin: [0, 0, 0]\n" + extra);
  };
  EXPECT_EQ(io::read_ros_map(yaml(wide_pgm, "")).cells,
            (std::vector<std::int8_t>{occupancy::kUnknown, occupancy::kOccupied}));
  const std::string pgm = write_text(".pgm", "P2\n2 1\n255\n0 255\n");
  EXPECT_EQ(io::read_ros_map(yaml(pgm, "negate: true\n")).cells, io::read_ros_map(yaml(pgm, "negate: 1\n")).cells);
  EXPECT_EQ(io::read_ros_map(yaml(pgm, "negate: false\n")).cells, io::read_ros_map(yaml(pgm, "")).cells);

  const auto message = [](const std::string& path) {
    try {
      io::read_ros_map(path);
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  const std::string crlf = write_text(".pgm", std::string("P5\r\n2 1\r\n255\r\n\x00\xff", 14));
  EXPECT_NE(message(yaml(crlf, "")).find("ends in CR LF"), std::string::npos) << message(yaml(crlf, ""));
  const std::string dir = test::temp_path(".yaml");
  std::filesystem::create_directory(dir);
  EXPECT_THROW(io::read_ros_map(dir), FileError);
  EXPECT_NE(message(dir).find("not a regular file"), std::string::npos) << message(dir);
  // Other tools' nested settings are skipped; a key we read given nested is named as such.
  EXPECT_EQ(io::read_ros_map(yaml(pgm, "plugins: [{name: a}, {name: b}]\nnav2: {x: 1}\n")).cells,
            io::read_ros_map(yaml(pgm, "")).cells);
  const std::string nested_origin =
      write_text(".yaml", "image: " + pgm + "\nresolution: 0.1\norigin: {x: 1, y: 2, yaw: 0}\n");
  EXPECT_NE(message(nested_origin).find(":3: origin: expected a value or a list of numbers"), std::string::npos)
      << message(nested_origin);
  // An image error names the YAML's line too.
  const std::string missing_image = yaml("missing.pgm", "");
  EXPECT_NE(message(missing_image).find(missing_image + ":1: image: "), std::string::npos) << message(missing_image);
  EXPECT_TRUE(io::is_ros_map_path("maps/FLOOR2.YAML") && io::is_ros_map_path("a.Yml"));
  EXPECT_FALSE(io::is_ros_map_path("a.log"));
}

// PNG map images (written here by libpng's own encoder) read as the same
// pixels in a PGM do: grey as is, colour as its channels' mean (map_server's
// rule), alpha ignored, a palette expanded; a 16-bit PNG is refused.
TEST(RosMap, APngImageReadsAsThePgmOfTheSamePixels) {
  const auto write_png = [](const std::vector<std::uint8_t>& samples, std::uint32_t format, std::uint32_t width) {
    png_image png{};
    png.version = PNG_IMAGE_VERSION;
    png.width = width, png.height = 2, png.format = format;
    const std::string path = test::temp_path(".png");
    EXPECT_TRUE(png_image_write_to_file(&png, path.c_str(), 0, samples.data(), 0, nullptr)) << png.message;
    return path;
  };
  const auto grid = [](const std::string& image, const std::string& extra = "") {
    return io::read_ros_map(write_text(".yaml", "image: " + image + "\nresolution: 0.1\norigin: [0, 0, 0]\n" + extra))
        .cells;
  };
  // Occupied (black), free (white), unknown (205) and a p of 0.5 (128: below occupied_thresh 0.65).
  const std::string pgm = write_text(".pgm", "P2\n4 2\n255\n0 255 205 128\n255 0 128 205\n");
  const std::vector<std::uint8_t> grey = {0, 255, 205, 128, 255, 0, 128, 205};
  EXPECT_EQ(grid(write_png(grey, PNG_FORMAT_GRAY, 4)), grid(pgm));
  EXPECT_EQ(grid(write_png(grey, PNG_FORMAT_GRAY, 4), "negate: 1\n"), grid(pgm, "negate: 1\n"));
  EXPECT_EQ(grid(write_png(grey, PNG_FORMAT_GRAY, 4), "mode: raw\n"), grid(pgm, "mode: raw\n"));
  std::vector<std::uint8_t> rgba, ga;
  for (const std::uint8_t v : grey) rgba.insert(rgba.end(), {v, v, v, 17}), ga.insert(ga.end(), {v, 255});
  EXPECT_EQ(grid(write_png(rgba, PNG_FORMAT_RGBA, 4)), grid(pgm));
  EXPECT_EQ(grid(write_png(ga, PNG_FORMAT_GA, 4)), grid(pgm));
  // Colour: p from the channels' mean, (0 + 0 + 255) / 3 = 85 is occupied (p 0.667), (255 + 255 + 0) / 3 = 170 free.
  const std::vector<std::uint8_t> colour = {0, 0, 255, 255, 255, 0, 0, 0, 255, 255, 255, 0};
  const std::string mean_pgm = write_text(".pgm", "P2\n2 2\n255\n85 170\n85 170\n");
  EXPECT_EQ(grid(write_png(colour, PNG_FORMAT_RGB, 2)), grid(mean_pgm));
  const std::vector<std::uint8_t> wide(2 * 2 * 2, 0);
  const std::string wide_png = write_png(wide, PNG_FORMAT_LINEAR_Y, 2);
  try {
    grid(wide_png);
    ADD_FAILURE() << "a 16-bit PNG was read";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("a 16-bit PNG; expected 8 bits per sample"), std::string::npos) << e.what();
  }
}

TEST(GridSubmap, VirtualScansMatchTheRoomsExactDistances) {
  for (const double yaw : {0.0, 0.7}) {
    const OccupancyGrid g = room_grid(yaw);
    const Pose2 corner = g.origin_pose() * Pose2(1.0, 1.0, 0.0);  // the room's (0, 0) in the map frame
    const Pose2 in_room(3.2, 2.1, 0.4);
    GridSubmapConfig config;
    config.beams = 361;
    config.field_of_view = 2.0 * std::numbers::pi;
    const LaserScan scan = cast_virtual_scan(g, corner * in_room, config);
    ASSERT_EQ(scan.size(), 361u);
    for (std::size_t i = 0; i < scan.size(); ++i) {
      // Exact distance from in_room to the rectangle's inner walls along the beam.
      const double a = in_room.theta + scan.bearing(i), dx = std::cos(a), dy = std::sin(a);
      double t = 1e9;
      if (dx > 1e-12) t = std::min(t, (10.0 - in_room.x) / dx);
      if (dx < -1e-12) t = std::min(t, -in_room.x / dx);
      if (dy > 1e-12) t = std::min(t, (6.0 - in_room.y) / dy);
      if (dy < -1e-12) t = std::min(t, -in_room.y / dy);
      ASSERT_EQ(scan.status(i), BeamStatus::kValid) << i;
      // The wall's cell centre lies half a cell behind its face (more along a slanted ray).
      EXPECT_NEAR(scan.ranges[i], t, 0.1) << "beam " << i << " yaw " << yaw;
    }
  }
  // A ray into unknown space is a no-return.
  OccupancyGrid open = room_grid();
  for (std::size_t r = 0; r < open.height; ++r)
    open.cells[r * open.width + 220] = occupancy::kUnknown;  // x = 10 wall gone
  const LaserScan scan = cast_virtual_scan(open, Pose2(5.0, 3.0, 0.0), {});
  EXPECT_EQ(scan.status(scan.size() / 2), BeamStatus::kNoReturn);
}

TEST(GridSubmap, MarksWallsWithTheirNormalsAndTheRoomAsFree) {
  GlobalMap map;
  const OccupancyGrid g = room_grid();
  const GridSubmapStats st = add_grid_submap(map, map.add_submap("room"), g);
  EXPECT_GE(st.positions, 50u);  // a 10 x 6 m room on a 1 m lattice
  EXPECT_EQ(st.virtual_scans, st.positions * 8);
  EXPECT_GT(st.features, 100u);
  EXPECT_EQ(map.stats().features, st.features);
  // The bottom wall (y = 0) faces up into the room, the left wall (x = 0) right.
  EXPECT_TRUE(map.occupancy().probe(0, 5.0, -0.02, std::numbers::pi / 2) & cell_flags::kOccupied);
  EXPECT_FALSE(map.occupancy().probe(0, 5.0, -0.02, -std::numbers::pi / 2) & cell_flags::kOccupied);
  EXPECT_TRUE(map.occupancy().probe(0, -0.02, 3.0, 0.0) & cell_flags::kOccupied);
  EXPECT_FALSE(map.occupancy().probe(0, -0.02, 3.0, std::numbers::pi) & cell_flags::kOccupied);
  EXPECT_TRUE(map.free_space().probe(0, 5.0, 3.0) & cell_flags::kFree);
  EXPECT_FALSE(map.free_space().probe(0, 5.0, 3.0) & cell_flags::kOccupied);
  EXPECT_TRUE(map.free_space().probe(0, 5.0, -0.02) & cell_flags::kReturn);
  EXPECT_FALSE(map.free_space().probe(0, 5.0, -0.5) & cell_flags::kFree);  // unknown behind the wall
  // The submap has scans now: a second grid cannot go into it.
  EXPECT_THROW(add_grid_submap(map, 0, g), Error);
  EXPECT_THROW(add_grid_submap(map, 7, g), Error);
  GridSubmapConfig bad;
  bad.pose_spacing = std::nan("");
  EXPECT_THROW(add_grid_submap(map, map.add_submap("x"), g, bad), Error);
}

TEST(GridSubmap, AGridBeyondTheMapsPoseGridsIsRefusedBeforeTheMapChanges) {
  // A UTM-framed map: its origin 500 km out, past the pose grids' +-13 km.
  GlobalMap map;
  OccupancyGrid far = room_grid();
  far.origin = {500000.0, 5000000.0};
  const std::uint32_t submap = map.add_submap("utm");
  try {
    add_grid_submap(map, submap, far);
    FAIL() << "a grid beyond the pose grids was taken";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("beyond the map's pose grids"), std::string::npos) << e.what();
  }
  EXPECT_EQ(map.stats().features, 0u);
  EXPECT_EQ(map.submap_scans(submap), 0u);
  // The same room near the origin goes in.
  EXPECT_GT(add_grid_submap(map, submap, room_grid()).features, 0u);
}

TEST(GridSubmap, AHugeExtentIsRefusedBeforeItsPositionsAreStored) {
  // 100 x 100 free cells of 50 m (a resolution meant as 0.05): 25 million lattice points, 200 million virtual
  // scans. Counted first, refused by the cap, nothing stored and the map unchanged.
  OccupancyGrid huge;
  huge.width = huge.height = 100;
  huge.resolution = 50.0;
  huge.cells.assign(100 * 100, occupancy::kFree);
  GlobalMap map;
  const std::uint32_t submap = map.add_submap("huge");
  try {
    add_grid_submap(map, submap, huge);
    FAIL() << "a 5 km grid at 1 m spacing was taken";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("virtual scans exceed GridSubmapConfig.max_virtual_scans"), std::string::npos)
        << e.what();
  }
  EXPECT_EQ(map.submap_scans(submap), 0u);
}

TEST(GridSubmap, ARobotLocalizesInAMapBuiltOnlyFromGrids) {
  // Every building of the small world as a ROS map: its mapper's scans turned
  // into an occupancy grid, written and read back, then into a submap.
  const Scenario sc = sim::synthetic_scenario(test::small_world());
  GlobalMap map;
  const GridSubmapConfig config = with_laser_of({}, sc.target.scans.front());
  for (const Submap& s : sc.submaps) {
    const std::string stem = test::temp_path("");
    io::write_ros_map(stem, build_occupancy_grid(s.scans));
    add_grid_submap(map, map.add_submap(s.name), io::read_ros_map(stem + ".yaml"), config);
  }
  const LocalizationRun run = localize_target(map, sc.target, LocalizerConfig{});
  const auto m =
      evaluate_localization(scan_estimates(run), sc.target.truth, static_cast<std::uint32_t>(sc.target_submap));
  ASSERT_TRUE(m.final_error_m.has_value()) << "the final estimate is in the wrong building or absent";
  EXPECT_LT(*m.final_error_m, 0.3);
  EXPECT_LT(*m.final_heading_error_deg, 3.0);
  ASSERT_TRUE(m.localized_at.has_value());
  EXPECT_EQ(m.confident_wrong, 0u);
}

}  // namespace
}  // namespace lshloc
