#include "cli_common.h"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <set>

#include "epiloc/cli/commands.h"
#include "epiloc/core/csv.h"
#include "epiloc/core/error.h"
#include "epiloc/core/logging.h"
#include "epiloc/core/progress.h"
#include "epiloc/io/drive.h"
#include "epiloc/io/frame_reader.h"

namespace epiloc {

namespace {

// Long option names of `app` without the dashes ("drive", "max-gap-s", ...).
std::vector<std::string> LongOptionNames(const CLI::App& app) {
  std::vector<std::string> names = {"help"};
  for (const CLI::Option* option : app.get_options()) {
    for (const std::string& name : option->get_lnames()) names.push_back(name);
  }
  return names;
}

bool IsOptionTakingValue(const CLI::App& app, const std::string& arg) {
  if (arg.rfind("--", 0) != 0 || arg.find('=') != std::string::npos) return false;
  const CLI::Option* option = app.get_option_no_throw(arg);
  return option != nullptr && option->get_type_size() != 0;
}

// The value after '=' ends where a closing quote or bracket says; false if it never closes.
bool ValueIsClosed(const std::string& value) {
  const char open = value.empty() ? '\0' : value[0];
  if (open == '"' || open == '\'') {
    for (size_t i = 1; i < value.size(); ++i) {
      if (open == '"' && value[i] == '\\') {
        ++i;
        continue;
      }
      if (value[i] == open) {
        const std::string rest = Trim(value.substr(i + 1));
        return rest.empty() || rest[0] == '#' || rest[0] == ';';
      }
    }
    return false;
  }
  if (open == '[') return value.back() == ']';
  return value.find_first_of("\"'") == std::string::npos;
}

size_t EditDistance(const std::string& a, const std::string& b) {
  std::vector<size_t> row(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (size_t i = 1; i <= a.size(); ++i) {
    size_t diagonal = row[0];
    row[0] = i;
    for (size_t j = 1; j <= b.size(); ++j) {
      const size_t above = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diagonal = above;
    }
  }
  return row[b.size()];
}

}  // namespace

std::string Suggest(const std::string& typed, const std::vector<std::string>& names) {
  std::string best;
  size_t best_distance = 3;
  for (const std::string& name : names) {
    const size_t distance = EditDistance(typed, name);
    if (distance < best_distance) {
      best_distance = distance;
      best = name;
    }
  }
  if (best.empty()) {
    for (const std::string& name : names) {
      if (!typed.empty() && name.rfind(typed, 0) == 0) return name;
    }
  }
  return best;
}

void CheckConfigFile(const std::string& path, const std::vector<std::string>& names) {
  std::ifstream in(path, std::ios::binary);
  if (!in) Throw("--config {}: cannot open the file", path);
  std::string text;
  std::set<std::string> seen;
  int64_t line = 0;
  while (ReadLine(in, text, path, line + 1)) {
    ++line;
    if (line == 1 && text.rfind("\xEF\xBB\xBF", 0) == 0) text = text.substr(3);
    const std::string trimmed = Trim(text);
    const std::string where = Where(path, line);
    if (trimmed.empty() || trimmed[0] == '#' || trimmed[0] == ';') continue;
    if (trimmed[0] == '[') {
      if (trimmed == "[default]") continue;
      Throw("{}: section '{}' is not used by epiloc (write the keys without a section)", where,
            Printable(trimmed));
    }
    const size_t equals = trimmed.find('=');
    if (equals == std::string::npos) {
      Throw("{}: expected 'key = value', got '{}'", where, Printable(trimmed, 60));
    }
    std::string key = Trim(trimmed.substr(0, equals));
    if (key.size() >= 2 && (key.front() == '"' || key.front() == '\'') && key.back() == key.front()) {
      key = key.substr(1, key.size() - 2);
    }
    const std::string value = Trim(trimmed.substr(equals + 1));
    if (key.empty() || key.find_first_not_of("abcdefghijklmnopqrstuvwxyz"
                                             "ABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789-_") !=
                           std::string::npos) {
      Throw("{}: '{}' is not an option name", where, Printable(key, 60));
    }
    if (key == "config" ||
        std::find(names.begin(), names.end(), key) == names.end() || key == "help") {
      const std::string suggestion = Suggest(key, names);
      Throw("{}: unknown key '{}'{}", where, key,
            suggestion.empty() ? "" : ", did you mean '" + suggestion + "'?");
    }
    if (value.empty()) Throw("{}: '{}' has no value", where, key);
    if (!ValueIsClosed(value)) {
      Throw("{}: unterminated string or list in the value of '{}'", where, key);
    }
    if (!seen.insert(key).second) Throw("{}: '{}' is given twice", where, key);
  }
  if (in.bad()) Throw("{}: read error", path);
}

void AddScanRangeOptions(CLI::App& app, double& min_range_m, double& max_range_m) {
  app.add_option("--min-range", min_range_m, "Scan points closer to the sensor are dropped, metres")
      ->capture_default_str();
  app.add_option("--max-range", max_range_m,
                 "Scan points farther from the sensor are dropped, metres")
      ->capture_default_str();
}

void AddTrajectoryImportOptions(CLI::App& app,
                                TrajectoryImportOptions& import,
                                std::string& format) {
  app.add_option("--vo-format", format,
                 "auto | tum | kitti | stella_map (stella_vslam map.msg: keyframes and landmarks)")
      ->capture_default_str();
  app.add_option("--vo-times", import.times_path, "KITTI poses: times file (one per line)");
  app.add_option("--time-offset-s", import.time_offset_s,
                 "Added to the trajectory's times (e.g. the UNIX time of its frame 0)")
      ->capture_default_str();
  app.add_flag("--relative-times", import.relative_times,
               "The trajectory's times count from the drive's first frame (ORB-SLAM times.txt)");
}

void SetDriveFrames(const Drive& drive, TrajectoryImportOptions* import) {
  for (const FrameRecord& f : drive.frames) {
    import->frame_times.push_back(f.timestamp_s);
    import->frame_numbers.push_back(f.frame);
  }
}

void AddCommonFlags(CLI::App& app, CommonFlags& flags) {
  app.add_flag("-q,--quiet", flags.quiet, "No progress bar; warnings and errors only");
  app.add_flag("-v,--verbose", flags.verbose, "Debug messages on stderr");
  app.set_config("--config", "", "Read options from a TOML/INI file (keys = long option names)");
  app.set_help_flag("-h,--help", "Print this help and exit");
}

std::optional<int> Parse(CLI::App& app, CommonFlags& flags, int argc, char** argv) {
  // Checked before CLI11 runs: it would report a missing required option before a mistyped one
  // ("--drive is required" for `--dirve`), and takes a malformed config file without a word.
  const std::vector<std::string> names = LongOptionNames(app);
  std::string config_path;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--") break;
    if (arg.rfind("--", 0) != 0 || arg.size() == 2) continue;
    const std::string name = arg.substr(2, arg.find('=') == std::string::npos
                                               ? std::string::npos
                                               : arg.find('=') - 2);
    if (name == "config") {
      if (arg.find('=') != std::string::npos) {
        config_path = arg.substr(arg.find('=') + 1);
      } else if (i + 1 < argc) {
        config_path = argv[i + 1];
      }
      continue;
    }
    if (std::find(names.begin(), names.end(), name) != names.end()) continue;
    // A value that merely starts with "--" (after an option taking one) is not an option.
    if (i > 1 && IsOptionTakingValue(app, argv[i - 1])) continue;
    const std::string suggestion = Suggest(name, names);
    std::fprintf(stderr, "epiloc %s: error: unknown option --%s%s (see 'epiloc %s --help')\n",
                 app.get_name().c_str(), Printable(name).c_str(),
                 suggestion.empty() ? "" : (", did you mean --" + suggestion + "?").c_str(),
                 app.get_name().c_str());
    return kExitUsage;
  }
  if (!config_path.empty()) CheckConfigFile(config_path, names);
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
  if (!flags.verbose) QuietLibraryLogging();
  InitLogging(flags.quiet ? Verbosity::kQuiet
                          : (flags.verbose ? Verbosity::kVerbose : Verbosity::kNormal));
  if (flags.quiet) SetDefaultProgressStyle(ProgressStyle::kQuiet);
  return std::nullopt;
}

std::vector<NamedPath> InputsOf(const std::string& option, const std::string& path) {
  if (path.empty() || path == "-") return {};
  std::error_code error;
  if (!std::filesystem::is_regular_file(std::filesystem::path(path) / "drive.json", error)) {
    return {{option, path}};
  }
  std::vector<NamedPath> inputs;
  for (const std::string& input : DriveInputPaths(path)) {
    inputs.push_back({option, input, std::filesystem::is_directory(input, error)});
  }
  return inputs;
}

void CheckCommandOutputs(const std::vector<NamedPath>& outputs,
                         const std::vector<NamedPath>& inputs) {
  std::vector<NamedPath> expanded;
  for (const NamedPath& input : inputs) {
    for (NamedPath& one : InputsOf(input.option, input.path)) expanded.push_back(std::move(one));
  }
  CheckOutputs(outputs, expanded);
}

}  // namespace epiloc
