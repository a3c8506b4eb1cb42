#include "ui/frame_panel.h"

#include "ui/frame_recall.h"

#include <Eigen/Geometry>
#include <Eigen/LU>

#include <QAction>
#include <QClipboard>
#include <QCoreApplication>
#include <QDateTime>
#include <QDir>
#include <QFileDialog>
#include <QFileInfo>
#include <QFontMetrics>
#include <QGridLayout>
#include <QGuiApplication>
#include <QHBoxLayout>
#include <QKeySequence>
#include <QLabel>
#include <QMouseEvent>
#include <QPaintEvent>
#include <QPainter>
#include <QPainterPath>
#include <QPushButton>
#include <QStackedWidget>
#include <QStyle>
#include <QTimeZone>
#include <QTimer>
#include <QToolButton>
#include <QVBoxLayout>
#include <QWheelEvent>
#include <algorithm>
#include <cmath>
#include <limits>

namespace saker::ui {

namespace {

// The video's frame index as the mission stores it (schema 2), or empty when any frame lacks its
// stream position or the positions are not strictly increasing.
std::vector<video::FrameIndexEntry> StoredFrameIndex(const mission::Mission& mission) {
  std::vector<video::FrameIndexEntry> index;
  index.reserve(mission.frames.size());
  for (const mission::FrameRecord& f : mission.frames) {
    if (!f.pts || f.index != static_cast<int64_t>(index.size()) ||
        (!index.empty() && *f.pts <= index.back().pts))
      return {};
    index.push_back({f.index, *f.pts, f.time_s, f.key_frame});
  }
  return index;
}

constexpr int kHintDelayMs = 100;  // a decode faster than this shows no "decoding…" hint
constexpr int kLongStep = 10;      // observations stepped by Shift+Left and Shift+Right
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// The 16 compass points, clockwise from north.
const char* const kCompassPoints[] = {QT_TRANSLATE_NOOP("saker::ui::FramePanel", "N"),
                                      QT_TRANSLATE_NOOP("saker::ui::FramePanel", "NNE"),
                                      QT_TRANSLATE_NOOP("saker::ui::FramePanel", "NE"),
                                      QT_TRANSLATE_NOOP("saker::ui::FramePanel", "ENE"),
                                      QT_TRANSLATE_NOOP("saker::ui::FramePanel", "E"),
                                      QT_TRANSLATE_NOOP("saker::ui::FramePanel", "ESE"),
                                      QT_TRANSLATE_NOOP("saker::ui::FramePanel", "SE"),
                                      QT_TRANSLATE_NOOP("saker::ui::FramePanel", "SSE"),
                                      QT_TRANSLATE_NOOP("saker::ui::FramePanel", "S"),
                                      QT_TRANSLATE_NOOP("saker::ui::FramePanel", "SSW"),
                                      QT_TRANSLATE_NOOP("saker::ui::FramePanel", "SW"),
                                      QT_TRANSLATE_NOOP("saker::ui::FramePanel", "WSW"),
                                      QT_TRANSLATE_NOOP("saker::ui::FramePanel", "W"),
                                      QT_TRANSLATE_NOOP("saker::ui::FramePanel", "WNW"),
                                      QT_TRANSLATE_NOOP("saker::ui::FramePanel", "NW"),
                                      QT_TRANSLATE_NOOP("saker::ui::FramePanel", "NNW")};

// The 8 directions on a map in pixels, clockwise from up the picture: such a map has no north.
const char* const kPictureDirections[] = {QT_TRANSLATE_NOOP("saker::ui::FramePanel", "up"),
                                          QT_TRANSLATE_NOOP("saker::ui::FramePanel", "up-right"),
                                          QT_TRANSLATE_NOOP("saker::ui::FramePanel", "right"),
                                          QT_TRANSLATE_NOOP("saker::ui::FramePanel", "down-right"),
                                          QT_TRANSLATE_NOOP("saker::ui::FramePanel", "down"),
                                          QT_TRANSLATE_NOOP("saker::ui::FramePanel", "down-left"),
                                          QT_TRANSLATE_NOOP("saker::ui::FramePanel", "left"),
                                          QT_TRANSLATE_NOOP("saker::ui::FramePanel", "up-left")};

// The word of `words` (which divide the circle equally, clockwise from 0) for a heading.
template <size_t N>
QString DirectionWord(double degrees, const char* const (&words)[N]) {
  const double wrapped = std::fmod(std::fmod(degrees, 360.0) + 360.0, 360.0);
  const size_t sector = static_cast<size_t>(std::floor(wrapped / (360.0 / N) + 0.5)) % N;
  return QCoreApplication::translate("saker::ui::FramePanel", words[sector]);
}

// The shortcuts as the platform writes them, for tooltips: "Right, .".
QString ShortcutText(const QAction* action) {
  QStringList keys;
  for (const QKeySequence& key : action->shortcuts()) {
    keys << key.toString(QKeySequence::NativeText);
  }
  return keys.join(QStringLiteral(", "));
}

// The track's motion at observation `i`: over the observations within 0.5 s either side (at least
// a neighbour), speed in map units per second and heading in degrees clockwise from map north
// (+y geo-referenced, up the image otherwise); nullopt for a single observation.
struct Motion {
  double speed = 0;
  double heading_deg = 0;
};
std::optional<Motion> MotionAt(const mission::ActivityTrack& track, size_t i, bool geo) {
  const auto& points = track.points;
  if (points.size() < 2 || i >= points.size()) return std::nullopt;
  constexpr double kHalfWindowS = 0.5;
  size_t a = i, b = i;
  while (a > 0 && points[i].time_s - points[a - 1].time_s <= kHalfWindowS) --a;
  while (b + 1 < points.size() && points[b + 1].time_s - points[i].time_s <= kHalfWindowS) ++b;
  if (a == b) (i > 0 ? a : b) = i > 0 ? i - 1 : i + 1;
  const double dt = points[b].time_s - points[a].time_s;
  const Eigen::Vector2d d = points[b].map - points[a].map;
  if (!(dt > 0) || !d.allFinite()) return std::nullopt;
  const double heading = std::atan2(d.x(), geo ? d.y() : -d.y()) * 180 / M_PI;
  return Motion{d.norm() / dt, std::fmod(heading + 360, 360)};
}

}  // namespace

// The frame, scaled to fit and kept in proportion (zoomable with the wheel, dragged to pan,
// double-click to zoom in or back out), with the observation's mark painted at display scale on
// top (so the lines stay crisp however the frame is scaled), the target's chip in a corner and a
// north arrow when the map is geo-referenced.
class FrameCanvas : public QWidget {
 public:
  explicit FrameCanvas(QWidget* parent) : QWidget(parent) {
    setMinimumSize(160, 90);
    setSizePolicy(QSizePolicy::Expanding, QSizePolicy::Expanding);
    setFocusPolicy(Qt::StrongFocus);
  }

