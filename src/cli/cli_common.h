// Shared flag handling of the subcommands (private to the cli module).
#pragma once

#include <optional>
#include <string>

#include <CLI/CLI.hpp>

#include "epiloc/survey/triangulate.h"

namespace epiloc {

struct CommonFlags {
  bool quiet = false;    // no progress bar, warnings and errors only
  bool verbose = false;  // debug messages
};

// Adds --quiet, --verbose and --config FILE (options from a TOML/INI file) to a command.
void AddCommonFlags(CLI::App& app, CommonFlags& flags);

// Parses argv; on success applies the common flags (logging, progress style) and returns nullopt;
// otherwise prints help (exit 0) or one error line plus a hint (exit 2) and returns the code.
std::optional<int> Parse(CLI::App& app, CommonFlags& flags, int argc, char** argv);

// One line of triangulation figures on stdout (triangulate and build-db).
void PrintTriangulateSummary(const TriangulateSummary& summary);

}  // namespace epiloc
