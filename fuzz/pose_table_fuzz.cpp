// libFuzzer target: any bytes read as a poses file (`timestamp x y theta`),
// a relations file and a TUM trajectory either read or are refused with
// lshloc::Error; never a crash, a hang or a runaway allocation.
#include <cstddef>
#include <cstdint>

#include "fuzz_input_file.hpp"
#include "lshloc/common/error.hpp"
#include "lshloc/io/ground_truth.hpp"
#include "lshloc/io/trajectory_writer.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = lshloc::fuzz::input_file(data, size);
  try {
    (void)lshloc::io::read_pose_file(path);
  } catch (const lshloc::Error&) {
  }
  try {
    (void)lshloc::io::read_relations(path);
  } catch (const lshloc::Error&) {
  }
  try {
    (void)lshloc::io::read_tum_trajectory(path);
  } catch (const lshloc::Error&) {
  }
  return 0;
}