  void setImage(const QImage& image) {
    if (image.size() != image_.size()) resetZoom();
    image_ = image;
    update();
  }
  // The observation to mark, in video frame pixels; nullopt hides the mark. Zoomed in, the view
  // follows the mark unless the user has panned since the observation changed.
  // `interpolated`: the object was not seen in this frame (the mark is dashed).
  void setMark(std::optional<QPointF> point, QRectF box, bool interpolated = false) {
    mark_ = point;
    box_ = box;
    mark_interpolated_ = interpolated;
    if (mark_ && zoom_ > 1 && !panned_) centre_ = *mark_;
    update();
  }
  void observationChanged() { panned_ = false; }
  const std::optional<QPointF>& mark() const { return mark_; }
  bool markInterpolated() const { return mark_interpolated_; }
  // The overlay mask to draw over the frame: one pixel a cell of `cell_px` video frame pixels
  // (the mask's colour and transparency are the image's); a null image draws none.
  void setOverlay(const QImage& cells, int cell_px) {
    overlay_ = cells;
    overlay_cell_px_ = cell_px;
    update();
  }
  bool hasOverlay() const { return !overlay_.isNull(); }
  // The sky mask's edge to draw over the frame (the part above it tinted); nullopt draws none.
  void setSkyLine(std::optional<mission::SkyLine> line) {
    sky_ = line;
    update();
  }
  // Where north points in the frame (radians clockwise from the frame's up); nullopt: not
  // geo-referenced, no arrow.
  void setNorth(std::optional<double> radians) {
    north_ = radians;
    update();
  }
  const std::optional<double>& north() const { return north_; }
  const QString& hint() const { return hint_; }
  void setPlaceholder(const QString& text) {
    placeholder_ = text;
    update();
  }
  void setHint(const QString& text) {
    if (hint_ == text) return;
    hint_ = text;
    update();
  }

  // Zoom: 1 fits the frame; up to kMaxZoom, about `anchor` (widget) when given.
  double zoom() const { return zoom_; }
  void setZoom(double zoom, std::optional<QPointF> anchor = std::nullopt) {
    if (image_.isNull()) return;
    zoom = std::clamp(zoom, 1.0, kMaxZoom);
    const QPointF at = anchor.value_or(QPointF(width() / 2.0, height() / 2.0));
    const QPointF fixed = imageFromWidget(at);  // stays under `at`
    zoom_ = zoom;
    const double scale = fitScale() * zoom_;
    // The image point at the widget centre such that `fixed` is drawn at `at`.
    centre_ = fixed + (QPointF(width() / 2.0, height() / 2.0) - at) / scale;
    if (zoom_ <= 1) resetZoom();
    update();
  }
  void resetZoom() {
    zoom_ = 1;
    panned_ = false;
    update();
  }

  // The chip: the target enlarged (the area round the box, at least 32 px, made kChipSide px
  // wide), with the box drawn; null without a mark.
  QImage chip() const {
    if (!mark_ || image_.isNull()) return {};
    const double side = std::max({32.0, box_.width() * 2.5, box_.height() * 2.5});
    const QRectF area(*mark_ - QPointF(side / 2, side / 2), QSizeF(side, side));
    QImage out(kChipSide, kChipSide, QImage::Format_RGB32);
    out.fill(QColor(24, 24, 24));
    QPainter painter(&out);
    painter.setRenderHint(QPainter::SmoothPixmapTransform);
    // Frame pixel p (centres at integers) covers [p - 0.5, p + 0.5).
    const QRectF source = area.translated(0.5, 0.5);
    painter.drawImage(QRectF(0, 0, kChipSide, kChipSide), image_, source);
    const double scale = kChipSide / side;
    const QRectF box((box_.left() + 0.5 - source.left()) * scale,
                     (box_.top() + 0.5 - source.top()) * scale, box_.width() * scale,
                     box_.height() * scale);
    painter.setRenderHint(QPainter::Antialiasing);
    painter.setPen(QPen(QColor(255, 255, 255, 200), 3));
    painter.drawRect(box.adjusted(-3, -3, 3, 3));
    painter.setPen(QPen(QColor(230, 20, 20), 1.5));
    painter.drawRect(box.adjusted(-3, -3, 3, 3));
    return out;
  }
  // The frame at its own size with the mark drawn, as saved by "Save Frame".
  QImage annotatedFrame() const {
    if (image_.isNull()) return {};
    QImage out = image_.convertToFormat(QImage::Format_RGB32);
    QPainter painter(&out);
    const QRectF target(0, 0, image_.width(), image_.height());
    if (mark_) paintMark(painter, target);
    if (north_) paintNorth(painter, target);
    return out;
  }

  QSize sizeHint() const override { return {480, 270}; }

 protected:
  void paintEvent(QPaintEvent*) override {
    QPainter painter(this);
    painter.fillRect(rect(), QColor(24, 24, 24));
    if (image_.isNull()) {
      painter.setPen(QColor(200, 200, 200));
      painter.drawText(rect().adjusted(12, 12, -12, -12), Qt::AlignCenter | Qt::TextWordWrap,
                       placeholder_);
    } else {
      const QRectF target = imageRect();
      painter.save();
      painter.setClipRect(rect());
      painter.setRenderHint(QPainter::SmoothPixmapTransform, zoom_ < 4);
      painter.drawImage(target, image_);
      if (sky_) paintSky(painter, target);
      if (!overlay_.isNull()) paintOverlay(painter, target);
      if (mark_) paintMark(painter, target);
      painter.restore();
      if (north_) paintNorth(painter, QRectF(rect()));
      if (mark_ && width() >= 3 * kChipSide / 2 && height() >= kChipSide + 40) paintChip(painter);
      if (zoom_ > 1) {
        const QString text = QStringLiteral("×%1").arg(zoom_, 0, 'f', zoom_ < 10 ? 1 : 0);
        paintBadge(painter, text, rect().bottomRight() + QPoint(-8, -8), Qt::AlignRight);
      }
    }

    if (!hint_.isEmpty())
      paintBadge(painter, hint_, rect().topRight() + QPoint(-8, 8), Qt::AlignTop);
  }

  void wheelEvent(QWheelEvent* event) override {
    const int delta = event->angleDelta().y();
    if (delta == 0 || image_.isNull()) {
      event->ignore();
      return;
    }
    setZoom(zoom_ * std::pow(1.25, delta / 120.0), event->position());
    panned_ = zoom_ > 1;
    event->accept();
  }
  void mousePressEvent(QMouseEvent* event) override {
    if (event->button() == Qt::LeftButton && zoom_ > 1) {
      drag_from_ = event->position();
      setCursor(Qt::ClosedHandCursor);
    }
    QWidget::mousePressEvent(event);
  }
  void mouseMoveEvent(QMouseEvent* event) override {
    if (drag_from_) {
      centre_ -= (event->position() - *drag_from_) / (fitScale() * zoom_);
      drag_from_ = event->position();
      panned_ = true;
      update();
    }
    QWidget::mouseMoveEvent(event);
  }
  void mouseReleaseEvent(QMouseEvent* event) override {
    drag_from_.reset();
    unsetCursor();
    QWidget::mouseReleaseEvent(event);
  }
  void mouseDoubleClickEvent(QMouseEvent* event) override {
    // Double-click: back to the whole frame, or (at the whole frame) 4x about the click.
    if (zoom_ > 1) {
      resetZoom();
    } else {
      setZoom(4, event->position());
    }
    event->accept();
  }

 private:
  static constexpr double kMaxZoom = 16;
  static constexpr int kChipSide = 128;

