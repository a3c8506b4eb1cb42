#include "core/track/image_geometry.h"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <gtest/gtest.h>

#include <cmath>

namespace saker::track {
namespace {

TEST(ImageCornersTest, MisbOrderOnTheOutermostPixelCentres) {
  const std::array<Eigen::Vector2d, 4> c = ImageCorners(640, 360);
  EXPECT_EQ(c[0], Eigen::Vector2d(0, 0));      // upper-left
  EXPECT_EQ(c[1], Eigen::Vector2d(639, 0));    // upper-right
  EXPECT_EQ(c[2], Eigen::Vector2d(639, 359));  // lower-right
  EXPECT_EQ(c[3], Eigen::Vector2d(0, 359));    // lower-left
}

TEST(HomographyFromCornersTest, FitsFourCornersWithTheirCovariance) {
  const auto image = ImageCorners(640, 360);
  const std::array<Eigen::Vector2d, 4> map = {Eigen::Vector2d(0, 0), Eigen::Vector2d(128, 2),
                                              Eigen::Vector2d(126, -70), Eigen::Vector2d(-1, -72)};
  StatusOr<HomographyWithCovariance> h = HomographyFromCorners(image, map, 2.0);
  ASSERT_TRUE(h.ok());
  for (int i = 0; i < 4; ++i) {
    EXPECT_LT((Transfer(h->target_from_source, image[static_cast<size_t>(i)]) -
               map[static_cast<size_t>(i)])
                  .norm(),
              1e-6);
    // Each corner is known to the stated sigma: 2 m per coordinate.
    const Eigen::Matrix2d cov =
        TransferCovariance(h->target_from_source, h->covariance, image[static_cast<size_t>(i)]);
    EXPECT_NEAR(cov(0, 0), 4.0, 1e-6);
    EXPECT_NEAR(cov(1, 1), 4.0, 1e-6);
  }
  const std::array<Eigen::Vector2d, 4> collinear = {Eigen::Vector2d(0, 0), Eigen::Vector2d(1, 1),
                                                    Eigen::Vector2d(2, 2), Eigen::Vector2d(3, 3)};
  EXPECT_FALSE(HomographyFromCorners(image, collinear, 1.0).ok());
}

TEST(ConfidenceEllipseTest, AxesAndAngle) {
  const double confidence = 1 - std::exp(-0.5);  // k = 1
  const Ellipse e =
      ConfidenceEllipse({5, 6}, Eigen::Vector2d(4, 1).asDiagonal().toDenseMatrix(), confidence);
  EXPECT_NEAR(e.semi_major, 2, 1e-12);
  EXPECT_NEAR(e.semi_minor, 1, 1e-12);
  EXPECT_NEAR(e.angle_rad, 0, 1e-12);
  EXPECT_EQ(e.centre, Eigen::Vector2d(5, 6));

  const double angle = 30 * M_PI / 180;
  const Eigen::Matrix2d r = Eigen::Rotation2Dd(angle).toRotationMatrix();
  const Eigen::Matrix2d cov = r * Eigen::Vector2d(9, 1).asDiagonal() * r.transpose();
  const Ellipse rotated = ConfidenceEllipse({0, 0}, cov, 0.95);
  const double k = std::sqrt(-2 * std::log(0.05));
  EXPECT_NEAR(rotated.semi_major, 3 * k, 1e-9);
  EXPECT_NEAR(rotated.semi_minor, k, 1e-9);
  EXPECT_NEAR(rotated.angle_rad, angle, 1e-9);
  const Ellipse other =
      ConfidenceEllipse({0, 0}, r.transpose() * Eigen::Vector2d(9, 1).asDiagonal() * r, 0.95);
  EXPECT_NEAR(other.angle_rad, -angle, 1e-9);

  const std::vector<Eigen::Vector2d> polygon = EllipsePolygon(rotated, 24);
  ASSERT_EQ(polygon.size(), 24u);
  for (const Eigen::Vector2d& p : polygon) {
    EXPECT_NEAR(p.transpose() * cov.inverse() * p, k * k, 1e-9);
  }
  EXPECT_NEAR(polygon[0].norm(), 3 * k, 1e-9);
}

TEST(GroundScaleTest, ANadirFootprintHasOneScaleEverywhere) {
  // 640 x 480 at 0.5 m a pixel, north up: 319.5 m by 239.5 m between the outermost centres.
  const std::array<Eigen::Vector2d, 4> ground = {
      Eigen::Vector2d(-159.75, 119.75), Eigen::Vector2d(159.75, 119.75),
      Eigen::Vector2d(159.75, -119.75), Eigen::Vector2d(-159.75, -119.75)};
  const std::optional<GroundScale> scale = GroundScale::FromCorners(ground, 640, 480);
  ASSERT_TRUE(scale.has_value());
  for (const Eigen::Vector2d& p : {Eigen::Vector2d(0, 0), Eigen::Vector2d(319.5, 239.5),
                                   Eigen::Vector2d(639, 479), Eigen::Vector2d(100, 400)}) {
    EXPECT_NEAR(scale->MetresPerPixel(p), 0.5, 0.5e-3) << p.transpose();
  }
}

TEST(GroundScaleTest, AnObliqueFootprintIsCoarserAtItsFarEdge) {
  // A trapezoid: the top of the image (far) 3 times as wide as its bottom (near), and the far
  // rows spread over more ground than the near ones.
  const std::array<Eigen::Vector2d, 4> ground = {Eigen::Vector2d(-300, 600),
                                                 Eigen::Vector2d(300, 600), Eigen::Vector2d(100, 0),
                                                 Eigen::Vector2d(-100, 0)};
  const std::optional<GroundScale> scale = GroundScale::FromCorners(ground, 400, 300);
  ASSERT_TRUE(scale.has_value());
  const double near = scale->MetresPerPixel({199.5, 299});
  const double far = scale->MetresPerPixel({199.5, 0});
  // Along the near edge a pixel spans 200 / 399 m across.
  EXPECT_GT(near, 0.5);
  EXPECT_GT(far, 3 * near);
  // The area of the footprint is the sum of its pixels' areas.
  double area = 0;
  for (int y = 0; y < 300; ++y) {
    for (int x = 0; x < 400; ++x) area += std::pow(scale->MetresPerPixel({x, y}), 2);
  }
  const double footprint = (600 + 200) / 2.0 * 600;  // the trapezoid between the centres
  EXPECT_NEAR(area / footprint, 400.0 * 300 / (399.0 * 299), 0.01);
}

TEST(GroundScaleTest, CornersThatMakeNoGroundAreRefused) {
  const std::array<Eigen::Vector2d, 4> square = {
      Eigen::Vector2d(-100, 100), Eigen::Vector2d(100, 100), Eigen::Vector2d(100, -100),
      Eigen::Vector2d(-100, -100)};
  std::array<Eigen::Vector2d, 4> crossed = square;
  std::swap(crossed[2], crossed[3]);
  EXPECT_FALSE(GroundScale::FromCorners(crossed, 200, 200).has_value());
  std::array<Eigen::Vector2d, 4> in_a_line = square;
  in_a_line[1] = Eigen::Vector2d(0, 0);
  in_a_line[2] = Eigen::Vector2d(100, -100);
  in_a_line[0] = Eigen::Vector2d(-100, 100);
  EXPECT_FALSE(GroundScale::FromCorners(in_a_line, 200, 200).has_value());
  std::array<Eigen::Vector2d, 4> not_finite = square;
  not_finite[2].x() = std::nan("");
  EXPECT_FALSE(GroundScale::FromCorners(not_finite, 200, 200).has_value());
  // Every corner at one point: no scale.
  const std::array<Eigen::Vector2d, 4> point = {Eigen::Vector2d(5, 7), Eigen::Vector2d(5, 7),
                                                Eigen::Vector2d(5, 7), Eigen::Vector2d(5, 7)};
  EXPECT_FALSE(GroundScale::FromCorners(point, 200, 200).has_value());
  EXPECT_FALSE(GroundScale::FromCorners(square, 1, 200).has_value());
  // Far from the map's origin, the same.
  std::array<Eigen::Vector2d, 4> far = square;
  for (Eigen::Vector2d& c : far) c += Eigen::Vector2d(-30000, 45000);
  const std::optional<GroundScale> scale = GroundScale::FromCorners(far, 201, 201);
  ASSERT_TRUE(scale.has_value());
  EXPECT_NEAR(scale->MetresPerPixel({100, 100}), 1.0, 1e-6);
}

}  // namespace
}  // namespace saker::track
