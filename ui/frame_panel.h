#pragma once

// The click-to-recall frame panel: for a moving-target observation picked on the mosaic it shows
// the original video frame the observation was made in, decoded from the source video, with the
// object marked (red cross at the observation, red box around it), and the track's attributes.
// It steps through the track's observations (Left and Right anywhere in the window once one is
// shown, Shift for ten at a time) and plays the video forward from the frame.
//
// The screen-fixed overlay mask the front end found (burned-in text, logos) and, in low oblique
// views, its sky mask can be drawn over the frame as faint layers (setOverlayMaskVisible; off by
// default).
//
// Decoding runs on a FrameRecall worker; while a decode is pending the previous frame stays on
// screen. When the mission's video is missing the panel says where it looked and offers to locate
// it (the owner answers locateVideoRequested with setMission and the new path).

#include "core/mission/mission.h"
#include "core/util/timer.h"

#include <QImage>
#include <QPointF>
#include <QString>
#include <QWidget>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <utility>
#include <vector>

class QAction;
class QLabel;
class QPushButton;
class QStackedWidget;
class QTimer;
class QToolButton;

namespace saker::ui {

class FrameCanvas;
class ValueLabel;
class FrameRecall;

class FramePanel : public QWidget {
  Q_OBJECT

 public:
  explicit FramePanel(QWidget* parent = nullptr);
  ~FramePanel() override;

  // Shows frames of `mission` decoded from `video_path`, which may differ from
  // mission->source.path when the video was located elsewhere. An empty path (the owner did not
  // find the video; the message names source.path) or a missing file shows a message naming the
  // path and a "Locate Video…" button. Starts warming the video (indexing it in the background)
  // at once, so the first recall is fast. Clears the observation. A null mission clears all.
  // `same_video`: the file is known to be the mission's video (its fingerprint matched), so the
  // frame positions the mission stores are used and no indexing is needed.
  void setMission(std::shared_ptr<const mission::Mission> mission, const QString& video_path,
                  bool same_video = true);
  // Recalls the frame of mission->tracks[track_index].points[point_index]; indices out of range
  // are ignored. Pauses playback. Emits observationChanged when the observation changes.
  void showObservation(size_t track_index, size_t point_index);
  // Recalls frame `frame_index` of the video (the time line, a place on the map): the selected
  // track's observation in it is marked when it has one. Pauses playback.
  void showFrame(int64_t frame_index);
  // Forgets the observation and the frame (the video stays open and warm).
  void clear();

  std::optional<std::pair<size_t, size_t>> currentObservation() const;
  int64_t displayedFrame() const;        // -1 until a frame is on screen
  const QImage& displayedImage() const;  // the frame on screen, at the video's size
  // The red cross's position in video frame pixels, as drawn (pixel centres at integers); NaN
  // when no mark is drawn (no observation in the displayed frame).
  QPointF markImagePosition() const;
  bool markVisible() const;
  // Whether the mark drawn is of an interpolated observation (dashed: not seen in this frame).
  bool markInterpolated() const;
  bool videoAvailable() const;
  QString videoPath() const;    // the path frames are decoded from (or looked for)
  double lastRecallMs() const;  // showObservation call to frame painted; NaN before the first
  double lastDecodeMs() const;  // the worker's part of it (seek, decode, colour conversion)
  bool isPlaying() const;
  // Draws the mission's overlay mask of the displayed frame over it (mission::OverlayAt), and
  // its sky mask (the part above its mission::SkyLine, in low oblique views); off by default.
  void setOverlayMaskVisible(bool visible);
  bool overlayMaskVisible() const { return overlay_visible_; }
  // The mask drawn over the frame on screen: null when none is (hidden, or none for the frame).
  const mission::OverlayRecord* drawnOverlayMask() const { return drawn_overlay_; }
  // The sky line drawn over the frame on screen: nullopt when none is.
  const std::optional<mission::SkyLine>& drawnSkyLine() const { return drawn_sky_; }
  QString errorText() const;  // the decode error shown in the panel, empty when none
  // The target enlarged (the frame panel's chip, Copy Chip); null without a mark on screen.
  QImage chipImage() const;
  // Saves the frame on screen at its own size with the target marked (and north, when
  // geo-referenced); false, with the reason shown in the panel, when it cannot.
  bool saveFrame(const QString& path);
  // The frame's zoom (1: the whole frame; the wheel zooms about the cursor, up to 16).
  double zoom() const;
  void setZoom(double zoom);
  // Where north lies in the frame on screen, radians clockwise from its up; nullopt when the map
  // is not geo-referenced or the frame is not placed.
  std::optional<double> northInFrame() const;
  bool decodingHintShown() const;  // "decoding…" is on screen (a decode pending > 100 ms)

