#include "core/track/motion_segmentation.h"

#include "core/track/target_tracks.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

namespace saker::track {
namespace {

// The frame rate the tests' frame counts were written for.
const FrameRate kRate(25);

// A synthetic scene: ground points translating by `flow` per frame (the camera flying), with
// per-frame noise, and objects that add their own motion.
struct Scene {
  std::mt19937 rng{7};
  std::normal_distribution<double> noise{0.0, 0.15};
  Eigen::Vector2d flow{0, 3};  // camera moving "up": ground moves down the image by 3 px/frame
  std::vector<Correspondence> Step(const std::vector<std::pair<int64_t, Eigen::Vector2d>>& points,
                                   const std::vector<Eigen::Vector2d>& own_motion,
                                   std::vector<Eigen::Vector2d>* now) {
    std::vector<Correspondence> matches;
    now->clear();
    for (size_t i = 0; i < points.size(); ++i) {
      const Eigen::Vector2d next =
          points[i].second + flow + own_motion[i] + Eigen::Vector2d(noise(rng), noise(rng));
      matches.push_back({FeatureTrackId{points[i].first}, points[i].second, next});
      now->push_back(next);
    }
    return matches;
  }
  Eigen::Matrix3d Homography() const {
    Eigen::Matrix3d h = Eigen::Matrix3d::Identity();
    h(0, 2) = flow.x(), h(1, 2) = flow.y();
    return h;
  }
};

TEST(MotionSegmenterTest, MovingObjectsSeparateFromGroundAndNoise) {
  Scene scene;
  MotionSegmenter segmenter({}, kRate);
  std::vector<std::pair<int64_t, Eigen::Vector2d>> points;
  std::vector<Eigen::Vector2d> own;
  for (int i = 0; i < 40; ++i)
    points.push_back({i, Eigen::Vector2d(20.0 * i, 100)}), own.push_back({0, 0});
  for (int i = 40; i < 44; ++i)
    points.push_back({i, Eigen::Vector2d(300 + i, 300)}), own.push_back({2, 0});  // a car
  points.push_back({99, Eigen::Vector2d(500, 500)});
  own.push_back({0, 0});  // a track that jumps once (a tracking error)
  std::vector<Eigen::Vector2d> now;
  for (int frame = 0; frame < 20; ++frame) {
    std::vector<Eigen::Vector2d> motion = own;
    if (frame == 10) motion.back() = Eigen::Vector2d(6, 0);
    const auto matches = scene.Step(points, motion, &now);
    segmenter.AddFrame(matches, scene.Homography(), std::nullopt);
    for (size_t i = 0; i < points.size(); ++i) points[i].second = now[i];
    if (frame >= 8) {
      for (int i = 40; i < 44; ++i)
        EXPECT_EQ(segmenter.LabelOf(FeatureTrackId{i}), MotionLabel::kMoving) << frame;
      for (int i = 0; i < 40; ++i)
        EXPECT_EQ(segmenter.LabelOf(FeatureTrackId{i}), MotionLabel::kStationary) << frame;
      EXPECT_NE(segmenter.LabelOf(FeatureTrackId{99}), MotionLabel::kMoving) << frame;
    }
  }
  EXPECT_EQ(segmenter.moving().size(), 4u);
  EXPECT_NEAR(segmenter.moving()[0].residual_velocity.x(), 2.0, 0.2);
}

TEST(MotionSegmenterTest, ParallaxAlongTheEpipolarLineIsNotMotion) {
  Scene scene;
  scene.flow = {0, 8};  // fast ground flow: a roof 12 % of the height up drifts 1 px per frame
  MotionSegmenter with_epipole({}, kRate), without({}, kRate);
  // The camera translates forward (up the image): the epipole is far up, at infinity along y.
  const Eigen::Vector3d epipole(0, 1, 0);
  std::vector<std::pair<int64_t, Eigen::Vector2d>> points{{1, {200, 200}}, {2, {400, 200}}};
  std::vector<Eigen::Vector2d> own{{0, 1.0}, {1.2, 0}};  // 1: a roof (parallax), 2: a slow walker
  std::vector<Eigen::Vector2d> now;
  for (int frame = 0; frame < 20; ++frame) {
    const auto matches = scene.Step(points, own, &now);
    with_epipole.AddFrame(matches, scene.Homography(), epipole);
    without.AddFrame(matches, scene.Homography(), std::nullopt);
    for (size_t i = 0; i < points.size(); ++i) points[i].second = now[i];
  }
  EXPECT_EQ(with_epipole.LabelOf(FeatureTrackId{1}), MotionLabel::kStationary);
  EXPECT_EQ(with_epipole.LabelOf(FeatureTrackId{2}), MotionLabel::kMoving);
  // Without the epipolar test the roof's drift would be taken for motion.
  EXPECT_EQ(without.LabelOf(FeatureTrackId{1}), MotionLabel::kMoving);
  EXPECT_EQ(without.LabelOf(FeatureTrackId{2}), MotionLabel::kMoving);
}

TEST(MotionSegmenterTest, AStoppingCarBecomesStationaryAgain) {
  Scene scene;
  MotionSegmenter segmenter({}, kRate);
  std::vector<std::pair<int64_t, Eigen::Vector2d>> points{{5, {100, 100}}};
  std::vector<Eigen::Vector2d> now;
  for (int frame = 0; frame < 40; ++frame) {
    const std::vector<Eigen::Vector2d> own{frame < 15 ? Eigen::Vector2d(2, 0)
                                                      : Eigen::Vector2d(0, 0)};
    segmenter.AddFrame(scene.Step(points, own, &now), scene.Homography(), std::nullopt);
    points[0].second = now[0];
    if (frame == 12) {
      EXPECT_EQ(segmenter.LabelOf(FeatureTrackId{5}), MotionLabel::kMoving);
    }
  }
  EXPECT_EQ(segmenter.LabelOf(FeatureTrackId{5}), MotionLabel::kStationary);
}

// Heavily compressed video: the tracker's corners wander over the ground, each steadily in its own
// direction (0.1-0.6 px a frame here, as measured at CRF 38), so that over the stage-1 window the
// ground itself moves more than the fixed threshold. The thresholds follow the median: the ground
// stays still and a car still moves. With the fixed thresholds alone most of the ground moves.
TEST(MotionSegmenterTest, ThresholdsFollowTheFeatureNoise) {
  const auto run = [](const SegmentationOptions& options, int* ground_moving, bool* car_moving,
                      double* threshold) {
    Scene scene;
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> speed(0.1, 0.6), angle(0, 2 * M_PI);
    MotionSegmenter segmenter(options, kRate);
    std::vector<std::pair<int64_t, Eigen::Vector2d>> points;
    std::vector<Eigen::Vector2d> own;
    for (int i = 0; i < 80; ++i) {
      const double a = angle(rng);
      points.push_back({i, Eigen::Vector2d(10.0 * i, 50 + 3.0 * i)});
      own.push_back(speed(rng) * Eigen::Vector2d(std::cos(a), std::sin(a)));
    }
    points.push_back({100, Eigen::Vector2d(400, 300)});
    own.push_back({3, 1});  // a car, 80 px a second
    std::vector<Eigen::Vector2d> now;
    *ground_moving = 0;
    for (int frame = 0; frame < 50; ++frame) {
      segmenter.AddFrame(scene.Step(points, own, &now), scene.Homography(), std::nullopt);
      for (size_t i = 0; i < points.size(); ++i) points[i].second = now[i];
      if (frame < 25) continue;  // the noise estimate has settled (1 s)
      for (int i = 0; i < 80; ++i)
        *ground_moving += segmenter.LabelOf(FeatureTrackId{i}) == MotionLabel::kMoving;
    }
    *car_moving = segmenter.LabelOf(FeatureTrackId{100}) == MotionLabel::kMoving;
    *threshold = segmenter.residual_threshold_px();
  };
  int ground_moving = 0;
  bool car_moving = false;
  double threshold = 0;
  run({}, &ground_moving, &car_moving, &threshold);
  EXPECT_EQ(ground_moving, 0);
  EXPECT_TRUE(car_moving);
  EXPECT_GT(threshold, 3.0);
  SegmentationOptions fixed;
  fixed.noise_multiple = fixed.window_noise_multiple = 0;
  run(fixed, &ground_moving, &car_moving, &threshold);
  EXPECT_GT(ground_moving, 25 * 80 / 3);  // a third of the ground, every frame
  EXPECT_TRUE(car_moving);
  EXPECT_DOUBLE_EQ(threshold, fixed.residual_threshold_px);
}

// Clean features (the median stage-1 motion about 0.25 px, as measured on clean simulated video)
// leave the fixed thresholds as they are.
TEST(MotionSegmenterTest, CleanVideoKeepsTheFixedThresholds) {
  Scene scene;
  scene.noise = std::normal_distribution<double>(0.0, 0.07);
  const SegmentationOptions options;
  MotionSegmenter segmenter(options, kRate);
  std::vector<std::pair<int64_t, Eigen::Vector2d>> points;
  std::vector<Eigen::Vector2d> own;
  for (int i = 0; i < 60; ++i)
    points.push_back({i, Eigen::Vector2d(10.0 * i, 200)}), own.push_back({0, 0});
  std::vector<Eigen::Vector2d> now;
  for (int frame = 0; frame < 40; ++frame) {
    segmenter.AddFrame(scene.Step(points, own, &now), scene.Homography(), std::nullopt);
    for (size_t i = 0; i < points.size(); ++i) points[i].second = now[i];
  }
  EXPECT_GT(segmenter.short_noise_px(), 0.1);
  EXPECT_LT(segmenter.short_noise_px(), 0.4);
  EXPECT_DOUBLE_EQ(segmenter.residual_threshold_px(), options.residual_threshold_px);
  EXPECT_DOUBLE_EQ(segmenter.window_displacement_px(), options.min_window_displacement_px);
}

TEST(MotionSegmenterTest, ValidatesOptions) {
  SegmentationOptions options;
  EXPECT_TRUE(options.Validate().ok());
  options.window_s = 0;
  EXPECT_FALSE(options.Validate().ok());
  options = {};
  options.release_fraction = 0.9;
  EXPECT_FALSE(options.Validate().ok());
}

// Seconds until a walker (7 px a second on the ground, 1.4 m/s at 0.2 m a pixel) among still
// ground points is labelled moving, for video of `fps` frames a second segmented at `rate`; -1
// when it never is within 4 s. The ground moves 75 px a second through the image.
double SecondsToLabelWalker(double fps, FrameRate rate) {
  Scene scene;
  scene.flow = Eigen::Vector2d(0, 75 / fps);
  MotionSegmenter segmenter({}, rate);
  std::vector<std::pair<int64_t, Eigen::Vector2d>> points;
  std::vector<Eigen::Vector2d> own;
  for (int i = 0; i < 30; ++i) points.push_back({i, Eigen::Vector2d(20.0 * i, 100)});
  own.assign(points.size(), Eigen::Vector2d(0, 0));
  points.push_back({99, Eigen::Vector2d(300, 300)});
  own.push_back(Eigen::Vector2d(7 / fps, 0));
  std::vector<Eigen::Vector2d> now;
  for (int frame = 1; frame <= static_cast<int>(4 * fps); ++frame) {
    segmenter.AddFrame(scene.Step(points, own, &now), scene.Homography(), std::nullopt);
    for (size_t i = 0; i < points.size(); ++i) points[i].second = now[i];
    for (int i = 0; i < 30; ++i) {
      EXPECT_NE(segmenter.LabelOf(FeatureTrackId{i}), MotionLabel::kMoving) << "ground " << i;
    }
    if (segmenter.LabelOf(FeatureTrackId{99}) == MotionLabel::kMoving) return frame / fps;
  }
  return -1;
}

// The windows are in seconds: a walker is labelled as soon at 5 or 10 frames a second as at 25
// (at 5 frames a second, the 25 frames-a-second windows counted in frames took 1.6 s).
TEST(MotionSegmenterTest, WindowsAreInSecondsNotFrames) {
  const double at_25 = SecondsToLabelWalker(25, FrameRate(25));
  ASSERT_GT(at_25, 0);
  EXPECT_LT(at_25, 0.7);
  for (const double fps : {5.0, 10.0, 30.0, 60.0}) {
    const double seconds = SecondsToLabelWalker(fps, FrameRate(fps));
    ASSERT_GT(seconds, 0) << fps << " fps";
    EXPECT_NEAR(seconds, at_25, 0.25) << fps << " fps";
  }
  // What counting frames did: the windows of 25 frames a second stretched to 2.4 s at 5.
  EXPECT_GT(SecondsToLabelWalker(5, FrameRate(25)), at_25 + 0.5);
}

TEST(FrameRateTest, DurationsBecomeFramesWithAFloor) {
  const FrameRate rate(25);
  EXPECT_EQ(rate.Frames(0.48, 3), 12);
  EXPECT_EQ(rate.Frames(0.01, 3), 3);
  EXPECT_EQ(FrameRate(2).Frames(0.48, 1), 1);
  EXPECT_EQ(FrameRate(5).Frames(1.0, 2), 5);
  EXPECT_DOUBLE_EQ(rate.PerFrame(12.5), 0.5);
  EXPECT_DOUBLE_EQ(FrameRate(5).Seconds(10), 2);
  // Rates a stream does not give, or a damaged header's, never make windows of thousands of
  // frames.
  EXPECT_DOUBLE_EQ(FrameRate(0).fps(), FrameRate::kDefaultFps);
  EXPECT_DOUBLE_EQ(FrameRate(-3).fps(), FrameRate::kDefaultFps);
  EXPECT_DOUBLE_EQ(FrameRate(std::nan("")).fps(), FrameRate::kDefaultFps);
  EXPECT_DOUBLE_EQ(FrameRate(90000).fps(), FrameRate::kMaxFps);
  EXPECT_DOUBLE_EQ(FrameRate(1e-9).fps(), FrameRate::kMinFps);
  EXPECT_LE(FrameRate(90000).Frames(1e300, 1), static_cast<int>(1e6 * FrameRate::kMaxFps));
}

MovingPoint Point(int64_t id, double x, double y, double vx = 2, double vy = 0) {
  return {FeatureTrackId{id}, {x, y}, {vx, vy}};
}

TEST(TargetTrackerTest, GroupsFeaturesIntoObjectsAndFollowsThem) {
  TargetTracker tracker({}, kRate);
  for (int frame = 0; frame < 30; ++frame) {
    const double x = 100 + 5 * frame;  // image motion: camera + own
    std::vector<MovingPoint> moving{Point(1, x, 50), Point(2, x + 6, 52), Point(3, x + 3, 47),
                                    Point(10, 400, 300 + 4.0 * frame, 0, 2),
                                    Point(11, 405, 304 + 4.0 * frame, 0, 2)};
    tracker.AddFrame(frame, moving);
  }
  ASSERT_EQ(tracker.active().size(), 2u);
  for (const TargetTrack& t : tracker.active()) {
    EXPECT_TRUE(t.confirmed);
    EXPECT_EQ(t.observations.size(), 30u);
  }
  tracker.FinishAll();
  EXPECT_EQ(tracker.TakeFinished().size(), 2u);
}

TEST(TargetTrackerTest, SurvivesFeatureTurnoverAndShortGaps) {
  TargetTracker tracker({}, kRate);
  int64_t next_feature = 100;
  for (int frame = 0; frame < 40; ++frame) {
    if (frame >= 20 && frame < 25) {
      tracker.AddFrame(frame, {});  // lost for five frames
      continue;
    }
    // Every 4 frames the car's corners are new features (old ones lost, new ones detected).
    if (frame % 4 == 0) next_feature += 3;
    const double x = 100 + 4 * frame;
    tracker.AddFrame(frame, {Point(next_feature, x, 80), Point(next_feature + 1, x + 5, 82),
                             Point(next_feature + 2, x + 2, 78)});
  }
  ASSERT_EQ(tracker.active().size(), 1u);
  EXPECT_EQ(tracker.active()[0].observations.size(), 35u);
}

// A car followed at 5 frames a second survives a gap of 0.6 s (3 frames) and ends once unseen for
// more than max_gap_s (1 s: 5 frames), not after 25 frames (5 s) as when the gap counted frames.
TEST(TargetTrackerTest, GapsAreInSecondsNotFrames) {
  const FrameRate rate(5);
  TargetTracker tracker({}, rate);
  const auto car = [](int frame) {
    const double x = 100 + 20 * frame;  // 100 px a second in the image
    return std::vector<MovingPoint>{Point(1, x, 50, 10), Point(2, x + 6, 52, 10),
                                    Point(3, x + 3, 47, 10)};
  };
  int frame = 0;
  for (; frame < 10; ++frame) tracker.AddFrame(frame, car(frame));
  for (; frame < 13; ++frame) tracker.AddFrame(frame, {});  // unseen for 0.6 s
  for (; frame < 20; ++frame) tracker.AddFrame(frame, car(frame));
  ASSERT_EQ(tracker.active().size(), 1u);
  EXPECT_TRUE(tracker.active()[0].confirmed);
  EXPECT_EQ(tracker.active()[0].observations.size(), 17u);
  for (int k = 0; k < 6; ++k, ++frame) tracker.AddFrame(frame, {});  // 1.2 s
  EXPECT_TRUE(tracker.active().empty());
  EXPECT_EQ(tracker.TakeFinished().size(), 1u);
}

// A walker's two corners, too far apart to be grouped, are merged into one target every frame.
// Its image velocity is that of the merged positions, not the pull of the corner it was matched by
// towards the midpoint (half the corners' distance a frame): after a gap, that velocity carried the
// prediction onto another walker 13 m away (the accuracy corpus's orbit, tuning seed 2).
TEST(TargetTrackerTest, AMergedTargetKeepsTheVelocityOfItsMergedPositions) {
  TargetTracker tracker({}, kRate);
  int frame = 0;
  for (; frame < 30; ++frame) {
    const double x = 100 + 0.2 * frame;
    tracker.AddFrame(frame, {Point(1, x, 300, 0.2), Point(2, x + 3, 301, 0.2),
                             Point(3, x + 14, 300, 0.2), Point(4, x + 17, 301, 0.2)});
  }
  ASSERT_EQ(tracker.active().size(), 1u);
  // Matched by the left pair and merged with the right one, it went 7 px a frame to the left.
  EXPECT_NEAR(tracker.active()[0].image_velocity.x(), 0.2, 0.1);
  for (; frame < 40; ++frame) tracker.AddFrame(frame, {});  // unseen for 0.4 s
  // Another walker, where 7 px a frame would have taken the first one.
  tracker.AddFrame(frame, {Point(20, 38, 300, 0.2), Point(21, 41, 301, 0.2)});
  ASSERT_EQ(tracker.active().size(), 2u);
  EXPECT_EQ(tracker.active()[0].observations.back().frame, 29);
  EXPECT_EQ(tracker.active()[1].observations.size(), 1u);
}

// Slow things (half a pixel a frame) whose corners are too far apart to be grouped but whose boxes
// touch, moving alike. A car that catches up with a van at a junction stays apart from it:
// merging the two would average both histories into a track between them. An object whose
// corners were found as two groups from the start is one.
TEST(TargetTrackerTest, ObjectsThatMeetStayTwoButPiecesOfOneAreOne) {
  TargetTracker tracker({}, kRate);
  for (int frame = 0; frame < 60; ++frame) {
    const double van = 200 + 0.5 * frame;
    const bool caught_up = frame >= 40;
    const double car = caught_up ? van - 11 : 100 + 2.5 * frame;
    const double car_speed = caught_up ? 0.5 : 2.5;
    const double x = 100 + 0.5 * frame;
    tracker.AddFrame(frame, {Point(1, van, 100, 0.5), Point(2, van + 3, 101, 0.5),
                             Point(3, car - 3, 100, car_speed), Point(4, car, 101, car_speed),
                             Point(10, x, 300, 0.5), Point(11, x + 3, 301, 0.5),
                             Point(12, x + 14, 300, 0.5), Point(13, x + 17, 301, 0.5)});
  }
  ASSERT_EQ(tracker.active().size(), 3u);
  for (const TargetTrack& t : tracker.active()) {
    EXPECT_EQ(t.observations.size(), 60u) << "target " << static_cast<int64_t>(t.id);
    for (const TargetObservation& o : t.observations) {
      // Never a van-and-car box (100 px wide before the car caught up).
      EXPECT_LT((o.box_max - o.box_min).x(), 40) << "target " << static_cast<int64_t>(t.id);
      if (o.position.y() > 200) {
        EXPECT_EQ(o.features.size(), 4u);
      }
    }
  }
}

TEST(TargetTrackerTest, ShortBlipsAreNeverConfirmed) {
  TargetTracker tracker({}, kRate);
  for (int frame = 0; frame < 3; ++frame) tracker.AddFrame(frame, {Point(1, 100, 100)});
  for (int frame = 3; frame < 30; ++frame) tracker.AddFrame(frame, {});
  EXPECT_TRUE(tracker.active().empty());
  EXPECT_TRUE(tracker.TakeFinished().empty());
}

TargetTrack Track(int64_t id, int64_t first, int64_t last, Eigen::Vector2d start,
                  Eigen::Vector2d image_step, Eigen::Vector2d velocity) {
  TargetTrack t;
  t.id = TargetTrackId{id};
  for (int64_t f = first; f <= last; ++f) {
    TargetObservation o;
    o.frame = f;
    o.position = start + image_step * static_cast<double>(f - first);
    o.velocity = velocity;
    o.features = {FeatureTrackId{id * 1000 + f}};
    t.observations.push_back(o);
  }
  t.confirmed = true;
  return t;
}

TEST(LinkFragmentsTest, JoinsContinuationsAndDuplicatesButNotPassersBy) {
  const TargetTrackOptions options;
  std::vector<TargetTrack> tracks;
  // A car lost for 20 frames: the second piece starts where the first was heading.
  tracks.push_back(Track(1, 0, 40, {100, 100}, {4, 0}, {2, 0}));
  tracks.push_back(Track(2, 60, 100, {100 + 4 * 60.0, 100}, {4, 0}, {2, 0}));
  // The same car's rear corners tracked as another target alongside the first piece.
  tracks.push_back(Track(3, 10, 30, {100 + 4 * 10.0 - 12, 101}, {4, 0}, {2, 0}));
  // Two walkers side by side, 3 m (15 px) apart: two people.
  tracks.push_back(Track(4, 0, 100, {500, 500}, {3, 0.3}, {0, 0.3}));
  tracks.push_back(Track(5, 0, 100, {515, 500}, {3, 0.3}, {0, 0.3}));
  // A car elsewhere, heading another way.
  tracks.push_back(Track(6, 70, 90, {100, 400}, {0, 4}, {0, 2}));
  const std::vector<TargetTrack> linked = LinkFragments(tracks, options, kRate);
  ASSERT_EQ(linked.size(), 4u);
  EXPECT_EQ(linked[0].id, TargetTrackId{1});
  EXPECT_EQ(linked[0].observations.front().frame, 0);
  EXPECT_EQ(linked[0].observations.back().frame, 100);
  EXPECT_EQ(linked[1].id, TargetTrackId{4});
  EXPECT_EQ(linked[2].id, TargetTrackId{5});
  EXPECT_EQ(linked[3].id, TargetTrackId{6});
}

// A walker's track ends 3 frames after another started beside it (fewer than a duplicate needs):
// the second took over and the two are one. Two walkers whose tracks pass within a few pixels
// for 3 frames, both going on, stay two, and so does a track beside another's last frames that
// ends before it.
TEST(LinkFragmentsTest, ATrackThatTookOverFromAnotherContinuesIt) {
  const TargetTrackOptions options;  // duplicates: 5 frames side by side at 25 fps
  std::vector<TargetTrack> tracks;
  tracks.push_back(Track(1, 0, 100, {100, 100}, {0.3, 0}, {0.3, 0}));  // ends at (130, 100)
  tracks.push_back(Track(2, 98, 200, {129.4 + 2, 101}, {0.3, 0}, {0.3, 0}));
  // Crossing: they meet at frame 50, each going on for 50 frames.
  tracks.push_back(Track(3, 0, 100, {300, 300}, {0.3, 0}, {0.3, 0}));
  tracks.push_back(Track(4, 0, 100, {315, 285}, {0, 0.3}, {0, 0.3}));
  // Beside track 1's last frames (and ending before it): no take-over; a second look.
  tracks.push_back(Track(5, 97, 99, {129.1 + 40, 100}, {0.3, 0}, {0.3, 0}));
  const std::vector<TargetTrack> linked = LinkFragments(tracks, options, kRate);
  ASSERT_EQ(linked.size(), 4u);
  EXPECT_EQ(linked[0].id, TargetTrackId{1});
  EXPECT_EQ(linked[0].observations.front().frame, 0);
  EXPECT_EQ(linked[0].observations.back().frame, 200);
  EXPECT_EQ(linked[0].observations.size(), 201u);  // the 3 common frames once
  EXPECT_EQ(linked[1].id, TargetTrackId{3});
  EXPECT_EQ(linked[2].id, TargetTrackId{4});
  EXPECT_EQ(linked[3].id, TargetTrackId{5});
  // Starting 10 frames before track 1 ended, beside it for all 10, track 2 is a duplicate (one
  // track too); 40 px away it is someone else.
  tracks[1] = Track(2, 91, 200, {127.3 + 2, 101}, {0.3, 0}, {0.3, 0});
  EXPECT_EQ(LinkFragments(tracks, options, kRate).size(), 4u);
  tracks[1] = Track(2, 98, 200, {129.4, 101 + 40}, {0.3, 0}, {0.3, 0});
  EXPECT_EQ(LinkFragments(tracks, options, kRate).size(), 5u);
}

// The camera pans: the ground moves 1 px per frame to the left in the image.
GroundMotion Panning(int64_t frames, int64_t chain_break = -1) {
  Eigen::Matrix3d current_from_previous = Eigen::Matrix3d::Identity();
  current_from_previous(0, 2) = -1;
  GroundMotion ground;
  for (int64_t f = 0; f < frames; ++f) {
    ground.Add(f, f > 0 && f != chain_break, current_from_previous);
  }
  return ground;
}

TEST(GroundMotionTest, CarriesPointsWithinAChainSegmentOnly) {
  GroundMotion ground = Panning(100, /*chain_break=*/60);
  const std::optional<Eigen::Vector2d> later = ground.Map({50, 20}, 10, 40);
  ASSERT_TRUE(later.has_value());
  EXPECT_NEAR(later->x(), 20, 1e-9);
  EXPECT_NEAR(later->y(), 20, 1e-9);
  const std::optional<Eigen::Vector2d> back = ground.Map(*later, 40, 10);
  ASSERT_TRUE(back.has_value());
  EXPECT_NEAR(back->x(), 50, 1e-9);
  EXPECT_FALSE(ground.Map({50, 20}, 50, 70).has_value());  // across the break
  EXPECT_TRUE(ground.Map({50, 20}, 60, 70).has_value());
  EXPECT_FALSE(ground.Map({50, 20}, 90, 100).has_value());  // never added
  // Frames that never came break the chain too.
  ground.Add(105, true, Eigen::Matrix3d::Identity());
  ground.Add(106, true, Eigen::Matrix3d::Identity());
  EXPECT_FALSE(ground.Map({50, 20}, 99, 105).has_value());
  EXPECT_FALSE(ground.Map({50, 20}, 102, 103).has_value());
  EXPECT_TRUE(ground.Map({50, 20}, 105, 106).has_value());
}

// A walker (0.3 px per frame on the ground, under a camera panning 1 px per frame) stands still
// for 120 frames and walks on: the two pieces are one walker, found where the
// ground's motion carries the place it stopped. Another walker 80 px away is someone else.
TEST(LinkFragmentsTest, OnTheGroundAStoppedWalkerIsJoinedAcrossALongGap) {
  const TargetTrackOptions options;
  std::vector<TargetTrack> tracks;
  tracks.push_back(Track(1, 0, 40, {400, 300}, {-0.7, 0}, {0.3, 0}));     // stops at (372, 300)
  tracks.push_back(Track(2, 160, 220, {254, 301}, {-0.7, 0}, {0.3, 0}));  // that spot: (252, 300)
  tracks.push_back(Track(3, 165, 220, {250, 380}, {-0.7, 0}, {0.3, 0}));
  const GroundMotion ground = Panning(300);
  const std::vector<TargetTrack> linked = LinkFragments(tracks, options, kRate, &ground);
  ASSERT_EQ(linked.size(), 2u);
  EXPECT_EQ(linked[0].id, TargetTrackId{1});
  EXPECT_EQ(linked[0].observations.back().frame, 220);
  EXPECT_EQ(linked[0].observations.size(), 41u + 61u);
  EXPECT_EQ(linked[1].id, TargetTrackId{3});
  // Without the ground's motion, or across a chain break, the gap is too long to bridge.
  EXPECT_EQ(LinkFragments(tracks, options, kRate).size(), 3u);
  const GroundMotion broken = Panning(300, /*chain_break=*/100);
  EXPECT_EQ(LinkFragments(tracks, options, kRate, &broken).size(), 3u);
}

// A walker (0.3 px per frame on the ground, the camera panning 1 px per frame) unseen for 10
// frames, then for 30: the short gap is filled on the ground (the image position moves by the
// walker's step less the pan), with boxes and velocities and no features, the long one is left.
// Nothing is filled across a chain break, or with fill_gap_s 0.
TEST(FillGapsTest, FillsShortGapsAlongTheGroundAndNoOther) {
  TargetTrack walker = Track(1, 0, 60, {400, 300}, {-0.7, 0}, {0.3, 0});
  std::erase_if(walker.observations, [](const TargetObservation& o) {
    return (o.frame > 10 && o.frame < 21) || (o.frame > 25 && o.frame < 56);
  });
  ASSERT_EQ(walker.observations.size(), 61u - 10u - 30u);
  for (TargetObservation& x : walker.observations) {
    x.box_min = x.position - Eigen::Vector2d(3, 4);
    x.box_max = x.position + Eigen::Vector2d(3, 4);
  }
  const TargetTrackOptions options;  // fill_gap_s 1: 25 frames at 25 fps
  const GroundMotion ground = Panning(100);
  const std::vector<TargetTrack> filled = FillGaps({walker}, options, kRate, ground);
  ASSERT_EQ(filled.size(), 1u);
  const std::vector<TargetObservation>& o = filled[0].observations;
  ASSERT_EQ(o.size(), 61u - 30u);
  for (size_t k = 0; k + 1 < o.size(); ++k) EXPECT_LT(o[k].frame, o[k + 1].frame);
  int interpolated = 0;
  for (const TargetObservation& x : o) {
    EXPECT_NEAR(x.position.x(), 400 - 0.7 * static_cast<double>(x.frame), 1e-9) << x.frame;
    EXPECT_NEAR(x.position.y(), 300, 1e-9);
    EXPECT_NEAR((x.box_min - (x.position - Eigen::Vector2d(3, 4))).norm(), 0, 1e-9);
    EXPECT_NEAR((x.box_max - (x.position + Eigen::Vector2d(3, 4))).norm(), 0, 1e-9);
    EXPECT_EQ(x.interpolated, x.frame > 10 && x.frame < 21) << x.frame;
    if (x.interpolated) {
      EXPECT_TRUE(x.features.empty());
      EXPECT_EQ(x.change, ChangeEvidence::kNotLooked);
      EXPECT_NEAR(x.velocity.x(), 0.3, 1e-9);
      ++interpolated;
    }
  }
  EXPECT_EQ(interpolated, 10);
  // A longer gap is filled when the option allows it (30 unseen frames, 1.2 s).
  TargetTrackOptions longer = options;
  longer.fill_gap_s = 1.3;
  EXPECT_EQ(FillGaps({walker}, longer, kRate, ground)[0].observations.size(), 61u);
  // Across a chain break (frame 15), or with filling off, the gap stays.
  EXPECT_EQ(
      FillGaps({walker}, options, kRate, Panning(100, /*chain_break=*/15))[0].observations.size(),
      21u);
  TargetTrackOptions off = options;
  off.fill_gap_s = 0;
  EXPECT_EQ(FillGaps({walker}, off, kRate, ground)[0].observations.size(), 21u);
  off.fill_gap_s = -1;
  EXPECT_FALSE(off.Validate().ok());
}

// A walker's second track that follows it, drifts and then follows the walker it passes is
// dropped: it runs beside one of them in most of its frames. The two walkers' own tracks, a third
// walker 20 px away and a car passing stay; of two tracks side by side throughout (one walker
// tracked twice), the later goes.
TEST(DropShadowsTest, DropsASecondTrackThatShadowsWalkersButNotTheWalkers) {
  const TargetTrackOptions options;
  std::vector<TargetTrack> tracks;
  tracks.push_back(Track(1, 0, 99, {100, 100}, {0.3, 0}, {0.3, 0}));
  tracks.push_back(Track(2, 60, 199, {150, 130}, {0.3, 0.1}, {0.3, 0.1}));
  TargetTrack shadow = Track(3, 20, 150, {0, 0}, {0, 0}, {0.3, 0});
  for (TargetObservation& o : shadow.observations) {
    const double f = static_cast<double>(o.frame);
    if (o.frame < 70) {
      o.position = Eigen::Vector2d(100 + 0.3 * f, 100) + Eigen::Vector2d(2, 1);
    } else if (o.frame < 90) {
      o.position = Eigen::Vector2d(300 + f, 300);  // drifting, beside nobody
    } else {
      o.position =
          Eigen::Vector2d(150 + 0.3 * (f - 60), 130 + 0.1 * (f - 60)) + Eigen::Vector2d(-2, 1);
    }
  }
  tracks.push_back(shadow);
  tracks.push_back(Track(4, 0, 99, {100, 120}, {0.3, 0}, {0.3, 0}));     // 20 px from walker 1
  tracks.push_back(Track(5, 200, 299, {400, 400}, {0.3, 0}, {0.3, 0}));  // one walker ...
  tracks.push_back(Track(6, 200, 299, {402, 401}, {0.3, 0}, {0.3, 0}));  // ... tracked twice
  tracks.push_back(Track(7, 0, 99, {0, 101}, {2, 0}, {2, 0}));           // a car passing 1
  const std::vector<TargetTrack> kept = DropShadows(tracks, options, kRate);
  std::vector<int64_t> ids;
  for (const TargetTrack& t : kept) ids.push_back(static_cast<int64_t>(t.id));
  EXPECT_EQ(ids, (std::vector<int64_t>{1, 2, 4, 5, 7}));
  // Turned off.
  TargetTrackOptions off;
  off.shadow_fraction = 2;
  EXPECT_EQ(DropShadows(tracks, off, kRate).size(), tracks.size());
}

// An hour of video gives thousands of fragments: each of 1000 cars, ten on screen at a time,
// broken into three pieces with its rear corners tracked alongside, comes out whole. (Rescanning
// every pair after every merge had not finished this after 300 s; see docs/front-end.md.)
TEST(LinkFragmentsTest, ThousandsOfFragmentsLinkIntoTheirTargets) {
  const TargetTrackOptions options;
  constexpr int kCars = 1000;
  std::vector<TargetTrack> tracks;
  for (int i = 0; i < kCars; ++i) {
    const int64_t s = 20 * i;  // one car enters every 20 frames and is seen for 200
    const Eigen::Vector2d at(100, 100 + 100 * (i % 20));
    const Eigen::Vector2d step(4, 0);
    const auto piece = [&](int64_t id, int64_t first, int64_t last, double dx) {
      tracks.push_back(Track(id, s + first, s + last,
                             at + step * static_cast<double>(first) + Eigen::Vector2d(dx, 0), step,
                             {2, 0}));
    };
    const int64_t id = 10 * i + 1;
    piece(id, 0, 60, 0);
    piece(id + 1, 80, 140, 0);
    piece(id + 2, 160, 200, 0);
    piece(id + 3, 10, 50, -12);  // the rear corners, alongside the first piece
  }
  std::shuffle(tracks.begin(), tracks.end(), std::mt19937(7));
  const std::vector<TargetTrack> linked = LinkFragments(tracks, options, kRate);
  ASSERT_EQ(linked.size(), static_cast<size_t>(kCars));
  for (int i = 0; i < kCars; ++i) {
    EXPECT_EQ(linked[i].id, TargetTrackId{10 * i + 1});
    EXPECT_EQ(linked[i].observations.front().frame, 20 * i);
    EXPECT_EQ(linked[i].observations.back().frame, 20 * i + 200);
    EXPECT_EQ(linked[i].observations.size(), 163u) << "car " << i;  // 61 + 61 + 41 frames seen
  }
}

}  // namespace
}  // namespace saker::track
