#include "core/mosaic/loop_closure.h"

#include "core/sim/world.h"
#include "core/sim/world_raster.h"
#include "core/track/homography.h"
#include "core/track/image_geometry.h"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/core/eigen.hpp>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <memory>
#include <set>

namespace saker::mosaic {
namespace {

// Full-resolution key frames of 1280 x 720 pixels, kept as 640 x 360 grey copies (scale 2), as
// the front end keeps them.
constexpr int kWidth = 1280;
constexpr int kHeight = 720;
constexpr double kScale = 2.0;
constexpr double kGsd = 0.25;  // metres per raster pixel (and per full-resolution pixel)

// The simulator's procedural town. The tests' "raster" is its ground raster (kGsd) shifted so
// that raster pixel (0, 0) is 400 m west and 300 m north of the town centre; tests use 800 m x
// 600 m (3200 x 2400 pixels) from there. Tiles are rendered on demand and cached.
struct Town {
  std::unique_ptr<sim::ProceduralGround> ground;
  cv::Point origin;  // ground raster pixel of the tests' raster pixel (0, 0)
};

const Town& TheTown() {
  static const Town* town = [] {
    StatusOr<sim::World> world = sim::GenerateWorld({}, cv::Rect2d(-1500, -1000, 3000, 2000));
    SAKER_CHECK(world.ok()) << world.status().ToString();
    auto shared = std::make_shared<const sim::World>(std::move(world).value());
    auto* t = new Town;
    t->origin = cv::Point(static_cast<int>(shared->town_centre.x() / kGsd) - 1600,
                          static_cast<int>(-shared->town_centre.y() / kGsd) - 1200);
    t->ground = std::make_unique<sim::ProceduralGround>(shared, kGsd);
    return t;
  }();
  return *town;
}

// raster_from_view of a view of `width` x `height` centred on raster pixel `centre` (relative to
// the rendered raster), rotated by `angle_deg` (view x axis anticlockwise on screen... any sense,
// the tests only need it known).
Eigen::Matrix3d RasterFromView(const Eigen::Vector2d& centre, double angle_deg, int width,
                               int height, double raster_px_per_view_px = 1.0) {
  const double a = angle_deg * M_PI / 180;
  Eigen::Matrix3d r = Eigen::Matrix3d::Identity();
  r.topLeftCorner<2, 2>() << std::cos(a), -std::sin(a), std::sin(a), std::cos(a);
  r.topLeftCorner<2, 2>() *= raster_px_per_view_px;
  Eigen::Matrix3d to_centre = Eigen::Matrix3d::Identity();
  to_centre.topRightCorner<2, 1>() = -Eigen::Vector2d(0.5 * (width - 1), 0.5 * (height - 1));
  Eigen::Matrix3d from_centre = Eigen::Matrix3d::Identity();
  from_centre.topRightCorner<2, 1>() = centre;
  return from_centre * r * to_centre;
}

Eigen::Matrix3d Translation(double x, double y) {
  Eigen::Matrix3d t = Eigen::Matrix3d::Identity();
  t(0, 2) = x;
  t(1, 2) = y;
  return t;
}

struct View {
  cv::Mat full;  // grey, full resolution
  cv::Mat grey;  // downscaled copy
  double scale = 1;
  std::vector<track::StationaryPoint> points;
  Eigen::Matrix3d raster_from_view;
};

// Renders a view, adds sensor noise, detects Harris corners on the full-resolution image.
View MakeView(const Eigen::Vector2d& centre, double angle_deg, int width, int height, double scale,
              int64_t first_id, uint64_t noise_seed, double raster_px_per_view_px = 1.0) {
  View v;
  v.raster_from_view = RasterFromView(centre, angle_deg, width, height, raster_px_per_view_px);
  // Render the raster under the view's bounding box (and a margin for the interpolation).
  double x0 = 1e9, y0 = 1e9, x1 = -1e9, y1 = -1e9;
  for (const Eigen::Vector2d& c : track::ImageCorners(width, height)) {
    const Eigen::Vector2d r = track::Transfer(v.raster_from_view, c);
    x0 = std::min(x0, r.x()), y0 = std::min(y0, r.y()), x1 = std::max(x1, r.x());
    y1 = std::max(y1, r.y());
  }
  const cv::Rect box(static_cast<int>(std::floor(x0)) - 2, static_cast<int>(std::floor(y0)) - 2,
                     static_cast<int>(x1 - x0) + 6, static_cast<int>(y1 - y0) + 6);
  const Town& town = TheTown();
  cv::Mat bgr, valid, raster;
  town.ground->Render(box + town.origin, &bgr, &valid);
  cv::cvtColor(bgr, raster, cv::COLOR_BGR2GRAY);
  const Eigen::Matrix3d view_from_box = v.raster_from_view.inverse() * Translation(box.x, box.y);
  cv::Mat m;
  cv::eigen2cv(view_from_box, m);
  cv::warpPerspective(raster, v.full, m, cv::Size(width, height), cv::INTER_LINEAR,
                      cv::BORDER_CONSTANT, cv::Scalar(0));
  cv::Mat noise(v.full.size(), CV_16S);
  cv::RNG rng(noise_seed);
  rng.fill(noise, cv::RNG::NORMAL, 0, 2.0);
  cv::Mat noisy;
  v.full.convertTo(noisy, CV_16S);
  noisy += noise;
  noisy.convertTo(v.full, CV_8U);
  v.scale = scale;
  if (scale != 1) {
    cv::resize(v.full, v.grey, cv::Size(), 1 / scale, 1 / scale, cv::INTER_AREA);
  } else {
    v.grey = v.full;
  }
  std::vector<cv::Point2f> corners;
  cv::goodFeaturesToTrack(v.full, corners, 1500, 0.001, 5, cv::noArray(), 3, true, 0.04);
  for (size_t i = 0; i < corners.size(); ++i) {
    v.points.emplace_back(static_cast<track::FeatureTrackId>(first_id + static_cast<int64_t>(i)),
                          Eigen::Vector2d(corners[i].x, corners[i].y));
  }
  return v;
}

KeyFrameFeatures Describe(KeyFrameId id, const View& v) {
  return DescribeKeyFrame(id, v.grey, v.scale, v.points, DescribeOptions{});
}

// Largest distance between the corners mapped by two homographies.
double CornerError(const Eigen::Matrix3d& estimate, const Eigen::Matrix3d& truth, int width,
                   int height) {
  double worst = 0;
  for (const Eigen::Vector2d& c : track::ImageCorners(width, height)) {
    worst = std::max(worst, (track::Transfer(estimate, c) - track::Transfer(truth, c)).norm());
  }
  return worst;
}

// Two views of the town: b is a turned by 90 degrees, 5 % closer and shifted; about half of a is
// in b.
struct Pair {
  View a, b;
  Eigen::Matrix3d b_from_a;
};

const Pair& RotatedPair() {
  static const Pair* pair = [] {
    auto* p = new Pair;
    const Eigen::Vector2d centre(1600, 1200);
    p->a = MakeView(centre, 0, kWidth, kHeight, kScale, 0, 1);
    p->b =
        MakeView(centre + Eigen::Vector2d(150, 100), 90, kWidth, kHeight, kScale, 100000, 2, 0.95);
    p->b_from_a = p->b.raster_from_view.inverse() * p->a.raster_from_view;
    p->b_from_a /= p->b_from_a(2, 2);
    return p;
  }();
  return *pair;
}

TEST(DescribeKeyFrameTest, EmptyInputsGiveEmptyFeatures) {
  const std::vector<track::StationaryPoint> some = {
      {static_cast<track::FeatureTrackId>(1), {100, 100}}};
  const KeyFrameFeatures no_image =
      DescribeKeyFrame(static_cast<KeyFrameId>(3), cv::Mat(), 2.0, some, {});
  EXPECT_EQ(no_image.id, KeyFrameId(3));
  EXPECT_TRUE(no_image.empty());
  EXPECT_EQ(no_image.descriptors.rows, 0);
  const KeyFrameFeatures no_points = DescribeKeyFrame(
      static_cast<KeyFrameId>(4), cv::Mat(360, 640, CV_8UC1, cv::Scalar(90)), 2.0, {}, {});
  EXPECT_TRUE(no_points.empty());
  EXPECT_EQ(no_points.descriptors.rows, 0);
  // A flat image: descriptors exist (all alike) but nothing crashes.
  const KeyFrameFeatures flat = DescribeKeyFrame(
      static_cast<KeyFrameId>(5), cv::Mat(360, 640, CV_8UC1, cv::Scalar(90)), 2.0, some, {});
  EXPECT_EQ(flat.descriptors.rows, static_cast<int>(flat.points.size()));
}

TEST(DescribeKeyFrameTest, OneRowPerPointBorderPointsDroppedAndCapRespected) {
  const View& v = RotatedPair().a;
  ASSERT_GT(v.points.size(), 1000u);
  std::vector<track::StationaryPoint> points = v.points;
  points.emplace_back(static_cast<track::FeatureTrackId>(-1),
                      Eigen::Vector2d(3, 3));  // at the border
  DescribeOptions options;
  options.max_features = 100000;
  const KeyFrameFeatures all =
      DescribeKeyFrame(static_cast<KeyFrameId>(0), v.grey, v.scale, points, options);
  EXPECT_EQ(all.descriptors.rows, static_cast<int>(all.points.size()));
  EXPECT_EQ(all.track_ids.size(), all.points.size());
  EXPECT_EQ(all.descriptors.type(), CV_32F);
  EXPECT_EQ(all.descriptors.cols, 128);
  EXPECT_GT(all.points.size(), points.size() * 3 / 4);
  EXPECT_LT(all.points.size(), points.size());
  const double margin = 3 * options.keypoint_size_px * v.scale;
  for (size_t i = 0; i < all.points.size(); ++i) {
    EXPECT_NE(all.track_ids[i], track::FeatureTrackId(-1));
    EXPECT_GE(all.points[i].x(), margin - v.scale);
    EXPECT_LE(all.points[i].x(), kWidth - margin + v.scale);
  }
  // Points keep their ids.
  std::map<int64_t, Eigen::Vector2d> by_id;
  for (const auto& [id, p] : points) by_id[static_cast<int64_t>(id)] = p;
  for (size_t i = 0; i < all.points.size(); ++i) {
    EXPECT_EQ(by_id.at(static_cast<int64_t>(all.track_ids[i])), all.points[i]);
  }
  options.max_features = 300;
  const KeyFrameFeatures capped =
      DescribeKeyFrame(static_cast<KeyFrameId>(0), v.grey, v.scale, points, options);
  EXPECT_EQ(capped.points.size(), 300u);
  EXPECT_EQ(capped.descriptors.rows, 300);
  // Spread over the image, not bunched: every quarter keeps some.
  int quarters[4] = {0, 0, 0, 0};
  for (const Eigen::Vector2d& p : capped.points) {
    ++quarters[(p.x() > kWidth / 2 ? 1 : 0) + (p.y() > kHeight / 2 ? 2 : 0)];
  }
  for (int q : quarters) EXPECT_GT(q, 40);
}

TEST(MatchAppearanceTest, RecoversA90DegreeTurn) {
  const Pair& p = RotatedPair();
  const KeyFrameFeatures a = Describe(static_cast<KeyFrameId>(0), p.a),
                         b = Describe(static_cast<KeyFrameId>(7), p.b);
  const std::optional<Link> link = MatchAppearance(a, b, kWidth, kHeight, MatchOptions{});
  ASSERT_TRUE(link.has_value());
  EXPECT_EQ(link->from, KeyFrameId(0));
  EXPECT_EQ(link->to, KeyFrameId(7));
  EXPECT_EQ(link->kind, LinkKind::kAppearance);
  EXPECT_GE(static_cast<int>(link->correspondences.size()), MatchOptions{}.min_inliers);
  const double error = CornerError(link->to_from_from, p.b_from_a, kWidth, kHeight);
  std::cout << "appearance: " << link->correspondences.size() << " inliers of " << a.size() << " / "
            << b.size() << " features, corner error " << error << " px\n";
  EXPECT_LT(error, 1.0);
  EXPECT_GT(link->covariance.trace(), 0);
}

TEST(MatchAppearanceTest, UnrelatedViewsGiveNothing) {
  const Pair& p = RotatedPair();
  const View elsewhere =
      MakeView(Eigen::Vector2d(600, 700), 30, kWidth, kHeight, kScale, 200000, 3);
  const KeyFrameFeatures a = Describe(static_cast<KeyFrameId>(0), p.a);
  const KeyFrameFeatures c = Describe(static_cast<KeyFrameId>(1), elsewhere);
  EXPECT_FALSE(MatchAppearance(a, c, kWidth, kHeight, MatchOptions{}).has_value());
}

TEST(MatchGeometricTest, RecoversFromAPredictionOffBy15Px) {
  const Pair& p = RotatedPair();
  const KeyFrameFeatures a = Describe(static_cast<KeyFrameId>(0), p.a),
                         b = Describe(static_cast<KeyFrameId>(1), p.b);
  const Eigen::Matrix3d predicted = Translation(12, -9) * p.b_from_a;
  const auto covariance = [](const Eigen::Vector2d&) {
    return Eigen::Matrix2d(Eigen::Matrix2d::Identity() * 8.0 * 8.0);
  };
  const std::optional<Link> link =
      MatchGeometric(a, b, predicted, covariance, kWidth, kHeight, MatchOptions{});
  ASSERT_TRUE(link.has_value());
  EXPECT_EQ(link->kind, LinkKind::kGeometric);
  EXPECT_EQ(link->from, KeyFrameId(0));
  EXPECT_EQ(link->to, KeyFrameId(1));
  const double error = CornerError(link->to_from_from, p.b_from_a, kWidth, kHeight);
  std::cout << "geometric: " << link->correspondences.size() << " inliers, corner error " << error
            << " px\n";
  EXPECT_LT(error, 1.0);
  for (const track::Correspondence& c : link->correspondences) {
    EXPECT_LT((track::Transfer(p.b_from_a, c.source) - c.target).norm(), 4.0);
  }
}

TEST(MatchGeometricTest, EllipsesThatExcludeTheTruthFindNothing) {
  const Pair& p = RotatedPair();
  const KeyFrameFeatures a = Describe(static_cast<KeyFrameId>(0), p.a),
                         b = Describe(static_cast<KeyFrameId>(1), p.b);
  const Eigen::Matrix3d predicted = Translation(160, 120) * p.b_from_a;  // 200 px off
  const auto tight = [](const Eigen::Vector2d&) {
    return Eigen::Matrix2d(Eigen::Matrix2d::Identity() * 5.0 * 5.0);
  };
  EXPECT_FALSE(MatchGeometric(a, b, predicted, tight, kWidth, kHeight, MatchOptions{}));
  // The same prediction with ellipses wide enough to hold the truth does find it.
  const auto wide = [](const Eigen::Vector2d&) {
    return Eigen::Matrix2d(Eigen::Matrix2d::Identity() * 100.0 * 100.0);
  };
  const std::optional<Link> link =
      MatchGeometric(a, b, predicted, wide, kWidth, kHeight, MatchOptions{});
  ASSERT_TRUE(link.has_value());
  EXPECT_LT(CornerError(link->to_from_from, p.b_from_a, kWidth, kHeight), 1.0);
}

TEST(PlausibleHomographyTest, RejectsInsaneAcceptsTrue) {
  const MatchOptions options;
  const Eigen::Matrix3d truth = RotatedPair().b_from_a;
  EXPECT_TRUE(PlausibleHomography(truth, kWidth, kHeight, options));
  EXPECT_TRUE(PlausibleHomography(Eigen::Matrix3d::Identity(), kWidth, kHeight, options));
  EXPECT_TRUE(PlausibleHomography(-truth, kWidth, kHeight, options));  // same map
  // Mirror: x -> width - 1 - x, then the true map (still overlapping).
  Eigen::Matrix3d mirror = Eigen::Matrix3d::Identity();
  mirror(0, 0) = -1;
  mirror(0, 2) = kWidth - 1;
  EXPECT_FALSE(PlausibleHomography(truth * mirror, kWidth, kHeight, options));
  // 5x zoom about the centre.
  const Eigen::Vector2d c(0.5 * (kWidth - 1), 0.5 * (kHeight - 1));
  const Eigen::Matrix3d zoom = Translation(c.x(), c.y()) * Eigen::Vector3d(5, 5, 1).asDiagonal() *
                               Translation(-c.x(), -c.y());
  EXPECT_FALSE(PlausibleHomography(zoom, kWidth, kHeight, options));
  const Eigen::Matrix3d mild_zoom = Translation(c.x(), c.y()) *
                                    Eigen::Vector3d(1.3, 1.3, 1).asDiagonal() *
                                    Translation(-c.x(), -c.y());
  EXPECT_TRUE(PlausibleHomography(mild_zoom, kWidth, kHeight, options));
  // Strong perspective: w goes from 1 to 3.6 across the image.
  Eigen::Matrix3d perspective = Eigen::Matrix3d::Identity();
  perspective(2, 0) = 0.002;
  EXPECT_FALSE(PlausibleHomography(perspective, kWidth, kHeight, options));
  perspective(2, 0) = 0.0001;  // w within 1 .. 1.13
  EXPECT_TRUE(PlausibleHomography(perspective, kWidth, kHeight, options));
  // A shear: anisotropy about 2.6.
  Eigen::Matrix3d shear = Eigen::Matrix3d::Identity();
  shear(0, 1) = 1.0;
  EXPECT_FALSE(PlausibleHomography(shear, kWidth, kHeight, options));
  // No overlap, and too little.
  EXPECT_FALSE(PlausibleHomography(Translation(2 * kWidth, 0) * truth, kWidth, kHeight, options));
  EXPECT_FALSE(PlausibleHomography(Translation(0.95 * kWidth, 0), kWidth, kHeight, options));
  EXPECT_TRUE(PlausibleHomography(Translation(0.8 * kWidth, 0), kWidth, kHeight, options));
  // Not finite, singular.
  Eigen::Matrix3d bad = truth;
  bad(0, 1) = std::nan("");
  EXPECT_FALSE(PlausibleHomography(bad, kWidth, kHeight, options));
  EXPECT_FALSE(PlausibleHomography(Eigen::Matrix3d::Zero(), kWidth, kHeight, options));
}

// Key frames of 640 x 360 (scale 1) at up to 25 places of the town on a grid, none overlapping;
// key frame k is place k.
std::vector<KeyFrameFeatures> Places(int count) {
  std::vector<KeyFrameFeatures> places;
  for (int k = 0; k < count && k < 25; ++k) {
    const int row = k / 5, col = k % 5;
    const View v = MakeView(Eigen::Vector2d(320 + 640 * col, 240 + 480 * row), 0, 640, 360, 1.0,
                            1000000 * (k + 1), 10 + static_cast<uint64_t>(k));
    places.push_back(Describe(static_cast<KeyFrameId>(k), v));
  }
  return places;
}

TEST(AppearanceIndexTest, TheOverlappingFrameRanksFirst) {
  const std::vector<KeyFrameFeatures> places = Places(25);
  AppearanceIndex index({});
  for (const KeyFrameFeatures& f : places) index.Add(f);
  ASSERT_TRUE(index.trained());
  EXPECT_EQ(index.size(), places.size());
  // The query looks at place 12 (row 2, column 2) turned by 90 degrees, half of it overlapping.
  const View query_view = MakeView(Eigen::Vector2d(320 + 640 * 2 + 100, 240 + 480 * 2), 90, 640,
                                   360, 1.0, 90000000, 99);
  const KeyFrameFeatures query = Describe(static_cast<KeyFrameId>(100), query_view);
  const auto best = index.Query(query, 5);
  ASSERT_EQ(best.size(), 5u);
  std::cout << "index: best " << static_cast<int>(best[0].first) << " (" << best[0].second
            << "), next " << static_cast<int>(best[1].first) << " (" << best[1].second << ")\n";
  EXPECT_EQ(best[0].first, KeyFrameId(12));
  for (size_t i = 1; i < best.size(); ++i) EXPECT_GE(best[i - 1].second, best[i].second);
  // skip() removes it; the query's own id is never returned.
  const auto without =
      index.Query(query, 3, [](KeyFrameId id) { return id == static_cast<KeyFrameId>(12); });
  for (const auto& [id, score] : without) EXPECT_NE(id, KeyFrameId(12));
  const auto self = index.Query(places[4], 3);
  for (const auto& [id, score] : self) EXPECT_NE(id, KeyFrameId(4));
}

TEST(AppearanceIndexTest, BeforeTrainingNewestFirstAndTrainingIsDeterministic) {
  const std::vector<KeyFrameFeatures> places = Places(10);
  AppearanceIndexOptions options;
  options.training_key_frames = 4;
  AppearanceIndex index(options), again(options);
  for (int i = 0; i < 3; ++i) {
    index.Add(places[i]);
    again.Add(places[i]);
  }
  EXPECT_FALSE(index.trained());
  const auto before = index.Query(places[9], 10);
  ASSERT_EQ(before.size(), 3u);
  EXPECT_EQ(before[0].first, KeyFrameId(2));
  EXPECT_EQ(before[2].first, KeyFrameId(0));
  for (int i = 3; i < 10; ++i) {
    index.Add(places[i]);
    again.Add(places[i]);
  }
  EXPECT_TRUE(index.trained());
  const auto first = index.Query(places[9], 10), second = again.Query(places[9], 10);
  ASSERT_EQ(first.size(), second.size());
  EXPECT_EQ(first.size(), 9u);  // all but itself share words with it
  for (size_t i = 0; i < first.size(); ++i) {
    EXPECT_EQ(first[i].first, second[i].first);
    EXPECT_EQ(first[i].second, second[i].second);
  }
  // An empty query touches no posting list and finds nothing.
  KeyFrameFeatures empty;
  empty.id = static_cast<KeyFrameId>(50);
  EXPECT_TRUE(index.Query(empty, 5).empty());
}

TEST(LoopClosureOptionsTest, ValidateNamesTheField) {
  MatchOptions m;
  EXPECT_TRUE(m.Validate().ok());
  m.min_inliers = 3;
  EXPECT_NE(m.Validate().message().find("min_inliers"), std::string::npos);
  DescribeOptions d;
  EXPECT_TRUE(d.Validate().ok());
  d.keypoint_size_px = 0;
  EXPECT_NE(d.Validate().message().find("keypoint_size_px"), std::string::npos);
  AppearanceIndexOptions i;
  EXPECT_TRUE(i.Validate().ok());
  i.words = 1;
  EXPECT_NE(i.Validate().message().find("words"), std::string::npos);
}

}  // namespace
}  // namespace saker::mosaic
