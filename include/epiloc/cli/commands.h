// The subcommands of the `epiloc` binary. Each RunXxx parses its arguments (argv[0] is the
// command name) and calls a typed library function; it returns the process exit code. Library
// errors (epiloc::Error) propagate to main, which prints one line and exits 1.
#pragma once

#include <string>
#include <vector>

namespace epiloc {

struct Command {
  std::string name;
  std::string summary;
  int (*run)(int argc, char** argv);
};

// All commands, in the order `epiloc help` lists them.
const std::vector<Command>& Commands();

// The closest command name to a mistyped one, or "" if none is close.
std::string SuggestCommand(const std::string& typed);

int RunSynth(int argc, char** argv);
int RunImportKitti(int argc, char** argv);
int RunBuildDb(int argc, char** argv);
int RunTriangulate(int argc, char** argv);
int RunInfo(int argc, char** argv);
int RunLocalize(int argc, char** argv);
int RunEvaluate(int argc, char** argv);
int RunExport(int argc, char** argv);
int RunBuildMap(int argc, char** argv);
int RunRender(int argc, char** argv);
int RunAnchor(int argc, char** argv);
int RunCalibrateRadial(int argc, char** argv);
int RunVo(int argc, char** argv);
int RunGeoref(int argc, char** argv);
int RunLidarTrack(int argc, char** argv);

// Exit codes.
constexpr int kExitOk = 0;
constexpr int kExitError = 1;  // bad input, I/O or database failure
constexpr int kExitUsage = 2;  // unknown command or option, bad option value

}  // namespace epiloc
