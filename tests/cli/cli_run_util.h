// Running the epiloc binary from a test: exit code and what it printed.
#pragma once

#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <string>

#include <fmt/format.h>

namespace epiloc {

struct CliRun {
  int exit_code = -1;
  std::string out;  // standard output
  std::string err;  // standard error
};

// Runs `EPILOC_BINARY args` through the shell (args are shell words: quote paths with spaces).
inline CliRun RunCli(const std::string& args) {
  const std::string err_file =
      fmt::format("/tmp/epiloc_cli_run_{}_{}.err", ::getpid(), reinterpret_cast<uintptr_t>(&args));
  const std::string command = fmt::format("{} {} 2>{}", EPILOC_BINARY, args, err_file);
  CliRun run;
  FILE* pipe = popen(command.c_str(), "r");
  std::array<char, 4096> buffer{};
  size_t n = 0;
  while ((n = fread(buffer.data(), 1, buffer.size(), pipe)) > 0) run.out.append(buffer.data(), n);
  const int status = pclose(pipe);
  run.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  if (FILE* err = fopen(err_file.c_str(), "rb")) {
    while ((n = fread(buffer.data(), 1, buffer.size(), err)) > 0) run.err.append(buffer.data(), n);
    fclose(err);
  }
  std::remove(err_file.c_str());
  return run;
}

// Number of non-empty lines.
inline int NumLines(const std::string& text) {
  int lines = 0;
  bool content = false;
  for (const char c : text) {
    if (c == '\n') {
      lines += content ? 1 : 0;
      content = false;
    } else {
      content = true;
    }
  }
  return lines + (content ? 1 : 0);
}

}  // namespace epiloc
