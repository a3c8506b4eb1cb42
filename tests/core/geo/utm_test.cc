#include "core/geo/utm.h"

#include <gtest/gtest.h>

#include <cmath>

namespace saker::geo {
namespace {

constexpr double kK0 = 0.9996;  // UTM's scale on the central meridian

// WGS84 meridian arc length from the equator to `latitude_deg`, integrated numerically from the
// meridian radius of curvature: an independent check of the northing on a central meridian,
// where UTM's northing is k0 times this arc.
double MeridianArc(double latitude_deg) {
  constexpr double kA = 6378137.0;
  constexpr double kF = 1 / 298.257223563;
  constexpr double kE2 = kF * (2 - kF);
  const double phi_end = latitude_deg * M_PI / 180.0;
  const int n = 20000;  // Simpson's rule, even count
  const double h = phi_end / n;
  double sum = 0;
  for (int i = 0; i <= n; ++i) {
    const double s = std::sin(i * h);
    const double m = kA * (1 - kE2) / std::pow(1 - kE2 * s * s, 1.5);
    sum += m * (i == 0 || i == n ? 1 : (i % 2 == 1 ? 4 : 2));
  }
  return sum * h / 3;
}

TEST(UtmTest, EquatorOnCentralMeridianIsTheFalseOrigin) {
  auto utm = UtmFromWgs84({0.0, 3.0, 0.0});
  ASSERT_TRUE(utm.ok()) << utm.status().ToString();
  EXPECT_EQ(utm->zone, 31);
  EXPECT_TRUE(utm->north);
  EXPECT_NEAR(utm->easting, 500000.0, 1e-6);
  EXPECT_NEAR(utm->northing, 0.0, 1e-6);
}

TEST(UtmTest, PublishedGeoConvertExample) {
  // GeographicLib's GeoConvert manual: 33.3N 44.4E is "38N 444140.54 3684706.36".
  auto utm = UtmFromWgs84({33.3, 44.4, 0.0});
  ASSERT_TRUE(utm.ok());
  EXPECT_EQ(utm->zone, 38);
  EXPECT_TRUE(utm->north);
  EXPECT_NEAR(utm->easting, 444140.54, 0.006);
  EXPECT_NEAR(utm->northing, 3684706.36, 0.006);
}

TEST(UtmTest, CentralMeridianNorthingIsScaledMeridianArc) {
  auto north = UtmFromWgs84({51.5, -3.0, 0.0});  // zone 30 central meridian
  ASSERT_TRUE(north.ok());
  EXPECT_EQ(north->zone, 30);
  EXPECT_NEAR(north->easting, 500000.0, 1e-6);
  EXPECT_NEAR(north->northing, kK0 * MeridianArc(51.5), 0.001);

  // Southern hemisphere: false northing of 10 000 km.
  auto south = UtmFromWgs84({-33.5, 21.0, 0.0});  // zone 34 central meridian
  ASSERT_TRUE(south.ok());
  EXPECT_EQ(south->zone, 34);
  EXPECT_FALSE(south->north);
  EXPECT_NEAR(south->easting, 500000.0, 1e-6);
  EXPECT_NEAR(south->northing, 10000000.0 - kK0 * MeridianArc(33.5), 0.001);
}

TEST(UtmTest, EastingNearTheCentralMeridianScalesByK0) {
  // 0.01 degree east along the equator is an arc of a * 0.01 deg; UTM scales it by k0 (the
  // growth of scale away from the meridian is below 1e-8 at 1 km).
  auto utm = UtmFromWgs84({0.0, 3.01, 0.0});
  ASSERT_TRUE(utm.ok());
  EXPECT_NEAR(utm->easting - 500000.0, kK0 * 6378137.0 * 0.01 * M_PI / 180.0, 0.01);
  EXPECT_NEAR(utm->northing, 0.0, 1e-6);
}

TEST(UtmTest, StandardZoneFollowsTheNorwayException) {
  auto utm = UtmFromWgs84({60.0, 4.0, 0.0});  // zone 31 by longitude, 32V by the exception
  ASSERT_TRUE(utm.ok());
  EXPECT_EQ(utm->zone, 32);
}

TEST(UtmTest, ForcedZoneAndHemisphere) {
  // 6.5E is in zone 32; forced into zone 31 (central meridian 3E) it lies east of the centre.
  auto standard = UtmFromWgs84({45.0, 6.5, 0.0});
  auto forced = UtmFromWgs84({45.0, 6.5, 0.0}, std::make_pair(31, true));
  ASSERT_TRUE(standard.ok() && forced.ok());
  EXPECT_EQ(standard->zone, 32);
  EXPECT_EQ(forced->zone, 31);
  EXPECT_GT(forced->easting, 700000.0);
  EXPECT_LT(standard->easting, 500000.0);

  // A point just north of the equator in the southern grid: northing just above 10 000 km.
  auto south_grid = UtmFromWgs84({0.001, 3.0, 0.0}, std::make_pair(31, false));
  auto north_grid = UtmFromWgs84({0.001, 3.0, 0.0});
  ASSERT_TRUE(south_grid.ok() && north_grid.ok());
  EXPECT_FALSE(south_grid->north);
  EXPECT_NEAR(south_grid->northing - 10000000.0, north_grid->northing, 1e-6);
  EXPECT_GT(north_grid->northing, 100.0);
}

TEST(UtmTest, RejectsPointsOutsideUtm) {
  auto arctic = UtmFromWgs84({84.5, 10.0, 0.0});
  EXPECT_FALSE(arctic.ok());
  EXPECT_EQ(arctic.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(arctic.status().message().find("84.5"), std::string::npos) << arctic.status().message();
  EXPECT_FALSE(UtmFromWgs84({-80.5, 10.0, 0.0}).ok());
  EXPECT_FALSE(UtmFromWgs84({NAN, 10.0, 0.0}).ok());
  EXPECT_FALSE(UtmFromWgs84({10.0, 190.0, 0.0}).ok());
  EXPECT_FALSE(UtmFromWgs84({10.0, 10.0, 0.0}, std::make_pair(61, true)).ok());
  EXPECT_TRUE(UtmFromWgs84({84.0, 10.0, 0.0}).ok());
  EXPECT_TRUE(UtmFromWgs84({-80.0, 10.0, 0.0}).ok());
}

TEST(UtmTest, EpsgCodes) {
  EXPECT_EQ(UtmEpsgCode(30, true), 32630);
  EXPECT_EQ(UtmEpsgCode(34, false), 32734);
  EXPECT_EQ(UtmEpsgCode(1, true), 32601);
  EXPECT_THROW(UtmEpsgCode(0, true), CheckError);
}

}  // namespace
}  // namespace saker::geo
