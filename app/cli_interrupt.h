#pragma once

// Ctrl-C cancels the running job cleanly (it keeps or removes its partial output as it
// documents) instead of killing the process; a second Ctrl-C ends the process at once.

#include "core/util/job_context.h"

namespace saker::app {

// While alive, SIGINT requests cancellation of `job`; the previous handler is restored after.
class ScopedInterrupt {
 public:
  explicit ScopedInterrupt(JobContext* job);
  ~ScopedInterrupt();
  ScopedInterrupt(const ScopedInterrupt&) = delete;
  ScopedInterrupt& operator=(const ScopedInterrupt&) = delete;

 private:
  void (*previous_)(int) = nullptr;
};

}  // namespace saker::app
