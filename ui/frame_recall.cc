#include "ui/frame_recall.h"

#include "core/util/status.h"
#include "core/util/timer.h"
#include "core/video/video_reader.h"

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <atomic>
#include <condition_variable>
#include <exception>
#include <mutex>
#include <new>
#include <optional>
#include <string>
#include <thread>
#include <utility>

namespace saker::ui {

namespace {

struct Request {
  int64_t frame_index = 0;
  quint64 ticket = 0;
};

}  // namespace

struct FrameRecall::Shared {
  std::mutex mutex;
  std::condition_variable wake;
  // Written under `mutex`; atomic so the warm-up pass can poll them once per frame without it.
  std::atomic<bool> stop{false};
  std::atomic<uint64_t> generation{0};        // bumped by every setVideo()
  std::string path;                           // the video of `generation`
  std::vector<video::FrameIndexEntry> index;  // its frame index when known (else indexed)
  std::optional<Request> pending;             // at most one: latest wins
  std::atomic<bool> warm{false};
  std::thread thread;
};

FrameRecall::FrameRecall(QObject* parent)
    : QObject(parent), shared_(std::make_unique<Shared>()), mailbox_(new Mailbox(this)) {
  shared_->thread = std::thread([this] { run(); });
}

FrameRecall::~FrameRecall() {
  {
    std::lock_guard<std::mutex> lock(shared_->mutex);
    shared_->stop = true;
    shared_->pending.reset();
  }
  shared_->wake.notify_all();
  // Bounded: the warm-up pass polls `stop` every frame, and a recall decodes at most one GOP.
  shared_->thread.join();
}

void FrameRecall::setVideo(const QString& path, std::vector<video::FrameIndexEntry> index) {
  {
    std::lock_guard<std::mutex> lock(shared_->mutex);
    shared_->path = path.toStdString();
    shared_->index = std::move(index);
    shared_->pending.reset();
    shared_->warm = false;
    ++shared_->generation;
  }
  shared_->wake.notify_all();
}

QString FrameRecall::video() const {
  std::lock_guard<std::mutex> lock(shared_->mutex);
  return QString::fromStdString(shared_->path);
}

void FrameRecall::request(int64_t frame_index, quint64 ticket) {
  {
    std::lock_guard<std::mutex> lock(shared_->mutex);
    shared_->pending = Request{frame_index, ticket};
  }
  shared_->wake.notify_all();
}

bool FrameRecall::isWarm() const { return shared_->warm; }

void FrameRecall::run() {
  Shared& shared = *shared_;
  uint64_t open_generation = 0;  // generation 0 is "no video"
  std::string path;
  std::vector<video::FrameIndexEntry> known_index;
  std::unique_ptr<video::VideoReader> reader;  // random access, on the complete index
  QString open_error;                          // why `reader` is null once an open was tried

  // Emission happens on the GUI thread, through this object's mailbox, which the destructor
  // outlives (it joins this thread first) and whose pending calls Qt discards with it.
  auto post = [this](auto emit_signal) { mailbox_->post(std::move(emit_signal)); };
  auto superseded = [&shared, &open_generation] {
    return shared.stop || shared.generation != open_generation;
  };

  // Opens `path` and builds its frame index without pixel conversion, checking between frames
  // whether the video was replaced or the recall is being destroyed.
  auto warm_up = [&]() -> bool {
    const Stopwatch timer;
    video::ReaderOptions recall_options;
    recall_options.want_bgr = true;
    if (!known_index.empty()) {
      auto opened = video::OpenWithIndex(path, std::move(known_index), recall_options);
      if (opened.ok()) {
        reader = std::move(opened).value();
        const auto count = static_cast<qint64>(reader->frame_index().size());
        const double fps = reader->info().fps, ms = timer.ElapsedMs();
        const QString qpath = QString::fromStdString(path);
        post([this, qpath, count, fps, ms] { emit videoReady(qpath, count, fps, ms); });
        return true;
      }
      // Not this file's index after all: index the file as if none had been given.
    }
    video::ReaderOptions scan_options;
    scan_options.want_bgr = false;
    scan_options.want_grey = false;
    auto scan = video::VideoReader::Open(path, scan_options);
    if (!scan.ok()) {
      open_error = QString::fromStdString(scan.status().message());
      return false;
    }
    video::Frame frame;
    while (true) {
      if (superseded()) return false;
      auto more = (*scan)->ReadNext(&frame, nullptr);
      if (!more.ok()) {
        open_error = QString::fromStdString(more.status().message());
        return false;
      }
      if (!*more) break;
    }
    if ((*scan)->frame_index().empty()) {
      open_error = tr("%1 has no decodable video frames.").arg(QString::fromStdString(path));
      return false;
    }
    const double fps = (*scan)->info().fps;
    auto opened = video::OpenWithIndex(path, (*scan)->frame_index(), recall_options);
    if (!opened.ok()) {
      open_error = QString::fromStdString(opened.status().message());
      return false;
    }
    reader = std::move(opened).value();
    const auto count = static_cast<qint64>(reader->frame_index().size());
    const double ms = timer.ElapsedMs();
    const QString qpath = QString::fromStdString(path);
    post([this, qpath, count, fps, ms] { emit videoReady(qpath, count, fps, ms); });
    return true;
  };

  while (true) {
    Request request;
    {
      std::unique_lock<std::mutex> lock(shared.mutex);
      shared.wake.wait(lock, [&] {
        return shared.stop || shared.generation != open_generation || shared.pending.has_value();
      });
      if (shared.stop) return;
      if (shared.generation != open_generation) {
        open_generation = shared.generation;
        path = shared.path;
        known_index = std::move(shared.index);
        shared.index.clear();
        lock.unlock();
        reader.reset();
        open_error.clear();
        if (path.empty()) continue;
        bool warmed = false;
        try {
          warmed = warm_up();
        } catch (...) {  // a broken invariant or no memory: report, never terminate
          open_error = QString::fromStdString(StatusFromCurrentException(path).message());
        }
        if (warmed) {
          std::lock_guard<std::mutex> relock(shared.mutex);
          if (shared.generation == open_generation) shared.warm = true;
        } else if (!superseded()) {
          reader.reset();
          const QString qpath = QString::fromStdString(path);
          const QString message = open_error;
          post([this, qpath, message] { emit videoFailed(qpath, message); });
        }
        continue;
      }
      request = *shared.pending;
      shared.pending.reset();
    }

    const quint64 ticket = request.ticket;
    if (!reader) {
      const QString message =
          path.empty() ? tr("No video is set for frame recall.")
                       : (open_error.isEmpty()
                              ? tr("%1 could not be opened.").arg(QString::fromStdString(path))
                              : open_error);
      post([this, ticket, message] { emit failed(ticket, message); });
      continue;
    }
    const Stopwatch timer;
    QString error;
    QImage image;
    try {
      auto frame = reader->ReadFrame(request.frame_index);
      if (!frame.ok()) {
        error = QString::fromStdString(frame.status().message());
      } else if (frame->bgr.empty() || frame->bgr.type() != CV_8UC3) {
        error = tr("%1: frame %2 decoded to no picture.")
                    .arg(QString::fromStdString(path))
                    .arg(request.frame_index);
      } else {
        // Convert straight into the QImage's buffer: one pass, no extra copy.
        image = QImage(frame->bgr.cols, frame->bgr.rows, QImage::Format_RGB888);
        if (image.isNull()) throw std::bad_alloc();  // Qt could not allocate it
        cv::Mat rgb(image.height(), image.width(), CV_8UC3, image.bits(),
                    static_cast<size_t>(image.bytesPerLine()));
        cv::cvtColor(frame->bgr, rgb, cv::COLOR_BGR2RGB);
      }
    } catch (...) {
      image = QImage();
      error = QString::fromStdString(StatusFromCurrentException(path).message());
    }
    const double ms = timer.ElapsedMs();
    // A request for a video that has since been replaced answers nobody.
    if (superseded()) continue;
    if (!error.isEmpty()) {
      post([this, ticket, error] { emit failed(ticket, error); });
    } else {
      const int64_t index = request.frame_index;
      post([this, ticket, index, image, ms] { emit frameReady(ticket, index, image, ms); });
    }
  }
}

}  // namespace saker::ui
