// The main window under QT_QPA_PLATFORM=offscreen, driven as an analyst and an operator would:
// open a mission, switch colour modes, click a track and get its frame, process a video and
// cancel it, export, open a corrupt mission, a mission whose video has gone.

#include "ui/main_window.h"

#include "core/mission/mission_store.h"
#include "tests/testing/test_data.h"
#include "tests/ui/ui_testing.h"
#include "ui/frame_panel.h"
#include "ui/mosaic_view.h"
#include "ui/task_runner.h"
#include "ui/time_line.h"
#include "ui/track_table.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <QAction>
#include <QApplication>
#include <QClipboard>
#include <QDockWidget>
#include <QDoubleSpinBox>
#include <QDragEnterEvent>
#include <QDropEvent>
#include <QElapsedTimer>
#include <QFile>
#include <QFileDialog>
#include <QGuiApplication>
#include <QImage>
#include <QLabel>
#include <QLineEdit>
#include <QListWidget>
#include <QMenu>
#include <QMessageBox>
#include <QMimeData>
#include <QProgressBar>
#include <QPushButton>
#include <QRegularExpression>
#include <QSignalSpy>
#include <QSlider>
#include <QStatusBar>
#include <QTableView>
#include <QTest>
#include <QTextBrowser>
#include <QTimer>
#include <QUndoStack>
#include <QUrl>
#include <QXmlStreamReader>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <memory>
#include <set>

