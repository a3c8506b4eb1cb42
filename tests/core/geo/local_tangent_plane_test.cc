#include "core/geo/local_tangent_plane.h"

#include <gtest/gtest.h>

#include <cmath>

namespace saker::geo {
namespace {

// Metres per degree at 38 N from the WGS84 radii of curvature (meridian M and
// prime vertical N), a cross-check independent of GeographicLib.
double MetresPerDegree(bool along_meridian, double latitude_deg) {
  constexpr double kA = 6378137.0;
  constexpr double kE2 = 6.69437999014e-3;
  const double phi = latitude_deg * M_PI / 180.0;
  const double w = 1.0 - kE2 * std::sin(phi) * std::sin(phi);
  const double radius =
      along_meridian ? kA * (1.0 - kE2) / std::pow(w, 1.5) : kA / std::sqrt(w) * std::cos(phi);
  return radius * M_PI / 180.0;
}

TEST(LocalTangentPlaneTest, OriginMapsToZero) {
  auto plane = LocalTangentPlane::Create({38.2455872, -77.3537377, 60.0});
  ASSERT_TRUE(plane.ok()) << plane.status().ToString();
  const Enu origin = plane->EnuFromWgs84(plane->origin());
  EXPECT_NEAR(origin.norm(), 0.0, 1e-9);
}

TEST(LocalTangentPlaneTest, EastAndNorthAxesAndScale) {
  auto plane = LocalTangentPlane::Create({38.0, -77.0, 0.0});
  ASSERT_TRUE(plane.ok());
  const Eigen::Vector2d north = plane->MapFromLatLon(38.001, -77.0);
  EXPECT_NEAR(north.x(), 0.0, 1e-6);
  EXPECT_NEAR(north.y(), 0.001 * MetresPerDegree(true, 38.0005), 0.01);
  const Eigen::Vector2d east = plane->MapFromLatLon(38.0, -76.999);
  EXPECT_GT(east.x(), 0.0);
  EXPECT_NEAR(east.x(), 0.001 * MetresPerDegree(false, 38.0), 0.01);
  EXPECT_NEAR(east.y(), 0.0, 1e-3);
}

TEST(LocalTangentPlaneTest, RoundTripsWithinMillimetres) {
  auto plane = LocalTangentPlane::Create({-10.5423886, 29.1578901, 3216.0});
  ASSERT_TRUE(plane.ok());
  for (double dlat : {-0.05, 0.0, 0.013}) {
    for (double dlon : {-0.05, 0.02}) {
      const Wgs84 point{-10.5423886 + dlat, 29.1578901 + dlon, 3216.0};
      const Eigen::Vector2d map = plane->MapFromLatLon(point.latitude_deg, point.longitude_deg);
      const Wgs84 back = plane->LatLonFromMap(map);
      EXPECT_NEAR(back.latitude_deg, point.latitude_deg, 1e-8);
      EXPECT_NEAR(back.longitude_deg, point.longitude_deg, 1e-8);
      EXPECT_NEAR(back.height_m, point.height_m, 1e-3);
      const Wgs84 full = plane->Wgs84FromEnu(
          plane->EnuFromWgs84({point.latitude_deg, point.longitude_deg, 500.0}));
      EXPECT_NEAR(full.height_m, 500.0, 1e-6);
    }
  }
}

TEST(LocalTangentPlaneTest, RejectsOriginsOffEarth) {
  EXPECT_FALSE(LocalTangentPlane::Create({91.0, 0.0, 0.0}).ok());
  EXPECT_FALSE(LocalTangentPlane::Create({0.0, 181.0, 0.0}).ok());
  EXPECT_FALSE(LocalTangentPlane::Create({NAN, 0.0, 0.0}).ok());
  EXPECT_FALSE(LocalTangentPlane::Create({0.0, 0.0, 1e9}).ok());
  auto status = LocalTangentPlane::Create({91.0, 0.0, 0.0}).status();
  EXPECT_NE(status.message().find("latitude 91"), std::string::npos) << status.message();
}

TEST(LocalTangentPlaneTest, CopiesAreIndependent) {
  auto plane = LocalTangentPlane::Create({10.0, 20.0, 0.0});
  ASSERT_TRUE(plane.ok());
  LocalTangentPlane copy = *plane;
  copy = *LocalTangentPlane::Create({11.0, 20.0, 0.0});
  EXPECT_NEAR(plane->MapFromLatLon(10.0, 20.0).norm(), 0.0, 1e-9);
  EXPECT_GT(copy.MapFromLatLon(10.0, 20.0).norm(), 100e3);
}

}  // namespace
}  // namespace saker::geo
