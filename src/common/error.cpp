#include "lshloc/common/error.hpp"

#include <cstdio>

namespace lshloc {

void throw_requirement(std::string_view field, std::string_view expected, double got) {
  char value[32];
  std::snprintf(value, sizeof value, "%.10g", got);
  throw Error(std::string(field) + ": expected " + std::string(expected) + ", got " + value);
}

void throw_requirement(std::string_view field, std::string_view expected) {
  throw Error(std::string(field) + ": expected " + std::string(expected));
}

}  // namespace lshloc