namespace saker::ui {
namespace {

namespace fs = std::filesystem;
using testing::ProcessingWaitMs;
using testing::SmallMission;
using testing::TestMission;
using testing::WaitUntil;

// Opens the small mission and waits until it is shown with its tiles.
bool OpenAndWait(MainWindow& window, const TestMission& m) {
  QSignalSpy opened(&window, &MainWindow::missionOpened);
  window.openMission(QString::fromStdString(m.mission.string()));
  return (opened.count() > 0 || opened.wait(30000)) &&
         WaitUntil([&] { return window.mosaicView()->tilesComplete(); });
}

QAction* ColourAction(MainWindow& window, const char* mode) {
  return window.findChild<QAction*>(QString("colourBy_") + mode);
}

// The Mission panel's filter boxes, in their order: from, to (s), slowest, fastest, least
// confidence.
std::vector<QDoubleSpinBox*> FilterBoxes(MainWindow& window) {
  auto* dock = window.findChild<QDockWidget*>("missionDock");
  if (dock == nullptr) return {};
  const QList<QDoubleSpinBox*> boxes = dock->findChildren<QDoubleSpinBox*>();
  return {boxes.begin(), boxes.end()};
}

// The texts of the Mission panel's labels (to find the speed unit).
QStringList MissionPanelTexts(MainWindow& window) {
  QStringList texts;
  auto* dock = window.findChild<QDockWidget*>("missionDock");
  if (dock == nullptr) return texts;
  for (QLabel* label : dock->findChildren<QLabel*>()) texts << label->text();
  return texts;
}

// After a run that ends in the window: the filters span the mission's tracks, in m/s (the map is
// geo-referenced), and can be used.
void ExpectFiltersFitTheMission(MainWindow& window) {
  const mission::Mission& m = *window.mission();
  ASSERT_TRUE(m.map.geo_referenced);
  ASSERT_FALSE(m.tracks.empty());
  const std::vector<QDoubleSpinBox*> boxes = FilterBoxes(window);
  ASSERT_EQ(boxes.size(), 5u);
  EXPECT_EQ(boxes[4]->objectName(), "minConfidence");
  EXPECT_EQ(boxes[4]->value(), 0);
  double end_s = 0, fastest = 0;
  for (const mission::ActivityTrack& t : m.tracks) {
    end_s = std::max(end_s, t.end_s);
    fastest = std::max(fastest, t.speed_mps.value_or(0));
  }
  for (QDoubleSpinBox* box : boxes) EXPECT_TRUE(box->isEnabled());
  EXPECT_GE(boxes[1]->maximum(), std::floor(end_s));
  EXPECT_GE(boxes[1]->value(), std::floor(end_s));
  EXPECT_GE(boxes[3]->maximum(), fastest);
  EXPECT_GE(boxes[3]->value(), fastest);
  const QStringList texts = MissionPanelTexts(window);
  EXPECT_TRUE(texts.contains("m/s")) << texts.join(" | ").toStdString();
  EXPECT_FALSE(texts.contains("px/s")) << texts.join(" | ").toStdString();
  EXPECT_EQ(window.mosaicView()->legend().title.find("pixels"), std::string::npos);
  for (size_t i = 0; i < m.tracks.size(); ++i) EXPECT_TRUE(window.mosaicView()->isTrackVisible(i));
}

// The confidence filter, set just above the least confident track's confidence, hides that track
// and keeps the others at or above it, in the view and in the count of tracks shown.
void ExpectConfidenceFilterHidesTheLeastConfidentTrack(MainWindow& window) {
  const mission::Mission& m = *window.mission();
  ASSERT_GE(m.tracks.size(), 2u);
  size_t least = 0;
  for (size_t i = 0; i < m.tracks.size(); ++i) {
    ASSERT_TRUE(m.tracks[i].confidence.has_value()) << "track " << i;
    if (*m.tracks[i].confidence < *m.tracks[least].confidence) least = i;
  }
  auto* box = window.findChild<QDoubleSpinBox*>("minConfidence");
  ASSERT_NE(box, nullptr);
  ASSERT_TRUE(box->isEnabled());
  // The box has two decimals: the next step above the least confidence.
  const double threshold = std::floor(*m.tracks[least].confidence * 100 + 1) / 100;
  ASSERT_LE(threshold, 1.0);
  box->setValue(threshold);
  EXPECT_FALSE(window.mosaicView()->isTrackVisible(least));
  size_t shown = 0;
  for (size_t i = 0; i < m.tracks.size(); ++i) {
    EXPECT_EQ(window.mosaicView()->isTrackVisible(i), *m.tracks[i].confidence >= box->value())
        << "track " << i << " of confidence " << *m.tracks[i].confidence;
    shown += window.mosaicView()->isTrackVisible(i);
  }
  EXPECT_TRUE(MissionPanelTexts(window).contains(
      QString("%1 of %2 tracks shown").arg(shown).arg(m.tracks.size())));
  box->setValue(0);
  for (size_t i = 0; i < m.tracks.size(); ++i) EXPECT_TRUE(window.mosaicView()->isTrackVisible(i));
}

// The track with the most observations.
size_t LongestTrack(const mission::Mission& mission) {
  size_t longest = 0;
  for (size_t i = 0; i < mission.tracks.size(); ++i) {
    if (mission.tracks[i].points.size() > mission.tracks[longest].points.size()) longest = i;
  }
  return longest;
}

// Saves `mission`, changed by `change`, as a new mission file at `path` (without tiles).
void SaveChangedCopy(const mission::Mission& mission, const fs::path& path,
                     const std::function<void(mission::Mission&)>& change) {
  auto store = mission::MissionStore::Create(path.string());
  ASSERT_TRUE(store.ok()) << store.status().ToString();
  mission::Mission copy = mission;
  change(copy);
  const Status saved = (*store)->Save(copy);
  ASSERT_TRUE(saved.ok()) << saved.ToString();
}

// Opens a damaged mission file called `name`: missionFailed and an error dialog naming it, which
// is then closed.
void OpenDamagedMission(MainWindow& window, const std::string& name) {
  const fs::path bad = saker::testing::MakeTempDir("saker-ui-corrupt") / name;
  std::ofstream(bad) << "SQLite format 3 but not really; a damaged file\n";
  QSignalSpy failed(&window, &MainWindow::missionFailed);
  window.openMission(QString::fromStdString(bad.string()));
  ASSERT_TRUE(failed.wait(10000));
  EXPECT_TRUE(failed.takeFirst().at(1).toString().contains(QString::fromStdString(name)));
  QMessageBox* box = nullptr;
  ASSERT_TRUE(WaitUntil([&] {
    box = window.findChild<QMessageBox*>("errorDialog");
    return box != nullptr && box->isVisible();
  }));
  EXPECT_TRUE(box->text().contains(QString::fromStdString(name))) << box->text().toStdString();
  box->accept();
}

// Compass words: the 16 points (in capitals, as Saker writes them), and north, east, south, west.
bool HasCompassWords(const QString& text) {
  static const QRegularExpression kPoints(
      "\\b(N|NNE|NE|ENE|E|ESE|SE|SSE|S|SSW|SW|WSW|W|WNW|NW|NNW)\\b");
  static const QRegularExpression kWords("\\b(north|east|south|west)",
                                         QRegularExpression::CaseInsensitiveOption);
  return kPoints.match(text).hasMatch() || kWords.match(text).hasMatch();
}

TEST(MainWindowTest, OpensAMissionAndSwitchesColourModesWithTheirLegends) {
  const TestMission* m = SmallMission();
  ASSERT_NE(m, nullptr);
  MainWindow window;
  window.show();
  ASSERT_TRUE(OpenAndWait(window, *m));
  ASSERT_NE(window.mission(), nullptr);
  EXPECT_EQ(window.mission()->tracks.size(), m->loaded.tracks.size());
  EXPECT_TRUE(window.windowTitle().contains("loop.saker"));
  EXPECT_TRUE(window.recentFiles().contains(window.missionPath()));
  ASSERT_FALSE(m->loaded.tracks.empty());
  ExpectConfidenceFilterHidesTheLeastConfidentTrack(window);

  struct Seen {
    std::string title;
    std::vector<activity::Rgb> colours;
  };
  std::map<std::string, Seen> seen;
  for (const char* mode : {"speed", "direction", "visit", "time"}) {
    QAction* action = ColourAction(window, mode);
    ASSERT_NE(action, nullptr) << mode;
    action->trigger();
    EXPECT_TRUE(action->isChecked());
    EXPECT_EQ(activity::ColourModeName(window.mosaicView()->colourMode()), std::string(mode));
    Seen& s = seen[mode];
    s.title = window.mosaicView()->legend().title;
    for (size_t i = 0; i < m->loaded.tracks.size(); ++i) {
      const auto colour = window.mosaicView()->trackColour(i);
      ASSERT_TRUE(colour.has_value());
      s.colours.push_back(*colour);
    }
  }
  // Each mode has its own legend, and the tracks' colours follow the mode.
  std::set<std::string> titles;
  for (const auto& [mode, s] : seen) titles.insert(s.title);
  EXPECT_EQ(titles.size(), 4u);
  EXPECT_NE(seen["speed"].title.find("speed"), std::string::npos) << seen["speed"].title;
  EXPECT_NE(seen["speed"].colours, seen["direction"].colours);
  EXPECT_NE(seen["speed"].colours, seen["time"].colours);
  // Visit: first-visit tracks red, as in the paper, and the legend says so.
  for (size_t i = 0; i < m->loaded.tracks.size(); ++i) {
    const activity::Rgb c = seen["visit"].colours[i];
    if (m->loaded.tracks[i].visit == 1) {
      EXPECT_TRUE(c.r > 150 && c.g < 100 && c.b < 100);
    } else if (m->loaded.tracks[i].visit == 2) {
      EXPECT_TRUE(c.b > 150 && c.r < 100);
    }
  }
  // The choice persists: a new window starts in the last mode.
  window.close();
  MainWindow again;
  EXPECT_EQ(again.mosaicView()->colourMode(), activity::ColourMode::kTime);
}

TEST(MainWindowTest, ClickOnATrackRecallsTheFrameWithTheObjectMarkedWhereTheTruthHasIt) {
  const TestMission* m = SmallMission();
  ASSERT_NE(m, nullptr);
  MainWindow window;
  window.resize(1400, 900);
  window.show();
  ASSERT_TRUE(OpenAndWait(window, *m));
  const mission::Mission& mission = *window.mission();
  const sim::Truth& truth = m->truth_data;

  // An observation in the middle of a long track whose truth target is right under it.
  struct Candidate {
    size_t track = 0;
    int target = -1;
    int64_t frame = 0;
    size_t points = 0;
  } best;
  for (size_t t = 0; t < mission.tracks.size(); ++t) {
    const auto& points = mission.tracks[t].points;
    const mission::TrackPoint& middle = points[points.size() / 2];
    for (size_t k = 0; k < truth.targets.size(); ++k) {
      const sim::TargetSampleTruth& s = truth.targets[k].samples[static_cast<size_t>(middle.frame)];
      if (s.visible && (s.image_px - middle.image).norm() < 6 && points.size() > best.points)
        best = {t, static_cast<int>(k), middle.frame, points.size()};
    }
  }
  ASSERT_GE(best.target, 0) << "no track follows a truth target";
  const mission::FrameRecord& frame = mission.frames[static_cast<size_t>(best.frame)];
  ASSERT_TRUE(frame.map_from_frame.has_value());
  const sim::TargetSampleTruth& truth_at =
      truth.targets[static_cast<size_t>(best.target)].samples[static_cast<size_t>(best.frame)];
  const Eigen::Vector2d at =
      (*frame.map_from_frame * truth_at.image_px.homogeneous()).hnormalized();

  // Like an analyst: the tracks seen around that moment, zoomed in on the place, then a click.
  const double time_s = frame.time_s;
  MosaicView* view = window.mosaicView();
  view->setTrackFilter({time_s - 0.5, time_s + 0.5, std::nullopt, std::nullopt, 0, {}});
  view->fitToWindow();
  view->zoomAt(4, view->widgetFromMap(at));
  const QPointF click = view->widgetFromMap(at);
  ASSERT_TRUE(view->rect().contains(click.toPoint()));
  FramePanel* panel = window.framePanel();
  QSignalSpy shown(panel, &FramePanel::frameShown);
  QTest::mouseClick(view, Qt::LeftButton, Qt::NoModifier, click.toPoint());
  ASSERT_TRUE(shown.wait(10000)) << "no frame recalled";
  const int64_t displayed = panel->displayedFrame();
  std::cout << "clicked at frame " << best.frame << " (target " << best.target
            << "), recalled frame " << displayed << " in " << panel->lastRecallMs() << " ms\n";

  // The red cross on the map, the frame of that moment, the object marked where the truth is.
  ASSERT_TRUE(view->marker().has_value());
  EXPECT_LT((*view->marker() - at).norm(), 8 / view->pixelsPerMapUnit() + 1e-9);
  EXPECT_LE(std::abs(displayed - best.frame), int64_t(0.5 * truth.fps));
  ASSERT_TRUE(panel->markVisible());
  const QPointF mark = panel->markImagePosition();
  const Eigen::Vector2d truth_px = truth.targets[static_cast<size_t>(best.target)]
                                       .samples[static_cast<size_t>(displayed)]
                                       .image_px;
  EXPECT_LT((Eigen::Vector2d(mark.x(), mark.y()) - truth_px).norm(), 12.0)
      << "mark at " << mark.x() << "," << mark.y() << ", truth at " << truth_px.transpose();

  // A click far from every track clears the cross and leaves the frame.
  view->setTrackFilter({});
  QTest::mouseClick(view, Qt::LeftButton, Qt::NoModifier, QPoint(2, 2));
  EXPECT_FALSE(view->marker().has_value());
  EXPECT_EQ(panel->displayedFrame(), displayed);
}

// View > Show Overlay and Sky Masks in Frames: off by default, it turns the frame panel's layer on
// and off, and its status tip says whether the mission has masks at all.
TEST(MainWindowTest, TheOverlayMaskLayerIsOffByDefaultAndTheViewMenuTogglesIt) {
  const TestMission* m = SmallMission();
  ASSERT_NE(m, nullptr);
  MainWindow window;
  window.show();
  ASSERT_TRUE(OpenAndWait(window, *m));
  QAction* action = window.findChild<QAction*>("showOverlayMask");
  ASSERT_NE(action, nullptr);
  EXPECT_TRUE(action->isCheckable());
  EXPECT_FALSE(action->isChecked());
  EXPECT_FALSE(window.framePanel()->overlayMaskVisible());
  EXPECT_EQ(action->statusTip().contains("no overlay or sky mask"), m->loaded.overlays.empty())
      << action->statusTip().toStdString();
  action->trigger();
  EXPECT_TRUE(window.framePanel()->overlayMaskVisible());
  action->trigger();
  EXPECT_FALSE(window.framePanel()->overlayMaskVisible());
}

TEST(MainWindowTest, DropOpensAMissionAndTheStatusBarShowsWhereTheCursorIs) {
  const TestMission* m = SmallMission();
  ASSERT_NE(m, nullptr);
  MainWindow window;
  window.show();
  QSignalSpy opened(&window, &MainWindow::missionOpened);
  QMimeData data;
  data.setUrls({QUrl::fromLocalFile(QString::fromStdString(m->mission.string()))});
  QDragEnterEvent enter(QPoint(50, 50), Qt::CopyAction, &data, Qt::LeftButton, Qt::NoModifier);
  QApplication::sendEvent(&window, &enter);
  EXPECT_TRUE(enter.isAccepted());
  QDropEvent drop(QPointF(50, 50), Qt::CopyAction, &data, Qt::LeftButton, Qt::NoModifier);
  QApplication::sendEvent(&window, &drop);
  ASSERT_TRUE(opened.wait(30000));
  EXPECT_EQ(window.missionPath().toStdString(), fs::absolute(m->mission).string());

  // The cursor over the map: latitude and longitude of the mission's geo-referenced map.
  MosaicView* view = window.mosaicView();
  const QPoint centre = view->rect().center();
  QTest::mouseMove(view, centre);
  ASSERT_TRUE(WaitUntil(
      [&] {
        for (QLabel* label : window.statusBar()->findChildren<QLabel*>()) {
          if (label->text().contains("° N") || label->text().contains("° S")) return true;
        }
        return false;
      },
      3000))
      << "no coordinates in the status bar";
}

// View > Coordinates changes how the status bar writes the cursor's position (and is
// remembered); Tools > Measure turns clicks into a measured path, on the ellipsoid, that
// Backspace shortens and Escape clears; the map's context menu recalls a track, copies the
// position and starts a measurement.
TEST(MainWindowTest, CoordinateFormatsMeasuringAndTheContextMenu) {
  const TestMission* m = SmallMission();
  ASSERT_NE(m, nullptr);
  auto window = std::make_unique<MainWindow>();
  window->resize(1200, 800);
  window->show();
  ASSERT_TRUE(OpenAndWait(*window, *m));
  MosaicView* view = window->mosaicView();
  auto* cursor = window->findChild<QLabel*>("cursorPosition");
  ASSERT_NE(cursor, nullptr);
  const QPoint centre = view->rect().center();
  const Eigen::Vector2d at = view->mapFromWidget(centre);
  QTest::mouseMove(view, centre);
  ASSERT_TRUE(WaitUntil([&] { return !cursor->text().isEmpty(); }, 3000));
  EXPECT_TRUE(QRegularExpression(R"(^\d+\.\d{5}° [NS], \d+\.\d{5}° [EW]$)")
                  .match(cursor->text())
                  .hasMatch())
      << cursor->text().toStdString();
  auto* mgrs = window->findChild<QAction*>("coordinates-mgrs");
  ASSERT_NE(mgrs, nullptr);
  mgrs->trigger();
  EXPECT_EQ(window->coordinateFormat(), geo::CoordinateFormat::kMgrs);
  EXPECT_EQ(cursor->text(), window->positionText(at));
  EXPECT_TRUE(
      QRegularExpression(R"(^\d{1,2}[C-X] [A-Z]{2} \d{5} \d{5}$)").match(cursor->text()).hasMatch())
      << cursor->text().toStdString();
  window->findChild<QAction*>("coordinates-dms")->trigger();
  EXPECT_TRUE(cursor->text().contains("′")) << cursor->text().toStdString();
  window->findChild<QAction*>("coordinates-utm")->trigger();

  // Measuring: three clicks make a closed path; the figures are those of the map's metres (a
  // local tangent plane, within 0.5 % of the ellipsoid over a few hundred metres).
  auto* measure = window->findChild<QAction*>("measure");
  ASSERT_NE(measure, nullptr);
  measure->trigger();
  ASSERT_TRUE(view->measuring());
  const std::vector<QPoint> clicks = {centre + QPoint(-150, -100), centre + QPoint(150, -100),
                                      centre + QPoint(150, 100)};
  for (const QPoint& p : clicks) QTest::mouseClick(view, Qt::LeftButton, Qt::NoModifier, p);
  ASSERT_EQ(view->measurePath().size(), 3u);
  EXPECT_FALSE(view->marker().has_value()) << "a click while measuring picks nothing";
  const double side_a = (view->measurePath()[1] - view->measurePath()[0]).norm();
  const double side_b = (view->measurePath()[2] - view->measurePath()[1]).norm();
  const QString text = window->measureText();
  const QRegularExpressionMatch length = QRegularExpression(R"(Length ([\d.]+) (k?m))").match(text);
  ASSERT_TRUE(length.hasMatch()) << text.toStdString();
  const double metres = length.captured(1).toDouble() * (length.captured(2) == "km" ? 1000 : 1);
  EXPECT_NEAR(metres, side_a + side_b, 0.005 * (side_a + side_b) + 1) << text.toStdString();
  const QRegularExpressionMatch area =
      QRegularExpression(R"(Area ([\d.]+) (m²|ha|km²))").match(text);
  ASSERT_TRUE(area.hasMatch()) << text.toStdString();
  const double unit = area.captured(2) == "ha" ? 1e4 : area.captured(2) == "km²" ? 1e6 : 1;
  EXPECT_NEAR(area.captured(1).toDouble() * unit, side_a * side_b / 2,
              0.01 * side_a * side_b / 2 + 1)
      << text.toStdString();
  auto* status = window->findChild<QLabel*>("measurement");
  ASSERT_NE(status, nullptr);
  EXPECT_TRUE(status->text().startsWith("Length")) << status->text().toStdString();
  QTest::keyClick(view, Qt::Key_Backspace);
  EXPECT_EQ(view->measurePath().size(), 2u);
  EXPECT_FALSE(window->measureText().contains("Area"));
  QTest::keyClick(view, Qt::Key_Escape);
  EXPECT_TRUE(view->measurePath().empty());
  EXPECT_TRUE(status->text().isEmpty());
  measure->trigger();
  EXPECT_FALSE(view->measuring());

  // The context menu: on a track, its frame; anywhere, the position and a measurement.
  const mission::ActivityTrack& track = window->mission()->tracks.front();
  const Eigen::Vector2d on_track = track.points[track.points.size() / 2].map;
  QMenu* menu = window->contextMenuFor(on_track, 1.0);
  auto* show = menu->findChild<QAction*>("showTrackFrame");
  ASSERT_NE(show, nullptr);
  QSignalSpy shown(window->framePanel(), &FramePanel::frameShown);
  show->trigger();
  EXPECT_TRUE(view->marker().has_value());
  EXPECT_TRUE(shown.count() > 0 || shown.wait(10000));
  const Eigen::Vector2d far_away = on_track + Eigen::Vector2d(1e6, 1e6);
  menu = window->contextMenuFor(far_away, 1.0);
  EXPECT_EQ(menu->findChild<QAction*>("showTrackFrame"), nullptr);
  menu->findChild<QAction*>("copyCoordinates")->trigger();
  EXPECT_EQ(QGuiApplication::clipboard()->text(), window->positionText(far_away));
  EXPECT_TRUE(window->positionText(far_away).contains(" E ")) << "UTM";
  menu = window->contextMenuFor(on_track, 1.0);
  menu->findChild<QAction*>("measureFromHere")->trigger();
  EXPECT_TRUE(view->measuring());
  ASSERT_EQ(view->measurePath().size(), 1u);
  EXPECT_EQ(
      window->contextMenuFor(on_track, 1.0)->findChild<QAction*>("clearMeasurement") != nullptr,
      true);

  // The coordinate format is remembered.
  window->close();
  window.reset();
  MainWindow again;
  EXPECT_EQ(again.coordinateFormat(), geo::CoordinateFormat::kUtm);
  again.setCoordinateFormat(geo::CoordinateFormat::kDecimalDegrees);
  again.close();
}

// The analyst's judgement: the track table lists the shown tracks and follows the selection both
// ways; marking a track false hides it (map, table, exports), is saved in the mission at once
// and undone by Edit > Undo; labels and notes are saved and filterable; a verdict that cannot be
// saved says so and stays in the window.
TEST(MainWindowTest, TheAnalystJudgesTracksAndTheTrackTableFollows) {
  const TestMission* m = SmallMission();
  ASSERT_NE(m, nullptr);
  ASSERT_GE(m->loaded.tracks.size(), 3u);
  const fs::path dir = saker::testing::MakeTempDir("saker-ui-reviews");
  const fs::path path = dir / "reviews.saker";
  ASSERT_NO_FATAL_FAILURE(SaveChangedCopy(m->loaded, path, [](mission::Mission&) {}));
  const auto saved_reviews = [&] {
    auto store = mission::MissionStore::Open(path.string());
    EXPECT_TRUE(store.ok());
    auto loaded = (*store)->Load();
    EXPECT_TRUE(loaded.ok());
    return loaded.ok() ? loaded->reviews : std::vector<mission::TrackReview>{};
  };
  auto window = std::make_unique<MainWindow>();
  window->resize(1300, 900);
  window->show();
  QSignalSpy opened(window.get(), &MainWindow::missionOpened);
  window->openMission(QString::fromStdString(path.string()));
  ASSERT_TRUE(opened.wait(30000));
  const auto& tracks = window->mission()->tracks;
  TrackTable* table = window->trackTable();
  ASSERT_NE(table, nullptr);
  EXPECT_EQ(table->rowsShown(), static_cast<int>(tracks.size()));

  // Sorted by speed, fastest first; a click on a row selects its track on the map.
  table->view()->sortByColumn(TrackTableModel::kSpeed, Qt::DescendingOrder);
  const std::optional<size_t> fastest = table->trackAtRow(0);
  ASSERT_TRUE(fastest.has_value());
  for (const auto& t : tracks) {
    EXPECT_LE(t.speed_mps.value_or(t.speed), tracks[*fastest].speed_mps.value_or(0) + 1e-9);
  }
  const QRect first_row = table->view()->visualRect(table->filterModel()->index(0, 0));
  QTest::mouseClick(table->view()->viewport(), Qt::LeftButton, Qt::NoModifier, first_row.center());
  EXPECT_EQ(window->selectedTrack(), fastest);
  EXPECT_EQ(window->mosaicView()->selectedTrack(), fastest);
  // ...and a pick on the map selects the row.
  const size_t picked = *fastest == 0 ? 1 : 0;
  ASSERT_TRUE(window->pickAt(tracks[picked].points.front().map, 1e-6));
  EXPECT_EQ(window->selectedTrack(), picked);
  const QModelIndex current = table->view()->currentIndex();
  ASSERT_TRUE(current.isValid());
  EXPECT_EQ(table->filterModel()->mapToSource(current).row(), static_cast<int>(picked));

  // Mark it false: hidden everywhere, saved, undoable.
  auto* mark_false = window->findChild<QAction*>("markTrackFalse");
  ASSERT_NE(mark_false, nullptr);
  ASSERT_TRUE(mark_false->isEnabled());
  mark_false->trigger();
  EXPECT_FALSE(window->mosaicView()->isTrackVisible(picked));
  EXPECT_EQ(table->rowsShown(), static_cast<int>(tracks.size()) - 1);
  EXPECT_FALSE(window->selectedTrack().has_value());
  EXPECT_FALSE(mark_false->isEnabled()) << "nothing selected any more";
  std::vector<mission::TrackReview> saved = saved_reviews();
  ASSERT_EQ(saved.size(), 1u);
  EXPECT_EQ(saved[0].track_id, tracks[picked].id);
  EXPECT_EQ(saved[0].verdict, mission::Verdict::kFalse);
  window->undoStack()->undo();
  EXPECT_TRUE(window->mosaicView()->isTrackVisible(picked));
  EXPECT_TRUE(saved_reviews().empty());
  window->undoStack()->redo();
  EXPECT_FALSE(window->mosaicView()->isTrackVisible(picked));
  // Show False Tracks brings it back to the map and the table (greyed there).
  auto* show_false = window->findChild<QAction*>("showFalseTracks");
  ASSERT_NE(show_false, nullptr);
  show_false->trigger();
  EXPECT_TRUE(window->mosaicView()->isTrackVisible(picked));
  EXPECT_EQ(table->rowsShown(), static_cast<int>(tracks.size()));
  show_false->trigger();

  // A label and a note on another track, from the menu and the API; the table filters on them.
  const size_t other = picked == 1 ? 2 : 1;
  window->selectTrack(other);
  window->findChild<QAction*>("label-vehicle")->trigger();
  ASSERT_TRUE(window->setTrackNote(other, "  stops at the gate\nthen turns  "));
  window->findChild<QAction*>("confirmTrack")->trigger();
  saved = saved_reviews();
  ASSERT_EQ(saved.size(), 2u);
  const mission::TrackReview& judged = saved[saved[0].track_id == tracks[other].id ? 0 : 1];
  EXPECT_EQ(judged.track_id, tracks[other].id);
  EXPECT_EQ(judged.verdict, mission::Verdict::kConfirmed);
  EXPECT_EQ(judged.label, mission::TargetLabel::kVehicle);
  EXPECT_EQ(judged.note, "stops at the gate\nthen turns");
  QTest::keyClicks(table->filterEdit(), "GATE");
  ASSERT_EQ(table->rowsShown(), 1);
  EXPECT_EQ(table->trackAtRow(0), other);
  const QModelIndex note = table->filterModel()->index(0, TrackTableModel::kNote);
  EXPECT_EQ(note.data().toString(), "stops at the gate");
  EXPECT_EQ(table->filterModel()->index(0, TrackTableModel::kVerdict).data().toString(),
            "Confirmed");
  table->filterEdit()->clear();

  // Double-click (activate) a row: the track is shown and its frame recalled.
  QSignalSpy shown(window->framePanel(), &FramePanel::frameShown);
  emit table->view()->activated(table->filterModel()->mapFromSource(
      table->filterModel()->sourceModel()->index(static_cast<int>(other), 0)));
  EXPECT_EQ(window->selectedTrack(), other);
  EXPECT_TRUE(window->mosaicView()->marker().has_value());
  EXPECT_TRUE(shown.count() > 0 || shown.wait(10000));

  // The exports carry the verdicts and leave the false track out.
  const fs::path geojson = dir / "tracks.geojson";
  QSignalSpy finished(window.get(), &MainWindow::jobFinished);
  window->exportTracks(QString::fromStdString(geojson.string()));
  ASSERT_TRUE(finished.wait(30000));
  const nlohmann::json j = nlohmann::json::parse(std::ifstream(geojson), nullptr, false);
  ASSERT_FALSE(j.is_discarded());
  EXPECT_EQ(j["features"].size(), tracks.size() - 1);
  bool found = false;
  for (const auto& feature : j["features"]) {
    EXPECT_NE(feature["id"], tracks[picked].id);
    if (feature["id"] == tracks[other].id) {
      found = true;
      EXPECT_EQ(feature["properties"]["verdict"], "confirmed");
      EXPECT_EQ(feature["properties"]["label"], "vehicle");
    }
  }
  EXPECT_TRUE(found);

  // While another writer holds the mission, a verdict is not saved: a message says so, and the
  // window keeps it.
  {
    auto writer = mission::MissionStore::Open(path.string(), mission::OpenMode::kReadWrite);
    ASSERT_TRUE(writer.ok()) << writer.status().ToString();
    EXPECT_FALSE(window->setTrackVerdict(other, mission::Verdict::kNone));
    QMessageBox* box = nullptr;
    ASSERT_TRUE(WaitUntil([&] {
      box = window->findChild<QMessageBox*>("errorDialog");
      return box != nullptr;
    }));
    EXPECT_TRUE(box->text().contains("not in the mission file")) << box->text().toStdString();
    box->close();
  }
  EXPECT_EQ(saved_reviews().size(), 2u);

  // A new window on the file reads the verdicts back.
  window.reset();
  MainWindow again;
  QSignalSpy reopened(&again, &MainWindow::missionOpened);
  again.openMission(QString::fromStdString(path.string()));
  ASSERT_TRUE(reopened.wait(30000));
  EXPECT_EQ(again.reviews().size(), 2u);
  EXPECT_FALSE(again.mosaicView()->isTrackVisible(picked));
}

// Bookmarks: made at a place (the time of the first frame that saw it), listed, noted, undone,
// deleted, saved in the mission and exported.
TEST(MainWindowTest, BookmarksAreListedSavedUndoneAndExported) {
  const TestMission* m = SmallMission();
  ASSERT_NE(m, nullptr);
  const fs::path dir = saker::testing::MakeTempDir("saker-ui-bookmarks");
  const fs::path path = dir / "bookmarks.saker";
  ASSERT_NO_FATAL_FAILURE(SaveChangedCopy(m->loaded, path, [](mission::Mission&) {}));
  const auto saved = [&] {
    auto store = mission::MissionStore::Open(path.string());
    EXPECT_TRUE(store.ok());
    auto loaded = (*store)->Load();
    EXPECT_TRUE(loaded.ok());
    return loaded.ok() ? loaded->bookmarks : std::vector<mission::Bookmark>{};
  };
  MainWindow window;
  window.show();
  QSignalSpy opened(&window, &MainWindow::missionOpened);
  window.openMission(QString::fromStdString(path.string()));
  ASSERT_TRUE(opened.wait(30000));
  auto* list = window.findChild<QListWidget*>("bookmarkList");
  ASSERT_NE(list, nullptr);
  EXPECT_EQ(list->count(), 0);

  // At a track's place: the time is that of the first frame whose picture saw it.
  const mission::Mission& mission = *window.mission();
  const Eigen::Vector2d place = mission.tracks.front().points.back().map;
  const std::vector<size_t> seen = mission::FramesSeeing(mission, place, 1);
  ASSERT_FALSE(seen.empty());
  EXPECT_EQ(window.addBookmark(place, std::nullopt, "  the gate  "), 1);
  EXPECT_EQ(window.addBookmark(place + Eigen::Vector2d(5, 5), 12.5, ""), 2);
  std::vector<mission::Bookmark> file = saved();
  ASSERT_EQ(file.size(), 2u);
  EXPECT_EQ(file[0].note, "the gate");
  EXPECT_DOUBLE_EQ(file[0].time_s, mission.frames[seen.front()].time_s);
  EXPECT_DOUBLE_EQ(file[1].time_s, 12.5);
  ASSERT_EQ(list->count(), 2);
  EXPECT_TRUE(list->item(0)->text().contains("the gate")) << list->item(0)->text().toStdString();
  EXPECT_TRUE(list->item(1)->text().contains("0:12.5")) << list->item(1)->text().toStdString();

  ASSERT_TRUE(window.setBookmarkNote(2, "parking"));
  EXPECT_EQ(saved()[1].note, "parking");
  window.undoStack()->undo();
  EXPECT_EQ(saved()[1].note, "");
  ASSERT_TRUE(window.removeBookmark(1));
  EXPECT_EQ(list->count(), 1);
  EXPECT_EQ(saved().size(), 1u);
  window.undoStack()->undo();
  EXPECT_EQ(saved().size(), 2u);
  EXPECT_FALSE(window.removeBookmark(99));

  // Activating a bookmark centres the map on it.
  emit list->itemActivated(list->item(1));
  const Eigen::Vector2d centre = window.mosaicView()->mapFromWidget(
      QPointF(window.mosaicView()->width() / 2.0, window.mosaicView()->height() / 2.0));
  EXPECT_LT((centre - file[1].map).norm(), 1e-6 + 1 / window.mosaicView()->pixelsPerMapUnit());

  // Exported as points with their notes.
  const fs::path geojson = dir / "bookmarks.geojson";
  QSignalSpy finished(&window, &MainWindow::jobFinished);
  window.exportTracks(QString::fromStdString(geojson.string()));
  ASSERT_TRUE(finished.wait(30000));
  const nlohmann::json j = nlohmann::json::parse(std::ifstream(geojson), nullptr, false);
  ASSERT_FALSE(j.is_discarded());
  int points = 0;
  for (const auto& feature : j["features"]) {
    if (feature["properties"].contains("bookmark")) {
      ++points;
      EXPECT_EQ(feature["geometry"]["type"], "Point");
    }
  }
  EXPECT_EQ(points, 2);

  // File > Export Report: the bookmarks and the tracks shown, one HTML file.
  const fs::path report = dir / "report.html";
  window.exportReport(QString::fromStdString(report.string()));
  ASSERT_TRUE(finished.wait(60000));
  EXPECT_TRUE(finished.last().at(1).value<Status>().ok());
  std::ifstream in(report);
  const std::string html((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(html.rfind("<!DOCTYPE html>", 0), 0u);
  EXPECT_NE(html.find("the gate"), std::string::npos);
  EXPECT_NE(html.find("data:image/jpeg;base64,"), std::string::npos);
}

// The time line: dragging the slider moves the map's footprint and markers and the frame panel
// to that time; playback runs at the chosen speed; a click on bare ground seeks to a pass that saw
// it; a recalled observation moves the time line.
TEST(MainWindowTest, TheTimeLineScrubsPlaysAndFollows) {
  const TestMission* m = SmallMission();
  ASSERT_NE(m, nullptr);
  MainWindow window;
  window.resize(1300, 900);
  window.show();
  ASSERT_TRUE(OpenAndWait(window, *m));
  const mission::Mission& mission = *window.mission();
  ASSERT_GT(mission.frames.size(), 50u);
  TimeLine* line = window.timeLine();
  ASSERT_NE(line, nullptr);
  auto* slider = line->findChild<QSlider*>("timeLineSlider");
  ASSERT_NE(slider, nullptr);
  EXPECT_EQ(slider->maximum(), static_cast<int>(mission.frames.size()) - 1);

  // Scrub to the middle: the frame, the footprint's frame and the markers of that moment.
  QSignalSpy shown(window.framePanel(), &FramePanel::frameShown);
  const size_t middle = mission.frames.size() / 2;
  slider->setValue(static_cast<int>(middle));
  const int64_t frame = mission.frames[middle].index;
  EXPECT_EQ(line->frame(), frame);
  EXPECT_EQ(window.mosaicView()->currentFrameIndex(), frame);
  ASSERT_TRUE(WaitUntil([&] { return window.framePanel()->displayedFrame() == frame; }, 10000));
  const double t = mission.frames[middle].time_s;
  for (const auto& [track, map] : window.mosaicView()->timeMarkers()) {
    EXPECT_LE(mission.tracks[track].start_s, t + 1e-9);
    EXPECT_GE(mission.tracks[track].end_s, t - 1e-9);
  }
  size_t alive = 0;
  for (const auto& track : mission.tracks) alive += track.start_s <= t && t <= track.end_s;
  EXPECT_GT(alive, 0u);
  EXPECT_GT(window.mosaicView()->timeMarkers().size(), 0u);

  // Playback at 8x: the position follows a clock, 8 video seconds a second.
  line->setSpeed(8);
  QElapsedTimer clock;
  clock.start();
  line->play();
  EXPECT_TRUE(line->isPlaying());
  QTest::qWait(600);
  line->pause();
  const double played = [&] {
    for (const auto& f : mission.frames) {
      if (f.index == line->frame()) return f.time_s - t;
    }
    return -1.0;
  }();
  const double wall = clock.elapsed() / 1000.0;
  // At least a second of video (8x for 0.6 s, even if the machine starves the timer for a
  // while); never more than the speed allows.
  EXPECT_GT(played, 1.0) << played << " s of video in " << wall << " s";
  EXPECT_LT(played, 8 * wall + 1) << played << " s of video in " << wall << " s";
  EXPECT_EQ(window.mosaicView()->currentFrameIndex(), line->frame());

  // Bare ground: the centre of an early frame's picture, seen in one pass or more.
  const mission::FrameRecord& early = mission.frames[10];
  ASSERT_TRUE(early.map_from_frame.has_value());
  const Eigen::Vector2d ground =
      (*early.map_from_frame *
       Eigen::Vector3d(mission.source.width / 2.0, mission.source.height / 2.0, 1))
          .hnormalized();
  const auto passes = window.passesSeeing(ground);
  ASSERT_FALSE(passes.empty());
  EXPECT_LE(passes.front().first_frame, early.index);
  EXPECT_GE(passes.front().last_frame, early.index);
  window.setGroundMenuSuppressed(true);
  window.seekGround(ground);
  EXPECT_GE(line->frame(), passes.front().first_frame);
  EXPECT_LE(line->frame(), passes.front().last_frame);
  EXPECT_EQ(window.mosaicView()->currentFrameIndex(), line->frame());

  // A recalled observation moves the time line to its frame.
  const auto& track = mission.tracks.front();
  window.framePanel()->showObservation(0, track.points.size() - 1);
  ASSERT_TRUE(WaitUntil([&] { return line->frame() == track.points.back().frame; }, 10000));
}

TEST(MainWindowTest, HelpShowsTheUserGuideWithItsPictures) {
  MainWindow window;
  window.show();
  QAction* guide = nullptr;
  for (QAction* a : window.findChildren<QAction*>()) {
    if (a->text() == "Saker &User Guide") guide = a;
  }
  ASSERT_NE(guide, nullptr);
  guide->trigger();
  QTextBrowser* browser = nullptr;
  ASSERT_TRUE(WaitUntil(
      [&] {
        browser = window.findChild<QTextBrowser*>();
        return browser != nullptr && browser->isVisible();
      },
      3000));
  EXPECT_TRUE(browser->toPlainText().contains("Click to recall"));
  // Every picture the guide shows is in the resources.
  const QString markdown = browser->toMarkdown();
  for (const char* picture : {"images/main-window-speed.png", "images/recall.png"}) {
    EXPECT_TRUE(markdown.contains(picture)) << picture;
    EXPECT_TRUE(QFile::exists(QString(":/saker/docs/") + picture)) << picture;
  }
}

// Processing runs on the task runner: the event loop keeps turning, the mosaic grows (preview
// key frames, then the committed stages), and Cancel leaves a usable partial mission.
TEST(MainWindowTest, ProcessingKeepsTheWindowLiveAndCancelLeavesAUsablePartialMission) {
  const TestMission* m = SmallMission();
  ASSERT_NE(m, nullptr);
  const fs::path dir = saker::testing::MakeTempDir("saker-ui-process");
  const QString target = QString::fromStdString((dir / "partial.saker").string());
  MainWindow window;
  window.show();
  QSignalSpy finished(&window, &MainWindow::jobFinished);

  // The event loop's heartbeat: the longest gap between 10 ms timer ticks.
  QElapsedTimer clock;
  clock.start();
  qint64 last = 0, longest_gap = 0;
  QTimer heartbeat;
  QObject::connect(&heartbeat, &QTimer::timeout, [&] {
    longest_gap = std::max(longest_gap, clock.elapsed() - last);
    last = clock.elapsed();
  });
  heartbeat.start(10);

  window.setCheckpointInterval(0);  // at every key frame, so that there is one to resume from
  window.processVideo(QString::fromStdString(m->video.string()), target, false);
  EXPECT_TRUE(window.taskRunner()->isRunning());
  QPushButton* cancel_button = nullptr;
  for (QPushButton* b : window.findChildren<QPushButton*>()) {
    if (b->text() == "Cancel") cancel_button = b;
  }
  ASSERT_NE(cancel_button, nullptr);
  EXPECT_TRUE(cancel_button->isVisible());
  // The mosaic grows while the front end runs: preview key frames arrive.
  ASSERT_TRUE(WaitUntil([&] { return window.mosaicView()->previewKeyFrameCount() >= 3; }))
      << "no preview";
  EXPECT_TRUE(window.mosaicView()->showingPreview());
  auto* progress = window.findChild<QProgressBar*>();
  ASSERT_NE(progress, nullptr);
  EXPECT_GT(progress->value(), 0);
  QTest::mouseClick(cancel_button, Qt::LeftButton);
  ASSERT_TRUE(finished.wait(30000));
  heartbeat.stop();
  const Status status = finished.takeFirst().at(1).value<Status>();
  EXPECT_EQ(status.code(), StatusCode::kCancelled) << status.ToString();
  std::cout << "longest event-loop gap during processing: " << longest_gap << " ms\n";
  EXPECT_LT(longest_gap, 500);
  EXPECT_FALSE(cancel_button->isVisible());

  // The partial mission opens: cancelled, with what had completed.
  ASSERT_TRUE(WaitUntil([&] { return window.mission() != nullptr; }));
  EXPECT_TRUE(window.mission()->progress.cancelled);
  const auto store = mission::MissionStore::Open(target.toStdString());
  ASSERT_TRUE(store.ok()) << store.status().ToString();
  const auto reopened = (*store)->Load();
  ASSERT_TRUE(reopened.ok()) << reopened.status().ToString();
  EXPECT_TRUE(reopened->progress.cancelled);
  EXPECT_EQ(reopened->source.fingerprint, m->loaded.source.fingerprint);

  // File > Resume Processing carries the job on from its checkpoint to a complete mission.
  QAction* resume = window.findChild<QAction*>("resumeProcessing");
  ASSERT_NE(resume, nullptr);
  ASSERT_TRUE(WaitUntil([&] { return resume->isEnabled(); }));
  auto* facts = window.findChild<QLabel*>("missionFacts");
  ASSERT_NE(facts, nullptr);
  EXPECT_TRUE(facts->text().contains("Resume Processing")) << facts->text().toStdString();
  EXPECT_TRUE(facts->text().contains("Checkpoint")) << facts->text().toStdString();
  resume->trigger();
  ASSERT_TRUE(finished.wait(ProcessingWaitMs()));
  const Status resumed = finished.takeFirst().at(1).value<Status>();
  EXPECT_TRUE(resumed.ok()) << resumed.ToString();
  ASSERT_TRUE(WaitUntil([&] {
    return window.mission() != nullptr && window.mission()->progress.tiles &&
           !window.taskRunner()->isRunning();
  }));
  EXPECT_FALSE(window.mission()->progress.cancelled);
  EXPECT_NEAR(static_cast<double>(window.mission()->tracks.size()),
              static_cast<double>(m->loaded.tracks.size()), 3);
  EXPECT_EQ(window.mission()->frames.size(), m->loaded.frames.size());
  // The tiles stage's reload may still show the checkpoint, which the job drops only as it
  // ends; the reload after the job shows the mission without it.
  EXPECT_TRUE(WaitUntil([&] { return !resume->isEnabled(); })) << "nothing left to resume";
  EXPECT_FALSE(facts->text().contains("Resume Processing")) << facts->text().toStdString();
  // The filters follow the resumed mission (they stayed at "0.0 to 1.0 px/s", disabled).
  ExpectFiltersFitTheMission(window);
}

TEST(MainWindowTest, ProcessingToTheEndShowsTheMissionAsItsStagesComplete) {
  const TestMission* m = SmallMission();
  ASSERT_NE(m, nullptr);
  const fs::path dir = saker::testing::MakeTempDir("saker-ui-process");
  const QString target = QString::fromStdString((dir / "full.saker").string());
  MainWindow window;
  window.show();
  QSignalSpy finished(&window, &MainWindow::jobFinished);
  QSignalSpy opened(&window, &MainWindow::missionOpened);
  window.processVideo(QString::fromStdString(m->video.string()), target, false);
  ASSERT_TRUE(finished.wait(ProcessingWaitMs()));
  EXPECT_TRUE(finished.takeFirst().at(1).value<Status>().ok());
  ASSERT_TRUE(WaitUntil([&] {
    return window.mission() != nullptr && window.mission()->progress.tiles &&
           window.mosaicView()->tilesComplete();
  }));
  // Reloaded at each committed stage (loads that overlap are merged, so at least twice).
  EXPECT_GE(opened.count(), 2);
  EXPECT_FALSE(window.mosaicView()->showingPreview());
  EXPECT_EQ(window.mission()->tracks.size(), m->loaded.tracks.size());
  // The filters follow the processed mission (they stayed at "0.0 to 1.0 px/s", disabled, until
  // the mission was opened again).
  ExpectFiltersFitTheMission(window);
  ExpectConfidenceFilterHidesTheLeastConfidentTrack(window);
}

TEST(MainWindowTest, ExportsWriteValidFilesOfTheShownTracks) {
  const TestMission* m = SmallMission();
  ASSERT_NE(m, nullptr);
  MainWindow window;
  window.show();
  ASSERT_TRUE(OpenAndWait(window, *m));
  const fs::path dir = saker::testing::MakeTempDir("saker-ui-export");
  QSignalSpy finished(&window, &MainWindow::jobFinished);
  const auto run = [&](auto export_call, const fs::path& path) {
    export_call(QString::fromStdString(path.string()));
    EXPECT_TRUE(finished.wait(60000)) << path;
    const Status status = finished.takeFirst().at(1).value<Status>();
    EXPECT_TRUE(status.ok()) << status.ToString();
    EXPECT_TRUE(fs::exists(path)) << path;
  };
  // The menu's actions are there and enabled for a complete mission.
  for (const QString& text : {QString("Export Activity &Map…"), QString("Export &Tracks…"),
                              QString("Export Mo&saic (GeoTIFF)…"), QString("Save Mission &As…")}) {
    bool found = false;
    for (QAction* a : window.findChildren<QAction*>()) {
      if (a->text() != text) continue;
      found = true;
      EXPECT_TRUE(a->isEnabled()) << text.toStdString();
    }
    EXPECT_TRUE(found) << text.toStdString();
  }

  ColourAction(window, "visit")->trigger();
  run([&](const QString& p) { window.exportActivityMap(p); }, dir / "map.png");
  const QImage picture(QString::fromStdString((dir / "map.png").string()));
  EXPECT_FALSE(picture.isNull());
  EXPECT_GT(picture.width(), 200);

  // Only the tracks shown are exported: hide the slow ones.
  const auto& tracks = window.mission()->tracks;
  std::vector<double> speeds;
  for (const auto& t : tracks) speeds.push_back(t.speed_mps.value_or(0));
  std::sort(speeds.begin(), speeds.end());
  const double median = speeds[speeds.size() / 2];
  window.mosaicView()->setTrackFilter({std::nullopt, std::nullopt, median, std::nullopt, 0, {}});
  size_t shown = 0;
  for (size_t i = 0; i < tracks.size(); ++i) shown += window.mosaicView()->isTrackVisible(i);
  ASSERT_GT(shown, 0u);
  ASSERT_LT(shown, tracks.size());
  run([&](const QString& p) { window.exportTracks(p); }, dir / "tracks.geojson");
  const auto geojson = nlohmann::json::parse(std::ifstream(dir / "tracks.geojson"));
  EXPECT_EQ(geojson["type"], "FeatureCollection");
  EXPECT_EQ(geojson["features"].size(), shown);

  run([&](const QString& p) { window.exportTracks(p); }, dir / "tracks.kml");
  QFile kml(QString::fromStdString((dir / "tracks.kml").string()));
  ASSERT_TRUE(kml.open(QIODevice::ReadOnly));
  QXmlStreamReader xml(&kml);
  int placemarks = 0;
  while (!xml.atEnd()) {
    if (xml.readNext() == QXmlStreamReader::StartElement && xml.name() == QString("Placemark"))
      ++placemarks;
  }
  EXPECT_FALSE(xml.hasError()) << xml.errorString().toStdString();
  EXPECT_EQ(static_cast<size_t>(placemarks), shown);

  run([&](const QString& p) { window.exportTracks(p); }, dir / "tracks.csv");
  run([&](const QString& p) { window.exportMosaic(p); }, dir / "mosaic.tif");
  std::ifstream tif(dir / "mosaic.tif", std::ios::binary);
  char magic[4] = {};
  tif.read(magic, 4);
  EXPECT_TRUE((magic[0] == 'I' && magic[1] == 'I') || (magic[0] == 'M' && magic[1] == 'M'));

  run([&](const QString& p) { window.saveMissionAs(p); }, dir / "copy.saker");
  const auto copy = mission::MissionStore::Open((dir / "copy.saker").string());
  ASSERT_TRUE(copy.ok());
  EXPECT_EQ((*copy)->Load()->tracks.size(), tracks.size());
}

// The whole menu path: File > Export Activity Map…, the file dialog answered as a person would.
TEST(MainWindowTest, ExportActivityMapFromTheFileMenu) {
  const TestMission* m = SmallMission();
  ASSERT_NE(m, nullptr);
  MainWindow window;
  window.show();
  ASSERT_TRUE(OpenAndWait(window, *m));
  ColourAction(window, "direction")->trigger();
  const fs::path dir = saker::testing::MakeTempDir("saker-ui-menu");
  const QString target = QString::fromStdString((dir / "from-menu.png").string());
  QAction* action = nullptr;
  for (QAction* a : window.findChildren<QAction*>()) {
    if (a->text() == "Export Activity &Map…") action = a;
  }
  ASSERT_NE(action, nullptr);
  // The dialog is modal: answer it from the event loop once it is up.
  bool answered = false;
  QTimer answer;
  QObject::connect(&answer, &QTimer::timeout, [&] {
    auto* dialog = qobject_cast<QFileDialog*>(QApplication::activeModalWidget());
    if (dialog == nullptr) return;
    answer.stop();
    EXPECT_TRUE(dialog->selectedFiles().value(0).endsWith("-activity-direction.png"))
        << dialog->selectedFiles().value(0).toStdString();
    // Typed into the file name box, then Save.
    auto* name = dialog->findChild<QLineEdit*>("fileNameEdit");
    ASSERT_NE(name, nullptr);
    name->setText(target);
    QMetaObject::invokeMethod(dialog, "accept");
    answered = true;
  });
  answer.start(20);
  QSignalSpy finished(&window, &MainWindow::jobFinished);
  action->trigger();
  EXPECT_TRUE(answered);
  ASSERT_TRUE(!finished.isEmpty() || finished.wait(60000));
  EXPECT_TRUE(finished.at(0).at(1).value<Status>().ok());
  const QImage picture(target);
  EXPECT_FALSE(picture.isNull()) << target.toStdString();
}

TEST(MainWindowTest, CorruptMissionGivesAnErrorDialogNamingTheFile) {
  MainWindow window;
  window.show();
  ASSERT_NO_FATAL_FAILURE(OpenDamagedMission(window, "sortie-12.saker"));
  EXPECT_EQ(window.mission(), nullptr);
  // The window is still usable: a good mission opens after it.
  const TestMission* m = SmallMission();
  ASSERT_NE(m, nullptr);
  EXPECT_TRUE(OpenAndWait(window, *m));
}

TEST(MainWindowTest, AMissionWhoseVideoHasGoneOpensAndOffersToLocateIt) {
  const TestMission* m = SmallMission();
  ASSERT_NE(m, nullptr);
  // A copy of the mission that records a video path that no longer exists.
  const fs::path dir = saker::testing::MakeTempDir("saker-ui-moved");
  const fs::path moved = dir / "moved.saker";
  ASSERT_NO_FATAL_FAILURE(SaveChangedCopy(m->loaded, moved, [&](mission::Mission& copy) {
    copy.source.path = (dir / "gone" / "loop.ts").string();
  }));
  MainWindow window;
  window.show();
  QSignalSpy opened(&window, &MainWindow::missionOpened);
  window.openMission(QString::fromStdString(moved.string()));
  ASSERT_TRUE(opened.wait(30000));
  ASSERT_NE(window.mission(), nullptr);
  EXPECT_EQ(window.mission()->tracks.size(), m->loaded.tracks.size());
  EXPECT_TRUE(window.videoPath().isEmpty());
  EXPECT_FALSE(window.framePanel()->videoAvailable());
  QSignalSpy locate(window.framePanel(), &FramePanel::locateVideoRequested);
  QPushButton* locate_button = nullptr;
  for (QPushButton* b : window.framePanel()->findChildren<QPushButton*>()) {
    if (b->text().contains("Locate")) locate_button = b;
  }
  ASSERT_NE(locate_button, nullptr);
  EXPECT_TRUE(locate_button->isVisible());

  // Located (the dialog's answer): the right video is taken and remembered, another refused.
  const fs::path other = dir / "other.ts";
  std::ofstream(other) << "not the same video";
  EXPECT_FALSE(window.useVideo(QString::fromStdString(other.string())));
  EXPECT_TRUE(window.useVideo(QString::fromStdString(m->video.string())));
  EXPECT_TRUE(window.framePanel()->videoAvailable());
  QSignalSpy shown(window.framePanel(), &FramePanel::frameShown);
  window.framePanel()->showObservation(0, 0);
  ASSERT_TRUE(shown.wait(10000));
  EXPECT_EQ(window.framePanel()->displayedFrame(), m->loaded.tracks[0].points[0].frame);

  // Next time, the remembered location is used without asking.
  MainWindow again;
  QSignalSpy again_opened(&again, &MainWindow::missionOpened);
  again.openMission(QString::fromStdString(moved.string()));
  ASSERT_TRUE(again_opened.wait(30000));
  EXPECT_EQ(again.videoPath().toStdString(), fs::absolute(m->video).string());
}

// What the front end found about the video is in the mission facts: kept in the mission, so a
// mission opened later says it as well as one just processed; a clean video's says nothing.
TEST(MainWindowTest, TheMissionFactsSayWhatTheFrontEndFound) {
  const TestMission* m = SmallMission();
  ASSERT_NE(m, nullptr);
  const auto facts_of = [](MainWindow& window) {
    auto* facts = window.findChild<QLabel*>("missionFacts");
    return facts != nullptr ? facts->text() : QString();
  };
  {
    MainWindow window;
    window.show();
    ASSERT_TRUE(OpenAndWait(window, *m));
    ASSERT_TRUE(window.mission()->findings.has_value()) << "processing keeps the findings";
    EXPECT_FALSE(facts_of(window).contains("noise")) << facts_of(window).toStdString();
  }
  const fs::path path = saker::testing::MakeTempDir("saker-ui-findings") / "noisy.saker";
  ASSERT_NO_FATAL_FAILURE(SaveChangedCopy(m->loaded, path, [](mission::Mission& copy) {
    mission::FrontEndFindings& f = copy.findings.emplace();
    f.noise_feature_frames = 40;
    f.noise_feature_px = 2.5;
    f.polarity_switches = 1;
  }));
  MainWindow window;
  QSignalSpy opened(&window, &MainWindow::missionOpened);
  window.openMission(QString::fromStdString(path.string()));
  ASSERT_TRUE(opened.wait(30000));
  const QString facts = facts_of(window);
  EXPECT_TRUE(facts.contains("Front end")) << facts.toStdString();
  EXPECT_TRUE(facts.contains("noise raised the thresholds in 40 of")) << facts.toStdString();
  EXPECT_TRUE(facts.contains("1 thermal polarity switch")) << facts.toStdString();
  // The whole sentences, as saker-cli says them, are the tooltip.
  const QString said = window.findChild<QLabel*>("missionFacts")->toolTip();
  EXPECT_TRUE(said.contains("raised the motion thresholds in 40 of")) << said.toStdString();
  EXPECT_TRUE(said.contains("slow and small targets may be missed")) << said.toStdString();
}

// A mission that does not open leaves the one shown open, with its title and facts.
TEST(MainWindowTest, AFailedOpenKeepsTheOpenMissionAndItsTitle) {
  const TestMission* m = SmallMission();
  ASSERT_NE(m, nullptr);
  MainWindow window;
  window.show();
  ASSERT_TRUE(OpenAndWait(window, *m));
  const auto shown = window.mission();
  const QString path = window.missionPath();
  const QString title = window.windowTitle();
  ASSERT_TRUE(title.contains("loop.saker"));

  ASSERT_NO_FATAL_FAILURE(OpenDamagedMission(window, "sortie-13.saker"));

  EXPECT_EQ(window.mission(), shown);
  EXPECT_EQ(window.missionPath(), path);
  EXPECT_EQ(window.windowTitle(), title);
  auto* facts = window.findChild<QLabel*>("missionFacts");
  ASSERT_NE(facts, nullptr);
  EXPECT_TRUE(facts->text().contains("loop.saker")) << facts->text().toStdString();
  EXPECT_FALSE(facts->text().contains("Loading")) << facts->text().toStdString();
  EXPECT_FALSE(facts->text().contains("sortie-13")) << facts->text().toStdString();
  EXPECT_TRUE(window.mosaicView()->tilesComplete());
  size_t visible = 0;
  for (size_t i = 0; i < shown->tracks.size(); ++i)
    visible += window.mosaicView()->isTrackVisible(i);
  EXPECT_EQ(visible, shown->tracks.size());
}

// After a pick on the map, Left and Right step along the picked track wherever the focus is in the
// window (but in a text box), Shift+Left and Shift+Right ten observations at a time.
TEST(MainWindowTest, ArrowKeysStepAlongTheSelectedTrackAfterAPick) {
  const TestMission* m = SmallMission();
  ASSERT_NE(m, nullptr);
  MainWindow window;
  window.resize(1400, 900);
  window.show();
  window.activateWindow();
  ASSERT_TRUE(QTest::qWaitForWindowActive(&window));
  ASSERT_TRUE(OpenAndWait(window, *m));
  const auto& tracks = window.mission()->tracks;
  const size_t longest = LongestTrack(*window.mission());
  ASSERT_GE(tracks[longest].points.size(), 30u);
  MosaicView* view = window.mosaicView();
  view->fitToWindow();
  const Eigen::Vector2d at = tracks[longest].points[tracks[longest].points.size() / 2].map;
  view->zoomAt(4, view->widgetFromMap(at));
  FramePanel* panel = window.framePanel();
  QTest::mouseClick(view, Qt::LeftButton, Qt::NoModifier, view->widgetFromMap(at).toPoint());
  ASSERT_TRUE(panel->currentObservation().has_value()) << "the click picked nothing";
  const auto [track, picked] = *panel->currentObservation();
  const auto& points = tracks[track].points;
  ASSERT_GE(picked, 10u);
  ASSERT_LT(picked + 12, points.size());
  EXPECT_TRUE(view->hasFocus());

  const auto expect_at = [&](size_t point, const char* how) {
    ASSERT_TRUE(panel->currentObservation().has_value()) << how;
    EXPECT_EQ(panel->currentObservation()->first, track) << how;
    EXPECT_EQ(panel->currentObservation()->second, point) << how;
    ASSERT_TRUE(view->marker().has_value()) << how;
    EXPECT_LT((*view->marker() - points[point].map).norm(), 1e-9) << how;
  };
  const QPointF centre = view->widgetFromMap(Eigen::Vector2d::Zero());
  QTest::keyClick(view, Qt::Key_Right);
  expect_at(picked + 1, "Right");
  EXPECT_EQ(view->widgetFromMap(Eigen::Vector2d::Zero()), centre) << "Right panned the map";
  QTest::keyClick(view, Qt::Key_Right, Qt::ShiftModifier);
  expect_at(picked + 11, "Shift+Right");
  QTest::keyClick(view, Qt::Key_Left);
  expect_at(picked + 10, "Left");
  QTest::keyClick(view, Qt::Key_Left, Qt::ShiftModifier);
  expect_at(picked, "Shift+Left");
  EXPECT_EQ(view->widgetFromMap(Eigen::Vector2d::Zero()), centre) << "the keys panned the map";
  // Shift steps stop at the track's ends.
  for (int i = 0; i < 1 + static_cast<int>(points.size()) / 10; ++i) {
    QTest::keyClick(view, Qt::Key_Left, Qt::ShiftModifier);
  }
  expect_at(0, "Shift+Left to the start");
  // Up and Down still pan the map.
  QTest::keyClick(view, Qt::Key_Down);
  EXPECT_NE(view->widgetFromMap(Eigen::Vector2d::Zero()), centre) << "Down did not pan";
  expect_at(0, "Down");

  // In a number box the arrow keys edit the number.
  QDoubleSpinBox* from = FilterBoxes(window).at(0);
  from->setFocus();
  QTest::keyClick(from, Qt::Key_Right);
  expect_at(0, "Right in a number box");
  // From the frame panel as from the map.
  panel->setFocus();
  QTest::keyClick(panel, Qt::Key_Right);
  expect_at(1, "Right in the frame panel");
}

// The frame panel keeps the width it was given while playback changes its frame and texts.
TEST(MainWindowTest, TheFramePanelKeepsItsWidthWhilePlaying) {
  const TestMission* m = SmallMission();
  ASSERT_NE(m, nullptr);
  MainWindow window;
  window.resize(1400, 900);
  window.show();
  ASSERT_TRUE(QTest::qWaitForWindowExposed(&window));
  ASSERT_TRUE(OpenAndWait(window, *m));
  FramePanel* panel = window.framePanel();
  auto* dock = window.findChild<QDockWidget*>("frameDock");
  ASSERT_NE(dock, nullptr);
  // An analyst narrowed the panel to see more of the map.
  window.resizeDocks({dock}, {280}, Qt::Horizontal);
  QTest::qWait(100);
  const int width = panel->width();
  ASSERT_LE(width, 300);

  const auto& tracks = window.mission()->tracks;
  const size_t longest = LongestTrack(*window.mission());
  QSignalSpy shown(panel, &FramePanel::frameShown);
  panel->showObservation(longest, tracks[longest].points.size() - 3);
  ASSERT_TRUE(shown.wait(10000));
  std::vector<int> widths = {panel->width()};
  QObject::connect(panel, &FramePanel::frameShown, panel,
                   [&](int64_t, double) { widths.push_back(panel->width()); });
  panel->play();
  ASSERT_TRUE(panel->isPlaying());
  QTest::qWait(2500);  // about 30 frames at 12.5 fps, past the end of the track
  panel->pause();
  QTest::qWait(50);
  widths.push_back(panel->width());
  ASSERT_GE(widths.size(), 10u);
  const auto [narrowest, widest] = std::minmax_element(widths.begin(), widths.end());
  EXPECT_EQ(*narrowest, width);
  EXPECT_EQ(*widest, width) << "the panel widened from " << width << " to " << *widest
                            << " px while playing";
}

// A mission whose map is not geo-referenced has no north: directions are given on the map's
// picture (up, right, down, left), in the frame panel and the legend.
TEST(MainWindowTest, UngeoreferencedMissionsShowNoCompassWords) {
  const TestMission* m = SmallMission();
  ASSERT_NE(m, nullptr);
  const fs::path dir = saker::testing::MakeTempDir("saker-ui-pixels");
  const fs::path pixels = dir / "pixels.saker";
  ASSERT_NO_FATAL_FAILURE(SaveChangedCopy(m->loaded, pixels, [](mission::Mission& copy) {
    copy.map.geo_referenced = false;
    copy.map.origin.reset();
    for (mission::FrameRecord& f : copy.frames) f.metadata_corners.reset();
    for (mission::ActivityTrack& t : copy.tracks) t.speed_mps.reset();
  }));
  for (const bool geo : {true, false}) {
    SCOPED_TRACE(geo ? "geo-referenced" : "not geo-referenced");
    MainWindow window;
    window.show();
    QSignalSpy opened(&window, &MainWindow::missionOpened);
    window.openMission(QString::fromStdString(geo ? m->mission.string() : pixels.string()));
    ASSERT_TRUE(opened.wait(30000));
    ASSERT_EQ(window.mission()->map.geo_referenced, geo);
    const auto& tracks = window.mission()->tracks;
    auto* heading = window.framePanel()->findChild<QLabel*>("headingValue");
    ASSERT_NE(heading, nullptr);
    bool any_compass = false;
    for (size_t t = 0; t < tracks.size(); ++t) {
      window.framePanel()->showObservation(t, 0);
      const bool compass = HasCompassWords(heading->text());
      any_compass |= compass;
      if (!geo) {
        EXPECT_FALSE(compass) << "track " << t << ": " << heading->text().toStdString();
      }
    }
    EXPECT_EQ(any_compass, geo);
    ColourAction(window, "direction")->trigger();
    const activity::Legend& legend = window.mosaicView()->legend();
    QString words = QString::fromStdString(legend.title);
    for (const activity::Legend::Entry& e : legend.entries)
      words += " " + QString::fromStdString(e.label);
    EXPECT_EQ(HasCompassWords(words), geo) << words.toStdString();
    auto* facts = window.findChild<QLabel*>("missionFacts");
    ASSERT_NE(facts, nullptr);
    if (!geo) {
      EXPECT_FALSE(HasCompassWords(facts->text())) << facts->text().toStdString();
    }
  }
}

// A mission whose tracks' confidence is unknown (as missions of schema 3 and older read): the
// Frame panel says "unknown", the confidence filter at 0 shows every track and above 0 none.
TEST(MainWindowTest, UnknownConfidenceShowsAsUnknownAndOnlyWithoutAThreshold) {
  const TestMission* m = SmallMission();
  ASSERT_NE(m, nullptr);
  const fs::path dir = saker::testing::MakeTempDir("saker-ui-unknown");
  const fs::path old = dir / "old.saker";
  ASSERT_NO_FATAL_FAILURE(SaveChangedCopy(m->loaded, old, [](mission::Mission& copy) {
    for (mission::ActivityTrack& t : copy.tracks) t.confidence.reset();
  }));
  MainWindow window;
  window.show();
  QSignalSpy opened(&window, &MainWindow::missionOpened);
  window.openMission(QString::fromStdString(old.string()));
  ASSERT_TRUE(opened.wait(30000));
  const size_t total = window.mission()->tracks.size();
  ASSERT_GT(total, 0u);
  window.framePanel()->showObservation(0, 0);
  auto* confidence = window.framePanel()->findChild<QLabel*>("confidenceValue");
  ASSERT_NE(confidence, nullptr);
  EXPECT_EQ(confidence->text(), "unknown");
  auto* box = window.findChild<QDoubleSpinBox*>("minConfidence");
  ASSERT_NE(box, nullptr);
  for (size_t i = 0; i < total; ++i) EXPECT_TRUE(window.mosaicView()->isTrackVisible(i));
  box->setValue(0.05);
  for (size_t i = 0; i < total; ++i) EXPECT_FALSE(window.mosaicView()->isTrackVisible(i));
  EXPECT_TRUE(MissionPanelTexts(window).contains(QString("0 of %1 tracks shown").arg(total)));
}

// Not a check: the user guide's screenshots, of the demo mission, when SAKER_UI_SCREENSHOTS
// names a folder (docs/user-guide.md says how to remake them).
TEST(MainWindowScreenshots, DemoMission) {
  const QString folder = qEnvironmentVariable("SAKER_UI_SCREENSHOTS");
  const fs::path demo = fs::path(SAKER_SOURCE_DIR) / "demo" / "demo.saker";
  if (folder.isEmpty() || !fs::exists(demo)) {
    GTEST_SKIP() << "set SAKER_UI_SCREENSHOTS to a folder, after `saker-cli demo`, to make the "
                    "user guide's screenshots";
  }
  MainWindow window;
  window.resize(1500, 900);
  window.show();
  QSignalSpy opened(&window, &MainWindow::missionOpened);
  window.openMission(QString::fromStdString(demo.string()));
  ASSERT_TRUE(opened.wait(30000));
  MosaicView* view = window.mosaicView();
  ASSERT_TRUE(WaitUntil([&] { return view->tilesComplete(); }));
  for (const char* mode : {"speed", "direction", "visit", "time", "density"}) {
    ColourAction(window, mode)->trigger();
    QTest::qWait(200);
    window.grab().save(folder + QString("/main-window-%1.png").arg(mode));
  }
  // A click on the middle observation of the longest track, zoomed in around it.
  ColourAction(window, "speed")->trigger();
  const auto& tracks = window.mission()->tracks;
  const size_t longest = LongestTrack(*window.mission());
  const Eigen::Vector2d at = tracks[longest].points[tracks[longest].points.size() / 2].map;
  view->zoomAt(2.5, view->widgetFromMap(at));
  ASSERT_TRUE(WaitUntil([&] { return view->tilesComplete(); }));
  QSignalSpy shown(window.framePanel(), &FramePanel::frameShown);
  QTest::mouseClick(view, Qt::LeftButton, Qt::NoModifier, view->widgetFromMap(at).toPoint());
  ASSERT_TRUE(shown.wait(10000));
  QTest::qWait(300);
  window.grab().save(folder + "/recall.png");

  // The time line at 0:28: the frame's footprint and the tracks of that moment.
  view->fitToWindow();
  auto* slider = window.timeLine()->findChild<QSlider*>("timeLineSlider");
  ASSERT_NE(slider, nullptr);
  window.framePanel()->clear();
  window.selectTrack(std::nullopt);
  view->setMarker(std::nullopt);
  slider->setValue(700);
  ASSERT_TRUE(WaitUntil([&] { return window.framePanel()->displayedFrame() >= 0; }, 10000));
  ASSERT_TRUE(WaitUntil([&] { return view->tilesComplete(); }));
  QTest::qWait(300);
  window.grab().save(folder + "/time-line.png");

  // Processing a video: the key-frame preview growing, the stage and Cancel in the status bar.
  const fs::path temp = saker::testing::MakeTempDir("saker-ui-shots");
  QSignalSpy finished(&window, &MainWindow::jobFinished);
  window.processVideo(QString::fromStdString((demo.parent_path() / "demo.ts").string()),
                      QString::fromStdString((temp / "processing.saker").string()), false);
  ASSERT_TRUE(WaitUntil([&] { return view->previewKeyFrameCount() >= 6; }, 120000));
  QTest::qWait(300);
  window.grab().save(folder + "/processing.png");
  window.taskRunner()->cancel();
  ASSERT_TRUE(finished.wait(60000));
}

}  // namespace
}  // namespace saker::ui
