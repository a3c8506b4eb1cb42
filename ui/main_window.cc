#include "ui/main_window.h"

#include "core/geo/local_tangent_plane.h"
#include "core/mission/mission_store.h"
#include "core/pipeline/checkpoint.h"
#include "core/pipeline/export_mission.h"
#include "core/pipeline/open_mission.h"
#include "core/pipeline/process.h"
#include "core/report/report.h"
#include "core/util/memory.h"
#include "ui/frame_panel.h"
#include "ui/mosaic_view.h"
#include "ui/report_pdf.h"
#include "ui/task_runner.h"
#include "ui/time_line.h"
#include "ui/track_table.h"

#include <QAction>
#include <QActionGroup>
#include <QApplication>
#include <QClipboard>
#include <QCloseEvent>
#include <QCursor>
#include <QDialog>
#include <QDialogButtonBox>
#include <QDir>
#include <QDockWidget>
#include <QDoubleSpinBox>
#include <QDragEnterEvent>
#include <QDropEvent>
#include <QFile>
#include <QFileDialog>
#include <QFileInfo>
#include <QFormLayout>
#include <QGuiApplication>
#include <QHBoxLayout>
#include <QIcon>
#include <QInputDialog>
#include <QKeySequence>
#include <QLabel>
#include <QListWidget>
#include <QMenu>
#include <QMenuBar>
#include <QMessageBox>
#include <QMimeData>
#include <QProgressBar>
#include <QPushButton>
#include <QSettings>
#include <QStatusBar>
#include <QTableView>
#include <QTextBrowser>
#include <QToolBar>
#include <QUndoCommand>
#include <QUndoStack>
#include <QVBoxLayout>
#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <functional>
#include <set>

// Resources compiled into a static library must be registered explicitly.
static void InitSakerResources() { Q_INIT_RESOURCE(saker); }

namespace saker::ui {

namespace {

constexpr int kProgressSteps = 1000;
constexpr int kMaxRecent = 10;

QString FromStd(const std::string& text) { return QString::fromStdString(text); }

bool IsMissionPath(const QString& path) {
  return QFileInfo(path).suffix().compare("saker", Qt::CaseInsensitive) == 0;
}

QString SettingsKeyForVideo(const std::string& fingerprint) {
  return "videoLocations/" + FromStd(fingerprint);
}

QString Duration(double seconds) {
  const int total = static_cast<int>(std::lround(seconds));
  return QString("%1:%2").arg(total / 60).arg(total % 60, 2, 10, QChar('0'));
}

// "51.23456° N, 1.23456° W"
QString LatLonText(double latitude, double longitude) {
  return QString("%1° %2, %3° %4")
      .arg(std::abs(latitude), 0, 'f', 5)
      .arg(latitude >= 0 ? "N" : "S")
      .arg(std::abs(longitude), 0, 'f', 5)
      .arg(longitude >= 0 ? "E" : "W");
}

// An undoable step made of two functions.
class FunctionCommand : public QUndoCommand {
 public:
  FunctionCommand(const QString& text, std::function<void()> redo, std::function<void()> undo)
      : QUndoCommand(text), redo_(std::move(redo)), undo_(std::move(undo)) {}
  void redo() override { redo_(); }
  void undo() override { undo_(); }

