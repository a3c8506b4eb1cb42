#pragma once

// Runs one engine job at a time on a worker thread for the GUI. The job is a plain function of a
// JobContext (the engine's progress and cancel channel); the runner turns its progress into
// queued signals on the GUI thread, at most one pending at a time so a chatty stage cannot flood
// the event loop, and reports the end with the job's Status. Cancel is a request the engine
// checks between units of work; destroying the runner cancels and waits, so a job never
// outlives the window that started it.

#include "core/util/job_context.h"
#include "core/util/status.h"
#include "ui/mailbox.h"
#include "ui/meta_types.h"

#include <QObject>
#include <QString>
#include <atomic>
#include <functional>
#include <memory>
#include <mutex>
#include <thread>

namespace saker::ui {

class TaskRunner : public QObject {
  Q_OBJECT

 public:
  using Task = std::function<Status(JobContext* job)>;

  explicit TaskRunner(QObject* parent = nullptr);
  ~TaskRunner() override;

  // Starts `task` on the worker thread; false (and nothing started) when a job is running.
  bool start(const QString& title, Task task);
  bool isRunning() const { return running_; }
  QString title() const { return title_; }

  // Asks the running job to stop; it ends soon after with a Cancelled status.
  void cancel();
  // Cancels the running job and blocks until its thread has ended (closing the window).
  void cancelAndWait();

 signals:
  // The stage's name and fraction done in [0, 1].
  void progress(const QString& stage, double fraction);
  // `status` is the job's; cancelled jobs end with StatusCode::kCancelled.
  void finished(const QString& title, const saker::Status& status);

 private:
  void postProgress();
  void join();

  std::thread thread_;
  Mailbox* mailbox_ = nullptr;  // progress and the end, to the GUI thread
  std::shared_ptr<JobContext> job_;
  bool running_ = false;
  QString title_;
  // The newest progress, taken by the GUI thread when the queued call arrives.
  std::mutex progress_mutex_;
  QString progress_stage_;
  double progress_fraction_ = 0;
  std::atomic<bool> progress_posted_{false};
};

}  // namespace saker::ui
