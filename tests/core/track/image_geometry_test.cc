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

}  // namespace
}  // namespace saker::track
