// A synthetic world generated once per option set and shared by the test processes (CTest runs
// every test in its own process, several at a time).
#pragma once

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "epiloc/synth/drive_gen.h"

namespace epiloc {

// The world `options` describe, in <temp>/<name>; `name` must change with the options (carry a
// version). Generated into a private directory and renamed, so concurrent test processes never
// see a partial world; a process that loses the race removes its copy.
inline std::string SharedWorld(const std::string& name, const SynthOptions& options) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() / name;
  if (fs::exists(dir / "complete")) return dir.string();
  const fs::path tmp = dir.string() + ".tmp." + std::to_string(::getpid());
  fs::remove_all(tmp);
  GenerateSynthetic(options, tmp.string());
  { std::ofstream(tmp / "complete") << "ok\n"; }
  std::error_code error;
  fs::rename(tmp, dir, error);
  if (error) fs::remove_all(tmp);  // another process was first
  return dir.string();
}

}  // namespace epiloc
