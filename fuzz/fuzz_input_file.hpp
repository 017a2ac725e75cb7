#pragma once
// The readers take file paths: each fuzz input becomes the contents of one
// in-memory file (memfd), read through /proc/self/fd like any other path.
#include <sys/mman.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

namespace lshloc::fuzz {

/// The path of an in-memory file now holding exactly `data`. One file per
/// slot (0 or 1) and process, rewritten for each input (libFuzzer runs
/// inputs one at a time).
inline std::string input_file(const std::uint8_t* data, std::size_t size, int slot = 0) {
  static const int fds[2] = {memfd_create("fuzz-input-0", 0), memfd_create("fuzz-input-1", 0)};
  if (slot < 0 || slot > 1 || fds[slot] < 0) std::abort();
  const int fd = fds[slot];
  if (ftruncate(fd, 0) != 0) std::abort();
  std::size_t done = 0;
  while (done < size) {
    const ssize_t n = pwrite(fd, data + done, size - done, static_cast<off_t>(done));
    if (n <= 0) std::abort();
    done += static_cast<std::size_t>(n);
  }
  return "/proc/self/fd/" + std::to_string(fd);
}

}  // namespace lshloc::fuzz
