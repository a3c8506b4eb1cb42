#include "ui/mosaic_view.h"

#include "core/activity/confidence.h"
#include "core/activity/density.h"
#include "core/mosaic/adjustment.h"
#include "core/track/homography.h"
#include "core/track/image_geometry.h"
#include "core/track/picture.h"
#include "core/util/statistics.h"
#include "core/util/timer.h"
#include "ui/tile_cache.h"

#include <Eigen/LU>
#include <opencv2/imgproc.hpp>

#include <QContextMenuEvent>
#include <QFontMetricsF>
#include <QKeyEvent>
#include <QLinearGradient>
#include <QMouseEvent>
#include <QNativeGestureEvent>
#include <QPainter>
#include <QTimer>
#include <QWheelEvent>
#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

namespace saker::ui {

namespace {

constexpr double kWheelZoomBase = 1.0015;   // zoom factor per unit of angleDelta (120 a notch)
constexpr double kButtonZoom = 1.5;         // zoomIn / zoomOut / the +/- keys
constexpr double kFitMargin = 0.95;         // fit leaves a thin border round the content
constexpr double kMinZoomOfFit = 0.5;       // zooming out stops at half the fit
constexpr double kMaxScreenPxPerPixel = 8;  // zooming in stops at 8 screen px per source pixel
constexpr double kClickTolerancePx = 8;
constexpr double kDragThresholdPx = 4;  // a press that moves less is still a click
constexpr double kArrowSpacingPx = 60;
constexpr double kArrowLengthPx = 9;
constexpr double kArrowHalfWidthPx = 4;
constexpr double kDecimatePx = 1.5;  // track points closer than this on screen are skipped
// Drawing the tracks slower than this (ms) defers redrawing them during a pan or zoom.
constexpr double kSlowTracksMs = 25;
constexpr int kSettleMs = 150;        // the view still this long: redraw what was deferred
constexpr int kMaxCanvasSide = 4096;  // the preview canvas, pixels (64 MiB at most)
constexpr double kPanelMargin = 10;
constexpr double kPanelPadding = 8;

const QColor kBackground(38, 40, 44);
const QColor kPanel(16, 17, 20, 205);
const QColor kPanelText(245, 245, 245);
// Opaque: a translucent wide pen makes Qt stroke each polyline into a path first (3x slower).
const QColor kTrackOutline(12, 12, 14);

const QColor kOutlineColour(120, 200, 255, 170);
const QColor kEllipseColour(255, 196, 40, 220);

QColor ToQColor(const activity::Rgb& c) { return QColor(c.r, c.g, c.b); }

// The dark rounded panel under every overlay (legend, scale bar, north arrow, preview label).
void FillPanel(QPainter& painter, const QRectF& rect, double radius = 5) {
  painter.setPen(Qt::NoPen);
  painter.setBrush(kPanel);
  painter.drawRoundedRect(rect, radius, radius);
}

// h (x, y, 1); nullopt when the point maps to or beyond infinity.
std::optional<QPointF> Project(const Eigen::Matrix3d& h, double x, double y) {
  const Eigen::Vector3d p = h * Eigen::Vector3d(x, y, 1);
  if (!p.allFinite() || !(p.z() > 1e-12)) return std::nullopt;
  return QPointF(p.x() / p.z(), p.y() / p.z());
}

// QTransform maps row vectors (x' = m11 x + m21 y + m31), the transpose of Eigen's convention.
QTransform ToQTransform(const Eigen::Matrix3d& h) {
  return QTransform(h(0, 0), h(1, 0), h(2, 0), h(0, 1), h(1, 1), h(2, 1), h(0, 2), h(1, 2),
                    h(2, 2));
}

// Closed-interval overlap, so that a horizontal or vertical track (a zero-width box) still counts.
bool Overlaps(const QRectF& a, const QRectF& b) {
  return a.left() <= b.right() && b.left() <= a.right() && a.top() <= b.bottom() &&
         b.top() <= a.bottom();
}

double TrackSpeed(const mission::ActivityTrack& track, bool geo_referenced) {
  return geo_referenced ? track.speed_mps.value_or(track.speed) : track.speed;
}

// A round length (1, 2 or 5 x 10^n map units) whose bar is closest to `target_px` pixels.
double RoundLength(double ppu, double target_px) {
  const double raw = target_px / ppu;
  const double decade = std::pow(10.0, std::floor(std::log10(raw)));
  double best = decade;
  for (const double m : {1.0, 2.0, 5.0, 10.0}) {
    if (std::abs(std::log(m * decade / raw)) < std::abs(std::log(best / raw))) best = m * decade;
  }
  return best;
}

QString FormatNumber(double value) { return QString::number(value, 'g', 6); }

// Arrowhead with its tip at `tip`, pointing along the unit vector `dir`.
QPolygonF Arrowhead(const QPointF& tip, const QPointF& dir) {
  const QPointF normal(-dir.y(), dir.x());
  const QPointF base = tip - dir * kArrowLengthPx;
  return QPolygonF({tip, base + normal * kArrowHalfWidthPx, base - normal * kArrowHalfWidthPx});
}

// Arrowheads every kArrowSpacingPx of screen length along `line` (none in the last stretch, where
// the end's arrowhead is) and one at its end.
void AddArrowheads(const QPolygonF& line, std::vector<QPolygonF>* arrows) {
  double total = 0;
  for (qsizetype i = 1; i < line.size(); ++i) {
    total += std::hypot(line[i].x() - line[i - 1].x(), line[i].y() - line[i - 1].y());
  }
  double next = kArrowSpacingPx;
  double walked = 0;
  QPointF last_dir;
  for (qsizetype i = 1; i < line.size(); ++i) {
    const QPointF d = line[i] - line[i - 1];
    const double length = std::hypot(d.x(), d.y());
    if (length <= 1e-9) continue;
    const QPointF dir = d / length;
    last_dir = dir;
    while (next <= walked + length && next < total - kArrowSpacingPx / 3) {
      arrows->push_back(Arrowhead(line[i - 1] + dir * (next - walked), dir));
      next += kArrowSpacingPx;
    }
    walked += length;
  }
  if (!last_dir.isNull()) arrows->push_back(Arrowhead(line.back(), last_dir));
}

}  // namespace

MosaicView::MosaicView(QWidget* parent) : QWidget(parent), tiles_(new TileCache(this)) {
  qRegisterMetaType<Eigen::Vector2d>();
  qRegisterMetaType<std::optional<Eigen::Vector2d>>();
  setMouseTracking(true);
  setFocusPolicy(Qt::StrongFocus);
  setCursor(Qt::OpenHandCursor);
  setAttribute(Qt::WA_OpaquePaintEvent);
  // A new tile shows on the next paint; Qt merges the updates of a burst of tiles.
  connect(tiles_, &TileCache::tileReady, this, [this] { update(); });
  connect(tiles_, &TileCache::failed, this, &MosaicView::tilesFailed);
  settle_timer_ = new QTimer(this);
  settle_timer_->setSingleShot(true);
  settle_timer_->setInterval(kSettleMs);
  connect(settle_timer_, &QTimer::timeout, this, [this] {
    redraw_tracks_now_ = true;
    update();
  });
}

MosaicView::~MosaicView() = default;

QSize MosaicView::sizeHint() const { return {800, 600}; }
QSize MosaicView::minimumSizeHint() const { return {200, 150}; }

// ---------------------------------------------------------------------------------------------
// Mission and preview.

void MosaicView::setMission(std::shared_ptr<const mission::Mission> mission,
                            const QString& mission_path) {
  const bool reload =
      mission && mission_ && !mission_path.isEmpty() && mission_path == mission_path_;
  mission_ = std::move(mission);
  mission_path_ = mission_ ? mission_path : QString();
  if (mission_ && mission_->pyramid) {
    tiles_->setMission(mission_path_, mission_->pyramid);
  } else {
    tiles_->setMission(QString(), std::nullopt);
  }
  if (!reload) {
    marker_.reset();
    selected_track_.reset();
    current_frame_.reset();
    if (!measure_path_.empty()) setMeasurePath({});  // another map
  }
  rebuildMissionGeometry();
  rebuildColouring();
  rebuildVisibility();
  rebuildDensity();
  rebuildTimeMarkers();
  tracksChanged();
  frameChanged(/*refit=*/!reload);
  update();
}

void MosaicView::addPreviewKeyFrame(const frontend::KeyFramePreview& preview) {
  const cv::Mat& grey = preview.image.grey;
  if (grey.empty() || grey.type() != CV_8UC1) return;
  const double scale = preview.image.scale > 0 ? preview.image.scale : 1;
  // Grey pixel edges to full-resolution pixel centres, then into the preview.
  Eigen::Matrix3d frame_from_grey;
  frame_from_grey << scale, 0, -0.5, 0, scale, -0.5, 0, 0, 1;
  const Eigen::Matrix3d preview_from_grey = preview.preview_from_frame * frame_from_grey;
  QPolygonF corners;
  const std::array<std::pair<int, int>, 4> grey_corners = {
      {{0, 0}, {grey.cols, 0}, {grey.cols, grey.rows}, {0, grey.rows}}};
  for (const auto& [u, v] : grey_corners) {
    const std::optional<QPointF> p = Project(preview_from_grey, u, v);
    if (!p) return;  // placed beyond the horizon: a broken chain, nothing sensible to draw
    corners << *p;
  }
  const QRectF bounds = corners.boundingRect();
  // A frame blown up far beyond its own size is a diverged placement; it would squeeze the
  // canvas's resolution for nothing.
  const double side = std::max(grey.cols, grey.rows) * scale;
  if (!(bounds.width() < 20 * side && bounds.height() < 20 * side)) return;

  if (preview_canvas_.isNull() || !canvas_bounds_.contains(bounds)) {
    QRectF wanted = canvas_bounds_.isNull() ? bounds : canvas_bounds_.united(bounds);
    // Room to grow: the flight goes on, and regrowing resamples the whole canvas.
    wanted.adjust(-0.25 * wanted.width(), -0.25 * wanted.height(), 0.25 * wanted.width(),
                  0.25 * wanted.height());
    const double canvas_scale =
        std::min(1.0 / scale, kMaxCanvasSide / std::max(wanted.width(), wanted.height()));
    QImage canvas(std::max(1, static_cast<int>(std::ceil(wanted.width() * canvas_scale))),
                  std::max(1, static_cast<int>(std::ceil(wanted.height() * canvas_scale))),
                  QImage::Format_ARGB32_Premultiplied);
    canvas.fill(Qt::transparent);
    const QTransform canvas_from_preview(canvas_scale, 0, 0, canvas_scale,
                                         -wanted.left() * canvas_scale,
                                         -wanted.top() * canvas_scale);
    if (!preview_canvas_.isNull()) {
      QPainter painter(&canvas);
      painter.setRenderHint(QPainter::SmoothPixmapTransform);
      painter.setTransform(canvas_from_preview_.inverted() * canvas_from_preview);
      painter.drawImage(QPointF(0, 0), preview_canvas_);
    }
    preview_canvas_ = std::move(canvas);
    canvas_from_preview_ = canvas_from_preview;
    canvas_bounds_ = wanted;
  }
  {
    // Colour key frames drawn in colour (the RGB888 image reads BGR as RGB: swapped first).
    cv::Mat rgb;
    if (track::IsColour(preview.image)) {
      cv::cvtColor(track::KeyFrameBgr(preview.image), rgb, cv::COLOR_BGR2RGB);
    }
    const QImage image = rgb.empty()
                             ? QImage(grey.data, grey.cols, grey.rows,
                                      static_cast<qsizetype>(grey.step), QImage::Format_Grayscale8)
                             : QImage(rgb.data, rgb.cols, rgb.rows,
                                      static_cast<qsizetype>(rgb.step), QImage::Format_RGB888);
    QPainter painter(&preview_canvas_);
    painter.setRenderHint(QPainter::SmoothPixmapTransform);
    painter.setTransform(ToQTransform(preview_from_grey) * canvas_from_preview_);
    painter.drawImage(QPointF(0, 0), image);
  }
  preview_bounds_ = preview_bounds_.isNull() ? bounds : preview_bounds_.united(bounds);
  preview_units_per_pixel_ = 1;  // the preview's frame is the first video frame's pixels
  ++preview_count_;
  frameChanged(/*refit=*/false);
  update();
}

void MosaicView::clearPreview() {
  preview_canvas_ = QImage();
  canvas_from_preview_ = QTransform();
  canvas_bounds_ = QRectF();
  preview_bounds_ = QRectF();
  preview_count_ = 0;
  frameChanged(/*refit=*/false);
  update();
}

bool MosaicView::showingPreview() const { return frame_ == Frame::kPreview; }

MosaicView::Frame MosaicView::currentFrame() const {
  if (mission_ && mission_->progress.mosaic) return Frame::kMap;
  if (preview_count_ > 0) return Frame::kPreview;
  return mission_ ? Frame::kMap : Frame::kNone;
}

void MosaicView::frameChanged(bool refit) {
  const Frame frame = currentFrame();
  const bool changed = frame != frame_;
  frame_ = frame;
  // A path measured in the preview's pixels means nothing on the map.
  if (changed && !measure_path_.empty()) setMeasurePath({});
  y_up_ = frame_ == Frame::kMap && mission_->map.geo_referenced;
  if (frame_ == Frame::kPreview) {
    map_units_per_pixel_ = preview_units_per_pixel_;
  } else if (frame_ == Frame::kMap && mission_->pyramid) {
    map_units_per_pixel_ = std::abs(mission_->pyramid->step_x);
  } else if (frame_ == Frame::kMap && !mission_->key_frames.empty()) {
    // Without tiles, the key frames' own resolution (median) limits the zoom.
    std::vector<double> scales;
    const Eigen::Vector2d centre(mission_->source.width / 2.0, mission_->source.height / 2.0);
    for (const mission::KeyFrameRecord& k : mission_->key_frames) {
      if (!Project(k.map_from_frame, centre.x(), centre.y())) continue;
      const double det = track::TransferPointJacobian(k.map_from_frame, centre).determinant();
      if (std::isfinite(det) && det != 0) scales.push_back(std::sqrt(std::abs(det)));
    }
    if (!scales.empty()) {
      map_units_per_pixel_ = Median(std::move(scales));
    } else {
      map_units_per_pixel_ = 1;
    }
  } else {
    map_units_per_pixel_ = 1;
  }
  // Until the user zooms or pans, the view follows content that grows (key frames of the preview
  // arriving, a reload that brings the mosaic).
  if (changed || refit || (auto_fit_ && contentBounds() != fitted_bounds_)) {
    fitToWindow();
  } else {
    setView(centre_, ppu_);
  }
}

void MosaicView::rebuildMissionGeometry() {
  track_shapes_.clear();
  key_frame_outlines_.clear();
  uncertainty_ellipses_.clear();
  if (!mission_) return;

  track_shapes_.reserve(mission_->tracks.size());
  for (const mission::ActivityTrack& track : mission_->tracks) {
    TrackShape shape;
    shape.points.reserve(track.points.size());
    double x0 = std::numeric_limits<double>::infinity(), y0 = x0, x1 = -x0, y1 = -x0;
    for (const mission::TrackPoint& p : track.points) {
      if (!p.map.allFinite()) continue;
      shape.points.emplace_back(p.map.x(), p.map.y());
      x0 = std::min(x0, p.map.x()), x1 = std::max(x1, p.map.x());
      y0 = std::min(y0, p.map.y()), y1 = std::max(y1, p.map.y());
    }
    if (!shape.points.empty()) shape.bounds = QRectF(QPointF(x0, y0), QPointF(x1, y1));
    track_shapes_.push_back(std::move(shape));
  }

  const double w = mission_->source.width, h = mission_->source.height;
  for (const mission::KeyFrameRecord& k : mission_->key_frames) {
    std::array<QPointF, 4> outline;
    bool placed = true;
    const std::array<Eigen::Vector2d, 4> corners = {Eigen::Vector2d(0, 0), Eigen::Vector2d(w, 0),
                                                    Eigen::Vector2d(w, h), Eigen::Vector2d(0, h)};
    for (size_t i = 0; i < 4 && placed; ++i) {
      const std::optional<QPointF> p = Project(k.map_from_frame, corners[i].x(), corners[i].y());
      if (p) outline[i] = *p;
      placed = p.has_value();
    }
    if (!placed) continue;
    key_frame_outlines_.push_back(outline);
    if (!k.node || k.covariance.isZero() || !k.covariance.allFinite()) continue;
    for (size_t i = 0; i < 4; ++i) {
      const Eigen::Matrix2d covariance =
          track::TransferCovariance(k.map_from_frame, k.covariance, corners[i]);
      if (!covariance.allFinite()) continue;
      const track::Ellipse ellipse = track::ConfidenceEllipse(
          Eigen::Vector2d(outline[i].x(), outline[i].y()), covariance, 0.95);
      QPolygonF polygon;
      for (const Eigen::Vector2d& p : track::EllipsePolygon(ellipse, 36)) {
        polygon << QPointF(p.x(), p.y());
      }
      polygon << polygon.front();
      uncertainty_ellipses_.push_back(std::move(polygon));
    }
  }
}

void MosaicView::rebuildColouring() {
  colouring_.reset();
  track_colours_.clear();
  if (!mission_ || mission_->tracks.empty()) return;
  colouring_.emplace(colour_mode_, mission_->tracks, mission_->map.geo_referenced);
  track_colours_.reserve(mission_->tracks.size());
  for (const mission::ActivityTrack& track : mission_->tracks) {
    track_colours_.push_back(ToQColor(colouring_->ColourOf(track)));
  }
}

void MosaicView::rebuildVisibility() {
  track_visible_.assign(mission_ ? mission_->tracks.size() : 0, true);
  if (!mission_) return;
  const bool geo = mission_->map.geo_referenced;
  for (size_t i = 0; i < mission_->tracks.size(); ++i) {
    const mission::ActivityTrack& t = mission_->tracks[i];
    const double speed = TrackSpeed(t, geo);
    track_visible_[i] = !(filter_.start_s && t.end_s < *filter_.start_s) &&
                        !(filter_.end_s && t.start_s > *filter_.end_s) &&
                        !(filter_.min_speed && speed < *filter_.min_speed) &&
                        !(filter_.max_speed && speed > *filter_.max_speed) &&
                        activity::PassesConfidence(t, filter_.min_confidence) &&
                        filter_.hidden_ids.count(t.id) == 0;
  }
}

// ---------------------------------------------------------------------------------------------
// Colours and filter.

void MosaicView::setColourMode(activity::ColourMode mode) {
  if (mode == colour_mode_) return;
  colour_mode_ = mode;
  rebuildColouring();
  rebuildDensity();
  tracksChanged();
}

const activity::Legend& MosaicView::legend() const {
  static const activity::Legend kNoLegend;
  if (colour_mode_ == activity::ColourMode::kDensity && colouring_) return density_legend_;
  return colouring_ ? colouring_->legend() : kNoLegend;
}

void MosaicView::rebuildDensity() {
  density_image_ = QImage();
  density_legend_ = activity::Legend();
  if (colour_mode_ != activity::ColourMode::kDensity || !mission_) return;
  std::vector<const mission::ActivityTrack*> shown;
  for (size_t i = 0; i < mission_->tracks.size(); ++i) {
    if (isTrackVisible(i)) shown.push_back(&mission_->tracks[i]);
  }
  const activity::DensityGrid grid =
      activity::CountObservations(shown, mission_->map.geo_referenced);
  density_legend_ = activity::DensityLegend(grid, mission_->map.geo_referenced);
  if (grid.cols == 0) return;
  QImage image(grid.cols, grid.rows, QImage::Format_ARGB32_Premultiplied);
  for (int r = 0; r < grid.rows; ++r) {
    auto* line = reinterpret_cast<QRgb*>(image.scanLine(r));
    for (int c = 0; c < grid.cols; ++c) {
      const double p = activity::DensityPosition(grid.At(c, r), grid.max);
      const activity::Rgb rgb = activity::DensityRamp(p);
      line[c] = qPremultiply(qRgba(rgb.r, rgb.g, rgb.b, activity::DensityAlpha(p)));
    }
  }
  density_image_ = std::move(image);
  // Image pixel (c, r) covers map x in [origin.x + c cell, + cell), y likewise.
  map_from_density_ = QTransform(grid.cell, 0, 0, grid.cell, grid.origin.x(), grid.origin.y());
}

void MosaicView::paintDensity(QPainter& painter) {
  if (density_image_.isNull() || !show_tracks_) return;
  painter.save();
  painter.setRenderHint(QPainter::SmoothPixmapTransform);
  painter.setTransform(map_from_density_ * widgetFromMapTransform());
  painter.drawImage(QPointF(0, 0), density_image_);
  painter.restore();
}

std::optional<activity::Rgb> MosaicView::trackColour(size_t track_index) const {
  if (track_index >= track_colours_.size() || !isTrackVisible(track_index)) return std::nullopt;
  const QColor& c = track_colours_[track_index];
  return activity::Rgb{static_cast<uint8_t>(c.red()), static_cast<uint8_t>(c.green()),
                       static_cast<uint8_t>(c.blue())};
}

void MosaicView::setTrackFilter(const TrackFilter& filter) {
  filter_ = filter;
  rebuildVisibility();
  rebuildDensity();
  rebuildTimeMarkers();
  tracksChanged();
}

bool MosaicView::isTrackVisible(size_t track_index) const {
  return track_index < track_visible_.size() && track_visible_[track_index];
}

void MosaicView::setShowTracks(bool show) {
  show_tracks_ = show;
  tracksChanged();
}

void MosaicView::tracksChanged() {
  ++tracks_version_;
  update();
}

void MosaicView::setShowKeyFrameOutlines(bool show) {
  show_outlines_ = show;
  update();
}

void MosaicView::setShowUncertainty(bool show) {
  show_uncertainty_ = show;
  update();
}

void MosaicView::setMarker(std::optional<Eigen::Vector2d> map_point) {
  marker_ = map_point;
  update();
}

// ---------------------------------------------------------------------------------------------
// View geometry.

QRectF MosaicView::contentBounds() const {
  switch (frame_) {
    case Frame::kNone:
      return {};
    case Frame::kPreview:
      return preview_bounds_;
    case Frame::kMap:
      break;
  }
  if (const auto& p = mission_->pyramid; p && p->width > 0 && p->height > 0) {
    const Eigen::Vector2d a = p->map_origin + Eigen::Vector2d(-0.5 * p->step_x, -0.5 * p->step_y);
    const Eigen::Vector2d b = p->map_origin + Eigen::Vector2d((p->width - 0.5) * p->step_x,
                                                              (p->height - 0.5) * p->step_y);
    return QRectF(QPointF(a.x(), a.y()), QPointF(b.x(), b.y())).normalized();
  }
  QRectF bounds;
  const auto unite = [&bounds](const QRectF& r) {
    bounds = bounds.isNull() ? r : bounds.united(r);
  };
  for (const auto& outline : key_frame_outlines_) {
    unite(QPolygonF(QList<QPointF>(outline.begin(), outline.end())).boundingRect());
  }
  for (const TrackShape& shape : track_shapes_) {
    if (!shape.points.empty()) unite(shape.bounds);
  }
  return bounds;
}

double MosaicView::fitPixelsPerMapUnit() const {
  const QRectF bounds = contentBounds();
  const double w = std::max(1, width()), h = std::max(1, height());
  double ppu = std::numeric_limits<double>::infinity();
  if (bounds.width() > 0) ppu = std::min(ppu, w / bounds.width());
  if (bounds.height() > 0) ppu = std::min(ppu, h / bounds.height());
  if (!std::isfinite(ppu)) return 1 / map_units_per_pixel_;
  return ppu * kFitMargin;
}

double MosaicView::maxPixelsPerMapUnit() const {
  return std::max(kMaxScreenPxPerPixel / map_units_per_pixel_, fitPixelsPerMapUnit());
}

double MosaicView::minPixelsPerMapUnit() const {
  return std::min(kMinZoomOfFit * fitPixelsPerMapUnit(), maxPixelsPerMapUnit());
}

void MosaicView::setView(const Eigen::Vector2d& centre, double ppu) {
  ppu = std::clamp(ppu, minPixelsPerMapUnit(), maxPixelsPerMapUnit());
  const bool changed = centre != centre_ || ppu != ppu_;
  centre_ = centre;
  ppu_ = ppu;
  if (changed) emit viewChanged();
  update();
}

void MosaicView::fitToWindow() {
  auto_fit_ = true;
  const QRectF bounds = contentBounds();
  fitted_bounds_ = bounds;
  const Eigen::Vector2d centre = bounds.isNull()
                                     ? Eigen::Vector2d(0, 0)
                                     : Eigen::Vector2d(bounds.center().x(), bounds.center().y());
  setView(centre, fitPixelsPerMapUnit());
}

void MosaicView::zoomIn() { zoomAt(kButtonZoom, QPointF(width() / 2.0, height() / 2.0)); }
void MosaicView::zoomOut() { zoomAt(1 / kButtonZoom, QPointF(width() / 2.0, height() / 2.0)); }

void MosaicView::zoomAt(double factor, const QPointF& widget_anchor) {
  if (!(factor > 0) || !std::isfinite(factor)) return;
  auto_fit_ = false;
  const Eigen::Vector2d anchor = mapFromWidget(widget_anchor);
  const double ppu = std::clamp(ppu_ * factor, minPixelsPerMapUnit(), maxPixelsPerMapUnit());
  const double sy = y_up_ ? -1 : 1;
  const Eigen::Vector2d centre(anchor.x() - (widget_anchor.x() - width() / 2.0) / ppu,
                               anchor.y() - sy * (widget_anchor.y() - height() / 2.0) / ppu);
  setView(centre, ppu);
}

void MosaicView::panBy(const QPointF& widget_delta) {
  auto_fit_ = false;
  const double sy = y_up_ ? -1 : 1;
  Eigen::Vector2d centre(centre_.x() - widget_delta.x() / ppu_,
                         centre_.y() - sy * widget_delta.y() / ppu_);
  // The content's edge may come to the middle of the window, no further: the map is never lost.
  const QRectF bounds = contentBounds();
  if (!bounds.isNull()) {
    centre.x() = std::clamp(centre.x(), bounds.left(), bounds.right());
    centre.y() = std::clamp(centre.y(), bounds.top(), bounds.bottom());
  }
  setView(centre, ppu_);
}

QPointF MosaicView::widgetFromMap(const Eigen::Vector2d& map) const {
  const double sy = y_up_ ? -1 : 1;
  return {width() / 2.0 + (map.x() - centre_.x()) * ppu_,
          height() / 2.0 + sy * (map.y() - centre_.y()) * ppu_};
}

Eigen::Vector2d MosaicView::mapFromWidget(const QPointF& widget) const {
  const double sy = y_up_ ? -1 : 1;
  return {centre_.x() + (widget.x() - width() / 2.0) / ppu_,
          centre_.y() + sy * (widget.y() - height() / 2.0) / ppu_};
}

QTransform MosaicView::widgetFromMapTransform() const {
  const double sy = y_up_ ? -1 : 1;
  return QTransform(ppu_, 0, 0, sy * ppu_, width() / 2.0 - centre_.x() * ppu_,
                    height() / 2.0 - sy * centre_.y() * ppu_);
}

QRectF MosaicView::visibleMapRect() const {
  const Eigen::Vector2d a = mapFromWidget(QPointF(0, 0));
  const Eigen::Vector2d b = mapFromWidget(QPointF(width(), height()));
  return QRectF(QPointF(a.x(), a.y()), QPointF(b.x(), b.y())).normalized();
}

// ---------------------------------------------------------------------------------------------
// Tiles.

int MosaicView::tileLevel() const {
  if (frame_ != Frame::kMap || !mission_->pyramid) return 0;
  const mission::PyramidInfo& p = *mission_->pyramid;
  // Device pixels per level-0 pixel. The finest level whose pixels are no larger than a device
  // pixel: a coarser one would be magnified (blurred) while a finer one is there.
  const double px = ppu_ * std::abs(p.step_x) * devicePixelRatioF();
  int level = 0;
  while (level + 1 < p.levels &&
         px * static_cast<double>(static_cast<int64_t>(1) << (level + 1)) <= 1.0 + 1e-9)
    ++level;
  return level;
}

MosaicView::TileRange MosaicView::visibleTiles(int level) const {
  TileRange range;
  range.level = level;
  if (frame_ != Frame::kMap || !mission_->pyramid) return range;
  const mission::PyramidInfo& p = *mission_->pyramid;
  const double span =
      static_cast<double>(static_cast<int64_t>(p.tile_size) << level);  // level-0 pixels per tile
  const int columns = static_cast<int>((p.width + span - 1) / span);
  const int rows = static_cast<int>((p.height + span - 1) / span);
  const QRectF r = visibleMapRect();
  // Level-0 pixel-centre coordinates of the visible rectangle; tiles start at -0.5.
  const double ua = (r.left() - p.map_origin.x()) / p.step_x + 0.5;
  const double ub = (r.right() - p.map_origin.x()) / p.step_x + 0.5;
  const double va = (r.top() - p.map_origin.y()) / p.step_y + 0.5;
  const double vb = (r.bottom() - p.map_origin.y()) / p.step_y + 0.5;
  const auto index = [span](double u, int count) {
    return static_cast<int>(std::clamp(std::floor(u / span), -1.0, static_cast<double>(count)));
  };
  range.x0 = std::max(0, index(std::min(ua, ub), columns));
  range.x1 = std::min(columns - 1, index(std::max(ua, ub), columns));
  range.y0 = std::max(0, index(std::min(va, vb), rows));
  range.y1 = std::min(rows - 1, index(std::max(va, vb), rows));
  return range;
}

QRectF MosaicView::tileRect(int level, int x, int y) const {
  const mission::PyramidInfo& p = *mission_->pyramid;
  const double f = static_cast<double>(static_cast<int64_t>(1) << level);
  const double t = p.tile_size;
  // A level-l pixel averages 2^l x 2^l level-0 pixels: its edges lie half a level-0 pixel
  // before their centres.
  const double u0 = x * t * f - 0.5, u1 = (x + 1) * t * f - 0.5;
  const double v0 = y * t * f - 0.5, v1 = (y + 1) * t * f - 0.5;
  const QPointF a = widgetFromMap(p.map_origin + Eigen::Vector2d(u0 * p.step_x, v0 * p.step_y));
  const QPointF b = widgetFromMap(p.map_origin + Eigen::Vector2d(u1 * p.step_x, v1 * p.step_y));
  return QRectF(a, b).normalized();
}

void MosaicView::requestTiles() {
  if (frame_ != Frame::kMap || !mission_->pyramid) return;
  const mission::PyramidInfo& p = *mission_->pyramid;
  QList<TileKey> wanted;
  // The coarsest level first: a tile or two that can stand in for anything while the rest load.
  const TileRange top = visibleTiles(p.levels - 1);
  for (int y = top.y0; y <= top.y1; ++y) {
    for (int x = top.x0; x <= top.x1; ++x) wanted.push_back({top.level, x, y});
  }
  // Then the visible tiles of the level drawn, from the centre out.
  const TileRange range = visibleTiles(tileLevel());
  const QPointF centre(width() / 2.0, height() / 2.0);
  std::vector<std::pair<double, TileKey>> visible;
  for (int y = range.y0; y <= range.y1; ++y) {
    for (int x = range.x0; x <= range.x1; ++x) {
      const QPointF d = tileRect(range.level, x, y).center() - centre;
      visible.push_back({QPointF::dotProduct(d, d), TileKey{range.level, x, y}});
    }
  }
  std::sort(visible.begin(), visible.end(),
            [](const auto& a, const auto& b) { return a.first < b.first; });
  for (const auto& [distance, key] : visible) wanted.push_back(key);
  // Then a ring round the view, so that a short pan finds its tiles ready.
  for (int y = range.y0 - 1; y <= range.y1 + 1; ++y) {
    for (int x = range.x0 - 1; x <= range.x1 + 1; ++x) {
      if (y < range.y0 || y > range.y1 || x < range.x0 || x > range.x1) {
        wanted.push_back({range.level, x, y});  // outside the pyramid: the cache skips it
      }
    }
  }
  tiles_->requestVisible(wanted);
}

bool MosaicView::tilesComplete() const {
  if (frame_ != Frame::kMap || !mission_->pyramid) return true;
  const TileRange range = visibleTiles(tileLevel());
  for (int y = range.y0; y <= range.y1; ++y) {
    for (int x = range.x0; x <= range.x1; ++x) {
      const TileCache::State state = tiles_->state(range.level, x, y);
      if (state != TileCache::State::kLoaded && state != TileCache::State::kEmpty) return false;
    }
  }
  return true;
}

// ---------------------------------------------------------------------------------------------
// Painting.

void MosaicView::paintEvent(QPaintEvent*) {
  QPainter painter(this);
  painter.fillRect(rect(), kBackground);
  switch (frame_) {
    case Frame::kNone:
      paintHint(painter);
      return;
    case Frame::kPreview:
      paintPreview(painter);
      break;
    case Frame::kMap:
      requestTiles();
      paintTiles(painter);
      paintKeyFrames(painter);
      paintDensity(painter);
      paintTracks(painter);
      break;
  }
  if (frame_ == Frame::kMap) {
    paintSelection(painter);
    paintTimeLine(painter);
    paintBookmarks(painter);
  }
  paintMarker(painter);
  paintMeasure(painter);
  paintLegend(painter);
  paintScaleBar(painter);
  paintPreviewLabel(painter);
}

void MosaicView::paintTiles(QPainter& painter) {
  if (!mission_->pyramid) return;
  const mission::PyramidInfo& p = *mission_->pyramid;
  const TileRange range = visibleTiles(tileLevel());
  const int level = range.level;
  painter.save();
  painter.setRenderHint(QPainter::SmoothPixmapTransform);
  for (int y = range.y0; y <= range.y1; ++y) {
    for (int x = range.x0; x <= range.x1; ++x) {
      const QRectF target = tileRect(level, x, y);
      const QImage image = tiles_->tile(level, x, y);
      if (!image.isNull()) {
        painter.drawImage(target, image);
        continue;
      }
      if (tiles_->state(level, x, y) == TileCache::State::kEmpty) continue;
      // Not loaded yet: the part of the nearest loaded coarser tile stands in for it...
      for (int coarse = level + 1; coarse < p.levels; ++coarse) {
        const int d = coarse - level;
        const int cx = x >> d, cy = y >> d;
        const QImage parent = tiles_->tile(coarse, cx, cy);
        if (!parent.isNull()) {
          const double sub = static_cast<double>(parent.width()) / static_cast<double>(1 << d);
          const QRectF source((x - (cx << d)) * sub, (y - (cy << d)) * sub, sub, sub);
          painter.drawImage(target, parent, source);
          break;
        }
        if (tiles_->state(coarse, cx, cy) == TileCache::State::kEmpty) break;
      }
      // ...with the finer tiles still in the cache after zooming out drawn over it.
      if (level > 0) {
        for (int dy = 0; dy < 2; ++dy) {
          for (int dx = 0; dx < 2; ++dx) {
            const QImage child = tiles_->tile(level - 1, 2 * x + dx, 2 * y + dy);
            if (!child.isNull()) {
              painter.drawImage(tileRect(level - 1, 2 * x + dx, 2 * y + dy), child);
            }
          }
        }
      }
    }
  }
  painter.restore();
}

void MosaicView::paintPreview(QPainter& painter) {
  if (preview_canvas_.isNull()) return;
  painter.save();
  painter.setRenderHint(QPainter::SmoothPixmapTransform);
  painter.setTransform(canvas_from_preview_.inverted() * widgetFromMapTransform());
  painter.drawImage(QPointF(0, 0), preview_canvas_);
  painter.restore();
}

void MosaicView::paintKeyFrames(QPainter& painter) {
  if (!show_outlines_ && !show_uncertainty_) return;
  const QTransform transform = widgetFromMapTransform();
  const QRectF screen = QRectF(rect()).adjusted(-2, -2, 2, 2);
  painter.save();
  painter.setRenderHint(QPainter::Antialiasing);
  painter.setBrush(Qt::NoBrush);
  if (show_outlines_) {
    painter.setPen(QPen(kOutlineColour, 1));
    for (const auto& outline : key_frame_outlines_) {
      QPolygonF polygon;
      for (const QPointF& p : outline) polygon << transform.map(p);
      if (Overlaps(polygon.boundingRect(), screen)) painter.drawPolygon(polygon);
    }
  }
  if (show_uncertainty_) {
    painter.setPen(QPen(kEllipseColour, 1.5));
    for (const QPolygonF& ellipse : uncertainty_ellipses_) {
      const QPolygonF polygon = transform.map(ellipse);
      if (Overlaps(polygon.boundingRect(), screen)) painter.drawPolyline(polygon);
    }
  }
  painter.restore();
}

void MosaicView::paintTracks(QPainter& painter) {
  if (!show_tracks_ || track_shapes_.empty() || track_colours_.size() != track_shapes_.size()) {
    return;
  }
  const QTransform view = widgetFromMapTransform();
  const double dpr = devicePixelRatioF();
  const QSize device_size(static_cast<int>(std::ceil(width() * dpr)),
                          static_cast<int>(std::ceil(height() * dpr)));
  const bool current = !track_layer_.isNull() && track_layer_version_ == tracks_version_ &&
                       track_layer_.size() == device_size;
  if (current && track_layer_view_ == view) {
    redraw_tracks_now_ = false;
    painter.drawImage(QPointF(0, 0), track_layer_);
    return;
  }
  if (current && track_draw_ms_ > kSlowTracksMs && !redraw_tracks_now_) {
    // Slow to draw and the user is moving the map: the last drawing follows the map until the
    // view settles.
    painter.save();
    painter.setRenderHint(QPainter::SmoothPixmapTransform);
    painter.setTransform(track_layer_view_.inverted() * view, /*combine=*/true);
    painter.drawImage(QPointF(0, 0), track_layer_);
    painter.restore();
    settle_timer_->start();
    return;
  }
  redraw_tracks_now_ = false;
  const Stopwatch timer;
  if (track_layer_.size() != device_size) {
    track_layer_ = QImage(device_size, QImage::Format_ARGB32_Premultiplied);
  }
  track_layer_.setDevicePixelRatio(dpr);
  track_layer_.fill(Qt::transparent);
  {
    QPainter layer(&track_layer_);
    drawTracks(layer);
  }
  track_layer_view_ = view;
  track_layer_version_ = tracks_version_;
  track_draw_ms_ = timer.ElapsedMs();
  painter.drawImage(QPointF(0, 0), track_layer_);
}

void MosaicView::drawTracks(QPainter& painter) const {
  // The density mode shows the heat map (paintDensity), not the tracks.
  if (colour_mode_ == activity::ColourMode::kDensity) return;
  const double margin = (kArrowLengthPx + 4) / ppu_;
  const QRectF view = visibleMapRect().adjusted(-margin, -margin, margin, margin);
  const QTransform transform = widgetFromMapTransform();

  // Screen polylines of the visible tracks, with points closer than kDecimatePx merged: a long
  // track seen from afar costs a few segments, not thousands.
  std::vector<std::pair<size_t, QPolygonF>> lines;
  for (size_t i = 0; i < track_shapes_.size(); ++i) {
    const TrackShape& shape = track_shapes_[i];
    if (!track_visible_[i] || shape.points.empty() || !Overlaps(shape.bounds, view)) continue;
    QPolygonF line;
    line.reserve(static_cast<qsizetype>(shape.points.size()));
    for (const QPointF& point : shape.points) {
      const QPointF p = transform.map(point);
      if (!line.isEmpty() && (std::abs(p.x() - line.back().x()) < kDecimatePx &&
                              std::abs(p.y() - line.back().y()) < kDecimatePx)) {
        continue;
      }
      line << p;
    }
    // Always end where the track ends (the arrowhead points there).
    const QPointF end = transform.map(shape.points.back());
    if (line.back() != end) line << end;
    lines.emplace_back(i, std::move(line));
  }

  painter.save();
  painter.setRenderHint(QPainter::Antialiasing);
  painter.setBrush(Qt::NoBrush);
  // A dark outline under every track first, so that crossing tracks keep their colours and each
  // stands out on bright or dark imagery. Square caps close the outline round the colour's flat
  // ends; bevel joins and flat caps rasterise faster than round ones.
  QPen outline(kTrackOutline, 4, Qt::SolidLine, Qt::SquareCap, Qt::BevelJoin);
  painter.setPen(outline);
  for (const auto& [i, line] : lines) {
    if (line.size() == 1) {
      painter.drawPoint(line.front());
    } else {
      painter.drawPolyline(line);
    }
  }
  QPen pen(Qt::white, 2, Qt::SolidLine, Qt::FlatCap, Qt::BevelJoin);
  for (const auto& [i, line] : lines) {
    pen.setColor(track_colours_[i]);
    painter.setPen(pen);
    if (line.size() == 1) {
      painter.drawPoint(line.front());
    } else {
      painter.drawPolyline(line);
    }
  }
  // Arrowheads last, over the lines.
  painter.setPen(QPen(kTrackOutline, 1));
  std::vector<QPolygonF> arrows;
  for (const auto& [i, line] : lines) {
    arrows.clear();
    AddArrowheads(line, &arrows);
    painter.setBrush(track_colours_[i]);
    for (const QPolygonF& arrow : arrows) painter.drawPolygon(arrow);
  }
  painter.restore();
}

void MosaicView::setSelectedTrack(std::optional<size_t> track_index) {
  if (track_index && (!mission_ || *track_index >= mission_->tracks.size())) track_index.reset();
  if (selected_track_ == track_index) return;
  selected_track_ = track_index;
  update();
}

void MosaicView::showTrack(size_t track_index) {
  if (track_index >= track_shapes_.size() || track_shapes_[track_index].points.empty()) return;
  const QRectF bounds = track_shapes_[track_index].bounds;
  const double side = std::max({bounds.width(), bounds.height(), 1e-9});
  // Half the view's smaller side for the track, within the zoom limits.
  const double ppu = 0.5 * std::min(width(), height()) / side;
  auto_fit_ = false;
  setView(Eigen::Vector2d(bounds.center().x(), bounds.center().y()),
          std::clamp(ppu, minPixelsPerMapUnit(), maxPixelsPerMapUnit()));
}

void MosaicView::setCurrentFrame(std::optional<int64_t> frame_index) {
  current_frame_ = frame_index;
  rebuildTimeMarkers();
  update();
}

void MosaicView::rebuildTimeMarkers() {
  footprint_.reset();
  time_markers_.clear();
  time_trails_.clear();
  if (!current_frame_ || !mission_) return;
  const mission::FrameRecord* it = mission::FrameRecordOf(*mission_, *current_frame_);
  if (it == nullptr) return;
  const double t = it->time_s;
  if (it->map_from_frame) {
    std::array<Eigen::Vector2d, 4> corners;
    bool ok = true;
    const auto image = track::ImageCorners(mission_->source.width, mission_->source.height);
    for (size_t k = 0; k < 4; ++k) {
      const Eigen::Vector3d p = *it->map_from_frame * image[k].homogeneous();
      ok = ok && p.z() > 1e-12 && p.allFinite();
      if (ok) corners[k] = p.hnormalized();
    }
    if (ok) footprint_ = corners;
  }
  constexpr double kTrailS = 3;
  for (size_t i = 0; i < mission_->tracks.size(); ++i) {
    const mission::ActivityTrack& track = mission_->tracks[i];
    if (!isTrackVisible(i) || track.points.empty() || t < track.start_s || t > track.end_s) {
      continue;
    }
    const auto& points = track.points;
    // The last observation at or before the time (the track may skip a frame or two).
    const auto at =
        std::upper_bound(points.begin(), points.end(), t,
                         [](double v, const mission::TrackPoint& p) { return v < p.time_s; });
    if (at == points.begin()) continue;
    const auto last = std::prev(at);
    if (t - last->time_s > 1.0) continue;  // not seen around this time
    time_markers_.emplace_back(i, last->map);
    std::vector<QPointF> trail;
    for (auto p = points.begin(); p != at; ++p) {
      if (t - p->time_s <= kTrailS) trail.emplace_back(p->map.x(), p->map.y());
    }
    time_trails_.emplace_back(i, std::move(trail));
  }
}

void MosaicView::paintTimeLine(QPainter& painter) {
  if (!current_frame_) return;
  painter.save();
  painter.setRenderHint(QPainter::Antialiasing);
  if (footprint_) {
    QPolygonF outline;
    for (const Eigen::Vector2d& c : *footprint_) outline << widgetFromMap(c);
    painter.setBrush(QColor(255, 255, 255, 28));
    painter.setPen(QPen(QColor(255, 255, 255, 220), 1.5, Qt::DashLine));
    painter.drawPolygon(outline);
  }
  const QTransform transform = widgetFromMapTransform();
  for (const auto& [i, trail] : time_trails_) {
    const QColor colour = i < track_colours_.size() ? track_colours_[i] : QColor(255, 214, 0);
    // Fading towards the past: each segment more transparent the older it is.
    for (size_t k = 1; k < trail.size(); ++k) {
      QColor faded = colour;
      faded.setAlphaF(0.15 + 0.85 * static_cast<double>(k) / static_cast<double>(trail.size()));
      painter.setPen(QPen(faded, 3, Qt::SolidLine, Qt::RoundCap));
      painter.drawLine(transform.map(trail[k - 1]), transform.map(trail[k]));
    }
  }
  for (const auto& [i, map] : time_markers_) {
    const QColor colour = i < track_colours_.size() ? track_colours_[i] : QColor(255, 214, 0);
    painter.setPen(QPen(QColor(12, 12, 14), 2));
    painter.setBrush(colour);
    painter.drawEllipse(widgetFromMap(map), 5.5, 5.5);
  }
  painter.restore();
}

void MosaicView::setBookmarks(std::vector<std::pair<int64_t, Eigen::Vector2d>> bookmarks) {
  bookmarks_ = std::move(bookmarks);
  update();
}

void MosaicView::centreOn(const Eigen::Vector2d& map_point) {
  if (!map_point.allFinite()) return;
  auto_fit_ = false;
  setView(map_point, ppu_);
}

void MosaicView::paintBookmarks(QPainter& painter) {
  if (bookmarks_.empty()) return;
  painter.save();
  painter.setRenderHint(QPainter::Antialiasing);
  QFont font = painter.font();
  font.setBold(true);
  painter.setFont(font);
  const QFontMetricsF metrics(font);
  const QRectF area = rect();
  for (const auto& [id, map] : bookmarks_) {
    const QPointF p = widgetFromMap(map);
    if (!area.adjusted(-20, -20, 20, 20).contains(p)) continue;
    // A pin: a diamond whose lower tip is the place, the number beside it.
    const QPolygonF pin({p, p + QPointF(-7, -10), p + QPointF(0, -20), p + QPointF(7, -10)});
    painter.setPen(QPen(QColor(20, 20, 24), 1.5));
    painter.setBrush(QColor(255, 214, 0));
    painter.drawPolygon(pin);
    const QString label = QString::number(id);
    QRectF box = metrics.boundingRect(label);
    box.moveTopLeft(p + QPointF(9, -24));
    box.adjust(-3, -1, 3, 1);
    painter.setPen(Qt::NoPen);
    painter.setBrush(QColor(20, 20, 24, 200));
    painter.drawRoundedRect(box, 3, 3);
    painter.setPen(QColor(255, 214, 0));
    painter.drawText(box, Qt::AlignCenter, label);
  }
  painter.restore();
}

void MosaicView::paintSelection(QPainter& painter) {
  if (!selected_track_ || !isTrackVisible(*selected_track_) ||
      *selected_track_ >= track_shapes_.size()) {
    return;
  }
  const TrackShape& shape = track_shapes_[*selected_track_];
  if (shape.points.empty()) return;
  const QTransform transform = widgetFromMapTransform();
  QPolygonF line;
  line.reserve(static_cast<qsizetype>(shape.points.size()));
  for (const QPointF& point : shape.points) line << transform.map(point);
  painter.save();
  painter.setRenderHint(QPainter::Antialiasing);
  painter.setBrush(Qt::NoBrush);
  const QColor colour =
      *selected_track_ < track_colours_.size() && colour_mode_ != activity::ColourMode::kDensity
          ? track_colours_[*selected_track_]
          : QColor(255, 214, 0);
  painter.setPen(QPen(QColor(255, 255, 255, 230), 8, Qt::SolidLine, Qt::RoundCap, Qt::RoundJoin));
  painter.drawPolyline(line);
  painter.setPen(QPen(kTrackOutline, 5, Qt::SolidLine, Qt::RoundCap, Qt::RoundJoin));
  painter.drawPolyline(line);
  painter.setPen(QPen(colour, 3, Qt::SolidLine, Qt::RoundCap, Qt::RoundJoin));
  painter.drawPolyline(line);
  if (line.size() == 1) {
    painter.setBrush(colour);
    painter.drawEllipse(line.front(), 5, 5);
  }
  painter.restore();
}

void MosaicView::paintMarker(QPainter& painter) {
  if (!marker_) return;
  const QPointF c = widgetFromMap(*marker_);
  constexpr double kHalf = 10;  // 21 px across
  painter.save();
  painter.setRenderHint(QPainter::Antialiasing);
  const std::array<std::pair<QColor, double>, 2> strokes = {
      {{QColor(Qt::white), 4.0}, {QColor(220, 0, 0), 2.0}}};  // white outline, red cross
  for (const auto& [colour, width] : strokes) {
    painter.setPen(QPen(colour, width, Qt::SolidLine, Qt::FlatCap));
    painter.drawLine(c + QPointF(-kHalf, 0), c + QPointF(kHalf, 0));
    painter.drawLine(c + QPointF(0, -kHalf), c + QPointF(0, kHalf));
  }
  painter.restore();
}

void MosaicView::paintLegend(QPainter& painter) {
  if (frame_ != Frame::kMap || !show_tracks_ || !colouring_) return;
  const activity::Legend& legend = colouring_->legend();
  QFont title_font = font();
  title_font.setBold(true);
  const QFontMetricsF title_metrics(title_font);
  const QFontMetricsF metrics(font());
  const QString title = QString::fromStdString(legend.title);

  constexpr double kRampWidth = 180, kRampHeight = 12, kTick = 4, kSwatch = 12;
  double content_width = title_metrics.horizontalAdvance(title);
  double content_height = title_metrics.height() + 6;
  if (legend.continuous) {
    double overhang = 0;  // end labels centred on their ticks stick out of the ramp
    for (const activity::Legend::Entry& e : legend.entries) {
      const double half = metrics.horizontalAdvance(QString::fromStdString(e.label)) / 2;
      overhang = std::max(overhang, half);
    }
    content_width = std::max(content_width, kRampWidth + 2 * overhang);
    content_height += kRampHeight + kTick + 2 + metrics.height();
  } else {
    for (const activity::Legend::Entry& e : legend.entries) {
      content_width = std::max(
          content_width, kSwatch + 6 + metrics.horizontalAdvance(QString::fromStdString(e.label)));
    }
    content_height += static_cast<double>(legend.entries.size()) * (metrics.height() + 2);
  }
  const QRectF panel(kPanelMargin, height() - kPanelMargin - content_height - 2 * kPanelPadding,
                     content_width + 2 * kPanelPadding, content_height + 2 * kPanelPadding);

  painter.save();
  painter.setRenderHint(QPainter::Antialiasing);
  FillPanel(painter, panel);
  const double left = panel.left() + kPanelPadding;
  double y = panel.top() + kPanelPadding;
  painter.setPen(kPanelText);
  painter.setFont(title_font);
  painter.drawText(QPointF(left, y + title_metrics.ascent()), title);
  y += title_metrics.height() + 6;
  painter.setFont(font());
  if (legend.continuous) {
    double overhang = (content_width - kRampWidth) / 2;
    const QRectF ramp(left + overhang, y, kRampWidth, kRampHeight);
    QLinearGradient gradient(ramp.topLeft(), ramp.topRight());
    constexpr int kStops = 48;
    for (int i = 0; i <= kStops; ++i) {
      const double position = static_cast<double>(i) / kStops;
      gradient.setColorAt(position, ToQColor(colouring_->RampColour(position)));
    }
    painter.fillRect(ramp, gradient);
    painter.setPen(QPen(QColor(255, 255, 255, 110), 1));
    painter.setBrush(Qt::NoBrush);
    painter.drawRect(ramp);
    for (const activity::Legend::Entry& e : legend.entries) {
      const double x = ramp.left() + e.position * ramp.width();
      painter.setPen(QPen(kPanelText, 1));
      painter.drawLine(QPointF(x, ramp.bottom()), QPointF(x, ramp.bottom() + kTick));
      const QString label = QString::fromStdString(e.label);
      const double w = metrics.horizontalAdvance(label);
      painter.drawText(QPointF(x - w / 2, ramp.bottom() + kTick + 2 + metrics.ascent()), label);
    }
  } else {
    for (const activity::Legend::Entry& e : legend.entries) {
      const QRectF swatch(left, y + (metrics.height() - kSwatch) / 2, kSwatch, kSwatch);
      painter.setPen(QPen(QColor(0, 0, 0, 200), 1));
      painter.setBrush(ToQColor(e.colour));
      painter.drawRect(swatch);
      painter.setPen(kPanelText);
      painter.drawText(QPointF(left + kSwatch + 6, y + metrics.ascent()),
                       QString::fromStdString(e.label));
      y += metrics.height() + 2;
    }
  }
  painter.restore();
}

void MosaicView::paintScaleBar(QPainter& painter) {
  const bool metres = frame_ == Frame::kMap && mission_->map.geo_referenced;
  const double length = RoundLength(ppu_, 120);
  const double bar = length * ppu_;
  if (!std::isfinite(bar) || bar <= 0) return;
  QString label;
  if (!metres) {
    label = tr("%1 px").arg(FormatNumber(length));
  } else if (length >= 1000) {
    label = tr("%1 km").arg(FormatNumber(length / 1000));
  } else {
    label = tr("%1 m").arg(FormatNumber(length));
  }
  const QFontMetricsF metrics(font());
  constexpr double kBarHeight = 6;
  const double content_width = std::max(bar, metrics.horizontalAdvance(label));
  const double content_height = metrics.height() + 4 + kBarHeight;
  const QRectF panel(width() - kPanelMargin - content_width - 2 * kPanelPadding,
                     height() - kPanelMargin - content_height - 2 * kPanelPadding,
                     content_width + 2 * kPanelPadding, content_height + 2 * kPanelPadding);
  painter.save();
  painter.setRenderHint(QPainter::Antialiasing);
  FillPanel(painter, panel);
  const double right = panel.right() - kPanelPadding;
  const double top = panel.top() + kPanelPadding;
  painter.setPen(kPanelText);
  painter.drawText(QPointF(right - metrics.horizontalAdvance(label), top + metrics.ascent()),
                   label);
  // Two halves, white and grey, as on a printed map.
  const QRectF whole(right - bar, top + metrics.height() + 4, bar, kBarHeight);
  painter.setPen(Qt::NoPen);
  painter.setBrush(kPanelText);
  painter.drawRect(QRectF(whole.left(), whole.top(), bar / 2, kBarHeight));
  painter.setBrush(QColor(120, 120, 120));
  painter.drawRect(QRectF(whole.left() + bar / 2, whole.top(), bar / 2, kBarHeight));
  painter.setPen(QPen(kPanelText, 1));
  painter.setBrush(Qt::NoBrush);
  painter.drawRect(whole);

  if (metres) {
    // North is +y on a geo-referenced map, drawn straight up.
    const double side = metrics.height() + 30;
    const QRectF north(width() - kPanelMargin - side, kPanelMargin, side, side + 6);
    FillPanel(painter, north);
    const double cx = north.center().x();
    const double arrow_top = north.top() + 6;
    const double arrow_bottom = north.bottom() - metrics.height() - 4;
    QPolygonF arrow({QPointF(cx, arrow_top), QPointF(cx + 8, arrow_bottom),
                     QPointF(cx, arrow_bottom - 6), QPointF(cx - 8, arrow_bottom)});
    painter.setBrush(kPanelText);
    painter.drawPolygon(arrow);
    painter.setPen(kPanelText);
    const QString n = tr("N");
    painter.drawText(
        QPointF(cx - metrics.horizontalAdvance(n) / 2, north.bottom() - 4 - metrics.descent()), n);
  }
  painter.restore();
}

void MosaicView::paintHint(QPainter& painter) {
  painter.save();
  painter.setPen(QColor(200, 200, 200));
  const QRectF area = QRectF(rect()).adjusted(24, 24, -24, -24);
  painter.drawText(area, Qt::AlignCenter | Qt::TextWordWrap,
                   tr("Open a mission or a video (File menu), or drop one here."));
  painter.restore();
}

void MosaicView::paintPreviewLabel(QPainter& painter) {
  if (frame_ != Frame::kPreview) return;
  const QString label = tr("Preview (unadjusted)");
  const QFontMetricsF metrics(font());
  const QRectF panel(kPanelMargin, kPanelMargin, metrics.horizontalAdvance(label) + 12,
                     metrics.height() + 8);
  painter.save();
  painter.setRenderHint(QPainter::Antialiasing);
  FillPanel(painter, panel, 4);
  painter.setPen(QColor(230, 230, 230));
  painter.drawText(panel, Qt::AlignCenter, label);
  painter.restore();
}

// ---------------------------------------------------------------------------------------------
// Interaction.

bool MosaicView::event(QEvent* event) {
  if (event->type() == QEvent::NativeGesture) {
    nativeGesture(static_cast<QNativeGestureEvent*>(event));
    return true;
  }
  return QWidget::event(event);
}

void MosaicView::nativeGesture(QNativeGestureEvent* event) {
  if (event->gestureType() == Qt::ZoomNativeGesture) {
    // value() is the change of the pinch's scale since the last event.
    zoomAt(1 + event->value(), event->position());
    event->accept();
  } else if (event->gestureType() == Qt::SmartZoomNativeGesture) {
    fitToWindow();
    event->accept();
  } else {
    event->ignore();
  }
}

void MosaicView::resizeEvent(QResizeEvent* event) {
  QWidget::resizeEvent(event);
  if (auto_fit_) {
    fitToWindow();
  } else {
    setView(centre_, ppu_);  // the zoom limits follow the fit
  }
  emit viewChanged();
}

void MosaicView::wheelEvent(QWheelEvent* event) {
  const int delta = event->angleDelta().y();
  if (delta == 0 || frame_ == Frame::kNone) {
    event->ignore();
    return;
  }
  zoomAt(std::pow(kWheelZoomBase, delta), event->position());
  event->accept();
}

void MosaicView::mousePressEvent(QMouseEvent* event) {
  if (event->button() != Qt::LeftButton) {
    QWidget::mousePressEvent(event);
    return;
  }
  pressed_ = true;
  dragging_ = false;
  suppress_click_ = false;
  press_pos_ = last_pos_ = event->position();
  setCursor(Qt::ClosedHandCursor);
  event->accept();
}

void MosaicView::mouseMoveEvent(QMouseEvent* event) {
  const QPointF pos = event->position();
  if (frame_ != Frame::kNone) emit cursorMoved(mapFromWidget(pos));
  if (measuring_ && !measure_path_.empty()) {
    hover_ = pos;
    update();
  }
  if (!pressed_) return;
  if (!dragging_) {
    const QPointF moved = pos - press_pos_;
    dragging_ = std::hypot(moved.x(), moved.y()) > kDragThresholdPx;
  }
  if (dragging_) {
    panBy(pos - last_pos_);
    last_pos_ = pos;
  }
  event->accept();
}

void MosaicView::mouseReleaseEvent(QMouseEvent* event) {
  if (event->button() != Qt::LeftButton || !pressed_) {
    QWidget::mouseReleaseEvent(event);
    return;
  }
  if (!dragging_ && !suppress_click_ && frame_ != Frame::kNone) {
    if (measuring_) {
      addMeasurePoint(event->position());
    } else {
      emit mapClicked(mapFromWidget(event->position()), kClickTolerancePx / ppu_);
    }
  }
  pressed_ = dragging_ = suppress_click_ = false;
  setCursor(measuring_ ? Qt::CrossCursor : Qt::OpenHandCursor);
  event->accept();
}

void MosaicView::mouseDoubleClickEvent(QMouseEvent* event) {
  if (event->button() != Qt::LeftButton) {
    QWidget::mouseDoubleClickEvent(event);
    return;
  }
  // The press of a double-click: zoom in (measuring: a point, as a click), and let its release
  // be no click (the first click of the pair was one already).
  if (measuring_) {
    if (frame_ != Frame::kNone) addMeasurePoint(event->position());
  } else {
    zoomAt(2, event->position());
  }
  pressed_ = true;
  dragging_ = false;
  suppress_click_ = true;
  press_pos_ = last_pos_ = event->position();
  event->accept();
}

void MosaicView::keyPressEvent(QKeyEvent* event) {
  const double step_x = width() / 8.0, step_y = height() / 8.0;
  switch (event->key()) {
    case Qt::Key_Plus:
    case Qt::Key_Equal:
      zoomIn();
      break;
    case Qt::Key_Minus:
      zoomOut();
      break;
    case Qt::Key_0:
      fitToWindow();
      break;
    case Qt::Key_Left:
      panBy(QPointF(step_x, 0));
      break;
    case Qt::Key_Right:
      panBy(QPointF(-step_x, 0));
      break;
    case Qt::Key_Up:
      panBy(QPointF(0, step_y));
      break;
    case Qt::Key_Down:
      panBy(QPointF(0, -step_y));
      break;
    case Qt::Key_Backspace:
    case Qt::Key_Delete:
      if (!measuring_ || measure_path_.empty()) {
        QWidget::keyPressEvent(event);
        return;
      }
      measure_path_.pop_back();
      emit measureChanged(measure_path_);
      update();
      break;
    case Qt::Key_Escape:
      if (!measuring_ || measure_path_.empty()) {
        QWidget::keyPressEvent(event);
        return;
      }
      setMeasurePath({});
      break;
    default:
      QWidget::keyPressEvent(event);
      return;
  }
  event->accept();
}

void MosaicView::leaveEvent(QEvent* event) {
  QWidget::leaveEvent(event);
  emit cursorMoved(std::nullopt);
  if (hover_) {
    hover_.reset();
    update();
  }
}

void MosaicView::contextMenuEvent(QContextMenuEvent* event) {
  if (frame_ == Frame::kNone) {
    QWidget::contextMenuEvent(event);
    return;
  }
  emit contextMenuAt(mapFromWidget(event->pos()), kClickTolerancePx / ppu_, event->globalPos());
  event->accept();
}

void MosaicView::setMeasuring(bool on) {
  if (measuring_ == on) return;
  measuring_ = on;
  hover_.reset();
  setCursor(on ? Qt::CrossCursor : Qt::OpenHandCursor);
  if (!on && !measure_path_.empty()) {
    setMeasurePath({});
    return;
  }
  update();
}

void MosaicView::setMeasurePath(std::vector<Eigen::Vector2d> path) {
  measure_path_ = std::move(path);
  if (measure_path_.empty()) measure_text_.clear();
  emit measureChanged(measure_path_);
  update();
}

void MosaicView::setMeasureText(const QString& text) {
  measure_text_ = text;
  update();
}

void MosaicView::addMeasurePoint(const QPointF& widget) {
  measure_path_.push_back(mapFromWidget(widget));
  hover_ = widget;
  emit measureChanged(measure_path_);
  update();
}

void MosaicView::paintMeasure(QPainter& painter) {
  if (measure_path_.empty()) return;
  QPolygonF line;
  for (const Eigen::Vector2d& p : measure_path_) line << widgetFromMap(p);
  painter.save();
  painter.setRenderHint(QPainter::Antialiasing);
  const QColor ink(255, 214, 0);  // amber: no track colour mode uses it alone
  // The closing side (area) dashed, the rubber band to the cursor dotted; all over a dark
  // outline so that they read on any ground.
  const auto stroke = [&](const QPolygonF& path, Qt::PenStyle style) {
    painter.setPen(QPen(QColor(0, 0, 0, 170), 4.5, Qt::SolidLine, Qt::RoundCap, Qt::RoundJoin));
    painter.drawPolyline(path);
    painter.setPen(QPen(ink, 2.0, style, Qt::RoundCap, Qt::RoundJoin));
    painter.drawPolyline(path);
  };
  if (line.size() >= 3) stroke(QPolygonF({line.back(), line.front()}), Qt::DashLine);
  if (measuring_ && hover_) stroke(QPolygonF({line.back(), *hover_}), Qt::DotLine);
  stroke(line, Qt::SolidLine);
  painter.setPen(QPen(QColor(0, 0, 0, 200), 1.5));
  painter.setBrush(ink);
  for (const QPointF& p : line) painter.drawEllipse(p, 3.5, 3.5);
  if (!measure_text_.isEmpty()) {
    QFont font = painter.font();
    font.setBold(true);
    painter.setFont(font);
    const QFontMetricsF metrics(font);
    QRectF box = metrics.boundingRect(QRectF(0, 0, 400, 200), Qt::AlignLeft, measure_text_);
    box.adjust(-6, -4, 6, 4);
    box.moveTopLeft(line.back() + QPointF(12, 12));
    // Kept inside the widget.
    box.moveLeft(std::clamp(box.left(), 4.0, std::max(4.0, width() - box.width() - 4)));
    box.moveTop(std::clamp(box.top(), 4.0, std::max(4.0, height() - box.height() - 4)));
    painter.setPen(Qt::NoPen);
    painter.setBrush(QColor(20, 20, 24, 215));
    painter.drawRoundedRect(box, 4, 4);
    painter.setPen(ink);
    painter.drawText(box.adjusted(6, 4, -6, -4), Qt::AlignLeft, measure_text_);
  }
  painter.restore();
}

}  // namespace saker::ui
