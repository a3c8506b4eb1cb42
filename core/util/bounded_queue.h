#pragma once

// A bounded queue between two threads, so that a fast producer waits for a slow consumer and
// memory stays flat (the front end's decode and change detection threads).

#include "core/util/status.h"

#include <condition_variable>
#include <cstddef>
#include <deque>
#include <mutex>
#include <optional>
#include <utility>

namespace saker {

// The producer pushes (blocking while the queue is full) and closes it with a status when done;
// the consumer pops (blocking while it is empty) until it is closed and empty. Either side may
// cancel: blocked calls return at once, what is queued is dropped, and later pushes and pops fail.
template <typename T>
class BoundedQueue {
 public:
  explicit BoundedQueue(size_t capacity) : capacity_(capacity) {}

  // Blocks while full; false once cancelled.
  bool Push(T item) {
    std::unique_lock<std::mutex> lock(mutex_);
    not_full_.wait(lock, [&] { return items_.size() < capacity_ || cancelled_; });
    if (cancelled_) return false;
    items_.push_back(std::move(item));
    not_empty_.notify_one();
    return true;
  }
  // The producer is done (end of the input, or an error).
  void Close(Status status = Status::Ok()) {
    std::lock_guard<std::mutex> lock(mutex_);
    closed_ = true;
    status_ = std::move(status);
    not_empty_.notify_all();
  }
  // Blocks while empty; nullopt at the end (closed and empty) or once cancelled.
  std::optional<T> Pop() {
    std::unique_lock<std::mutex> lock(mutex_);
    not_empty_.wait(lock, [&] { return !items_.empty() || closed_ || cancelled_; });
    if (cancelled_ || items_.empty()) return std::nullopt;
    T item = std::move(items_.front());
    items_.pop_front();
    not_full_.notify_one();
    return item;
  }
  // Either side gives up (cancel, error): unblocks the other.
  void Cancel() {
    std::lock_guard<std::mutex> lock(mutex_);
    cancelled_ = true;
    items_.clear();
    not_full_.notify_all();
    not_empty_.notify_all();
  }
  // What Close() was given (Ok before it).
  Status status() {
    std::lock_guard<std::mutex> lock(mutex_);
    return status_;
  }

 private:
  size_t capacity_;
  std::mutex mutex_;
  std::condition_variable not_full_, not_empty_;
  std::deque<T> items_;
  bool closed_ = false;
  bool cancelled_ = false;
  Status status_;
};

}  // namespace saker
