#include "core/util/bounded_queue.h"

#include <gtest/gtest.h>

#include <thread>
#include <vector>

namespace saker {
namespace {

// Through a queue of two, a producer's items all arrive, in order, and the end carries the
// producer's status.
TEST(BoundedQueueTest, DeliversInOrderThroughASmallQueueAndEndsWithTheStatus) {
  BoundedQueue<int> queue(2);
  std::thread producer([&] {
    for (int i = 0; i < 1000; ++i) ASSERT_TRUE(queue.Push(i));
    queue.Close(IoError("the end"));
  });
  std::vector<int> received;
  while (std::optional<int> item = queue.Pop()) received.push_back(*item);
  producer.join();
  ASSERT_EQ(received.size(), 1000u);
  for (int i = 0; i < 1000; ++i) EXPECT_EQ(received[static_cast<size_t>(i)], i);
  EXPECT_EQ(queue.status().code(), StatusCode::kIoError);
  EXPECT_FALSE(queue.Pop().has_value()) << "closed and empty stays at the end";
}

// What was queued before Close is still handed out.
TEST(BoundedQueueTest, ClosingKeepsWhatIsQueued) {
  BoundedQueue<int> queue(4);
  ASSERT_TRUE(queue.Push(1));
  ASSERT_TRUE(queue.Push(2));
  queue.Close();
  EXPECT_EQ(queue.Pop(), 1);
  EXPECT_EQ(queue.Pop(), 2);
  EXPECT_EQ(queue.Pop(), std::nullopt);
  EXPECT_TRUE(queue.status().ok());
}

// Cancelling wakes a producer blocked on a full queue and a consumer blocked on an empty one,
// drops what is queued, and refuses what comes later.
TEST(BoundedQueueTest, CancelUnblocksBothSides) {
  BoundedQueue<int> full(1);
  ASSERT_TRUE(full.Push(1));
  bool pushed = true;
  std::thread producer([&] { pushed = full.Push(2); });  // blocks: the queue is full
  BoundedQueue<int> empty(1);
  std::optional<int> popped = 0;
  std::thread consumer([&] { popped = empty.Pop(); });  // blocks: nothing to pop
  full.Cancel();
  empty.Cancel();
  producer.join();
  consumer.join();
  EXPECT_FALSE(pushed);
  EXPECT_EQ(popped, std::nullopt);
  EXPECT_EQ(full.Pop(), std::nullopt) << "what was queued is dropped";
  EXPECT_FALSE(empty.Push(3));
}

}  // namespace
}  // namespace saker
