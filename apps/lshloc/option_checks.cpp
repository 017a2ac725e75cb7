#include "option_checks.hpp"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <string>

namespace lshloc::app {

namespace {

/// The number `text` spells in full, or NaN when it spells none (or NaN).
double parse_whole(const std::string& text) {
  errno = 0;
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || end != text.c_str() + text.size()) return std::nan("");
  // Underflow (1e-400) reads as the nearest double, 0: a number, not an error.
  if (errno == ERANGE && std::abs(v) > 1.0) return std::nan("");
  return v;
}

std::string short_number(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

void attach(CLI::App& app) {
  for (CLI::Option* opt : app.get_options()) {
    const std::string type = opt->get_type_name();
    const bool count = type.rfind("UINT", 0) == 0, integer = type.rfind("INT", 0) == 0,
               real = type.rfind("FLOAT", 0) == 0;
    if (!count && !integer && !real) continue;
    opt->check(CLI::Validator(
        [count, integer](std::string& text) -> std::string {
          const double v = parse_whole(text);
          if (!std::isfinite(v)) return "expected a finite number, got '" + text + "'";
          if ((count || integer) && v != std::floor(v)) return "expected a whole number, got " + text;
          if (count && v < 0) return "expected a count (0 or more), got " + text;
          if ((count || integer) && std::abs(v) > 9.0e15) return "expected a count below 9e15, got " + text;
          return "";
        },
        "", "finite"));
  }
  for (CLI::App* sub : app.get_subcommands({})) attach(*sub);
}

}  // namespace

void check_numeric_options(CLI::App& app) { attach(app); }

CLI::Validator within(double lo, double hi) {
  return CLI::Validator(
      [lo, hi](std::string& text) -> std::string {
        const double v = parse_whole(text);
        if (!(v >= lo && v <= hi))
          return "expected a number in [" + short_number(lo) + ", " + short_number(hi) + "], got '" + text + "'";
        return "";
      },
      "in [" + short_number(lo) + ", " + short_number(hi) + "]");
}

void require_given(std::initializer_list<const CLI::Option*> options) {
  for (const CLI::Option* o : options)
    if (o->count() == 0) throw CLI::RequiredError(o->get_name());
}

}  // namespace lshloc::app
