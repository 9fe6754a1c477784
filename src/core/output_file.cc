#include "epiloc/core/output_file.h"

#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <system_error>

#include "epiloc/core/error.h"

namespace epiloc {
namespace {

namespace fs = std::filesystem;

// The temporary files of the AtomicFiles alive now, for the signal handler: a run stopped by
// SIGINT, SIGTERM or SIGHUP (Ctrl-C, kill, a closed terminal) removes them before it dies
// instead of leaving ".out.csv.tmp-<pid>-<n>.csv" files beside its outputs.
constexpr int kMaxLiveTemps = 64;
std::atomic<const char*> g_live_temps[kMaxLiveTemps];

extern "C" void RemoveTempsAndDie(int signal_number) {
  for (std::atomic<const char*>& slot : g_live_temps) {
    const char* path = slot.load();
    if (path != nullptr) ::unlink(path);  // async-signal-safe
  }
  ::signal(signal_number, SIG_DFL);
  ::raise(signal_number);
}

void InstallSignalHandlers() {
  static std::atomic<bool> installed{false};
  if (installed.exchange(true)) return;
  for (const int signal_number : {SIGINT, SIGTERM, SIGHUP}) {
    struct sigaction old = {};
    if (::sigaction(signal_number, nullptr, &old) != 0) continue;
    // An ignored signal (nohup, a background job) stays ignored; another handler stays.
    if ((old.sa_flags & SA_SIGINFO) != 0 || old.sa_handler != SIG_DFL) continue;
    struct sigaction action = {};
    action.sa_handler = RemoveTempsAndDie;
    sigemptyset(&action.sa_mask);
    ::sigaction(signal_number, &action, nullptr);
  }
}

void RegisterTemp(const char* path) {
  InstallSignalHandlers();
  for (std::atomic<const char*>& slot : g_live_temps) {
    const char* expected = nullptr;
    if (slot.compare_exchange_strong(expected, path)) return;
  }
  // More than kMaxLiveTemps open outputs: this one is not removed on a signal.
}

void UnregisterTemp(const char* path) {
  for (std::atomic<const char*>& slot : g_live_temps) {
    const char* expected = path;
    if (slot.compare_exchange_strong(expected, nullptr)) return;
  }
}

fs::path FolderOf(const std::string& path) {
  const fs::path parent = fs::path(path).parent_path();
  return parent.empty() ? fs::path(".") : parent;
}

std::string TempName(const std::string& path) {
  static std::atomic<unsigned> counter{0};
  const fs::path p(path);
  return (FolderOf(path) / ("." + p.filename().string() + ".tmp-" + std::to_string(getpid()) +
                            "-" + std::to_string(counter++) + p.extension().string()))
      .string();
}

// True if `path` exists (links followed) and is neither a regular file nor a folder: a device
// such as /dev/null or /dev/full, a FIFO, a socket. Such an output is written in place: a
// temporary file renamed over it would replace the device node itself (as root) instead of
// writing to it.
bool IsSpecialFile(const std::string& path) {
  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);
  return !ec && fs::exists(status) && !fs::is_regular_file(status) && !fs::is_directory(status);
}

// Where an atomic write of `path` renames its file to: the file a symbolic link points to (the
// link stays a link), else `path`.
std::string RenameTarget(const std::string& path) {
  std::error_code ec;
  if (!fs::is_symlink(fs::symlink_status(path, ec))) return path;
  const fs::path target = fs::canonical(path, ec);
  return ec ? path : target.string();
}

fs::path Resolved(const std::string& path) {
  std::error_code ec;
  return fs::weakly_canonical(fs::absolute(path, ec), ec).lexically_normal();
}

}  // namespace

bool IsWithinFolder(const std::string& path, const std::string& folder) {
  const fs::path p = Resolved(path);
  const fs::path f = Resolved(folder);
  auto pi = p.begin();
  for (auto fi = f.begin(); fi != f.end(); ++fi) {
    if (fi->empty()) continue;  // the trailing "" of "dir/"
    if (pi == p.end() || *pi != *fi) return false;
    ++pi;
  }
  return true;
}

namespace {

// True if `path` lies inside the folder `folder`, not the folder itself (after resolving both).
bool IsInside(const std::string& path, const std::string& folder) {
  return IsWithinFolder(path, folder) && Resolved(path) != Resolved(folder);
}

}  // namespace

