// The horizon finder (core/track/horizon.h): on drawn skies and grounds, level and tilted, on the
// simulator's low oblique views, and its refusals: a frame that is all ground, or all sky.

#include "core/track/horizon.h"

#include "core/sim/camera.h"
#include "core/sim/simulator.h"
#include "tests/testing/test_data.h"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <cmath>

namespace saker::track {
namespace {

// Textured ground (patches of 8 pixels and finer noise) with, above the line
// y = y0 + slope (x - centre), a smooth sky brightening towards the horizon.
cv::Mat Scene(int width, int height, double y0, double slope, uint64_t seed) {
  cv::RNG rng(seed);
  cv::Mat coarse(height / 8, width / 8, CV_8UC1), fine(height, width, CV_8UC1), ground;
  rng.fill(coarse, cv::RNG::UNIFORM, 40, 180);
  rng.fill(fine, cv::RNG::UNIFORM, 0, 40);
  cv::resize(coarse, ground, cv::Size(width, height), 0, 0, cv::INTER_NEAREST);
  ground += fine;
  cv::GaussianBlur(ground, ground, cv::Size(0, 0), 1.0);
  cv::Mat out = ground.clone();
  const double centre = (width - 1) / 2.0;
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const double line = y0 + slope * (x - centre);
      if (y < line) out.at<uint8_t>(y, x) = cv::saturate_cast<uint8_t>(200 + 30 * y / line);
    }
  }
  return out;
}

TEST(HorizonTest, FindsALevelAndATiltedHorizon) {
  const HorizonOptions options;
  for (const double slope : {0.0, 0.2, -0.3}) {
    SCOPED_TRACE(slope);
    const cv::Mat grey = Scene(640, 360, 120, slope, 7);
    const std::optional<HorizonLine> line = FindHorizon(grey, options);
    ASSERT_TRUE(line.has_value());
    // Within about a pixel of the reduced image (5 full-resolution pixels) at the centre, and half
    // a tilt step (1.25 degrees: 7 pixels) more at the edges.
    EXPECT_NEAR(line->YAt(319.5), 120, 6);
    EXPECT_NEAR(line->YAt(0), 120 + slope * -319.5, 14);
    EXPECT_NEAR(line->YAt(639), 120 + slope * 319.5, 14);
  }
}

// A 1920x1080 frame, which is reduced by a whole 8 (240 across, a box average) rather than to 256
// across by a fractional 7.5: the line is found where it is at the other sizes, within the reduced
// image's pixels (8 full-resolution pixels; the line sits 1-3 of them above the drawn one at every
// size, as the edge's own gradient counts with the ground).
TEST(HorizonTest, FindsTheHorizonOfAFullHdFrame) {
  const HorizonOptions options;
  for (const double slope : {0.0, 0.2}) {
    SCOPED_TRACE(slope);
    const cv::Mat grey = Scene(1920, 1080, 360, slope, 7);
    const std::optional<HorizonLine> line = FindHorizon(grey, options);
    ASSERT_TRUE(line.has_value());
    EXPECT_NEAR(line->YAt(959.5), 360 - 16, 16);
    EXPECT_NEAR(line->slope, slope, 0.03);
  }
}

TEST(HorizonTest, AFrameOfGroundAloneOrOfSkyAloneHasNone) {
  const HorizonOptions options;
  // All ground: textured everywhere.
  EXPECT_FALSE(FindHorizon(Scene(640, 360, -1, 0, 3), options).has_value());
  // Ground with a smooth band at the top too narrow to be sky, and a frame that is all smooth.
  EXPECT_FALSE(FindHorizon(Scene(640, 360, 10, 0, 3), options).has_value());
  EXPECT_FALSE(FindHorizon(cv::Mat(360, 640, CV_8UC1, cv::Scalar(210)), options).has_value());
  // Smooth in the middle, textured above and below: no sky at the top.
  cv::Mat band = Scene(640, 360, -1, 0, 4);
  band.rowRange(120, 240).setTo(cv::Scalar(210));
  EXPECT_FALSE(FindHorizon(band, options).has_value());
  // Nothing to look at.
  EXPECT_FALSE(FindHorizon(cv::Mat(), options).has_value());
  EXPECT_FALSE(FindHorizon(cv::Mat(8, 8, CV_8UC1, cv::Scalar(0)), options).has_value());
}