  double fitScale() const {
    if (image_.isNull()) return 1;
    return std::min(width() / static_cast<double>(image_.width()),
                    height() / static_cast<double>(image_.height()));
  }
  // Where the image is drawn (widget coordinates): fitted, or zoomed about centre_ (kept so
  // that the image covers the widget where it can).
  QRectF imageRect() const {
    const double scale = fitScale() * zoom_;
    const QSizeF size(image_.width() * scale, image_.height() * scale);
    if (zoom_ <= 1) {
      return QRectF(QPointF((width() - size.width()) / 2, (height() - size.height()) / 2), size);
    }
    QPointF top_left =
        QPointF(width() / 2.0, height() / 2.0) - (centre_ + QPointF(0.5, 0.5)) * scale;
    const auto clamp_axis = [](double v, double extent, double view) {
      return extent <= view ? (view - extent) / 2 : std::clamp(v, view - extent, 0.0);
    };
    top_left.setX(clamp_axis(top_left.x(), size.width(), width()));
    top_left.setY(clamp_axis(top_left.y(), size.height(), height()));
    return QRectF(top_left, size);
  }
  QPointF imageFromWidget(const QPointF& widget) const {
    const QRectF target = imageRect();
    const double scale = target.width() / image_.width();
    return (widget - target.topLeft()) / scale - QPointF(0.5, 0.5);
  }

  void paintBadge(QPainter& painter, const QString& text, QPoint corner,
                  Qt::Alignment where) const {
    const QFontMetrics metrics(font());
    const QRect size = metrics.boundingRect(text).adjusted(-6, -3, 6, 3);
    QRect box(QPoint(0, 0), size.size());
    if (where & Qt::AlignRight) {
      box.moveBottomRight(corner);
    } else {
      box.moveTopRight(corner);
    }
    painter.fillRect(box, QColor(0, 0, 0, 170));
    painter.setPen(Qt::white);
    painter.drawText(box, Qt::AlignCenter, text);
  }

  // The target chip, in the canvas's lower-left corner.
  void paintChip(QPainter& painter) const {
    const QImage picture = chip();
    if (picture.isNull()) return;
    const QRectF box(8, height() - 8 - kChipSide, kChipSide, kChipSide);
    painter.save();
    painter.drawImage(box, picture);
    painter.setPen(QPen(QColor(255, 255, 255, 220), 2));
    painter.setBrush(Qt::NoBrush);
    painter.drawRect(box.adjusted(-1, -1, 1, 1));
    painter.restore();
  }

  // A north arrow in the upper-left corner of `area`, rotated as north lies in the frame.
  void paintNorth(QPainter& painter, const QRectF& area) const {
    const double radius = std::clamp(std::min(area.width(), area.height()) / 14, 12.0, 40.0);
    const QPointF centre = area.topLeft() + QPointF(radius + 8, radius + 8);
    painter.save();
    painter.setRenderHint(QPainter::Antialiasing);
    painter.setPen(Qt::NoPen);
    painter.setBrush(QColor(0, 0, 0, 150));
    painter.drawEllipse(centre, radius, radius);
    painter.translate(centre);
    painter.rotate(*north_ * 180 / M_PI);
    const QPolygonF arrow({QPointF(0, -radius * 0.8), QPointF(radius * 0.35, radius * 0.45),
                           QPointF(0, radius * 0.2), QPointF(-radius * 0.35, radius * 0.45)});
    painter.setBrush(QColor(235, 235, 235));
    painter.drawPolygon(arrow);
    QFont font = painter.font();
    font.setBold(true);
    font.setPixelSize(std::max(9, static_cast<int>(radius * 0.55)));
    painter.setFont(font);
    painter.setPen(QColor(230, 40, 40));
    painter.drawText(QRectF(-radius, -radius * 1.02, 2 * radius, radius * 0.7), Qt::AlignCenter,
                     QStringLiteral("N"));
    painter.restore();
  }

  // The overlay mask's cells over the image drawn in `target`, sharp-edged: cell (x, y) covers
  // frame pixels [x, x+1) * cell_px, and pixel p is drawn at [p, p+1) * scale.
  void paintOverlay(QPainter& painter, const QRectF& target) const {
    const double scale = target.width() / image_.width();
    const QRectF cells(target.topLeft(), QSizeF(overlay_.width() * overlay_cell_px_ * scale,
                                                overlay_.height() * overlay_cell_px_ * scale));
    painter.save();
    painter.setClipRect(target);
    painter.setRenderHint(QPainter::SmoothPixmapTransform, false);
    painter.drawImage(cells, overlay_);
    painter.restore();
  }

  // The sky mask over the image drawn in `target`: the part above the line, tinted amber, and the
  // line itself.
  void paintSky(QPainter& painter, const QRectF& target) const {
    const double scale = target.width() / image_.width();
    const double right = image_.width() - 0.5;
    // Frame pixel p (centres at integers) is drawn at (p + 0.5) * scale.
    const auto at = [&](double x) {
      return target.topLeft() +
             QPointF((x + 0.5) * scale, (sky_->y0 + sky_->slope * x + 0.5) * scale);
    };
    QPolygonF sky;
    sky << target.topLeft() << target.topRight() << at(right) << at(-0.5);
    painter.save();
    painter.setClipRect(target);
    painter.setRenderHint(QPainter::Antialiasing);
    painter.setPen(Qt::NoPen);
    painter.setBrush(QColor(255, 170, 0, 70));
    painter.drawPolygon(sky);
    painter.setPen(QPen(QColor(255, 170, 0, 200), 1.5, Qt::DashLine));
    painter.drawLine(at(-0.5), at(right));
    painter.restore();
  }

  // The mark over the image drawn in `target` (widget coordinates): a box round the object and
  // a cross whose arms start outside the box, so that the object itself stays clear.
  void paintMark(QPainter& painter, const QRectF& target) const {
    // Pixel centres are at integer coordinates (the engine's convention), so pixel (0, 0) covers
    // [-0.5, 0.5) and is drawn at [0, scale).
    const double scale = target.width() / image_.width();
    auto to_widget = [&](QPointF p) {
      return target.topLeft() + QPointF((p.x() + 0.5) * scale, (p.y() + 0.5) * scale);
    };
    painter.save();
    painter.setRenderHint(QPainter::Antialiasing);
    painter.setClipRect(target);
    const QPointF centre = to_widget(*mark_);
    const QRectF box = QRectF(to_widget(box_.topLeft()), to_widget(box_.bottomRight()))
                           .normalized()
                           .adjusted(-2, -2, 2, 2);
    constexpr double kGap = 5;
    constexpr double kArm = 11;
    QPainterPath cross;
    const double half_w = std::max(box.width() / 2, 2.0) + kGap;
    const double half_h = std::max(box.height() / 2, 2.0) + kGap;
    for (const auto& [direction, start] :
         {std::pair{QPointF(1, 0), half_w}, std::pair{QPointF(-1, 0), half_w},
          std::pair{QPointF(0, 1), half_h}, std::pair{QPointF(0, -1), half_h}}) {
      cross.moveTo(centre + direction * start);
      cross.lineTo(centre + direction * (start + kArm));
    }
    // A thin white outline under the red keeps the mark visible on red or dark ground.
    painter.setBrush(Qt::NoBrush);
    painter.setPen(QPen(QColor(255, 255, 255, 220), 3.5, Qt::SolidLine, Qt::FlatCap));
    painter.drawRect(box);
    painter.drawPath(cross);
    painter.setPen(QPen(QColor(230, 20, 20), 1.75,
                        mark_interpolated_ ? Qt::DashLine : Qt::SolidLine, Qt::FlatCap));
    painter.drawRect(box);
    painter.drawPath(cross);
    painter.restore();
  }

