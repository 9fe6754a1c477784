#include "epiloc/core/progress.h"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <exception>

#include <fmt/format.h>

namespace epiloc {
namespace {

std::atomic<ProgressStyle> g_default_style{ProgressStyle::kAuto};

constexpr int kBarWidth = 24;
// Plain-line mode prints at most this often, so logs stay short.
constexpr double kLineIntervalS = 5.0;
// Bar mode redraws at most this often.
constexpr double kBarIntervalS = 0.1;

}  // namespace

void SetDefaultProgressStyle(ProgressStyle style) { g_default_style = style; }
ProgressStyle DefaultProgressStyle() { return g_default_style; }

std::string FormatDuration(double seconds) {
  if (!std::isfinite(seconds) || seconds < 0) return "?";
  const int64_t s = static_cast<int64_t>(std::llround(seconds));
  if (s >= 3600) return fmt::format("{}h{:02d}m", s / 3600, (s % 3600) / 60);
  if (s >= 60) return fmt::format("{}m{:02d}s", s / 60, s % 60);
  return fmt::format("{}s", s);
}

Progress::Progress(std::string label, int64_t total, ProgressStyle style)
    : label_(std::move(label)), total_(std::max<int64_t>(total, 0)), style_(style) {
  if (style_ == ProgressStyle::kAuto) {
    style_ = isatty(STDERR_FILENO) ? ProgressStyle::kBar : ProgressStyle::kLines;
  }
  start_ = last_print_ = std::chrono::steady_clock::now();
  uncaught_at_start_ = std::uncaught_exceptions();
}

Progress::~Progress() {
  // Unwinding from an error: the error line is what the user should see, not a last bar.
  if (std::uncaught_exceptions() > uncaught_at_start_) return;
  Finish();
}

void Progress::Add(int64_t n) {
  std::lock_guard<std::mutex> lock(mutex_);
  done_ += n;
  Render(false);
}

void Progress::Set(int64_t done) {
  std::lock_guard<std::mutex> lock(mutex_);
  done_ = done;
  Render(false);
}

void Progress::Finish() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (finished_) return;
  finished_ = true;
  Render(true);
}

void Progress::SetTotal(int64_t total) {
  std::lock_guard<std::mutex> lock(mutex_);
  total_ = std::max<int64_t>(total, 0);
}

ProgressCallback Progress::Callback() {
  return [this](int64_t done, int64_t total) {
    SetTotal(total);
    Set(done);
  };
}

std::string Progress::Line() const {
  const double elapsed =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  const double rate = elapsed > 0 ? static_cast<double>(done_) / elapsed : 0.0;
  std::string line = label_;
  if (total_ > 0) {
    const double fraction = std::clamp(static_cast<double>(done_) / total_, 0.0, 1.0);
    const int filled = static_cast<int>(fraction * kBarWidth);
    std::string bar(kBarWidth, ' ');
    std::fill(bar.begin(), bar.begin() + filled, '=');
    if (filled < kBarWidth) bar[filled] = '>';
    const double eta = rate > 0 ? (total_ - done_) / rate : NAN;
    line += fmt::format(" [{}] {}/{} {:3.0f}% {:.1f}/s ETA {}", bar, done_, total_,
                        100.0 * fraction, rate, FormatDuration(eta));
  } else {
    line += fmt::format(" {} {:.1f}/s", done_, rate);
  }
  line += fmt::format(" elapsed {}", FormatDuration(elapsed));
  return line;
}

void Progress::Render(bool final) {
  if (style_ == ProgressStyle::kQuiet) return;
  const auto now = std::chrono::steady_clock::now();
  const double since = std::chrono::duration<double>(now - last_print_).count();
  if (style_ == ProgressStyle::kBar) {
    if (!final && since < kBarIntervalS) return;
    std::fprintf(stderr, "\r%s\033[K%s", Line().c_str(), final ? "\n" : "");
  } else {
    if (!final && since < kLineIntervalS) return;
    std::fprintf(stderr, "%s\n", Line().c_str());
  }
  std::fflush(stderr);
  last_print_ = now;
}

}  // namespace epiloc
