// The GUI's job runner on its own: the job runs on a worker thread, progress arrives on the GUI
// thread coalesced to the newest value, the end arrives with the job's Status, cancel and
// destruction stop the job, and an exception becomes an error. Labelled `threads`: the tsan
// test preset runs it under ThreadSanitizer.

#include "ui/task_runner.h"

#include "tests/ui/ui_testing.h"

#include <gtest/gtest.h>

#include <QCoreApplication>
#include <QThread>
#include <atomic>
#include <chrono>
#include <memory>
#include <new>
#include <optional>
#include <stdexcept>
#include <thread>
#include <vector>

namespace saker::ui {
namespace {

using saker::ui::testing::WaitUntil;

// What the runner's signals delivered, recorded on the GUI thread.
struct Received {
  std::vector<double> fractions;
  std::vector<QString> stages;
  std::optional<Status> finished;
  QString finished_title;
  bool all_on_gui_thread = true;
};

void Record(TaskRunner* runner, Received* received) {
  QObject::connect(runner, &TaskRunner::progress, runner,
                   [received](const QString& stage, double fraction) {
                     received->all_on_gui_thread &=
                         QThread::currentThread() == QCoreApplication::instance()->thread();
                     received->stages.push_back(stage);
                     received->fractions.push_back(fraction);
                   });
  QObject::connect(runner, &TaskRunner::finished, runner,
                   [received](const QString& title, const Status& status) {
                     received->all_on_gui_thread &=
                         QThread::currentThread() == QCoreApplication::instance()->thread();
                     received->finished_title = title;
                     received->finished = status;
                   });
}

TEST(TaskRunnerTest, RunsTheJobOnAWorkerAndDeliversItsStatus) {
  TaskRunner runner;
  Received received;
  Record(&runner, &received);
  std::atomic<bool> on_worker{false};
  const std::thread::id gui = std::this_thread::get_id();
  ASSERT_TRUE(runner.start("scan", [&](JobContext* job) {
    on_worker = std::this_thread::get_id() != gui;
    job->ReportProgress("front end", 0.5);
    return InvalidDataError("sortie.ts: not a video");
  }));
  EXPECT_TRUE(runner.isRunning());
  EXPECT_EQ(runner.title(), "scan");
  ASSERT_TRUE(WaitUntil([&] { return received.finished.has_value(); }));
  EXPECT_TRUE(on_worker);
  EXPECT_FALSE(runner.isRunning());
  EXPECT_EQ(received.finished_title, "scan");
  EXPECT_EQ(received.finished->code(), StatusCode::kInvalidData);
  EXPECT_EQ(received.finished->message(), "sortie.ts: not a video");
  ASSERT_EQ(received.fractions.size(), 1u);
  EXPECT_EQ(received.stages[0], "front end");
  EXPECT_DOUBLE_EQ(received.fractions[0], 0.5);
  EXPECT_TRUE(received.all_on_gui_thread);
}

TEST(TaskRunnerTest, ProgressIsCoalescedToTheNewestValue) {
  TaskRunner runner;
  Received received;
  Record(&runner, &received);
  std::atomic<bool> reported{false};
  std::atomic<bool> release{false};
  ASSERT_TRUE(runner.start("busy", [&](JobContext* job) {
    for (int i = 1; i <= 1000; ++i) job->ReportProgress("tiles", i / 1000.0);
    reported = true;
    while (!release) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    return Status::Ok();
  }));
  // The GUI thread is busy (no event loop) while the job reports 1000 times: one queued call.
  while (!reported) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  ASSERT_TRUE(WaitUntil([&] { return !received.fractions.empty(); }));
  QCoreApplication::processEvents();
  ASSERT_EQ(received.fractions.size(), 1u);
  EXPECT_DOUBLE_EQ(received.fractions[0], 1.0);
  release = true;
  ASSERT_TRUE(WaitUntil([&] { return received.finished.has_value(); }));
  EXPECT_TRUE(received.finished->ok());
  EXPECT_EQ(received.fractions.size(), 1u);
}

TEST(TaskRunnerTest, OneJobAtATimeAndCancelEndsIt) {
  TaskRunner runner;
  Received received;
  Record(&runner, &received);
  std::atomic<int> rounds{0};
  auto until_cancelled = [&](JobContext* job) {
    while (!job->IsCancelled()) {
      ++rounds;
      job->ReportProgress("mosaic", 0.1);
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    return CancelledError("mosaic cancelled");
  };
  ASSERT_TRUE(runner.start("first", until_cancelled));
  EXPECT_FALSE(runner.start("second", until_cancelled)) << "a second job started alongside";
  EXPECT_EQ(runner.title(), "first");
  ASSERT_TRUE(WaitUntil([&] { return rounds > 10; }));
  runner.cancel();
  ASSERT_TRUE(WaitUntil([&] { return received.finished.has_value(); }));
  EXPECT_EQ(received.finished->code(), StatusCode::kCancelled);
  EXPECT_EQ(received.finished_title, "first");
  EXPECT_FALSE(runner.isRunning());

  // The runner takes the next job once the first has ended.
  received.finished.reset();
  ASSERT_TRUE(runner.start("third", [](JobContext*) { return Status::Ok(); }));
  ASSERT_TRUE(WaitUntil([&] { return received.finished.has_value(); }));
  EXPECT_TRUE(received.finished->ok());
  EXPECT_EQ(received.finished_title, "third");
}

TEST(TaskRunnerTest, AnExceptionInTheJobBecomesAnError) {
  TaskRunner runner;
  Received received;
  Record(&runner, &received);
  ASSERT_TRUE(runner.start(
      "export", [](JobContext*) -> Status { throw std::runtime_error("disk on fire"); }));
  ASSERT_TRUE(WaitUntil([&] { return received.finished.has_value(); }));
  EXPECT_FALSE(received.finished->ok());
  EXPECT_NE(received.finished->message().find("disk on fire"), std::string::npos)
      << received.finished->ToString();
}

// Memory running out in a job (std::bad_alloc) is an error saying so; an exception that is no
// std::exception ended the GUI (std::terminate on the worker thread).
TEST(TaskRunnerTest, OutOfMemoryAndUnknownExceptionsBecomeErrors) {
  TaskRunner runner;
  Received received;
  Record(&runner, &received);
  ASSERT_TRUE(runner.start("process", [](JobContext*) -> Status { throw std::bad_alloc(); }));
  ASSERT_TRUE(WaitUntil([&] { return received.finished.has_value(); }));
  EXPECT_EQ(received.finished->code(), StatusCode::kResourceExhausted);
  EXPECT_NE(received.finished->message().find("out of memory"), std::string::npos)
      << received.finished->ToString();
  received.finished.reset();
  ASSERT_TRUE(runner.start("export", [](JobContext*) -> Status { throw 42; }));
  ASSERT_TRUE(WaitUntil([&] { return received.finished.has_value(); }));
  EXPECT_EQ(received.finished->code(), StatusCode::kInternal);
}

TEST(TaskRunnerTest, DestroyingWhileRunningCancelsAndWaitsForTheJob) {
  auto runner = std::make_unique<TaskRunner>();
  Received received;
  Record(runner.get(), &received);
  std::atomic<bool> started{false};
  std::atomic<bool> ended{false};
  ASSERT_TRUE(runner->start("long", [&](JobContext* job) {
    started = true;
    while (!job->IsCancelled()) {
      job->ReportProgress("front end", 0.2);
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));  // still working after cancel
    ended = true;
    return CancelledError("cancelled");
  }));
  while (!started) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  runner.reset();
  EXPECT_TRUE(ended) << "the runner was destroyed before its job ended";
  // Calls the job queued for the destroyed runner are dropped, not delivered.
  QCoreApplication::processEvents();
  EXPECT_FALSE(received.finished.has_value());
}

}  // namespace
}  // namespace saker::ui
