// Shared flag handling of the subcommands (private to the cli module).
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "epiloc/core/output_file.h"
#include "epiloc/georef/trajectory_import.h"
#include "epiloc/io/drive.h"
#include "epiloc/survey/triangulate.h"

namespace epiloc {

struct CommonFlags {
  bool quiet = false;    // no progress bar, warnings and errors only
  bool verbose = false;  // debug messages
};

// Adds --quiet, --verbose and --config FILE (options from a TOML/INI file) to a command.
void AddCommonFlags(CLI::App& app, CommonFlags& flags);

// Adds --min-range and --max-range (a LiDAR scan's points kept by their distance from the sensor).
void AddScanRangeOptions(CLI::App& app, double& min_range_m, double& max_range_m);

// Adds --vo-format (into `format`), --vo-times, --time-offset-s and --relative-times: how a
// monocular trajectory given with --vo is read and put on the drive's clock
// (georef/trajectory_import.h).
void AddTrajectoryImportOptions(CLI::App& app,
                                TrajectoryImportOptions& import,
                                std::string& format);

// Puts the import on `drive`'s clock: its frame times and numbers (a pose within 1 ms of a frame
// takes that frame's number; KITTI poses without a times file take the frames' times).
void SetDriveFrames(const Drive& drive, TrajectoryImportOptions* import);

// Parses argv; on success applies the common flags (logging, progress style) and returns nullopt;
// otherwise prints help (exit 0) or one error line plus a hint (exit 2) and returns the code.
// An unknown --option is named first (with the closest known one), before CLI11 reports missing
// required options; a --config file is checked by CheckConfigFile first.
std::optional<int> Parse(CLI::App& app, CommonFlags& flags, int argc, char** argv);

// The known name closest to `typed` (at most 2 edits), else the first one it begins, else "".
std::string Suggest(const std::string& typed, const std::vector<std::string>& names);

// Checks a --config file line by line (TOML / INI: `key = value`, '#' or ';' comments, an
// optional [default] section): throws Error "FILE:LINE: ..." for a line that is not `key = value`,
// a key that is not one of `names` (long option names), an unterminated quoted string or list,
// an empty value or a key given twice.
void CheckConfigFile(const std::string& path, const std::vector<std::string>& names);

// The inputs a path option stands for: a drive directory (one holding drive.json) gives the files
// and folders its manifest names (image folders as folder_contents), anything else the path
// itself. Empty paths give nothing.
std::vector<NamedPath> InputsOf(const std::string& option, const std::string& path);

// CheckOutputs(outputs, inputs) with the inputs expanded by InputsOf.
void CheckCommandOutputs(const std::vector<NamedPath>& outputs,
                         const std::vector<NamedPath>& inputs);

// One line of triangulation figures on stdout (triangulate and build-db).
void PrintTriangulateSummary(const TriangulateSummary& summary);

}  // namespace epiloc
