#include "core/sim/flight.h"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <map>

namespace saker::sim {
namespace {

constexpr double kFrameInterval = 1.0 / 30.0;

// Signed difference a - b of two headings, in (-180, 180].
double HeadingDifference(double a, double b) {
  double d = std::fmod(a - b, 360.0);
  if (d > 180.0) d -= 360.0;
  if (d <= -180.0) d += 360.0;
  return d;
}

std::vector<cv::Point2f> Polygon(const std::array<Eigen::Vector2d, 4>& corners) {
  std::vector<cv::Point2f> polygon;
  for (const Eigen::Vector2d& c : corners) polygon.emplace_back(c.x(), c.y());
  return polygon;
}

std::array<Eigen::Vector2d, 4> Footprint(const Flight& flight, double t_s) {
  const auto footprint = GroundFootprint(CameraIntrinsics(), flight.PoseAt(t_s));
  EXPECT_TRUE(footprint.has_value()) << "t = " << t_s;
  return footprint.value_or(std::array<Eigen::Vector2d, 4>{});
}

// Intersection area of two footprints over the area of the first.
double OverlapFraction(const std::array<Eigen::Vector2d, 4>& a,
                       const std::array<Eigen::Vector2d, 4>& b) {
  std::vector<cv::Point2f> intersection;
  const double area = cv::intersectConvexConvex(Polygon(a), Polygon(b), intersection, true);
  return area / cv::contourArea(Polygon(a));
}

// Nadir footprint sizes of the default camera at the default altitude.
double AlongTrackM() { return 720 * NadirGsd(CameraIntrinsics(), 400); }
double AcrossTrackM() { return 1280 * NadirGsd(CameraIntrinsics(), 400); }

// A road loop like a town's: east from the roundabout at (100, 50), round a 300 x 200 m block
// and back (1 km).
FlightSite TownSite() {
  FlightSite site;
  site.centre = {250, 150};
  site.road_loop = {{100, 50}, {250, 50}, {400, 50}, {400, 250}, {100, 250}, {100, 50}};
  return site;
}

StatusOr<Flight> MakeFlight(Scenario scenario, const FlightOptions& options = {}) {
  return Flight::Create(scenario, options, CameraIntrinsics(), TownSite());
}

// Whether segments p0-p1 and q0-q1 cross (proper intersection).
bool SegmentsCross(const Eigen::Vector2d& p0, const Eigen::Vector2d& p1, const Eigen::Vector2d& q0,
                   const Eigen::Vector2d& q1, Eigen::Vector2d* at) {
  auto cross = [](const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    return a.x() * b.y() - a.y() * b.x();
  };
  const Eigen::Vector2d r = p1 - p0;
  const Eigen::Vector2d s = q1 - q0;
  const double denominator = cross(r, s);
  if (std::abs(denominator) < 1e-12) return false;
  const double t = cross(q0 - p0, s) / denominator;
  const double u = cross(q0 - p0, r) / denominator;
  if (t <= 0 || t >= 1 || u <= 0 || u >= 1) return false;
  *at = p0 + t * r;
  return true;
}

TEST(ScenarioTest, NamesRoundTrip) {
  ASSERT_EQ(AllScenarios().size(), 5u);
  for (Scenario scenario : AllScenarios()) {
    EXPECT_EQ(ParseScenario(ScenarioName(scenario)), scenario);
    EXPECT_GT(std::string(ScenarioDescription(scenario)).size(), 10u);
  }
  EXPECT_STREQ(ScenarioName(Scenario::kRoundaboutLoop), "roundabout-loop");
  EXPECT_STREQ(ScenarioName(Scenario::kFigureEight), "figure-eight");
  EXPECT_STREQ(ScenarioName(Scenario::kRaster), "raster");
  EXPECT_STREQ(ScenarioName(Scenario::kStraight), "straight");
  EXPECT_FALSE(ParseScenario("Figure-Eight").has_value());
  EXPECT_FALSE(ParseScenario("").has_value());
}

TEST(GroundTrackTest, ArcLengthAndClamping) {
  const GroundTrack track({{0, 0}, {0, 100}, {0, 100}, {50, 100}});
  EXPECT_EQ(track.points().size(), 3u);  // the repeated point is dropped
  EXPECT_DOUBLE_EQ(track.length_m(), 150);
  EXPECT_TRUE(track.PointAt(40).isApprox(Eigen::Vector2d(0, 40)));
  EXPECT_TRUE(track.PointAt(125).isApprox(Eigen::Vector2d(25, 100)));
  EXPECT_EQ(track.PointAt(-10), Eigen::Vector2d(0, 0));
  EXPECT_EQ(track.PointAt(1e9), Eigen::Vector2d(50, 100));
  EXPECT_THROW(GroundTrack({{1, 1}, {1, 1}}), CheckError);
  EXPECT_THROW(GroundTrack({{1, 1}}), CheckError);
}

TEST(GroundTrackTest, HeadingIsSmoothedOverTwentyMetresEachSide) {
  // North, then a right-angle turn east.
  const GroundTrack track({{0, 0}, {0, 100}, {100, 100}});
  EXPECT_NEAR(track.HeadingAt(0), 0, 1e-9);
  EXPECT_NEAR(track.HeadingAt(79), 0, 1e-9);
  EXPECT_NEAR(track.HeadingAt(100), 45, 1e-9);  // half way through the turn
  EXPECT_NEAR(track.HeadingAt(110), 67.5, 1e-9);
  EXPECT_NEAR(track.HeadingAt(121), 90, 1e-9);
  EXPECT_NEAR(track.HeadingAt(200), 90, 1e-9);
  // South, then right to west: the turn passes through 225, not through north.
  const GroundTrack south_west({{0, 0}, {0, -100}, {-100, -100}});
  EXPECT_NEAR(south_west.HeadingAt(100), 225, 1e-9);
  EXPECT_NEAR(south_west.HeadingAt(90), 202.5, 1e-9);
  // Headings west of north come back in [0, 360).
  const GroundTrack west({{0, 0}, {-10, 10}});
  EXPECT_NEAR(west.HeadingAt(5), 315, 1e-9);
}

TEST(GroundTrackTest, HairpinTurnsGraduallyWithoutFlipping) {
  // North 100 m, then straight back south on the same line: a chord between points either side
  // of the apex is zero, so smoothing positions would flip the heading at once.
  const GroundTrack track({{0, 0}, {0, 100}, {0, 0}});
  double previous = track.HeadingAt(0);
  double largest_step = 0;
  for (double s = 0.5; s <= track.length_m(); s += 0.5) {
    const double heading = track.HeadingAt(s);
    largest_step = std::max(largest_step, std::abs(HeadingDifference(heading, previous)));
    previous = heading;
  }
  EXPECT_NEAR(track.HeadingAt(200), 180, 1e-9);
  // 180 degrees spread over 40 m: 2.25 degrees per half metre.
  EXPECT_LE(largest_step, 2.25 + 1e-9);
  EXPECT_GT(largest_step, 2.0);
}

TEST(FlightOptionsTest, ValidateRejectsNonsense) {
  EXPECT_TRUE(FlightOptions().Validate().ok());
  auto with = [](auto change) {
    FlightOptions options;
    change(options);
    return options.Validate();
  };
  EXPECT_FALSE(with([](FlightOptions& o) { o.speed_mps = -1; }).ok());
  EXPECT_FALSE(with([](FlightOptions& o) { o.speed_mps = 0; }).ok());
  EXPECT_FALSE(with([](FlightOptions& o) { o.speed_mps = NAN; }).ok());
  EXPECT_FALSE(with([](FlightOptions& o) { o.altitude_m = 0; }).ok());
  EXPECT_FALSE(with([](FlightOptions& o) { o.altitude_m = INFINITY; }).ok());
  EXPECT_FALSE(with([](FlightOptions& o) { o.attitude_jitter_deg = -0.1; }).ok());
  EXPECT_FALSE(with([](FlightOptions& o) { o.altitude_jitter_m = 100; }).ok());
  EXPECT_FALSE(with([](FlightOptions& o) { o.key_frame_overlap = 1; }).ok());
  EXPECT_FALSE(with([](FlightOptions& o) { o.key_frame_overlap = -0.2; }).ok());
  EXPECT_FALSE(with([](FlightOptions& o) { o.figure_eight_key_frames = 0; }).ok());
  EXPECT_FALSE(with([](FlightOptions& o) { o.raster_rows = 0; }).ok());
  EXPECT_FALSE(with([](FlightOptions& o) { o.raster_row_length_m = -5; }).ok());
  EXPECT_FALSE(with([](FlightOptions& o) { o.raster_sidelap = 1.5; }).ok());
  EXPECT_FALSE(with([](FlightOptions& o) { o.straight_length_m = 0; }).ok());
  EXPECT_FALSE(with([](FlightOptions& o) { o.straight_heading_deg = NAN; }).ok());
  const Status status = with([](FlightOptions& o) { o.key_frame_overlap = 1; });
  EXPECT_NE(status.message().find("key_frame_overlap"), std::string::npos) << status.message();

  FlightOptions bad;
  bad.altitude_m = 0;
  const auto flight = MakeFlight(Scenario::kStraight, bad);
  ASSERT_FALSE(flight.ok());
  EXPECT_NE(flight.status().message().find("altitude_m"), std::string::npos);
  CameraIntrinsics bad_camera;
  bad_camera.hfov_deg = 0;
  EXPECT_FALSE(Flight::Create(Scenario::kStraight, {}, bad_camera, TownSite()).ok());
}

TEST(FlightTest, RoundaboutLoopNeedsARoadLoop) {
  FlightSite site = TownSite();
  site.road_loop.clear();
  auto flight = Flight::Create(Scenario::kRoundaboutLoop, {}, CameraIntrinsics(), site);
  ASSERT_FALSE(flight.ok());
  EXPECT_NE(flight.status().message().find("road loop is missing"), std::string::npos)
      << flight.status().message();
  site.road_loop = {{0, 0}, {50, 0}, {50, 40}, {0, 0}};  // 154 m
  flight = Flight::Create(Scenario::kRoundaboutLoop, {}, CameraIntrinsics(), site);
  ASSERT_FALSE(flight.ok());
  EXPECT_NE(flight.status().message().find("too short"), std::string::npos)
      << flight.status().message();
  // The other scenarios do not need one.
  EXPECT_TRUE(Flight::Create(Scenario::kFigureEight, {}, CameraIntrinsics(), site).ok());
}

TEST(FlightTest, RoundaboutLoopGoesRoundOnceAndRepeatsItsStart) {
  const auto flight = MakeFlight(Scenario::kRoundaboutLoop);
  ASSERT_TRUE(flight.ok()) << flight.status().ToString();
  const GroundTrack& track = flight->track();
  const Eigen::Vector2d roundabout = TownSite().road_loop.front();
  EXPECT_NEAR(track.length_m(), 1000 + 0.5 * AlongTrackM(), 1e-6);
  EXPECT_NEAR(flight->duration_s(), track.length_m() / 15, 1e-9);
  EXPECT_TRUE(track.PointAt(0).isApprox(roundabout));
  EXPECT_TRUE(track.PointAt(track.length_m())
                  .isApprox(roundabout + Eigen::Vector2d(0.5 * AlongTrackM(), 0)));

  // Passes over the roundabout twice: at the start and after one loop.
  int passes = 0;
  bool near = false;
  for (double s = 0; s <= track.length_m(); s += 1.0) {
    const bool now = (track.PointAt(s) - roundabout).norm() < 20;
    if (now && !near) ++passes;
    near = now;
  }
  EXPECT_EQ(passes, 2);

  // Loop closure: beyond the corner at the roundabout the flight sees the first frame's ground
  // again, its last frames repeat the frames half a footprint in, and the last frame covers
  // about half of the first.
  const double speed = 15;
  const auto first = Footprint(*flight, 0);
  EXPECT_GT(OverlapFraction(first, Footprint(*flight, 1025 / speed)), 0.75);
  EXPECT_GT(OverlapFraction(Footprint(*flight, flight->duration_s()),
                            Footprint(*flight, 0.5 * AlongTrackM() / speed)),
            0.9);
  EXPECT_NEAR(OverlapFraction(first, Footprint(*flight, flight->duration_s())), 0.5, 0.1);
  EXPECT_EQ(OverlapFraction(first, Footprint(*flight, 0.5 * flight->duration_s())), 0.0);
}

TEST(FlightTest, RoundaboutLoopClosesAnOpenRoadLoop) {
  FlightSite site = TownSite();
  site.road_loop.pop_back();
  const auto flight = Flight::Create(Scenario::kRoundaboutLoop, {}, CameraIntrinsics(), site);
  ASSERT_TRUE(flight.ok()) << flight.status().ToString();
  EXPECT_NEAR(flight->track().length_m(), 1000 + 0.5 * AlongTrackM(), 1e-6);
}

TEST(FlightTest, FigureEightCrossesItselfOnceAndClosesAtTheStart) {
  const auto flight = MakeFlight(Scenario::kFigureEight);
  ASSERT_TRUE(flight.ok()) << flight.status().ToString();
  const GroundTrack& track = flight->track();
  const Eigen::Vector2d centre = TownSite().centre;
  const std::vector<Eigen::Vector2d>& points = track.points();

  // Starts on the left (western tip) and ends where it started.
  EXPECT_LT((track.PointAt(0) - track.PointAt(track.length_m())).norm(), 1e-6);
  double west = INFINITY, east = -INFINITY, south = INFINITY, north = -INFINITY;
  for (const Eigen::Vector2d& p : points) {
    west = std::min(west, p.x());
    east = std::max(east, p.x());
    south = std::min(south, p.y());
    north = std::max(north, p.y());
  }
  EXPECT_NEAR(track.PointAt(0).x(), west, 1e-6);
  EXPECT_NEAR(track.PointAt(0).y(), centre.y(), 1e-6);
  // Centred, long axis east-west.
  EXPECT_NEAR(0.5 * (west + east), centre.x(), 1e-6);
  EXPECT_NEAR(0.5 * (south + north), centre.y(), 1e-6);
  EXPECT_GT(east - west, 2.5 * (north - south));

  // One self-crossing, at the centre. Resampled every 9.7 m to keep the test quick and to keep
  // polyline vertices off the crossing point.
  std::vector<Eigen::Vector2d> coarse;
  for (double s = 0; s < track.length_m(); s += 9.7) coarse.push_back(track.PointAt(s));
  coarse.push_back(track.PointAt(track.length_m()));
  std::vector<Eigen::Vector2d> crossings;
  for (size_t i = 0; i + 1 < coarse.size(); ++i) {
    for (size_t j = i + 2; j + 1 < coarse.size(); ++j) {
      Eigen::Vector2d at;
      if (SegmentsCross(coarse[i], coarse[i + 1], coarse[j], coarse[j + 1], &at)) {
        crossings.push_back(at);
      }
    }
  }
  ASSERT_EQ(crossings.size(), 1u);
  EXPECT_LT((crossings[0] - centre).norm(), 1.0);

  // Sized for 75 key frames at 30 % overlap.
  const double advance = 0.7 * AlongTrackM();
  EXPECT_NEAR(track.length_m() / advance, 75, 7.5);
  FlightOptions options;
  options.figure_eight_key_frames = 150;
  const auto longer = MakeFlight(Scenario::kFigureEight, options);
  ASSERT_TRUE(longer.ok());
  EXPECT_NEAR(longer->track().length_m() / advance, 150, 15);

  // Two loop closures: the frames over the centre crossing see each other, and the last frame the
  // first.
  double first_centre_pass = -1, second_centre_pass = -1;
  for (double s = 0; s <= track.length_m(); s += 1.0) {
    if ((track.PointAt(s) - centre).norm() < 1.0) {
      if (first_centre_pass < 0) {
        first_centre_pass = s;
      } else if (s - first_centre_pass > 100) {
        second_centre_pass = s;
        break;
      }
    }
  }
  ASSERT_GE(first_centre_pass, 0);
  ASSERT_GE(second_centre_pass, 0);
  EXPECT_GT(OverlapFraction(Footprint(*flight, first_centre_pass / 15),
                            Footprint(*flight, second_centre_pass / 15)),
            0.3);
  EXPECT_GT(OverlapFraction(Footprint(*flight, 0), Footprint(*flight, flight->duration_s())), 0.9);
}

TEST(FlightTest, RasterRowsAreParallelAndOverlapBySidelap) {
  FlightOptions options;
  options.raster_rows = 5;
  const auto flight = MakeFlight(Scenario::kRaster, options);
  ASSERT_TRUE(flight.ok()) << flight.status().ToString();
  const GroundTrack& track = flight->track();
  const Eigen::Vector2d centre = TownSite().centre;
  const double spacing = 0.7 * AcrossTrackM();

  // Group the straight east- or westbound stretches by their northing.
  std::map<long, std::vector<double>> rows;  // northing (cm) -> headings seen
  std::map<long, std::pair<double, double>> row_x;
  for (double s = 0; s <= track.length_m(); s += 2.0) {
    const double heading = track.HeadingAt(s);
    if (std::abs(HeadingDifference(heading, 90)) > 1e-9 &&
        std::abs(HeadingDifference(heading, 270)) > 1e-9) {
      continue;
    }
    const Eigen::Vector2d p = track.PointAt(s);
    const long key = std::lround(p.y() * 100);
    rows[key].push_back(heading);
    auto [it, inserted] = row_x.try_emplace(key, p.x(), p.x());
    it->second.first = std::min(it->second.first, p.x());
    it->second.second = std::max(it->second.second, p.x());
  }
  ASSERT_EQ(rows.size(), 5u);
  int index = 0;
  for (const auto& [key, headings] : rows) {
    // South to north, evenly spaced about the centre, alternate directions, first eastbound.
    EXPECT_NEAR(key / 100.0, centre.y() + (index - 2) * spacing, 0.01) << "row " << index;
    for (double heading : headings) EXPECT_NEAR(heading, index % 2 == 0 ? 90 : 270, 1e-9);
    // Straight for the row length less the heading smoothing at either end.
    // (The first and last rows start or end straight, the others turn at both ends.)
    const auto [x0, x1] = row_x[key];
    EXPECT_NEAR(0.5 * (x0 + x1), centre.x(), GroundTrack::kHeadingWindowM);
    EXPECT_GE(x1 - x0, 800 - 2 * GroundTrack::kHeadingWindowM - 2);
    EXPECT_LE(x1 - x0, 800);
    ++index;
  }
  // Rows joined by semicircles: 5 rows and 4 half turns of radius spacing / 2.
  EXPECT_NEAR(track.length_m(), 5 * 800 + 4 * M_PI * 0.5 * spacing, 1.0);

  // Frames over the middle of adjacent rows overlap by the sidelap (up to the jitter).
  const double row_time = (800 + M_PI * 0.5 * spacing) / 15;
  for (int row = 0; row + 1 < 5; ++row) {
    const double t = (400 + row * (800 + M_PI * 0.5 * spacing)) / 15;
    const double overlap = OverlapFraction(Footprint(*flight, t), Footprint(*flight, t + row_time));
    EXPECT_NEAR(overlap, 0.3, 0.03) << "rows " << row << " and " << row + 1;
  }
}

TEST(FlightTest, StraightFlightKeepsItsHeading) {
  FlightOptions options;
  options.straight_heading_deg = 30;
  options.straight_length_m = 600;
  const auto flight = MakeFlight(Scenario::kStraight, options);
  ASSERT_TRUE(flight.ok());
  const GroundTrack& track = flight->track();
  EXPECT_NEAR(track.length_m(), 600, 1e-9);
  EXPECT_TRUE(track.PointAt(300).isApprox(TownSite().centre));
  const Eigen::Vector2d direction = track.PointAt(600) - track.PointAt(0);
  EXPECT_NEAR(std::atan2(direction.x(), direction.y()) * 180 / M_PI, 30, 1e-9);
  for (double t = 0; t <= flight->duration_s(); t += 1.0) {
    EXPECT_NEAR(track.HeadingAt(t * 15), 30, 1e-9);
    EXPECT_NEAR(flight->PoseAt(t).heading_deg, 30, 1.5);  // up to 5 sigma of heading wander
  }
  const auto east = MakeFlight(Scenario::kStraight);  // default: eastbound, 1 km
  ASSERT_TRUE(east.ok());
  EXPECT_TRUE(east->track().PointAt(0).isApprox(TownSite().centre - Eigen::Vector2d(500, 0)));
  EXPECT_NEAR(east->track().HeadingAt(10), 90, 1e-9);
}

TEST(FlightTest, HeadingChangesLittleBetweenFrames) {
  for (Scenario scenario : AllScenarios()) {
    const auto flight = MakeFlight(scenario);
    ASSERT_TRUE(flight.ok()) << ScenarioName(scenario) << ": " << flight.status().ToString();
    double largest_step = 0;
    double previous = flight->PoseAt(0).heading_deg;
    const int frames = static_cast<int>(flight->duration_s() / kFrameInterval);
    for (int i = 1; i <= frames; ++i) {
      const double heading = flight->PoseAt(i * kFrameInterval).heading_deg;
      ASSERT_GE(heading, 0.0);
      ASSERT_LT(heading, 360.0);
      largest_step = std::max(largest_step, std::abs(HeadingDifference(heading, previous)));
      previous = heading;
    }
    // The road loop's right-angle corners are the sharpest: 90 degrees over 40 m at 0.5 m/frame.
    EXPECT_LT(largest_step, 1.5) << ScenarioName(scenario);
  }
}

TEST(FlightTest, PosesFollowTheTrackAtTheAltitudeWithSmallWander) {
  const auto flight = MakeFlight(Scenario::kFigureEight);
  ASSERT_TRUE(flight.ok());
  double sum_pitch2 = 0, sum_roll2 = 0, sum_altitude2 = 0, sum_pitch_step2 = 0;
  int n = 0;
  double previous_pitch = flight->PoseAt(0).pitch_deg;
  for (double t = 0; t <= flight->duration_s(); t += 0.25) {
    const CameraPose pose = flight->PoseAt(t);
    EXPECT_TRUE(pose.position_m.head<2>().isApprox(flight->track().PointAt(15 * t), 1e-12));
    sum_pitch2 += pose.pitch_deg * pose.pitch_deg;
    sum_roll2 += pose.roll_deg * pose.roll_deg;
    sum_altitude2 += (pose.position_m.z() - 400) * (pose.position_m.z() - 400);
    sum_pitch_step2 += (pose.pitch_deg - previous_pitch) * (pose.pitch_deg - previous_pitch);
    previous_pitch = pose.pitch_deg;
    ++n;
  }
  EXPECT_NEAR(std::sqrt(sum_pitch2 / n), 0.3, 0.12);
  EXPECT_NEAR(std::sqrt(sum_roll2 / n), 0.3, 0.12);
  EXPECT_NEAR(std::sqrt(sum_altitude2 / n), 2.0, 0.8);
  // Smooth: white noise of the same sigma would step sqrt(2) sigma between samples.
  EXPECT_LT(std::sqrt(sum_pitch_step2 / n), 0.5 * std::sqrt(sum_pitch2 / n));

  // t is clamped to the flight.
  const CameraPose before = flight->PoseAt(-3);
  const CameraPose start = flight->PoseAt(0);
  EXPECT_EQ(before.position_m, start.position_m);
  EXPECT_EQ(before.pitch_deg, start.pitch_deg);
  EXPECT_EQ(flight->PoseAt(1e6).position_m, flight->PoseAt(flight->duration_s()).position_m);

  FlightOptions calm;
  calm.attitude_jitter_deg = 0;
  calm.altitude_jitter_m = 0;
  const auto steady = MakeFlight(Scenario::kRaster, calm);
  ASSERT_TRUE(steady.ok());
  for (double t = 0; t < steady->duration_s(); t += 7.3) {
    const CameraPose pose = steady->PoseAt(t);
    EXPECT_EQ(pose.pitch_deg, 0.0);
    EXPECT_EQ(pose.roll_deg, 0.0);
    EXPECT_EQ(pose.position_m.z(), 400.0);
    EXPECT_NEAR(HeadingDifference(pose.heading_deg, steady->track().HeadingAt(15 * t)), 0, 1e-9);
  }
}

TEST(FlightTest, SameSeedSamePosesOtherSeedOtherJitter) {
  FlightOptions options;
  options.seed = 1234;
  const auto a = MakeFlight(Scenario::kRoundaboutLoop, options);
  const auto b = MakeFlight(Scenario::kRoundaboutLoop, options);
  options.seed = 1235;
  const auto c = MakeFlight(Scenario::kRoundaboutLoop, options);
  ASSERT_TRUE(a.ok() && b.ok() && c.ok());
  int differing = 0;
  for (double t = 0; t <= a->duration_s(); t += 0.5) {
    const CameraPose pa = a->PoseAt(t);
    const CameraPose pb = b->PoseAt(t);
    const CameraPose pc = c->PoseAt(t);
    ASSERT_EQ(pa.position_m, pb.position_m) << "t = " << t;
    ASSERT_EQ(pa.heading_deg, pb.heading_deg) << "t = " << t;
    ASSERT_EQ(pa.pitch_deg, pb.pitch_deg) << "t = " << t;
    ASSERT_EQ(pa.roll_deg, pb.roll_deg) << "t = " << t;
    EXPECT_EQ(pa.position_m.head<2>(), pc.position_m.head<2>());  // same track
    if (pa.pitch_deg != pc.pitch_deg && pa.roll_deg != pc.roll_deg &&
        pa.position_m.z() != pc.position_m.z()) {
      ++differing;
    }
  }
  EXPECT_GT(differing, 0.9 * a->duration_s() / 0.5);
}

}  // namespace
}  // namespace saker::sim
