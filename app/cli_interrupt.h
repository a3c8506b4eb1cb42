#pragma once

// Ctrl-C (SIGINT) and SIGTERM (kill, a service manager, a logout) cancel the running job cleanly
// (it keeps or removes its partial output as it documents) instead of killing the process; a
// second signal of the same kind ends the process at once. SIGKILL cannot be caught: what a
// killed job leaves (a temporary) is removed by the next job writing the same file.

#include "core/util/job_context.h"

namespace saker::app {

// While alive, SIGINT and SIGTERM request cancellation of `job`; the previous handlers are
// restored after.
class ScopedInterrupt {
 public:
  explicit ScopedInterrupt(JobContext* job);
  ~ScopedInterrupt();
  ScopedInterrupt(const ScopedInterrupt&) = delete;
  ScopedInterrupt& operator=(const ScopedInterrupt&) = delete;

 private:
  void (*previous_)(int) = nullptr;
  void (*previous_term_)(int) = nullptr;
};

}  // namespace saker::app
