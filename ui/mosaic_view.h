#pragma once

// The analyst's map (the paper's activity view): the mission's mosaic as a zoomable tile pyramid
// with the moving targets' tracks drawn over it, coloured by speed, direction, visit or time, with
// a legend, a scale bar and a north arrow. Before a mission has a mosaic, it shows the key frames
// as the front end places them (an unadjusted preview). Painting only draws: tiles are read and
// decoded by a TileCache worker, track geometry and colours are prepared when the mission or the
// colour mode changes, and tracks off screen are skipped by their bounding boxes.

#include "core/activity/colours.h"
#include "core/frontend/front_end.h"
#include "core/mission/mission.h"

#include <Eigen/Core>

#include <QColor>
#include <QImage>
#include <QMetaType>
#include <QPointF>
#include <QPolygonF>
#include <QRectF>
#include <QString>
#include <QTransform>
#include <QWidget>
#include <array>
#include <memory>
#include <optional>
#include <set>
#include <vector>

// Map points travel in signals as Eigen vectors (registered in the MosaicView constructor, so
// queued connections work too).
Q_DECLARE_METATYPE(Eigen::Vector2d)
Q_DECLARE_METATYPE(std::optional<Eigen::Vector2d>)

class QContextMenuEvent;
class QNativeGestureEvent;
class QTimer;

namespace saker::ui {

class TileCache;

class MosaicView : public QWidget {
  Q_OBJECT

 public:
  // Which tracks are drawn. Unset bounds do not filter.
  struct TrackFilter {
    std::optional<double> start_s, end_s;  // shown when the track overlaps [start_s, end_s]
    // Average speed in the legend's unit: m/s when geo-referenced, map units (pixels) per second
    // otherwise; shown when min_speed <= speed <= max_speed.
    std::optional<double> min_speed, max_speed;
    // Shown when activity::PassesConfidence: at 0 every track, above it only tracks whose
    // confidence is known and at least this.
    double min_confidence = 0;
    // Never shown (by ActivityTrack::id): the tracks the analyst marked false, unless asked.
    std::set<int64_t> hidden_ids;
  };

  explicit MosaicView(QWidget* parent = nullptr);
  ~MosaicView() override;

  // Shows `mission`, its tiles read from the file at `mission_path`. Reloading the same path
  // (processing committed a new stage) keeps the view where the user put it (a view nobody moved
  // since it was fitted is fitted again when the content grew); a new path fits the map to the
  // window; a null mission clears.
  void setMission(std::shared_ptr<const mission::Mission> mission, const QString& mission_path);
  const std::shared_ptr<const mission::Mission>& mission() const { return mission_; }

  // While the mission has no mosaic yet (none, or progress.mosaic false), the view shows the key
  // frames as the front end places them, in the first video frame's pixels (y down).
  void addPreviewKeyFrame(const frontend::KeyFramePreview& preview);
  void clearPreview();
  int previewKeyFrameCount() const { return preview_count_; }
  bool showingPreview() const;  // the preview is what is drawn now

  void setColourMode(activity::ColourMode mode);
  activity::ColourMode colourMode() const { return colour_mode_; }
  // The legend of the current mode for the current mission's tracks; empty (no title, no entries)
  // when the mission has no tracks, as none is drawn then.
  const activity::Legend& legend() const;
  // The colour a track is drawn in; nullopt when the filter hides it (or no such track). Turning
  // all tracks off with setShowTracks(false) does not change it.
  std::optional<activity::Rgb> trackColour(size_t track_index) const;

  void setTrackFilter(const TrackFilter& filter);
  const TrackFilter& trackFilter() const { return filter_; }
  bool isTrackVisible(size_t track_index) const;

  void setShowTracks(bool show);
  void setShowKeyFrameOutlines(bool show);
  void setShowUncertainty(bool show);  // 95 % ellipses of the node key frames' corners
  bool showTracks() const { return show_tracks_; }
  bool showKeyFrameOutlines() const { return show_outlines_; }
  bool showUncertainty() const { return show_uncertainty_; }

  void zoomIn();
  void zoomOut();
  void fitToWindow();
  // Multiplies the zoom by `factor` (within the limits) keeping the map point under
  // `widget_anchor` where it is.
  void zoomAt(double factor, const QPointF& widget_anchor);
  double pixelsPerMapUnit() const { return ppu_; }
  // Widget pixels <-> map coordinates (the preview's frame while the preview is shown). On a
  // geo-referenced map north (+y) is up.
  QPointF widgetFromMap(const Eigen::Vector2d& map) const;
  Eigen::Vector2d mapFromWidget(const QPointF& widget) const;

