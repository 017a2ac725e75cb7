#include "lshloc/io/line_reader.hpp"

#include <unistd.h>

#include <zlib.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <charconv>
#include <cstdio>
#include <cstring>
#include <memory>
#include <filesystem>
#include <string_view>

#include "lshloc/common/error.hpp"

namespace lshloc::io {

namespace {

constexpr const char* kBagAdvice =
    "; lshloc reads CARMEN logs: convert the bag with lshloc-rosbag-to-carmen BAG --out run.log.gz "
    "(scripts/tools/rosbag_to_carmen.py in the source tree)";

/// What a binary file that users give in place of a text file is, by its
/// first bytes (empty: none we know).
std::string known_binary_format(const unsigned char* bytes, std::size_t n) {
  const auto starts = [&](std::string_view magic) {
    return n >= magic.size() && std::memcmp(bytes, magic.data(), magic.size()) == 0;
  };
  if (starts("SQLite format 3")) return std::string("a ROS 2 bag (sqlite3 storage)") + kBagAdvice;
  if (starts("\x89MCAP")) return std::string("a ROS 2 bag (MCAP storage)") + kBagAdvice;
  if (starts("#ROSBAG V")) return std::string("a ROS 1 bag") + kBagAdvice;
  if (starts("\x28\xb5\x2f\xfd")) return "zstd-compressed (a rosbag2 storage file?): decompress it, or convert the bag";
  const char* map_advice = ": a ROS map is given by its YAML file (MAP.yaml, which names the image)";
  if (starts("\x89PNG")) return std::string("a PNG image") + map_advice;
  if (n >= 3 && bytes[0] == 'P' && (bytes[1] == '2' || bytes[1] == '5') && std::isspace(bytes[2]) != 0)
    return std::string("a PGM image") + map_advice;
  return {};
}

}  // namespace

/// The raw file and, for gzip input, the inflate state (zlib's own gzread
/// would skip bytes after the last gzip member without a word).
struct LineReader::Source {
  std::FILE* file = nullptr;
  bool gzip = false;
  z_stream zs{};
  bool zs_open = false;
  bool member_ended = false;      ///< the last inflate() finished a gzip member
  std::vector<unsigned char> in;  ///< raw bytes read, sized to the file up to 128 KiB
  ~Source() {
    if (zs_open) inflateEnd(&zs);
    if (file != nullptr) std::fclose(file);
  }
  /// Reads more of the file behind the unread input (kept, moved to the
  /// front); false when nothing more was read.
  bool read_more(const std::string& path) {
    const std::size_t kept = zs.avail_in;
    if (kept > 0 && zs.next_in != in.data()) std::memmove(in.data(), zs.next_in, kept);
    const std::size_t n = std::fread(in.data() + kept, 1, in.size() - kept, file);
    if (n == 0 && std::ferror(file)) throw FileError(path + ": cannot read: " + std::strerror(errno));
    zs.next_in = in.data();
    zs.avail_in = static_cast<uInt>(kept + n);
    return n > 0;
  }
};

LineReader::LineReader(std::string path) : path_(std::move(path)) {
  constexpr std::size_t kLineBytes = std::size_t{1} << 16;
  if (path_ == "-") {  // stdin, read as it arrives (zlib would wait for a whole buffer)
    from_stdin_ = true;
    buffer_.resize(kLineBytes);
    return;
  }
  std::error_code ec;
  if (!std::filesystem::exists(path_, ec)) throw FileError(path_ + ": no such file");
  if (std::filesystem::is_directory(path_, ec)) {
    if (std::filesystem::exists(std::filesystem::path(path_) / "metadata.yaml", ec))
      throw FileError(path_ + ": is a ROS 2 bag directory" + kBagAdvice);
    throw FileError(path_ + ": is a directory, expected a log file");
  }
  source_ = std::make_unique<Source>();
  source_->file = std::fopen(path_.c_str(), "rb");
  if (source_->file == nullptr) throw FileError(path_ + ": cannot open: " + std::strerror(errno));
  // Small files get small buffers (a reader per poses file, per fuzz input).
  constexpr std::size_t kInputBytes = std::size_t{1} << 17;
  std::error_code size_ec;
  const auto size = std::filesystem::file_size(path_, size_ec);
  source_->in.resize(size_ec ? kInputBytes : std::clamp<std::size_t>(size, 4096, kInputBytes));
  source_->read_more(path_);
  if (const std::string format = known_binary_format(source_->in.data(), source_->zs.avail_in); !format.empty())
    throw FileError(path_ + ": is " + format);
  // gzip is told by its magic bytes, not by the name.
  source_->gzip = source_->zs.avail_in >= 2 && source_->in[0] == 0x1f && source_->in[1] == 0x8b;
  if (source_->gzip) {
    if (inflateInit2(&source_->zs, 15 + 16) != Z_OK) throw Error(path_ + ": cannot start gzip decoding");
    source_->zs_open = true;
  }
  buffer_.resize(source_->gzip ? kLineBytes : std::min(source_->in.size(), kLineBytes));
}

LineReader::~LineReader() = default;

std::string LineReader::where() const {
  return (from_stdin_ ? std::string("stdin") : path_) + ":" + std::to_string(line_number_);
}

std::size_t LineReader::read_plain() {
  Source& src = *source_;
  if (src.zs.avail_in == 0) {
    // Past the bytes read to sniff the format: straight into the line buffer.
    const std::size_t n = std::fread(buffer_.data(), 1, buffer_.size(), src.file);
    if (n == 0 && std::ferror(src.file)) throw FileError(path_ + ": cannot read: " + std::strerror(errno));
    return n;
  }
  const std::size_t n = std::min<std::size_t>(src.zs.avail_in, buffer_.size());
  std::memcpy(buffer_.data(), src.zs.next_in, n);
  src.zs.next_in += n;
  src.zs.avail_in -= static_cast<uInt>(n);
  return n;
}

std::size_t LineReader::read_gzip() {
  Source& src = *source_;
  const auto fail = [&](const std::string& reason) {
    throw Error(path_ + ":" + std::to_string(line_number_ + 1) + ": " + reason +
                "; the file is incomplete or damaged, fetch or copy it again");
  };
  for (;;) {
    if (src.zs.avail_in == 0 && !src.read_more(path_)) {
      if (!src.member_ended) fail("the gzip stream is truncated (unexpected end of file)");
      return 0;
    }
    if (src.member_ended) {
      // After a member: another member (concatenated gzip), or bytes that are
      // none. Too few bytes to tell a gzip header: read on behind them.
      if (src.zs.avail_in < 2) src.read_more(path_);
      if (!(src.zs.next_in[0] == 0x1f && src.zs.avail_in >= 2 && src.zs.next_in[1] == 0x8b)) {
        do {
          trailing_bytes_ += src.zs.avail_in;
          src.zs.avail_in = 0;
        } while (src.read_more(path_));
        return 0;
      }
      inflateReset(&src.zs);
      src.member_ended = false;
    }
    src.zs.next_out = reinterpret_cast<Bytef*>(buffer_.data());
    src.zs.avail_out = static_cast<uInt>(buffer_.size());
    const int rc = inflate(&src.zs, Z_NO_FLUSH);
    if (rc == Z_STREAM_END) {
      src.member_ended = true;
    } else if (rc != Z_OK && rc != Z_BUF_ERROR) {
      fail(std::string("corrupt gzip data: ") + (src.zs.msg ? src.zs.msg : "unknown error"));
    }
    const std::size_t got = buffer_.size() - src.zs.avail_out;
    if (got > 0) return got;
  }
}

bool LineReader::fill() {
  if (start_ > 0) {  // drop the lines already returned before appending
    pending_.erase(0, start_);
    start_ = 0;
  }
  std::size_t got = 0;
  if (from_stdin_) {
    for (;;) {
      const ssize_t n = ::read(STDIN_FILENO, buffer_.data(), buffer_.size());
      if (n < 0 && errno == EINTR) continue;
      if (n < 0) throw FileError(std::string("stdin: cannot read: ") + std::strerror(errno));
      got = static_cast<std::size_t>(n);
      break;
    }
    // A stream is plain text, read as it arrives (zlib would wait for whole buffers): say so for gzip.
    if (line_number_ == 0 && pending_.empty() && got >= 2 && static_cast<unsigned char>(buffer_[0]) == 0x1f &&
        static_cast<unsigned char>(buffer_[1]) == 0x8b)
      throw Error(
          "stdin: gzip data; a log on stdin is read as plain text: pipe it through zcat (a log file may be gzip)");
  } else {
    got = source_->gzip ? read_gzip() : read_plain();
  }
  if (got == 0) return false;
  pending_.append(buffer_.data(), got);
  return true;
}

std::size_t LineReader::line_end(std::size_t from) const {
  // memchr twice (vectorized) rather than one find_first_of: reading logs is
  // line splitting above all.
  const char* data = pending_.data();
  const std::size_t size = pending_.size();
  if (from >= size) return std::string::npos;
  const auto* nl = static_cast<const char*>(std::memchr(data + from, '\n', size - from));
  const std::size_t limit = nl ? static_cast<std::size_t>(nl - data) : size;
  const auto* cr = static_cast<const char*>(std::memchr(data + from, '\r', limit - from));
  if (cr != nullptr) return static_cast<std::size_t>(cr - data);
  return nl ? limit : std::string::npos;
}

bool LineReader::next(std::string& line) {
  line.clear();
  std::size_t from = 0;  // where to look for the line's end, relative to start_
  for (;;) {
    const std::size_t end = line_end(start_ + from);
    // A '\r' as the last byte read may be the first half of "\r\n": decide once more is read.
    if (end != std::string::npos && !(pending_[end] == '\r' && end + 1 == pending_.size() && !at_end_)) {
      const bool crlf = pending_[end] == '\r' && end + 1 < pending_.size() && pending_[end + 1] == '\n';
      line.assign(pending_, start_, end - start_);
      start_ = end + (crlf ? 2 : 1);
      break;
    }
    from = (end != std::string::npos ? end : pending_.size()) - start_;
    if (from > kMaxLineBytes)
      throw Error(path_ + ":" + std::to_string(line_number_ + 1) + ": a line longer than " +
                  std::to_string(kMaxLineBytes >> 20) + " MiB; expected a text log");
    if (!at_end_ && fill()) continue;
    at_end_ = true;
    if (end != std::string::npos) continue;  // a final lone '\r' ends the last line
    if (start_ >= pending_.size()) return false;
    line.assign(pending_, start_, std::string::npos);  // the last line, without a line end
    start_ = pending_.size();
    break;
  }
  ++line_number_;
  if (line_number_ == 1 && line.starts_with("\xEF\xBB\xBF")) line.erase(0, 3);  // a UTF-8 byte-order mark
  if (const std::size_t nul = line.find('\0'); nul != std::string::npos)
    throw Error(where() + ": a NUL byte at column " + std::to_string(nul + 1) +
                "; expected a text line (is this a binary file?)");
  return true;
}

void split_fields(std::string_view line, std::vector<std::string_view>& fields) {
  fields.clear();
  std::size_t i = 0;
  const std::size_t n = line.size();
  while (i < n) {
    while (i < n && (line[i] == ' ' || line[i] == '\t')) ++i;
    if (i >= n) break;
    const std::size_t start = i;
    while (i < n && line[i] != ' ' && line[i] != '\t') ++i;
    fields.push_back(line.substr(start, i - start));
  }
}

std::vector<std::string> split_csv_row(std::string_view line, const std::string& where) {
  std::vector<std::string> fields(1);
  std::size_t i = 0;
  while (i < line.size()) {
    const char c = line[i++];
    if (c == ',') {
      fields.emplace_back();
    } else if (c != '"' || !fields.back().empty()) {
      fields.back() += c;
    } else {  // a quoted field, up to its closing quote
      for (;;) {
        if (i >= line.size()) throw Error(where + ": a quoted CSV field is not closed");
        if (line[i] != '"') {
          fields.back() += line[i++];
        } else if (i + 1 < line.size() && line[i + 1] == '"') {
          fields.back() += '"', i += 2;
        } else {
          ++i;
          break;
        }
      }
      if (i < line.size() && line[i] != ',')
        throw Error(where + ": text after a quoted CSV field's closing quote (expected a comma)");
    }
  }
  return fields;
}

CsvHeader::CsvHeader(std::string_view line, const std::string& where, std::string expected)
    : names_(split_csv_row(line, where)), where_(where), expected_(std::move(expected)) {}

std::size_t CsvHeader::find(std::string_view name) const {
  return static_cast<std::size_t>(std::find(names_.begin(), names_.end(), name) - names_.begin());
}

std::size_t CsvHeader::column(std::string_view name) const {
  const std::size_t at = find(name);
  if (at == names_.size()) throw Error(where_ + ": no column \"" + std::string(name) + "\"; expected " + expected_);
  return at;
}

std::vector<std::string> CsvHeader::row(std::string_view line, const std::string& where) const {
  std::vector<std::string> fields = split_csv_row(line, where);
  if (fields.size() != names_.size())
    throw Error(where + ": " + std::to_string(fields.size()) + " fields; expected " + std::to_string(names_.size()) +
                " as in the header");
  return fields;
}

double parse_double(std::string_view field, const std::string& where, std::size_t index, const char* what) {
  double v = 0.0;
  const char* first = field.data();
  const char* last = field.data() + field.size();
  if (first != last && *first == '+') ++first;
  const auto [ptr, ec] = std::from_chars(first, last, v);
  if (ec == std::errc::result_out_of_range) return (first != last && *first == '-') ? -HUGE_VAL : HUGE_VAL;
  if (ec != std::errc() || ptr != last || first == last) {
    throw Error(where + ": field " + std::to_string(index + 1) + " is '" + std::string(field) + "', expected " + what +
                " (a number)");
  }
  return v;
}

long parse_int(std::string_view field, const std::string& where, std::size_t index, const char* what) {
  long v = 0;
  const auto [ptr, ec] = std::from_chars(field.data(), field.data() + field.size(), v);
  if (ec != std::errc() || ptr != field.data() + field.size() || field.empty()) {
    throw Error(where + ": field " + std::to_string(index + 1) + " is '" + std::string(field) + "', expected " + what +
                " (an integer)");
  }
  return v;
}

}  // namespace lshloc::io
