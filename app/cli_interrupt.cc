#include "app/cli_interrupt.h"

#include <atomic>
#include <csignal>

namespace saker::app {
namespace {

std::atomic<JobContext*> g_job{nullptr};

extern "C" void CancelOnInterrupt(int signal) {
  if (JobContext* job = g_job.load()) job->RequestCancel();
  std::signal(signal, SIG_DFL);  // a second Ctrl-C (or kill) ends the process at once
}

}  // namespace

ScopedInterrupt::ScopedInterrupt(JobContext* job) {
  g_job.store(job);
  previous_ = std::signal(SIGINT, CancelOnInterrupt);
  previous_term_ = std::signal(SIGTERM, CancelOnInterrupt);
}

ScopedInterrupt::~ScopedInterrupt() {
  std::signal(SIGINT, previous_ == SIG_ERR ? SIG_DFL : previous_);
  std::signal(SIGTERM, previous_term_ == SIG_ERR ? SIG_DFL : previous_term_);
  g_job.store(nullptr);
}

}  // namespace saker::app
