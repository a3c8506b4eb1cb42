#include "core/activity/activity.h"

#include <Eigen/LU>
#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace saker::activity {
namespace {

using mission::ActivityTrack;
using mission::Mission;
using mission::TrackPoint;

constexpr int kWidth = 640, kHeight = 480;
constexpr double kFps = 25;
constexpr double kMetresPerPixel = 0.1;

// The camera's centre on the map at time t: east at 10 m/s from x = -100 for 30 s, away for
// 10 s (frames not placed), then back west at 10 m/s from x = 200.
std::optional<Eigen::Vector2d> CameraCentre(double t) {
  if (t < 30) return Eigen::Vector2d(-100 + 10 * t, 0);
  if (t < 40) return std::nullopt;
  return Eigen::Vector2d(200 - 10 * (t - 40), 0);
}

// A geo-referenced mission (north up, 0.1 m per pixel) with 70 s of frames.
Mission MakeMission(bool geo_referenced = true) {
  Mission mission;
  mission.source.width = kWidth;
  mission.source.height = kHeight;
  mission.source.frame_rate = kFps;
  mission.map.geo_referenced = geo_referenced;
  if (geo_referenced) mission.map.origin = geo::Wgs84{51.5, -1.2, 100};
  for (int64_t k = 0; k < static_cast<int64_t>(70 * kFps); ++k) {
    mission::FrameRecord frame;
    frame.index = k;
    frame.time_s = static_cast<double>(k) / kFps;
    if (const auto centre = CameraCentre(frame.time_s)) {
      Eigen::Matrix3d map_from_frame;
      const double flip = geo_referenced ? -1 : 1;  // image y down; map north up
      map_from_frame << kMetresPerPixel, 0, centre->x() - kMetresPerPixel * (kWidth - 1) / 2,   //
          0, flip * kMetresPerPixel, centre->y() - flip * kMetresPerPixel * (kHeight - 1) / 2,  //
          0, 0, 1;
      frame.map_from_frame = map_from_frame;
    }
    mission.frames.push_back(frame);
  }
  mission.progress.mosaic = true;
  return mission;
}

// A target at `start` moving with `velocity` (m/s) seen on frames [first, last], its image
// positions measured with `noise_px` of jitter.
ActivityTrack Observe(const Mission& mission, int64_t id, Eigen::Vector2d start,
                      Eigen::Vector2d velocity, int64_t first, int64_t last, double noise_px,
                      std::mt19937_64* random) {
  std::normal_distribution<double> noise(0, noise_px);
  ActivityTrack track;
  track.id = id;
  for (int64_t k = first; k <= last; ++k) {
    const mission::FrameRecord& frame = mission.frames[static_cast<size_t>(k)];
    const Eigen::Vector2d map =
        start + velocity * (frame.time_s - mission.frames[static_cast<size_t>(first)].time_s);
    TrackPoint point;
    point.frame = k;
    point.image = (frame.map_from_frame->inverse() * map.homogeneous()).hnormalized() +
                  Eigen::Vector2d(noise(*random), noise(*random));
    point.box_min = point.image - Eigen::Vector2d(10, 10);
    point.box_max = point.image + Eigen::Vector2d(10, 10);
    track.points.push_back(point);
  }
  return track;
}

TEST(Activity, SpeedDirectionAndPlacementOfASteadyTarget) {
  const Mission mission = MakeMission();
  std::mt19937_64 random(7);
  // Northbound at 5 m/s through x = 50 during the first pass (covered from t = 11.8 s to 18.2 s),
  // eastbound at 1.4 m/s (a walker) during the second.
  std::vector<ActivityTrack> tracks = {
      Observe(mission, 1, {50, -10}, {0, 5}, 300, 400, 0.5, &random),
      Observe(mission, 2, {40, 5}, {1.4, 0}, 1320, 1420, 0.5, &random)};
  const auto summary = MapActivity(mission, &tracks);
  ASSERT_TRUE(summary.ok()) << summary.status().ToString();
  ASSERT_EQ(tracks.size(), 2u);
  EXPECT_EQ(summary->observations_dropped, 0);

  const ActivityTrack& car = tracks[0];
  EXPECT_NEAR(car.start_s, 12.0, 1e-9);
  EXPECT_NEAR(car.end_s, 16.0, 1e-9);
  // Map positions: the truth within the jitter (0.5 px = 5 cm, 3 sigma).
  EXPECT_NEAR(car.points.front().map.x(), 50, 0.15);
  EXPECT_NEAR(car.points.front().map.y(), -10, 0.15);
  ASSERT_TRUE(car.speed_mps.has_value());
  EXPECT_NEAR(*car.speed_mps, 5.0, 0.1);
  EXPECT_NEAR(car.length, 20.0, 0.5);
  EXPECT_NEAR(car.heading_deg < 180 ? car.heading_deg : car.heading_deg - 360, 0.0, 1.0);

  const ActivityTrack& walker = tracks[1];
  ASSERT_TRUE(walker.speed_mps.has_value());
  EXPECT_NEAR(*walker.speed_mps, 1.4, 0.1);
  EXPECT_NEAR(walker.heading_deg, 90.0, 2.0);
}

TEST(Activity, VisitCountsThePassesOverThePlace) {
  const Mission mission = MakeMission();
  std::mt19937_64 random(8);
  // The same crossing seen on the way out (visit 1) and on the way back (visit 2).
  std::vector<ActivityTrack> tracks = {
      Observe(mission, 1, {50, -10}, {0, 5}, 300, 400, 0.3, &random),
      Observe(mission, 2, {50, -10}, {0, 5}, 1300, 1400, 0.3, &random)};
  const auto summary = MapActivity(mission, &tracks);
  ASSERT_TRUE(summary.ok()) << summary.status().ToString();
  ASSERT_EQ(tracks.size(), 2u);
  EXPECT_EQ(tracks[0].visit, 1);
  EXPECT_EQ(tracks[1].visit, 2);
  EXPECT_EQ(summary->max_visit, 2);

  // A gap longer than the time away (10 s + the footprint's crossing) joins both passes.
  std::vector<ActivityTrack> joined = {
      Observe(mission, 2, {50, -10}, {0, 5}, 1300, 1400, 0.3, &random)};
  ActivityOptions options;
  options.visit_gap_s = 60;
  ASSERT_TRUE(MapActivity(mission, &joined, options).ok());
  EXPECT_EQ(joined[0].visit, 1);
}

TEST(Activity, CoverageIndexFindsBothPasses) {
  const Mission mission = MakeMission();
  const CoverageIndex coverage(mission, 1);
  const auto visits = coverage.Visits({50, 0}, 5);
  ASSERT_EQ(visits.size(), 2u);
  // The footprint (64 m wide) covers x = 50 while the centre is within 32 m of it.
  EXPECT_NEAR(visits[0].start_s, 11.8, 0.05);
  EXPECT_NEAR(visits[0].end_s, 18.2, 0.05);
  EXPECT_NEAR(visits[1].start_s, 51.8, 0.05);
  EXPECT_TRUE(coverage.Visits({50, 100}, 5).empty());  // north of the strip
}

TEST(Activity, ObservationsOnUnplacedFramesAreDropped) {
  const Mission mission = MakeMission();
  std::mt19937_64 random(9);
  // Frames 700-800 (t = 28-32 s): the camera is away from t = 30 s.
  std::vector<ActivityTrack> tracks = {Observe(mission, 1, {180, 0}, {1, 0}, 700, 749, 0, &random)};
  ActivityTrack unplaced = tracks[0];
  unplaced.id = 2;
  for (TrackPoint& point : unplaced.points) point.frame += 60;  // frames 760-809: not placed
  tracks.push_back(unplaced);
  const auto summary = MapActivity(mission, &tracks);
  ASSERT_TRUE(summary.ok());
  ASSERT_EQ(tracks.size(), 1u);  // the track with no placed observation is removed
  EXPECT_EQ(tracks[0].id, 1);
  EXPECT_EQ(summary->observations_dropped, 50);
  EXPECT_EQ(summary->tracks_out, 1);

  std::vector<ActivityTrack> foreign = {tracks[0]};
  foreign[0].points[0].frame = 999999;
  const auto bad = MapActivity(mission, &foreign);
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().message().find("999999"), std::string::npos);
}