bool SameFile(const std::string& a, const std::string& b) {
  if (a.empty() || b.empty()) return false;
  std::error_code ec;
  if (fs::exists(a, ec) && fs::exists(b, ec)) {
    const bool same = fs::equivalent(a, b, ec);
    if (!ec) return same;
  }
  return Resolved(a) == Resolved(b);
}

void CheckWritable(const std::string& path, const std::string& option) {
  std::error_code ec;
  if (fs::is_directory(path, ec)) Throw("{} {}: is a folder, expected a file name", option, path);
  if (IsSpecialFile(path)) {
    if (::access(path.c_str(), W_OK) != 0) {
      Throw("{} {}: cannot write ({})", option, path, std::strerror(errno));
    }
    return;  // written in place (AtomicFile)
  }
  const fs::path folder = FolderOf(path);
  if (!fs::is_directory(folder, ec)) {
    Throw("{} {}: folder {} does not exist", option, path, folder.string());
  }
  // Creating a file is the only reliable test (access(2) ignores read-only mounts for root and
  // ACLs); the probe is what the atomic write will do.
  const std::string probe = TempName(path);
  std::FILE* f = std::fopen(probe.c_str(), "wx");
  if (!f) {
    Throw("{} {}: cannot create a file in {} ({})", option, path, folder.string(),
          std::strerror(errno));
  }
  std::fclose(f);
  fs::remove(probe, ec);
}

void CheckOutputs(const std::vector<NamedPath>& outputs, const std::vector<NamedPath>& inputs) {
  for (size_t i = 0; i < outputs.size(); ++i) {
    const NamedPath& out = outputs[i];
    if (out.path.empty() || out.path == "-") continue;
    for (const NamedPath& in : inputs) {
      if (in.folder_contents && IsInside(out.path, in.path)) {
        Throw("{} {} is inside the input folder {} {}: refusing to write into an input",
              out.option, out.path, in.option, in.path);
      }
      if (SameFile(out.path, in.path)) {
        Throw("{} {} is the same file as the input {} {}: refusing to overwrite an input",
              out.option, out.path, in.option, in.path);
      }
    }
    for (size_t j = 0; j < i; ++j) {
      if (outputs[j].path != "-" && SameFile(out.path, outputs[j].path)) {
        Throw("{} {} is the same file as {} {}", out.option, out.path, outputs[j].option,
              outputs[j].path);
      }
    }
  }
  for (const NamedPath& out : outputs) {
    if (!out.path.empty() && out.path != "-") CheckWritable(out.path, out.option);
  }
}

AtomicFile::AtomicFile(const std::string& path) : path_(path) {
  // CSV and NMEA writers stream "-" to standard output themselves; any other writer would make a
  // file named "-" (export --out - did, and printed its summary on stdout as if it had streamed).
  if (path == "-") Throw("--out -: this output cannot go to standard output; give a file name");
  if (IsSpecialFile(path)) {
    in_place_ = true;
    temp_path_ = path;
  } else {
    temp_path_ = TempName(RenameTarget(path));
    RegisterTemp(temp_path_.c_str());
  }
}

AtomicFile::~AtomicFile() { Discard(); }

void AtomicFile::Commit() {
  if (done_) return;
  if (in_place_) {
    done_ = true;
    return;
  }
  std::error_code ec;
  fs::rename(temp_path_, RenameTarget(path_), ec);
  if (ec) {
    Discard();
    Throw("{}: cannot write ({})", path_, ec.message());
  }
  UnregisterTemp(temp_path_.c_str());
  done_ = true;
}

void AtomicFile::Discard() {
  if (done_ || in_place_) {
    done_ = true;
    return;
  }
  std::error_code ec;
  fs::remove(temp_path_, ec);
  UnregisterTemp(temp_path_.c_str());
  done_ = true;
}

AtomicOfstream::AtomicOfstream(const std::string& path, std::ios::openmode mode)
    : file_(path), out_(file_.temp_path(), mode | std::ios::out) {
  if (!out_) Throw("{}: cannot open for writing", path);
}

void AtomicOfstream::Commit() {
  out_.flush();
  const bool ok = static_cast<bool>(out_);
  out_.close();
  if (!ok || out_.fail()) {
    file_.Discard();
    Throw("{}: write failed", file_.path());
  }
  file_.Commit();
}

}  // namespace epiloc
