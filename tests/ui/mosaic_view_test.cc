// The mosaic view and its tile cache under QT_QPA_PLATFORM=offscreen, on the small simulated
// mission: tiles load off the GUI thread and appear, the view's geometry and interaction keep
// the map where the user expects it, tracks take the colours and filter asked for, and broken
// files are reported without a crash.
//
// With SAKER_UI_SCREENSHOTS set, the Screenshots test writes /root/diag/view-<mode>.png (or into
// the folder SAKER_UI_SCREENSHOTS names, when that is one).

#include "ui/mosaic_view.h"

#include "core/activity/colours.h"
#include "core/activity/density.h"
#include "core/mission/mission_store.h"
#include "core/mosaic/adjustment.h"
#include "core/track/homography.h"
#include "core/track/image_geometry.h"
#include "core/video/video_reader.h"
#include "tests/testing/png_bomb.h"
#include "tests/testing/test_data.h"
#include "tests/ui/ui_testing.h"
#include "ui/tile_cache.h"

#include <Eigen/LU>
#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <QApplication>
#include <QDir>
#include <QElapsedTimer>
#include <QFile>
#include <QFileInfo>
#include <QKeyEvent>
#include <QMouseEvent>
#include <QPainter>
#include <QSignalSpy>
#include <QTest>
#include <QWheelEvent>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <random>
#include <set>

