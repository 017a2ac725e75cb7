#pragma once
// The one exception type every lshloc layer throws (docs/design.md section 5,
// "Errors"), and its kind for files that cannot be opened or read.
// No physical units.
// Thread safety: an Error is an immutable value; copy and read it from any thread.
#include <stdexcept>
#include <string>
#include <string_view>
#include <type_traits>

namespace lshloc {

/// The one exception type of lshloc. Its message is meant for the user: it
/// says what was wrong and, where it can, where (file:line) and how to fix it.
class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& what) : std::runtime_error(what) {}
};

/// An Error about a file that cannot be opened, read or written at all
/// (missing, no permission, a full disk, an I/O error): callers may tell it
/// from bad content (Python gets an OSError). The message names the file and
/// the system's reason.
class FileError : public Error {
 public:
  using Error::Error;
};

/// Throws Error("FIELD: expected EXPECTED, got GOT").
[[noreturn]] void throw_requirement(std::string_view field, std::string_view expected, double got);
/// Throws Error("FIELD: expected EXPECTED").
[[noreturn]] void throw_requirement(std::string_view field, std::string_view expected);

/// The one check of config fields: unless `ok`, throws
/// Error("Struct.field: expected EXPECTED, got GOT"), e.g.
/// require(K >= 1, "LshConfig.K", ">= 1", K).
template <class Number>
requires std::is_arithmetic_v<Number>
void require(bool ok, std::string_view field, std::string_view expected, Number got) {
  if (!ok) throw_requirement(field, expected, static_cast<double>(got));
}
/// The same for a field whose value does not print as one number.
inline void require(bool ok, std::string_view field, std::string_view expected) {
  if (!ok) throw_requirement(field, expected);
}

}  // namespace lshloc
