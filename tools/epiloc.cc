// epiloc: locate a vehicle along a surveyed road from a dashcam and a cheap GPS.
// `epiloc <command> [options]`; `epiloc help` lists the commands.
#include <malloc.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <exception>
#include <string>

#include "epiloc/cli/commands.h"
#include "epiloc/core/error.h"

namespace {

void PrintUsage() {
  std::printf("epiloc %s: locate a vehicle along a surveyed road from a dashcam and a cheap GPS\n\n",
              EPILOC_VERSION);
  std::printf("usage: epiloc <command> [options]    (epiloc <command> --help for its options)\n\n");
  std::printf("commands:\n");
  for (const epiloc::Command& command : epiloc::Commands()) {
    std::printf("  %-14s %s\n", command.name.c_str(), command.summary.c_str());
  }
  std::printf("  %-14s %s\n", "help", "Print this list");
}

// A message as one line on a terminal: line breaks (OpenCV's exception texts have them) become
// spaces, other control bytes (from input files) are shown as \xNN.
std::string OneLine(const std::string& message) {
  std::string line;
  for (size_t i = 0; i < message.size(); ++i) {
    const unsigned char c = static_cast<unsigned char>(message[i]);
    if (c == '\n' || c == '\r') {
      if (!line.empty() && line.back() != ' ') line += ' ';
    } else if (c < 0x20 || c == 0x7f) {
      char hex[8];
      std::snprintf(hex, sizeof(hex), "\\x%02x", c);
      line += hex;
    } else {
      line += static_cast<char>(c);
    }
  }
  while (!line.empty() && line.back() == ' ') line.pop_back();
  // A value quoted whole (a 20 MB field) would make a 20 MB line: keep its start and its end,
  // where the file name and the verdict are.
  constexpr size_t kMaxBytes = 2000;
  if (line.size() > kMaxBytes) {
    line = line.substr(0, kMaxBytes - 300) + " [...] " + line.substr(line.size() - 300);
  }
  return line;
}

// Keeps freed image buffers in the heap for the next frame. glibc serves blocks above
// M_MMAP_THRESHOLD with a fresh mmap each time and returns them on free, so every frame's SIFT
// pyramid (tens of MB of float images) was page-faulted and zeroed again: 13 % of the CPU time
// of localizing a 1080p drive went to the kernel. Peak memory is unchanged (the same buffers,
// reused). Programs linking the library choose their own allocator policy.
void KeepImageBuffers() {
  constexpr int kMmapThreshold = 256 << 20;  // larger than any per-frame buffer
  constexpr int kTrimThreshold = 512 << 20;  // free memory kept before it is returned
  mallopt(M_MMAP_THRESHOLD, kMmapThreshold);
  mallopt(M_TRIM_THRESHOLD, kTrimThreshold);
}

}  // namespace

int main(int argc, char** argv) {
  KeepImageBuffers();
  if (argc < 2) {
    std::fprintf(stderr, "epiloc: no command given (see 'epiloc help')\n");
    return epiloc::kExitUsage;
  }
  if (std::strcmp(argv[1], "help") == 0 || std::strcmp(argv[1], "--help") == 0 ||
      std::strcmp(argv[1], "-h") == 0) {
    PrintUsage();
    return epiloc::kExitOk;
  }
  if (std::strcmp(argv[1], "--version") == 0 || std::strcmp(argv[1], "version") == 0) {
    std::printf("epiloc %s\n", EPILOC_VERSION);
    return epiloc::kExitOk;
  }
  const std::string name = argv[1];
  for (const epiloc::Command& command : epiloc::Commands()) {
    if (command.name != name) continue;
    try {
      const int code = command.run(argc - 1, argv + 1);
      // Data printed on standard output (info's summary, a table) that could not be written is a
      // failure: `epiloc info > /dev/full` exited 0.
      if (std::fflush(stdout) != 0 || std::ferror(stdout)) {
        std::fprintf(stderr, "epiloc %s: error: standard output: write failed (%s)\n",
                     name.c_str(), std::strerror(errno));
        return epiloc::kExitError;
      }
      return code;
    } catch (const epiloc::Error& e) {
      std::fprintf(stderr, "epiloc %s: error: %s\n", name.c_str(), OneLine(e.what()).c_str());
    } catch (const std::exception& e) {
      std::fprintf(stderr, "epiloc %s: error: %s\n", name.c_str(), OneLine(e.what()).c_str());
    }
    return epiloc::kExitError;
  }
  const std::string suggestion = epiloc::SuggestCommand(name);
  std::fprintf(stderr, "epiloc: unknown command '%s'%s (see 'epiloc help')\n",
               OneLine(name).c_str(),
               suggestion.empty() ? "" : (", did you mean '" + suggestion + "'?").c_str());
  return epiloc::kExitUsage;
}
