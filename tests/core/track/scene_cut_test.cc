#include "core/track/scene_cut.h"

#include "core/track/target_tracks.h"

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <cstdint>

namespace saker::track {
namespace {

// A textured ground (blurred noise, details of a few pixels like a town seen from 400 m; the
// simulator's worlds give the same correlations), seen through a
// 640x360 window. Seeds must be far apart: cv::RNG streams of nearby seeds (1 and 2) correlate.
class Ground {
 public:
  explicit Ground(uint64_t seed) : pixels_(1200, 2000, CV_8UC1) {
    cv::RNG(seed).fill(pixels_, cv::RNG::UNIFORM, 0, 256);
    cv::GaussianBlur(pixels_, pixels_, cv::Size(0, 0), 5);
    cv::normalize(pixels_, pixels_, 20, 235, cv::NORM_MINMAX);
  }
  cv::Mat View(int x, int y) const { return pixels_(cv::Rect(x, y, 640, 360)).clone(); }

 private:
  cv::Mat pixels_;
};

// Frames 0-9 of a ground, a break, then frames 10-19 of `after` (each a new segment at its first
// frame); the verdict for joining frame 5 to frame 15.
bool JoinedAcross(const cv::Mat& before, const cv::Mat& after) {
  SceneContinuity scenes;
  for (int f = 0; f < 20; ++f) scenes.Add(f, f == 0 || f == 10, f < 10 ? before : after);
  return scenes.SameScene(5, 15);
}

TEST(SceneContinuityTest, ACutIsToldFromAnInterruptionOfOneScene) {
  const Ground town(0x9E3779B97F4A7C15), elsewhere(0x14057B7EF767814F);
  const cv::Mat here = town.View(300, 300);
  // The same ground after a blank of a second or two (the camera moved 60 px), and after a
  // thermal camera switched polarity: one scene.
  EXPECT_TRUE(JoinedAcross(here, town.View(360, 310)));
  cv::Mat inverted;
  cv::bitwise_not(here, inverted);
  EXPECT_TRUE(JoinedAcross(here, inverted));
  // Another place: a cut.
  EXPECT_FALSE(JoinedAcross(here, elsewhere.View(300, 300)));
  EXPECT_FALSE(JoinedAcross(here, town.View(1200, 800)));  // the same town, far away
  // A blank look tells nothing: the pieces may be joined, as without the check.
  EXPECT_TRUE(JoinedAcross(here, cv::Mat(360, 640, CV_8UC1, cv::Scalar(128))));
}

TEST(SceneContinuityTest, WithinASegmentAndForUnknownFramesItIsOneScene) {
  const Ground town(0x2545F4914F6CDD1D), elsewhere(0x27BB2EE687B0B0FD);
  SceneContinuity scenes;
  for (int f = 10; f < 30; ++f) {
    scenes.Add(f, f == 10 || f == 20, f < 20 ? town.View(100, 100) : elsewhere.View(100, 100));
  }
  EXPECT_TRUE(scenes.SameScene(11, 19));
  EXPECT_FALSE(scenes.SameScene(11, 25));
  EXPECT_TRUE(scenes.SameScene(3, 25));   // frame 3 was never added
  EXPECT_TRUE(scenes.SameScene(11, 40));  // nor frame 40
  ASSERT_TRUE(scenes.CorrelationAt(20).has_value());
  EXPECT_LT(std::abs(*scenes.CorrelationAt(20)), 0.4);
  EXPECT_FALSE(scenes.CorrelationAt(10).has_value());  // the first segment: no break before it
  EXPECT_FALSE(scenes.CorrelationAt(15).has_value());  // no segment starts there
}

// A camera moving 4 px a frame over the town switches polarity at frame 20 and back at frame 40;
// a blank (cloud) lies across the second switch, and a cut to another place comes at frame 50.
TEST(PolarityWatchTest, FindsEachSwitchAcrossBlanksAndNotAtACut) {
  const Ground town(0x8BADF00DDEADBEEF), elsewhere(0x0123456789ABCDEF);
  const cv::Mat blank(360, 640, CV_8UC1, cv::Scalar(90));
  PolarityWatch watch;
  std::vector<bool> inverted;
  for (int f = 0; f < 60; ++f) {
    cv::Mat frame = f < 50 ? town.View(100 + 4 * f, 200) : elsewhere.View(4 * f, 200);
    if (f >= 20 && f < 40) cv::bitwise_not(frame, frame);
    if (f >= 38 && f < 42) frame = blank;
    inverted.push_back(watch.Add(f, frame));
  }
  EXPECT_EQ(watch.switches(), (std::vector<int64_t>{20, 42}));
  for (int f = 0; f < 60; ++f) {
    EXPECT_EQ(inverted[f], f >= 20 && f < 42) << "frame " << f;
    EXPECT_EQ(watch.Inverted(f), inverted[f]);
  }

  // Restored from its state (as a resumed run does), it knows the switches; replaying frames
  // detects nothing but keeps the look, so a switch right after the replay is found.
  ByteWriter out;
  watch.SaveState(&out);
  PolarityWatch resumed;
  ByteReader in(out.bytes());
  ASSERT_TRUE(resumed.RestoreState(&in));
  EXPECT_TRUE(in.AtEnd());
  EXPECT_TRUE(resumed.Replay(30, town.View(220, 200)));  // inverted by the record, not by looking
  cv::Mat next = elsewhere.View(240, 200);
  EXPECT_FALSE(resumed.Replay(59, next));
  cv::bitwise_not(next, next);
  EXPECT_TRUE(resumed.Add(60, next));
  EXPECT_EQ(resumed.switches(), (std::vector<int64_t>{20, 42, 60}));
  // A state out of order, or cut short, is refused.
  ByteWriter bad;
  bad.PutVector(std::vector<int64_t>{42, 20});
  ByteReader bad_in(bad.bytes());
  EXPECT_FALSE(PolarityWatch().RestoreState(&bad_in));
  std::vector<uint8_t> cut(out.bytes().begin(), out.bytes().end() - 1);
  ByteReader cut_in(cut);
  EXPECT_FALSE(PolarityWatch().RestoreState(&cut_in));
}

// A car lost for 10 frames comes back where it was heading: one car across a chain break in one
// scene (a blank, a polarity switch), two cars when the break is a cut to another scene, where
// the same image position is another place.
TEST(LinkFragmentsTest, NoTrackContinuesAnotherAcrossACut) {
  const auto track = [](int64_t id, int64_t first, int64_t last, Eigen::Vector2d start) {
    TargetTrack t;
    t.id = TargetTrackId{id};
    for (int64_t f = first; f <= last; ++f) {
      TargetObservation o;
      o.frame = f;
      o.position = start + Eigen::Vector2d(3, 0) * static_cast<double>(f - first);
      o.velocity = {2, 0};
      o.features = {FeatureTrackId{id * 1000 + f}};
      t.observations.push_back(o);
    }
    t.confirmed = true;
    return t;
  };
  const std::vector<TargetTrack> tracks = {track(1, 0, 40, {100, 300}),
                                           track(2, 51, 90, {253, 300})};
  const Ground town(0x5851F42D4C957F2D), elsewhere(0x6A09E667F3BCC909);
  const auto scenes_with = [&](const cv::Mat& after) {
    SceneContinuity scenes;
    for (int f = 0; f < 100; ++f) {
      scenes.Add(f, f == 0 || f == 45, f < 45 ? town.View(200, 200) : after);
    }
    return scenes;
  };
  const TargetTrackOptions options;
  const FrameRate rate(25);
  const SceneContinuity interrupted = scenes_with(town.View(230, 205));
  EXPECT_EQ(LinkFragments(tracks, options, rate, nullptr, &interrupted).size(), 1u);
  const SceneContinuity cut = scenes_with(elsewhere.View(200, 200));
  EXPECT_EQ(LinkFragments(tracks, options, rate, nullptr, &cut).size(), 2u);
  EXPECT_EQ(LinkFragments(tracks, options, rate).size(), 1u);  // without the check
}

}  // namespace
}  // namespace saker::track
