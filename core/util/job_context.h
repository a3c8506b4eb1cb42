#pragma once

// The small context every long engine call takes: it reports progress by
// stage, and lets the caller cancel. Engine calls are synchronous and
// thread-agnostic; the UI's task runner turns these callbacks into queued
// signals.

#include <atomic>
#include <functional>
#include <string>

namespace saker {

class JobContext {
 public:
  // Called with the stage name and the fraction of that stage done, in [0, 1].
  using ProgressCallback = std::function<void(const std::string& stage, double fraction)>;

  JobContext() = default;
  explicit JobContext(ProgressCallback on_progress) : on_progress_(std::move(on_progress)) {}

  // Thread-safe; may be called from any thread, typically the GUI's.
  void RequestCancel() { cancelled_.store(true, std::memory_order_relaxed); }
  bool IsCancelled() const { return cancelled_.load(std::memory_order_relaxed); }

  void ReportProgress(const std::string& stage, double fraction) const {
    if (on_progress_) on_progress_(stage, fraction);
  }

 private:
  ProgressCallback on_progress_;
  std::atomic<bool> cancelled_{false};
};

}  // namespace saker
