#pragma once

// Saker's main window: the mission's mosaic with its tracks in the centre, the recalled video
// frame and the mission's facts and filters in docks, menus in desktop conventions. Everything
// slow runs off the GUI thread: processing a video and exporting on one task runner, loading a
// mission on another; results come back as queued calls, so the window never freezes.
// docs/user-guide.md describes it for analysts.

#include "core/activity/activity.h"
#include "core/activity/colours.h"
#include "core/geo/coordinates.h"
#include "core/geo/local_tangent_plane.h"
#include "core/mission/mission.h"
#include "core/util/job_context.h"
#include "core/util/status.h"
#include "ui/mailbox.h"
#include "ui/meta_types.h"

#include <Eigen/Core>

#include <QMainWindow>
#include <QString>
#include <QStringList>
#include <functional>
#include <memory>
#include <optional>
#include <set>
#include <vector>

class QAction;
class QActionGroup;
class QDoubleSpinBox;
class QLabel;
class QListWidget;
class QMenu;
class QProgressBar;
class QPushButton;
class QUndoStack;

namespace saker::ui {

class FramePanel;
class MosaicView;
class TaskRunner;
class TimeLine;
class TrackTable;

class MainWindow : public QMainWindow {
  Q_OBJECT

 public:
  explicit MainWindow(QWidget* parent = nullptr);
  ~MainWindow() override;

  // A .saker file is opened as a mission, anything else processed as a video (asking where to
  // save its mission).
  void openPath(const QString& path);
  // Loads the mission in the background: missionOpened, or missionFailed and an error dialog.
  void openMission(const QString& path);
  // Asks where to save the mission (beside the video by default), then processes the video.
  void openVideo(const QString& path);
  // Processes `video` into the mission `mission_path` without asking; `replace` overwrites a
  // mission there, `resume` carries on the interrupted job in it from its checkpoint. The mosaic
  // and tracks appear and grow as stages complete.
  void processVideo(const QString& video, const QString& mission_path, bool replace,
                    bool resume = false);
  // File > Resume Processing: carries the shown mission's interrupted job on (its video must be
  // available). False, with a message in the status bar, when there is nothing to resume.
  bool resumeProcessing();
  // Seconds between the front end's checkpoints of the jobs started from now (default 30).
  void setCheckpointInterval(double seconds) { checkpoint_interval_s_ = seconds; }
  // Exports with the current colour mode and filters (only the tracks shown), without asking.
  void exportActivityMap(const QString& path);
  void exportTracks(const QString& path);  // by extension: .geojson / .json, .kml, .csv
  void exportMosaic(const QString& path);  // GeoTIFF, full resolution
  // The mission report (HTML or PDF by the extension) of the tracks shown.
  void exportReport(const QString& path);
  void saveMissionAs(const QString& path);
  // Uses `path` as the mission's video from now on (remembered by the video's fingerprint); a
  // file that is not that video is refused with a dialog unless `force`.
  bool useVideo(const QString& path, bool force = false);

  std::shared_ptr<const mission::Mission> mission() const { return mission_; }
  QString missionPath() const { return mission_path_; }
  QString videoPath() const { return video_path_; }
  MosaicView* mosaicView() const { return view_; }
  FramePanel* framePanel() const { return frame_panel_; }
  TaskRunner* taskRunner() const { return jobs_; }
  QStringList recentFiles() const { return recent_; }

  // The click: selects the shown track observation nearest `map_point` within `tolerance` (map
  // units), marks it and recalls its frame. False when there is none.
  bool pickAt(const Eigen::Vector2d& map_point, double tolerance);

