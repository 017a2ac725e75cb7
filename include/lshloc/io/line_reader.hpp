#pragma once
// The text layer under every reader: lines of a plain or gzip file, one at a
// time, and the splitting and number parsing of their fields.
// No physical units.
// Thread safety: a LineReader is one per thread; split_fields and parse_* are
// stateless and safe from any thread.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

namespace lshloc::io {

/// Streams the lines of a text file, plain or gzip-compressed (detected from
/// the content, not the name); the path "-" reads plain text from stdin, each
/// line as soon as it arrives. Lines end at "\n", "\r\n" or a lone "\r"; a
/// UTF-8 byte-order mark before the first line is dropped; a NUL byte, or a
/// line over 16 MiB, throws lshloc::Error naming file:line.
/// A truncated or corrupt gzip stream throws lshloc::Error naming the file and
/// the line where the data ended; concatenated gzip members read as one
/// stream, and bytes after the last member are counted (trailing_bytes()).
/// Not thread-safe; one reader per thread.
class LineReader {
 public:
  explicit LineReader(std::string path);
  ~LineReader();
  LineReader(const LineReader&) = delete;
  LineReader& operator=(const LineReader&) = delete;

  /// Reads the next line without its end-of-line characters. Returns false at
  /// the end of the file.
  bool next(std::string& line);

  const std::string& path() const { return path_; }
  std::size_t line_number() const { return line_number_; }

  /// "path:line" of the line last returned, for error messages.
  std::string where() const;

  /// Bytes after the last gzip member that are no gzip member (skipped;
  /// known once next() returned false). 0 for plain files.
  std::uint64_t trailing_bytes() const { return trailing_bytes_; }

 private:
  struct Source;
  std::size_t read_plain();
  std::size_t read_gzip();
  /// Appends the next chunk of the input to pending_; false at its end.
  bool fill();
  /// The first '\n' or '\r' in pending_ at or after `from` (npos: none).
  std::size_t line_end(std::size_t from) const;
  static constexpr std::size_t kMaxLineBytes = std::size_t{16} << 20;
  std::string path_;
  bool from_stdin_ = false;         ///< path "-": plain text from stdin, line by line as it arrives
  std::unique_ptr<Source> source_;  // the file and zlib's state, kept opaque so that zlib.h stays private
  std::uint64_t trailing_bytes_ = 0;
  std::size_t line_number_ = 0;
  std::vector<char> buffer_;
  std::string pending_;    ///< bytes read, from the next line on (from start_)
  std::size_t start_ = 0;  ///< where the next line starts in pending_
  bool at_end_ = false;    ///< the input has no more bytes
};

/// Splits a line into whitespace-separated fields (views into `line`).
void split_fields(std::string_view line, std::vector<std::string_view>& fields);

/// Splits one CSV row into its fields (RFC 4180: a field in double quotes
/// may hold commas, and "" in it stands for one quote). An unclosed quote or
/// text after a closing one throws lshloc::Error naming `where`.
std::vector<std::string> split_csv_row(std::string_view line, const std::string& where);

/// A CSV file's header row: its columns by name, and its rows checked
/// against it. `expected` says what the file should be, for errors (e.g.
/// "the CSV of `lshloc localize --out`").
class CsvHeader {
 public:
  CsvHeader(std::string_view line, const std::string& where, std::string expected);
  /// The index of column `name`; throws lshloc::Error naming the header's
  /// file:line, the column and what was expected when there is none.
  std::size_t column(std::string_view name) const;
  /// The index of column `name`, or size() where there is none (a column older files lack).
  std::size_t find(std::string_view name) const;
  std::size_t size() const { return names_.size(); }
  /// A row's fields; throws lshloc::Error naming `where` when their count is not the header's.
  std::vector<std::string> row(std::string_view line, const std::string& where) const;

 private:
  std::vector<std::string> names_;
  std::string where_, expected_;
};

/// Parses a field as a number or throws lshloc::Error naming `where`, the
/// field's index and what was expected. Accepts "nan"/"inf" (the caller
/// decides whether they are valid).
double parse_double(std::string_view field, const std::string& where, std::size_t index, const char* what);
long parse_int(std::string_view field, const std::string& where, std::size_t index, const char* what);

}  // namespace lshloc::io
