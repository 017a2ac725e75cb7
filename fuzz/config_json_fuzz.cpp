// libFuzzer target: any bytes given as a --config JSON file either give
// settings that pass every config's validate() or are refused with
// lshloc::Error; never a crash, a hang or a runaway allocation.
#include <cstddef>
#include <cstdint>

#include "fuzz_input_file.hpp"
#include "lshloc/common/error.hpp"
#include "lshloc/io/config_json.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    const nlohmann::json patch = lshloc::io::read_json_file(lshloc::fuzz::input_file(data, size));
    lshloc::RunConfig config;
    lshloc::io::apply_config_patch(patch, config, "fuzz");
    config.map.validate();
    config.localizer.validate();
  } catch (const lshloc::Error&) {
  }
  return 0;
}
