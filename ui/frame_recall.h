#pragma once

// Recall of original video frames for the frame panel: decodes frames of one video on a worker
// thread of its own, so the GUI thread never waits on FFmpeg.
//
// setVideo() "warms" the video at once in the background: it opens the file and builds its frame
// index with a decode pass that converts no pixels (cancellable frame by frame), then opens a
// random-access reader on that index. By the time the analyst clicks, a recall is a seek plus the
// decode of part of a GOP. Requests are "latest wins": a request superseded before its decode
// starts is dropped, so stepping or scrubbing quickly never builds a queue. Results arrive as
// queued signals on the thread that owns the FrameRecall (the GUI thread).

#include "core/video/video_reader.h"
#include "ui/mailbox.h"

#include <QImage>
#include <QObject>
#include <QString>
#include <cstdint>
#include <memory>
#include <vector>

namespace saker::ui {

class FrameRecall : public QObject {
  Q_OBJECT

 public:
  explicit FrameRecall(QObject* parent = nullptr);
  // Stops the worker: a warm-up pass stops at its next frame, a decode in flight finishes (at most
  // one GOP), and nothing is emitted afterwards.
  ~FrameRecall() override;
  FrameRecall(const FrameRecall&) = delete;
  FrameRecall& operator=(const FrameRecall&) = delete;

  // Closes the previous video and warms `path` on the worker (an empty path only closes). A
  // pending request for the previous video is dropped. Emits videoReady or videoFailed.
  // `index`, when given, is the video's frame index as a reader made it (a mission stores it):
  // the video is then opened on it at once, without the indexing pass (which remains the
  // fallback should the index not fit the file).
  void setVideo(const QString& path, std::vector<video::FrameIndexEntry> index = {});
  QString video() const;

  // Asks for frame `frame_index` (0-based, presentation order). Latest wins: a request not yet
  // started when the next one arrives is dropped without a signal. A request made while the video
  // warms up is served once it is warm. Emits frameReady or failed with the same ticket.
  void request(int64_t frame_index, quint64 ticket);

  // True once the current video's index is built and frames can be recalled.
  bool isWarm() const;

 signals:
  // `image` is RGB888 at the video's coded size; `decode_ms` is the worker's time for this frame
  // (seek, decode and colour conversion), not counting the queue.
  void frameReady(quint64 ticket, int64_t frame_index, const QImage& image, double decode_ms);
  // The message names the file: missing video, not a video, frame out of range, decode error.
  void failed(quint64 ticket, const QString& message);
  // The video `path` is warm: `frame_count` frames indexed in `warm_ms` (open + index pass).
  void videoReady(const QString& path, qint64 frame_count, double fps, double warm_ms);
  // The video `path` could not be opened or indexed; requests for it fail with `message`.
  void videoFailed(const QString& path, const QString& message);

 private:
  struct Shared;
  void run();  // the worker thread's loop

  // State shared with the worker (mutex, condition variable, requests); see frame_recall.cc.
  std::unique_ptr<Shared> shared_;
  Mailbox* mailbox_ = nullptr;  // the worker's answers, to the GUI thread
};

}  // namespace saker::ui