  // The selected track (an index into the mission's tracks), drawn over the others with a white
  // halo; nullopt: none.
  void setSelectedTrack(std::optional<size_t> track_index);
  const std::optional<size_t>& selectedTrack() const { return selected_track_; }
  // Centres the view on a track and zooms so that it fills about half the view.
  void showTrack(size_t track_index);

  // The time line's frame (a mission frame index; nullopt: none): its footprint drawn on the map,
  // and every shown track seen at its time as a marker with its last seconds as a fading trail.
  void setCurrentFrame(std::optional<int64_t> frame_index);
  const std::optional<int64_t>& currentFrameIndex() const { return current_frame_; }
  // The markers drawn for the current frame: (track index, map point).
  const std::vector<std::pair<size_t, Eigen::Vector2d>>& timeMarkers() const {
    return time_markers_;
  }

  // The analyst's bookmarks, drawn as numbered amber pins (map frame only).
  void setBookmarks(std::vector<std::pair<int64_t, Eigen::Vector2d>> bookmarks);
  // Centres the view on a map point, keeping the zoom.
  void centreOn(const Eigen::Vector2d& map_point);

  // The red cross that marks a recalled place; nullopt removes it.
  void setMarker(std::optional<Eigen::Vector2d> map_point);
  const std::optional<Eigen::Vector2d>& marker() const { return marker_; }

  // Measuring: while on, a click adds a point to the measured path instead of picking (a
  // double-click too, without zooming), Backspace takes the last point off and Escape clears the
  // path; the path is drawn with a rubber band to the cursor, closed (dashed) from three points,
  // and `measureText` in a box beside its last point. Turning it off clears the path.
  void setMeasuring(bool on);
  bool measuring() const { return measuring_; }
  const std::vector<Eigen::Vector2d>& measurePath() const { return measure_path_; }
  void setMeasurePath(std::vector<Eigen::Vector2d> path);  // map points; emits measureChanged
  void setMeasureText(const QString& text);  // what the path measures, drawn beside it

  // The pyramid level drawn at the current zoom (0 without a pyramid).
  int tileLevel() const;
  // Every tile the current view needs at tileLevel() has been read (or found empty): nothing is
  // shown as a coarser placeholder any more.
  bool tilesComplete() const;
  TileCache* tileCache() const { return tiles_; }

  QSize sizeHint() const override;
  QSize minimumSizeHint() const override;

 signals:
  // A click (press and release without dragging) at `map_point`; `tolerance_map_units` is 8
  // widget pixels on the map, for picking.
  void mapClicked(const Eigen::Vector2d& map_point, double tolerance_map_units);
  // The map point under the cursor; nullopt when the cursor leaves the view.
  void cursorMoved(std::optional<Eigen::Vector2d> map_point);
  // The measured path changed (a point added or taken off, cleared).
  void measureChanged(const std::vector<Eigen::Vector2d>& path);
  // A right-click (or the context-menu key) at `map_point`, at `global_pos` on the screen.
  void contextMenuAt(const Eigen::Vector2d& map_point, double tolerance_map_units,
                     const QPoint& global_pos);
  // The visible part of the map changed (zoom, pan, resize, new mission).
  void viewChanged();
  // The mission's tiles cannot be read (forwarded from the TileCache; names the file).
  void tilesFailed(const QString& message);

 protected:
  bool event(QEvent* event) override;
  void paintEvent(QPaintEvent* event) override;
  void resizeEvent(QResizeEvent* event) override;
  void wheelEvent(QWheelEvent* event) override;
  void mousePressEvent(QMouseEvent* event) override;
  void mouseMoveEvent(QMouseEvent* event) override;
  void mouseReleaseEvent(QMouseEvent* event) override;
  void mouseDoubleClickEvent(QMouseEvent* event) override;
  void keyPressEvent(QKeyEvent* event) override;
  void leaveEvent(QEvent* event) override;
  void contextMenuEvent(QContextMenuEvent* event) override;

 private:
  // The coordinate frame drawn: the mission's map or the preview's (first video frame pixels).
  enum class Frame { kNone, kMap, kPreview };

  // A track's geometry on the map, prepared once per mission.
  struct TrackShape {
    std::vector<QPointF> points;  // map
    QRectF bounds;                // map, for culling
  };

  Frame currentFrame() const;
  // Re-derives what depends on the drawn frame (zoom limits, content, y direction); refits when
  // the frame changed or `refit`.
  void frameChanged(bool refit);
  void rebuildMissionGeometry();
  void rebuildColouring();
  void rebuildVisibility();
  QRectF contentBounds() const;  // map rectangle of what there is to see
  double fitPixelsPerMapUnit() const;
  double minPixelsPerMapUnit() const;
  double maxPixelsPerMapUnit() const;
  void setView(const Eigen::Vector2d& centre, double ppu);
  void panBy(const QPointF& widget_delta);
  QRectF visibleMapRect() const;
  bool yUp() const { return y_up_; }
  QTransform widgetFromMapTransform() const;

