#include "core/frontend/change_thread.h"

#include "core/util/check.h"
#include "core/util/timer.h"

#include <utility>

namespace saker::frontend {
ChangeThread::ChangeThread(const track::ChangeOptions& options, track::FrameRate rate,
                           size_t queue_frames, size_t lag_frames)
    : inputs_(queue_frames), answers_(lag_frames + 1) {
  thread_ = std::thread([this, options, rate] { Run(options, rate); });
}

ChangeThread::~ChangeThread() {
  inputs_.Cancel();
  answers_.Cancel();
  thread_.join();
}

void ChangeThread::Submit(int64_t frame, cv::Mat grey, std::optional<Eigen::Matrix3d> motion) {
  SAKER_CHECK(outstanding_.empty() || frame > outstanding_.back());
  const Stopwatch watch;
  const bool pushed = inputs_.Push({frame, std::move(grey), std::move(motion)});
  wait_ms_ += watch.ElapsedMs();
  if (!pushed) RethrowOrFail();
  outstanding_.push_back(frame);
}

std::optional<ChangeThread::Answer> ChangeThread::NextThrough(int64_t frame) {
  if (outstanding_.empty() || outstanding_.front() > frame) return std::nullopt;
  const Stopwatch watch;
  std::optional<Answer> answer = answers_.Pop();
  wait_ms_ += watch.ElapsedMs();
  if (!answer) RethrowOrFail();
  SAKER_CHECK(answer->submitted == outstanding_.front());
  outstanding_.pop_front();
  return answer;
}

void ChangeThread::Run(const track::ChangeOptions& options, track::FrameRate rate) {
  try {
    track::ChangeDetector detector(options, rate);
    while (std::optional<Input> input = inputs_.Pop()) {
      const Stopwatch watch;
      Answer answer;
      answer.submitted = input->frame;
      answer.restart = !input->motion;
      answer.change = detector.Process(input->frame, input->grey, input->motion);
      input.reset();  // the frame is no longer needed here
      answer.ms = watch.ElapsedMs();
      if (!answers_.Push(std::move(answer))) return;
    }
  } catch (...) {
    error_ = std::current_exception();  // published by the queues' locks below
    inputs_.Cancel();
  }
  answers_.Close();
}

void ChangeThread::RethrowOrFail() {
  if (error_) std::rethrow_exception(error_);
  throw CheckError("front end: the change detection thread stopped early");
}

}  // namespace saker::frontend