 public slots:
  void previousObservation();
  void nextObservation();
  // Steps `steps` observations along the track (back when negative), stopping at its ends.
  void stepObservation(int steps);
  void play();
  void pause();
  void togglePlay();
  void copyChip();  // the chip to the clipboard

 signals:
  // The panel moved to another observation (showObservation, stepping, or playback reaching a
  // frame with an observation of the track): the view moves its marker.
  void observationChanged(size_t track_index, size_t point_index);
  void locateVideoRequested();
  // A recalled frame is on screen; `recall_ms` from the showObservation call (NaN for frames
  // shown by playback).
  void frameShown(int64_t frame_index, double recall_ms);
  void playingChanged(bool playing);

 private:
  const mission::TrackPoint* currentPoint() const;
  void setObservation(size_t track_index, size_t point_index, bool announce);
  void requestFrame(int64_t frame_index);
  void onFrameReady(quint64 ticket, int64_t frame_index, const QImage& image, double decode_ms);
  void onFailed(quint64 ticket, const QString& message);
  void onVideoReady(const QString& path, qint64 frame_count, double fps);
  void onVideoFailed(const QString& path, const QString& message);
  void present(int64_t frame_index, const QImage& image);  // puts a frame on screen
  void showMissingVideo(const QString& message);
  void showError(const QString& message);
  void updateMark();
  void updateOverlay();
  void updateInfo();
  void updateActions();
  void requestNextPlayFrame();
  void presentHeldPlayFrame();
  QString idlePlaceholder() const;  // the canvas text with no frame and nothing pending
  int64_t frameCount() const;
  double frameRate() const;

  // Widgets.
  QStackedWidget* stack_ = nullptr;  // the canvas, or the missing-video page
  FrameCanvas* canvas_ = nullptr;
  QLabel* missing_label_ = nullptr;
  QPushButton* locate_button_ = nullptr;
  QLabel* error_label_ = nullptr;
  // The observation's attributes; the track's note says when the observation is interpolated.
  ValueLabel* track_value_ = nullptr;
  ValueLabel* visit_value_ = nullptr;
  ValueLabel* time_value_ = nullptr;
  ValueLabel* frame_value_ = nullptr;
  ValueLabel* utc_value_ = nullptr;
  ValueLabel* speed_value_ = nullptr;
  ValueLabel* heading_value_ = nullptr;
  ValueLabel* confidence_value_ = nullptr;
  QToolButton* save_frame_button_ = nullptr;
  QToolButton* copy_chip_button_ = nullptr;
  QAction* previous_action_ = nullptr;
  QAction* next_action_ = nullptr;
  QAction* play_action_ = nullptr;
  // Left, Right, Shift+Left, Shift+Right: window-wide while an observation is shown.
  std::vector<QAction*> step_actions_;
  QTimer* hint_timer_ = nullptr;  // shows "decoding…" when a decode takes > 100 ms
  QTimer* play_timer_ = nullptr;  // holds a decoded playback frame until its time

  // Mission and video.
  std::shared_ptr<const mission::Mission> mission_;
  QString video_path_;
  bool video_available_ = false;
  qint64 frame_count_ = 0;  // from the warm video, else the mission's source
  double fps_ = 0;
  FrameRecall* recall_ = nullptr;
  QString warm_path_;  // the video the recall has indexed (empty while warming or failed)
  qint64 warm_frame_count_ = 0;
  double warm_fps_ = 0;

  // What is shown.
  std::optional<std::pair<size_t, size_t>> current_;
  int64_t displayed_frame_ = -1;
  QImage image_;
  bool overlay_visible_ = false;
  const mission::OverlayRecord* drawn_overlay_ = nullptr;  // in mission_->overlays
  std::optional<mission::SkyLine> drawn_sky_;

  // The request in flight (latest wins: answers to any other ticket are dropped, except frames
  // asked for by showFrame, newer than the one on screen: scrubbing).
  quint64 next_ticket_ = 0;
  quint64 presented_ticket_ = 0;                           // of the frame on screen
  std::deque<std::pair<quint64, double>> scrub_requests_;  // ticket, scrub_clock_ ms when asked
  Stopwatch scrub_clock_;
  quint64 pending_ticket_ = 0;  // 0: none
  Stopwatch click_timer_;       // since the showObservation that asked for the pending frame
  bool pending_from_click_ = false;
  double last_recall_ms_;
  double last_decode_ms_;

  // Playback: frame n is due at play_anchor_frame_ + (n - anchor) / fps on play_clock_.
  bool playing_ = false;
  int64_t play_anchor_frame_ = 0;
  Stopwatch play_clock_;
  int64_t held_frame_ = -1;  // decoded, waiting for its time
  QImage held_image_;
};

}  // namespace saker::ui
