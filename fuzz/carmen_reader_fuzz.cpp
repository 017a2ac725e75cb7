// libFuzzer target: any bytes read as a CARMEN log, plain or (first byte odd)
// gzip-compressed, either read or are refused with lshloc::Error; never a
// crash, a hang or a runaway allocation.
#include <zlib.h>

#include <cstddef>
#include <cstdint>
#include <vector>

#include "fuzz_input_file.hpp"
#include "lshloc/common/error.hpp"
#include "lshloc/io/carmen_reader.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  // Most inputs are text; compressing some here lets the gzip path see
  // well-formed streams of fuzzed text (raw fuzzed gzip is covered too).
  std::vector<std::uint8_t> bytes(data + 1, data + size);
  if (data[0] & 1) {
    uLongf length = compressBound(static_cast<uLong>(bytes.size())) + 32;
    std::vector<std::uint8_t> gz(length);
    z_stream zs{};
    if (deflateInit2(&zs, 1, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY) != Z_OK) return 0;
    zs.next_in = bytes.data();
    zs.avail_in = static_cast<uInt>(bytes.size());
    zs.next_out = gz.data();
    zs.avail_out = static_cast<uInt>(gz.size());
    const int rc = deflate(&zs, Z_FINISH);
    gz.resize(zs.total_out);
    deflateEnd(&zs);
    if (rc != Z_STREAM_END) return 0;
    if (data[0] & 2) gz.resize(gz.size() / 2);  // and truncated
    bytes = std::move(gz);
  }
  try {
    const lshloc::io::CarmenLog log = lshloc::io::read_carmen_log(lshloc::fuzz::input_file(bytes.data(), bytes.size()));
    (void)log.front_laser_offset();
  } catch (const lshloc::Error&) {
  }
  return 0;
}
