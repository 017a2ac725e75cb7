// libFuzzer target: any bytes read as a live map's stream entry (a map log
// record, docs/fleet.md) either decode or are refused with lshloc::Error;
// never a crash or a runaway allocation. Each input is tried as it is (mostly
// refused by its checksum) and sealed with a valid checksum, so that the
// decoding behind the checksum is reached too.
#include <zlib.h>

#include <cstddef>
#include <cstdint>
#include <string>

#include "lshloc/common/error.hpp"
#include "lshloc/fleet/map_log.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string raw(reinterpret_cast<const char*>(data), size);
  std::string sealed(raw);
  const auto crc = static_cast<std::uint32_t>(crc32_z(crc32_z(0L, Z_NULL, 0), data, size));
  for (int i = 0; i < 4; ++i) sealed.push_back(static_cast<char>((crc >> (8 * i)) & 0xff));
  for (const std::string* record : {&raw, static_cast<const std::string*>(&sealed)}) {
    lshloc::fleet::MapUpdate update;
    try {
      lshloc::fleet::decode_update(*record, "fuzz entry", update);
    } catch (const lshloc::Error&) {
    }
  }
  return 0;
}