// A low oblique view: observations above the frame's sky line, or on ground seen more than
// kMaxScaleSpread times coarser than its nearest, are not placed (the tiles leave them out too).
TEST(Activity, ObservationsInTheSkyOrTheDistantGroundAreDropped) {
  Mission mission = MakeMission(/*geo_referenced=*/false);
  Eigen::Matrix3d oblique = Eigen::Matrix3d::Identity();
  oblique(2, 1) = 1.0 / 100;  // w = 0.05 + y / 100 ...
  oblique(2, 2) = 0.05;       // ... 0.05 on the top row, 0.25 at row 20
  mission::FrameRecord& frame = mission.frames[10];
  frame.map_from_frame = oblique;
  frame.sky_line = mission::SkyLine{5, 0};  // rows above 5 are sky
  const double nearest = 0.05 + (kHeight - 1) / 100.0;
  const double farthest_row =
      (nearest * std::pow(mission::kMaxScaleSpread, -2.0 / 3.0) - 0.05) * 100;
  ASSERT_GT(farthest_row, 5);
  ASSERT_LT(farthest_row, kHeight - 10);
  std::vector<ActivityTrack> tracks(1);
  tracks[0].id = 1;
  for (const double row : {2.0, farthest_row - 1, farthest_row + 1, kHeight - 2.0}) {
    TrackPoint point;
    point.frame = 10;
    point.image = {kWidth / 2.0, row};
    tracks[0].points.push_back(point);
  }
  const auto summary = MapActivity(mission, &tracks);
  ASSERT_TRUE(summary.ok()) << summary.status().ToString();
  EXPECT_EQ(summary->observations_dropped, 2);  // the sky and the distant ground
  ASSERT_EQ(tracks.size(), 1u);
  ASSERT_EQ(tracks[0].points.size(), 2u);
  EXPECT_EQ(tracks[0].points[0].image.y(), farthest_row + 1);
  EXPECT_EQ(tracks[0].points[1].image.y(), kHeight - 2.0);
}

