#include <cstdio>

#include "cli_common.h"
#include "epiloc/cli/commands.h"
#include "epiloc/survey/db_info.h"

namespace epiloc {

int RunInfo(int argc, char** argv) {
  CLI::App app("Summarise a route database: drives, frames, route length, features, schema.",
               "info");
  CommonFlags flags;
  AddCommonFlags(app, flags);
  std::string db_path;
  app.add_option("--db", db_path, "Route database (SQLite)")->required();
  if (auto code = Parse(app, flags, argc, argv)) return *code;
  std::printf("%s", FormatDatabaseInfo(SummarizeDatabase(db_path)).c_str());
  return kExitOk;
}

}  // namespace epiloc