  // The analyst's judgement (the Track menu, the map's context menu): each change is one
  // undoable step (Edit > Undo) and is saved in the mission at once (MissionStore::SaveReviews).
  // False when there is no such track or no mission, or the change could not be saved (an error
  // dialog says why; the change stays in this window).
  bool setTrackVerdict(size_t track_index, mission::Verdict verdict);
  bool setTrackLabel(size_t track_index, mission::TargetLabel label);
  bool setTrackNote(size_t track_index, const QString& note);
  // The reviews as the window has them (saved, unless saving failed).
  const std::vector<mission::TrackReview>& reviews() const { return reviews_; }
  // Bookmarks (Track > Add Bookmark, the map's context menu, the Bookmarks panel): undoable and
  // saved at once like the reviews. A bookmark without a time takes that of the first frame that
  // saw its place (0 when none did). addBookmark returns the new id (0 when there is no mission).
  int64_t addBookmark(const Eigen::Vector2d& map_point, std::optional<double> time_s,
                      const QString& note);
  bool setBookmarkNote(int64_t id, const QString& note);
  bool removeBookmark(int64_t id);
  const std::vector<mission::Bookmark>& bookmarks() const { return bookmarks_; }
  QUndoStack* undoStack() const { return undo_; }
  // Selects a track (highlighted on the map, its row in the track table); nullopt: none.
  void selectTrack(std::optional<size_t> track_index);
  std::optional<size_t> selectedTrack() const;
  // Jumps to a track: selects it, fits the map to it and recalls its middle observation.
  void showTrack(size_t track_index);
  TrackTable* trackTable() const { return track_table_; }
  TimeLine* timeLine() const { return time_line_; }
  // The passes of the aircraft that saw a map point: runs of frames whose picture holds it,
  // split where 2 s pass without one.
  struct Pass {
    int64_t first_frame = 0, last_frame = 0;
    double start_s = 0, end_s = 0;
  };
  std::vector<Pass> passesSeeing(const Eigen::Vector2d& map_point) const;
  // A click on bare ground: the time line, the map and the frame go to the middle of the pass
  // that saw it (a menu of the passes when several did).
  void seekGround(const Eigen::Vector2d& map_point);
  // For tests: no menu of passes, the first one is taken.
  void setGroundMenuSuppressed(bool suppressed) { ground_menu_suppressed_ = suppressed; }

  // How positions are written (status bar, Copy Coordinates): View > Coordinates.
  void setCoordinateFormat(geo::CoordinateFormat format);
  geo::CoordinateFormat coordinateFormat() const { return coordinate_format_; }
  // A map point as text: in the coordinate format on a geo-referenced map, "x 12, y 34 px" on
  // another; empty without a mission.
  QString positionText(const Eigen::Vector2d& map_point) const;
  // What the measured path measures (Tools > Measure): length, and area from three points; on
  // the ellipsoid for a geo-referenced map, in map pixels otherwise. Empty without a path.
  QString measureText() const;
  // The map's context menu at `map_point` (what a right-click there opens), for the tests.
  QMenu* contextMenuFor(const Eigen::Vector2d& map_point, double tolerance);

 signals:
  void missionOpened(const QString& path);
  void missionFailed(const QString& path, const QString& message);
  // A job of the task runner ended ("Processing", "Export", "Save As").
  void jobFinished(const QString& title, const saker::Status& status);

 protected:
  void dragEnterEvent(QDragEnterEvent* event) override;
  void dropEvent(QDropEvent* event) override;
  void closeEvent(QCloseEvent* event) override;

 private:
  struct Loaded;
  // The mission as the window shows it, for a worker: the tracks the filters show (by id), the
  // reviews and bookmarks as the window has them.
  struct ShownMission {
    std::shared_ptr<const mission::Mission> loaded;
    std::set<int64_t> ids;
    std::vector<mission::TrackReview> reviews;
    std::vector<mission::Bookmark> bookmarks;
    mission::Mission Make() const;
  };
  ShownMission shownMission() const;

  void createActions();
  void createDocks();
  void createStatusBar();
  void readSettings();
  void writeSettings() const;

  void chooseVideo();
  void chooseMission();
  void chooseSaveAs();
  void chooseActivityMap();
  void chooseTracks();
  void chooseMosaic();
  // Asks where to export (beside the mission, named after it with `name_suffix`); empty: cancelled.
  QString askExportPath(const QString& title, const QString& name_suffix, const QString& filters);
  void locateVideo();
  void showAbout();
  void showUserGuide();

  void reloadMission();  // the same mission again (processing committed a stage)
  void startLoad(const QString& path);
  void missionLoaded(const Loaded& loaded);
  void jobEnded(const QString& title, const Status& status);
  void setColourMode(activity::ColourMode mode);
  void applyFilter();
  void resetFilter();  // the ranges of the mission shown, no bounds
  // The ranges, unit and boxes of the mission shown; `keep_bounds` keeps the bounds set inside
  // the ranges (the speeds only in the same unit).
  void setFilterRanges(bool keep_bounds);
  // Shows no mission (one that was being opened or processed and never opened).
  void forgetMission();
  void updateMissionFacts();
  void updateActions();
  void updateCursor(const std::optional<Eigen::Vector2d>& map_point);
  // Changes the review of track `track_index` with `change`, as one undoable step named `what`.
  bool changeReview(size_t track_index, const std::function<void(mission::TrackReview*)>& change,
                    const QString& what);
  // Makes `review` the review of its track (none when empty), saves, and shows it.
  void applyReview(const mission::TrackReview& review);
  bool saveReviews();
  // Replaces the bookmarks with `after` as one undoable step named `what`.
  bool changeBookmarks(std::vector<mission::Bookmark> after, const QString& what);
  void applyBookmarks(const std::vector<mission::Bookmark>& bookmarks);
  void chooseBookmark(std::optional<Eigen::Vector2d> at);  // asks for the note, then adds
  void rebuildBookmarkList();
  void selectionChanged();  // selected_ changed: the map's highlight, the table's row, actions
  void editNote();          // asks for the selected track's note
  void updateMeasure();
  void addRecent(const QString& path);
  void rebuildRecentMenu();
  void showError(const QString& title, const QString& message);
  bool startJob(const QString& title, std::function<Status(JobContext*)> task);
  void exportFiles(const QString& what, const QString& path, const QString& png,
                   const QString& geotiff, const QString& geojson, const QString& kml,
                   const QString& csv);

