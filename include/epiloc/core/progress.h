// Progress reporting for long work: a bar with rate and ETA on a terminal, plain lines otherwise.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <mutex>
#include <string>

namespace epiloc {

// Long algorithms take a callback instead of printing (done and total in the caller's units).
using ProgressCallback = std::function<void(int64_t done, int64_t total)>;

enum class ProgressStyle {
  kAuto,   // bar on a terminal, plain lines when stderr is not a TTY
  kBar,    // always redraw one line with '\r'
  kLines,  // one line every few seconds and at the end
  kQuiet,  // nothing
};

// Sets the style used by Progress objects created afterwards (the CLI's --quiet sets kQuiet).
void SetDefaultProgressStyle(ProgressStyle style);
ProgressStyle DefaultProgressStyle();

// A thread-safe progress display on stderr. Add() may be called from worker threads.
//   Progress progress("build-db", num_frames);
//   for (...) { ...; progress.Add(); }
//   progress.Finish();
class Progress {
 public:
  Progress(std::string label, int64_t total, ProgressStyle style = DefaultProgressStyle());
  ~Progress();
  Progress(const Progress&) = delete;
  Progress& operator=(const Progress&) = delete;

  // Counts `n` more units done.
  void Add(int64_t n = 1);
  // Sets the count of units done (e.g. when resuming).
  void Set(int64_t done);
  // Prints the final line once; called by the destructor if not called before (unless the
  // destructor runs because of an exception).
  void Finish();
  // Changes the total (when it becomes known only once work starts).
  void SetTotal(int64_t total);
  // A ProgressCallback that forwards to SetTotal() and Set().
  ProgressCallback Callback();

  // The line as it would be printed now (for tests), e.g.
  // "build-db [=====>    ] 77/154 50% 12.3 frames/s ETA 6s".
  std::string Line() const;

 private:
  void Render(bool final);

  std::string label_;
  int64_t total_;
  int64_t done_ = 0;
  ProgressStyle style_;
  bool finished_ = false;
  int uncaught_at_start_ = 0;
  std::chrono::steady_clock::time_point start_;
  std::chrono::steady_clock::time_point last_print_;
  mutable std::mutex mutex_;
};

// "1h02m", "3m05s", "12s".
std::string FormatDuration(double seconds);

}  // namespace epiloc
