#pragma once
// Checks of numeric command-line options: what no setting means is refused
// at parse time, before any file is read (docs/reliability.md, "Limits").
#include <CLI/CLI.hpp>

namespace lshloc::app {

/// Adds to every numeric option of `app` and of its subcommands (by CLI11's
/// type name UINT, INT or FLOAT) a check that refuses non-numbers, NaN and
/// infinities, and negative or fractional counts (CLI11 alone would read
/// "-1" as 2^64 - 1).
void check_numeric_options(CLI::App& app);

/// A check: a number in [lo, hi], for sizes whose larger values would only
/// exhaust memory or time.
CLI::Validator within(double lo, double hi);

/// Options a run needs but --print-config does not: CLI11's required() would
/// refuse `--print-config` alone, so the command's callback asks for them
/// after its --print-config check. Throws CLI11's "NAME is required" error.
void require_given(std::initializer_list<const CLI::Option*> options);

}  // namespace lshloc::app