  // The mission shown, its file and its video (empty when not found).
  std::shared_ptr<const mission::Mission> mission_;
  QString mission_path_;
  QString video_path_;
  QString video_problem_;  // why the video is not available, for the frame panel
  // How far an interrupted job's checkpoint goes (none: no checkpoint in the file).
  std::optional<int64_t> checkpoint_frame_;
  bool checkpoint_complete_ = false;  // the front end had finished
  double checkpoint_interval_s_ = 30;
  std::unique_ptr<activity::TrackIndex> track_index_;
  std::optional<geo::LocalTangentPlane> plane_;  // map -> latitude, longitude (geo-referenced)
  std::optional<std::pair<size_t, size_t>> selected_;

  MosaicView* view_ = nullptr;
  FramePanel* frame_panel_ = nullptr;
  QLabel* facts_ = nullptr;
  QDoubleSpinBox* from_s_ = nullptr;
  QDoubleSpinBox* to_s_ = nullptr;
  QDoubleSpinBox* min_speed_ = nullptr;
  QDoubleSpinBox* max_speed_ = nullptr;
  QDoubleSpinBox* min_confidence_ = nullptr;  // 0 to 1: tracks below it are hidden
  QLabel* speed_unit_ = nullptr;
  QLabel* shown_count_ = nullptr;
  bool filter_updating_ = false;

  QLabel* stage_label_ = nullptr;
  QProgressBar* progress_ = nullptr;
  QPushButton* cancel_button_ = nullptr;
  QLabel* cursor_label_ = nullptr;
  QLabel* measure_label_ = nullptr;
  std::optional<Eigen::Vector2d> cursor_;  // the map point under the cursor
  geo::CoordinateFormat coordinate_format_ = geo::CoordinateFormat::kDecimalDegrees;
  QActionGroup* coordinate_group_ = nullptr;
  QAction* measure_action_ = nullptr;
  QMenu* context_menu_ = nullptr;

  // The analyst's reviews (sorted by track id) and the undo stack of their changes.
  std::vector<mission::TrackReview> reviews_;
  std::vector<mission::Bookmark> bookmarks_;
  QListWidget* bookmark_list_ = nullptr;
  QUndoStack* undo_ = nullptr;
  bool reviews_saved_ = true;  // the last change reached the file
  TrackTable* track_table_ = nullptr;
  TimeLine* time_line_ = nullptr;
  bool ground_menu_suppressed_ = false;
  QAction* show_false_action_ = nullptr;
  std::vector<QAction*> review_actions_;  // need a selected track and no job on the mission

  QMenu* recent_menu_ = nullptr;
  QActionGroup* colour_group_ = nullptr;
  QAction* save_as_action_ = nullptr;
  QAction* export_map_action_ = nullptr;
  QAction* export_tracks_action_ = nullptr;
  QAction* export_mosaic_action_ = nullptr;
  QAction* export_report_action_ = nullptr;
  QAction* locate_action_ = nullptr;
  QAction* resume_action_ = nullptr;
  QAction* show_tracks_action_ = nullptr;
  QAction* show_outlines_action_ = nullptr;
  QAction* show_ellipses_action_ = nullptr;
  QAction* show_overlay_mask_action_ = nullptr;  // the frame panel's overlay mask layer
  QStringList recent_;

  TaskRunner* jobs_ = nullptr;    // processing, exports, copies: one at a time
  TaskRunner* loader_ = nullptr;  // mission loads
  Mailbox* mailbox_ = nullptr;    // the processing job's commits and key frames
  std::shared_ptr<Loaded> loading_;
  QString pending_load_;  // a load asked for while one ran
  QString opening_path_;  // a mission being opened (the one shown stays until it has loaded)
  QString processing_video_;
};

}  // namespace saker::ui