  QImage overlay_;  // ARGB, a pixel a cell
  int overlay_cell_px_ = 8;
  std::optional<mission::SkyLine> sky_;
  std::optional<double> north_;
  QImage image_;
  std::optional<QPointF> mark_;
  QRectF box_;
  bool mark_interpolated_ = false;
  QString placeholder_;
  QString hint_;
  double zoom_ = 1;
  QPointF centre_;  // zoomed: the image point at the widget's centre
  bool panned_ = false;
  std::optional<QPointF> drag_from_;
};

// A value of the observation's attributes. Its text does not size the panel: playback changes it
// at every frame, and the panel keeps the width it was given. A text wider than the label is
// elided, and given in full in the tooltip, followed by the value's note (setNote), if any.
class ValueLabel : public QLabel {
 public:
  explicit ValueLabel(QWidget* parent) : QLabel(parent) {
    setSizePolicy(QSizePolicy::Ignored, QSizePolicy::Preferred);
    setTextInteractionFlags(Qt::TextSelectableByMouse);
  }
  // A word on the value, shown as its tooltip (after the full text when that is elided).
  void setNote(const QString& note) {
    note_ = note;
    updateTip();
  }

 protected:
  void paintEvent(QPaintEvent* event) override {
    const QRect area = contentsRect();
    const QFontMetrics metrics(font());
    const bool fits = updateTip();
    if (fits) {
      QLabel::paintEvent(event);
      return;
    }
    QPainter painter(this);
    painter.setPen(palette().color(foregroundRole()));
    painter.drawText(area, Qt::AlignLeft | Qt::AlignVCenter,
                     metrics.elidedText(text(), Qt::ElideRight, area.width()));
  }

 private:
  // Sets the tooltip; whether the text fits the label.
  bool updateTip() {
    const bool fits = QFontMetrics(font()).horizontalAdvance(text()) <= contentsRect().width();
    const QString full = fits ? QString() : text();
    setToolTip(note_.isEmpty() ? full
                               : (full.isEmpty() ? note_ : full + QStringLiteral("\n\n") + note_));
    return fits;
  }

