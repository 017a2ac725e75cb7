#include "lshloc/common/byte_codec.hpp"

#include "lshloc/common/error.hpp"

namespace lshloc {

std::uint64_t ByteReader::varint_at_most(std::uint64_t max, const char* field) {
  const std::size_t at = pos_;
  const std::uint64_t v = varint();
  if (v > max) {
    pos_ = at;
    fail(std::string(field) + " of at most " + std::to_string(max) + ", got " + std::to_string(v));
  }
  return v;
}

std::string ByteReader::string(std::size_t max_size) {
  const auto n = static_cast<std::size_t>(varint_at_most(max_size, "a string length"));
  const auto bytes = raw(n);
  return {bytes.begin(), bytes.end()};
}

void ByteReader::expect_done() {
  if (!done()) fail("the end of the data (" + std::to_string(remaining()) + " bytes left over)");
}

void ByteReader::fail(const std::string& expected) const {
  throw Error(what_ + ", byte " + std::to_string(pos_) + ": expected " + expected);
}

void ByteReader::fail_short(std::size_t n) const {
  throw Error(what_ + ", byte " + std::to_string(pos_) + ": expected " + std::to_string(n) + " more bytes, only " +
              std::to_string(data_.size() - pos_) + " left (truncated)");
}

}  // namespace lshloc
