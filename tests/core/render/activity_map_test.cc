#include "core/render/activity_map.h"

#include "core/activity/density.h"

#include <Eigen/Geometry>
#include <gtest/gtest.h>
#include <opencv2/core.hpp>

namespace saker::render {
namespace {

using activity::ColourMode;
using activity::TrackColouring;

// A straight east-bound track at map y = `y` from x = 20 to 220 over 10 s, seen on `visit`.
mission::ActivityTrack Track(int64_t id, double y, double speed, int visit, double start_s) {
  mission::ActivityTrack track;
  track.id = id;
  for (int k = 0; k <= 100; ++k) {
    mission::TrackPoint p;
    p.frame = k;
    p.time_s = start_s + 0.1 * k;
    p.map = {20 + 2.0 * k, y};
    track.points.push_back(p);
  }
  track.start_s = start_s;
  track.end_s = start_s + 10;
  track.speed = speed;
  track.speed_mps = speed;
  track.heading_deg = 90;
  track.visit = visit;
  return track;
}

// A geo-referenced mission whose pyramid is one level of 4 x 2 tiles of 64 px, 1 m per pixel,
// north up, with a slow track (north) and a fast one (south), on visits 1 and 2.
mission::Mission MakeMission() {
  mission::Mission m;
  m.map.geo_referenced = true;
  m.map.origin = geo::Wgs84{51.5, -1.2, 100};
  mission::PyramidInfo info;
  info.tile_size = 64;
  info.levels = 1;
  info.width = 256;
  info.height = 128;
  info.map_origin = {0, 127};
  info.step_x = 1;
  info.step_y = -1;
  m.pyramid = info;
  m.tracks = {Track(1, 100, 1.0, 1, 0), Track(2, 30, 10.0, 2, 20)};
  return m;
}

// Mid-grey opaque tiles.
StatusOr<cv::Mat> GreyTile(int, int, int) {
  return cv::Mat(64, 64, CV_8UC4, cv::Scalar(128, 128, 128, 255));
}

cv::Vec3b At(const ActivityMap& map, const Eigen::Vector2d& point) {
  const Eigen::Vector2d p = (map.image_from_map * point.homogeneous()).hnormalized();
  return map.bgr.at<cv::Vec3b>(static_cast<int>(std::lround(p.y())),
                               static_cast<int>(std::lround(p.x())));
}

void ExpectColour(const cv::Vec3b& pixel, const activity::Rgb& rgb) {
  EXPECT_NEAR(pixel[0], rgb.b, 12);
  EXPECT_NEAR(pixel[1], rgb.g, 12);
  EXPECT_NEAR(pixel[2], rgb.r, 12);
}

TEST(ActivityMap, TracksTakeTheirModesColourOverTheMosaic) {
  const mission::Mission m = MakeMission();
  ActivityMapOptions options;
  options.legend = false;
  options.line_width = 3;
  const auto speed = RenderActivityMap(m, GreyTile, options);
  ASSERT_TRUE(speed.ok()) << speed.status().ToString();
  EXPECT_EQ(speed->bgr.cols, 256);
  EXPECT_EQ(speed->bgr.rows, 128);
  EXPECT_EQ(speed->tracks, 2);
  // The mosaic where no track runs.
  EXPECT_EQ(At(*speed, {120, 64}), cv::Vec3b(128, 128, 128));
  // Slowest red, fastest blue.
  const TrackColouring by_speed(ColourMode::kSpeed, m.tracks, true);
  ExpectColour(At(*speed, {120, 100}), by_speed.ColourOf(m.tracks[0]));
  ExpectColour(At(*speed, {120, 30}), by_speed.ColourOf(m.tracks[1]));
  EXPECT_GT(At(*speed, {120, 100})[2], 200);  // red
  EXPECT_GT(At(*speed, {120, 30})[0], 200);   // blue

  // Visit: first red, second blue; switching the mode changes the colours.
  options.colour_by = ColourMode::kVisit;
  const auto visit = RenderActivityMap(m, GreyTile, options);
  ASSERT_TRUE(visit.ok());
  const TrackColouring by_visit(ColourMode::kVisit, m.tracks, true);
  ExpectColour(At(*visit, {120, 100}), by_visit.ColourOf(m.tracks[0]));
  ExpectColour(At(*visit, {120, 30}), by_visit.ColourOf(m.tracks[1]));

  // A time window keeps the tracks seen in it only.
  options.start_s = 15;
  const auto later = RenderActivityMap(m, GreyTile, options);
  ASSERT_TRUE(later.ok());
  EXPECT_EQ(later->tracks, 1);
  EXPECT_EQ(At(*later, {120, 100}), cv::Vec3b(128, 128, 128));
}

// The density mode: the heat of the observations blended over the mosaic, where the tracks ran
// and nowhere else, the tracks themselves not drawn; the time window applies.
TEST(ActivityMap, DensityIsAHeatMapOfTheObservations) {
  mission::Mission m = MakeMission();
  // Track 1 waits: five times as many observations along the same line.
  mission::ActivityTrack& slow = m.tracks[0];
  const std::vector<mission::TrackPoint> once = slow.points;
  for (int k = 0; k < 4; ++k) slow.points.insert(slow.points.end(), once.begin(), once.end());
  ActivityMapOptions options;
  options.legend = false;
  options.colour_by = ColourMode::kDensity;
  const auto heat = RenderActivityMap(m, GreyTile, options);
  ASSERT_TRUE(heat.ok()) << heat.status().ToString();
  EXPECT_EQ(heat->tracks, 2);
  EXPECT_EQ(At(*heat, {120, 64}), cv::Vec3b(128, 128, 128));  // no observation there
  // Sampled at the centres of the cells the tracks run through (between cells the picture is
  // interpolated).
  std::vector<const mission::ActivityTrack*> all;
  for (const mission::ActivityTrack& t : m.tracks) all.push_back(&t);
  const activity::DensityGrid grid = activity::CountObservations(all, true);
  const auto centre = [&](const Eigen::Vector2d& p) -> Eigen::Vector2d {
    const Eigen::Vector2d cell = ((p - grid.origin) / grid.cell).array().floor();
    return grid.origin + grid.cell * (cell.array() + 0.5).matrix();
  };
  const cv::Vec3b busy = At(*heat, centre({120, 100})), quiet = At(*heat, centre({120, 30}));
  for (const cv::Vec3b& pixel : {busy, quiet}) {
    EXPECT_GT(pixel[2], pixel[0] + 40) << "warm " << pixel;  // red over blue, on grey ground
  }
  EXPECT_LT(busy[1], quiet[1]) << "denser is darker red, less yellow";
  // No speed colours: the fast track is not drawn blue.
  EXPECT_LT(quiet[0], 128);
  options.start_s = 15;
  const auto later = RenderActivityMap(m, GreyTile, options);
  ASSERT_TRUE(later.ok());
  EXPECT_EQ(At(*later, {120, 100}), cv::Vec3b(128, 128, 128));
  const cv::Vec3b alone = At(*later, centre({120, 30}));  // the densest now: dark red
  EXPECT_GT(alone[2], alone[0] + 40);
  EXPECT_GT(alone[2], alone[1] + 40);
}

TEST(ActivityMap, OverlaysAndFallbacks) {
  mission::Mission m = MakeMission();
  ActivityMapOptions options;
  options.legend = false;
  const auto plain = RenderActivityMap(m, GreyTile, options);
  options.legend = true;
  const auto with_legend = RenderActivityMap(m, GreyTile, options);
  ASSERT_TRUE(plain.ok() && with_legend.ok());
  // The legend (top right), the north arrow (top left) and the scale bar (bottom left) change
  // those corners; geo-referencing off removes the arrow and the bar.
  const auto differs = [](const cv::Mat& a, const cv::Mat& b, cv::Rect r) {
    return cv::norm(a(r), b(r), cv::NORM_L1) > 0;
  };
  EXPECT_TRUE(differs(plain->bgr, with_legend->bgr, cv::Rect(180, 5, 70, 20)));
  const cv::Mat blank(128, 256, CV_8UC3, cv::Scalar(128, 128, 128));
  EXPECT_TRUE(differs(plain->bgr, blank, cv::Rect(5, 5, 20, 15)));    // north arrow
  EXPECT_TRUE(differs(plain->bgr, blank, cv::Rect(5, 108, 40, 15)));  // scale bar
  m.map.geo_referenced = false;
  m.map.origin.reset();
  options.legend = false;
  const auto local = RenderActivityMap(m, GreyTile, options);
  ASSERT_TRUE(local.ok());
  EXPECT_FALSE(differs(local->bgr, blank, cv::Rect(5, 5, 20, 15)));

  // A tile reader error is the render's error.
  const auto failed = RenderActivityMap(
      m, [](int, int, int) -> StatusOr<cv::Mat> { return IoError("tile store gone"); }, options);
  ASSERT_FALSE(failed.ok());
  EXPECT_NE(failed.status().message().find("tile store gone"), std::string::npos);

  // No pyramid: the tracks over their own extent; nothing at all: an error.
  m.pyramid.reset();
  const auto tracks_only = RenderActivityMap(m, GreyTile, options);
  ASSERT_TRUE(tracks_only.ok()) << tracks_only.status().ToString();
  EXPECT_EQ(tracks_only->tracks, 2);
  m.tracks.clear();
  const auto nothing = RenderActivityMap(m, GreyTile, options);
  ASSERT_FALSE(nothing.ok());
  EXPECT_EQ(nothing.status().code(), StatusCode::kInvalidData);
}

TEST(TrackColouring, LegendsMatchTheModes) {
  const std::vector<mission::ActivityTrack> tracks = {Track(1, 0, 2.0, 1, 0),
                                                      Track(2, 0, 6.0, 3, 50)};
  for (const ColourMode mode :
       {ColourMode::kSpeed, ColourMode::kDirection, ColourMode::kVisit, ColourMode::kTime}) {
    EXPECT_EQ(activity::ParseColourMode(activity::ColourModeName(mode)), mode);
  }
  EXPECT_FALSE(activity::ParseColourMode("colour").has_value());

  const TrackColouring speed(ColourMode::kSpeed, tracks, true);
  EXPECT_EQ(speed.legend().title, "Average speed (m/s)");
  EXPECT_TRUE(speed.legend().continuous);
  EXPECT_EQ(speed.legend().entries.front().label, "2.0");
  EXPECT_EQ(speed.legend().entries.back().label, "6.0");
  EXPECT_EQ(speed.ColourOf(tracks[0]), speed.legend().entries.front().colour);
  EXPECT_EQ(speed.ColourOf(tracks[1]), speed.legend().entries.back().colour);
  EXPECT_EQ(TrackColouring(ColourMode::kSpeed, tracks, false).legend().title,
            "Average speed (pixels/s)");

  const TrackColouring visit(ColourMode::kVisit, tracks, true);
  ASSERT_EQ(visit.legend().entries.size(), 3u);  // up to the largest visit seen
  EXPECT_EQ(visit.legend().entries[2].label, "3rd visit");
  EXPECT_EQ(visit.ColourOf(tracks[1]), visit.legend().entries[2].colour);

  const TrackColouring time(ColourMode::kTime, tracks, true);
  EXPECT_EQ(time.legend().entries.front().label, "0:00");
  EXPECT_EQ(time.legend().entries.back().label, "1:00");

  const TrackColouring direction(ColourMode::kDirection, tracks, true);
  EXPECT_EQ(direction.legend().entries.front().label, "N");
  EXPECT_EQ(direction.RampColour(0), direction.RampColour(1));  // a wheel
}

}  // namespace
}  // namespace saker::render
