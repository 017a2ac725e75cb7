// libFuzzer target: any bytes read as a ROS occupancy-grid map (map_server's
// YAML and its PGM image) either read or are refused with lshloc::Error;
// never a crash, a hang or a runaway allocation. The input is the YAML's
// text, a NUL byte, then the image's bytes; the image key is set here (first,
// so a fuzzed image key repeats it).
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>

#include "fuzz_input_file.hpp"
#include "lshloc/common/error.hpp"
#include "lshloc/io/ros_map.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::size_t split = 0;
  while (split < size && data[split] != 0) ++split;
  const std::size_t image_from = split < size ? split + 1 : size;
  const std::string image = lshloc::fuzz::input_file(data + image_from, size - image_from, 1);
  const std::string yaml = "image: " + std::filesystem::path(image).filename().string() + "\n" +
                           std::string(reinterpret_cast<const char*>(data), split);
  try {
    (void)lshloc::io::read_ros_map(
        lshloc::fuzz::input_file(reinterpret_cast<const std::uint8_t*>(yaml.data()), yaml.size(), 0));
  } catch (const lshloc::Error&) {
  }
  return 0;
}
