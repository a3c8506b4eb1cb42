#pragma once

// Wall-clock durations for summaries, progress and benchmarks, on the monotonic clock (never the
// calendar clock, which jumps when the system time is set).

#include <chrono>

namespace saker {

// Measures the time since it was started (constructed or Restart()ed).
class Stopwatch {
 public:
  using Clock = std::chrono::steady_clock;

  Stopwatch() : start_(Clock::now()) {}

  void Restart() { start_ = Clock::now(); }
  // Returns the time so far and starts again: consecutive laps add up to the total.
  double LapSeconds() {
    const Clock::time_point now = Clock::now();
    const double seconds = std::chrono::duration<double>(now - start_).count();
    start_ = now;
    return seconds;
  }
  double ElapsedSeconds() const {
    return std::chrono::duration<double>(Clock::now() - start_).count();
  }
  double ElapsedMs() const {
    return std::chrono::duration<double, std::milli>(Clock::now() - start_).count();
  }
  double ElapsedUs() const {
    return std::chrono::duration<double, std::micro>(Clock::now() - start_).count();
  }

 private:
  Clock::time_point start_;
};

}  // namespace saker
