#pragma once
// Writing output files so that a crash or a full disk never leaves a
// half-written file under the final name: the bytes go to a temporary file
// beside it, which is fsync'ed and renamed over the final name
// (docs/reliability.md, "Writes").
// No physical units.
// Stateless; safe from any thread on distinct paths.
#include <cstdint>
#include <span>
#include <string>
#include <string_view>

namespace lshloc::io {

/// "PATH: WHAT: strerror(errno)", the message of a failed system call.
std::string system_error(const std::string& path, const std::string& what);

/// Writes all of `data` to `fd` (retrying short writes), or throws
/// lshloc::Error naming `path` (e.g. "No space left on device").
void write_all(int fd, std::span<const std::uint8_t> data, const std::string& path);

/// fsyncs the directory holding `path`, so that a rename in it is durable.
void sync_directory_of(const std::string& path);

/// A name beside `path` for a temporary file, distinct per process and call.
std::string temporary_path_for(const std::string& path);

/// What an output path names: a regular file, or nothing yet (kFile), or a
/// character device or FIFO (kStream: /dev/null, a pipe), which is written
/// into and never replaced. Anything else (a directory, a block device, a
/// socket) throws lshloc::Error naming it.
enum class OutputKind { kFile, kStream };
OutputKind output_kind(const std::string& path);

/// Writes `bytes` to a temporary file beside `path`, fsyncs it, renames it
/// over `path` and fsyncs the directory: `path` then holds all of `bytes`,
/// and on any failure (thrown as lshloc::Error naming the file) its old
/// content or nothing, with no temporary file left. Returns the new file's
/// descriptor, locked (flock) and at its end, for a writer that appends.
/// A path naming anything but a regular file (or nothing) is refused.
int replace_file(const std::string& path, std::span<const std::uint8_t> bytes);

/// Appends printf-formatted text to `out` (outputs are built in memory, then
/// written whole by write_file_atomically).
[[gnu::format(printf, 2, 3)]] void append_format(std::string& out, const char* format, ...);

/// replace_file() for a whole text or binary output, closing the file; a
/// character device or FIFO is written into instead.
void write_file_atomically(const std::string& path, std::string_view bytes);

/// One file of write_files_atomically().
struct FileOutput {
  std::string path;
  std::string_view bytes;
};

/// write_file_atomically() for files that belong together (a ROS map's YAML
/// and its image; character devices and FIFOs among them are written into
/// first): every file is written and fsync'ed beside its path first,
/// then all are renamed into place. A failure before the renames (a full
/// disk) leaves every old file; a failed rename puts back the files renamed
/// before it (from hard links of the old ones). Only a crash between the
/// renames, microseconds apart, can leave new and old files together.
void write_files_atomically(std::span<const FileOutput> files);

/// Throws lshloc::Error naming `path` unless a file can be written there
/// (its directory exists and is writable, and it is no directory itself),
/// or it is a character device or FIFO that can be written into: the check
/// a long run makes before it starts.
void require_writable(const std::string& path);

/// require_writable() for an output replaced whole (a saved map and its
/// journal, replace_file()): a character device or FIFO is refused too, before
/// the run makes what it would write there.
void require_replaceable(const std::string& path);

/// Creates `dir` (and its parents) where it is missing, and throws
/// lshloc::Error naming it, and what it is for (`what`, e.g. "the figure
/// directory"), unless files can be written in it.
void require_writable_directory(const std::string& dir, const std::string& what = "the directory");

}  // namespace lshloc::io