 private:
  std::function<void()> redo_, undo_;
};

}  // namespace

// A mission as loaded on the loader's thread, with where its video is.
struct MainWindow::Loaded {
  QString path;
  std::shared_ptr<const mission::Mission> mission;
  QString video;    // the video to recall frames from; empty when not found
  QString problem;  // why not, for a person
  std::optional<pipeline::CheckpointState> checkpoint;  // an interrupted job's
  // Its key frames, placed as the front end placed them, to show until there is a mosaic.
  std::vector<frontend::KeyFramePreview> previews;
  bool read_only = false;  // the file cannot be written here
};

MainWindow::MainWindow(QWidget* parent) : QMainWindow(parent) {
  InitSakerResources();
  setWindowTitle(tr("Saker"));
  setWindowIcon(QIcon(":/saker/icons/saker.svg"));
  setAcceptDrops(true);
  resize(1280, 800);

  mailbox_ = new Mailbox(this);
  jobs_ = new TaskRunner(this);
  loader_ = new TaskRunner(this);
  connect(jobs_, &TaskRunner::progress, this, [this](const QString& stage, double fraction) {
    stage_label_->setText(processing_video_.isEmpty()
                              ? stage
                              : tr("%1: %2").arg(QFileInfo(processing_video_).fileName(), stage));
    progress_->setValue(static_cast<int>(std::lround(fraction * kProgressSteps)));
  });
  connect(jobs_, &TaskRunner::finished, this, &MainWindow::jobEnded);
  connect(loader_, &TaskRunner::finished, this, [this](const QString&, const Status& status) {
    const std::shared_ptr<Loaded> loaded = std::move(loading_);
    if (!pending_load_.isEmpty()) {  // superseded while it loaded
      const QString next = std::exchange(pending_load_, QString());
      startLoad(next);
      return;
    }
    if (!status.ok()) {
      const QString path = loaded ? loaded->path : QString();
      if (path == mission_path_ && jobs_->isRunning()) return;  // mid-processing: next commit
      // The mission shown (if any) stays open; a mission that never opened is forgotten.
      if (path == opening_path_) opening_path_.clear();
      if (path == mission_path_ && !mission_) forgetMission();
      statusBar()->clearMessage();
      updateMissionFacts();
      showError(tr("Cannot open the mission"), FromStd(status.message()));
      emit missionFailed(path, FromStd(status.message()));
      return;
    }
    if (loaded) missionLoaded(*loaded);
  });

  // The map, with the mission's time line under it.
  auto* centre = new QWidget(this);
  view_ = new MosaicView(centre);
  time_line_ = new TimeLine(centre);
  auto* centre_layout = new QVBoxLayout(centre);
  centre_layout->setContentsMargins(0, 0, 0, 0);
  centre_layout->setSpacing(0);
  centre_layout->addWidget(view_, 1);
  centre_layout->addWidget(time_line_);
  setCentralWidget(centre);
  connect(view_, &MosaicView::mapClicked, this,
          [this](const Eigen::Vector2d& map_point, double tolerance) {
            if (pickAt(map_point, tolerance)) return;
            view_->setMarker(std::nullopt);
            seekGround(map_point);  // bare ground: the frames that saw it
          });
  connect(time_line_, &TimeLine::frameChanged, this, [this](int64_t frame) {
    view_->setCurrentFrame(frame);
    frame_panel_->showFrame(frame);
  });
  connect(view_, &MosaicView::cursorMoved, this, &MainWindow::updateCursor);
  connect(view_, &MosaicView::measureChanged, this, &MainWindow::updateMeasure);
  connect(view_, &MosaicView::contextMenuAt, this,
          [this](const Eigen::Vector2d& map_point, double tolerance, const QPoint& global_pos) {
            contextMenuFor(map_point, tolerance)->popup(global_pos);
          });

  createDocks();
  createActions();
  createStatusBar();
  readSettings();
  updateActions();
  updateMissionFacts();
}

MainWindow::~MainWindow() {
  // Worker threads post to this window: end them before its members go.
  jobs_->cancelAndWait();
  loader_->cancelAndWait();
}

// --------------------------------------------------------------------------------------------
// Construction

void MainWindow::createDocks() {
  frame_panel_ = new FramePanel(this);
  auto* frame_dock = new QDockWidget(tr("Frame"), this);
  frame_dock->setObjectName("frameDock");
  frame_dock->setWidget(frame_panel_);
  addDockWidget(Qt::RightDockWidgetArea, frame_dock);
  connect(frame_panel_, &FramePanel::observationChanged, this, [this](size_t track, size_t point) {
    if (!mission_ || track >= mission_->tracks.size() ||
        point >= mission_->tracks[track].points.size())
      return;
    selected_ = {track, point};
    view_->setMarker(mission_->tracks[track].points[point].map);
    selectionChanged();
  });
  connect(frame_panel_, &FramePanel::locateVideoRequested, this, &MainWindow::locateVideo);
  // The frame on screen is the map's time: its footprint and the tracks at that moment.
  connect(frame_panel_, &FramePanel::frameShown, this, [this](int64_t frame, double) {
    if (time_line_->isPlaying()) return;
    time_line_->setFrame(frame);
    view_->setCurrentFrame(frame);
  });

  // The mission's facts and the track filters.
  auto* side = new QWidget(this);
  auto* layout = new QVBoxLayout(side);
  facts_ = new QLabel(side);
  facts_->setObjectName("missionFacts");
  facts_->setTextInteractionFlags(Qt::TextSelectableByMouse);
  facts_->setWordWrap(true);
  facts_->setAlignment(Qt::AlignTop | Qt::AlignLeft);
  layout->addWidget(facts_);

  auto* filters = new QFormLayout();
  const auto spin = [side](const QString& suffix) {
    auto* box = new QDoubleSpinBox(side);
    box->setDecimals(1);
    box->setSuffix(suffix);
    box->setKeyboardTracking(false);
    return box;
  };
  from_s_ = spin(tr(" s"));
  to_s_ = spin(tr(" s"));
  min_speed_ = spin(QString());
  max_speed_ = spin(QString());
  speed_unit_ = new QLabel(side);
  min_confidence_ = spin(QString());
  min_confidence_->setObjectName("minConfidence");
  min_confidence_->setDecimals(2);
  min_confidence_->setRange(0, 1);
  min_confidence_->setSingleStep(0.05);
  min_confidence_->setPrefix(tr("at least "));
  min_confidence_->setToolTip(
      tr("Hide the tracks whose confidence (0 to 1: how long they were seen, how steadily they "
         "moved, feature and change support, a plausible speed) is below this; above 0, tracks "
         "of unknown confidence (older missions) are hidden too"));
  auto* time_row = new QHBoxLayout();
  time_row->addWidget(from_s_);
  time_row->addWidget(new QLabel(tr("to"), side));
  time_row->addWidget(to_s_);
  auto* speed_row = new QHBoxLayout();
  speed_row->addWidget(min_speed_);
  speed_row->addWidget(new QLabel(tr("to"), side));
  speed_row->addWidget(max_speed_);
  speed_row->addWidget(speed_unit_);
  filters->addRow(tr("Time:"), time_row);
  filters->addRow(tr("Speed:"), speed_row);
  filters->addRow(tr("Confidence:"), min_confidence_);
  auto* filter_title = new QLabel(tr("<b>Show tracks</b>"), side);
  layout->addSpacing(8);
  layout->addWidget(filter_title);
  layout->addLayout(filters);
  shown_count_ = new QLabel(side);
  auto* reset = new QPushButton(tr("Show All"), side);
  reset->setToolTip(tr("Clear the time, speed and confidence filters"));
  auto* count_row = new QHBoxLayout();
  count_row->addWidget(shown_count_, 1);
  count_row->addWidget(reset);
  layout->addLayout(count_row);
  layout->addStretch(1);
  for (QDoubleSpinBox* box : {from_s_, to_s_, min_speed_, max_speed_, min_confidence_}) {
    connect(box, &QDoubleSpinBox::valueChanged, this, &MainWindow::applyFilter);
  }
  connect(reset, &QPushButton::clicked, this, &MainWindow::resetFilter);

  auto* mission_dock = new QDockWidget(tr("Mission"), this);
  mission_dock->setObjectName("missionDock");
  mission_dock->setWidget(side);
  addDockWidget(Qt::LeftDockWidgetArea, mission_dock);
  resizeDocks({mission_dock, frame_dock}, {220, 400}, Qt::Horizontal);

  // The track table, under the map.
  undo_ = new QUndoStack(this);
  track_table_ = new TrackTable(this);
  track_table_->setReviews(&reviews_);
  track_table_->setShown([this](size_t track) { return view_->isTrackVisible(track); });
  auto* table_dock = new QDockWidget(tr("Tracks"), this);
  table_dock->setObjectName("trackTableDock");
  table_dock->setWidget(track_table_);
  addDockWidget(Qt::BottomDockWidgetArea, table_dock);
  resizeDocks({table_dock}, {190}, Qt::Vertical);
  connect(track_table_, &TrackTable::trackSelected, this,
          [this](size_t track) { selectTrack(track); });
  connect(track_table_, &TrackTable::trackActivated, this, &MainWindow::showTrack);

  // The bookmarks, in a tab beside the tracks.
  bookmark_list_ = new QListWidget(this);
  bookmark_list_->setObjectName("bookmarkList");
  bookmark_list_->setContextMenuPolicy(Qt::CustomContextMenu);
  auto* bookmark_dock = new QDockWidget(tr("Bookmarks"), this);
  bookmark_dock->setObjectName("bookmarkDock");
  bookmark_dock->setWidget(bookmark_list_);
  tabifyDockWidget(table_dock, bookmark_dock);
  table_dock->raise();
  const auto bookmark_of = [this](const QListWidgetItem* item) -> const mission::Bookmark* {
    if (item == nullptr) return nullptr;
    const int64_t id = item->data(Qt::UserRole).toLongLong();
    for (const mission::Bookmark& b : bookmarks_) {
      if (b.id == id) return &b;
    }
    return nullptr;
  };
  connect(bookmark_list_, &QListWidget::itemActivated, this,
          [this, bookmark_of](QListWidgetItem* item) {
            if (const mission::Bookmark* b = bookmark_of(item)) view_->centreOn(b->map);
          });
  connect(bookmark_list_, &QWidget::customContextMenuRequested, this,
          [this, bookmark_of](const QPoint& at) {
            const mission::Bookmark* b = bookmark_of(bookmark_list_->itemAt(at));
            if (b == nullptr) return;
            const int64_t id = b->id;
            const QString note = FromStd(b->note);
            auto* menu = new QMenu(bookmark_list_);
            menu->setAttribute(Qt::WA_DeleteOnClose);
            menu->addAction(tr("Edit Note…"), this, [this, id, note] {
              bool ok = false;
              const QString text = QInputDialog::getText(this, tr("Bookmark %1").arg(id),
                                                         tr("Note:"), QLineEdit::Normal, note, &ok);
              if (ok) setBookmarkNote(id, text);
            });
            menu->addAction(tr("Delete Bookmark"), this, [this, id] { removeBookmark(id); });
            menu->popup(bookmark_list_->viewport()->mapToGlobal(at));
          });
}

void MainWindow::createActions() {
  QMenu* file = menuBar()->addMenu(tr("&File"));
  QAction* open_video = file->addAction(QIcon::fromTheme("video-x-generic"), tr("Open &Video…"),
                                        this, &MainWindow::chooseVideo);
  open_video->setShortcut(QKeySequence(tr("Ctrl+Shift+O")));
  open_video->setStatusTip(tr("Process a video into a new mission"));
  QAction* open_mission = file->addAction(QIcon::fromTheme("document-open"), tr("&Open Mission…"),
                                          this, &MainWindow::chooseMission);
  open_mission->setShortcut(QKeySequence::Open);
  recent_menu_ = file->addMenu(tr("Open &Recent"));
  file->addSeparator();
  save_as_action_ = file->addAction(QIcon::fromTheme("document-save-as"), tr("Save Mission &As…"),
                                    this, &MainWindow::chooseSaveAs);
  save_as_action_->setShortcut(QKeySequence::SaveAs);
  file->addSeparator();
  export_map_action_ =
      file->addAction(tr("Export Activity &Map…"), this, &MainWindow::chooseActivityMap);
  export_map_action_->setShortcut(QKeySequence(tr("Ctrl+E")));
  export_tracks_action_ = file->addAction(tr("Export &Tracks…"), this, &MainWindow::chooseTracks);
  export_mosaic_action_ =
      file->addAction(tr("Export Mo&saic (GeoTIFF)…"), this, &MainWindow::chooseMosaic);
  export_report_action_ = file->addAction(tr("Export &Report…"), this, [this] {
    const QString path =
        askExportPath(tr("Export Report"), "-report.html", tr("Report (*.html *.pdf)"));
    if (!path.isEmpty()) exportReport(path);
  });
  export_report_action_->setObjectName(QStringLiteral("exportReport"));
  export_report_action_->setStatusTip(
      tr("The mission's facts, the activity map, the tracks shown with a chip of each, your "
         "verdicts and notes, and the bookmarks, as HTML or PDF"));
  file->addSeparator();
  locate_action_ = file->addAction(tr("&Locate Video…"), this, &MainWindow::locateVideo);
  locate_action_->setStatusTip(tr("Tell Saker where this mission's video is now"));
  resume_action_ = file->addAction(QIcon::fromTheme("media-playback-start"),
                                   tr("&Resume Processing"), this, [this] { resumeProcessing(); });
  resume_action_->setObjectName("resumeProcessing");
  resume_action_->setStatusTip(
      tr("Carry this mission's interrupted processing on from its last checkpoint"));
  file->addSeparator();
  QAction* quit =
      file->addAction(QIcon::fromTheme("application-exit"), tr("&Quit"), this, &QWidget::close);
  quit->setShortcut(QKeySequence::Quit);
  quit->setMenuRole(QAction::QuitRole);

  QMenu* edit = menuBar()->addMenu(tr("&Edit"));
  QAction* undo = undo_->createUndoAction(this, tr("&Undo"));
  undo->setShortcut(QKeySequence::Undo);
  undo->setObjectName(QStringLiteral("undo"));
  QAction* redo = undo_->createRedoAction(this, tr("&Redo"));
  redo->setShortcut(QKeySequence::Redo);
  redo->setObjectName(QStringLiteral("redo"));
  edit->addAction(undo);
  edit->addAction(redo);

  QMenu* view = menuBar()->addMenu(tr("&View"));
  QMenu* colour = view->addMenu(tr("&Colour Tracks By"));
  colour_group_ = new QActionGroup(this);
  const std::pair<activity::ColourMode, QString> modes[] = {
      {activity::ColourMode::kSpeed, tr("&Speed")},
      {activity::ColourMode::kDirection, tr("&Direction")},
      {activity::ColourMode::kVisit, tr("&Visit")},
      {activity::ColourMode::kTime, tr("&Time")},
      {activity::ColourMode::kDensity, tr("D&ensity (Heat Map)")}};
  int key = 1;
  for (const auto& [mode, label] : modes) {
    QAction* action = colour->addAction(label);
    action->setCheckable(true);
    action->setData(static_cast<int>(mode));
    action->setShortcut(QKeySequence(QString("Ctrl+%1").arg(key++)));
    action->setObjectName(QString("colourBy_") + activity::ColourModeName(mode));
    colour_group_->addAction(action);
    connect(action, &QAction::triggered, this, [this, mode = mode] { setColourMode(mode); });
  }
  colour_group_->actions().front()->setChecked(true);
  view->addSeparator();
  const auto toggle = [&](const QString& label, const QString& shortcut, bool on,
                          void (MosaicView::*slot)(bool)) {
    QAction* action = view->addAction(label);
    action->setCheckable(true);
    action->setChecked(on);
    action->setShortcut(QKeySequence(shortcut));
    connect(action, &QAction::toggled, view_, slot);
    // std::invoke rather than (view_->*slot)(on): GCC 12's -fsanitize=vptr instruments that
    // call inside this lambda with its type-hash constant as the object address and reports a
    // misaligned MainWindow in every asan run.
    std::invoke(slot, view_, on);
    return action;
  };
  show_tracks_action_ = toggle(tr("Show &Tracks"), tr("Ctrl+T"), true, &MosaicView::setShowTracks);
  show_outlines_action_ = toggle(tr("Show &Key-Frame Outlines"), tr("Ctrl+K"), false,
                                 &MosaicView::setShowKeyFrameOutlines);
  show_ellipses_action_ = toggle(tr("Show &Uncertainty Ellipses"), tr("Ctrl+U"), false,
                                 &MosaicView::setShowUncertainty);
  show_overlay_mask_action_ = view->addAction(tr("Show &Overlay and Sky Masks in Frames"));
  show_overlay_mask_action_->setObjectName(QStringLiteral("showOverlayMask"));
  show_overlay_mask_action_->setCheckable(true);
  show_overlay_mask_action_->setChecked(false);
  connect(show_overlay_mask_action_, &QAction::toggled, frame_panel_,
          &FramePanel::setOverlayMaskVisible);
  QMenu* coordinates = view->addMenu(tr("Coo&rdinates"));
  coordinate_group_ = new QActionGroup(this);
  const std::array<std::pair<geo::CoordinateFormat, QString>, 4> formats = {{
      {geo::CoordinateFormat::kDecimalDegrees, tr("&Decimal Degrees")},
      {geo::CoordinateFormat::kDms, tr("Degrees, Minutes, &Seconds")},
      {geo::CoordinateFormat::kMgrs, tr("&MGRS")},
      {geo::CoordinateFormat::kUtm, tr("&UTM")},
  }};
  for (const auto& [format, name] : formats) {
    QAction* action = coordinates->addAction(name);
    action->setObjectName(QStringLiteral("coordinates-") + geo::CoordinateFormatName(format));
    action->setCheckable(true);
    action->setData(static_cast<int>(format));
    coordinate_group_->addAction(action);
    connect(action, &QAction::triggered, this, [this, f = format] { setCoordinateFormat(f); });
  }
  coordinate_group_->actions().front()->setChecked(true);
  view->addSeparator();
  QAction* zoom_in =
      view->addAction(QIcon::fromTheme("zoom-in"), tr("Zoom &In"), view_, &MosaicView::zoomIn);
  zoom_in->setShortcut(QKeySequence::ZoomIn);
  QAction* zoom_out =
      view->addAction(QIcon::fromTheme("zoom-out"), tr("Zoom &Out"), view_, &MosaicView::zoomOut);
  zoom_out->setShortcut(QKeySequence::ZoomOut);
  QAction* fit = view->addAction(QIcon::fromTheme("zoom-fit-best"), tr("&Fit to Window"), view_,
                                 &MosaicView::fitToWindow);
  fit->setShortcut(QKeySequence(tr("Ctrl+0")));
  view->addSeparator();
  for (QDockWidget* dock : findChildren<QDockWidget*>()) view->addAction(dock->toggleViewAction());

  QMenu* track = menuBar()->addMenu(tr("T&rack"));
  const auto review_action = [&](QMenu* menu, const QString& name, const QString& text,
                                 const QString& shortcut, std::function<void(size_t)> act) {
    QAction* action = menu->addAction(text);
    action->setObjectName(name);
    if (!shortcut.isEmpty()) action->setShortcut(QKeySequence(shortcut));
    connect(action, &QAction::triggered, this, [this, act = std::move(act)] {
      if (const std::optional<size_t> t = selectedTrack()) act(*t);
    });
    review_actions_.push_back(action);
    return action;
  };
  review_action(track, "confirmTrack", tr("&Confirm"), tr("C"), [this](size_t t) {
    setTrackVerdict(t, mission::Verdict::kConfirmed);
  })->setStatusTip(tr("The selected track is a real moving target"));
  review_action(track, "markTrackFalse", tr("Mark &False"), tr("X"),
                [this](size_t t) { setTrackVerdict(t, mission::Verdict::kFalse); })
      ->setStatusTip(tr("The selected track is not a moving target: hide it (Edit > Undo brings "
                        "it back; View > Show False Tracks shows them)"));
  review_action(track, "clearVerdict", tr("C&lear Verdict"), QString(),
                [this](size_t t) { setTrackVerdict(t, mission::Verdict::kNone); });
  QMenu* label = track->addMenu(tr("&Label"));
  const std::array<std::tuple<mission::TargetLabel, QString, QString>, 4> labels = {{
      {mission::TargetLabel::kVehicle, tr("&Vehicle"), tr("V")},
      {mission::TargetLabel::kPerson, tr("&Person"), tr("P")},
      {mission::TargetLabel::kOther, tr("&Other"), tr("O")},
      {mission::TargetLabel::kNone, tr("&None"), QString()},
  }};
  for (const auto& [value, text, letter] : labels) {
    review_action(
        label,
        QStringLiteral("label-") +
            (mission::TargetLabelName(value)[0] != '\0' ? mission::TargetLabelName(value) : "none"),
        text, letter, [this, v = value](size_t t) { setTrackLabel(t, v); });
  }
  review_action(track, "editNote", tr("&Note…"), tr("N"), [this](size_t) { editNote(); });
  track->addSeparator();
  QAction* bookmark = track->addAction(tr("Add &Bookmark…"));
  bookmark->setObjectName(QStringLiteral("addBookmark"));
  bookmark->setShortcut(QKeySequence(tr("Ctrl+B")));
  bookmark->setStatusTip(
      tr("Mark the selected observation's place and time (or the map's centre) with a note"));
  connect(bookmark, &QAction::triggered, this, [this] { chooseBookmark(std::nullopt); });
  track->addSeparator();
  show_false_action_ = track->addAction(tr("Show &False Tracks"));
  show_false_action_->setObjectName(QStringLiteral("showFalseTracks"));
  show_false_action_->setCheckable(true);
  show_false_action_->setStatusTip(tr("Show the tracks marked false too, greyed in the table"));
  connect(show_false_action_, &QAction::toggled, this, [this] { applyFilter(); });

  QMenu* tools_menu = menuBar()->addMenu(tr("&Tools"));
  measure_action_ = tools_menu->addAction(tr("&Measure Distance and Area"));
  measure_action_->setObjectName(QStringLiteral("measure"));
  measure_action_->setIconText(tr("Measure"));
  measure_action_->setCheckable(true);
  measure_action_->setShortcut(QKeySequence(tr("Ctrl+M")));
  measure_action_->setToolTip(
      tr("Click points on the map to measure the path and the area it encloses; Backspace "
         "takes the last point off, Escape clears (Ctrl+M)"));
  connect(measure_action_, &QAction::toggled, view_, &MosaicView::setMeasuring);

  QMenu* help = menuBar()->addMenu(tr("&Help"));
  QAction* guide = help->addAction(tr("Saker &User Guide"), this, &MainWindow::showUserGuide);
  guide->setShortcut(QKeySequence::HelpContents);
  help->addAction(tr("&About Saker"), this, &MainWindow::showAbout)
      ->setMenuRole(QAction::AboutRole);

  QToolBar* tools = addToolBar(tr("Main"));
  tools->setObjectName("mainToolBar");
  tools->addAction(open_video);
  tools->addAction(open_mission);
  tools->addSeparator();
  tools->addWidget(new QLabel(tr(" Colour by: "), tools));
  for (QAction* action : colour_group_->actions()) tools->addAction(action);
  tools->addSeparator();
  tools->addAction(zoom_in);
  tools->addAction(zoom_out);
  tools->addAction(fit);
  tools->addSeparator();
  tools->addAction(measure_action_);
}

void MainWindow::createStatusBar() {
  stage_label_ = new QLabel(this);
  progress_ = new QProgressBar(this);
  progress_->setRange(0, kProgressSteps);
  progress_->setMaximumWidth(220);
  cancel_button_ = new QPushButton(tr("Cancel"), this);
  cancel_button_->setToolTip(tr("Stop processing; the mission keeps the stages that completed"));
  connect(cancel_button_, &QPushButton::clicked, jobs_, &TaskRunner::cancel);
  cursor_label_ = new QLabel(this);
  cursor_label_->setObjectName(QStringLiteral("cursorPosition"));
  cursor_label_->setMinimumWidth(260);
  cursor_label_->setTextInteractionFlags(Qt::TextSelectableByMouse);
  measure_label_ = new QLabel(this);
  measure_label_->setObjectName(QStringLiteral("measurement"));
  statusBar()->addPermanentWidget(measure_label_);
  statusBar()->addWidget(stage_label_);
  statusBar()->addWidget(progress_);
  statusBar()->addWidget(cancel_button_);
  statusBar()->addPermanentWidget(cursor_label_);
  for (QWidget* w : std::initializer_list<QWidget*>{stage_label_, progress_, cancel_button_})
    w->setVisible(false);
}

void MainWindow::readSettings() {
  QSettings settings;
  restoreGeometry(settings.value("window/geometry").toByteArray());
  restoreState(settings.value("window/state").toByteArray());
  recent_ = settings.value("recentFiles").toStringList();
  rebuildRecentMenu();
  const auto mode =
      activity::ParseColourMode(settings.value("view/colourBy", "speed").toString().toStdString());
  setColourMode(mode.value_or(activity::ColourMode::kSpeed));
  show_tracks_action_->setChecked(settings.value("view/showTracks", true).toBool());
  show_outlines_action_->setChecked(settings.value("view/showOutlines", false).toBool());
  show_ellipses_action_->setChecked(settings.value("view/showEllipses", false).toBool());
  show_overlay_mask_action_->setChecked(settings.value("view/showOverlayMask", false).toBool());
  setCoordinateFormat(geo::ParseCoordinateFormat(
                          settings.value("view/coordinates", "decimal").toString().toStdString())
                          .value_or(geo::CoordinateFormat::kDecimalDegrees));
}

void MainWindow::writeSettings() const {
  QSettings settings;
  settings.setValue("window/geometry", saveGeometry());
  settings.setValue("window/state", saveState());
  settings.setValue("recentFiles", recent_);
  settings.setValue("view/colourBy", activity::ColourModeName(view_->colourMode()));
  settings.setValue("view/showTracks", show_tracks_action_->isChecked());
  settings.setValue("view/showOutlines", show_outlines_action_->isChecked());
  settings.setValue("view/showEllipses", show_ellipses_action_->isChecked());
  settings.setValue("view/showOverlayMask", show_overlay_mask_action_->isChecked());
  settings.setValue("view/coordinates", geo::CoordinateFormatName(coordinate_format_));
}

// --------------------------------------------------------------------------------------------
// Opening

void MainWindow::openPath(const QString& path) {
  if (IsMissionPath(path)) {
    openMission(path);
  } else {
    openVideo(path);
  }
}

void MainWindow::openMission(const QString& path) {
  const QString absolute = QFileInfo(path).absoluteFilePath();
  // The mission shown stays until the new one has loaded: one that fails to open leaves it open.
  opening_path_ = absolute;
  statusBar()->showMessage(tr("Opening %1…").arg(QFileInfo(absolute).fileName()));
  updateMissionFacts();
  startLoad(absolute);
}

void MainWindow::forgetMission() {
  mission_.reset();
  mission_path_.clear();
  track_index_.reset();
  selected_.reset();
  reviews_.clear();
  bookmarks_.clear();
  undo_->clear();
  track_table_->setMission(nullptr);
  time_line_->setMission(nullptr);
  rebuildBookmarkList();
  selectionChanged();
  plane_.reset();
  view_->clearPreview();
  view_->setMission(nullptr, QString());
  frame_panel_->setMission(nullptr, QString());
  setWindowTitle(tr("Saker"));
  resetFilter();
  updateMissionFacts();
  updateActions();
}

void MainWindow::reloadMission() {
  if (!mission_path_.isEmpty()) startLoad(mission_path_);
}

void MainWindow::startLoad(const QString& path) {
  if (loader_->isRunning()) {
    pending_load_ = path;
    return;
  }
  auto loaded = std::make_shared<Loaded>();
  loaded->path = path;
  // Where the video may be besides the path recorded in the mission: filled in by the loader
  // once it knows the fingerprint; the settings are read here, on the GUI thread.
  QSettings settings;
  const QStringList keys = [&] {
    settings.beginGroup("videoLocations");
    QStringList k = settings.childKeys();
    settings.endGroup();
    return k;
  }();
  std::map<std::string, QString> remembered;
  for (const QString& k : keys)
    remembered[k.toStdString()] = settings.value("videoLocations/" + k).toString();
  loading_ = loaded;
  loader_->start(tr("Open"), [loaded, remembered](JobContext*) -> Status {
    pipeline::OpenMissionOptions options;
    options.remembered_video = [&remembered](const std::string& fingerprint) {
      const auto it = remembered.find(fingerprint);
      return it == remembered.end() ? std::nullopt
                                    : std::optional<std::string>(it->second.toStdString());
    };
    SAKER_ASSIGN_OR_RETURN(pipeline::OpenedMission opened,
                           pipeline::OpenMission(loaded->path.toStdString(), options));
    loaded->checkpoint = opened.checkpoint;
    loaded->previews = std::move(opened.previews);
    loaded->read_only = opened.read_only;
    const pipeline::VideoLocation& video = opened.video;
    switch (video.state) {
      case pipeline::VideoLocation::State::kFound:
        loaded->video = FromStd(video.path);
        break;
      case pipeline::VideoLocation::State::kChanged:
        loaded->problem = QObject::tr(
                              "The file at %1 is not the video this mission was made "
                              "from (its content differs).")
                              .arg(FromStd(video.path));
        break;
      case pipeline::VideoLocation::State::kMissing:
        loaded->problem = QObject::tr("The video of this mission is not at %1.")
                              .arg(FromStd(opened.mission.source.path));
        break;
    }
    loaded->mission = std::make_shared<const mission::Mission>(std::move(opened.mission));
    return Status();
  });
}

void MainWindow::missionLoaded(const Loaded& loaded) {
  const bool same = loaded.path == mission_path_ && mission_ != nullptr;
  if (loaded.path == opening_path_) opening_path_.clear();
  if (!same) {
    // Another mission: nothing of the one shown carries over.
    selected_.reset();
    view_->setMarker(std::nullopt);
    view_->clearPreview();
    undo_->clear();
  }
  mission_ = loaded.mission;
  // The file's reviews, unless this window's last change did not reach it.
  if (!same || reviews_saved_) {
    reviews_ = mission_->reviews;
    bookmarks_ = mission_->bookmarks;
  }
  if (!same) reviews_saved_ = true;
  mission_path_ = loaded.path;
  video_path_ = loaded.video;
  video_problem_ = loaded.problem;
  checkpoint_frame_.reset();
  checkpoint_complete_ = false;
  if (loaded.checkpoint) {
    checkpoint_frame_ = loaded.checkpoint->through_frame;
    checkpoint_complete_ = loaded.checkpoint->complete;
  }
  track_index_ = std::make_unique<activity::TrackIndex>(&mission_->tracks);
  plane_.reset();
  if (mission_->map.geo_referenced && mission_->map.origin) {
    if (auto plane = geo::LocalTangentPlane::Create(*mission_->map.origin); plane.ok())
      plane_ = std::move(plane).value();
  }
  if (selected_ && (selected_->first >= mission_->tracks.size() ||
                    selected_->second >= mission_->tracks[selected_->first].points.size()))
    selected_.reset();
  if (mission_->progress.mosaic) view_->clearPreview();
  // An interrupted job's key frames stand in for the mosaic it has not made yet.
  if (!mission_->progress.mosaic && !loaded.previews.empty() && !jobs_->isRunning()) {
    view_->clearPreview();
    for (const frontend::KeyFramePreview& preview : loaded.previews) {
      view_->addPreviewKeyFrame(preview);
    }
  }
  view_->setMission(mission_, mission_path_);
  frame_panel_->setMission(mission_, video_path_);
  track_table_->setMission(mission_);
  track_table_->reviewsChanged();
  time_line_->setMission(mission_);
  rebuildBookmarkList();
  const bool sky =
      std::any_of(mission_->frames.begin(), mission_->frames.end(),
                  [](const mission::FrameRecord& f) { return f.sky_line.has_value(); });
  show_overlay_mask_action_->setStatusTip(
      mission_->overlays.empty() && !sky
          ? tr("This mission has no overlay or sky mask: none was found, or it was processed "
               "before Saker kept them")
          : tr("Tint what processing left out in the recalled frame: burned-in text and logos, "
               "and the sky of low oblique views"));
  if (!same) {
    resetFilter();
    addRecent(mission_path_);
  } else {
    // A reload (processing committed a stage): the ranges, unit and boxes follow the mission,
    // the bounds the analyst set stay.
    setFilterRanges(/*keep_bounds=*/true);
  }
  const QString name = QFileInfo(mission_path_).fileName();
  setWindowTitle(loaded.read_only ? tr("%1 (read-only) — Saker").arg(name)
                                  : tr("%1 — Saker").arg(name));
  updateMissionFacts();
  updateActions();
  if (!jobs_->isRunning()) {
    const QString opened =
        tr("Opened %1: %n track(s)", nullptr, static_cast<int>(mission_->tracks.size())).arg(name);
    statusBar()->showMessage(loaded.read_only ? tr("%1 (read-only)").arg(opened) : opened, 5000);
  }
  emit missionOpened(mission_path_);
}

// --------------------------------------------------------------------------------------------
// Processing, exports and copies on the task runner

bool MainWindow::startJob(const QString& title, std::function<Status(JobContext*)> task) {
  if (jobs_->isRunning()) {
    showError(tr("Busy"), tr("%1 is running. Wait for it or cancel it first.").arg(jobs_->title()));
    return false;
  }
  jobs_->start(title, std::move(task));
  stage_label_->setText(title);
  progress_->setValue(0);
  for (QWidget* w : std::initializer_list<QWidget*>{stage_label_, progress_, cancel_button_})
    w->setVisible(true);
  updateActions();
  return true;
}

bool MainWindow::resumeProcessing() {
  if (!mission_ || mission_path_.isEmpty()) return false;
  const mission::Progress& p = mission_->progress;
  if (!p.cancelled && p.tiles && !checkpoint_frame_) {
    statusBar()->showMessage(tr("The mission is complete: nothing to resume"), 8000);
    return false;
  }
  if (video_path_.isEmpty()) {
    showError(tr("Resume Processing"),
              tr("%1\nLocate the video first (File > Locate Video…).").arg(video_problem_));
    return false;
  }
  processVideo(video_path_, mission_path_, /*replace=*/false, /*resume=*/true);
  return true;
}

void MainWindow::processVideo(const QString& video, const QString& mission_path, bool replace,
                              bool resume) {
  if (jobs_->isRunning()) {
    showError(tr("Busy"), tr("%1 is running. Wait for it or cancel it first.").arg(jobs_->title()));
    return;
  }
  // The new mission replaces what is shown; it appears as its stages are committed.
  mission_.reset();
  track_index_.reset();
  selected_.reset();
  reviews_.clear();
  bookmarks_.clear();
  undo_->clear();
  track_table_->setMission(nullptr);
  time_line_->setMission(nullptr);
  rebuildBookmarkList();
  view_->setMission(nullptr, QString());
  view_->clearPreview();
  frame_panel_->clear();
  mission_path_ = QFileInfo(mission_path).absoluteFilePath();
  processing_video_ = video;
  setWindowTitle(tr("%1 — Saker").arg(QFileInfo(mission_path_).fileName()));
  resetFilter();

  checkpoint_frame_.reset();
  pipeline::ProcessOptions options;
  options.replace = replace;
  options.resume = resume;
  options.front_end.checkpoint_interval_s = checkpoint_interval_s_;
  options.saker_version = SAKER_VERSION;
  // A video too long for this machine stops with a message instead of exhausting its memory.
  options.front_end.max_memory_mib = DefaultMemoryLimitMiB();
  // Both callbacks run on the worker; the runner is joined before this window is destroyed.
  options.on_commit = [this](const std::string& stage) {
    if (stage == pipeline::kStageSource || stage == pipeline::kStageCancelled) {
      return;  // nothing to show yet
    }
    mailbox_->post([this] { reloadMission(); });
  };
  options.front_end.on_key_frame = [this](const frontend::KeyFramePreview& preview) {
    mailbox_->post([this, preview] {
      if (!mission_ || !mission_->progress.mosaic) view_->addPreviewKeyFrame(preview);
    });
  };
  const std::string video_path = video.toStdString(), target = mission_path_.toStdString();
  startJob(resume ? tr("Resuming") : tr("Processing"),
           [video_path, target, options](JobContext* job) -> Status {
             return pipeline::ProcessVideo(video_path, target, options, job).status();
           });
  updateMissionFacts();
}

void MainWindow::jobEnded(const QString& title, const Status& status) {
  for (QWidget* w : std::initializer_list<QWidget*>{stage_label_, progress_, cancel_button_})
    w->setVisible(false);
  const bool processing = !processing_video_.isEmpty();
  processing_video_.clear();
  // A completed job has dropped its checkpoint; the reload below shows the rest.
  if (processing && status.ok()) checkpoint_frame_.reset();
  updateActions();
  updateMissionFacts();
  if (status.ok()) {
    statusBar()->showMessage(tr("%1: done").arg(title), 8000);
    if (processing) reloadMission();
  } else if (status.code() == StatusCode::kCancelled) {
    statusBar()->showMessage(processing ? tr("Processing cancelled: the mission keeps the stages "
                                             "that completed and its checkpoint (File > Resume "
                                             "Processing carries on)")
                                        : tr("%1 cancelled").arg(title),
                             10000);
    if (processing) reloadMission();
  } else {
    showError(tr("%1 failed").arg(title), FromStd(status.message()));
    if (processing && QFileInfo::exists(mission_path_)) {
      reloadMission();
    } else if (processing && !mission_) {
      forgetMission();  // no mission was made: not "Processing…" for ever
    }
  }
  emit jobFinished(title, status);
}

void MainWindow::exportFiles(const QString& what, const QString& path, const QString& png,
                             const QString& geotiff, const QString& geojson, const QString& kml,
                             const QString& csv) {
  if (!mission_) return;
  pipeline::ExportRequest request;
  request.png = png.toStdString();
  request.geotiff = geotiff.toStdString();
  request.geojson = geojson.toStdString();
  request.kml = kml.toStdString();
  request.csv = csv.toStdString();
  request.map.colour_by = view_->colourMode();
  // Only the tracks shown: the filters apply to exports as to the view. The mission shown is
  // immutable and already loaded: the worker reads only the tiles.
  const std::string source = mission_path_.toStdString();
  startJob(what, [source, request, shown = shownMission()](JobContext* job) -> Status {
    SAKER_ASSIGN_OR_RETURN(const std::unique_ptr<mission::MissionStore> store,
                           mission::MissionStore::Open(source));
    return pipeline::ExportMission(shown.Make(), *store, request, job).status();
  });
  statusBar()->showMessage(tr("Writing %1…").arg(path));
}

mission::Mission MainWindow::ShownMission::Make() const {
  mission::Mission m = *loaded;
  m.reviews = reviews;
  m.bookmarks = bookmarks;
  std::erase_if(m.tracks, [&](const mission::ActivityTrack& t) { return !ids.count(t.id); });
  return m;
}

MainWindow::ShownMission MainWindow::shownMission() const {
  ShownMission shown{mission_, {}, reviews_, bookmarks_};
  for (size_t i = 0; i < mission_->tracks.size(); ++i) {
    if (view_->isTrackVisible(i)) shown.ids.insert(mission_->tracks[i].id);
  }
  return shown;
}

void MainWindow::exportActivityMap(const QString& path) {
  exportFiles(tr("Export"), path, path, {}, {}, {}, {});
}

void MainWindow::exportTracks(const QString& path) {
  const QString suffix = QFileInfo(path).suffix().toLower();
  if (suffix == "kml") {
    exportFiles(tr("Export"), path, {}, {}, {}, path, {});
  } else if (suffix == "csv") {
    exportFiles(tr("Export"), path, {}, {}, {}, {}, path);
  } else {
    exportFiles(tr("Export"), path, {}, {}, path, {}, {});
  }
}

void MainWindow::exportMosaic(const QString& path) {
  exportFiles(tr("Export"), path, {}, path, {}, {}, {});
}

void MainWindow::exportReport(const QString& path) {
  if (!mission_) return;
  // The tracks shown (the filters apply), with the verdicts as this window has them; false
  // tracks are left out by the report (and hidden here unless shown on purpose).
  report::ReportOptions options;
  options.map.colour_by = view_->colourMode();
  options.video_path = video_path_.toStdString();
  options.chips = !video_path_.isEmpty();
  options.include_false = show_false_action_->isChecked();
  options.saker_version = SAKER_VERSION;
  const bool pdf = QFileInfo(path).suffix().compare("pdf", Qt::CaseInsensitive) == 0;
  startJob(tr("Export"),
           [source = mission_path_.toStdString(), target = path.toStdString(),
            shown = shownMission(), options, pdf](JobContext* job) -> Status {
             SAKER_ASSIGN_OR_RETURN(const std::unique_ptr<mission::MissionStore> store,
                                    mission::MissionStore::Open(source));
             const mission::Mission m = shown.Make();
             SAKER_ASSIGN_OR_RETURN(
                 const report::Report built,
                 report::BuildReport(
                     m, pipeline::StoreTileReader(*store, m.pyramid ? m.pyramid->tile_size : 0),
                     options, job));
             return pdf ? WriteReportPdf(built, target) : report::WriteHtml(built, target);
           });
  statusBar()->showMessage(tr("Writing %1…").arg(path));
}

void MainWindow::saveMissionAs(const QString& path) {
  if (!mission_) return;
  const std::string from = mission_path_.toStdString(), to = path.toStdString();
  startJob(tr("Save As"), [from, to](JobContext* job) {
    return pipeline::CopyMission(from, to, /*replace=*/true, job);
  });
}

// --------------------------------------------------------------------------------------------
// Dialogs

void MainWindow::chooseVideo() {
  QSettings settings;
  const QString video = QFileDialog::getOpenFileName(
      this, tr("Open Video"), settings.value("lastVideoDir").toString(),
      tr("Videos (*.ts *.mpg *.mpeg *.m2ts *.mp4 *.mkv *.mov);;All files (*)"));
  if (!video.isEmpty()) openVideo(video);
}

void MainWindow::openVideo(const QString& path) {
  const QFileInfo info(path);
  if (!info.exists()) {
    showError(tr("Cannot open the video"), tr("%1: no such file").arg(path));
    return;
  }
  QSettings().setValue("lastVideoDir", info.absolutePath());
  // The mission goes beside the video by default; the dialog confirms replacing a file.
  const QString suggestion = info.dir().filePath(info.completeBaseName() + ".saker");
  const QString target = QFileDialog::getSaveFileName(this, tr("Save the Mission As"), suggestion,
                                                      tr("Saker missions (*.saker)"));
  if (target.isEmpty()) return;
  processVideo(path, target, /*replace=*/QFileInfo::exists(target));
}

void MainWindow::chooseMission() {
  QSettings settings;
  const QString path = QFileDialog::getOpenFileName(this, tr("Open Mission"),
                                                    settings.value("lastMissionDir").toString(),
                                                    tr("Saker missions (*.saker);;All files (*)"));
  if (path.isEmpty()) return;
  settings.setValue("lastMissionDir", QFileInfo(path).absolutePath());
  openMission(path);
}

void MainWindow::chooseSaveAs() {
  if (!mission_) return;
  const QString path = QFileDialog::getSaveFileName(this, tr("Save Mission As"), mission_path_,
                                                    tr("Saker missions (*.saker)"));
  if (!path.isEmpty()) saveMissionAs(path);
}

QString MainWindow::askExportPath(const QString& title, const QString& name_suffix,
                                  const QString& filters) {
  if (!mission_) return {};
  const QFileInfo info(mission_path_);
  return QFileDialog::getSaveFileName(
      this, title, info.dir().filePath(info.completeBaseName() + name_suffix), filters);
}

void MainWindow::chooseActivityMap() {
  const QString path = askExportPath(
      tr("Export Activity Map"),
      QStringLiteral("-activity-") + activity::ColourModeName(view_->colourMode()) + ".png",
      tr("PNG pictures (*.png);;JPEG pictures (*.jpg);;TIFF pictures (*.tif)"));
  if (!path.isEmpty()) exportActivityMap(path);
}

void MainWindow::chooseTracks() {
  if (!mission_) return;
  QString filters = tr("GeoJSON (*.geojson);;CSV (*.csv)");
  if (mission_->map.geo_referenced) filters += tr(";;KML (*.kml)");
  const QString path = askExportPath(tr("Export Tracks"), "-tracks.geojson", filters);
  if (!path.isEmpty()) exportTracks(path);
}

void MainWindow::chooseMosaic() {
  const QString path =
      askExportPath(tr("Export Mosaic"), "-mosaic.tif", tr("GeoTIFF (*.tif *.tiff)"));
  if (!path.isEmpty()) exportMosaic(path);
}

void MainWindow::locateVideo() {
  if (!mission_) return;
  const QString path = QFileDialog::getOpenFileName(
      this, tr("Locate the Video of %1").arg(QFileInfo(mission_path_).fileName()),
      QFileInfo(mission_path_).absolutePath(),
      tr("Videos (*.ts *.mpg *.mpeg *.m2ts *.mp4 *.mkv *.mov);;All files (*)"));
  if (path.isEmpty()) return;
  if (!useVideo(path)) {
    const auto answer = QMessageBox::question(
        this, tr("Not the same video"),
        tr("%1 is not the video this mission was made from: its content differs, so recalled "
           "frames would not match the tracks. Use it anyway?")
            .arg(path),
        QMessageBox::Yes | QMessageBox::No, QMessageBox::No);
    if (answer == QMessageBox::Yes) useVideo(path, /*force=*/true);
  }
}

bool MainWindow::useVideo(const QString& path, bool force) {
  if (!mission_) return false;
  const StatusOr<std::string> fingerprint = mission::FingerprintFile(path.toStdString());
  if (!fingerprint.ok()) {
    showError(tr("Cannot use the video"), FromStd(fingerprint.status().message()));
    return false;
  }
  if (*fingerprint != mission_->source.fingerprint && !force) return false;
  if (*fingerprint == mission_->source.fingerprint) {
    QSettings().setValue(SettingsKeyForVideo(mission_->source.fingerprint),
                         QFileInfo(path).absoluteFilePath());
  }
  video_path_ = QFileInfo(path).absoluteFilePath();
  video_problem_.clear();
  frame_panel_->setMission(mission_, video_path_,
                           /*same_video=*/*fingerprint == mission_->source.fingerprint);
  if (selected_) frame_panel_->showObservation(selected_->first, selected_->second);
  updateMissionFacts();
  return true;
}

void MainWindow::showAbout() {
  QMessageBox::about(
      this, tr("About Saker"),
      tr("<h3>Saker %1</h3>"
         "<p>An analyst workstation for airborne video with STANAG 4609 metadata: moving targets "
         "found in the video and placed on a mosaic map of the ground, coloured by speed, "
         "direction, visit or time; click a track to see the original frame.</p>"
         "<p>After <i>Building Aerial Mosaics II</i> (Turkbeyler and Harris, Roke Manor "
         "Research).</p>"
         "<p>Built with Qt %2, OpenCV, Eigen, Ceres Solver, GeographicLib, FFmpeg, GDAL and "
         "SQLite.</p>")
          .arg(SAKER_VERSION, qVersion()));
}

void MainWindow::showUserGuide() {
  auto* dialog = new QDialog(this);
  dialog->setAttribute(Qt::WA_DeleteOnClose);
  dialog->setWindowTitle(tr("Saker User Guide"));
  dialog->resize(820, 760);
  auto* browser = new QTextBrowser(dialog);
  browser->setOpenExternalLinks(true);
  browser->setSearchPaths({":/saker/docs"});
  QFile guide(":/saker/docs/user-guide.md");
  if (guide.open(QIODevice::ReadOnly)) {
    browser->setMarkdown(QString::fromUtf8(guide.readAll()));
  } else {
    browser->setPlainText(tr("The user guide is not in this build."));
  }
  auto* buttons = new QDialogButtonBox(QDialogButtonBox::Close, dialog);
  connect(buttons, &QDialogButtonBox::rejected, dialog, &QDialog::close);
  auto* layout = new QVBoxLayout(dialog);
  layout->addWidget(browser);
  layout->addWidget(buttons);
  dialog->show();
}

void MainWindow::showError(const QString& title, const QString& message) {
  // Window-modal but not blocking: the event loop (and any job) goes on while it is shown.
  auto* box = new QMessageBox(QMessageBox::Warning, title, message, QMessageBox::Ok, this);
  box->setAttribute(Qt::WA_DeleteOnClose);
  box->setObjectName("errorDialog");
  box->open();
}

// --------------------------------------------------------------------------------------------
// The map

bool MainWindow::pickAt(const Eigen::Vector2d& map_point, double tolerance) {
  if (!mission_ || !track_index_) return false;
  const auto pick = track_index_->Nearest(
      map_point, tolerance, [this](size_t track) { return view_->isTrackVisible(track); });
  if (!pick) return false;
  selected_ = {pick->track, pick->point};
  view_->setMarker(mission_->tracks[pick->track].points[pick->point].map);
  selectionChanged();
  if (QDockWidget* dock = qobject_cast<QDockWidget*>(frame_panel_->parentWidget())) dock->show();
  frame_panel_->showObservation(pick->track, pick->point);
  return true;
}

std::vector<MainWindow::Pass> MainWindow::passesSeeing(const Eigen::Vector2d& map_point) const {
  std::vector<Pass> passes;
  if (!mission_) return passes;
  // A gap of more than 2 s between frames that saw the place starts another pass.
  constexpr double kPassGapS = 2;
  std::vector<const mission::FrameRecord*> seeing;
  for (const size_t i : mission::FramesSeeing(*mission_, map_point)) {
    seeing.push_back(&mission_->frames[i]);
  }
  for (size_t k = 0; k < seeing.size(); ++k) {
    if (k == 0 || seeing[k]->time_s - seeing[k - 1]->time_s > kPassGapS) {
      passes.push_back({seeing[k]->index, seeing[k]->index, seeing[k]->time_s, seeing[k]->time_s});
    }
    passes.back().last_frame = seeing[k]->index;
    passes.back().end_s = seeing[k]->time_s;
  }
  return passes;
}

void MainWindow::seekGround(const Eigen::Vector2d& map_point) {
  const std::vector<Pass> passes = passesSeeing(map_point);
  if (passes.empty()) return;
  const auto seek = [this](const Pass& pass) {
    // The middle of the pass: the place well inside the picture.
    const int64_t frame = pass.first_frame + (pass.last_frame - pass.first_frame) / 2;
    time_line_->setFrame(frame);
    view_->setCurrentFrame(frame);
    frame_panel_->showFrame(frame);
  };
  if (passes.size() == 1 || ground_menu_suppressed_) {
    seek(passes.front());
    return;
  }
  auto* menu = new QMenu(this);
  menu->setObjectName(QStringLiteral("passesMenu"));
  menu->setAttribute(Qt::WA_DeleteOnClose);
  menu->addSection(tr("Seen in %1 passes").arg(passes.size()));
  for (const Pass& pass : passes) {
    menu->addAction(tr("%1 to %2 (frames %3-%4)")
                        .arg(pass.start_s, 0, 'f', 1)
                        .arg(pass.end_s, 0, 'f', 1)
                        .arg(pass.first_frame)
                        .arg(pass.last_frame),
                    this, [seek, pass] { seek(pass); });
  }
  menu->popup(QCursor::pos());
}

std::optional<size_t> MainWindow::selectedTrack() const {
  if (!selected_) return std::nullopt;
  return selected_->first;
}

void MainWindow::selectTrack(std::optional<size_t> track_index) {
  if (!mission_ || (track_index && *track_index >= mission_->tracks.size())) {
    track_index.reset();
  }
  if (!track_index) {
    selected_.reset();
  } else if (!selected_ || selected_->first != *track_index) {
    const auto& points = mission_->tracks[*track_index].points;
    selected_ = {*track_index, points.empty() ? 0 : points.size() / 2};
  }
  selectionChanged();
}

void MainWindow::selectionChanged() {
  view_->setSelectedTrack(selectedTrack());
  track_table_->selectTrack(selectedTrack());
  updateActions();
}

void MainWindow::showTrack(size_t track_index) {
  if (!mission_ || track_index >= mission_->tracks.size()) return;
  const mission::ActivityTrack& t = mission_->tracks[track_index];
  if (t.points.empty()) return;
  view_->showTrack(track_index);
  const size_t middle = t.points.size() / 2;
  selected_ = {track_index, middle};
  view_->setMarker(t.points[middle].map);
  selectionChanged();
  if (QDockWidget* dock = qobject_cast<QDockWidget*>(frame_panel_->parentWidget())) dock->show();
  frame_panel_->showObservation(track_index, middle);
}

bool MainWindow::setTrackVerdict(size_t track_index, mission::Verdict verdict) {
  static const char* const kWhat[] = {"Clear the verdict of track %1", "Confirm track %1",
                                      "Mark track %1 false"};
  return changeReview(
      track_index, [verdict](mission::TrackReview* r) { r->verdict = verdict; },
      tr(kWhat[static_cast<int>(verdict)]));
}

bool MainWindow::setTrackLabel(size_t track_index, mission::TargetLabel label) {
  return changeReview(
      track_index, [label](mission::TrackReview* r) { r->label = label; },
      label == mission::TargetLabel::kNone
          ? tr("Clear the label of track %1")
          : tr("Label track %1 %2").arg("%1", FromStd(mission::TargetLabelName(label))));
}

bool MainWindow::setTrackNote(size_t track_index, const QString& note) {
  const std::string text = note.trimmed().toStdString();
  if (text.size() > mission::kMaxNoteBytes) {
    showError(tr("Note too long"), tr("A note holds at most %1 bytes; this one has %2.")
                                       .arg(mission::kMaxNoteBytes)
                                       .arg(text.size()));
    return false;
  }
  return changeReview(
      track_index, [text](mission::TrackReview* r) { r->note = text; },
      tr("Edit the note of track %1"));
}

void MainWindow::editNote() {
  const std::optional<size_t> track = selectedTrack();
  if (!track || !mission_) return;
  const int64_t id = mission_->tracks[*track].id;
  const mission::TrackReview* review = mission::FindReview(reviews_, id);
  bool ok = false;
  const QString note = QInputDialog::getMultiLineText(
      this, tr("Note on Track %1").arg(id), tr("What the analyst says of track %1:").arg(id),
      review ? FromStd(review->note) : QString(), &ok);
  if (ok) setTrackNote(*track, note);
}

bool MainWindow::changeReview(size_t track_index,
                              const std::function<void(mission::TrackReview*)>& change,
                              const QString& what) {
  if (!mission_ || track_index >= mission_->tracks.size()) return false;
  const int64_t id = mission_->tracks[track_index].id;
  mission::TrackReview before{id, mission::Verdict::kNone, mission::TargetLabel::kNone, {}};
  if (const mission::TrackReview* r = mission::FindReview(reviews_, id)) before = *r;
  mission::TrackReview after = before;
  change(&after);
  if (after.verdict == before.verdict && after.label == before.label && after.note == before.note) {
    return true;  // nothing to do
  }
  // QUndoStack::push runs redo() (applyReview) at once.
  undo_->push(new FunctionCommand(
      what.arg(id), [this, after] { applyReview(after); },
      [this, before] { applyReview(before); }));
  return reviews_saved_;
}

void MainWindow::applyReview(const mission::TrackReview& review) {
  const auto it =
      std::lower_bound(reviews_.begin(), reviews_.end(), review.track_id,
                       [](const mission::TrackReview& r, int64_t id) { return r.track_id < id; });
  const bool present = it != reviews_.end() && it->track_id == review.track_id;
  if (review.empty()) {
    if (present) reviews_.erase(it);
  } else if (present) {
    *it = review;
  } else {
    reviews_.insert(it, review);
  }
  reviews_saved_ = saveReviews();
  applyFilter();  // a false track hides (or shows again)
  track_table_->reviewsChanged();
  // A track hidden by its verdict is no longer selected.
  if (selected_ && !view_->isTrackVisible(selected_->first)) {
    selected_.reset();
    view_->setMarker(std::nullopt);
  }
  selectionChanged();
  if (!reviews_saved_) {
    statusBar()->showMessage(
        tr("Track %1: not saved in the mission (see the message)").arg(review.track_id), 8000);
    return;
  }
  QStringList said;
  for (const char* part :
       {mission::VerdictName(review.verdict), mission::TargetLabelName(review.label)}) {
    if (part[0] != '\0') said << QString::fromUtf8(part);
  }
  if (!review.note.empty()) said << tr("a note");
  statusBar()->showMessage(
      tr("Track %1: %2 (Edit > Undo takes it back)")
          .arg(review.track_id)
          .arg(said.isEmpty() ? tr("no verdict, label or note") : said.join(QStringLiteral(", "))),
      8000);
}

int64_t MainWindow::addBookmark(const Eigen::Vector2d& map_point, std::optional<double> time_s,
                                const QString& note) {
  if (!mission_ || !map_point.allFinite()) return 0;
  if (!time_s) {
    const std::vector<size_t> seen = mission::FramesSeeing(*mission_, map_point, 1);
    time_s = seen.empty() ? 0.0 : mission_->frames[seen.front()].time_s;
  }
  const std::string text = note.trimmed().toStdString();
  if (text.size() > mission::kMaxNoteBytes) return 0;
  std::vector<mission::Bookmark> after = bookmarks_;
  const int64_t id = after.empty() ? 1 : after.back().id + 1;
  after.push_back({id, *time_s, map_point, text});
  changeBookmarks(std::move(after), tr("Add bookmark %1").arg(id));
  return id;
}

bool MainWindow::setBookmarkNote(int64_t id, const QString& note) {
  std::vector<mission::Bookmark> after = bookmarks_;
  const std::string text = note.trimmed().toStdString();
  if (text.size() > mission::kMaxNoteBytes) return false;
  for (mission::Bookmark& b : after) {
    if (b.id != id) continue;
    b.note = text;
    return changeBookmarks(std::move(after), tr("Edit bookmark %1").arg(id));
  }
  return false;
}

bool MainWindow::removeBookmark(int64_t id) {
  std::vector<mission::Bookmark> after = bookmarks_;
  const auto removed = std::remove_if(after.begin(), after.end(),
                                      [id](const mission::Bookmark& b) { return b.id == id; });
  if (removed == after.end()) return false;
  after.erase(removed, after.end());
  return changeBookmarks(std::move(after), tr("Delete bookmark %1").arg(id));
}

bool MainWindow::changeBookmarks(std::vector<mission::Bookmark> after, const QString& what) {
  if (!mission_) return false;
  undo_->push(new FunctionCommand(
      what, [this, after] { applyBookmarks(after); },
      [this, before = bookmarks_] { applyBookmarks(before); }));
  return reviews_saved_;
}

void MainWindow::applyBookmarks(const std::vector<mission::Bookmark>& bookmarks) {
  bookmarks_ = bookmarks;
  reviews_saved_ = saveReviews();
  rebuildBookmarkList();
}

void MainWindow::rebuildBookmarkList() {
  bookmark_list_->clear();
  std::vector<std::pair<int64_t, Eigen::Vector2d>> pins;
  for (const mission::Bookmark& b : bookmarks_) {
    const double t = std::max(b.time_s, 0.0);
    const int minutes = static_cast<int>(t / 60);
    auto* item = new QListWidgetItem(tr("%1  ·  %2:%3  ·  %4")
                                         .arg(b.id)
                                         .arg(minutes)
                                         .arg(t - 60.0 * minutes, 4, 'f', 1, QLatin1Char('0'))
                                         .arg(b.note.empty() ? tr("(no note)") : FromStd(b.note)),
                                     bookmark_list_);
    item->setData(Qt::UserRole, static_cast<qlonglong>(b.id));
    item->setToolTip(positionText(b.map));
    pins.emplace_back(b.id, b.map);
  }
  view_->setBookmarks(std::move(pins));
}

void MainWindow::chooseBookmark(std::optional<Eigen::Vector2d> at) {
  if (!mission_) return;
  std::optional<double> time_s;
  if (!at && selected_ && selected_->first < mission_->tracks.size()) {
    const mission::TrackPoint& p = mission_->tracks[selected_->first].points[selected_->second];
    at = p.map;
    time_s = p.time_s;
  }
  if (!at) at = view_->mapFromWidget(QPointF(view_->width() / 2.0, view_->height() / 2.0));
  bool ok = false;
  const QString note = QInputDialog::getText(
      this, tr("Add Bookmark"), tr("Note for the bookmark at %1:").arg(positionText(*at)),
      QLineEdit::Normal, QString(), &ok);
  if (ok) addBookmark(*at, time_s, note);
}

bool MainWindow::saveReviews() {
  if (mission_path_.isEmpty()) return false;
  const std::string path = mission_path_.toStdString();
  Status status = [&]() -> Status {
    SAKER_ASSIGN_OR_RETURN(std::unique_ptr<mission::MissionStore> store,
                           mission::MissionStore::Open(path, mission::OpenMode::kReadWrite));
    mission::Mission reviews;
    reviews.reviews = reviews_;
    reviews.bookmarks = bookmarks_;
    return store->SaveReviews(reviews);
  }();
  if (!status.ok()) {
    showError(tr("Cannot save the verdict"),
              tr("%1\n\nThe change stays in this window (Edit > Undo takes it back) but is not in "
                 "the mission file.")
                  .arg(FromStd(status.message())));
    return false;
  }
  return true;
}

void MainWindow::setColourMode(activity::ColourMode mode) {
  view_->setColourMode(mode);
  for (QAction* action : colour_group_->actions()) {
    if (action->data().toInt() == static_cast<int>(mode)) action->setChecked(true);
  }
}

void MainWindow::resetFilter() { setFilterRanges(/*keep_bounds=*/false); }

void MainWindow::setFilterRanges(bool keep_bounds) {
  double start = 0, end = 0, fastest = 0;
  bool geo = false;
  if (mission_) {
    geo = mission_->map.geo_referenced;
    end = mission_->source.duration_s;
    for (const mission::ActivityTrack& t : mission_->tracks) {
      end = std::max(end, t.end_s);
      fastest = std::max(fastest, geo ? t.speed_mps.value_or(0) : t.speed);
    }
  }
  end = std::max(std::ceil(end), 1.0);
  fastest = std::max(std::ceil(fastest + 0.5), 1.0);
  const QString unit = geo ? tr("m/s") : tr("px/s");
  // A bound at its end of the range is no bound and follows the range; a bound set inside it is
  // kept (within the new range) when asked, speeds only in the same unit.
  const bool same_unit = speed_unit_->text() == unit;
  const auto kept = [keep_bounds](QDoubleSpinBox* box, bool low, bool allowed, double none) {
    const bool set = low ? box->value() > box->minimum() : box->value() < box->maximum();
    return keep_bounds && allowed && set ? box->value() : none;
  };
  const double from = kept(from_s_, true, true, start), to = kept(to_s_, false, true, end);
  const double slowest = kept(min_speed_, true, same_unit, 0);
  const double quickest = kept(max_speed_, false, same_unit, fastest);
  const double least_confidence = kept(min_confidence_, true, true, 0);
  filter_updating_ = true;
  for (QDoubleSpinBox* box : {from_s_, to_s_}) box->setRange(start, end);
  for (QDoubleSpinBox* box : {min_speed_, max_speed_}) box->setRange(0, fastest);
  from_s_->setValue(from);
  to_s_->setValue(to);
  min_speed_->setValue(slowest);
  max_speed_->setValue(quickest);
  min_confidence_->setValue(least_confidence);
  speed_unit_->setText(unit);
  const bool has_tracks = mission_ && !mission_->tracks.empty();
  for (QDoubleSpinBox* box : {from_s_, to_s_, min_speed_, max_speed_, min_confidence_}) {
    box->setEnabled(has_tracks);
  }
  filter_updating_ = false;
  applyFilter();
}

void MainWindow::applyFilter() {
  if (filter_updating_) return;
  MosaicView::TrackFilter filter;
  // A bound at its end of the range is no bound (tracks beyond the rounded range stay shown).
  if (from_s_->value() > from_s_->minimum()) filter.start_s = from_s_->value();
  if (to_s_->value() < to_s_->maximum()) filter.end_s = to_s_->value();
  if (min_speed_->value() > min_speed_->minimum()) filter.min_speed = min_speed_->value();
  if (max_speed_->value() < max_speed_->maximum()) filter.max_speed = max_speed_->value();
  filter.min_confidence = min_confidence_->value();
  if (!show_false_action_->isChecked()) {
    for (const mission::TrackReview& r : reviews_) {
      if (r.verdict == mission::Verdict::kFalse) filter.hidden_ids.insert(r.track_id);
    }
  }
  view_->setTrackFilter(filter);
  track_table_->shownChanged();
  size_t shown = 0, total = mission_ ? mission_->tracks.size() : 0;
  for (size_t i = 0; i < total; ++i) shown += view_->isTrackVisible(i);
  shown_count_->setText(tr("%1 of %2 tracks shown").arg(shown).arg(total));
}

void MainWindow::updateCursor(const std::optional<Eigen::Vector2d>& map_point) {
  cursor_ = map_point;
  cursor_label_->setText(map_point ? positionText(*map_point) : QString());
}

QString MainWindow::positionText(const Eigen::Vector2d& map_point) const {
  if (!mission_) return {};
  if (plane_) {
    return FromStd(geo::FormatPosition(plane_->LatLonFromMap(map_point), coordinate_format_));
  }
  return tr("x %1, y %2 px").arg(map_point.x(), 0, 'f', 0).arg(map_point.y(), 0, 'f', 0);
}

void MainWindow::setCoordinateFormat(geo::CoordinateFormat format) {
  coordinate_format_ = format;
  for (QAction* action : coordinate_group_->actions()) {
    if (action->data().toInt() == static_cast<int>(format)) action->setChecked(true);
  }
  updateCursor(cursor_);
}

QString MainWindow::measureText() const {
  const std::vector<Eigen::Vector2d>& path = view_->measurePath();
  if (path.empty() || !mission_) return {};
  QString length, area;
  if (plane_) {
    std::vector<geo::Wgs84> points;
    for (const Eigen::Vector2d& p : path) points.push_back(plane_->LatLonFromMap(p));
    const geo::GeodesicMeasure m = geo::MeasureGeodesic(points);
    length = FromStd(geo::LengthText(m.length_m));
    if (path.size() >= 3) area = FromStd(geo::AreaText(m.area_m2));
  } else {
    // Not geo-referenced: the map's own units, the first key frame's pixels.
    double sum = 0, twice_area = 0;
    for (size_t i = 0; i < path.size(); ++i) {
      const Eigen::Vector2d& a = path[i];
      const Eigen::Vector2d& b = path[(i + 1) % path.size()];
      if (i + 1 < path.size()) sum += (b - a).norm();
      twice_area += a.x() * b.y() - b.x() * a.y();
    }
    length = tr("%1 px").arg(sum, 0, 'f', 0);
    if (path.size() >= 3) area = tr("%1 px²").arg(std::abs(twice_area) / 2, 0, 'f', 0);
  }
  QString text = tr("Length %1").arg(length);
  if (!area.isEmpty()) text += tr("\nArea %1 (closed)").arg(area);
  return text;
}

void MainWindow::updateMeasure() {
  const QString text = measureText();
  view_->setMeasureText(text);
  measure_label_->setText(QString(text).replace('\n', QStringLiteral(" · ")));
}

QMenu* MainWindow::contextMenuFor(const Eigen::Vector2d& map_point, double tolerance) {
  if (context_menu_ == nullptr) context_menu_ = new QMenu(this);
  context_menu_->clear();
  if (mission_ && track_index_) {
    const auto pick = track_index_->Nearest(
        map_point, tolerance, [this](size_t track) { return view_->isTrackVisible(track); });
    if (pick) {
      const int64_t id = mission_->tracks[pick->track].id;
      QAction* show = context_menu_->addAction(tr("Show Frame of Track %1").arg(id));
      show->setObjectName(QStringLiteral("showTrackFrame"));
      connect(show, &QAction::triggered, this,
              [this, map_point, tolerance] { pickAt(map_point, tolerance); });
      const size_t index = pick->track;
      const bool idle = !jobs_->isRunning();
      QAction* confirm = context_menu_->addAction(tr("Confirm Track %1").arg(id));
      confirm->setObjectName(QStringLiteral("contextConfirm"));
      confirm->setEnabled(idle);
      connect(confirm, &QAction::triggered, this,
              [this, index] { setTrackVerdict(index, mission::Verdict::kConfirmed); });
      QAction* mark_false = context_menu_->addAction(tr("Mark Track %1 False").arg(id));
      mark_false->setObjectName(QStringLiteral("contextMarkFalse"));
      mark_false->setEnabled(idle);
      connect(mark_false, &QAction::triggered, this,
              [this, index] { setTrackVerdict(index, mission::Verdict::kFalse); });
      QAction* note = context_menu_->addAction(tr("Note on Track %1…").arg(id));
      note->setEnabled(idle);
      connect(note, &QAction::triggered, this, [this, index] {
        selectTrack(index);
        editNote();
      });
      context_menu_->addSeparator();
    }
  }
  const QString position = positionText(map_point);
  QAction* copy = context_menu_->addAction(tr("Copy Coordinates (%1)").arg(position));
  copy->setObjectName(QStringLiteral("copyCoordinates"));
  copy->setEnabled(!position.isEmpty());
  connect(copy, &QAction::triggered, this,
          [position] { QGuiApplication::clipboard()->setText(position); });
  QAction* add_bookmark = context_menu_->addAction(tr("Add Bookmark Here…"));
  add_bookmark->setObjectName(QStringLiteral("addBookmarkHere"));
  add_bookmark->setEnabled(mission_ != nullptr && !jobs_->isRunning());
  connect(add_bookmark, &QAction::triggered, this,
          [this, map_point] { chooseBookmark(map_point); });
  QAction* measure = context_menu_->addAction(tr("Measure From Here"));
  measure->setObjectName(QStringLiteral("measureFromHere"));
  measure->setEnabled(mission_ != nullptr);
  connect(measure, &QAction::triggered, this, [this, map_point] {
    measure_action_->setChecked(true);
    view_->setMeasurePath({map_point});
  });
  if (!view_->measurePath().empty()) {
    QAction* clear = context_menu_->addAction(tr("Clear Measurement"));
    clear->setObjectName(QStringLiteral("clearMeasurement"));
    connect(clear, &QAction::triggered, this, [this] { view_->setMeasurePath({}); });
  }
  return context_menu_;
}

// --------------------------------------------------------------------------------------------
// State shown

void MainWindow::updateMissionFacts() {
  // A mission being opened, while another is shown or none.
  const QString opening =
      !opening_path_.isEmpty() && opening_path_ != mission_path_
          ? tr("<p>Opening %1…</p>").arg(QFileInfo(opening_path_).fileName().toHtmlEscaped())
          : QString();
  if (mission_path_.isEmpty()) {
    facts_->setText(opening.isEmpty()
                        ? tr("<p>No mission open.</p><p>Open a mission (File &gt; Open Mission…) "
                             "or process a video (File &gt; Open Video…). You can also drop "
                             "either on the window.</p>")
                        : opening);
    return;
  }
  QString html = tr("<b>%1</b><br>").arg(QFileInfo(mission_path_).fileName().toHtmlEscaped());
  if (!mission_) {
    html += jobs_->isRunning() ? tr("Processing…") : tr("Loading…");
    facts_->setText(html);
    return;
  }
  const mission::Mission& m = *mission_;
  QString state;
  if (jobs_->isRunning() && !processing_video_.isEmpty()) {
    state = tr("processing");
  } else if (m.progress.cancelled) {
    state = tr("cancelled (partial)");
  } else if (m.progress.tiles || (m.progress.activity && !m.pyramid)) {
    state = tr("complete");
  } else {
    state = tr("partial");
  }
  const auto row = [](const QString& key, const QString& value) {
    return QString("<tr><td>%1&nbsp;</td><td>%2</td></tr>").arg(key, value);
  };
  html += "<table>";
  html += row(tr("State"), state);
  html += row(tr("Video"), QFileInfo(FromStd(m.source.path)).fileName().toHtmlEscaped());
  html += row(tr("Frames"), tr("%1 (%2 × %3, %4 fps)")
                                .arg(m.frames.size())
                                .arg(m.source.width)
                                .arg(m.source.height)
                                .arg(m.source.frame_rate, 0, 'f', 2));
  html += row(tr("Duration"), Duration(m.source.duration_s));
  html += row(tr("Key frames"), QString::number(m.key_frames.size()));
  html += row(tr("Tracks"), QString::number(m.tracks.size()));
  html += row(tr("Map"),
              m.map.geo_referenced && m.map.origin
                  ? tr("geo-referenced at %1")
                        .arg(LatLonText(m.map.origin->latitude_deg, m.map.origin->longitude_deg))
                  : QString::fromStdString(pipeline::DescribeMapFrame(m)));
  // What the front end found about the video, in a few words (masks, the low-frame-rate mode,
  // noise, thermal polarity); the sentences `saker-cli process` and `info` print are the tooltip.
  QStringList found, said;
  if (const mission::OverlayExtent overlays = mission::ExtentOf(m.overlays); overlays.frames > 0) {
    found << tr("overlays masked in %1 of %2 frames").arg(overlays.frames).arg(m.frames.size());
  }
  const auto sky = std::count_if(m.frames.begin(), m.frames.end(),
                                 [](const auto& f) { return f.sky_line.has_value(); });
  if (sky > 0) found << tr("sky masked in %1 of %2 frames").arg(sky).arg(m.frames.size());
  if (m.findings) {
    for (const pipeline::Finding& f : pipeline::DescribeFindings(
             *m.findings, static_cast<int64_t>(m.frames.size()), m.source.frame_rate)) {
      found << FromStd(f.brief).toHtmlEscaped();
      said << FromStd(f.sentence);
    }
  }
  if (!found.isEmpty()) html += row(tr("Front end"), found.join(QStringLiteral("<br>")));
  facts_->setToolTip(said.join(QStringLiteral("\n\n")));
  if (checkpoint_frame_ && !jobs_->isRunning()) {
    html += row(tr("Checkpoint"), checkpoint_complete_
                                      ? tr("front end finished")
                                      : tr("front end up to frame %1").arg(*checkpoint_frame_));
  }
  html += "</table>";
  if (state != tr("complete") && state != tr("processing")) {
    html += checkpoint_frame_
                ? tr("<p>Processing stopped before it completed. File &gt; Resume Processing "
                     "carries it on from its checkpoint.</p>")
                : tr("<p>Processing stopped before it completed. File &gt; Resume Processing "
                     "processes the video again into this mission.</p>");
  }
  if (!video_problem_.isEmpty()) {
    html += tr("<p style='color:#c0392b'>%1 Frame recall needs it: File &gt; Locate Video…</p>")
                .arg(video_problem_.toHtmlEscaped());
  }
  facts_->setText(html + opening);
}

void MainWindow::updateActions() {
  const bool has = mission_ != nullptr;
  const bool idle = !jobs_->isRunning();
  save_as_action_->setEnabled(has && idle);
  export_map_action_->setEnabled(has && idle && (!mission_->tracks.empty() || mission_->pyramid));
  export_tracks_action_->setEnabled(has && idle && !mission_->tracks.empty());
  export_mosaic_action_->setEnabled(has && idle && mission_->pyramid.has_value());
  export_report_action_->setEnabled(has && idle);
  locate_action_->setEnabled(has);
  const mission::Progress* p = has ? &mission_->progress : nullptr;
  const bool complete =
      has && !p->cancelled && (p->tiles || (p->activity && !mission_->pyramid.has_value()));
  resume_action_->setEnabled(has && idle && (!complete || checkpoint_frame_) &&
                             !video_path_.isEmpty());
  const bool judge = has && idle && selectedTrack().has_value();
  for (QAction* action : review_actions_) action->setEnabled(judge);
}

void MainWindow::addRecent(const QString& path) {
  recent_.removeAll(path);
  recent_.prepend(path);
  while (recent_.size() > kMaxRecent) recent_.removeLast();
  QSettings().setValue("recentFiles", recent_);
  rebuildRecentMenu();
}

void MainWindow::rebuildRecentMenu() {
  recent_menu_->clear();
  for (int i = 0; i < recent_.size(); ++i) {
    const QString path = recent_[i];
    QAction* action =
        recent_menu_->addAction(tr("&%1 %2").arg(i + 1).arg(QFileInfo(path).fileName()), this,
                                [this, path] { openPath(path); });
    action->setToolTip(path);
    action->setStatusTip(path);
  }
  if (!recent_.isEmpty()) {
    recent_menu_->addSeparator();
    recent_menu_->addAction(tr("&Clear Menu"), this, [this] {
      recent_.clear();
      QSettings().setValue("recentFiles", recent_);
      rebuildRecentMenu();
    });
  }
  recent_menu_->setEnabled(!recent_.isEmpty());
}

// --------------------------------------------------------------------------------------------
// Events

void MainWindow::dragEnterEvent(QDragEnterEvent* event) {
  if (event->mimeData()->hasUrls() && event->mimeData()->urls().front().isLocalFile())
    event->acceptProposedAction();
}

void MainWindow::dropEvent(QDropEvent* event) {
  const QList<QUrl> urls = event->mimeData()->urls();
  if (urls.isEmpty() || !urls.front().isLocalFile()) return;
  event->acceptProposedAction();
  const QString path = urls.front().toLocalFile();
  // Dialogs after the drop has returned: the drag source must not wait on them.
  QMetaObject::invokeMethod(
      this, [this, path] { openPath(path); }, Qt::QueuedConnection);
}

void MainWindow::closeEvent(QCloseEvent* event) {
  if (jobs_->isRunning() && !processing_video_.isEmpty()) {
    const auto answer = QMessageBox::question(
        this, tr("Processing is running"),
        tr("Stop processing and quit? The mission keeps the stages that have completed."),
        QMessageBox::Yes | QMessageBox::No, QMessageBox::No);
    if (answer != QMessageBox::Yes) {
      event->ignore();
      return;
    }
  }
  jobs_->cancelAndWait();
  writeSettings();
  event->accept();
}

}  // namespace saker::ui
