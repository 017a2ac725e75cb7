#pragma once
// Little-endian byte encoding of the structures a map snapshot holds
// (docs/map-format.md): fixed-width integers and floats, LEB128 varints, and
// a bounds-checked reader whose errors name what it was reading.
// No physical units.
// Thread safety: a ByteWriter or ByteReader is one caller's value; nothing
// is shared.
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <span>
#include <string>
#include <vector>

namespace lshloc {

/// Appends encoded values to a byte vector; the byte order is little-endian
/// whatever the host's.
class ByteWriter {
 public:
  void u8(std::uint8_t v) { bytes_.push_back(v); }
  void u32(std::uint32_t v) { fixed<4>(v); }
  void u64(std::uint64_t v) { fixed<8>(v); }
  void f32(float v) {
    std::uint32_t u;
    std::memcpy(&u, &v, 4);
    u32(u);
  }
  void f64(double v) {
    std::uint64_t u;
    std::memcpy(&u, &v, 8);
    u64(u);
  }
  /// LEB128: 7 bits per byte, low bits first (1 byte below 128).
  void varint(std::uint64_t v) {
    while (v >= 0x80) {
      bytes_.push_back(static_cast<std::uint8_t>(v | 0x80));
      v >>= 7;
    }
    bytes_.push_back(static_cast<std::uint8_t>(v));
  }
  /// A signed value as a varint of its zigzag form (small magnitudes stay short).
  void signed_varint(std::int64_t v) {
    varint((static_cast<std::uint64_t>(v) << 1) ^ static_cast<std::uint64_t>(v >> 63));
  }
  /// A varint length, then the bytes.
  void string(const std::string& s) {
    varint(s.size());
    bytes_.insert(bytes_.end(), s.begin(), s.end());
  }
  void raw(std::span<const std::uint8_t> data) { bytes_.insert(bytes_.end(), data.begin(), data.end()); }

  /// Room for n bytes in all, when the caller knows the size ahead.
  void reserve(std::size_t n) { bytes_.reserve(n); }
  std::size_t size() const { return bytes_.size(); }
  const std::vector<std::uint8_t>& bytes() const { return bytes_; }
  std::vector<std::uint8_t> take() { return std::move(bytes_); }

 private:
  template <int N>
  void fixed(std::uint64_t v) {
    std::uint8_t b[N];
    for (int i = 0; i < N; ++i) b[i] = static_cast<std::uint8_t>(v >> (8 * i));
    bytes_.insert(bytes_.end(), b, b + N);
  }
  std::vector<std::uint8_t> bytes_;
};

/// Reads what a ByteWriter wrote. Every read is bounds-checked: reading past
/// the end, or a varint over 64 bits, throws lshloc::Error naming `what`
/// (e.g. "map.lsh: section database") and the byte offset.
class ByteReader {
 public:
  ByteReader(std::span<const std::uint8_t> data, std::string what) : data_(data), what_(std::move(what)) {}

  std::uint8_t u8() {
    need(1);
    return data_[pos_++];
  }
  std::uint32_t u32() {
    need(4);
    std::uint32_t v = 0;
    for (int i = 0; i < 4; ++i) v |= static_cast<std::uint32_t>(data_[pos_ + i]) << (8 * i);
    pos_ += 4;
    return v;
  }
  std::uint64_t u64() {
    need(8);
    std::uint64_t v = 0;
    for (int i = 0; i < 8; ++i) v |= static_cast<std::uint64_t>(data_[pos_ + i]) << (8 * i);
    pos_ += 8;
    return v;
  }
  float f32() {
    const std::uint32_t u = u32();
    float v;
    std::memcpy(&v, &u, 4);
    return v;
  }
  double f64() {
    const std::uint64_t u = u64();
    double v;
    std::memcpy(&v, &u, 8);
    return v;
  }
  std::uint64_t varint() {
    std::uint64_t v = 0;
    for (int shift = 0; shift < 64; shift += 7) {
      const std::uint8_t b = u8();
      v |= static_cast<std::uint64_t>(b & 0x7f) << shift;
      if ((b & 0x80) == 0) return v;
    }
    fail("a varint of more than 64 bits");
  }
  std::int64_t signed_varint() {
    const std::uint64_t u = varint();
    return static_cast<std::int64_t>((u >> 1) ^ (~(u & 1) + 1));
  }
  /// A varint that must be at most `max` (a count or an index): `field` names
  /// it in the error.
  std::uint64_t varint_at_most(std::uint64_t max, const char* field);
  std::string string(std::size_t max_size = 1 << 20);
  std::span<const std::uint8_t> raw(std::size_t n) {
    need(n);
    const auto out = data_.subspan(pos_, n);
    pos_ += n;
    return out;
  }

  std::size_t offset() const { return pos_; }
  std::size_t remaining() const { return data_.size() - pos_; }
  bool done() const { return pos_ == data_.size(); }
  /// Throws unless every byte was read (a payload longer than its content is corrupt).
  void expect_done();
  /// Throws lshloc::Error "WHAT, byte OFFSET: expected EXPECTED".
  [[noreturn]] void fail(const std::string& expected) const;

 private:
  void need(std::size_t n) const {
    if (n > data_.size() - pos_) fail_short(n);
  }
  [[noreturn]] void fail_short(std::size_t n) const;

  std::span<const std::uint8_t> data_;
  std::string what_;
  std::size_t pos_ = 0;
};

}  // namespace lshloc
