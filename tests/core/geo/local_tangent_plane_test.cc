#include "core/geo/local_tangent_plane.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

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

// A footprint 30 m across the antimeridian at 51.15 N (its corners 179.9998 E and 179.9998 W):
// its centre is on the antimeridian, not at 0 (the plain mean of the longitudes), and the map,
// the projection and its inverse go across it the short way round.
TEST(LocalTangentPlaneTest, AntimeridianFootprintsStayWhereTheyAre) {
  const std::vector<Wgs84> corners = {{51.1501, 179.9998, 0},
                                      {51.1501, -179.9998, 0},
                                      {51.1499, -179.9998, 0},
                                      {51.1499, 179.9998, 0}};
  const Wgs84 centre = CentreOf(corners);
  EXPECT_NEAR(centre.latitude_deg, 51.15, 1e-9);
  EXPECT_NEAR(std::abs(centre.longitude_deg), 180.0, 1e-9);
  EXPECT_LE(std::abs(centre.longitude_deg), 180.0);

  auto plane = LocalTangentPlane::Create(centre);
  ASSERT_TRUE(plane.ok()) << plane.status().ToString();
  for (const Wgs84& c : corners) {
    const Eigen::Vector2d map = plane->MapFromLatLon(c.latitude_deg, c.longitude_deg);
    EXPECT_LT(map.norm(), 20.0) << c.longitude_deg;  // about 14 m east or west, 11 m north or south
    const Wgs84 back = plane->LatLonFromMap(map);
    EXPECT_NEAR(back.latitude_deg, c.latitude_deg, 1e-9);
    EXPECT_NEAR(back.longitude_deg, c.longitude_deg, 1e-9);
  }
  // Either spelling of a meridian near 180 is the same place.
  EXPECT_NEAR(
      (plane->MapFromLatLon(51.15, 180.0001) - plane->MapFromLatLon(51.15, -179.9999)).norm(), 0.0,
      1e-6);
}

TEST(LocalTangentPlaneTest, LongitudesWrapAndUnwrap) {
  EXPECT_EQ(WrapLongitude(179.25), 179.25);  // in range: unchanged, bit for bit
  EXPECT_NEAR(WrapLongitude(180.5), -179.5, 1e-12);
  EXPECT_NEAR(WrapLongitude(-540.25), 179.75, 1e-12);
  EXPECT_EQ(UnwrapLongitude(-1.747, -1.8), -1.747);
  EXPECT_NEAR(UnwrapLongitude(-179.9, 179.9), 180.1, 1e-12);
  EXPECT_NEAR(UnwrapLongitude(179.9, -179.9), -180.1, 1e-12);
  // Away from the antimeridian the centre is the plain mean.
  const Wgs84 centre = CentreOf({{51.0, -1.5, 10}, {51.2, -1.7, 30}});
  EXPECT_NEAR(centre.latitude_deg, 51.1, 1e-12);
  EXPECT_NEAR(centre.longitude_deg, -1.6, 1e-12);
  EXPECT_NEAR(centre.height_m, 20.0, 1e-12);
}

// Near a pole the plane's north is not north a few km away: refused, saying why.
TEST(LocalTangentPlaneTest, RefusesOriginsNearThePoles) {
  EXPECT_TRUE(LocalTangentPlane::Create({kMaxMapLatitudeDeg, 10.0, 0.0}).ok());
  EXPECT_TRUE(LocalTangentPlane::Create({-kMaxMapLatitudeDeg, 10.0, 0.0}).ok());
  for (const double latitude : {89.5, -89.99, 90.0, -90.0}) {
    const Status status = LocalTangentPlane::Create({latitude, 10.0, 0.0}).status();
    ASSERT_FALSE(status.ok()) << latitude;
    EXPECT_EQ(status.code(), StatusCode::kInvalidArgument);
    EXPECT_NE(status.message().find("km from the pole"), std::string::npos) << status.message();
    EXPECT_NE(status.message().find("without its metadata"), std::string::npos) << status.message();
  }
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
