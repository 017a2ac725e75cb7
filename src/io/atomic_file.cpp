#include "lshloc/io/atomic_file.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdarg>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <vector>

#include "lshloc/common/error.hpp"

namespace lshloc::io {

std::string system_error(const std::string& path, const std::string& what) {
  return path + ": " + what + ": " + std::strerror(errno);
}

void write_all(int fd, std::span<const std::uint8_t> data, const std::string& path) {
  while (!data.empty()) {
    const ssize_t n = ::write(fd, data.data(), data.size());
    if (n < 0) {
      if (errno == EINTR) continue;
      throw FileError(system_error(path, "cannot write"));
    }
    data = data.subspan(static_cast<std::size_t>(n));
  }
}

void sync_directory_of(const std::string& path) {
  const std::filesystem::path dir = std::filesystem::path(path).parent_path();
  const std::string name = dir.empty() ? "." : dir.string();
  const int fd = ::open(name.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) throw FileError(system_error(name, "cannot open the directory to sync it"));
  const int rc = ::fsync(fd);
  ::close(fd);
  if (rc != 0) throw FileError(system_error(name, "cannot sync the directory"));
}

std::string temporary_path_for(const std::string& path) {
  // Unique per process and call: two outputs of one run never share a temp.
  static std::atomic<unsigned> serial{0};
  return path + ".tmp." + std::to_string(::getpid()) + "." + std::to_string(serial++);
}

OutputKind output_kind(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) {
    if (errno == ENOENT) return OutputKind::kFile;
    throw FileError(system_error(path, "cannot look at what it names"));
  }
  if (S_ISREG(st.st_mode)) return OutputKind::kFile;
  if (S_ISCHR(st.st_mode) || S_ISFIFO(st.st_mode)) return OutputKind::kStream;
  const char* what = S_ISDIR(st.st_mode)    ? "a directory"
                     : S_ISBLK(st.st_mode)  ? "a block device"
                     : S_ISSOCK(st.st_mode) ? "a socket"
                                            : "not a regular file";
  throw Error(path + ": is " + what + "; expected a file name to write (or a character device or FIFO to write into)");
}

namespace {

/// Writes `bytes` into a character device or FIFO as it is (nothing to replace there).
void write_into_stream(const std::string& path, std::string_view bytes) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CLOEXEC);
  if (fd < 0) throw FileError(system_error(path, "cannot open to write"));
  try {
    write_all(fd, {reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size()}, path);
  } catch (...) {
    ::close(fd);
    throw;
  }
  if (::close(fd) != 0) throw FileError(system_error(path, "cannot write"));
}

}  // namespace

namespace {

void refuse_stream(const std::string& path) {
  if (output_kind(path) != OutputKind::kFile)
    throw Error(path +
                ": is a character device or FIFO; expected a file name (this output is replaced whole, "
                "and a device is never replaced)");
}

}  // namespace

int replace_file(const std::string& path, std::span<const std::uint8_t> bytes) {
  refuse_stream(path);
  const std::string tmp = temporary_path_for(path);
  const int fd = ::open(tmp.c_str(), O_RDWR | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) throw FileError(system_error(path, "cannot create its temporary file " + tmp));
  try {
    if (::flock(fd, LOCK_EX | LOCK_NB) != 0) throw FileError(system_error(tmp, "cannot lock"));
    write_all(fd, bytes, tmp);
    if (::fsync(fd) != 0) throw FileError(system_error(tmp, "cannot sync"));
    if (::rename(tmp.c_str(), path.c_str()) != 0) throw FileError(system_error(path, "cannot replace it with " + tmp));
  } catch (...) {
    ::close(fd);
    ::unlink(tmp.c_str());
    throw;
  }
  sync_directory_of(path);
  return fd;
}

