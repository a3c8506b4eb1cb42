#include "ui/time_line.h"

#include <QComboBox>
#include <QDateTime>
#include <QHBoxLayout>
#include <QLabel>
#include <QSlider>
#include <QStyle>
#include <QTimeZone>
#include <QTimer>
#include <QToolButton>
#include <algorithm>
#include <array>
#include <cmath>

namespace saker::ui {
namespace {

constexpr std::array<double, 6> kSpeeds = {0.25, 0.5, 1, 2, 4, 8};
constexpr int kTickMs = 40;

QString Clock(double seconds) {
  const double s = std::max(seconds, 0.0);
  const int minutes = static_cast<int>(s / 60);
  return QStringLiteral("%1:%2").arg(minutes).arg(s - 60.0 * minutes, 4, 'f', 1, QLatin1Char('0'));
}

}  // namespace

TimeLine::TimeLine(QWidget* parent) : QWidget(parent) {
  play_button_ = new QToolButton(this);
  play_button_->setObjectName(QStringLiteral("timeLinePlay"));
  play_button_->setIcon(style()->standardIcon(QStyle::SP_MediaPlay));
  play_button_->setToolTip(tr("Play the mission from here (the map and the frame follow)"));
  play_button_->setAutoRaise(true);
  slider_ = new QSlider(Qt::Horizontal, this);
  slider_->setObjectName(QStringLiteral("timeLineSlider"));
  slider_->setToolTip(tr("The mission's time: drag to scrub through the video"));
  speed_box_ = new QComboBox(this);
  speed_box_->setObjectName(QStringLiteral("timeLineSpeed"));
  for (const double speed : kSpeeds) {
    speed_box_->addItem(QStringLiteral("%1×").arg(speed), speed);
  }
  speed_box_->setCurrentIndex(2);
  speed_box_->setToolTip(tr("Playback speed"));
  time_label_ = new QLabel(this);
  time_label_->setObjectName(QStringLiteral("timeLineTime"));
  time_label_->setMinimumWidth(time_label_->fontMetrics().horizontalAdvance(
      QStringLiteral("00:00.0 / 00:00.0  2000-00-00T00:00:00.000Z")));
  auto* layout = new QHBoxLayout(this);
  layout->setContentsMargins(4, 2, 4, 2);
  layout->addWidget(play_button_);
  layout->addWidget(slider_, 1);
  layout->addWidget(speed_box_);
  layout->addWidget(time_label_);
  timer_ = new QTimer(this);
  timer_->setInterval(kTickMs);
  connect(timer_, &QTimer::timeout, this, &TimeLine::tick);
  connect(play_button_, &QToolButton::clicked, this, &TimeLine::togglePlay);
  connect(slider_, &QSlider::valueChanged, this, [this](int position) {
    if (updating_) return;
    if (playing_ && slider_->isSliderDown()) pause();
    moveTo(position, /*announce=*/true);
  });
  connect(speed_box_, &QComboBox::currentIndexChanged, this,
          [this](int index) { setSpeed(speed_box_->itemData(index).toDouble()); });
  setMission(nullptr);
}

void TimeLine::setMission(std::shared_ptr<const mission::Mission> mission) {
  const int64_t keep = frame();
  const bool same = mission_ && mission && mission_->frames.size() == mission->frames.size();
  mission_ = std::move(mission);
  const int count = mission_ ? static_cast<int>(mission_->frames.size()) : 0;
  if (count == 0) pause();
  updating_ = true;
  slider_->setRange(0, std::max(0, count - 1));
  slider_->setPageStep(std::max(1, count / 20));
  updating_ = false;
  setEnabled(count > 0);
  if (same && keep >= 0) {
    setFrame(keep);
  } else {
    updating_ = true;
    slider_->setValue(0);
    updating_ = false;
  }
  updateLabel();
}

int64_t TimeLine::frame() const {
  if (!mission_ || mission_->frames.empty()) return -1;
  return mission_->frames[static_cast<size_t>(slider_->value())].index;
}

void TimeLine::setFrame(int64_t frame_index) {
  if (!mission_ || mission_->frames.empty()) return;
  const auto& frames = mission_->frames;
  const auto it = std::lower_bound(
      frames.begin(), frames.end(), frame_index,
      [](const mission::FrameRecord& r, int64_t index) { return r.index < index; });
  const int position = static_cast<int>(
      std::min<size_t>(static_cast<size_t>(it - frames.begin()), frames.size() - 1));
  moveTo(position, /*announce=*/false);
}

void TimeLine::moveTo(int position, bool announce) {
  if (!mission_ || mission_->frames.empty()) return;
  position = std::clamp(position, 0, static_cast<int>(mission_->frames.size()) - 1);
  if (slider_->value() != position) {
    updating_ = true;
    slider_->setValue(position);
    updating_ = false;
  }
  updateLabel();
  if (announce) emit frameChanged(mission_->frames[static_cast<size_t>(position)].index);
}

void TimeLine::setSpeed(double speed) {
  speed = std::clamp(speed, kSpeeds.front(), kSpeeds.back());
  if (playing_ && mission_ && !mission_->frames.empty()) {
    anchor_time_s_ = mission_->frames[static_cast<size_t>(slider_->value())].time_s;
    clock_.Restart();
  }
  speed_ = speed;
  for (int i = 0; i < speed_box_->count(); ++i) {
    if (std::abs(speed_box_->itemData(i).toDouble() - speed) < 1e-9 &&
        speed_box_->currentIndex() != i) {
      speed_box_->setCurrentIndex(i);
    }
  }
}

void TimeLine::play() {
  if (playing_ || !mission_ || mission_->frames.size() < 2) return;
  // From the start again when at the end.
  if (slider_->value() >= slider_->maximum()) moveTo(0, /*announce=*/true);
  playing_ = true;
  anchor_time_s_ = mission_->frames[static_cast<size_t>(slider_->value())].time_s;
  clock_.Restart();
  timer_->start();
  play_button_->setIcon(style()->standardIcon(QStyle::SP_MediaPause));
  emit playingChanged(true);
}

void TimeLine::pause() {
  if (!playing_) return;
  playing_ = false;
  timer_->stop();
  play_button_->setIcon(style()->standardIcon(QStyle::SP_MediaPlay));
  emit playingChanged(false);
}

void TimeLine::togglePlay() { playing_ ? pause() : play(); }

void TimeLine::tick() {
  if (!playing_ || !mission_) return;
  const auto& frames = mission_->frames;
  const double target = anchor_time_s_ + clock_.ElapsedSeconds() * speed_;
  // The last frame at or before the target time.
  const auto it =
      std::upper_bound(frames.begin(), frames.end(), target,
                       [](double t, const mission::FrameRecord& r) { return t < r.time_s; });
  const int position = std::max(0, static_cast<int>(it - frames.begin()) - 1);
  if (position != slider_->value()) moveTo(position, /*announce=*/true);
  if (position >= slider_->maximum()) pause();
}

void TimeLine::updateLabel() {
  if (!mission_ || mission_->frames.empty()) {
    time_label_->setText(tr("no frames"));
    return;
  }
  const mission::FrameRecord& f = mission_->frames[static_cast<size_t>(slider_->value())];
  QString text =
      QStringLiteral("%1 / %2").arg(Clock(f.time_s), Clock(mission_->frames.back().time_s));
  if (f.utc_us) {
    text +=
        QStringLiteral("  ") + QDateTime::fromMSecsSinceEpoch(*f.utc_us / 1000, QTimeZone::utc())
                                   .toString(QStringLiteral("yyyy-MM-dd'T'HH:mm:ss.zzz'Z'"));
  }
  time_label_->setText(text);
}

}  // namespace saker::ui