namespace saker::ui {
namespace {

using testing::SmallMission;
using testing::WaitUntil;

const QColor kBackground(38, 40, 44);  // the view's background (mosaic_view.cc)

std::shared_ptr<const mission::Mission> Share(const mission::Mission& mission) {
  return std::make_shared<const mission::Mission>(mission);
}

QString PathOf(const testing::TestMission& m) { return QString::fromStdString(m.mission.string()); }

bool IsBackground(const QImage& image, const QPointF& p) {
  return image.pixelColor(p.toPoint()) == kBackground;
}

// A point of the map the mosaic certainly covers: the middle of the first key frame.
Eigen::Vector2d CoveredPoint(const mission::Mission& mission) {
  const Eigen::Vector3d p =
      mission.key_frames.front().map_from_frame *
      Eigen::Vector3d(mission.source.width / 2.0, mission.source.height / 2.0, 1);
  return p.head<2>() / p.z();
}

// A view of the small mission, shown at 800x600 with the tiles it needs read.
class LoadedView {
 public:
  explicit LoadedView(const testing::TestMission& m, bool show_tracks = true) {
    view.resize(800, 600);
    view.setShowTracks(show_tracks);
    view.setMission(Share(m.loaded), PathOf(m));
    view.show();
  }
  bool WaitForTiles() {
    return WaitUntil([this] {
      view.update();
      return view.tilesComplete() && view.tileCache()->queuedCount() == 0;
    });
  }
  MosaicView view;
};

void SendMouse(QWidget* widget, QEvent::Type type, const QPointF& pos, Qt::MouseButton button,
               Qt::MouseButtons buttons) {
  QMouseEvent event(type, pos, widget->mapToGlobal(pos), button, buttons, Qt::NoModifier);
  QApplication::sendEvent(widget, &event);
}

void ExpectNear(const Eigen::Vector2d& a, const Eigen::Vector2d& b, double tolerance) {
  EXPECT_NEAR(a.x(), b.x(), tolerance);
  EXPECT_NEAR(a.y(), b.y(), tolerance);
}

TEST(MosaicViewTest, ShowsTilesAfterLoading) {
  const testing::TestMission* m = SmallMission();
  ASSERT_NE(m, nullptr);
  ASSERT_TRUE(m->loaded.pyramid.has_value());
  ASSERT_FALSE(m->loaded.key_frames.empty());
  MosaicView view;
  view.resize(800, 600);
  view.setShowTracks(false);
  view.setMission(Share(m->loaded), PathOf(*m));
  const QPointF covered = view.widgetFromMap(CoveredPoint(m->loaded));
  ASSERT_TRUE(view.rect().contains(covered.toPoint()));
  // Nothing is decoded on the GUI thread: before the worker has answered, the map is empty.
  EXPECT_TRUE(IsBackground(view.grab().toImage(), covered));
  view.show();
  ASSERT_TRUE(WaitUntil([&] { return view.tilesComplete(); }));
  const QImage shown = view.grab().toImage();
  EXPECT_FALSE(IsBackground(shown, covered));
  // Most of the fitted mosaic's footprint (the key frames) is imagery.
  int imagery = 0, total = 0;
  for (const mission::KeyFrameRecord& k : m->loaded.key_frames) {
    for (double u : {0.3, 0.5, 0.7}) {
      for (double v : {0.3, 0.5, 0.7}) {
        const Eigen::Vector3d p =
            k.map_from_frame *
            Eigen::Vector3d(u * m->loaded.source.width, v * m->loaded.source.height, 1);
        ++total;
        imagery += IsBackground(shown, view.widgetFromMap(p.head<2>() / p.z())) ? 0 : 1;
      }
    }
  }
  EXPECT_GT(imagery, total * 9 / 10) << imagery << " of " << total;
  std::printf("[ mosaic ] pyramid %dx%d px, %d levels; drawn at level %d; cache %.1f MiB\n",
              m->loaded.pyramid->width, m->loaded.pyramid->height, m->loaded.pyramid->levels,
              view.tileLevel(), static_cast<double>(view.tileCache()->bytesUsed()) / (1 << 20));
}

TEST(MosaicViewTest, ZoomingInDrawsFinerLevelWithCoarsePlaceholder) {
  const testing::TestMission* m = SmallMission();
  ASSERT_NE(m, nullptr);
  LoadedView loaded(*m, /*show_tracks=*/false);
  MosaicView& view = loaded.view;
  ASSERT_TRUE(loaded.WaitForTiles());
  const int fit_level = view.tileLevel();
  const Eigen::Vector2d covered = CoveredPoint(m->loaded);
  view.zoomAt(1e9, view.widgetFromMap(covered));  // as far as it goes
  // At the limit, 8 screen pixels per level-0 pixel, drawn from level 0.
  EXPECT_NEAR(view.pixelsPerMapUnit() * std::abs(m->loaded.pyramid->step_x), 8, 1e-6);
  EXPECT_EQ(view.tileLevel(), 0);
  EXPECT_LE(view.tileLevel(), fit_level);
  // The first paint after the jump has no level-0 tile yet, but the coarser ones stand in.
  const QPointF p = view.widgetFromMap(covered);
  EXPECT_FALSE(IsBackground(view.grab().toImage(), p));
  ASSERT_TRUE(loaded.WaitForTiles());
  EXPECT_FALSE(IsBackground(view.grab().toImage(), p));
}

TEST(MosaicViewTest, WidgetMapRoundTripWithNorthUp) {
  const testing::TestMission* m = SmallMission();
  ASSERT_NE(m, nullptr);
  ASSERT_TRUE(m->loaded.map.geo_referenced);
  MosaicView view;
  view.resize(640, 480);
  view.setMission(Share(m->loaded), PathOf(*m));
  view.zoomAt(1.37, QPointF(100, 70));
  for (const QPointF p : {QPointF(0, 0), QPointF(123.5, 456.25), QPointF(640, 480)}) {
    const QPointF back = view.widgetFromMap(view.mapFromWidget(p));
    EXPECT_NEAR(back.x(), p.x(), 1e-9);
    EXPECT_NEAR(back.y(), p.y(), 1e-9);
  }
  // Geo-referenced: north (+y) is up the screen, east (+x) to the right.
  EXPECT_GT(view.mapFromWidget(QPointF(320, 100)).y(), view.mapFromWidget(QPointF(320, 300)).y());
  EXPECT_GT(view.mapFromWidget(QPointF(400, 240)).x(), view.mapFromWidget(QPointF(200, 240)).x());
  // Pixel maps keep the image's y down.
  mission::Mission pixels = m->loaded;
  pixels.map.geo_referenced = false;
  pixels.map.origin.reset();
  pixels.pyramid.reset();
  view.setMission(Share(pixels), "pixels.saker");
  EXPECT_LT(view.mapFromWidget(QPointF(320, 100)).y(), view.mapFromWidget(QPointF(320, 300)).y());
  const QPointF back = view.widgetFromMap(view.mapFromWidget(QPointF(17, 29)));
  EXPECT_NEAR(back.x(), 17, 1e-9);
  EXPECT_NEAR(back.y(), 29, 1e-9);
}

TEST(MosaicViewTest, ZoomAtKeepsAnchorFixed) {
  const testing::TestMission* m = SmallMission();
  ASSERT_NE(m, nullptr);
  MosaicView view;
  view.resize(800, 600);
  view.setMission(Share(m->loaded), PathOf(*m));
  QSignalSpy changed(&view, &MosaicView::viewChanged);
  const QPointF anchor(213, 377);
  const Eigen::Vector2d before = view.mapFromWidget(anchor);
  const double ppu = view.pixelsPerMapUnit();
  view.zoomAt(1.8, anchor);
  EXPECT_NEAR(view.pixelsPerMapUnit(), ppu * 1.8, ppu * 1e-9);
  ExpectNear(view.mapFromWidget(anchor), before, 1e-9 / ppu);
  view.zoomAt(1 / 3.0, anchor);
  ExpectNear(view.mapFromWidget(anchor), before, 1e-9 / ppu);
  EXPECT_GE(changed.count(), 2);
  // Zooming out stops a little below the fit.
  view.zoomAt(1e-9, anchor);
  EXPECT_NEAR(view.pixelsPerMapUnit(), ppu * 0.5, ppu * 1e-9);
  view.fitToWindow();
  EXPECT_NEAR(view.pixelsPerMapUnit(), ppu, ppu * 1e-12);
}

TEST(MosaicViewTest, WheelZoomsAboutTheCursor) {
  const testing::TestMission* m = SmallMission();
  ASSERT_NE(m, nullptr);
  MosaicView view;
  view.resize(800, 600);
  view.setMission(Share(m->loaded), PathOf(*m));
  const QPointF cursor(600, 150);
  const Eigen::Vector2d under = view.mapFromWidget(cursor);
  const double ppu = view.pixelsPerMapUnit();
  QWheelEvent wheel(cursor, view.mapToGlobal(cursor), QPoint(), QPoint(0, 240), Qt::NoButton,
                    Qt::NoModifier, Qt::NoScrollPhase, false);
  QApplication::sendEvent(&view, &wheel);
  EXPECT_NEAR(view.pixelsPerMapUnit(), ppu * std::pow(1.0015, 240), ppu * 1e-9);
  ExpectNear(view.mapFromWidget(cursor), under, 1e-6 / ppu);
  QWheelEvent back(cursor, view.mapToGlobal(cursor), QPoint(), QPoint(0, -240), Qt::NoButton,
                   Qt::NoModifier, Qt::NoScrollPhase, false);
  QApplication::sendEvent(&view, &back);
  EXPECT_NEAR(view.pixelsPerMapUnit(), ppu, ppu * 1e-9);
}

TEST(MosaicViewTest, KeysZoomPanAndFit) {
  const testing::TestMission* m = SmallMission();
  ASSERT_NE(m, nullptr);
  MosaicView view;
  view.resize(800, 600);
  view.setMission(Share(m->loaded), PathOf(*m));
  const double fit = view.pixelsPerMapUnit();
  QTest::keyClick(&view, Qt::Key_Plus);
  EXPECT_GT(view.pixelsPerMapUnit(), fit * 1.2);
  const Eigen::Vector2d centre = view.mapFromWidget(QPointF(400, 300));
  QTest::keyClick(&view, Qt::Key_Right);
  // Right shows more of the east: the centre moves east by 1/8 of the width.
  EXPECT_NEAR(view.mapFromWidget(QPointF(400, 300)).x() - centre.x(), 100 / view.pixelsPerMapUnit(),
              1e-6);
  QTest::keyClick(&view, Qt::Key_0);
  EXPECT_NEAR(view.pixelsPerMapUnit(), fit, fit * 1e-12);
  QTest::keyClick(&view, Qt::Key_Minus);
  EXPECT_LT(view.pixelsPerMapUnit(), fit);
}

TEST(MosaicViewTest, DragPansWithoutClicking) {
  const testing::TestMission* m = SmallMission();
  ASSERT_NE(m, nullptr);
  MosaicView view;
  view.resize(800, 600);
  view.setMission(Share(m->loaded), PathOf(*m));
  view.zoomAt(3, QPointF(400, 300));
  QSignalSpy clicked(&view, &MosaicView::mapClicked);
  const QPointF from(400, 300), to(330, 350);
  const Eigen::Vector2d grabbed = view.mapFromWidget(from);
  SendMouse(&view, QEvent::MouseButtonPress, from, Qt::LeftButton, Qt::LeftButton);
  EXPECT_EQ(view.cursor().shape(), Qt::ClosedHandCursor);
  for (int i = 1; i <= 10; ++i) {
    SendMouse(&view, QEvent::MouseMove, from + (to - from) * (i / 10.0), Qt::NoButton,
              Qt::LeftButton);
  }
  SendMouse(&view, QEvent::MouseButtonRelease, to, Qt::LeftButton, Qt::NoButton);
  // The map point grabbed follows the cursor.
  ExpectNear(view.mapFromWidget(to), grabbed, 1e-6);
  EXPECT_EQ(clicked.count(), 0);
  EXPECT_EQ(view.cursor().shape(), Qt::OpenHandCursor);
}

TEST(MosaicViewTest, ClickEmitsMapPointAndTolerance) {
  const testing::TestMission* m = SmallMission();
  ASSERT_NE(m, nullptr);
  MosaicView view;
  view.resize(800, 600);
  view.setMission(Share(m->loaded), PathOf(*m));
  QSignalSpy clicked(&view, &MosaicView::mapClicked);
  QSignalSpy cursor(&view, &MosaicView::cursorMoved);
  const QPointF at(250, 410);
  const double ppu = view.pixelsPerMapUnit();
  SendMouse(&view, QEvent::MouseButtonPress, at, Qt::LeftButton, Qt::LeftButton);
  // A tremor of a pixel or two is still a click.
  SendMouse(&view, QEvent::MouseMove, at + QPointF(2, 1), Qt::NoButton, Qt::LeftButton);
  SendMouse(&view, QEvent::MouseButtonRelease, at + QPointF(2, 1), Qt::LeftButton, Qt::NoButton);
  ASSERT_EQ(clicked.count(), 1);
  EXPECT_EQ(view.pixelsPerMapUnit(), ppu);  // nothing panned
  const auto point = clicked.at(0).at(0).value<Eigen::Vector2d>();
  ExpectNear(point, view.mapFromWidget(at + QPointF(2, 1)), 1e-9);
  EXPECT_NEAR(clicked.at(0).at(1).toDouble(), 8 / ppu, 1e-12);
  ASSERT_GE(cursor.count(), 1);
  const auto moved = cursor.last().at(0).value<std::optional<Eigen::Vector2d>>();
  ASSERT_TRUE(moved.has_value());
  ExpectNear(*moved, point, 1e-9);
  QEvent leave(QEvent::Leave);
  QApplication::sendEvent(&view, &leave);
  EXPECT_FALSE(cursor.last().at(0).value<std::optional<Eigen::Vector2d>>().has_value());
}

TEST(MosaicViewTest, ReloadKeepsTheViewNewMissionFits) {
  const testing::TestMission* m = SmallMission();
  ASSERT_NE(m, nullptr);
  MosaicView view;
  view.resize(800, 600);
  view.setMission(Share(m->loaded), PathOf(*m));
  const double fit = view.pixelsPerMapUnit();
  view.zoomAt(2.5, QPointF(100, 100));
  const Eigen::Vector2d corner = view.mapFromWidget(QPointF(0, 0));
  view.setMarker(Eigen::Vector2d(1, 2));
  view.setMission(Share(m->loaded), PathOf(*m));  // processing committed a stage
  EXPECT_NEAR(view.pixelsPerMapUnit(), fit * 2.5, fit * 1e-9);
  ExpectNear(view.mapFromWidget(QPointF(0, 0)), corner, 1e-9);
  EXPECT_TRUE(view.marker().has_value());
  view.setMission(Share(m->loaded), PathOf(*m) + ".copy");  // another mission
  EXPECT_NEAR(view.pixelsPerMapUnit(), fit, fit * 1e-9);
  EXPECT_FALSE(view.marker().has_value());
  view.setMission(nullptr, QString());
  EXPECT_TRUE(view.legend().title.empty());

  // A view nobody moved follows the content a reload brings (here: the mosaic after the tracks).
  mission::Mission early = m->loaded;
  early.key_frames.clear();
  early.pyramid.reset();
  MosaicView fresh;
  fresh.resize(800, 600);
  fresh.setMission(Share(early), PathOf(*m));
  EXPECT_GT(fresh.pixelsPerMapUnit(), fit * 1.5);  // fitted to the tracks alone
  fresh.setMission(Share(m->loaded), PathOf(*m));
  EXPECT_NEAR(fresh.pixelsPerMapUnit(), fit, fit * 1e-9);
}

TEST(MosaicViewTest, ColourModesChangeLegendAndTrackColours) {
  const testing::TestMission* m = SmallMission();
  ASSERT_NE(m, nullptr);
  const std::vector<mission::ActivityTrack>& tracks = m->loaded.tracks;
  ASSERT_FALSE(tracks.empty());
  MosaicView view;
  view.setMission(Share(m->loaded), PathOf(*m));
  EXPECT_EQ(view.colourMode(), activity::ColourMode::kSpeed);
  std::set<std::string> titles;
  for (const activity::ColourMode mode :
       {activity::ColourMode::kSpeed, activity::ColourMode::kDirection,
        activity::ColourMode::kVisit, activity::ColourMode::kTime}) {
    view.setColourMode(mode);
    EXPECT_EQ(view.colourMode(), mode);
    const activity::TrackColouring expected(mode, tracks, m->loaded.map.geo_referenced);
    EXPECT_EQ(view.legend().title, expected.legend().title);
    EXPECT_EQ(view.legend().entries.size(), expected.legend().entries.size());
    EXPECT_EQ(view.legend().continuous, mode != activity::ColourMode::kVisit);
    titles.insert(view.legend().title);
    for (size_t i = 0; i < tracks.size(); ++i) {
      const std::optional<activity::Rgb> colour = view.trackColour(i);
      ASSERT_TRUE(colour.has_value());
      EXPECT_TRUE(*colour == expected.ColourOf(tracks[i])) << "track " << i;
    }
  }
  EXPECT_EQ(titles.size(), 4u);
  // Visit mode: the first visit red.
  view.setColourMode(activity::ColourMode::kVisit);
  for (size_t i = 0; i < tracks.size(); ++i) {
    if (tracks[i].visit != 1) continue;
    const activity::Rgb c = *view.trackColour(i);
    EXPECT_GT(c.r, 180);
    EXPECT_LT(c.g, 90);
    EXPECT_LT(c.b, 90);
  }
  EXPECT_FALSE(view.trackColour(tracks.size()).has_value());
  // A mission without tracks draws no legend, so has none.
  mission::Mission bare = m->loaded;
  bare.tracks.clear();
  view.setMission(Share(bare), PathOf(*m));
  EXPECT_TRUE(view.legend().title.empty());
  EXPECT_TRUE(view.legend().entries.empty());
}

TEST(MosaicViewTest, FilterHidesTracks) {
  const testing::TestMission* m = SmallMission();
  ASSERT_NE(m, nullptr);
  const std::vector<mission::ActivityTrack>& tracks = m->loaded.tracks;
  ASSERT_GE(tracks.size(), 2u);
  LoadedView loaded(*m);
  MosaicView& view = loaded.view;
  ASSERT_TRUE(loaded.WaitForTiles());
  const QImage all = view.grab().toImage();

  // Speed: the faster half.
  std::vector<double> speeds;
  for (const auto& t : tracks) speeds.push_back(t.speed_mps.value_or(t.speed));
  std::vector<double> sorted = speeds;
  std::sort(sorted.begin(), sorted.end());
  const double median = sorted[sorted.size() / 2];
  MosaicView::TrackFilter filter;
  filter.min_speed = median;
  view.setTrackFilter(filter);
  size_t shown = 0;
  for (size_t i = 0; i < tracks.size(); ++i) {
    EXPECT_EQ(view.isTrackVisible(i), speeds[i] >= median) << "track " << i;
    EXPECT_EQ(view.trackColour(i).has_value(), view.isTrackVisible(i));
    shown += view.isTrackVisible(i) ? 1 : 0;
  }
  EXPECT_GT(shown, 0u);
  EXPECT_LT(shown, tracks.size());

  // Time: a window that ends before the first track starts hides them all, and nothing of the
  // tracks is drawn then.
  double first_start = tracks.front().start_s;
  for (const auto& t : tracks) first_start = std::min(first_start, t.start_s);
  filter = {};
  filter.end_s = first_start - 1;
  view.setTrackFilter(filter);
  for (size_t i = 0; i < tracks.size(); ++i) EXPECT_FALSE(view.isTrackVisible(i));
  // The legend stays (it still explains the colours); the rest is as without tracks.
  const auto without_legend = [](QImage image) {
    QPainter(&image).fillRect(0, image.height() - 160, 320, 160, Qt::black);
    return image;
  };
  const QImage none = without_legend(view.grab().toImage());
  view.setTrackFilter({});
  view.setShowTracks(false);
  const QImage hidden = without_legend(view.grab().toImage());
  EXPECT_EQ(none, hidden);
  EXPECT_NE(without_legend(all), hidden);
  view.setShowTracks(true);
  // A window round one track's time shows it.
  filter = {};
  filter.start_s = tracks[0].start_s;
  filter.end_s = tracks[0].start_s;
  view.setTrackFilter(filter);
  EXPECT_TRUE(view.isTrackVisible(0));
}

// The density mode draws a heat map of the shown tracks' observations, not the tracks, with its
// own legend; the filter applies to it as to the tracks.
TEST(MosaicViewTest, DensityModeDrawsAHeatMapOfTheShownTracks) {
  const testing::TestMission* m = SmallMission();
  ASSERT_NE(m, nullptr);
  const std::vector<mission::ActivityTrack>& tracks = m->loaded.tracks;
  ASSERT_FALSE(tracks.empty());
  LoadedView loaded(*m);
  MosaicView& view = loaded.view;
  ASSERT_TRUE(loaded.WaitForTiles());
  view.setColourMode(activity::ColourMode::kDensity);
  std::vector<const mission::ActivityTrack*> all;
  for (const mission::ActivityTrack& t : tracks) all.push_back(&t);
  const activity::DensityGrid grid = activity::CountObservations(all, m->loaded.map.geo_referenced);
  ASSERT_GT(grid.max, 0u);
  EXPECT_EQ(view.legend().title.rfind("Observations per ", 0), 0u) << view.legend().title;
  ASSERT_FALSE(view.legend().entries.empty());
  EXPECT_EQ(view.legend().entries.back().label, std::to_string(grid.max));
  // The densest cell, on screen: warm (heat colours are red over green or grey ground).
  int best = 0;
  for (int i = 1; i < grid.cols * grid.rows; ++i) {
    if (grid.counts[static_cast<size_t>(i)] > grid.counts[static_cast<size_t>(best)]) best = i;
  }
  const Eigen::Vector2d hottest =
      grid.origin + grid.cell * Eigen::Vector2d(best % grid.cols + 0.5, best / grid.cols + 0.5);
  view.zoomAt(4, view.widgetFromMap(hottest));
  ASSERT_TRUE(loaded.WaitForTiles());
  const QPoint at = view.widgetFromMap(hottest).toPoint();
  ASSERT_TRUE(view.rect().contains(at));
  const QColor heat = view.grab().toImage().pixelColor(at);
  view.setShowTracks(false);
  const QColor ground = view.grab().toImage().pixelColor(at);
  view.setShowTracks(true);
  EXPECT_GT(heat.red() - heat.blue(), ground.red() - ground.blue() + 30)
      << "heat " << heat.name().toStdString() << " over " << ground.name().toStdString();
  // Filtered out, the heat map goes; its legend counts nothing.
  MosaicView::TrackFilter filter;
  double first_start = tracks.front().start_s;
  for (const auto& t : tracks) first_start = std::min(first_start, t.start_s);
  filter.end_s = first_start - 1;
  view.setTrackFilter(filter);
  EXPECT_EQ(view.grab().toImage().pixelColor(at), ground);
  view.setTrackFilter({});
  EXPECT_EQ(view.grab().toImage().pixelColor(at), heat);
  // Back to speed: the tracks again, with the speed legend.
  view.setColourMode(activity::ColourMode::kSpeed);
  EXPECT_EQ(view.legend().title.find("Observations"), std::string::npos);
}

TEST(MosaicViewTest, OverlaysAreDrawn) {
  const testing::TestMission* m = SmallMission();
  ASSERT_NE(m, nullptr);
  LoadedView loaded(*m, /*show_tracks=*/false);
  MosaicView& view = loaded.view;
  ASSERT_TRUE(loaded.WaitForTiles());
  const QImage plain = view.grab().toImage();
  view.setShowKeyFrameOutlines(true);
  const QImage outlines = view.grab().toImage();
  EXPECT_NE(plain, outlines);
  // The marker: red at its centre's arm, white outline beside it.
  const Eigen::Vector2d covered = CoveredPoint(m->loaded);
  view.setShowKeyFrameOutlines(false);
  view.setMarker(covered);
  const QImage marked = view.grab().toImage();
  const QPoint c = view.widgetFromMap(covered).toPoint();
  const QColor arm = marked.pixelColor(c + QPoint(6, 0));
  EXPECT_GT(arm.red(), 180);
  EXPECT_LT(arm.green(), 60);
  view.setMarker(std::nullopt);
  EXPECT_EQ(view.grab().toImage(), plain);
  // Uncertainty ellipses (of the adjusted nodes' corners) change the picture. Zoomed in on the
  // corner with the widest one: they are a metre or so across.
  std::optional<Eigen::Vector2d> corner;
  double widest = 0;
  for (const mission::KeyFrameRecord& k : m->loaded.key_frames) {
    if (!k.node || k.covariance.isZero()) continue;
    const Eigen::Matrix2d cov = track::TransferCovariance(k.map_from_frame, k.covariance, {0, 0});
    const double semi_major = track::ConfidenceEllipse({0, 0}, cov, 0.95).semi_major;
    if (semi_major > widest) {
      widest = semi_major;
      corner = k.map_from_frame.col(2).head<2>() / k.map_from_frame(2, 2);
    }
  }
  ASSERT_TRUE(corner.has_value()) << "no node key frame has a covariance";
  std::printf("[ mosaic ] widest 95 %% corner ellipse: semi-major %.3f map units\n", widest);
  view.setShowUncertainty(true);
  view.zoomAt(1e9, view.widgetFromMap(*corner));
  ASSERT_TRUE(loaded.WaitForTiles());
  const QImage with = view.grab().toImage();
  view.setShowUncertainty(false);
  const QImage without = view.grab().toImage();
  EXPECT_NE(with, without);
}

TEST(MosaicViewTest, EmptyViewShowsHint) {
  MosaicView view;
  view.resize(600, 400);
  const QImage image = view.grab().toImage();
  // The hint's text is light on the dark background in the middle.
  int light = 0;
  for (int x = 0; x < 600; ++x) light += image.pixelColor(x, 200).lightness() > 120 ? 1 : 0;
  EXPECT_GT(light, 20);
  EXPECT_FALSE(view.showingPreview());
}

frontend::KeyFramePreview MakePreview(int id, double shift_x, int brightness) {
  frontend::KeyFramePreview preview;
  preview.image.id = track::KeyFrameId{id};
  preview.image.scale = 4;  // 160x90 grey for a 640x360 video
  preview.image.grey = cv::Mat(90, 160, CV_8UC1, cv::Scalar(brightness));
  preview.preview_from_frame = Eigen::Matrix3d::Identity();
  preview.preview_from_frame(0, 2) = shift_x;
  return preview;
}

TEST(MosaicViewTest, PreviewShowsKeyFramesUntilTheMosaicExists) {
  const testing::TestMission* m = SmallMission();
  ASSERT_NE(m, nullptr);
  MosaicView view;
  view.resize(800, 600);
  view.addPreviewKeyFrame(MakePreview(0, 0, 200));
  view.addPreviewKeyFrame(MakePreview(1, 500, 90));
  EXPECT_EQ(view.previewKeyFrameCount(), 2);
  EXPECT_TRUE(view.showingPreview());
  // Fitted to both frames (0..1140 x 0..360 in the first frame's pixels, y down).
  EXPECT_LT(view.mapFromWidget(QPointF(400, 100)).y(), view.mapFromWidget(QPointF(400, 500)).y());
  QImage image = view.grab().toImage();
  EXPECT_NEAR(image.pixelColor(view.widgetFromMap({100, 180}).toPoint()).lightness(), 200, 4);
  EXPECT_NEAR(image.pixelColor(view.widgetFromMap({1000, 180}).toPoint()).lightness(), 90, 4);
  EXPECT_TRUE(IsBackground(image, view.widgetFromMap({570, 600})));
  // A mission still without a mosaic keeps the preview; one with a mosaic replaces it.
  mission::Mission early = m->loaded;
  early.progress.mosaic = false;
  early.pyramid.reset();
  view.setMission(Share(early), PathOf(*m));
  EXPECT_TRUE(view.showingPreview());
  view.setMission(Share(m->loaded), PathOf(*m));
  EXPECT_FALSE(view.showingPreview());
  EXPECT_TRUE(m->loaded.map.geo_referenced);
  EXPECT_GT(view.mapFromWidget(QPointF(400, 100)).y(), view.mapFromWidget(QPointF(400, 500)).y());
  view.setMission(nullptr, QString());
  EXPECT_TRUE(view.showingPreview());
  view.clearPreview();
  EXPECT_FALSE(view.showingPreview());
  EXPECT_EQ(view.previewKeyFrameCount(), 0);
}

// --- TileCache -------------------------------------------------------------------------------

TEST(TileCacheTest, MissingFileIsReportedOnceNamingIt) {
  const testing::TestMission* m = SmallMission();
  ASSERT_NE(m, nullptr);
  TileCache cache;
  QSignalSpy failed(&cache, &TileCache::failed);
  QSignalSpy ready(&cache, &TileCache::tileReady);
  cache.setMission("/nonexistent/sortie-7.saker", m->loaded.pyramid);
  cache.request(0, 0, 0);
  cache.request(0, 1, 0);
  ASSERT_TRUE(WaitUntil([&] { return ready.count() == 2; }));
  ASSERT_EQ(failed.count(), 1);
  EXPECT_TRUE(failed.at(0).at(0).toString().contains("sortie-7.saker"))
      << failed.at(0).at(0).toString().toStdString();
  EXPECT_EQ(cache.state(0, 0, 0), TileCache::State::kEmpty);
  EXPECT_TRUE(cache.tile(0, 0, 0).isNull());
  cache.request(0, 0, 0);  // known: not asked again
  EXPECT_EQ(cache.queuedCount(), 0);
}

TEST(TileCacheTest, CorruptFileIsReportedNamingIt) {
  const testing::TestMission* m = SmallMission();
  ASSERT_NE(m, nullptr);
  const std::filesystem::path path = saker::testing::MakeTempDir("saker-tiles") / "broken.saker";
  {
    std::ofstream out(path, std::ios::binary);
    out << "this is not an SQLite database, whatever its name says";
  }
  TileCache cache;
  QSignalSpy failed(&cache, &TileCache::failed);
  cache.setMission(QString::fromStdString(path.string()), m->loaded.pyramid);
  cache.requestVisible({{0, 0, 0}, {0, 1, 0}, {1, 0, 0}});
  ASSERT_TRUE(failed.wait(10000));
  EXPECT_TRUE(failed.at(0).at(0).toString().contains("broken.saker"));
  ASSERT_TRUE(WaitUntil([&] { return cache.queuedCount() == 0; }));
  EXPECT_EQ(failed.count(), 1);
}

// A mission file with two tiles: one copied from the small mission, one of bytes that are no
// image; the other tiles have no row.
std::filesystem::path WriteTwoTileMission(const testing::TestMission& m,
                                          mission::EncodedTile* good) {
  const std::filesystem::path path = saker::testing::MakeTempDir("saker-tiles") / "two.saker";
  auto source = mission::MissionStore::Open(m.mission.string());
  EXPECT_TRUE(source.ok());
  const int top = m.loaded.pyramid->levels - 1;
  auto bytes = (*source)->ReadTile(top, 0, 0);
  EXPECT_TRUE(bytes.ok() && bytes->has_value());
  *good = {top, 0, 0, **bytes};
  auto store = mission::MissionStore::Create(path.string());
  EXPECT_TRUE(store.ok()) << store.status().ToString();
  EXPECT_TRUE((*store)->Save(m.loaded).ok());
  EXPECT_TRUE((*store)->WriteTiles({*good, {0, 0, 0, {1, 2, 3, 4, 5}}}).ok());
  return path;
}

TEST(TileCacheTest, MissingTileIsEmptyAndBadTileReportedOnce) {
  const testing::TestMission* m = SmallMission();
  ASSERT_NE(m, nullptr);
  mission::EncodedTile good;
  const std::filesystem::path path = WriteTwoTileMission(*m, &good);
  TileCache cache;
  QSignalSpy failed(&cache, &TileCache::failed);
  QSignalSpy ready(&cache, &TileCache::tileReady);
  cache.setMission(QString::fromStdString(path.string()), m->loaded.pyramid);
  cache.request(good.level, 0, 0);
  cache.request(0, 1, 0);  // no row
  ASSERT_TRUE(WaitUntil([&] { return ready.count() == 2; }));
  EXPECT_EQ(failed.count(), 0);
  const QImage image = cache.tile(good.level, 0, 0);
  ASSERT_FALSE(image.isNull());
  EXPECT_EQ(image.width(), m->loaded.pyramid->tile_size);
  EXPECT_EQ(image.format(), QImage::Format_ARGB32_Premultiplied);
  EXPECT_EQ(cache.state(0, 1, 0), TileCache::State::kEmpty);
  cache.request(0, 1, 0);  // remembered as empty
  EXPECT_EQ(cache.queuedCount(), 0);
  // The undecodable tile: reported once, naming the file, then empty.
  cache.request(0, 0, 0);
  ASSERT_TRUE(failed.wait(10000));
  const QString message = failed.at(0).at(0).toString();
  EXPECT_TRUE(message.contains("two.saker")) << message.toStdString();
  EXPECT_EQ(cache.state(0, 0, 0), TileCache::State::kEmpty);
  // A reload asks again, and reports again (once).
  cache.setMission(QString::fromStdString(path.string()), m->loaded.pyramid);
  EXPECT_FALSE(cache.tile(good.level, 0, 0).isNull());  // kept while it reloads
  EXPECT_EQ(cache.state(good.level, 0, 0), TileCache::State::kUnknown);
  cache.request(0, 0, 0);
  ASSERT_TRUE(failed.wait(10000));
  EXPECT_EQ(failed.count(), 2);
}

// A tile whose PNG header claims 40000 x 40000 pixels (a 100-byte decompression bomb) ended the
// GUI: cv::imdecode threw on the cache's worker thread. It is reported, naming the file, and the
// cache goes on serving the other tiles.
TEST(TileCacheTest, DecompressionBombTileIsReportedNotDecoded) {
  const testing::TestMission* m = SmallMission();
  ASSERT_NE(m, nullptr);
  mission::EncodedTile good;
  const std::filesystem::path path = WriteTwoTileMission(*m, &good);
  {
    auto store = mission::MissionStore::Open(path.string(), mission::OpenMode::kReadWrite);
    ASSERT_TRUE(store.ok());
    ASSERT_TRUE((*store)->WriteTiles({{0, 0, 0, saker::testing::PngBomb(40000, 40000)}}).ok());
  }
  TileCache cache;
  QSignalSpy failed(&cache, &TileCache::failed);
  QSignalSpy ready(&cache, &TileCache::tileReady);
  cache.setMission(QString::fromStdString(path.string()), m->loaded.pyramid);
  cache.request(0, 0, 0);
  ASSERT_TRUE(failed.wait(10000));
  const QString message = failed.at(0).at(0).toString();
  EXPECT_TRUE(message.contains("two.saker")) << message.toStdString();
  EXPECT_TRUE(message.contains("40000x40000")) << message.toStdString();
  EXPECT_EQ(cache.state(0, 0, 0), TileCache::State::kEmpty);
  cache.request(good.level, 0, 0);
  ASSERT_TRUE(WaitUntil([&] { return !cache.tile(good.level, 0, 0).isNull(); }));
}

TEST(TileCacheTest, NewestRequestsWinAndBudgetEvicts) {
  const testing::TestMission* m = SmallMission();
  ASSERT_NE(m, nullptr);
  const mission::PyramidInfo& p = *m->loaded.pyramid;
  TileCache cache;
  QSignalSpy ready(&cache, &TileCache::tileReady);
  cache.setMission(PathOf(*m), p);
  // Every level-0 tile, then at once only the top one: the backlog is dropped.
  QList<TileKey> all;
  const int columns = (p.width + p.tile_size - 1) / p.tile_size;
  const int rows = (p.height + p.tile_size - 1) / p.tile_size;
  for (int y = 0; y < rows; ++y) {
    for (int x = 0; x < columns; ++x) all.push_back({0, x, y});
  }
  ASSERT_GE(all.size(), 6);
  cache.requestVisible(all);
  cache.requestVisible({{p.levels - 1, 0, 0}});
  ASSERT_TRUE(
      WaitUntil([&] { return cache.state(p.levels - 1, 0, 0) == TileCache::State::kLoaded; }));
  QTest::qWait(200);
  int level0 = 0;
  for (const QList<QVariant>& args : ready) level0 += args.at(0).toInt() == 0 ? 1 : 0;
  EXPECT_LE(level0, 2) << "answered " << level0 << " of " << all.size() << " dropped requests";

  // A budget of three tiles keeps the three used last.
  const qint64 tile_bytes = static_cast<qint64>(p.tile_size) * p.tile_size * 4 + 64;
  cache.setByteBudget(3 * tile_bytes);
  std::vector<TileKey> loaded;
  for (const TileKey& key : all) {
    cache.request(key.level, key.x, key.y);
    ASSERT_TRUE(WaitUntil([&] { return cache.queuedCount() == 0; }));
    if (cache.state(key.level, key.x, key.y) == TileCache::State::kLoaded) loaded.push_back(key);
    EXPECT_LE(cache.bytesUsed(), cache.byteBudget());
  }
  ASSERT_GE(loaded.size(), 4u);
  const TileKey last = loaded.back(), oldest = loaded.front();
  EXPECT_FALSE(cache.tile(last.level, last.x, last.y).isNull());
  EXPECT_TRUE(cache.tile(oldest.level, oldest.x, oldest.y).isNull());
}

TEST(TileCacheTest, DestroyingWhileLoadingDoesNotHang) {
  const testing::TestMission* m = SmallMission();
  ASSERT_NE(m, nullptr);
  QElapsedTimer timer;
  timer.start();
  for (int round = 0; round < 5; ++round) {
    auto view = std::make_unique<MosaicView>();
    view->resize(1200, 900);
    view->setMission(Share(m->loaded), PathOf(*m));
    view->zoomAt(1e9, QPointF(600, 450));
    view->grab();         // queues the visible tiles
    QTest::qWait(round);  // let a few answers be in flight, or none
    view.reset();
    QTest::qWait(5);  // answers posted to the gone cache must be dropped
  }
  EXPECT_LT(timer.elapsed(), 5000);
}

// The mission with `count` tracks: copies of its own shifted about the mosaic.
mission::Mission WithManyTracks(const mission::Mission& mission, size_t count, size_t* points) {
  mission::Mission many = mission;
  std::mt19937 random(7);
  std::uniform_real_distribution<double> shift(-150, 150);
  many.tracks.clear();
  *points = 0;
  while (many.tracks.size() < count) {
    for (mission::ActivityTrack t : mission.tracks) {
      const Eigen::Vector2d offset(shift(random), shift(random));
      for (mission::TrackPoint& p : t.points) p.map += offset;
      *points += t.points.size();
      many.tracks.push_back(std::move(t));
    }
  }
  return many;
}

TEST(MosaicViewTest, ManyTracksSettleToTheirExactDrawing) {
  const testing::TestMission* m = SmallMission();
  ASSERT_NE(m, nullptr);
  ASSERT_FALSE(m->loaded.tracks.empty());
  size_t points = 0;
  const auto many = Share(WithManyTracks(m->loaded, 3000, &points));
  const std::vector<Qt::Key> keys = {Qt::Key_Plus, Qt::Key_Right, Qt::Key_Up};
  const auto wait_for_tiles = [](MosaicView& view) {
    return WaitUntil([&] {
      view.update();
      return view.tilesComplete() && view.tileCache()->queuedCount() == 0;
    });
  };
  MosaicView moved;
  moved.resize(900, 600);
  moved.setMission(many, PathOf(*m));
  moved.show();
  ASSERT_TRUE(wait_for_tiles(moved));
  moved.repaint();
  // Zooming and panning: if drawing the tracks is slow, the last drawing follows the map for a
  // moment...
  for (const Qt::Key key : keys) {
    QTest::keyClick(&moved, key);
    moved.repaint();
  }
  ASSERT_TRUE(wait_for_tiles(moved));
  // ...and once the view is still, the tracks are drawn afresh: exactly as a view first painted
  // there draws them.
  QTest::qWait(600);
  MosaicView direct;
  direct.resize(900, 600);
  direct.setMission(many, PathOf(*m));
  for (const Qt::Key key : keys) QTest::keyClick(&direct, key);  // before any paint
  direct.show();
  ASSERT_TRUE(wait_for_tiles(direct));
  EXPECT_EQ(moved.grab().toImage(), direct.grab().toImage());
}

// --- Measurements (printed, not asserted) -----------------------------------------------------

// Average time of `repeats` synchronous paints, `before` called ahead of each.
double AveragePaintMs(MosaicView& view, int repeats, const std::function<void()>& before = {}) {
  view.repaint();
  double total_ms = 0;
  for (int i = 0; i < repeats; ++i) {
    if (before) before();
    QElapsedTimer timer;
    timer.start();
    view.repaint();
    total_ms += static_cast<double>(timer.nsecsElapsed()) / 1e6;
  }
  return total_ms / repeats;
}

TEST(MosaicViewBenchmark, PaintTime) {
  const testing::TestMission* m = SmallMission();
  ASSERT_NE(m, nullptr);
  size_t points = 0;
  const mission::Mission many = WithManyTracks(m->loaded, 3000, &points);
  const std::array<std::pair<const char*, const mission::Mission*>, 2> cases = {
      {{"small mission", &m->loaded}, {"3000 tracks", &many}}};
  for (const auto& [name, data] : cases) {
    MosaicView view;
    view.resize(1280, 800);
    view.setMission(Share(*data), PathOf(*m));
    view.show();
    ASSERT_TRUE(WaitUntil([&] {
      view.update();
      return view.tilesComplete() && view.tileCache()->queuedCount() == 0;
    }));
    // Every track drawn afresh (as after a change of colours or filter, or a settled pan).
    const double full = AveragePaintMs(view, 10, [&] { view.setShowTracks(true); });
    // A paint that changes nothing about the tracks (a tile arrived, the marker moved).
    const double cached = AveragePaintMs(view, 10);
    // One step of a pan, as the mouse moves.
    const double pan = AveragePaintMs(view, 10, [&] { QTest::keyClick(&view, Qt::Key_Right); });
    view.setShowTracks(false);
    const double tiles_only = AveragePaintMs(view, 10);
    std::printf(
        "[ paint  ] %s (%zu tracks, 1280x800): all tracks drawn %.1f ms, tracks unchanged "
        "%.1f ms, pan step %.1f ms, tiles only %.1f ms\n",
        name, data->tracks.size(), full, cached, pan, tiles_only);
  }
  std::printf("[ paint  ] (the 3000 tracks hold %zu points)\n", points);
}

// --- Screenshots (SAKER_UI_SCREENSHOTS) ---------------------------------------------------------

TEST(MosaicViewScreenshots, Screenshots) {
  if (qEnvironmentVariableIsEmpty("SAKER_UI_SCREENSHOTS")) {
    GTEST_SKIP() << "set SAKER_UI_SCREENSHOTS to write the screenshots";
  }
  const testing::TestMission* m = SmallMission();
  ASSERT_NE(m, nullptr);
  QString dir = qEnvironmentVariable("SAKER_UI_SCREENSHOTS");
  if (!QFileInfo(dir).isDir()) dir = "/root/diag";
  LoadedView loaded(*m);
  MosaicView& view = loaded.view;
  view.resize(1000, 700);
  ASSERT_TRUE(loaded.WaitForTiles());
  for (const activity::ColourMode mode :
       {activity::ColourMode::kSpeed, activity::ColourMode::kDirection,
        activity::ColourMode::kVisit, activity::ColourMode::kTime}) {
    view.setColourMode(mode);
    const QString file =
        QDir(dir).filePath(QString("view-%1.png").arg(activity::ColourModeName(mode)));
    ASSERT_TRUE(view.grab().save(file)) << file.toStdString();
    std::printf("[ shot   ] %s\n", qPrintable(file));
  }
  view.setColourMode(activity::ColourMode::kSpeed);
  view.setShowKeyFrameOutlines(true);
  view.setShowUncertainty(true);
  view.setMarker(CoveredPoint(m->loaded));
  view.zoomAt(4, view.widgetFromMap(CoveredPoint(m->loaded)));
  ASSERT_TRUE(loaded.WaitForTiles());
  const QString zoomed = QDir(dir).filePath("view-zoomed.png");
  ASSERT_TRUE(view.grab().save(zoomed));
  std::printf("[ shot   ] %s\n", qPrintable(zoomed));

  // The preview as the front end would feed it: the key frames' grey images at half size, placed
  // relative to the first one.
  MosaicView preview;
  preview.resize(1000, 700);
  video::ReaderOptions options;
  options.want_bgr = false;
  options.want_grey = true;
  auto reader = video::VideoReader::Open(m->video.string(), options);
  ASSERT_TRUE(reader.ok()) << reader.status().ToString();
  const Eigen::Matrix3d first_from_map = m->loaded.key_frames.front().map_from_frame.inverse();
  for (const mission::KeyFrameRecord& k : m->loaded.key_frames) {
    auto frame = (*reader)->ReadFrame(k.frame_index);
    ASSERT_TRUE(frame.ok()) << frame.status().ToString();
    frontend::KeyFramePreview p;
    p.image.id = track::KeyFrameId{k.id};
    p.image.frame_index = k.frame_index;
    p.image.scale = 2;
    cv::resize(frame->grey, p.image.grey, cv::Size(), 0.5, 0.5, cv::INTER_AREA);
    p.preview_from_frame = first_from_map * k.map_from_frame;
    p.preview_from_frame /= p.preview_from_frame(2, 2);
    preview.addPreviewKeyFrame(p);
  }
  const QString previewed = QDir(dir).filePath("view-preview.png");
  ASSERT_TRUE(preview.grab().save(previewed));
  std::printf("[ shot   ] %s\n", qPrintable(previewed));
}

}  // namespace
}  // namespace saker::ui