  struct TileRange {
    int level = 0;
    int x0 = 0, x1 = -1, y0 = 0, y1 = -1;  // inclusive
  };
  TileRange visibleTiles(int level) const;
  QRectF tileRect(int level, int x, int y) const;  // widget
  void requestTiles();

  void paintTiles(QPainter& painter);
  void paintPreview(QPainter& painter);
  void paintKeyFrames(QPainter& painter);
  void paintTracks(QPainter& painter);
  void paintDensity(QPainter& painter);
  void rebuildDensity();  // the heat map of the visible tracks (density mode only)
  void drawTracks(QPainter& painter) const;  // every visible track, in widget coordinates
  void tracksChanged();                      // what the tracks look like changed: redraw them
  void paintMarker(QPainter& painter);
  void paintSelection(QPainter& painter);
  void paintBookmarks(QPainter& painter);
  void paintTimeLine(QPainter& painter);  // the current frame's footprint, markers and trails
  void rebuildTimeMarkers();
  void paintMeasure(QPainter& painter);
  void addMeasurePoint(const QPointF& widget);
  void paintLegend(QPainter& painter);
  void paintScaleBar(QPainter& painter);
  void paintHint(QPainter& painter);
  void paintPreviewLabel(QPainter& painter);

  void nativeGesture(QNativeGestureEvent* event);

  TileCache* tiles_ = nullptr;
  std::shared_ptr<const mission::Mission> mission_;
  QString mission_path_;

  // The view: the map point at the widget's centre and the zoom.
  Eigen::Vector2d centre_{0, 0};
  double ppu_ = 1;  // widget pixels per map unit
  bool y_up_ = false;
  Frame frame_ = Frame::kNone;
  bool auto_fit_ = true;            // follow the content until the user zooms or pans
  QRectF fitted_bounds_;            // contentBounds() at the last fit
  double map_units_per_pixel_ = 1;  // of the source imagery (limits the zoom)

  // Tracks.
  activity::ColourMode colour_mode_ = activity::ColourMode::kSpeed;
  std::optional<activity::TrackColouring> colouring_;
  std::vector<QColor> track_colours_;
  std::vector<TrackShape> track_shapes_;
  std::vector<bool> track_visible_;
  TrackFilter filter_;
  bool show_tracks_ = true;
  bool show_outlines_ = false;
  bool show_uncertainty_ = false;
  // The density mode's heat map: one premultiplied pixel per cell, its placement, its legend.
  QImage density_image_;
  QTransform map_from_density_;
  activity::Legend density_legend_;

  // Key frames, on the map.
  std::vector<std::array<QPointF, 4>> key_frame_outlines_;
  std::vector<QPolygonF> uncertainty_ellipses_;

  // The tracks as last drawn, reused by paints that change nothing about them (a tile arriving,
  // the marker). When drawing them is slow (thousands of tracks), a pan or zoom shows this image
  // moved and scaled with the map and redraws once the view has been still for a moment.
  QImage track_layer_;
  QTransform track_layer_view_;      // widgetFromMapTransform() it was drawn with
  quint64 track_layer_version_ = 0;  // tracks_version_ it shows
  quint64 tracks_version_ = 1;
  double track_draw_ms_ = 0;  // the last full drawing
  bool redraw_tracks_now_ = false;
  QTimer* settle_timer_ = nullptr;

  std::optional<Eigen::Vector2d> marker_;
  std::optional<size_t> selected_track_;
  std::vector<std::pair<int64_t, Eigen::Vector2d>> bookmarks_;
  std::optional<int64_t> current_frame_;
  std::optional<std::array<Eigen::Vector2d, 4>> footprint_;  // of the current frame, on the map
  std::vector<std::pair<size_t, Eigen::Vector2d>> time_markers_;
  std::vector<std::pair<size_t, std::vector<QPointF>>> time_trails_;  // map points, oldest first

  // Measuring.
  bool measuring_ = false;
  std::vector<Eigen::Vector2d> measure_path_;
  QString measure_text_;
  std::optional<QPointF> hover_;  // the cursor in the widget, for the rubber band

  // The preview: key frames composited as they arrive into one canvas (bounded in size), so a
  // paint draws one image whatever the number of key frames.
  QImage preview_canvas_;
  QTransform canvas_from_preview_;
  QRectF canvas_bounds_;   // preview coordinates the canvas covers
  QRectF preview_bounds_;  // of the key frames added
  double preview_units_per_pixel_ = 1;
  int preview_count_ = 0;

  // Mouse.
  bool pressed_ = false;
  bool dragging_ = false;
  bool suppress_click_ = false;  // the release that ends a double-click
  QPointF press_pos_;
  QPointF last_pos_;
};

}  // namespace saker::ui
