#include "cli_common.h"

#include <cstdio>

#include "epiloc/cli/commands.h"
#include "epiloc/core/logging.h"
#include "epiloc/core/progress.h"

namespace epiloc {

void AddCommonFlags(CLI::App& app, CommonFlags& flags) {
  app.add_flag("-q,--quiet", flags.quiet, "No progress bar; warnings and errors only");
  app.add_flag("-v,--verbose", flags.verbose, "Debug messages on stderr");
  app.set_config("--config", "", "Read options from a TOML/INI file (keys = long option names)");
  app.set_help_flag("-h,--help", "Print this help and exit");
}

std::optional<int> Parse(CLI::App& app, CommonFlags& flags, int argc, char** argv) {
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp&) {
    std::printf("%s", app.help().c_str());
    return kExitOk;
  } catch (const CLI::ParseError& e) {
    std::fprintf(stderr, "epiloc %s: error: %s (see 'epiloc %s --help')\n", app.get_name().c_str(),
                 e.what(), app.get_name().c_str());
    return kExitUsage;
  }
  InitLogging(flags.quiet ? Verbosity::kQuiet
                          : (flags.verbose ? Verbosity::kVerbose : Verbosity::kNormal));
  if (flags.quiet) SetDefaultProgressStyle(ProgressStyle::kQuiet);
  return std::nullopt;
}

}  // namespace epiloc
