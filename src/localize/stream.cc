#include "epiloc/localize/stream.h"

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <exception>
#include <future>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "epiloc/core/error.h"

namespace epiloc {
namespace {

using Clock = std::chrono::steady_clock;

// Linear interpolation between order statistics (as the evaluator's percentiles).
double Percentile(std::vector<double> values, double p) {
  if (values.empty()) return 0.0;
  std::sort(values.begin(), values.end());
  const double rank = p * static_cast<double>(values.size() - 1);
  const size_t lo = static_cast<size_t>(rank);
  const size_t hi = std::min(lo + 1, values.size() - 1);
  return values[lo] + (values[hi] - values[lo]) * (rank - static_cast<double>(lo));
}

// Names a frame in a message: "<frames.csv>:<line>: frame 7", "<video> frame 7" (the video's
// `where` already says which frame) or "frame 7".
std::string FrameSubject(const std::string& where, frame_t frame) {
  if (where.empty()) return fmt::format("frame {}", frame);
  const std::string suffix = fmt::format(" frame {}", frame);
  if (where.size() >= suffix.size() &&
      where.compare(where.size() - suffix.size(), suffix.size(), suffix) == 0) {
    return where;
  }
  return fmt::format("{}: frame {}", where, frame);
}

// Frames read and prepared ahead of the tracker, in order, at most `depth` at a time. While the
// queue is full, a live source is still polled, so that frames are stamped when they arrive; with
// `max_latency_s` > 0, a frame already that late with a newer one arrived is dropped unread.
class PrepareQueue {
 public:
  struct Entry {
    std::future<PreparedFrame> prepared;
    std::optional<QueryFrame> unread;  // a frame dropped unread (no image, no features)
  };

  PrepareQueue(const Localizer& localizer, FrameSource& source, int depth, double max_latency_s)
      : localizer_(localizer), source_(source), depth_(depth), max_latency_s_(max_latency_s) {
    producer_ = std::thread([this] { Produce(); });
  }
  ~PrepareQueue() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    changed_.notify_all();
    producer_.join();
  }

  // Whether a newer frame has arrived behind the one popped last (queued, or seen by the
  // source's last poll).
  bool HasWaiting() {
    std::lock_guard<std::mutex> lock(mutex_);
    return !queue_.empty() || arrived_ > 0;
  }

  // The next entry; none at the end of the input. Rethrows a source error.
  std::optional<Entry> Pop() {
    std::unique_lock<std::mutex> lock(mutex_);
    changed_.wait(lock, [this] { return !queue_.empty() || done_; });
    if (queue_.empty()) {
      if (error_) std::rethrow_exception(error_);
      return std::nullopt;
    }
    Entry next = std::move(queue_.front());
    queue_.pop_front();
    changed_.notify_all();
    return next;
  }

 private:
  // How often a live source is polled while the queue is full (the follow poll's interval).
  static constexpr std::chrono::milliseconds kPollInterval{5};

  void Produce() {
    try {
      for (;;) {
        {
          std::unique_lock<std::mutex> lock(mutex_);
          while (!stop_ && static_cast<int>(queue_.size()) >= depth_) {
            if (changed_.wait_for(lock, kPollInterval) == std::cv_status::timeout) {
              lock.unlock();
              source_.Poll();
              const int arrived = source_.NumArrived();
              lock.lock();
              arrived_ = arrived;
            }
          }
          if (stop_) break;
        }
        if (max_latency_s_ > 0) {
          if (std::optional<QueryFrame> stale = source_.SkipStale(max_latency_s_)) {
            const int arrived = source_.NumArrived();
            std::lock_guard<std::mutex> lock(mutex_);
            queue_.push_back({std::future<PreparedFrame>(), std::move(stale)});
            arrived_ = arrived;
            changed_.notify_all();
            continue;
          }
        }
        std::optional<QueryFrame> frame = source_.Next();
        if (!frame) break;
        const int arrived = source_.NumArrived();
        std::future<PreparedFrame> prepared = std::async(
            std::launch::async, [this](const QueryFrame& f) { return localizer_.Prepare(f); },
            std::move(*frame));
        std::lock_guard<std::mutex> lock(mutex_);
        queue_.push_back({std::move(prepared), std::nullopt});
        arrived_ = arrived;
        changed_.notify_all();
      }
    } catch (...) {
      std::lock_guard<std::mutex> lock(mutex_);
      error_ = std::current_exception();
    }
    std::lock_guard<std::mutex> lock(mutex_);
    done_ = true;
    changed_.notify_all();
  }

  const Localizer& localizer_;
  FrameSource& source_;
  int depth_;
  double max_latency_s_;
  std::mutex mutex_;
  std::condition_variable changed_;
  std::deque<Entry> queue_;
  int arrived_ = 0;  // the source's NumArrived() after its last call
  bool done_ = false, stop_ = false;
  std::exception_ptr error_;
  std::thread producer_;
};

}  // namespace

