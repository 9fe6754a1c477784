// Logging setup. Library code logs through spdlog's default logger (spdlog::info, ...), which
// writes to stderr; data goes to stdout or files.
#pragma once

namespace epiloc {

enum class Verbosity { kQuiet, kNormal, kVerbose };

// Installs a stderr logger: kQuiet shows warnings and errors only, kVerbose adds debug messages.
void InitLogging(Verbosity verbosity);

}  // namespace epiloc
