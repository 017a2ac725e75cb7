#include "lshloc/io/line_reader.hpp"

#include <unistd.h>

#include <zlib.h>

#include <cerrno>
#include <cmath>
#include <charconv>
#include <cstring>
#include <filesystem>

#include "lshloc/common/error.hpp"

namespace lshloc::io {

namespace {
gzFile as_gz(void* p) { return static_cast<gzFile>(p); }
}  // namespace

LineReader::LineReader(std::string path) : path_(std::move(path)), buffer_(1 << 16) {
  if (path_ == "-") {  // stdin, read as it arrives (zlib would wait for a whole buffer)
    from_stdin_ = true;
    return;
  }
  std::error_code ec;
  if (!std::filesystem::exists(path_, ec)) throw Error(path_ + ": no such file");
  if (std::filesystem::is_directory(path_, ec)) throw Error(path_ + ": is a directory, expected a log file");
  gz_ = gzopen(path_.c_str(), "rb");
  if (gz_ == nullptr) throw Error(path_ + ": cannot open: " + std::strerror(errno));
  gzbuffer(as_gz(gz_), 1 << 17);
}

LineReader::~LineReader() {
  if (gz_ != nullptr) gzclose(as_gz(gz_));
}

std::string LineReader::where() const {
  return (from_stdin_ ? std::string("stdin") : path_) + ":" + std::to_string(line_number_);
}

bool LineReader::next_from_stdin(std::string& line) {
  for (;;) {
    const std::size_t newline = pending_.find('\n');
    if (newline != std::string::npos) {
      line.assign(pending_, 0, newline);
      pending_.erase(0, newline + 1);
      break;
    }
    const ssize_t n = ::read(STDIN_FILENO, buffer_.data(), buffer_.size());
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) throw Error(std::string("stdin: cannot read: ") + std::strerror(errno));
    if (n == 0) {
      if (pending_.empty()) return false;
      line.swap(pending_);  // last line without a newline
      pending_.clear();
      break;
    }
    pending_.append(buffer_.data(), static_cast<std::size_t>(n));
  }
  while (!line.empty() && line.back() == '\r') line.pop_back();
  ++line_number_;
  return true;
}

void LineReader::check_stream_error() {
  int err = Z_OK;
  const char* msg = gzerror(as_gz(gz_), &err);
  if (err == Z_OK || err == Z_STREAM_END) return;
  const std::string reason = (err == Z_BUF_ERROR) ? "the gzip stream is truncated (unexpected end of file)"
                                                  : std::string("corrupt gzip data: ") + (msg ? msg : "unknown error");
  throw Error(path_ + ":" + std::to_string(line_number_ + 1) + ": " + reason +
              "; the file is incomplete or damaged, fetch or copy it again");
}

bool LineReader::next(std::string& line) {
  line.clear();
  if (from_stdin_) return next_from_stdin(line);
  for (;;) {
    char* got = gzgets(as_gz(gz_), buffer_.data(), static_cast<int>(buffer_.size()));
    if (got == nullptr) {
      check_stream_error();
      if (line.empty()) return false;
      break;  // last line without a newline
    }
    const std::size_t n = std::strlen(got);
    line.append(got, n);
    if (n > 0 && got[n - 1] == '\n') break;
    // A partial line: either longer than the buffer, or the end of the data.
    if (gzeof(as_gz(gz_))) {
      check_stream_error();
      break;
    }
  }
  while (!line.empty() && (line.back() == '\n' || line.back() == '\r')) line.pop_back();
  ++line_number_;
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
