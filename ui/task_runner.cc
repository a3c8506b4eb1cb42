#include "ui/task_runner.h"

#include <exception>

namespace saker::ui {

TaskRunner::TaskRunner(QObject* parent) : QObject(parent), mailbox_(new Mailbox(this)) {
  qRegisterMetaType<saker::Status>();
}

TaskRunner::~TaskRunner() { cancelAndWait(); }

bool TaskRunner::start(const QString& title, Task task) {
  if (running_) return false;
  join();  // the previous job's thread has ended (finished was delivered); reap it
  running_ = true;
  title_ = title;
  auto job = std::make_shared<JobContext>([this](const std::string& stage, double fraction) {
    {
      std::lock_guard<std::mutex> lock(progress_mutex_);
      progress_stage_ = QString::fromStdString(stage);
      progress_fraction_ = fraction;
    }
    if (!progress_posted_.exchange(true)) {
      mailbox_->post([this] { postProgress(); });
    }
  });
  job_ = job;
  thread_ = std::thread([this, job, task = std::move(task), context = title.toStdString()] {
    Status status;
    try {
      status = task(job.get());
    } catch (...) {
      // The engine reports errors as Status; an exception is a bug or memory running out, but
      // it must not take the analyst's work down with it.
      status = StatusFromCurrentException(context);
    }
    mailbox_->post([this, status] {
      running_ = false;
      emit finished(title_, status);
    });
  });
  return true;
}

void TaskRunner::cancel() {
  if (job_) job_->RequestCancel();
}

void TaskRunner::cancelAndWait() {
  cancel();
  join();
  running_ = false;
}

void TaskRunner::join() {
  if (thread_.joinable()) thread_.join();
}

void TaskRunner::postProgress() {
  progress_posted_ = false;
  QString stage;
  double fraction = 0;
  {
    std::lock_guard<std::mutex> lock(progress_mutex_);
    stage = progress_stage_;
    fraction = progress_fraction_;
  }
  if (running_) emit progress(stage, fraction);
}

}  // namespace saker::ui