  QString note_;
};

FramePanel::FramePanel(QWidget* parent)
    : QWidget(parent), last_recall_ms_(kNaN), last_decode_ms_(kNaN) {
  recall_ = new FrameRecall(this);
  connect(recall_, &FrameRecall::frameReady, this, &FramePanel::onFrameReady);
  connect(recall_, &FrameRecall::failed, this, &FramePanel::onFailed);
  connect(recall_, &FrameRecall::videoReady, this,
          [this](const QString& path, qint64 count, double fps, double) {
            onVideoReady(path, count, fps);
          });
  connect(recall_, &FrameRecall::videoFailed, this, &FramePanel::onVideoFailed);

  // The frame, or the message about a missing video.
  canvas_ = new FrameCanvas(this);
  canvas_->setObjectName(QStringLiteral("frameCanvas"));
  auto* missing_page = new QWidget(this);
  missing_label_ = new QLabel(missing_page);
  missing_label_->setObjectName(QStringLiteral("missingVideoMessage"));
  missing_label_->setWordWrap(true);
  missing_label_->setAlignment(Qt::AlignCenter);
  missing_label_->setTextInteractionFlags(Qt::TextSelectableByMouse);
  locate_button_ = new QPushButton(style()->standardIcon(QStyle::SP_DirOpenIcon),
                                   tr("Locate Video…"), missing_page);
  locate_button_->setObjectName(QStringLiteral("locateVideoButton"));
  connect(locate_button_, &QPushButton::clicked, this, &FramePanel::locateVideoRequested);
  auto* missing_layout = new QVBoxLayout(missing_page);
  auto* missing_icon = new QLabel(missing_page);
  missing_icon->setPixmap(style()->standardIcon(QStyle::SP_MessageBoxWarning).pixmap(32, 32));
  missing_layout->addStretch(1);
  missing_layout->addWidget(missing_icon, 0, Qt::AlignHCenter);
  missing_layout->addWidget(missing_label_);
  missing_layout->addWidget(locate_button_, 0, Qt::AlignHCenter);
  missing_layout->addStretch(1);
  stack_ = new QStackedWidget(this);
  stack_->addWidget(canvas_);
  stack_->addWidget(missing_page);

  error_label_ = new QLabel(this);
  error_label_->setObjectName(QStringLiteral("frameError"));
  error_label_->setWordWrap(true);
  error_label_->setTextInteractionFlags(Qt::TextSelectableByMouse);
  error_label_->setStyleSheet(QStringLiteral("color: #c62828;"));
  error_label_->hide();

  // Stepping and playback: actions carry the shortcuts, tool buttons show them. Comma, period and
  // Space act while the focus is in the panel. Left and Right (with Shift: ten observations) act
  // anywhere in the window once an observation is shown, so that they step along the track picked
  // on the map; with none shown they pan the map, and text boxes keep them.
  previous_action_ = new QAction(style()->standardIcon(QStyle::SP_MediaSkipBackward),
                                 tr("Previous Observation"), this);
  previous_action_->setShortcut(QKeySequence(Qt::Key_Comma));
  next_action_ =
      new QAction(style()->standardIcon(QStyle::SP_MediaSkipForward), tr("Next Observation"), this);
  next_action_->setShortcut(QKeySequence(Qt::Key_Period));
  const std::pair<QKeyCombination, int> steps[] = {{Qt::Key_Left, -1},
                                                   {Qt::Key_Right, 1},
                                                   {Qt::ShiftModifier | Qt::Key_Left, -kLongStep},
                                                   {Qt::ShiftModifier | Qt::Key_Right, kLongStep}};
  for (const auto& [key, delta] : steps) {
    auto* step = new QAction(this);
    step->setShortcut(QKeySequence(key));
    step->setShortcutContext(Qt::WindowShortcut);
    connect(step, &QAction::triggered, this, [this, delta = delta] { stepObservation(delta); });
    addAction(step);
    step_actions_.push_back(step);
  }
  play_action_ = new QAction(style()->standardIcon(QStyle::SP_MediaPlay), tr("Play"), this);
  play_action_->setShortcut(QKeySequence(Qt::Key_Space));
  connect(previous_action_, &QAction::triggered, this, &FramePanel::previousObservation);
  connect(next_action_, &QAction::triggered, this, &FramePanel::nextObservation);
  connect(play_action_, &QAction::triggered, this, &FramePanel::togglePlay);
  auto* buttons = new QHBoxLayout;
  buttons->setSpacing(2);
  const std::pair<QAction*, const char*> tool_buttons[] = {{previous_action_, "previousButton"},
                                                           {play_action_, "playButton"},
                                                           {next_action_, "nextButton"}};
  for (const auto& [action, name] : tool_buttons) {
    action->setShortcutContext(Qt::WidgetWithChildrenShortcut);
    addAction(action);
    auto* button = new QToolButton(this);
    button->setObjectName(QLatin1String(name));
    button->setDefaultAction(action);
    button->setAutoRaise(true);
    button->setIconSize(QSize(20, 20));
    // Buttons never take focus: Space must toggle playback, not press the focused button.
    button->setFocusPolicy(Qt::NoFocus);
    buttons->addWidget(button);
  }
  buttons->addStretch(1);
  // The frame and the target, for a report or a message.
  save_frame_button_ = new QToolButton(this);
  save_frame_button_->setObjectName(QStringLiteral("saveFrameButton"));
  save_frame_button_->setText(tr("Save Frame…"));
  save_frame_button_->setToolTip(
      tr("Save the frame on screen, with the target marked, as a picture"));
  save_frame_button_->setAutoRaise(true);
  save_frame_button_->setFocusPolicy(Qt::NoFocus);
  connect(save_frame_button_, &QToolButton::clicked, this, [this] {
    const QString path = QFileDialog::getSaveFileName(
        this, tr("Save Frame"),
        QDir::home().filePath(QStringLiteral("frame-%1.png").arg(displayed_frame_)),
        tr("Pictures (*.png *.jpg *.tif)"));
    if (!path.isEmpty()) saveFrame(path);
  });
  copy_chip_button_ = new QToolButton(this);
  copy_chip_button_->setObjectName(QStringLiteral("copyChipButton"));
  copy_chip_button_->setText(tr("Copy Chip"));
  copy_chip_button_->setToolTip(tr("Copy the target, enlarged, to the clipboard"));
  copy_chip_button_->setAutoRaise(true);
  copy_chip_button_->setFocusPolicy(Qt::NoFocus);
  connect(copy_chip_button_, &QToolButton::clicked, this, &FramePanel::copyChip);
  buttons->addWidget(save_frame_button_);
  buttons->addWidget(copy_chip_button_);

  // The observation's attributes, two pairs a row to stay compact.
  auto* info = new QGridLayout;
  info->setHorizontalSpacing(8);
  info->setVerticalSpacing(2);
  auto add = [this, info](int row, int column, const QString& name, const char* object_name,
                          int span = 1) {
    auto* key = new QLabel(name, this);
    key->setForegroundRole(QPalette::PlaceholderText);
    auto* value = new ValueLabel(this);
    value->setObjectName(QLatin1String(object_name));
    info->addWidget(key, row, column * 2);
    info->addWidget(value, row, column * 2 + 1, 1, span);
    return value;
  };
  track_value_ = add(0, 0, tr("Track"), "trackValue");
  visit_value_ = add(0, 1, tr("Visit"), "visitValue");
  time_value_ = add(1, 0, tr("Time"), "timeValue");
  frame_value_ = add(1, 1, tr("Frame"), "frameValue");
  utc_value_ = add(2, 0, tr("UTC"), "utcValue", 3);
  speed_value_ = add(3, 0, tr("Speed"), "speedValue", 3);
  heading_value_ = add(4, 0, tr("Heading"), "headingValue", 3);
  confidence_value_ = add(5, 0, tr("Confidence"), "confidenceValue");
  info->setColumnStretch(1, 1);
  info->setColumnStretch(3, 1);

  auto* layout = new QVBoxLayout(this);
  layout->setContentsMargins(4, 4, 4, 4);
  layout->setSpacing(4);
  layout->addWidget(stack_, 1);
  layout->addWidget(error_label_);
  layout->addLayout(buttons);
  layout->addLayout(info);

  setFocusPolicy(Qt::StrongFocus);
  setFocusProxy(canvas_);

  hint_timer_ = new QTimer(this);
  hint_timer_->setSingleShot(true);
  connect(hint_timer_, &QTimer::timeout, this, [this] {
    if (pending_ticket_ != 0) canvas_->setHint(tr("decoding…"));
  });
  play_timer_ = new QTimer(this);
  play_timer_->setSingleShot(true);
  play_timer_->setTimerType(Qt::PreciseTimer);
  connect(play_timer_, &QTimer::timeout, this, &FramePanel::presentHeldPlayFrame);

  setMission(nullptr, QString());
}

FramePanel::~FramePanel() = default;

void FramePanel::setMission(std::shared_ptr<const mission::Mission> mission,
                            const QString& video_path, bool same_video) {
  pause();
  mission_ = std::move(mission);
  current_.reset();
  displayed_frame_ = -1;
  image_ = QImage();
  canvas_->setImage(QImage());
  canvas_->setMark(std::nullopt, {});
  drawn_overlay_ = nullptr;
  canvas_->setOverlay(QImage(), 1);
  drawn_sky_.reset();
  canvas_->setSkyLine(std::nullopt);
  pending_ticket_ = 0;
  pending_from_click_ = false;
  hint_timer_->stop();
  canvas_->setHint(QString());
  showError(QString());
  frame_count_ = mission_ ? mission_->source.frame_count : 0;
  fps_ = mission_ ? mission_->source.frame_rate : 0;

  if (!mission_) {
    video_path_.clear();
    video_available_ = false;
    warm_path_.clear();
    recall_->setVideo(QString());
    stack_->setCurrentWidget(canvas_);
    canvas_->setPlaceholder(tr("No mission is open."));
  } else {
    // An empty path means the owner did not find the video: name where the mission says it was.
    const bool given = !video_path.isEmpty();
    video_path_ = given ? video_path : QString::fromStdString(mission_->source.path);
    if (!given || !QFileInfo(video_path_).isFile()) {
      video_available_ = false;
      warm_path_.clear();
      recall_->setVideo(QString());
      showMissingVideo(tr("The video of this mission is not at %1. Frame recall needs the video.")
                           .arg(video_path_.isEmpty() ? tr("(no path recorded)")
                                                      : QDir::toNativeSeparators(video_path_)));
    } else {
      video_available_ = true;
      // Warm up now, while the analyst looks at the mosaic; a mission reloaded on the same video
      // (processing progress, a new track list) keeps the warm index instead of rebuilding it.
      if (warm_path_ == video_path_ && recall_->isWarm()) {
        frame_count_ = warm_frame_count_;
        if (warm_fps_ > 0) fps_ = warm_fps_;
      } else {
        warm_path_.clear();
        recall_->setVideo(video_path_, same_video ? StoredFrameIndex(*mission_)
                                                  : std::vector<video::FrameIndexEntry>{});
      }
      stack_->setCurrentWidget(canvas_);
      canvas_->setPlaceholder(idlePlaceholder());
    }
  }
  updateInfo();
  updateActions();
}

void FramePanel::showObservation(size_t track_index, size_t point_index) {
  if (!mission_ || track_index >= mission_->tracks.size() ||
      point_index >= mission_->tracks[track_index].points.size()) {
    return;
  }
  pause();
  click_timer_.Restart();
  scrub_requests_.clear();  // a click ends scrubbing: its frame alone is awaited
  const int64_t frame = mission_->tracks[track_index].points[point_index].frame;
  // Another observation in the frame already on screen: only the mark moves.
  const bool on_screen = video_available_ && frame == displayed_frame_ && pending_ticket_ == 0;
  pending_from_click_ = video_available_ && !on_screen;
  if (pending_from_click_) requestFrame(frame);
  setObservation(track_index, point_index, true);
  if (on_screen) {
    canvas_->repaint();
    last_recall_ms_ = click_timer_.ElapsedMs();
    emit frameShown(frame, last_recall_ms_);
  }
}

void FramePanel::showFrame(int64_t frame_index) {
  if (!mission_ || !video_available_ || frame_index < 0) return;
  pause();
  click_timer_.Restart();
  // The selected track's observation in that frame, if it has one, is marked.
  if (current_) {
    const auto& points = mission_->tracks[current_->first].points;
    const auto it = std::lower_bound(
        points.begin(), points.end(), frame_index,
        [](const mission::TrackPoint& p, int64_t index) { return p.frame < index; });
    // Marked in the frame, without moving the map's cross: the time line and the place clicked
    // lead here, not the observation.
    if (it != points.end() && it->frame == frame_index) {
      setObservation(current_->first, static_cast<size_t>(it - points.begin()), false);
    }
  }
  if (frame_index == displayed_frame_ && pending_ticket_ == 0) {
    updateMark();
    updateInfo();
    return;
  }
  pending_from_click_ = true;
  requestFrame(frame_index);
  scrub_requests_.emplace_back(pending_ticket_, scrub_clock_.ElapsedMs());
  while (scrub_requests_.size() > 64) scrub_requests_.pop_front();
  updateInfo();
}

void FramePanel::clear() {
  pause();
  current_.reset();
  displayed_frame_ = -1;
  image_ = QImage();
  canvas_->setImage(QImage());
  pending_ticket_ = 0;
  pending_from_click_ = false;
  hint_timer_->stop();
  canvas_->setHint(QString());
  canvas_->setPlaceholder(idlePlaceholder());
  showError(QString());
  updateMark();
  updateOverlay();
  updateInfo();
  updateActions();
}

std::optional<std::pair<size_t, size_t>> FramePanel::currentObservation() const { return current_; }

int64_t FramePanel::displayedFrame() const { return displayed_frame_; }

const QImage& FramePanel::displayedImage() const { return image_; }

QPointF FramePanel::markImagePosition() const {
  const auto& mark = canvas_->mark();
  return mark ? *mark : QPointF(kNaN, kNaN);
}

bool FramePanel::markVisible() const { return canvas_->mark().has_value(); }

bool FramePanel::markInterpolated() const {
  return canvas_->mark().has_value() && canvas_->markInterpolated();
}

bool FramePanel::videoAvailable() const { return video_available_; }

QString FramePanel::videoPath() const { return video_path_; }

double FramePanel::lastRecallMs() const { return last_recall_ms_; }

double FramePanel::lastDecodeMs() const { return last_decode_ms_; }

bool FramePanel::isPlaying() const { return playing_; }

QString FramePanel::errorText() const { return error_label_->text(); }

bool FramePanel::decodingHintShown() const { return !canvas_->hint().isEmpty(); }

void FramePanel::previousObservation() { stepObservation(-1); }

void FramePanel::nextObservation() { stepObservation(1); }

void FramePanel::stepObservation(int steps) {
  if (!current_ || !mission_) return;
  const auto last = static_cast<int64_t>(mission_->tracks[current_->first].points.size()) - 1;
  const int64_t point =
      std::clamp<int64_t>(static_cast<int64_t>(current_->second) + steps, 0, last);
  if (point != static_cast<int64_t>(current_->second))
    showObservation(current_->first, static_cast<size_t>(point));
}

void FramePanel::togglePlay() {
  if (playing_) {
    pause();
  } else {
    play();
  }
}

void FramePanel::play() {
  if (playing_ || !video_available_) return;
  const bool recalling = pending_ticket_ != 0 && pending_from_click_;
  if (!recalling && (displayed_frame_ < 0 || displayed_frame_ + 1 >= frameCount())) return;
  playing_ = true;
  held_frame_ = -1;
  if (recalling) {
    play_anchor_frame_ = -1;  // start from the recalled frame when it arrives
  } else {
    play_anchor_frame_ = displayed_frame_;
    play_clock_.Restart();
    requestNextPlayFrame();
  }
  emit playingChanged(true);
  updateActions();
}

void FramePanel::pause() {
  if (!playing_) return;
  playing_ = false;
  play_timer_->stop();
  held_frame_ = -1;
  held_image_ = QImage();
  if (pending_ticket_ != 0 && !pending_from_click_) {
    pending_ticket_ = 0;  // the next playback frame: its answer is dropped
    hint_timer_->stop();
    canvas_->setHint(QString());
  }
  emit playingChanged(false);
  updateInfo();
  updateActions();
}

const mission::TrackPoint* FramePanel::currentPoint() const {
  if (!current_ || !mission_) return nullptr;
  return &mission_->tracks[current_->first].points[current_->second];
}

void FramePanel::setObservation(size_t track_index, size_t point_index, bool announce) {
  const std::pair<size_t, size_t> observation(track_index, point_index);
  const bool changed = current_ != observation;
  current_ = observation;
  if (changed) canvas_->observationChanged();  // zoomed in: follow the target again
  updateMark();
  updateInfo();
  updateActions();
  if (announce && changed) emit observationChanged(track_index, point_index);
}

void FramePanel::requestFrame(int64_t frame_index) {
  pending_ticket_ = ++next_ticket_;
  recall_->request(frame_index, pending_ticket_);
  if (!hint_timer_->isActive()) hint_timer_->start(kHintDelayMs);
  if (image_.isNull()) {
    // Nothing on screen yet: say what the wait is for (the first click may come while the video
    // is still being indexed, which takes seconds on a long video).
    canvas_->setPlaceholder(
        recall_->isWarm()
            ? tr("Decoding frame %1…").arg(frame_index)
            : tr("Preparing %1 for frame recall (indexing its frames, once per video)…")
                  .arg(QFileInfo(video_path_).fileName()));
  }
}

QString FramePanel::idlePlaceholder() const {
  return tr(
      "Click a moving-target track on the mosaic to see the video frame it was observed "
      "in.");
}

void FramePanel::onFrameReady(quint64 ticket, int64_t frame_index, const QImage& image,
                              double decode_ms) {
  if (ticket != pending_ticket_) {
    // Superseded. A frame asked for while scrubbing is still newer than the one on screen: shown,
    // so that a drag shows frames as fast as they decode rather than none until it stops.
    const auto asked = std::find_if(scrub_requests_.begin(), scrub_requests_.end(),
                                    [ticket](const auto& r) { return r.first == ticket; });
    if (asked == scrub_requests_.end() || ticket <= presented_ticket_ || playing_) return;
    presented_ticket_ = ticket;
    present(frame_index, image);
    emit frameShown(frame_index, scrub_clock_.ElapsedMs() - asked->second);
    return;
  }
  presented_ticket_ = ticket;
  pending_ticket_ = 0;
  hint_timer_->stop();
  canvas_->setHint(QString());
  showError(QString());
  last_decode_ms_ = decode_ms;
  if (playing_ && play_anchor_frame_ >= 0) {
    const double interval_ms = 1000.0 / frameRate();
    const double due_ms = static_cast<double>(frame_index - play_anchor_frame_) * interval_ms;
    const double wait_ms = due_ms - play_clock_.ElapsedMs();
    if (wait_ms > 1) {
      held_frame_ = frame_index;
      held_image_ = image;
      play_timer_->start(static_cast<int>(std::lround(wait_ms)));
      return;
    }
    if (wait_ms < -2 * interval_ms) {
      // Decoding fell behind: carry on from here at the frame rate instead of rushing to catch up.
      play_anchor_frame_ = frame_index;
      play_clock_.Restart();
    }
    present(frame_index, image);
    emit frameShown(frame_index, kNaN);
    requestNextPlayFrame();
    return;
  }
  present(frame_index, image);
  if (pending_from_click_) {
    pending_from_click_ = false;
    last_recall_ms_ = click_timer_.ElapsedMs();
    emit frameShown(frame_index, last_recall_ms_);
  } else {
    emit frameShown(frame_index, kNaN);
  }
  if (playing_) {  // play() was pressed while this recall was pending: start from it
    play_anchor_frame_ = frame_index;
    play_clock_.Restart();
    requestNextPlayFrame();
  }
}

void FramePanel::onFailed(quint64 ticket, const QString& message) {
  if (ticket != pending_ticket_) return;
  pending_ticket_ = 0;
  pending_from_click_ = false;
  hint_timer_->stop();
  canvas_->setHint(QString());
  pause();
  if (!video_available_) return;  // already explained on the missing-video page
  if (!QFileInfo(video_path_).isFile()) {
    video_available_ = false;
    showMissingVideo(tr("The video of this mission is not at %1 any more. Frame recall needs "
                        "the video.")
                         .arg(QDir::toNativeSeparators(video_path_)));
    updateActions();
    return;
  }
  if (image_.isNull()) canvas_->setPlaceholder(idlePlaceholder());
  showError(message);
}

void FramePanel::onVideoReady(const QString& path, qint64 frame_count, double fps) {
  if (path != video_path_) return;
  warm_path_ = path;
  warm_frame_count_ = frame_count;
  warm_fps_ = fps;
  frame_count_ = frame_count;
  if (fps > 0) fps_ = fps;
  updateActions();
}

void FramePanel::onVideoFailed(const QString& path, const QString& message) {
  if (path != video_path_ || !video_available_) return;
  video_available_ = false;
  pending_ticket_ = 0;
  pending_from_click_ = false;
  hint_timer_->stop();
  canvas_->setHint(QString());
  pause();
  showMissingVideo(tr("%1\nFrame recall needs the video of this mission.").arg(message));
  updateActions();
}

void FramePanel::present(int64_t frame_index, const QImage& image) {
  displayed_frame_ = frame_index;
  image_ = image;
  canvas_->setImage(image);
  if (playing_ && current_ && mission_) {
    // The mark follows the track: move to its observation in this frame, when it has one.
    const auto& points = mission_->tracks[current_->first].points;
    auto it = std::lower_bound(
        points.begin(), points.end(), frame_index,
        [](const mission::TrackPoint& point, int64_t frame) { return point.frame < frame; });
    if (it != points.end() && it->frame == frame_index) {
      setObservation(current_->first, static_cast<size_t>(it - points.begin()), true);
    }
  }
  updateMark();
  updateOverlay();
  updateInfo();
  updateActions();
  // Paint now rather than at the next event-loop pass, so "on screen" is measured honestly.
  if (canvas_->isVisible()) canvas_->repaint();
}

void FramePanel::showMissingVideo(const QString& message) {
  missing_label_->setText(message);
  stack_->setCurrentIndex(1);
  showError(QString());
}

void FramePanel::showError(const QString& message) {
  if (error_label_->text() == message) return;  // spares a relayout on every frame
  error_label_->setText(message);
  error_label_->setVisible(!message.isEmpty());
}

void FramePanel::setOverlayMaskVisible(bool visible) {
  if (overlay_visible_ == visible) return;
  overlay_visible_ = visible;
  updateOverlay();
}

void FramePanel::updateOverlay() {
  // The displayed frame's sky line (low oblique views), with the overlay mask.
  std::optional<mission::SkyLine> sky;
  if (overlay_visible_ && mission_ && displayed_frame_ >= 0 && !image_.isNull()) {
    if (const mission::FrameRecord* frame = mission::FrameRecordOf(*mission_, displayed_frame_)) {
      sky = frame->sky_line;
    }
  }
  if (sky.has_value() != drawn_sky_.has_value() ||
      (sky && (sky->y0 != drawn_sky_->y0 || sky->slope != drawn_sky_->slope))) {
    drawn_sky_ = sky;
    canvas_->setSkyLine(sky);
  }
  const mission::OverlayRecord* record =
      overlay_visible_ && mission_ && displayed_frame_ >= 0 && !image_.isNull()
          ? mission::OverlayAt(mission_->overlays, displayed_frame_)
          : nullptr;
  if (record == drawn_overlay_) return;  // playback within one mask redraws nothing
  drawn_overlay_ = record;
  if (record == nullptr) {
    canvas_->setOverlay(QImage(), 1);
    return;
  }
  // A faint tint: the frame beneath stays readable.
  QImage cells(record->cols, record->rows, QImage::Format_ARGB32_Premultiplied);
  cells.fill(Qt::transparent);
  const QRgb tint = qPremultiply(qRgba(0, 190, 255, 90));
  for (int y = 0; y < record->rows; ++y) {
    QRgb* line = reinterpret_cast<QRgb*>(cells.scanLine(y));
    const uint8_t* row = record->cells.data() + static_cast<size_t>(y) * record->cols;
    for (int x = 0; x < record->cols; ++x) {
      if (row[x] != 0) line[x] = tint;
    }
  }
  canvas_->setOverlay(cells, record->cell_px);
}

void FramePanel::updateMark() {
  const mission::TrackPoint* point = currentPoint();
  save_frame_button_->setEnabled(!image_.isNull());
  copy_chip_button_->setEnabled(false);
  if (point == nullptr || image_.isNull() || point->frame != displayed_frame_) {
    canvas_->setMark(std::nullopt, {});
    canvas_->setNorth(std::nullopt);
    return;
  }
  copy_chip_button_->setEnabled(true);
  canvas_->setMark(QPointF(point->image.x(), point->image.y()),
                   QRectF(QPointF(point->box_min.x(), point->box_min.y()),
                          QPointF(point->box_max.x(), point->box_max.y())),
                   point->interpolated);
  // North in the frame: the image direction of a step north on the map from the target.
  std::optional<double> north;
  const mission::FrameRecord* record = mission::FrameRecordOf(*mission_, displayed_frame_);
  if (mission_->map.geo_referenced && record != nullptr && record->map_from_frame) {
    const Eigen::Matrix3d& h = *record->map_from_frame;
    Eigen::Matrix3d frame_from_map;
    bool invertible = false;
    h.computeInverseWithCheck(frame_from_map, invertible);
    const Eigen::Vector3d at = h * point->image.homogeneous();
    if (invertible && std::abs(at.z()) > 1e-12) {
      const Eigen::Vector2d ground = at.hnormalized();
      const Eigen::Vector3d ahead = frame_from_map * (ground + Eigen::Vector2d(0, 1)).homogeneous();
      const Eigen::Vector2d step = ahead.hnormalized() - point->image;
      // Clockwise from the frame's up (image y grows down).
      if (ahead.z() * at.z() > 0 && step.allFinite() && step.norm() > 1e-9) {
        north = std::atan2(step.x(), -step.y());
      }
    }
  }
  canvas_->setNorth(north);
}

void FramePanel::updateInfo() {
  const mission::TrackPoint* point = currentPoint();
  if (point == nullptr) {
    for (QLabel* label : {track_value_, visit_value_, time_value_, frame_value_, utc_value_,
                          speed_value_, heading_value_, confidence_value_}) {
      label->setText(QStringLiteral("–"));
    }
    track_value_->setNote(QString());
    // A frame shown for its time (the time line, a place): its time, number and UTC.
    if (const mission::FrameRecord* record =
            mission_ && displayed_frame_ >= 0 ? mission::FrameRecordOf(*mission_, displayed_frame_)
                                              : nullptr) {
      time_value_->setText(tr("%1 s").arg(record->time_s, 0, 'f', 2));
      frame_value_->setText(QString::number(record->index));
      if (record->utc_us) {
        const QDateTime utc =
            QDateTime::fromMSecsSinceEpoch(*record->utc_us / 1000, QTimeZone::utc());
        utc_value_->setText(utc.toString(QStringLiteral("yyyy-MM-dd'T'HH:mm:ss.zzz'Z'")));
      }
    }
    return;
  }
  const mission::ActivityTrack& track = mission_->tracks[current_->first];
  track_value_->setText((point->interpolated ? tr("%1 (interpolated: observation %2 of %3)")
                                             : tr("%1 (observation %2 of %3)"))
                            .arg(track.id)
                            .arg(current_->second + 1)
                            .arg(track.points.size()));
  track_value_->setNote(
      point->interpolated
          ? tr("Not seen in this frame: placed between the observations before and "
               "after it, over the ground (a gap of at most a second in the track).")
          : QString());
  visit_value_->setText(QString::number(track.visit));
  if (track.speed_mps) {
    speed_value_->setText(tr("%1 m/s (%2 km/h)")
                              .arg(*track.speed_mps, 0, 'f', 1)
                              .arg(*track.speed_mps * 3.6, 0, 'f', 1));
  } else {
    speed_value_->setText(tr("%1 px/s").arg(track.speed, 0, 'f', 1));
  }
  // Unknown in missions written before Saker kept the evidence behind it.
  confidence_value_->setText(track.confidence ? QString::number(*track.confidence, 'f', 2)
                                              : tr("unknown"));
  const double heading = std::fmod(std::fmod(track.heading_deg, 360.0) + 360.0, 360.0);
  // A map in pixels has no north: its directions are those of its picture.
  const QString direction = mission_->map.geo_referenced
                                ? DirectionWord(heading, kCompassPoints)
                                : DirectionWord(heading, kPictureDirections);
  heading_value_->setText(tr("%1° %2").arg(std::lround(heading) % 360).arg(direction));
  // Beside the track's averages: its speed and heading at this observation (over a second).
  if (const std::optional<Motion> now =
          MotionAt(track, current_->second, mission_->map.geo_referenced)) {
    speed_value_->setText(tr("%1; now %2").arg(speed_value_->text()).arg(now->speed, 0, 'f', 1));
    heading_value_->setText(
        tr("%1; now %2°").arg(heading_value_->text()).arg(std::lround(now->heading_deg) % 360));
  }

  // Time and frame: of the observation, unless playback (or a pause after it) shows another frame.
  const bool recalling = pending_ticket_ != 0 && pending_from_click_;
  const int64_t frame =
      (video_available_ && !recalling && displayed_frame_ >= 0) ? displayed_frame_ : point->frame;
  const mission::FrameRecord* record = mission::FrameRecordOf(*mission_, frame);
  double time_s = point->time_s;
  if (frame != point->frame) {
    time_s = record != nullptr ? record->time_s
                               : static_cast<double>(frame) / std::max(frameRate(), 1e-9);
  }
  time_value_->setText(tr("%1 s").arg(time_s, 0, 'f', 2));
  frame_value_->setText(frame == point->frame ? QString::number(frame)
                                              : tr("%1 (track not observed)").arg(frame));
  if (record == nullptr) {
    // Processing has not stored the frames yet, or the video has more frames than the mission.
    utc_value_->setText(tr("unknown (the mission has no record of this frame)"));
  } else if (record->utc_us) {
    // ISO 8601 with the "Z" designator (Qt 6.4 writes UTC as "+00:00").
    const QDateTime utc = QDateTime::fromMSecsSinceEpoch(*record->utc_us / 1000, QTimeZone::utc());
    utc_value_->setText(utc.toString(QStringLiteral("yyyy-MM-dd'T'HH:mm:ss.zzz'Z'")));
  } else if (record->sensor || record->metadata_corners) {
    utc_value_->setText(tr("no time stamp in the frame's metadata"));
  } else {
    utc_value_->setText(tr("no metadata for this frame"));
  }
}

void FramePanel::updateActions() {
  const size_t points = current_ ? mission_->tracks[current_->first].points.size() : 0;
  previous_action_->setEnabled(current_ && current_->second > 0);
  next_action_->setEnabled(current_ && current_->second + 1 < points);
  const bool can_play =
      playing_ ||
      (video_available_ && ((displayed_frame_ >= 0 && displayed_frame_ + 1 < frameCount()) ||
                            (pending_ticket_ != 0 && pending_from_click_)));
  play_action_->setEnabled(can_play);
  play_action_->setIcon(
      style()->standardIcon(playing_ ? QStyle::SP_MediaPause : QStyle::SP_MediaPlay));
  play_action_->setText(playing_ ? tr("Pause") : tr("Play"));
  for (QAction* step : step_actions_) step->setEnabled(current_.has_value());
  previous_action_->setToolTip(tr("Previous observation of the track (%1, %2; %3: %4 back)")
                                   .arg(ShortcutText(step_actions_[0]))
                                   .arg(ShortcutText(previous_action_))
                                   .arg(ShortcutText(step_actions_[2]))
                                   .arg(kLongStep));
  next_action_->setToolTip(tr("Next observation of the track (%1, %2; %3: %4 on)")
                               .arg(ShortcutText(step_actions_[1]))
                               .arg(ShortcutText(next_action_))
                               .arg(ShortcutText(step_actions_[3]))
                               .arg(kLongStep));
  play_action_->setToolTip((playing_ ? tr("Pause (%1)") : tr("Play the video from this frame (%1)"))
                               .arg(ShortcutText(play_action_)));
}

void FramePanel::requestNextPlayFrame() {
  if (!playing_) return;
  const int64_t next = displayed_frame_ + 1;
  if (next >= frameCount()) {
    pause();  // the end of the video
    return;
  }
  requestFrame(next);
}

void FramePanel::presentHeldPlayFrame() {
  if (!playing_ || held_frame_ < 0) return;
  const int64_t frame = held_frame_;
  const QImage image = held_image_;
  held_frame_ = -1;
  held_image_ = QImage();
  present(frame, image);
  emit frameShown(frame, kNaN);
  requestNextPlayFrame();
}

int64_t FramePanel::frameCount() const {
  // Unknown before warm-up when the mission does not say: playback then stops at the first frame
  // the recall reports out of range.
  return frame_count_ > 0 ? frame_count_ : std::numeric_limits<int64_t>::max();
}

double FramePanel::frameRate() const { return fps_ > 0 ? fps_ : 25.0; }

QImage FramePanel::chipImage() const { return canvas_->chip(); }

void FramePanel::copyChip() {
  const QImage chip = chipImage();
  if (!chip.isNull()) QGuiApplication::clipboard()->setImage(chip);
}

bool FramePanel::saveFrame(const QString& path) {
  const QImage frame = canvas_->annotatedFrame();
  if (frame.isNull()) return false;
  if (!frame.save(path)) {
    showError(tr("Cannot save the frame to %1 (an unwritable folder, or a name without .png, "
                 ".jpg or .tif)")
                  .arg(path));
    return false;
  }
  return true;
}

double FramePanel::zoom() const { return canvas_->zoom(); }
void FramePanel::setZoom(double zoom) { canvas_->setZoom(zoom); }
std::optional<double> FramePanel::northInFrame() const { return canvas_->north(); }

}  // namespace saker::ui
