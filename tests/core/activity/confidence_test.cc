#include "core/activity/confidence.h"

#include "core/activity/activity.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <random>
#include <unordered_map>

namespace saker::activity {
namespace {

using mission::ActivityTrack;
using mission::Mission;
using mission::TrackPoint;

constexpr int kWidth = 640, kHeight = 480;
constexpr double kMetresPerPixel = 0.1;
constexpr double kSeconds = 30;

// A mission of `fps` frames per second over 30 s from a camera that stays still, so that every
// frame is placed with the same map_from_frame: 0.1 m per pixel, north up (when geo-referenced).
Mission MakeMission(double fps, bool geo_referenced = true) {
  Mission mission;
  mission.source.width = kWidth;
  mission.source.height = kHeight;
  mission.source.frame_rate = fps;
  mission.map.geo_referenced = geo_referenced;
  if (geo_referenced) mission.map.origin = geo::Wgs84{51.5, -1.2, 100};
  Eigen::Matrix3d map_from_frame;
  const double flip = geo_referenced ? -1 : 1;
  map_from_frame << kMetresPerPixel, 0, 0, 0, flip * kMetresPerPixel, 0, 0, 0, 1;
  for (int64_t k = 0; k < static_cast<int64_t>(kSeconds * fps); ++k) {
    mission::FrameRecord frame;
    frame.index = k;
    frame.time_s = static_cast<double>(k) / fps;
    frame.map_from_frame = map_from_frame;
    mission.frames.push_back(frame);
  }
  mission.progress.mosaic = true;
  return mission;
}

// A target whose map position at time t (from its first sighting) is `path(t)`, seen from
// `start_s` for `duration_s`, its map positions scattered by `noise_m` (the detector's jitter).
ActivityTrack Observe(const Mission& mission, int64_t id, double start_s, double duration_s,
                      const std::function<Eigen::Vector2d(double)>& path, double noise_m,
                      uint64_t seed) {
  std::mt19937_64 random(seed);
  std::normal_distribution<double> noise(0, noise_m);
  const double fps = mission.source.frame_rate;
  const Eigen::Matrix3d frame_from_map = mission.frames.front().map_from_frame->inverse();
  ActivityTrack track;
  track.id = id;
  for (int64_t k = static_cast<int64_t>(std::lround(start_s * fps));
       k <= static_cast<int64_t>(std::lround((start_s + duration_s) * fps)); ++k) {
    const double t = static_cast<double>(k) / fps - start_s;
    const Eigen::Vector2d map = path(t) + Eigen::Vector2d(noise(random), noise(random));
    TrackPoint point;
    point.frame = k;
    point.image = (frame_from_map * map.homogeneous()).hnormalized();
    point.box_min = point.image - Eigen::Vector2d(10, 10);
    point.box_max = point.image + Eigen::Vector2d(10, 10);
    track.points.push_back(point);
  }
  return track;
}

// Evidence of a track with `features` supporting features per observation and change seen at
// `changed` of its observations (the change detector looked at all of them).
TrackEvidence Evidence(const ActivityTrack& track, double features, double changed) {
  TrackEvidence e;
  e.observations = static_cast<int64_t>(track.points.size());
  e.feature_sightings = std::llround(features * static_cast<double>(e.observations));
  e.looked = e.observations;
  e.changed = std::llround(changed * static_cast<double>(e.observations));
  return e;
}

std::function<Eigen::Vector2d(double)> Straight(Eigen::Vector2d start, Eigen::Vector2d velocity) {
  return [=](double t) -> Eigen::Vector2d { return start + velocity * t; };
}

// Maps `tracks` with evidence `evidence_of(track)` for each.
StatusOr<ActivitySummary> Assess(const Mission& mission, std::vector<ActivityTrack>* tracks,
                                 const std::function<TrackEvidence(const ActivityTrack&)>& of,
                                 const ActivityOptions& options = {}) {
  std::unordered_map<int64_t, TrackEvidence> evidence;
  for (const ActivityTrack& t : *tracks) evidence[t.id] = of(t);
  return MapActivity(mission, tracks, options, &evidence);
}

// A car seen for 10 s at 10 m/s, carrying three corners, the change detector agreeing at most
// observations; a flicker seen for 0.6 s whose positions scatter more than it moves, one feature,
// rarely a change.
TEST(Confidence, LongSteadyTrackScoresHighShortJitteryLow) {
  const Mission mission = MakeMission(25);
  std::vector<ActivityTrack> tracks = {
      Observe(mission, 1, 2, 10, Straight({5, -20}, {10, 0}), 0.05, 1),
      Observe(mission, 2, 5, 0.6, Straight({20, -30}, {0.3, 0}), 0.5, 2)};
  const auto summary = Assess(mission, &tracks, [](const ActivityTrack& t) {
    return t.id == 1 ? Evidence(t, 3, 0.9) : Evidence(t, 1, 0.1);
  });
  ASSERT_TRUE(summary.ok()) << summary.status().ToString();
  ASSERT_EQ(tracks.size(), 2u);
  ASSERT_TRUE(tracks[0].confidence.has_value());
  ASSERT_TRUE(tracks[1].confidence.has_value());
  std::printf("steady: %.3f, jittery: %.3f\n", *tracks[0].confidence, *tracks[1].confidence);
  EXPECT_GT(*tracks[0].confidence, 0.85);
  EXPECT_LT(*tracks[1].confidence, 0.35);
  EXPECT_EQ(summary->tracks_implausible, 0);
}

// The same targets filmed at 5 and at 25 frames per second: the confidence is measured in
// seconds and metres, not in frames.
TEST(Confidence, FrameRateDoesNotChangeTheConfidence) {
  const Mission slow = MakeMission(5), fast = MakeMission(25);
  struct Case {
    double duration_s, noise_m, features, changed;
    Eigen::Vector2d velocity;
  };
  for (const Case& c : {Case{10, 0.05, 3, 0.9, {10, 0}}, Case{3, 0.3, 1, 0.5, {1.4, 0.3}},
                        Case{1.5, 0.2, 2, 0.3, {0.6, 0}}}) {
    std::vector<ActivityTrack> at5 = {
        Observe(slow, 1, 2, c.duration_s, Straight({5, -20}, c.velocity), c.noise_m, 3)};
    std::vector<ActivityTrack> at25 = {
        Observe(fast, 1, 2, c.duration_s, Straight({5, -20}, c.velocity), c.noise_m, 4)};
    const auto of = [&](const ActivityTrack& t) { return Evidence(t, c.features, c.changed); };
    ASSERT_TRUE(Assess(slow, &at5, of).ok());
    ASSERT_TRUE(Assess(fast, &at25, of).ok());
    ASSERT_EQ(at5.size(), 1u);
    ASSERT_EQ(at25.size(), 1u);
    std::printf("%.1f s at %.1f m/s, %.2f m scatter: %.3f at 5 fps, %.3f at 25 fps\n", c.duration_s,
                c.velocity.norm(), c.noise_m, *at5[0].confidence, *at25[0].confidence);
    EXPECT_NEAR(*at5[0].confidence, *at25[0].confidence, 0.1)
        << c.duration_s << " s at " << c.velocity.norm() << " m/s";
  }
}

// Above 70 m/s no ground vehicle goes: such a track is not reported, and counted. Between the
// plausible limit (40 m/s) and that, the confidence falls.
TEST(Confidence, ImpossibleGroundSpeedIsNotReported) {
  const Mission mission = MakeMission(25);
  std::vector<ActivityTrack> tracks = {
      Observe(mission, 1, 2, 5, Straight({0, -20}, {90, 0}), 0.05, 5),
      Observe(mission, 2, 2, 5, Straight({0, -30}, {55, 0}), 0.05, 6),
      Observe(mission, 3, 2, 5, Straight({0, -40}, {25, 0}), 0.05, 7)};
  const auto summary =
      Assess(mission, &tracks, [](const ActivityTrack& t) { return Evidence(t, 3, 0.9); });
  ASSERT_TRUE(summary.ok()) << summary.status().ToString();
  EXPECT_EQ(summary->tracks_implausible, 1);
  ASSERT_EQ(tracks.size(), 2u);
  EXPECT_EQ(tracks[0].id, 2);
  EXPECT_EQ(tracks[1].id, 3);
  EXPECT_LT(*tracks[0].confidence, 0.6);  // 55 m/s: half way to the limit
  EXPECT_GT(*tracks[1].confidence, 0.8);

  // Without a scale (a map in pixels) a speed proves nothing: kept.
  const Mission pixels = MakeMission(25, /*geo_referenced=*/false);
  std::vector<ActivityTrack> unscaled = {
      Observe(pixels, 1, 2, 5, Straight({0, 20}, {90, 0}), 0.05, 5)};
  const auto kept =
      Assess(pixels, &unscaled, [](const ActivityTrack& t) { return Evidence(t, 3, 0.9); });
  ASSERT_TRUE(kept.ok());
  EXPECT_EQ(kept->tracks_implausible, 0);
  ASSERT_EQ(unscaled.size(), 1u);
  EXPECT_GT(*unscaled[0].confidence, 0.8);
}

// A path that goes back and forth every second is no ground mover, however long it lasts.
TEST(Confidence, HeadingReversalsLowerTheMotionFactor) {
  const Mission mission = MakeMission(25);
  const auto shuttle = [](double t) -> Eigen::Vector2d {
    const double phase = std::fmod(t, 2.0);
    return {10 + 3 * (phase < 1 ? phase : 2 - phase), -20};
  };
  std::vector<ActivityTrack> tracks = {Observe(mission, 1, 2, 10, shuttle, 0.02, 8)};
  ASSERT_TRUE(
      Assess(mission, &tracks, [](const ActivityTrack& t) { return Evidence(t, 3, 0.9); }).ok());
  ASSERT_EQ(tracks.size(), 1u);
  const ConfidenceFactors f = AssessTrack(tracks[0], Evidence(tracks[0], 3, 0.9), {});
  EXPECT_LT(f.steadiness, 0.3);
  EXPECT_LT(*tracks[0].confidence, 0.6);
}

// Feature and change support each count; either alone supports a track.
TEST(Confidence, SupportFromFeaturesOrChange) {
  const Mission mission = MakeMission(25);
  std::vector<ActivityTrack> tracks = {
      Observe(mission, 1, 2, 6, Straight({5, -20}, {8, 0}), 0.05, 9)};
  ASSERT_TRUE(
      Assess(mission, &tracks, [](const ActivityTrack& t) { return Evidence(t, 3, 0.9); }).ok());
  const ActivityTrack& t = tracks[0];
  const ConfidenceOptions options;
  const double none = AssessTrack(t, Evidence(t, 0, 0), options).confidence;
  const double features = AssessTrack(t, Evidence(t, 4, 0), options).confidence;
  const double change = AssessTrack(t, Evidence(t, 0, 0.9), options).confidence;
  const double both = AssessTrack(t, Evidence(t, 4, 0.9), options).confidence;
  EXPECT_EQ(none, 0);
  EXPECT_GT(features, 0.7);
  EXPECT_GT(change, 0.7);
  EXPECT_GT(both, std::max(features, change));
  // The change detector having looked nowhere is no evidence against the track.
  TrackEvidence unlooked = Evidence(t, 4, 0);
  unlooked.looked = 0;
  EXPECT_DOUBLE_EQ(AssessTrack(t, unlooked, options).confidence, features);
}

// Interpolated points (track::FillGaps) lie on a line by construction: the motion factors are
// those of the seen points, however many were filled in between.
TEST(Confidence, InterpolatedPointsAreNoEvidenceOfSteadyMotion) {
  const Mission mission = MakeMission(25);
  std::vector<ActivityTrack> tracks = {
      Observe(mission, 1, 2, 6, Straight({5, -20}, {1.2, 0}), 0.4, 11)};
  ASSERT_TRUE(
      Assess(mission, &tracks, [](const ActivityTrack& t) { return Evidence(t, 2, 0.8); }).ok());
  ASSERT_EQ(tracks.size(), 1u);
  // Four points in five not seen (gaps of 0.16 s): once left out, once filled in on the line
  // between the seen points on either side.
  ActivityTrack seen = tracks[0], filled = tracks[0];
  seen.points.clear();
  const size_t n = filled.points.size();
  for (size_t i = 0; i < n; ++i) {
    const size_t before = i / 5 * 5, after = std::min(before + 5, n - 1);
    if (i == before || i == n - 1) {
      seen.points.push_back(filled.points[i]);
      continue;
    }
    const double w = static_cast<double>(i - before) / static_cast<double>(after - before);
    filled.points[i].map = (1 - w) * tracks[0].points[before].map + w * tracks[0].points[after].map;
    filled.points[i].interpolated = true;
  }
  const TrackEvidence evidence = Evidence(seen, 2, 0.8);
  const ConfidenceFactors with_filled = AssessTrack(filled, evidence, {});
  const ConfidenceFactors seen_only = AssessTrack(seen, evidence, {});
  EXPECT_DOUBLE_EQ(with_filled.jitter, seen_only.jitter);
  EXPECT_DOUBLE_EQ(with_filled.steadiness, seen_only.steadiness);
  EXPECT_DOUBLE_EQ(with_filled.confidence, seen_only.confidence);
  // Taken as seen, the points on the line would make the track look steadier than it was.
  ActivityTrack counted = filled;
  for (TrackPoint& p : counted.points) p.interpolated = false;
  const ConfidenceFactors as_seen = AssessTrack(counted, evidence, {});
  std::printf("jitter: seen %.3f, filled points taken as seen %.3f\n", seen_only.jitter,
              as_seen.jitter);
  EXPECT_GT(as_seen.jitter, seen_only.jitter + 0.02);
}

TEST(Confidence, MinimumConfidenceDropsAndCounts) {
  const Mission mission = MakeMission(25);
  std::vector<ActivityTrack> tracks = {
      Observe(mission, 1, 2, 10, Straight({5, -20}, {10, 0}), 0.05, 1),
      Observe(mission, 2, 5, 0.6, Straight({20, -30}, {0.3, 0}), 0.5, 2)};
  ActivityOptions options;
  options.confidence.min_confidence = 0.5;
  const auto summary = Assess(
      mission, &tracks,
      [](const ActivityTrack& t) { return t.id == 1 ? Evidence(t, 3, 0.9) : Evidence(t, 1, 0.1); },
      options);
  ASSERT_TRUE(summary.ok());
  EXPECT_EQ(summary->tracks_low_confidence, 1);
  ASSERT_EQ(tracks.size(), 1u);
  EXPECT_EQ(tracks[0].id, 1);

  options.confidence.min_confidence = 1.5;
  EXPECT_EQ(MapActivity(mission, &tracks, options).status().code(), StatusCode::kInvalidArgument);
}

// Without the front end's evidence (a loaded mission mapped again) a track's confidence is left
// as it was.
TEST(Confidence, NoEvidenceLeavesTheConfidence) {
  const Mission mission = MakeMission(25);
  std::vector<ActivityTrack> tracks = {
      Observe(mission, 1, 2, 10, Straight({5, -20}, {10, 0}), 0.05, 1),
      Observe(mission, 2, 2, 10, Straight({5, -30}, {10, 0}), 0.05, 1)};
  tracks[1].confidence = 0.25;
  ASSERT_TRUE(MapActivity(mission, &tracks).ok());
  ASSERT_EQ(tracks.size(), 2u);
  EXPECT_FALSE(tracks[0].confidence.has_value());
  EXPECT_EQ(tracks[1].confidence, 0.25);
}

TEST(Confidence, PassesAndSpread) {
  ActivityTrack known, unknown;
  known.confidence = 0.6;
  EXPECT_TRUE(PassesConfidence(known, 0));
  EXPECT_TRUE(PassesConfidence(unknown, 0));
  EXPECT_TRUE(PassesConfidence(known, 0.6));
  EXPECT_FALSE(PassesConfidence(known, 0.61));
  EXPECT_FALSE(PassesConfidence(unknown, 0.1));
  std::vector<ActivityTrack> tracks(5);
  tracks[0].confidence = 0.9;
  tracks[1].confidence = 0.8;
  tracks[2].confidence = 0.5;
  tracks[3].confidence = 0.1;
  const ConfidenceSpread spread = SpreadOf(tracks);
  EXPECT_EQ(spread.high, 2);
  EXPECT_EQ(spread.medium, 1);
  EXPECT_EQ(spread.low, 1);
  EXPECT_EQ(spread.unknown, 1);
}

}  // namespace
}  // namespace saker::activity