void append_format(std::string& out, const char* format, ...) {
  std::va_list args;
  va_start(args, format);
  std::va_list again;
  va_copy(again, args);
  const int n = std::vsnprintf(nullptr, 0, format, args);
  va_end(args);
  if (n > 0) {
    const std::size_t at = out.size();
    out.resize(at + static_cast<std::size_t>(n) + 1);
    std::vsnprintf(out.data() + at, static_cast<std::size_t>(n) + 1, format, again);
    out.resize(at + static_cast<std::size_t>(n));
  }
  va_end(again);
}

void write_file_atomically(const std::string& path, std::string_view bytes) {
  if (output_kind(path) == OutputKind::kStream) return write_into_stream(path, bytes);
  ::close(replace_file(path, {reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size()}));
}

void write_files_atomically(std::span<const FileOutput> all) {
  // Devices and FIFOs are written into, first; the regular files are replaced together.
  std::vector<FileOutput> files;
  for (const FileOutput& f : all) {
    if (output_kind(f.path) == OutputKind::kStream)
      write_into_stream(f.path, f.bytes);
    else
      files.push_back(f);
  }
  // backups[i]: a hard link to the old files[i]; empty when there was none,
  // and then `existed[i]` says whether an old file (that cannot be linked) is replaced.
  std::vector<std::string> temporaries, backups;
  std::vector<bool> existed;
  std::size_t renamed = 0;
  const auto remove_leftovers = [&] {
    for (std::size_t i = renamed; i < temporaries.size(); ++i) ::unlink(temporaries[i].c_str());
    for (const std::string& b : backups)
      if (!b.empty()) ::unlink(b.c_str());
  };
  try {
    for (const FileOutput& f : files) {
      temporaries.push_back(temporary_path_for(f.path));
      const std::string& tmp = temporaries.back();
      const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
      if (fd < 0) throw FileError(system_error(f.path, "cannot create its temporary file " + tmp));
      try {
        write_all(fd, {reinterpret_cast<const std::uint8_t*>(f.bytes.data()), f.bytes.size()}, tmp);
        if (::fsync(fd) != 0) throw FileError(system_error(tmp, "cannot sync"));
      } catch (...) {
        ::close(fd);
        throw;
      }
      ::close(fd);
    }
    for (const FileOutput& f : files) {
      const std::string backup = temporary_path_for(f.path);
      const bool linked = ::link(f.path.c_str(), backup.c_str()) == 0;
      backups.push_back(linked ? backup : std::string());
      existed.push_back(linked || errno != ENOENT);
    }
    for (; renamed < files.size(); ++renamed) {
      if (::rename(temporaries[renamed].c_str(), files[renamed].path.c_str()) == 0) continue;
      const std::string why = system_error(files[renamed].path, "cannot replace it with " + temporaries[renamed]);
      for (std::size_t i = 0; i < renamed; ++i) {  // put the old files back
        if (backups[i].empty()) {
          if (!existed[i]) ::unlink(files[i].path.c_str());  // (an old file without a link stays replaced)
        } else if (::rename(backups[i].c_str(), files[i].path.c_str()) == 0) {
          backups[i].clear();
        }
      }
      throw Error(why);
    }
  } catch (...) {
    remove_leftovers();
    throw;
  }
  remove_leftovers();
  for (const FileOutput& f : files) sync_directory_of(f.path);
}

void require_writable(const std::string& path) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (output_kind(path) == OutputKind::kStream) {
    if (::access(path.c_str(), W_OK) != 0) throw FileError(system_error(path, "cannot write"));
    return;
  }
  const fs::path dir = fs::path(path).parent_path();
  const std::string name = dir.empty() ? "." : dir.string();
  if (!fs::is_directory(name, ec))
    throw FileError(path + ": cannot write here (the directory " + name + " does not exist)");
  if (::access(name.c_str(), W_OK) != 0) throw FileError(system_error(path, "cannot write in " + name));
}

void require_replaceable(const std::string& path) {
  refuse_stream(path);
  require_writable(path);
}

void require_writable_directory(const std::string& dir, const std::string& what) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw Error(dir + ": cannot create " + what + ": " + ec.message());
  require_writable(dir + "/file");
}

}  // namespace lshloc::io
