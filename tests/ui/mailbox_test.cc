// Worker-to-GUI hand-over: calls posted from another thread run on the mailbox's thread, in the
// order posted, with their captures intact; a mailbox deleted with calls pending destroys them
// without running them. Labelled `threads`: under ThreadSanitizer these tests also check that the
// hand-over is visible to it (a capture written by the worker and read on the GUI thread).

#include "ui/mailbox.h"

#include "tests/ui/ui_testing.h"

#include <gtest/gtest.h>

#include <QCoreApplication>
#include <QThread>
#include <chrono>
#include <memory>
#include <thread>
#include <vector>

namespace saker::ui {
namespace {

using saker::ui::testing::WaitUntil;

TEST(MailboxTest, CallsFromAWorkerRunOnTheGuiThreadInOrderWithTheirCaptures) {
  Mailbox mailbox;
  constexpr int kCalls = 500;
  std::vector<int> order;  // touched only on the GUI thread
  bool all_on_gui_thread = true;
  std::thread worker([&] {
    for (int i = 0; i < kCalls; ++i) {
      // Written here, read on the GUI thread: TSan sees the hand-over or reports it.
      std::vector<int> payload(64, i);
      auto owned = std::make_unique<int>(i);  // move-only captures are accepted
      mailbox.post([&, i, payload = std::move(payload), owned = std::move(owned)] {
        all_on_gui_thread &= QThread::currentThread() == QCoreApplication::instance()->thread();
        for (int v : payload) EXPECT_EQ(v, i);
        EXPECT_EQ(*owned, i);
        order.push_back(i);
      });
      std::this_thread::sleep_for(std::chrono::microseconds(200));  // interleave with the GUI
    }
  });
  // The GUI thread runs the calls while the worker is still posting: joining the worker first
  // would order everything for TSan and hide a missing hand-over.
  const bool all_ran = WaitUntil([&] { return order.size() == static_cast<size_t>(kCalls); });
  worker.join();
  ASSERT_TRUE(all_ran);
  EXPECT_TRUE(all_on_gui_thread);
  for (int i = 0; i < kCalls; ++i) ASSERT_EQ(order[i], i);
}

TEST(MailboxTest, DeletedWithCallsPendingDestroysThemWithoutRunningThem) {
  auto mailbox = std::make_unique<Mailbox>();
  auto witness = std::make_shared<int>(0);
  int runs = 0;
  std::thread worker([&, witness] {
    for (int i = 0; i < 100; ++i) mailbox->post([&runs, witness] { ++runs; });
  });
  worker.join();
  EXPECT_EQ(witness.use_count(), 101);  // here and in every pending call
  mailbox.reset();                      // before the event loop turned
  EXPECT_EQ(witness.use_count(), 1);
  QCoreApplication::processEvents();
  EXPECT_EQ(runs, 0);
}

TEST(MailboxTest, ACallPostedOnTheGuiThreadWaitsForTheEventLoop) {
  Mailbox mailbox;
  bool ran = false;
  mailbox.post([&] { ran = true; });
  EXPECT_FALSE(ran);
  ASSERT_TRUE(WaitUntil([&] { return ran; }));
}

}  // namespace
}  // namespace saker::ui
