// libFuzzer target: any bytes given to the map loader either load or are
// refused with lshloc::Error; never a crash, a hang or a runaway allocation.
// Build: cmake -DLSHLOC_BUILD_FUZZERS=ON -DCMAKE_CXX_COMPILER=clang++ (fuzz/CMakeLists.txt).
#include <cstddef>
#include <cstdint>
#include <span>

#include "lshloc/common/error.hpp"
#include "lshloc/io/map_store.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    lshloc::io::load_map_bytes(std::span<const std::uint8_t>(data, size), "fuzz");
  } catch (const lshloc::Error&) {
    // A refused file is the expected outcome for almost every input.
  }
  return 0;
}