// The tracker masks once the horizon was seen in most of the recent frames, and stops when it is
// not any more.
TEST(HorizonTest, TheTrackerMasksAHorizonSeenInMostRecentFrames) {
  const HorizonOptions options;  // a 1 s window: 5 frames at 5 fps
  HorizonTracker tracker(options, FrameRate(5));
  const cv::Mat sky = Scene(640, 360, 120, 0, 11);
  const cv::Mat ground = Scene(640, 360, -1, 0, 12);
  EXPECT_FALSE(tracker.Add(sky).has_value());  // one frame is not enough
  EXPECT_FALSE(tracker.Add(sky).has_value());
  ASSERT_TRUE(tracker.Add(sky).has_value());
  EXPECT_TRUE(tracker.Masks(Eigen::Vector2d(300, 60)));
  EXPECT_TRUE(tracker.Masks(Eigen::Vector2d(300, 130)));  // within the margin below the line
  EXPECT_FALSE(tracker.Masks(Eigen::Vector2d(300, 200)));
  EXPECT_TRUE(tracker.Add(ground).has_value());  // one frame without it: still most
  EXPECT_TRUE(tracker.Add(ground).has_value());  // 3 of 5
  EXPECT_FALSE(tracker.Add(ground).has_value());
  EXPECT_FALSE(tracker.Masks(Eigen::Vector2d(300, 60)));
  tracker.Reset();
  EXPECT_FALSE(tracker.Add(sky).has_value());
  HorizonOptions off;
  off.enabled = false;
  HorizonTracker none(off, FrameRate(5));
  for (int i = 0; i < 5; ++i) EXPECT_FALSE(none.Add(sky).has_value());
}

// Where the metadata puts the four corners on the ground, a split of smooth over textured is not
// the horizon (the nadir demo's frames 503-535: a straight road with even grass beyond it, taken
// for the horizon, masked a car): the frames count as frames without it, and the mask comes only
// once frames without such metadata show it most of the window.
TEST(HorizonTest, AFrameTheMetadataPutsOnTheGroundHasNoHorizon) {
  HorizonTracker tracker(HorizonOptions(), FrameRate(5));
  const cv::Mat split = Scene(640, 360, 120, 0, 13);
  ASSERT_TRUE(FindHorizon(split, HorizonOptions()).has_value());
  for (int i = 0; i < 5; ++i) {
    EXPECT_FALSE(tracker.Add(split, /*on_ground=*/true).has_value()) << "frame " << i;
    EXPECT_FALSE(tracker.found().has_value()) << "frame " << i;
  }
  EXPECT_FALSE(tracker.Add(split).has_value());  // 1 of 5
  EXPECT_FALSE(tracker.Add(split).has_value());  // 2 of 5
  EXPECT_TRUE(tracker.Add(split).has_value());   // 3 of 5
}

TEST(HorizonTest, OptionsAreValidated) {
  EXPECT_TRUE(HorizonOptions().Validate().ok());
  HorizonOptions o;
  o.max_sky_fraction = o.min_sky_fraction;
  EXPECT_FALSE(o.Validate().ok());
  o = HorizonOptions();
  o.max_texture_ratio = 1.5;
  EXPECT_FALSE(o.Validate().ok());
  o = HorizonOptions();
  o.margin_fraction = -0.1;
  EXPECT_FALSE(o.Validate().ok());
  o = HorizonOptions();
  o.window_s = 0;
  EXPECT_FALSE(o.Validate().ok());
}

}  // namespace
}  // namespace saker::track
