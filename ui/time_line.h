#pragma once

// The mission time line under the map: a slider over the mission's frames with play / pause and
// a playback speed (0.25x to 8x, in video time), and the current time (video seconds and UTC).
// Dragging the slider scrubs; the owner follows frameChanged (the map's footprint and markers,
// the frame panel's picture).

#include "core/mission/mission.h"
#include "core/util/timer.h"

#include <QWidget>
#include <cstdint>
#include <memory>

class QComboBox;
class QLabel;
class QSlider;
class QTimer;
class QToolButton;

namespace saker::ui {

class TimeLine : public QWidget {
  Q_OBJECT

 public:
  explicit TimeLine(QWidget* parent = nullptr);

  // The frames to move over (none: disabled). Keeps the position when the same frames come back.
  void setMission(std::shared_ptr<const mission::Mission> mission);
  // Moves to the mission's frame `frame_index` (the nearest record) without emitting.
  void setFrame(int64_t frame_index);
  int64_t frame() const;  // -1 without frames
  bool isPlaying() const { return playing_; }
  double speed() const { return speed_; }
  void setSpeed(double speed);  // 0.25 .. 8

 public slots:
  void play();
  void pause();
  void togglePlay();

 signals:
  // The user (dragging, stepping) or playback moved to `frame_index`.
  void frameChanged(int64_t frame_index);
  void playingChanged(bool playing);

 private:
  void moveTo(int position, bool announce);  // position: index into mission_->frames
  void tick();
  void updateLabel();

  std::shared_ptr<const mission::Mission> mission_;
  QToolButton* play_button_ = nullptr;
  QSlider* slider_ = nullptr;
  QComboBox* speed_box_ = nullptr;
  QLabel* time_label_ = nullptr;
  QTimer* timer_ = nullptr;
  bool playing_ = false;
  double speed_ = 1;
  Stopwatch clock_;           // since playback started (or the speed changed)
  double anchor_time_s_ = 0;  // the video time at clock_'s start
  bool updating_ = false;     // setFrame is moving the slider
};

}  // namespace saker::ui