LocalizeRun LocalizeStream(Localizer& localizer,
                           FrameSource& source,
                           const RowSink& sink,
                           const ProgressCallback& progress) {
  const auto start = Clock::now();
  LocalizeRun run;
  run.refined = localizer.refining();
  std::vector<double> latencies;
  const int64_t total = std::max<int64_t>(0, source.size());
  {
    const double max_latency_s = localizer.options().max_latency_s;
    PrepareQueue queue(localizer, source, std::max(1, localizer.options().num_threads),
                       max_latency_s);
    // A skipped frame's rows (status skipped), counted with its extraction time if it had one.
    const auto skip = [&](FrameEstimate skipped, const std::string& note) {
      skipped.status = TrackStatus::kSkipped;
      skipped.note = note;
      sink(&skipped, localizer.Rows(skipped));
      ++run.num_frames;
      ++run.num_skipped;
      run.extraction_seconds += skipped.extraction_seconds;
      run.stages += skipped.stages;
      if (progress) progress(run.num_frames, std::max<int64_t>(total, run.num_frames));
    };
    while (std::optional<PrepareQueue::Entry> next = queue.Pop()) {
      if (next->unread) {
        // Dropped before its extraction: late, with a newer frame arrived.
        FrameEstimate skipped;
        skipped.frame = next->unread->frame;
        skipped.timestamp_s = next->unread->timestamp_s;
        skipped.gnss = next->unread->gnss;
        skip(std::move(skipped),
             fmt::format("skipped unread: {:.0f} ms late, a newer frame arrived",
                         1e3 * (SteadyNowSeconds() - next->unread->arrival_s)));
        continue;
      }
      const PreparedFrame prepared = next->prepared.get();
      if (prepared.features.size() == 0) {
        std::vector<frame_t>& none = run.frames_without_features;
        none.push_back(prepared.frame);
        if (none.size() <= static_cast<size_t>(kFeaturelessWarnings)) {
          spdlog::warn(
              "{} gave no SIFT features (a black, overexposed or textureless image){}",
              FrameSubject(prepared.where, prepared.frame),
              none.size() == static_cast<size_t>(kFeaturelessWarnings)
                  ? "; further ones are counted at the end"
                  : "");
        }
      }
      if (max_latency_s > 0 && SteadyNowSeconds() - prepared.arrival_s >= max_latency_s &&
          queue.HasWaiting()) {
        FrameEstimate skipped;
        skipped.frame = prepared.frame;
        skipped.timestamp_s = prepared.timestamp_s;
        skipped.gnss = prepared.gnss;
        skipped.extraction_seconds = prepared.extraction_seconds;
        skipped.stages = prepared.stages;
        skip(std::move(skipped), fmt::format("skipped: {:.0f} ms late, a newer frame waiting",
                                             1e3 * (SteadyNowSeconds() - prepared.arrival_s)));
        continue;
      }
      FrameEstimate estimate = localizer.Track(prepared);
      estimate.latency_seconds = SteadyNowSeconds() - prepared.arrival_s;
      sink(&estimate, localizer.Rows(estimate));
      latencies.push_back(SteadyNowSeconds() - prepared.arrival_s);
      // Upkeep while the next frame is read and prepared (off this frame's latency).
      const auto maintain_start = Clock::now();
      localizer.Maintain();
      const double maintenance_s =
          std::chrono::duration<double>(Clock::now() - maintain_start).count();
      run.stages.window += maintenance_s;
      run.maintenance_seconds += maintenance_s;
      ++run.num_frames;
      run.extraction_seconds += estimate.extraction_seconds;
      run.tracking_seconds += estimate.tracking_seconds;
      run.stages += estimate.stages;
      if (estimate.status == TrackStatus::kOk) ++run.num_localized_online;
      if (estimate.refined) {
        switch (estimate.refined->status) {
          case RefineStatus::kOk:
            ++run.num_refined_ok;
            break;
          case RefineStatus::kThin:
            ++run.num_refine_thin;
            break;
          case RefineStatus::kRejected:
            ++run.num_refine_rejected;
            break;
        }
      }
      if (progress) progress(run.num_frames, std::max<int64_t>(total, run.num_frames));
    }
  }
  if (localizer.options().record_offline && localizer.options().WantsOffline()) {
    sink(nullptr, localizer.OfflineRows());
  }
  if (!run.frames_without_features.empty()) {
    const auto& none = run.frames_without_features;
    spdlog::warn(
        "{} of {} query frames gave no SIFT features (frames {}{}); they cannot be "
        "localized",
        none.size(), run.num_frames,
        fmt::join(none.begin(), none.begin() + std::min<size_t>(none.size(), 10), ", "),
        none.size() > 10 ? ", ..." : "");
  }
  run.num_reinitialisations = localizer.num_reinitialisations();
  run.num_pairs = localizer.num_pairs();
  run.seconds = std::chrono::duration<double>(Clock::now() - start).count();
  run.frames_per_second = run.seconds > 0 ? run.num_frames / run.seconds : 0.0;
  run.latency_p50_s = Percentile(latencies, 0.50);
  run.latency_p95_s = Percentile(latencies, 0.95);
  run.latency_max_s =
      latencies.empty() ? 0.0 : *std::max_element(latencies.begin(), latencies.end());
  return run;
}