TEST(Activity, HeadingConventions) {
  EXPECT_NEAR(HeadingDegrees({0, 1}, true), 0, 1e-12);
  EXPECT_NEAR(HeadingDegrees({1, 0}, true), 90, 1e-12);
  EXPECT_NEAR(HeadingDegrees({0, -1}, true), 180, 1e-12);
  EXPECT_NEAR(HeadingDegrees({-1, 0}, true), 270, 1e-12);
  // Not geo-referenced: north is up the image, -y.
  EXPECT_NEAR(HeadingDegrees({0, -1}, false), 0, 1e-12);
  EXPECT_NEAR(HeadingDegrees({0, 1}, false), 180, 1e-12);
}

TEST(Activity, NotGeoReferencedHasNoMetresPerSecond) {
  const Mission mission = MakeMission(/*geo_referenced=*/false);
  std::mt19937_64 random(10);
  std::vector<ActivityTrack> tracks = {
      Observe(mission, 1, {50, 10}, {0, -5}, 300, 400, 0, &random)};
  ASSERT_TRUE(MapActivity(mission, &tracks).ok());
  EXPECT_FALSE(tracks[0].speed_mps.has_value());
  EXPECT_NEAR(tracks[0].speed, 5.0, 0.05);       // map units per second
  EXPECT_NEAR(tracks[0].heading_deg, 0.0, 0.5);  // up the image
}

TEST(TrackIndex, NearestAgreesWithBruteForce) {
  std::mt19937_64 random(11);
  std::uniform_real_distribution<double> coordinate(-500, 500);
  std::vector<ActivityTrack> tracks(50);
  for (size_t t = 0; t < tracks.size(); ++t) {
    for (int p = 0; p < 40; ++p) {
      TrackPoint point;
      point.map = {coordinate(random), coordinate(random)};
      tracks[t].points.push_back(point);
    }
  }
  const TrackIndex index(&tracks);
  EXPECT_EQ(index.size(), 2000u);
  for (int q = 0; q < 500; ++q) {
    const Eigen::Vector2d query(coordinate(random), coordinate(random));
    const double tolerance = q % 2 == 0 ? 15 : 2000;
    std::optional<Pick> brute;
    for (size_t t = 0; t < tracks.size(); ++t) {
      if (t % 7 == 3) continue;  // filtered out
      for (size_t p = 0; p < tracks[t].points.size(); ++p) {
        const double d = (tracks[t].points[p].map - query).norm();
        if (d <= tolerance && (!brute || d < brute->distance)) brute = Pick{t, p, d};
      }
    }
    const auto pick = index.Nearest(query, tolerance, [](size_t t) { return t % 7 != 3; });
    ASSERT_EQ(pick.has_value(), brute.has_value()) << q;
    if (pick) {
      EXPECT_EQ(pick->track, brute->track);
      EXPECT_EQ(pick->point, brute->point);
      EXPECT_DOUBLE_EQ(pick->distance, brute->distance);
    }
  }
  const std::vector<ActivityTrack> none;
  EXPECT_FALSE(TrackIndex(&none).Nearest({0, 0}, 1e9).has_value());
}

}  // namespace
}  // namespace saker::activity
