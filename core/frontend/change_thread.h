#pragma once

// Change detection on a thread of its own (docs/front-end.md, "Threads").

#include "core/track/change_detector.h"
#include "core/util/bounded_queue.h"

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include <cstddef>
#include <cstdint>
#include <deque>
#include <exception>
#include <optional>
#include <thread>

namespace saker::frontend {

// Runs a track::ChangeDetector on a thread of its own. The calling thread submits every frame and
// takes the answers back, one per frame submitted, in the same order. A frame's grey image is
// shared, not copied: the decode thread made it for this frame alone, and nobody writes to it
// afterwards. An exception on the change thread (a failed check) is rethrown on the calling
// thread. The caller takes answers at a fixed lag (`lag_frames`), so at most `lag_frames` + 1
// frames are ever outstanding and the answer queue, that long, never holds the change thread up.
class ChangeThread {
 public:
  struct Answer {
    int64_t submitted = 0;      // the frame submitted
    bool restart = false;       // it came without ground motion: the comparison started again
    track::ChangeFrame change;  // the answer (for the frame the longest baseline earlier)
    double ms = 0;              // time the change thread spent on it
  };

  ChangeThread(const track::ChangeOptions& options, track::FrameRate rate, size_t queue_frames,
               size_t lag_frames);
  // Stops the thread (it finishes the frame in hand) and joins it.
  ~ChangeThread();
  ChangeThread(const ChangeThread&) = delete;
  ChangeThread& operator=(const ChangeThread&) = delete;

  // Frames must increase. Blocks while the queue is full.
  void Submit(int64_t frame, cv::Mat grey, std::optional<Eigen::Matrix3d> motion);
  // The answer to the oldest frame submitted and not yet taken, when that frame is at most
  // `frame` (blocking until the answer is ready); otherwise nullopt, at once.
  std::optional<Answer> NextThrough(int64_t frame);
  // Time the calling thread spent waiting in Submit and NextThrough, milliseconds.
  double wait_ms() const { return wait_ms_; }

 private:
  struct Input {
    int64_t frame = 0;
    cv::Mat grey;
    std::optional<Eigen::Matrix3d> motion;
  };

  void Run(const track::ChangeOptions& options, track::FrameRate rate);
  [[noreturn]] void RethrowOrFail();

  BoundedQueue<Input> inputs_;
  BoundedQueue<Answer> answers_;
  std::exception_ptr error_;         // set by the change thread before it closes answers_
  std::deque<int64_t> outstanding_;  // frames submitted whose answers are not taken yet
  double wait_ms_ = 0;
  std::thread thread_;  // last: started once everything above exists
};

}  // namespace saker::frontend
