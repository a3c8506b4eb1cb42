// Screen-fixed overlays: the overlay detector on hand-made change answers, and the front end on a
// small simulated clip with HUD text, a reticle and a rotating logo against its truth.

#include "core/sim/overlay.h"

#include "core/eval/front_end_accuracy.h"
#include "core/frontend/front_end.h"
#include "core/sim/simulator.h"
#include "core/sim/truth.h"
#include "core/track/overlay_mask.h"
#include "tests/testing/test_data.h"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <iostream>

namespace saker::frontend {
namespace {

// A change answer for a 320x240 frame at full resolution whose ground moved `shift_px` to the
// right since the previous frame; `changed` marks where it changed.
track::ChangeFrame Answer(int64_t frame, const cv::Rect& changed, double shift_px) {
  track::ChangeFrame c;
  c.frame = frame;
  c.scale = 1;
  c.changed = cv::Mat::zeros(240, 320, CV_8U);
  c.changed(changed).setTo(255);
  c.valid = cv::Mat(240, 320, CV_8U, cv::Scalar(255));
  c.frame_motion(0, 2) = shift_px;
  return c;
}

// The overlay window and the evidence needed at 25 fps, in frames.
int WindowFrames(const track::OverlayOptions& o) {
  return track::FrameRate(25).Frames(o.window_s, o.min_window_frames);
}

// Above the sky mask's edge nothing is learnt: the same change in place that becomes an overlay
// below the edge (burned-in text) does not above it (still clouds over a low oblique view).
TEST(OverlayDetectorTest, NothingIsLearntAboveTheSkyEdge) {
  track::OverlayOptions options;
  options.enabled = true;
  const track::HorizonLine sky{160, 100, 0};  // the sky mask's edge: row 100, level
  const auto run = [&](const std::optional<track::HorizonLine>& edge) {
    track::OverlayDetector detector(options, track::FrameRate(25));
    for (int64_t f = 0; f < WindowFrames(options); ++f) {
      track::ChangeFrame c = Answer(f, cv::Rect(16, 40, 64, 16), 1);  // above the edge
      c.changed(cv::Rect(16, 180, 64, 16)).setTo(255);                // below it
      detector.AddChange(c, 12, edge);
    }
    return detector;
  };
  const track::OverlayDetector without = run(std::nullopt);
  EXPECT_TRUE(without.Contains({40, 48}));
  EXPECT_TRUE(without.Contains({40, 188}));
  const track::OverlayDetector with = run(sky);
  EXPECT_FALSE(with.Contains({40, 48}));
  EXPECT_TRUE(with.Contains({40, 188}));
}

TEST(OverlayDetectorTest, ScreenFixedChangeBecomesOverlayAndMoversDoNot) {
  track::OverlayOptions options;
  options.enabled = true;
  track::OverlayDetector detector(options, track::FrameRate(25));
  const int window = WindowFrames(options);
  const cv::Rect hud(16, 16, 64, 16);
  int64_t f = 0;
  for (; f < window; ++f) {
    // The HUD changes in place every frame; a mover crosses the image, 4 px a frame.
    track::ChangeFrame c = Answer(f, hud, 1);
    c.changed(cv::Rect(static_cast<int>(4 * f), 150, 12, 12) & cv::Rect(0, 0, 320, 240)).setTo(255);
    detector.AddChange(c, 12);
  }
  EXPECT_TRUE(detector.Contains({40, 24}));
  EXPECT_TRUE(detector.Contains({79, 31}));
  EXPECT_FALSE(detector.Contains({150, 155}));  // the mover's path
  EXPECT_FALSE(detector.Contains({200, 60}));
  // Dilated by `dilate_cells`, no more.
  EXPECT_TRUE(detector.Contains({40, 16 + 16 + options.dilate_cells * options.cell_px - 1}));
  EXPECT_FALSE(detector.Contains({40, 16 + 16 + (options.dilate_cells + 1) * options.cell_px}));

  // Hovering (the ground still): nothing is learnt, the mask stays, even with the HUD gone.
  const track::OverlayMask before = detector.mask();
  for (const int64_t end = f + window; f < end; ++f) {
    detector.AddChange(Answer(f, cv::Rect(0, 0, 1, 1), 0), 12);
  }
  EXPECT_EQ(cv::countNonZero(before.cells != detector.mask().cells), 0);
  // Moving again without the HUD: it goes within two windows (the fraction is a running mean
  // over the window, and must fall from 1 below `off_fraction`).
  for (const int64_t end = f + 2 * window; f < end; ++f) {
    detector.AddChange(Answer(f, cv::Rect(0, 0, 1, 1), 1), 12);
  }
  EXPECT_FALSE(detector.Contains({40, 24}));

  // An overlay that appears later is found within two windows.
  for (const int64_t end = f + 2 * window; f < end; ++f) {
    detector.AddChange(Answer(f, cv::Rect(200, 100, 30, 30), 1), 12);
  }
  EXPECT_TRUE(detector.Contains({215, 115}));

  // A car keeping pace with the camera for two seconds (it stays in place in the image while the
  // ground moves, and then drifts away) does not become overlay.
  track::OverlayDetector pacing(options, track::FrameRate(25));
  for (int64_t g = 0; g < 2 * window; ++g) {
    const int x = g < 50 ? 100 : static_cast<int>(100 + 2 * (g - 50));
    track::ChangeFrame c = Answer(g, cv::Rect(0, 0, 1, 1), 1);
    c.changed(cv::Rect(x, 100, 24, 12) & cv::Rect(0, 0, 320, 240)).setTo(255);
    pacing.AddChange(c, 12);
    EXPECT_FALSE(pacing.Contains({110, 105})) << "frame " << g;
  }

  // The state carries over exactly.
  ByteWriter out;
  detector.SaveState(&out);
  track::OverlayDetector restored(options, track::FrameRate(25));
  ByteReader in(out.bytes());
  ASSERT_TRUE(restored.RestoreState(&in));
  EXPECT_TRUE(in.AtEnd());
  EXPECT_EQ(cv::countNonZero(restored.mask().cells != detector.mask().cells), 0);
  EXPECT_EQ(restored.version(), detector.version());

  // A state cut short, or whose first matrix claims more cells than it holds, is refused.
  std::vector<uint8_t> cut(out.bytes().begin(), out.bytes().end() - 1);
  ByteReader short_in(cut);
  EXPECT_FALSE(track::OverlayDetector(options, track::FrameRate(25)).RestoreState(&short_in));
  std::vector<uint8_t> grown = out.bytes();
  const int32_t rows = 1 << 16;  // after width, height (int32) and version (int64)
  std::memcpy(grown.data() + 16, &rows, sizeof(rows));
  ByteReader grown_in(grown);
  EXPECT_FALSE(track::OverlayDetector(options, track::FrameRate(25)).RestoreState(&grown_in));
}

TEST(OverlayDetectorTest, FeaturesThatStayPutWhileTheGroundMovesAreOverlay) {
  track::OverlayOptions options;
  options.enabled = true;
  track::OverlayDetector detector(options, track::FrameRate(25));
  Eigen::Matrix3d ground = Eigen::Matrix3d::Identity();
  ground(0, 2) = 3;  // the ground moves 3 px a frame to the right
  for (int64_t f = 0; f < WindowFrames(options); ++f) {
    std::vector<track::Correspondence> matches;
    // A corner of the HUD at the image's edge stays; a ground corner follows the ground; a car
    // goes its own way.
    matches.push_back({track::FeatureTrackId{1}, {4, 4}, {4.05, 3.98}});
    matches.push_back({track::FeatureTrackId{2}, {100, 100}, {103.02, 100}});
    matches.push_back({track::FeatureTrackId{3}, {200, 50}, {200, 55}});
    detector.AddFeatures(matches, ground, cv::Size(320, 240));
  }
  EXPECT_TRUE(detector.Contains({4, 4}));
  EXPECT_FALSE(detector.Contains({103, 100}));
  EXPECT_FALSE(detector.Contains({200, 55}));
  // Without ground motion nothing is learnt.
  track::OverlayDetector hover(options, track::FrameRate(25));
  for (int64_t f = 0; f < WindowFrames(options); ++f) {
    hover.AddFeatures({{track::FeatureTrackId{1}, {4, 4}, {4, 4}}}, Eigen::Matrix3d::Identity(),
                      cv::Size(320, 240));
  }
  EXPECT_FALSE(hover.Contains({4, 4}));
}

// The ground turns about the image centre (an orbit), a degree a frame; a block of text keeps its
// place in a corner. Over the last 12 frames the text's corners kept still and the ground's
// moved, all but those at the very centre of the turn. Without motion nothing can be told.
TEST(StillFeaturesTest, TextThatKeepsItsPlaceWhileTheGroundTurnsAndNothingElse) {
  constexpr int kSize = 320;
  cv::Mat texture(2 * kSize, 2 * kSize, CV_32F);
  cv::RNG rng(11);
  rng.fill(texture, cv::RNG::NORMAL, 128, 90);
  cv::GaussianBlur(texture, texture, cv::Size(0, 0), 2.5);
  const cv::Rect text(12, 12, 90, 40);
  const auto frame = [&](double degrees) {
    cv::Mat turned, grey;
    const cv::Mat m = cv::getRotationMatrix2D(cv::Point2f(kSize, kSize), degrees, 1.0);
    cv::warpAffine(texture, turned, m, texture.size(), cv::INTER_LINEAR);
    turned(cv::Rect(kSize / 2, kSize / 2, kSize, kSize)).convertTo(grey, CV_8U);
    for (int x = text.x; x + 7 <= text.x + text.width; x += 11) {
      cv::rectangle(grey, cv::Rect(x, text.y, 7, text.height), cv::Scalar(15), cv::FILLED);
      cv::rectangle(grey, cv::Rect(x + 2, text.y + 3, 3, text.height - 12), cv::Scalar(240),
                    cv::FILLED);
    }
    return grey;
  };
  const auto run = [&](double degrees_a_frame, int frames) {
    track::TrackerOptions options;
    options.processing_width = 0;
    options.max_history = 13;
    track::FeatureTracker tracker(options, track::FrameRate(25));
    for (int f = 0; f < frames; ++f) tracker.Process(f, frame(degrees_a_frame * f));
    EXPECT_GT(tracker.matches().size(), 50u);
    const std::vector<track::FeatureTrackId> still =
        track::StillFeatures(tracker, tracker.matches(), 12, 1, 1.0, 0.2, 0.5);
    int in_text = 0, elsewhere = 0;
    for (const track::Correspondence& m : tracker.matches()) {
      const bool is_still = std::binary_search(still.begin(), still.end(), m.id);
      // On the text or at its edge (a corner of a glyph against the ground).
      const cv::Rect grown(text.x - 6, text.y - 6, text.width + 12, text.height + 12);
      const bool on_text =
          grown.contains(cv::Point(static_cast<int>(m.target.x()), static_cast<int>(m.target.y())));
      in_text += is_still && on_text;
      elsewhere += is_still && !on_text;
      // The ground that kept still is about the centre of the turn.
      if (is_still && !on_text) {
        EXPECT_LT((m.target - Eigen::Vector2d(kSize / 2.0, kSize / 2.0)).norm(), 30)
            << m.target.transpose();
      }
    }
    return std::make_pair(in_text, elsewhere);
  };
  const auto [in_text, elsewhere] = run(1.0, 14);
  EXPECT_GE(in_text, 5);
  EXPECT_EQ(elsewhere, 0);
  // Two frames into the turn only the one-frame window is known: the text is found all the same,
  // with some of the ground that turned by less than 0.5 px (within 29 px of the centre at a
  // degree a frame).
  const auto [early, early_elsewhere] = run(1.0, 3);
  EXPECT_GE(early, 5);
  EXPECT_LE(early_elsewhere, 20);
  const auto [hover, hover_elsewhere] = run(0.0, 14);
  EXPECT_EQ(hover + hover_elsewhere, 0);
}

TEST(OverlayMasksTest, ATargetIsJudgedByTheMasksOfItsFrameAndTheLaterOnesOfItsSegment) {
  // Two masks handed out one after the other: the first covers the top-left cell, the second
  // that cell and the one to its right (more evidence).
  track::OverlayMask first, second;
  first.first_frame = 100, first.last_frame = 199;
  first.cells = cv::Mat::zeros(4, 4, CV_8U);
  first.cells.at<uint8_t>(0, 0) = 1;
  second.first_frame = 200, second.last_frame = 299;
  second.cells = first.cells.clone();
  second.cells.at<uint8_t>(0, 1) = 1;
  const std::vector<track::OverlayMask> masks = {first, second};
  const auto target = [](int64_t from, int64_t to, const Eigen::Vector2d& at) {
    track::TargetTrack t;
    for (int64_t f = from; f <= to; ++f) {
      track::TargetObservation o;
      o.frame = f;
      o.position = at;
      t.observations.push_back(o);
    }
    return t;
  };
  const Eigen::Vector2d left(3, 3), right(11, 3), elsewhere(27, 27);
  // Ended before any mask existed, on the overlay: judged by the segment's masks.
  EXPECT_TRUE(track::OnOverlayMasks(target(10, 20, left), masks, {}, 0.5));
  EXPECT_TRUE(track::OnOverlayMasks(target(10, 20, right), masks, {}, 0.5));
  // ... but not across a chain break.
  EXPECT_FALSE(track::OnOverlayMasks(target(10, 20, left), masks, {50}, 0.5));
  // During the first mask, on a cell only the later one has.
  EXPECT_TRUE(track::OnOverlayMasks(target(150, 160, right), masks, {}, 0.5));
  // During the second mask, not on the first's cells afterwards; after the last mask, nothing.
  EXPECT_FALSE(track::OnOverlayMasks(target(150, 160, elsewhere), masks, {}, 0.5));
  EXPECT_FALSE(track::OnOverlayMasks(target(300, 320, left), masks, {}, 0.5));
  // Half of its observations on the mask (frames 290-299 of 290-309) is enough at 0.5.
  EXPECT_TRUE(track::OnOverlayMasks(target(290, 309, left), masks, {}, 0.5));
  EXPECT_FALSE(track::OnOverlayMasks(target(290, 309, left), masks, {}, 0.6));
  EXPECT_FALSE(track::OnOverlayMasks(target(10, 20, left), {}, {}, 0.5));
}

// A target that stays put in the image while the ground moves is screen-fixed, and is judged on
// the mask grown by a few cells: the end of a text line the evidence has not covered yet. One that
// moves, or stays put over a hovering camera, is judged on the mask's own cells.
TEST(OverlayMasksTest, AScreenFixedTargetBesideTheMaskIsOnIt) {
  track::OverlayMask mask;
  mask.first_frame = 0, mask.last_frame = 99;
  mask.cells = cv::Mat::zeros(10, 20, CV_8U);
  mask.cells.colRange(0, 8).rowRange(8, 10).setTo(1);  // a text line at the bottom left
  const std::vector<track::OverlayMask> masks = {mask};
  const auto target = [](const Eigen::Vector2d& from, const Eigen::Vector2d& step) {
    track::TargetTrack t;
    for (int64_t f = 40; f < 64; ++f) {
      track::TargetObservation o;
      o.frame = f;
      o.position = from + static_cast<double>(f - 40) * step;
      t.observations.push_back(o);
    }
    return t;
  };
  // The ground moving 2 px a frame (46 px over frames 41-63), or not at all.
  const auto moving = [](int64_t first, int64_t last, const Eigen::Vector2d&) {
    return 2.0 * static_cast<double>(last - first);
  };
  const auto hovering = [](int64_t, int64_t, const Eigen::Vector2d&) { return 0.0; };
  // Two cells right of the text, jittering by a pixel.
  track::TargetTrack beside = target({81, 72}, {0, 0});
  for (size_t i = 0; i < beside.observations.size(); i += 2)
    beside.observations[i].position.x() += 1;
  EXPECT_TRUE(track::ScreenFixed(beside, 3, 0.8, 0, 12, moving));
  EXPECT_FALSE(track::ScreenFixed(beside, 3, 0.8, 0, 12, hovering));
  // The change blob of a line of HUD text: its centroid jumps by 4 px in a sixth of the frames,
  // as other digits change.
  track::TargetTrack text = beside;
  for (size_t i = 0; i < text.observations.size(); i += 6) text.observations[i].position.y() -= 4;
  EXPECT_TRUE(track::ScreenFixed(text, 3, 0.8, 0, 12, moving));
  EXPECT_FALSE(track::ScreenFixed(text, 3, 1.0, 0, 12, moving));
  EXPECT_FALSE(track::OnOverlayMasks(beside, masks, {}, 0.5));
  EXPECT_TRUE(track::OnOverlayMasks(beside, masks, {}, 0.5, 3));
  // A car driving past the same place is not fixed.
  const track::TargetTrack driving = target({81, 60}, {0, 1});
  EXPECT_FALSE(track::ScreenFixed(driving, 3, 0.8, 0.15, 12, moving));
  // The blob of HUD text drifting by 10 px along the line (0.4 px a frame against the ground's 2
  // px) as its digits change: fixed within 15 % of the ground's motion (46 px, so 6.9 px).
  const track::TargetTrack drifting = target({81, 72}, {-0.4, 0});
  EXPECT_TRUE(track::ScreenFixed(drifting, 3, 0.8, 0.15, 12, moving));
  EXPECT_FALSE(track::ScreenFixed(drifting, 3, 0.8, 0, 12, moving));
  // Four cells away is not beside it.
  EXPECT_FALSE(track::OnOverlayMasks(target({97, 72}, {0, 0}), masks, {}, 0.5, 3));
}

TEST(OverlayDetectorTest, OptionsAreValidated) {
  track::OverlayOptions options;
  EXPECT_TRUE(options.Validate().ok());
  options.window_s = 0;
  EXPECT_FALSE(options.Validate().ok());
  options = {};
  options.off_fraction = options.on_fraction + 0.1;
  EXPECT_FALSE(options.Validate().ok());
  options = {};
  options.cell_px = 0;
  EXPECT_FALSE(options.Validate().ok());
  options = {};
  options.min_ground_shift_px = 0;
  EXPECT_FALSE(options.Validate().ok());
  options = {};
  options.fixed_share = 0;
  EXPECT_FALSE(options.Validate().ok());
  options = {};
  options.fixed_ground_fraction = 1;
  EXPECT_FALSE(options.Validate().ok());
}

// The pixels an overlay draws in the frame at `time_s`: painted over black and over white.
cv::Mat OverlayPixels(const sim::OverlayOptions& overlay, int width, int height, double time_s) {
  sim::OverlayPainter painter(overlay, width, height);
  cv::Mat black = cv::Mat::zeros(height, width, CV_8UC3);
  cv::Mat white(height, width, CV_8UC3, cv::Scalar(255, 255, 255));
  painter.Paint({}, time_s, &black);
  painter.Paint({}, time_s, &white);
  cv::Mat grey_black, grey_white;
  cv::cvtColor(black, grey_black, cv::COLOR_BGR2GRAY);
  cv::cvtColor(white, grey_white, cv::COLOR_BGR2GRAY);
  return (grey_black > 0) | (grey_white < 255);
}

// A flight of 640x360 frames into `output`.
sim::SimulationOptions SmallFlight(const std::filesystem::path& output) {
  sim::SimulationOptions options;
  options.output = output;
  options.camera.width = 640;
  options.camera.height = 360;
  return options;
}

// Burned-in text and a reticle keep their place while the ground moves. Until the overlay mask
// knows them (seconds of evidence), their features went into the ground motion, and where the
// ground moves slowly they lie within the robust fit's threshold and pull the estimate towards no
// motion. Those that kept still while the rest moved are left out of the fit from the first
// frames: the first second's frame-to-frame error is close to that of the flight without them
// (measured 0.061 px, against 0.191 with them and 0.042 without the text).
TEST(OverlayFrontEndTest, TextThatKeepsStillDoesNotPullTheFirstSecondsGroundMotion) {
  const std::filesystem::path dir = saker::testing::MakeTempDir("saker-overlay-still");
  sim::SimulationOptions options = SmallFlight(dir / "hud.ts");
  options.duration_s = 3;
  options.overlay.hud_text = true;
  options.overlay.reticle = true;
  ASSERT_TRUE(sim::Simulate(options).ok());
  StatusOr<sim::Truth> truth = sim::ReadTruth(options.TruthPath());
  ASSERT_TRUE(truth.ok());
  sim::SimulationOptions clean = options;
  clean.output = dir / "clean.ts";
  clean.overlay = sim::OverlayOptions();
  ASSERT_TRUE(sim::Simulate(clean).ok());
  // The mean corner error of the frame-to-frame homographies of the first second.
  const auto first_second_px = [&](const FrontEndOptions& front,
                                   const sim::SimulationOptions& video) {
    StatusOr<FrontEndResult> result = RunFrontEnd(video.output.string(), front);
    EXPECT_TRUE(result.ok()) << result.status().ToString();
    if (!result.ok()) return -1.0;
    StatusOr<eval::FrontEndEvaluation> evaluation = eval::EvaluateFrontEnd(*result, *truth);
    EXPECT_TRUE(evaluation.ok()) << evaluation.status().ToString();
    if (!evaluation.ok()) return -1.0;
    const std::vector<double>& errors = evaluation->homography.errors_px;
    const size_t n = std::min<size_t>(errors.size(), 25);
    EXPECT_EQ(n, 25u);
    double sum = 0;
    for (size_t i = 0; i < n; ++i) sum += errors[i];
    return sum / std::max<size_t>(1, n);
  };
  const double with = first_second_px(FrontEndOptions(), options);
  FrontEndOptions off;
  off.overlays.enabled = false;
  const double without = first_second_px(off, options);
  const double plain = first_second_px(FrontEndOptions(), clean);
  std::cout << "first second's corner error: " << with << " px with the still features left out, "
            << without << " px with them, " << plain << " px on the flight without the text\n";
  EXPECT_GE(with, 0);
  EXPECT_LT(with, 0.5 * without);
  EXPECT_LT(with, 1.8 * plain);
}

TEST(OverlayFrontEndTest, NoTargetOnTheOverlayAndTheMaskCoversIt) {
  const std::filesystem::path dir = saker::testing::MakeTempDir("saker-overlay");
  sim::SimulationOptions options = SmallFlight(dir / "hud.ts");
  options.flight.altitude_m = 200;
  options.duration_s = 12;
  options.targets.cars = 60;
  options.overlay.hud_text = true;
  options.overlay.reticle = true;
  options.overlay.logo = sim::LogoMotion::kRotating;
  StatusOr<sim::SimulationSummary> summary = sim::Simulate(options);
  ASSERT_TRUE(summary.ok()) << summary.status().ToString();
  StatusOr<sim::Truth> truth = sim::ReadTruth(options.TruthPath());
  ASSERT_TRUE(truth.ok());
  ASSERT_FALSE(truth->overlays.empty());

  // Targets on the overlay in half of their frames or more (as the accuracy corpus counts).
  const auto on_overlay = [&](const FrontEndResult& result) {
    int count = 0;
    for (const track::TargetTrack& t : result.targets) {
      const auto on = std::count_if(
          t.observations.begin(), t.observations.end(),
          [&](const track::TargetObservation& o) { return truth->OnOverlay(o.position); });
      count += 2 * static_cast<size_t>(on) >= t.observations.size();
    }
    return count;
  };
  // The clip is a test: without the overlay detection, the overlay makes targets.
  FrontEndOptions without;
  without.overlays.enabled = false;
  StatusOr<FrontEndResult> plain = RunFrontEnd(options.output.string(), without);
  ASSERT_TRUE(plain.ok()) << plain.status().ToString();
  EXPECT_TRUE(plain->overlays.empty());
  const FrontEndOptions with;  // the default: on
  ASSERT_TRUE(with.overlays.enabled);
  StatusOr<FrontEndResult> result = RunFrontEnd(options.output.string(), with);
  ASSERT_TRUE(result.ok()) << result.status().ToString();
  std::cout << "without overlay detection: " << plain->targets.size() << " targets, "
            << on_overlay(*plain) << " on the overlay; with: " << result->targets.size()
            << " targets, " << on_overlay(*result) << " on the overlay, " << result->overlays.size()
            << " overlay masks\n";
  EXPECT_GT(on_overlay(*plain), 0);
  EXPECT_EQ(on_overlay(*result), 0);
  EXPECT_GT(result->targets.size(), 0u);

  // The masks follow one another within the video, the first within the overlay window (the
  // evidence takes seconds to gather), and the last one covers the overlay's pixels (those the
  // overlay draws in the last frame) and little more than its boxes grown by the cells' rounding
  // and the dilation.
  ASSERT_FALSE(result->overlays.empty());
  EXPECT_LT(result->overlays.front().first_frame, WindowFrames(with.overlays));
  for (size_t i = 0; i < result->overlays.size(); ++i) {
    const track::OverlayMask& m = result->overlays[i];
    EXPECT_LE(m.first_frame, m.last_frame);
    if (i > 0) {
      EXPECT_GT(m.first_frame, result->overlays[i - 1].last_frame);
    }
  }
  const track::OverlayMask& mask = result->overlays.back();
  EXPECT_EQ(mask.last_frame, result->frames.back().index);
  const double margin = (1.0 + with.overlays.dilate_cells) * mask.cell_px;
  const auto near_box = [&](const Eigen::Vector2d& p) {
    return std::any_of(truth->overlays.begin(), truth->overlays.end(), [&](const auto& box) {
      return p.x() >= box.x - margin && p.y() >= box.y - margin &&
             p.x() < box.x + box.width + margin && p.y() < box.y + box.height + margin;
    });
  };
  const cv::Mat drawn = OverlayPixels(options.overlay, 640, 360, result->frames.back().time_s);
  int overlay_pixels = 0, covered = 0, elsewhere = 0;
  for (int y = 0; y < drawn.rows; ++y) {
    for (int x = 0; x < drawn.cols; ++x) {
      const Eigen::Vector2d p(x, y);
      const bool in_box = near_box(p);
      if (drawn.at<uint8_t>(y, x) != 0) {
        ++overlay_pixels;
        covered += mask.Contains(p);
      } else if (!in_box) {
        elsewhere += mask.Contains(p);
      }
    }
  }
  std::cout << "mask covers " << covered << " of " << overlay_pixels << " overlay pixels, "
            << elsewhere << " pixels farther from the overlay boxes\n";
  ASSERT_GT(overlay_pixels, 0);
  EXPECT_GE(covered, 0.9 * overlay_pixels);
  EXPECT_LT(elsewhere, 0.005 * 640 * 360);

  // saker-cli evaluate's measure of the masks agrees: part of the overlay boxes covered (they
  // hold the space between the glyphs, and the first seconds have no mask), little of the image
  // masked off them, nothing masked without the detection.
  StatusOr<eval::FrontEndEvaluation> evaluation = eval::EvaluateFrontEnd(*result, *truth);
  ASSERT_TRUE(evaluation.ok()) << evaluation.status().ToString();
  const eval::OverlayMaskAccuracy& accuracy = evaluation->overlay_mask;
  std::cout << eval::FrontEndEvaluationToText(*evaluation);
  EXPECT_GT(accuracy.frames, 0);
  EXPECT_LT(accuracy.frames, static_cast<int64_t>(result->frames.size()));  // seconds to gather
  EXPECT_GT(accuracy.overlay_covered, 0.1);
  EXPECT_LT(accuracy.off_overlay_fraction, 0.05);
  EXPECT_GT(accuracy.masked_fraction, accuracy.off_overlay_fraction);
  StatusOr<eval::FrontEndEvaluation> none = eval::EvaluateFrontEnd(*plain, *truth);
  ASSERT_TRUE(none.ok());
  EXPECT_EQ(none->overlay_mask.frames, 0);
  EXPECT_EQ(none->overlay_mask.overlay_covered, 0);
}

}  // namespace
}  // namespace saker::frontend
