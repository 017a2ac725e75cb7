#pragma once
#include <stdexcept>
#include <string>

namespace lshloc {

/// The one exception type of lshloc. Its message is meant for the user: it
/// says what was wrong and, where it can, where (file:line) and how to fix it.
class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& what) : std::runtime_error(what) {}
};

}  // namespace lshloc
