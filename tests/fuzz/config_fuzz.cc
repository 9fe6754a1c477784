// --config files (TOML/INI subset): the line checker, then CLI11's own reader on what passed.
#include <cstdint>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "cli_common.h"
#include "epiloc/core/error.h"
#include "fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = epiloc::fuzz::WriteInput("config.toml", data, size);
  static const std::vector<std::string> kNames = {"help", "quiet", "verbose", "drive", "db",
                                                  "threads", "max-gap-s", "positions"};
  try {
    epiloc::CheckConfigFile(path, kNames);
  } catch (const epiloc::Error&) {
    return 0;
  }
  // Accepted: CLI11 must read it without surprises (its own errors are ParseError).
  CLI::App app("fuzz", "fuzz");
  std::string drive, db, positions;
  int threads = 0;
  double max_gap_s = 0;
  bool quiet = false, verbose = false;
  app.add_option("--drive", drive);
  app.add_option("--db", db);
  app.add_option("--positions", positions);
  app.add_option("--threads", threads);
  app.add_option("--max-gap-s", max_gap_s);
  app.add_flag("--quiet", quiet);
  app.add_flag("--verbose", verbose);
  app.set_config("--config");
  const std::string arg0 = "fuzz", arg1 = "--config", arg2 = path;
  char* argv[] = {const_cast<char*>(arg0.c_str()), const_cast<char*>(arg1.c_str()),
                  const_cast<char*>(arg2.c_str())};
  try {
    app.parse(3, argv);
  } catch (const CLI::ParseError&) {
  }
  return 0;
}