LocalizeRun Localize(const std::string& db_path,
                     const std::string& drive_dir,
                     const LocalizeOptions& options,
                     const ProgressCallback& progress) {
  options.Check();
  DriveFrameSource source(drive_dir, options.use_gps);
  LocalizeOptions effective = options;
  effective.record_offline = options.WantsOffline();
  Localizer localizer(db_path, source.camera(), effective);
  ResultTable results;
  results.extra_columns = Localizer::ExtraColumns();
  std::vector<ResultRow> offline;
  LocalizeRun run = LocalizeStream(
      localizer, source,
      [&](const FrameEstimate* estimate, const std::vector<ResultRow>& rows) {
        std::vector<ResultRow>& into = estimate ? results.rows : offline;
        into.insert(into.end(), rows.begin(), rows.end());
      },
      progress);
  results.rows.insert(results.rows.end(), offline.begin(), offline.end());
  run.results = std::move(results);
  return run;
}

DiagnosticsCsv::DiagnosticsCsv(const std::string& path, const Localizer& localizer)
    : out_(path,
           {"frame",
            "timestamp_s",
            "gps_s_m",
            "db_frame",
            "db_s_m",
            "valid",
            "d",
            "signed_d",
            "signed_cot",
            "matches",
            "inliers",
            "parallax_deg",
            "heading_deg",
            "failure",
            "verdict",
            "epipolar_l_m",
            "epipolar_sigma_m",
            "pnp_s_m",
            "pnp_sigma_m",
            "online_s_m",
            "online_sigma_m",
            "status",
            "note",
            "reinitialised",
            "frame_seconds",
            "extraction_seconds",
            "latency_seconds"}) {
  for (int j = 0; j < localizer.num_db_frames(); ++j) {
    db_frame_numbers_.push_back(localizer.db_frame_number(j));
    db_s_m_.push_back(localizer.db_s_m(j));
  }
}

void DiagnosticsCsv::Write(const FrameEstimate& est) {
  const bool ok = est.status == TrackStatus::kOk;
  const bool pnp = est.refined && est.refined->status == RefineStatus::kOk;
  for (size_t k = 0; k < est.pairs.size(); ++k) {
    const PairResult& p = est.pairs[k];
    const char* verdict =
        k < est.epipolar.verdicts.size() ? PairVerdictName(est.epipolar.verdicts[k]) : "";
    out_.WriteRow({std::to_string(est.frame),
                   FormatDouble(est.timestamp_s),
                   est.gnss_on_route ? FormatFixed(est.gnss_on_route->s_m, 3) : "",
                   std::to_string(db_frame_numbers_[p.db_index]),
                   FormatFixed(db_s_m_[p.db_index], 3),
                   p.valid ? "1" : "0",
                   p.valid ? FormatDouble(p.distance) : "",
                   p.valid ? FormatDouble(p.signed_distance) : "",
                   p.valid ? FormatDouble(p.signed_cot) : "",
                   std::to_string(p.num_matches),
                   std::to_string(p.num_inliers),
                   p.valid ? FormatFixed(p.parallax_deg, 3) : "",
                   p.valid ? FormatFixed(p.heading_deg, 3) : "",
                   p.failure,
                   verdict,
                   est.epipolar.valid ? FormatFixed(est.epipolar.l_m, 3) : "",
                   est.epipolar.valid ? FormatFixed(est.epipolar.sigma_m, 4) : "",
                   pnp ? FormatFixed(est.refined->projection.s_m, 3) : "",
                   pnp ? FormatFixed(est.pnp_sigma_m, 4) : "",
                   ok ? FormatFixed(est.s_m, 3) : "",
                   ok ? FormatFixed(est.sigma_along_m, 4) : "",
                   TrackStatusName(est.status),
                   est.note,
                   est.reinitialised ? "1" : "0",
                   FormatFixed(est.tracking_seconds, 4),
                   FormatFixed(est.extraction_seconds, 4),
                   FormatFixed(est.latency_seconds, 4)});
  }
}

void DiagnosticsCsv::Close() { out_.Close(); }

}  // namespace epiloc
