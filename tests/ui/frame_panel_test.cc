// The frame panel and its recall worker under QT_QPA_PLATFORM=offscreen, on the small simulated
// mission: the frame shown is the observation's frame (checked bit for bit against an independent
// decode, and against the simulator's truth), the mark sits on the target, stepping and playback
// work from buttons and keys, stale requests are dropped, a missing video is explained.
// Recall latencies are printed (and measured on the demo mission when it is present).

#include "ui/frame_panel.h"

#include "core/mission/mission_store.h"
#include "core/video/video_reader.h"
#include "tests/testing/test_data.h"
#include "tests/ui/ui_testing.h"
#include "ui/frame_recall.h"

#include <Eigen/Geometry>
#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <QDateTime>
#include <QDir>
#include <QElapsedTimer>
#include <QFile>
#include <QLabel>
#include <QPushButton>
#include <QRegularExpression>
#include <QSignalSpy>
#include <QTest>
#include <QToolButton>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <random>
#include <vector>

namespace saker::ui {
namespace {

using testing::SmallMission;
using testing::TestMission;
using testing::WaitUntil;

// The offscreen platform warns on every relayout of a top-level window; the panel is one here.
const QtMessageHandler kPreviousHandler = qInstallMessageHandler(
    [](QtMsgType type, const QMessageLogContext& context, const QString& message) {
      if (message.contains(QLatin1String("propagateSizeHints"))) return;
      if (kPreviousHandler != nullptr) {
        kPreviousHandler(type, context, message);
      } else {
        std::fprintf(stderr, "%s\n", qPrintable(qFormatLogMessage(type, context, message)));
      }
    });

// How far the observation may lie from the simulator's target centre: the detector sees the
// moving blob, whose centroid shifts with the background it uncovers (a car is ~20 px long here).
constexpr double kTruthTolerancePx = 12;

std::shared_ptr<const mission::Mission> Shared(const TestMission& test) {
  return std::make_shared<const mission::Mission>(test.loaded);
}

QString VideoOf(const TestMission& test) { return QString::fromStdString(test.video.string()); }

// The track with the most observations (the one most worth stepping through).
size_t LongestTrack(const mission::Mission& mission) {
  size_t best = 0;
  for (size_t i = 0; i < mission.tracks.size(); ++i) {
    if (mission.tracks[i].points.size() > mission.tracks[best].points.size()) best = i;
  }
  return best;
}

// Distance from `image_px` to the nearest visible truth target in `frame`.
double NearestTruthDistance(const sim::Truth& truth, int64_t frame, const Eigen::Vector2d& px) {
  double best = std::numeric_limits<double>::infinity();
  for (const sim::TargetTruth& target : truth.targets) {
    const auto& sample = target.samples.at(static_cast<size_t>(frame));
    if (!sample.visible) continue;
    best = std::min(best, (sample.image_px - px).norm());
  }
  return best;
}

FrameRecall* RecallOf(FramePanel& panel) { return panel.findChild<FrameRecall*>(); }

// Waits for the panel's video to be indexed, so what follows measures recall, not warm-up.
bool WaitWarm(FramePanel& panel, int timeout_ms = 60000) {
  FrameRecall* recall = RecallOf(panel);
  return recall != nullptr && WaitUntil([recall] { return recall->isWarm(); }, timeout_ms);
}

// Shows an observation and waits until its frame is on screen.
bool ShowAndWait(FramePanel& panel, size_t track, size_t point, int timeout_ms = 30000) {
  QSignalSpy shown(&panel, &FramePanel::frameShown);
  panel.showObservation(track, point);
  return !shown.isEmpty() || shown.wait(timeout_ms);
}

void MaybeScreenshot(QWidget& widget, const char* name) {
  if (qEnvironmentVariableIsEmpty("SAKER_UI_SCREENSHOTS")) return;
  QDir().mkpath(QStringLiteral("/root/diag"));
  const QString path = QStringLiteral("/root/diag/frame-panel-%1.png").arg(QLatin1String(name));
  EXPECT_TRUE(widget.grab().save(path)) << path.toStdString();
  std::printf("screenshot: %s\n", qPrintable(path));
}

struct Stats {
  double median = 0, max = 0;
};
Stats Summarise(std::vector<double> values) {
  std::sort(values.begin(), values.end());
  if (values.empty()) return {};
  return {values[values.size() / 2], values.back()};
}

TEST(FramePanelTest, ShowsTheObservedFrameWithTheMarkOnTheTarget) {
  const TestMission* test = SmallMission();
  ASSERT_NE(test, nullptr);
  const auto mission = Shared(*test);
  ASSERT_FALSE(mission->tracks.empty());
  FramePanel panel;
  panel.resize(640, 520);
  panel.show();
  panel.setMission(mission, VideoOf(*test));
  EXPECT_TRUE(panel.videoAvailable());
  EXPECT_EQ(panel.displayedFrame(), -1);
  ASSERT_TRUE(WaitWarm(panel));

  const size_t track_index = LongestTrack(*mission);
  const auto& track = mission->tracks[track_index];
  const size_t point_index = track.points.size() / 2;
  const mission::TrackPoint& point = track.points[point_index];
  QSignalSpy changed(&panel, &FramePanel::observationChanged);
  ASSERT_TRUE(ShowAndWait(panel, track_index, point_index));
  EXPECT_EQ(panel.displayedFrame(), point.frame);
  ASSERT_TRUE(panel.markVisible());
  EXPECT_DOUBLE_EQ(panel.markImagePosition().x(), point.image.x());
  EXPECT_DOUBLE_EQ(panel.markImagePosition().y(), point.image.y());
  ASSERT_EQ(changed.count(), 1);
  EXPECT_EQ(changed.at(0).at(0).value<size_t>(), track_index);
  EXPECT_EQ(changed.at(0).at(1).value<size_t>(), point_index);
  ASSERT_TRUE(panel.currentObservation());
  EXPECT_EQ(*panel.currentObservation(), std::make_pair(track_index, point_index));
  std::printf("first recall after warm-up (640x360): %.1f ms (decode %.1f ms)\n",
              panel.lastRecallMs(), panel.lastDecodeMs());

  // The right frame: bit-identical to an independent decode of that frame, and different from
  // its neighbour (the camera moves), so an off-by-one would show.
  auto reader = video::VideoReader::Open(test->video.string());
  ASSERT_TRUE(reader.ok()) << reader.status().ToString();
  auto expected = (*reader)->ReadFrame(point.frame);
  ASSERT_TRUE(expected.ok()) << expected.status().ToString();
  cv::Mat expected_rgb;
  cv::cvtColor(expected->bgr, expected_rgb, cv::COLOR_BGR2RGB);
  const QImage& shown = panel.displayedImage();
  ASSERT_EQ(shown.width(), expected_rgb.cols);
  ASSERT_EQ(shown.height(), expected_rgb.rows);
  ASSERT_EQ(shown.format(), QImage::Format_RGB888);
  auto differs_from = [&shown](const cv::Mat& rgb) {
    for (int y = 0; y < rgb.rows; ++y) {
      if (std::memcmp(shown.constScanLine(y), rgb.ptr(y), static_cast<size_t>(rgb.cols) * 3)) {
        return true;
      }
    }
    return false;
  };
  EXPECT_FALSE(differs_from(expected_rgb))
      << "the panel shows another picture than frame " << point.frame;
  auto neighbour = (*reader)->ReadFrame(point.frame + 1);
  ASSERT_TRUE(neighbour.ok());
  cv::Mat neighbour_rgb;
  cv::cvtColor(neighbour->bgr, neighbour_rgb, cv::COLOR_BGR2RGB);
  EXPECT_TRUE(differs_from(neighbour_rgb));

  // The mark is on a real target: the simulator put one within tolerance in that very frame.
  const double distance = NearestTruthDistance(test->truth_data, point.frame, point.image);
  EXPECT_LT(distance, kTruthTolerancePx) << "track " << track.id << " frame " << point.frame;
  std::printf("track %lld frame %lld: observation %.1f px from the nearest truth target\n",
              static_cast<long long>(track.id), static_cast<long long>(point.frame), distance);

  // The info grid describes the observation.
  EXPECT_EQ(panel.findChild<QLabel*>("frameValue")->text(), QString::number(point.frame));
  EXPECT_TRUE(panel.findChild<QLabel*>("trackValue")->text().startsWith(QString::number(track.id)));
  EXPECT_EQ(panel.findChild<QLabel*>("visitValue")->text(), QString::number(track.visit));
  EXPECT_TRUE(panel.findChild<QLabel*>("headingValue")->text().contains(QChar(0x00B0)));
  const QString speed = panel.findChild<QLabel*>("speedValue")->text();
  if (track.speed_mps) {
    EXPECT_TRUE(speed.contains("m/s") && speed.contains("km/h")) << speed.toStdString();
  } else {
    EXPECT_TRUE(speed.contains("px/s")) << speed.toStdString();
  }
  ASSERT_TRUE(track.confidence.has_value());
  EXPECT_EQ(panel.findChild<QLabel*>("confidenceValue")->text(),
            QString::number(*track.confidence, 'f', 2));
  const auto& record = mission->frames.at(static_cast<size_t>(point.frame));
  ASSERT_EQ(record.index, point.frame);
  if (record.utc_us) {
    const QString utc = panel.findChild<QLabel*>("utcValue")->text();
    EXPECT_TRUE(
        QRegularExpression(R"(^\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\.\d{3}Z$)").match(utc).hasMatch())
        << utc.toStdString();
    EXPECT_EQ(QDateTime::fromString(utc, Qt::ISODateWithMs).toMSecsSinceEpoch(),
              *record.utc_us / 1000)
        << utc.toStdString();
  }
  MaybeScreenshot(panel, "observation");
}

// An observation the object was not seen at (track::FillGaps) is marked dashed and says so; the
// seen one beside it is not. The small mission's longest track with one of its points flagged,
// should it have none of its own.
TEST(FramePanelTest, AnInterpolatedObservationIsMarkedAsNotSeen) {
  const TestMission* test = SmallMission();
  ASSERT_NE(test, nullptr);
  auto mission = std::make_shared<mission::Mission>(test->loaded);
  const size_t track_index = LongestTrack(*mission);
  auto& points = mission->tracks[track_index].points;
  ASSERT_GE(points.size(), 3u);
  const auto own = std::find_if(points.begin() + 1, points.end() - 1,
                                [](const mission::TrackPoint& p) { return p.interpolated; });
  const size_t filled =
      own != points.end() - 1 ? static_cast<size_t>(own - points.begin()) : points.size() / 2;
  points[filled].interpolated = true;
  points[filled - 1].interpolated = false;
  FramePanel panel;
  panel.resize(640, 520);
  panel.show();
  panel.setMission(mission, VideoOf(*test));
  ASSERT_TRUE(WaitWarm(panel));
  ASSERT_TRUE(ShowAndWait(panel, track_index, filled - 1));
  ASSERT_TRUE(panel.markVisible());
  EXPECT_FALSE(panel.markInterpolated());
  EXPECT_FALSE(panel.findChild<QLabel*>("trackValue")->text().contains("interpolated"));
  ASSERT_TRUE(ShowAndWait(panel, track_index, filled));
  ASSERT_TRUE(panel.markVisible());
  EXPECT_TRUE(panel.markInterpolated());
  EXPECT_DOUBLE_EQ(panel.markImagePosition().x(), points[filled].image.x());
  QLabel* track_value = panel.findChild<QLabel*>("trackValue");
  EXPECT_TRUE(track_value->text().contains("(interpolated: observation"))
      << track_value->text().toStdString();
  // The note survives painting (the label sets its tooltip as it paints).
  track_value->repaint();
  EXPECT_TRUE(track_value->toolTip().contains("Not seen in this frame"))
      << track_value->toolTip().toStdString();
  MaybeScreenshot(panel, "interpolated");
}

// Where frame pixel (x, y) of a frame of `frame` size is drawn on the panel's canvas (the frame
// fitted and centred, pixel centres at integers).
QPoint OnCanvas(const QWidget& canvas, const QSize& frame, double x, double y) {
  const double scale = std::min(static_cast<double>(canvas.width()) / frame.width(),
                                static_cast<double>(canvas.height()) / frame.height());
  return QPoint(
      static_cast<int>((canvas.width() - frame.width() * scale) / 2 + (x + 0.5) * scale),
      static_cast<int>((canvas.height() - frame.height() * scale) / 2 + (y + 0.5) * scale));
}

// The overlay mask layer: off by default; when on, the cells of the displayed frame's mask are
// tinted over the frame and the rest is untouched; a frame that no mask covers draws none.
// Judging a target: zoom in the frame, the chip, north in the frame, save the frame, and the
// speed and heading at the observation beside the track's averages.
TEST(FramePanelTest, ZoomChipNorthSaveAndSpeedNow) {
  const TestMission* test = SmallMission();
  ASSERT_NE(test, nullptr);
  const auto mission = Shared(*test);
  ASSERT_TRUE(mission->map.geo_referenced);
  FramePanel panel;
  panel.resize(640, 520);
  panel.show();
  panel.setMission(mission, VideoOf(*test));
  ASSERT_TRUE(WaitWarm(panel));
  const size_t track_index = LongestTrack(*mission);
  const auto& track = mission->tracks[track_index];
  const size_t point_index = track.points.size() / 2;
  const mission::TrackPoint& point = track.points[point_index];
  ASSERT_TRUE(ShowAndWait(panel, track_index, point_index));

  // The chip: the target enlarged, its middle the frame around the target.
  const QImage chip = panel.chipImage();
  ASSERT_FALSE(chip.isNull());
  EXPECT_EQ(chip.width(), chip.height());
  EXPECT_GE(chip.width(), 96);
  // Save Frame: the frame at its own size.
  const auto dir = saker::testing::MakeTempDir("saker-frame-save");
  const QString saved = QString::fromStdString((dir / "frame.png").string());
  ASSERT_TRUE(panel.saveFrame(saved));
  const QImage read(saved);
  EXPECT_EQ(read.size(), panel.displayedImage().size());
  EXPECT_FALSE(panel.saveFrame(QString::fromStdString((dir / "missing" / "f.png").string())));
  EXPECT_FALSE(panel.errorText().isEmpty());

  // Zoom: 1 is the whole frame, 16 the most.
  EXPECT_DOUBLE_EQ(panel.zoom(), 1);
  panel.setZoom(3);
  EXPECT_DOUBLE_EQ(panel.zoom(), 3);
  panel.setZoom(100);
  EXPECT_DOUBLE_EQ(panel.zoom(), 16);
  panel.setZoom(0.2);
  EXPECT_DOUBLE_EQ(panel.zoom(), 1);

  // North: a step along it in the frame goes north on the map (forward through the frame's
  // homography, the inverse of how the panel found it).
  const std::optional<double> north = panel.northInFrame();
  ASSERT_TRUE(north.has_value());
  const mission::FrameRecord* record = nullptr;
  for (const auto& f : mission->frames) {
    if (f.index == point.frame) record = &f;
  }
  ASSERT_NE(record, nullptr);
  ASSERT_TRUE(record->map_from_frame.has_value());
  const Eigen::Matrix3d& h = *record->map_from_frame;
  const Eigen::Vector2d step(std::sin(*north), -std::cos(*north));
  const Eigen::Vector2d from = (h * point.image.homogeneous()).hnormalized();
  const Eigen::Vector2d to = (h * (point.image + 5 * step).homogeneous()).hnormalized();
  const Eigen::Vector2d moved = to - from;
  EXPECT_GT(moved.y(), 0);
  EXPECT_LT(std::abs(moved.x()), 0.05 * moved.y()) << moved.transpose();

  // Speed and heading: the averages, then "now" at the observation.
  auto* speed = panel.findChild<QLabel*>("speedValue");
  auto* heading = panel.findChild<QLabel*>("headingValue");
  ASSERT_NE(speed, nullptr);
  ASSERT_NE(heading, nullptr);
  EXPECT_TRUE(speed->text().contains("; now ")) << speed->text().toStdString();
  EXPECT_TRUE(heading->text().contains("; now ")) << heading->text().toStdString();
  const double now = speed->text().section("; now ", 1).toDouble();
  EXPECT_GT(now, 0.3 * track.speed_mps.value_or(1));
  EXPECT_LT(now, 3 * track.speed_mps.value_or(1) + 1);
}

// Scrubbing (frames asked for faster than they decode): frames reach the screen while the drag
// goes on, always newer than the one shown, and the last one asked for ends on screen.
TEST(FramePanelTest, ScrubbingShowsFramesInOrderAndEndsOnTheLast) {
  const TestMission* test = SmallMission();
  ASSERT_NE(test, nullptr);
  const auto mission = Shared(*test);
  ASSERT_GT(mission->frames.size(), 80u);
  FramePanel panel;
  panel.resize(640, 520);
  panel.show();
  panel.setMission(mission, VideoOf(*test));
  ASSERT_TRUE(WaitWarm(panel));
  std::vector<int64_t> shown;
  QObject::connect(&panel, &FramePanel::frameShown,
                   [&](int64_t frame, double) { shown.push_back(frame); });
  int64_t last = -1;
  for (size_t i = 10; i < 70; ++i) {
    last = mission->frames[i].index;
    panel.showFrame(last);
    QTest::qWait(2);
  }
  ASSERT_TRUE(WaitUntil([&] { return !shown.empty() && shown.back() == last; }, 10000));
  EXPECT_GE(shown.size(), 2u);
  EXPECT_TRUE(std::is_sorted(shown.begin(), shown.end()));
  EXPECT_EQ(std::adjacent_find(shown.begin(), shown.end()), shown.end()) << "each shown once";
  EXPECT_EQ(panel.displayedFrame(), last);
  EXPECT_FALSE(panel.markVisible() && panel.currentObservation().has_value() &&
               mission->tracks[panel.currentObservation()->first]
                       .points[panel.currentObservation()->second]
                       .frame != last);
}

TEST(FramePanelTest, DrawsTheOverlayMaskOfTheDisplayedFrameWhenAsked) {
  const TestMission* test = SmallMission();
  ASSERT_NE(test, nullptr);
  auto copy = std::make_shared<mission::Mission>(test->loaded);
  const size_t track_index = LongestTrack(*copy);
  const auto& points = copy->tracks[track_index].points;
  ASSERT_GE(points.size(), 2u);
  const size_t point_index = points.size() / 2;
  ASSERT_NE(points[point_index].frame, points[point_index + 1].frame);
  // A mask of the observation's frame alone: a block of cells at the top left, pixels
  // [16, 96) x [8, 40).
  mission::OverlayRecord mask;
  mask.first_frame = mask.last_frame = points[point_index].frame;
  mask.cell_px = 8;
  mask.cols = (copy->source.width + 7) / 8;
  mask.rows = (copy->source.height + 7) / 8;
  mask.cells.assign(static_cast<size_t>(mask.cols * mask.rows), 0);
  for (int y = 1; y < 5; ++y) {
    for (int x = 2; x < 12; ++x) mask.cells[static_cast<size_t>(y * mask.cols + x)] = 1;
  }
  copy->overlays = {mask};
  const std::shared_ptr<const mission::Mission> mission = copy;

  FramePanel panel;
  panel.resize(640, 520);
  panel.show();
  panel.setMission(mission, VideoOf(*test));
  ASSERT_TRUE(WaitWarm(panel));
  ASSERT_TRUE(ShowAndWait(panel, track_index, point_index));
  EXPECT_FALSE(panel.overlayMaskVisible());
  EXPECT_EQ(panel.drawnOverlayMask(), nullptr);

  QWidget* canvas = panel.findChild<QWidget*>(QStringLiteral("frameCanvas"));
  ASSERT_NE(canvas, nullptr);
  const auto on_canvas = [&](double x, double y) {
    return OnCanvas(*canvas, panel.displayedImage().size(), x, y);
  };
  const QImage before = canvas->grab().toImage();
  panel.setOverlayMaskVisible(true);
  EXPECT_EQ(panel.drawnOverlayMask(), &mission->overlays[0]);
  const QImage after = canvas->grab().toImage();
  ASSERT_EQ(before.size(), after.size());
  const QColor masked_before = before.pixelColor(on_canvas(56, 24));
  const QColor masked_after = after.pixelColor(on_canvas(56, 24));
  EXPECT_GT(masked_after.blue(), masked_before.blue() + 20)
      << "the mask's cell is not tinted: " << masked_before.name().toStdString() << " -> "
      << masked_after.name().toStdString();
  for (const QPoint& p : {on_canvas(110, 24), on_canvas(56, 50), on_canvas(300, 200)}) {
    EXPECT_EQ(before.pixel(p), after.pixel(p)) << "off the mask at " << p.x() << ", " << p.y();
  }
  MaybeScreenshot(panel, "overlay-mask");

  // The next observation's frame has no mask: nothing drawn; hiding the layer draws none either.
  QSignalSpy shown(&panel, &FramePanel::frameShown);
  panel.nextObservation();
  ASSERT_TRUE(!shown.isEmpty() || shown.wait(30000));
  EXPECT_EQ(panel.displayedFrame(), points[point_index + 1].frame);
  EXPECT_EQ(panel.drawnOverlayMask(), nullptr);
  ASSERT_TRUE(ShowAndWait(panel, track_index, point_index));
  EXPECT_EQ(panel.drawnOverlayMask(), &mission->overlays[0]);
  panel.setOverlayMaskVisible(false);
  EXPECT_EQ(panel.drawnOverlayMask(), nullptr);
  EXPECT_EQ(canvas->grab().toImage().pixel(on_canvas(56, 24)), before.pixel(on_canvas(56, 24)));
}

// The sky mask of a low oblique view, with the overlay layer: the part of the displayed frame
// above its sky line is tinted, the rest untouched; a frame without a sky line draws none.
TEST(FramePanelTest, DrawsTheSkyMaskOfTheDisplayedFrameWhenAsked) {
  const TestMission* test = SmallMission();
  ASSERT_NE(test, nullptr);
  auto copy = std::make_shared<mission::Mission>(test->loaded);
  const size_t track_index = LongestTrack(*copy);
  const auto& points = copy->tracks[track_index].points;
  ASSERT_GE(points.size(), 2u);
  const size_t point_index = points.size() / 2;
  ASSERT_NE(points[point_index].frame, points[point_index + 1].frame);
  const auto frame_record = std::find_if(
      copy->frames.begin(), copy->frames.end(),
      [&](const mission::FrameRecord& f) { return f.index == points[point_index].frame; });
  ASSERT_NE(frame_record, copy->frames.end());
  frame_record->sky_line = mission::SkyLine{100, 0.05};  // row 100 at the left, 116 at x 320
  const std::shared_ptr<const mission::Mission> mission = copy;

  FramePanel panel;
  panel.resize(640, 520);
  panel.show();
  panel.setMission(mission, VideoOf(*test));
  ASSERT_TRUE(WaitWarm(panel));
  ASSERT_TRUE(ShowAndWait(panel, track_index, point_index));
  EXPECT_FALSE(panel.drawnSkyLine().has_value());
  QWidget* canvas = panel.findChild<QWidget*>(QStringLiteral("frameCanvas"));
  ASSERT_NE(canvas, nullptr);
  const auto on_canvas = [&](double x, double y) {
    return OnCanvas(*canvas, panel.displayedImage().size(), x, y);
  };
  const QImage before = canvas->grab().toImage();
  panel.setOverlayMaskVisible(true);
  ASSERT_TRUE(panel.drawnSkyLine().has_value());
  EXPECT_EQ(panel.drawnSkyLine()->y0, 100);
  const QImage after = canvas->grab().toImage();
  for (const QPoint& p : {on_canvas(40, 40), on_canvas(300, 60)}) {
    const QColor b = before.pixelColor(p), a = after.pixelColor(p);
    EXPECT_GT(a.red() - a.blue(), b.red() - b.blue() + 20)
        << "the sky is not tinted at " << p.x() << ", " << p.y() << ": " << b.name().toStdString()
        << " -> " << a.name().toStdString();
  }
  for (const QPoint& p : {on_canvas(40, 140), on_canvas(300, 200)}) {
    EXPECT_EQ(before.pixel(p), after.pixel(p))
        << "below the sky line at " << p.x() << ", " << p.y();
  }
  MaybeScreenshot(panel, "sky-mask");

  QSignalSpy shown(&panel, &FramePanel::frameShown);
  panel.nextObservation();
  ASSERT_TRUE(!shown.isEmpty() || shown.wait(30000));
  EXPECT_FALSE(panel.drawnSkyLine().has_value());
  ASSERT_TRUE(ShowAndWait(panel, track_index, point_index));
  EXPECT_TRUE(panel.drawnSkyLine().has_value());
  panel.setOverlayMaskVisible(false);
  EXPECT_FALSE(panel.drawnSkyLine().has_value());
}

TEST(FramePanelTest, ObservationsOfEveryTrackLieOnTruthTargets) {
  const TestMission* test = SmallMission();
  ASSERT_NE(test, nullptr);
  const auto mission = Shared(*test);
  FramePanel panel;
  panel.resize(480, 400);
  panel.show();
  panel.setMission(mission, VideoOf(*test));
  ASSERT_TRUE(WaitWarm(panel));
  int near = 0;
  for (size_t t = 0; t < mission->tracks.size(); ++t) {
    const auto& points = mission->tracks[t].points;
    const size_t p = points.size() / 2;
    ASSERT_TRUE(ShowAndWait(panel, t, p));
    ASSERT_EQ(panel.displayedFrame(), points[p].frame);
    const QPointF mark = panel.markImagePosition();
    const double distance = NearestTruthDistance(test->truth_data, panel.displayedFrame(),
                                                 Eigen::Vector2d(mark.x(), mark.y()));
    if (distance < kTruthTolerancePx) ++near;
  }
  std::printf("%d of %zu tracks: mid observation within %.0f px of a truth target\n", near,
              mission->tracks.size(), kTruthTolerancePx);
  // A short false track may come from parallax or noise; nearly all must be real targets.
  EXPECT_GE(near, static_cast<int>(std::ceil(0.8 * static_cast<double>(mission->tracks.size()))));
}

TEST(FramePanelTest, StepsThroughObservationsWithButtonsAndKeys) {
  const TestMission* test = SmallMission();
  ASSERT_NE(test, nullptr);
  const auto mission = Shared(*test);
  FramePanel panel;
  panel.resize(640, 520);
  panel.show();
  panel.activateWindow();
  ASSERT_TRUE(QTest::qWaitForWindowActive(&panel));
  panel.setMission(mission, VideoOf(*test));
  const size_t t = LongestTrack(*mission);
  const auto& points = mission->tracks[t].points;
  ASSERT_GE(points.size(), 6u);
  ASSERT_TRUE(ShowAndWait(panel, t, 2));
  panel.setFocus();

  QSignalSpy changed(&panel, &FramePanel::observationChanged);
  auto expect_at = [&](size_t p, const char* how) {
    ASSERT_TRUE(WaitUntil([&] { return panel.displayedFrame() == points[p].frame; }, 10000))
        << how << ": expected frame " << points[p].frame << ", shown " << panel.displayedFrame();
    ASSERT_TRUE(panel.currentObservation());
    EXPECT_EQ(panel.currentObservation()->second, p) << how;
    ASSERT_FALSE(changed.isEmpty()) << how;
    EXPECT_EQ(changed.last().at(1).value<size_t>(), p) << how;
    EXPECT_DOUBLE_EQ(panel.markImagePosition().x(), points[p].image.x()) << how;
    EXPECT_DOUBLE_EQ(panel.markImagePosition().y(), points[p].image.y()) << how;
  };
  auto* next = panel.findChild<QToolButton*>("nextButton");
  auto* previous = panel.findChild<QToolButton*>("previousButton");
  ASSERT_NE(next, nullptr);
  ASSERT_NE(previous, nullptr);
  QTest::mouseClick(next, Qt::LeftButton);
  expect_at(3, "next button");
  QTest::mouseClick(previous, Qt::LeftButton);
  expect_at(2, "previous button");
  QTest::keyClick(&panel, Qt::Key_Right);
  expect_at(3, "Right");
  QTest::keyClick(&panel, Qt::Key_Period);
  expect_at(4, "period");
  QTest::keyClick(&panel, Qt::Key_Left);
  expect_at(3, "Left");
  QTest::keyClick(&panel, Qt::Key_Comma);
  expect_at(2, "comma");

  // At the first observation, previous is disabled and does nothing.
  ASSERT_TRUE(ShowAndWait(panel, t, 0));
  EXPECT_FALSE(previous->isEnabled());
  panel.previousObservation();
  EXPECT_EQ(panel.currentObservation()->second, 0u);
  EXPECT_TRUE(next->isEnabled());
}

// The UTC row says "no metadata" only for a frame that has none: a frame the mission has no
// record of is unknown, a frame with metadata but no time stamp says so.
TEST(FramePanelTest, SaysNoMetadataOnlyWhenTheFrameHasNone) {
  const TestMission* test = SmallMission();
  ASSERT_NE(test, nullptr);
  const size_t t = LongestTrack(test->loaded);
  const mission::TrackPoint& point = test->loaded.tracks[t].points[0];
  const auto record =
      std::find_if(test->loaded.frames.begin(), test->loaded.frames.end(),
                   [&](const mission::FrameRecord& f) { return f.index == point.frame; });
  ASSERT_NE(record, test->loaded.frames.end());
  ASSERT_TRUE(record->utc_us && record->sensor);
  const size_t at = static_cast<size_t>(record - test->loaded.frames.begin());
  // The UTC row for the track's first observation, the frames changed by `change`.
  const auto utc_text = [&](const std::function<void(std::vector<mission::FrameRecord>&)>& change) {
    auto copy = std::make_shared<mission::Mission>(test->loaded);
    change(copy->frames);
    FramePanel panel;
    panel.setMission(copy, QString());  // no video: the row is the observation's frame
    panel.showObservation(t, 0);
    auto* utc = panel.findChild<QLabel*>("utcValue");
    return utc != nullptr ? utc->text() : QString("(no UTC row)");
  };
  const QString with_time = utc_text([](auto&) {});
  EXPECT_TRUE(with_time.endsWith("Z")) << with_time.toStdString();
  // Processing has not stored the frames yet.
  const QString unrecorded = utc_text([](auto& frames) { frames.clear(); });
  EXPECT_FALSE(unrecorded.contains("metadata")) << unrecorded.toStdString();
  // Metadata without the time stamp (the sensor position is there).
  const QString no_time = utc_text([at](auto& frames) { frames[at].utc_us.reset(); });
  EXPECT_FALSE(no_time.contains("no metadata")) << no_time.toStdString();
  EXPECT_TRUE(no_time.contains("time stamp")) << no_time.toStdString();
  // No metadata at all.
  const QString none = utc_text([at](auto& frames) {
    frames[at].utc_us.reset();
    frames[at].sensor.reset();
    frames[at].metadata_corners.reset();
  });
  EXPECT_TRUE(none.contains("no metadata")) << none.toStdString();
}

TEST(FramePanelTest, MissingVideoShowsMessageAndOffersToLocateIt) {
  const TestMission* test = SmallMission();
  ASSERT_NE(test, nullptr);
  const auto mission = Shared(*test);
  FramePanel panel;
  panel.resize(480, 400);
  panel.show();
  const QString missing = QStringLiteral("/nonexistent/sortie-7/video.ts");
  panel.setMission(mission, missing);
  EXPECT_FALSE(panel.videoAvailable());
  auto* message = panel.findChild<QLabel*>("missingVideoMessage");
  auto* locate = panel.findChild<QPushButton*>("locateVideoButton");
  ASSERT_NE(message, nullptr);
  ASSERT_NE(locate, nullptr);
  EXPECT_TRUE(message->isVisible());
  EXPECT_TRUE(locate->isVisible());
  EXPECT_EQ(message->text(), QStringLiteral("The video of this mission is not at %1. Frame recall "
                                            "needs the video.")
                                 .arg(missing));
  QSignalSpy locate_requested(&panel, &FramePanel::locateVideoRequested);
  QTest::mouseClick(locate, Qt::LeftButton);
  EXPECT_EQ(locate_requested.count(), 1);
  MaybeScreenshot(panel, "missing-video");

  // Observations can still be selected; no frame appears and nothing crashes.
  panel.showObservation(0, 0);
  QTest::qWait(200);
  EXPECT_EQ(panel.displayedFrame(), -1);
  EXPECT_TRUE(panel.currentObservation());
  EXPECT_FALSE(panel.markVisible());

  // An empty path (the owner did not find the video) names where the mission says it was.
  panel.setMission(mission, QString());
  EXPECT_FALSE(panel.videoAvailable());
  EXPECT_TRUE(message->text().contains(QString::fromStdString(mission->source.path)))
      << message->text().toStdString();

  // Locating it brings the frames back.
  panel.setMission(mission, VideoOf(*test));
  EXPECT_TRUE(panel.videoAvailable());
  EXPECT_FALSE(locate->isVisible());
  ASSERT_TRUE(ShowAndWait(panel, 0, 0));
  EXPECT_EQ(panel.displayedFrame(), mission->tracks[0].points[0].frame);
}

TEST(FramePanelTest, ReloadingTheMissionOnTheSameVideoKeepsItWarm) {
  const TestMission* test = SmallMission();
  ASSERT_NE(test, nullptr);
  const auto mission = Shared(*test);
  FramePanel panel;
  panel.resize(480, 400);
  panel.show();
  panel.setMission(mission, VideoOf(*test));
  ASSERT_TRUE(WaitWarm(panel));
  ASSERT_TRUE(ShowAndWait(panel, 0, 0));
  // Processing progress reloads the mission: the observation is cleared, the index is kept.
  panel.setMission(Shared(*test), VideoOf(*test));
  EXPECT_FALSE(panel.currentObservation());
  EXPECT_EQ(panel.displayedFrame(), -1);
  EXPECT_TRUE(RecallOf(panel)->isWarm());
  ASSERT_TRUE(ShowAndWait(panel, 0, 1));
  EXPECT_EQ(panel.displayedFrame(), mission->tracks[0].points[1].frame);
}

TEST(FramePanelTest, StaleRequestsAreDropped) {
  const TestMission* test = SmallMission();
  ASSERT_NE(test, nullptr);
  const auto mission = Shared(*test);

  // The worker directly: 30 requests at once answer with far fewer frames, the last one last.
  {
    FrameRecall recall;
    QSignalSpy ready(&recall, &FrameRecall::videoReady);
    recall.setVideo(VideoOf(*test));
    ASSERT_TRUE(ready.wait(60000));
    EXPECT_GT(ready.at(0).at(1).toLongLong(), 30);
    QSignalSpy frames(&recall, &FrameRecall::frameReady);
    for (int i = 0; i < 30; ++i) recall.request(i * 3, static_cast<quint64>(i + 1));
    ASSERT_TRUE(
        WaitUntil([&] { return !frames.isEmpty() && frames.last().at(0).value<quint64>() == 30; }));
    QTest::qWait(200);
    std::printf("30 requests at once: %lld decoded\n", static_cast<long long>(frames.count()));
    EXPECT_LT(frames.count(), 30);
    EXPECT_EQ(frames.last().at(1).value<int64_t>(), 29 * 3);
    quint64 previous_ticket = 0;
    for (const auto& args : frames) {
      EXPECT_GT(args.at(0).value<quint64>(), previous_ticket);
      previous_ticket = args.at(0).value<quint64>();
    }
  }

  // The panel: clicking through many observations quickly shows only the last one.
  FramePanel panel;
  panel.resize(480, 400);
  panel.show();
  panel.setMission(mission, VideoOf(*test));
  ASSERT_TRUE(WaitWarm(panel));
  const size_t t = LongestTrack(*mission);
  const auto& points = mission->tracks[t].points;
  ASSERT_TRUE(ShowAndWait(panel, t, 0));
  const int64_t before = panel.displayedFrame();
  QSignalSpy shown(&panel, &FramePanel::frameShown);
  const size_t last = points.size() - 1;
  for (size_t p = 1; p <= last; p += std::max<size_t>(1, last / 20)) panel.showObservation(t, p);
  panel.showObservation(t, last);
  // Until the answer comes, the previous frame stays on screen (no flicker to blank).
  EXPECT_EQ(panel.displayedFrame(), before);
  EXPECT_FALSE(panel.displayedImage().isNull());
  ASSERT_TRUE(shown.wait(30000));
  QTest::qWait(300);
  ASSERT_EQ(shown.count(), 1);
  EXPECT_EQ(shown.at(0).at(0).value<int64_t>(), points[last].frame);
  EXPECT_EQ(panel.displayedFrame(), points[last].frame);
  EXPECT_EQ(panel.currentObservation()->second, last);
}

// A mission stores the video's frame index (schema 2): recall opens on it without the indexing
// pass, and gives the same pictures as after indexing.
TEST(FramePanelTest, TheMissionsFrameIndexSkipsTheIndexingPass) {
  const TestMission* test = SmallMission();
  ASSERT_NE(test, nullptr);
  std::vector<video::FrameIndexEntry> index;
  for (const mission::FrameRecord& f : test->loaded.frames) {
    ASSERT_TRUE(f.pts.has_value()) << "frame " << f.index << " has no stream position";
    index.push_back({f.index, *f.pts, f.time_s, f.key_frame});
  }
  const auto warm = [&](std::vector<video::FrameIndexEntry> known, double* warm_ms) {
    auto recall = std::make_unique<FrameRecall>();
    QSignalSpy ready(recall.get(), &FrameRecall::videoReady);
    recall->setVideo(VideoOf(*test), std::move(known));
    EXPECT_TRUE(ready.wait(60000));
    EXPECT_EQ(ready.at(0).at(1).toLongLong(), static_cast<int64_t>(test->loaded.frames.size()));
    *warm_ms = ready.at(0).at(3).toDouble();
    return recall;
  };
  double indexed_ms = 0, stored_ms = 0;
  auto indexed = warm({}, &indexed_ms);
  auto stored = warm(index, &stored_ms);
  std::printf("ready to recall: %.1f ms after indexing the video, %.1f ms on the stored index\n",
              indexed_ms, stored_ms);
  EXPECT_LT(stored_ms, indexed_ms);
  for (const int64_t frame : {static_cast<int64_t>(0), static_cast<int64_t>(index.size() / 2),
                              static_cast<int64_t>(index.size() - 1)}) {
    QSignalSpy a(indexed.get(), &FrameRecall::frameReady);
    QSignalSpy b(stored.get(), &FrameRecall::frameReady);
    indexed->request(frame, 1);
    stored->request(frame, 1);
    ASSERT_TRUE(!a.isEmpty() || a.wait(10000));
    ASSERT_TRUE(!b.isEmpty() || b.wait(10000));
    EXPECT_EQ(a.at(0).at(2).value<QImage>(), b.at(0).at(2).value<QImage>()) << "frame " << frame;
  }
}

TEST(FramePanelTest, RecallReportsFilesThatAreNotVideosAndFramesOutOfRange) {
  const std::filesystem::path dir = saker::testing::MakeTempDir("saker-frame-panel");
  const std::filesystem::path notes = dir / "notes-not-a-video.ts";
  std::ofstream(notes) << "Mission notes: this is plain text, not an MPEG transport stream.\n";
  FrameRecall recall;
  QSignalSpy video_failed(&recall, &FrameRecall::videoFailed);
  QSignalSpy failed(&recall, &FrameRecall::failed);
  QSignalSpy frames(&recall, &FrameRecall::frameReady);
  recall.setVideo(QString::fromStdString(notes.string()));
  recall.request(0, 7);
  ASSERT_TRUE(WaitUntil([&] { return !failed.isEmpty(); }));
  EXPECT_EQ(failed.at(0).at(0).value<quint64>(), 7u);
  const QString message = failed.at(0).at(1).toString();
  EXPECT_TRUE(message.contains("notes-not-a-video.ts")) << message.toStdString();
  ASSERT_EQ(video_failed.count(), 1);
  EXPECT_TRUE(video_failed.at(0).at(1).toString().contains("notes-not-a-video.ts"));
  EXPECT_TRUE(frames.isEmpty());

  // A frame past the end, on a real video: the message names the file and the valid range.
  const TestMission* test = SmallMission();
  ASSERT_NE(test, nullptr);
  recall.setVideo(VideoOf(*test));
  recall.request(1000000, 8);
  ASSERT_TRUE(WaitUntil([&] { return failed.count() == 2; }));
  const QString range = failed.at(1).at(1).toString();
  EXPECT_EQ(failed.at(1).at(0).value<quint64>(), 8u);
  EXPECT_TRUE(range.contains(QString::fromStdString(test->video.filename().string())))
      << range.toStdString();
  EXPECT_TRUE(range.contains("out of range")) << range.toStdString();

  // A missing file.
  recall.setVideo(QString::fromStdString((dir / "gone.ts").string()));
  recall.request(0, 9);
  ASSERT_TRUE(WaitUntil([&] { return failed.count() == 3; }));
  EXPECT_TRUE(failed.at(2).at(1).toString().contains("gone.ts"));
}

TEST(FramePanelTest, PlayAdvancesFramesWithTheMarkAndPauseStops) {
  const TestMission* test = SmallMission();
  ASSERT_NE(test, nullptr);
  const auto mission = Shared(*test);
  FramePanel panel;
  panel.resize(640, 520);
  panel.show();
  panel.activateWindow();
  ASSERT_TRUE(QTest::qWaitForWindowActive(&panel));
  panel.setMission(mission, VideoOf(*test));
  ASSERT_TRUE(WaitWarm(panel));
  const size_t t = LongestTrack(*mission);
  ASSERT_TRUE(ShowAndWait(panel, t, 0));
  panel.setFocus();
  const int64_t start = panel.displayedFrame();

  // Every frame shown during playback: the mark is on the track's observation of that frame when
  // it has one, and absent otherwise.
  int checked = 0, marked = 0;
  auto check_mark = [&](int64_t frame) {
    ++checked;
    ASSERT_TRUE(panel.currentObservation());
    const auto& track_points = mission->tracks[panel.currentObservation()->first].points;
    auto it = std::find_if(track_points.begin(), track_points.end(),
                           [frame](const mission::TrackPoint& p) { return p.frame == frame; });
    if (it == track_points.end()) {
      EXPECT_FALSE(panel.markVisible()) << "frame " << frame;
      return;
    }
    ++marked;
    EXPECT_TRUE(panel.markVisible()) << "frame " << frame;
    EXPECT_DOUBLE_EQ(panel.markImagePosition().x(), it->image.x()) << "frame " << frame;
    EXPECT_EQ(panel.currentObservation()->second, static_cast<size_t>(it - track_points.begin()));
  };
  std::vector<int64_t> shown_frames;
  QObject::connect(&panel, &FramePanel::frameShown, &panel, [&](int64_t frame, double) {
    shown_frames.push_back(frame);
    check_mark(frame);
  });
  QSignalSpy playing(&panel, &FramePanel::playingChanged);
  QElapsedTimer clock;
  clock.start();
  QTest::keyClick(&panel, Qt::Key_Space);
  ASSERT_TRUE(panel.isPlaying());
  ASSERT_TRUE(WaitUntil([&] { return panel.displayedFrame() >= start + 10; }, 20000));
  const double seconds = static_cast<double>(clock.elapsed()) / 1000;
  std::printf("playback: 10 frames in %.2f s (video at %.1f fps)\n", seconds,
              mission->source.frame_rate);
  QTest::mouseClick(panel.findChild<QToolButton*>("playButton"), Qt::LeftButton);
  EXPECT_FALSE(panel.isPlaying());
  ASSERT_EQ(playing.count(), 2);
  const int64_t paused_at = panel.displayedFrame();
  QTest::qWait(400);
  EXPECT_EQ(panel.displayedFrame(), paused_at) << "frames kept coming after pause";
  // Sequential: every frame from the start, none skipped, none repeated.
  ASSERT_FALSE(shown_frames.empty());
  for (size_t i = 0; i < shown_frames.size(); ++i) {
    EXPECT_EQ(shown_frames[i], start + 1 + static_cast<int64_t>(i));
  }
  EXPECT_GT(checked, 0);
  EXPECT_GT(marked, 0);
  MaybeScreenshot(panel, "paused");

  // Past the end of a track: the mark disappears once the track has no observation.
  const int64_t frame_count = mission->source.frame_count;
  size_t ending = mission->tracks.size();
  for (size_t i = 0; i < mission->tracks.size(); ++i) {
    const auto& track_points = mission->tracks[i].points;
    if (track_points.size() >= 3 && track_points.back().frame + 5 < frame_count) ending = i;
  }
  ASSERT_LT(ending, mission->tracks.size()) << "no track ends before the video";
  const auto& ending_points = mission->tracks[ending].points;
  ASSERT_TRUE(ShowAndWait(panel, ending, ending_points.size() - 3));
  checked = marked = 0;
  panel.play();
  ASSERT_TRUE(
      WaitUntil([&] { return panel.displayedFrame() >= ending_points.back().frame + 3; }, 20000));
  panel.pause();
  EXPECT_GT(marked, 0);
  EXPECT_GT(checked - marked, 0) << "the mark never disappeared after the track ended";
  EXPECT_FALSE(panel.markVisible());
  EXPECT_EQ(panel.currentObservation()->second, ending_points.size() - 1);
  EXPECT_TRUE(panel.findChild<QLabel*>("frameValue")->text().contains("not observed"));
  MaybeScreenshot(panel, "after-track-end");

  // Play to the end: stops by itself on the last frame.
  std::optional<std::pair<size_t, size_t>> near_end;
  for (size_t i = 0; i < mission->tracks.size() && !near_end; ++i) {
    const auto& track_points = mission->tracks[i].points;
    for (size_t p = 0; p < track_points.size(); ++p) {
      if (track_points[p].frame >= frame_count - 25 && track_points[p].frame < frame_count - 1) {
        near_end = std::make_pair(i, p);
        break;
      }
    }
  }
  ASSERT_TRUE(near_end) << "no observation in the last second of the video";
  ASSERT_TRUE(ShowAndWait(panel, near_end->first, near_end->second));
  playing.clear();
  checked = 0;
  QTest::keyClick(&panel, Qt::Key_Space);
  ASSERT_TRUE(WaitUntil([&] { return !panel.isPlaying(); }, 60000));
  EXPECT_EQ(panel.displayedFrame(), frame_count - 1);
  EXPECT_GT(checked, 0);
  EXPECT_EQ(playing.count(), 2);  // started, stopped at the end
  EXPECT_FALSE(panel.findChild<QToolButton*>("playButton")->isEnabled());
  EXPECT_TRUE(panel.errorText().isEmpty()) << panel.errorText().toStdString();
}

TEST(FramePanelTest, RecallLatencyOnTheTestMission) {
  const TestMission* test = SmallMission();
  ASSERT_NE(test, nullptr);
  const auto mission = Shared(*test);
  FramePanel panel;
  panel.resize(640, 520);
  panel.show();
  QElapsedTimer warm;
  warm.start();
  panel.setMission(mission, VideoOf(*test));
  ASSERT_TRUE(WaitWarm(panel));
  std::printf("warm-up (640x360, %lld frames): %lld ms\n",
              static_cast<long long>(mission->source.frame_count),
              static_cast<long long>(warm.elapsed()));
  std::mt19937 random(20240521);
  std::vector<double> recall_ms, decode_ms;
  for (int i = 0; i < 30; ++i) {
    const size_t t = random() % mission->tracks.size();
    const size_t p = random() % mission->tracks[t].points.size();
    if (panel.currentObservation() == std::make_pair(t, p)) continue;
    ASSERT_TRUE(ShowAndWait(panel, t, p));
    ASSERT_EQ(panel.displayedFrame(), mission->tracks[t].points[p].frame);
    recall_ms.push_back(panel.lastRecallMs());
    decode_ms.push_back(panel.lastDecodeMs());
  }
  const Stats r = Summarise(recall_ms), d = Summarise(decode_ms);
  std::printf(
      "recall 640x360 over %zu random observations: median %.1f ms, max %.1f ms "
      "(decode median %.1f ms, max %.1f ms)\n",
      recall_ms.size(), r.median, r.max, d.median, d.max);
  EXPECT_GT(r.median, 0);
}

TEST(FramePanelTest, DestroyingWithWorkInFlightDoesNotHang) {
  const TestMission* test = SmallMission();
  ASSERT_NE(test, nullptr);
  const auto mission = Shared(*test);
  QElapsedTimer timer;
  {
    auto panel = std::make_unique<FramePanel>();
    panel->setMission(mission, VideoOf(*test));  // warming starts
    panel->showObservation(0, 0);
    QTest::qWait(20);
    timer.start();
  }
  const qint64 while_warming = timer.elapsed();
  {
    auto panel = std::make_unique<FramePanel>();
    panel->setMission(mission, VideoOf(*test));
    ASSERT_TRUE(WaitWarm(*panel));
    panel->showObservation(0, 0);  // a decode in flight
    timer.start();
  }
  const qint64 while_decoding = timer.elapsed();
  std::printf("destruction: %lld ms while warming, %lld ms with a decode in flight\n",
              static_cast<long long>(while_warming), static_cast<long long>(while_decoding));
  EXPECT_LT(while_warming, 2000);
  EXPECT_LT(while_decoding, 2000);
  QTest::qWait(100);  // queued answers for the destroyed objects must not arrive anywhere
}

// The figure that matters: the 1280x720 demo mission, when the repository has it.
TEST(FramePanelTest, RecallLatencyOnTheDemoMission) {
  const std::filesystem::path demo =
      std::filesystem::path(__FILE__).parent_path().parent_path().parent_path() / "demo";
  const std::filesystem::path mission_path = demo / "demo.saker";
  const std::filesystem::path video_path = demo / "demo.ts";
  if (!std::filesystem::exists(mission_path) || !std::filesystem::exists(video_path)) {
    GTEST_SKIP() << "demo mission not found at " << demo << " (demo.saker and demo.ts)";
  }
  auto store = mission::MissionStore::Open(mission_path.string(), mission::OpenMode::kReadOnly);
  ASSERT_TRUE(store.ok()) << store.status().ToString();
  auto loaded = (*store)->Load();
  ASSERT_TRUE(loaded.ok()) << loaded.status().ToString();
  const auto mission = std::make_shared<const mission::Mission>(std::move(loaded).value());
  ASSERT_FALSE(mission->tracks.empty());

  FramePanel panel;
  panel.resize(800, 620);
  panel.show();
  QElapsedTimer warm;
  warm.start();
  panel.setMission(mission, QString::fromStdString(video_path.string()));
  // A click straight after opening: with the frame index the mission stores (schema 2) it is
  // answered at once; a mission without one is answered once the video is indexed, with the
  // "decoding…" hint meanwhile.
  QSignalSpy shown(&panel, &FramePanel::frameShown);
  panel.showObservation(0, 0);
  ASSERT_TRUE(WaitUntil([&] { return panel.decodingHintShown() || !shown.isEmpty(); }, 5000));
  const bool hint_seen = panel.decodingHintShown();
  if (hint_seen) MaybeScreenshot(panel, "demo-warming");
  ASSERT_TRUE(!shown.isEmpty() || shown.wait(120000));
  EXPECT_FALSE(panel.decodingHintShown());
  std::printf(
      "demo: click during warm-up answered after %.0f ms (warm-up %lld ms so far; hint "
      "%s)\n",
      panel.lastRecallMs(), static_cast<long long>(warm.elapsed()),
      hint_seen ? "shown" : "not needed");
  ASSERT_TRUE(WaitWarm(panel));

  std::mt19937 random(71);
  std::vector<double> recall_ms, decode_ms;
  for (int i = 0; i < 30; ++i) {
    const size_t t = random() % mission->tracks.size();
    const size_t p = random() % mission->tracks[t].points.size();
    if (panel.currentObservation() == std::make_pair(t, p)) continue;
    ASSERT_TRUE(ShowAndWait(panel, t, p));
    ASSERT_EQ(panel.displayedFrame(), mission->tracks[t].points[p].frame);
    if (i == 0) {
      std::printf("demo: first random recall after warm-up %.1f ms\n", panel.lastRecallMs());
    }
    recall_ms.push_back(panel.lastRecallMs());
    decode_ms.push_back(panel.lastDecodeMs());
  }
  const Stats r = Summarise(recall_ms), d = Summarise(decode_ms);
  std::printf(
      "demo 1280x720 recall over %zu random observations: median %.1f ms, max %.1f ms "
      "(decode median %.1f ms, max %.1f ms); target 150 ms\n",
      recall_ms.size(), r.median, r.max, d.median, d.max);
  MaybeScreenshot(panel, "demo");
  EXPECT_EQ(panel.displayedImage().width(), 1280);

  // Playback at 25 fps across GOP boundaries: every frame shown, in order, at about real time.
  ASSERT_TRUE(ShowAndWait(panel, 0, 0));
  const int64_t play_from = panel.displayedFrame();
  if (play_from + 60 < mission->source.frame_count) {
    std::vector<int64_t> played;
    std::vector<double> play_decode_ms;
    auto connection =
        QObject::connect(&panel, &FramePanel::frameShown, &panel, [&](int64_t frame, double) {
          played.push_back(frame);
          play_decode_ms.push_back(panel.lastDecodeMs());
        });
    QElapsedTimer clock;
    clock.start();
    panel.play();
    ASSERT_TRUE(WaitUntil([&] { return panel.displayedFrame() >= play_from + 50; }, 30000));
    const double seconds = static_cast<double>(clock.elapsed()) / 1000;
    panel.pause();
    QObject::disconnect(connection);
    for (size_t i = 0; i < played.size(); ++i) {
      EXPECT_EQ(played[i], play_from + 1 + static_cast<int64_t>(i));
    }
    const Stats p = Summarise(play_decode_ms);
    std::printf(
        "demo: playback 50 frames in %.2f s (%.1f fps, video %.0f fps); decode per frame "
        "median %.1f ms, max %.1f ms\n",
        seconds, 50 / seconds, mission->source.frame_rate, p.median, p.max);
  }

  // Destruction while the 1280x720 video warms up, and with a recall decoding.
  QElapsedTimer timer;
  qint64 while_warming = 0, while_decoding = 0;
  {
    FrameRecall recall;
    recall.setVideo(QString::fromStdString(video_path.string()));
    QTest::qWait(300);
    timer.start();
  }
  while_warming = timer.elapsed();
  {
    FrameRecall recall;
    QSignalSpy ready(&recall, &FrameRecall::videoReady);
    recall.setVideo(QString::fromStdString(video_path.string()));
    ASSERT_TRUE(ready.wait(120000));
    recall.request(mission->source.frame_count - 2, 1);  // the end of a GOP: the longest decode
    QTest::qWait(5);
    timer.start();
  }
  while_decoding = timer.elapsed();
  std::printf("demo: destruction %lld ms while warming, %lld ms with a decode in flight\n",
              static_cast<long long>(while_warming), static_cast<long long>(while_decoding));
  EXPECT_LT(while_warming, 2000);
  EXPECT_LT(while_decoding, 2000);
}

}  // namespace
}  // namespace saker::ui
