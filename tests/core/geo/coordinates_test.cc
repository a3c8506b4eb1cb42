// Positions as analysts read them and lengths and areas on the ellipsoid, against values worked
// out from the definitions (the UTM grid at the equator, degrees of arc on WGS84).

#include "core/geo/coordinates.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

namespace saker::geo {
namespace {

TEST(CoordinatesTest, DecimalAndDmsRoundOnceAndNameTheHemispheres) {
  const Wgs84 dover{51.15199, -1.747, 0};
  EXPECT_EQ(FormatPosition(dover, CoordinateFormat::kDecimalDegrees), "51.15199° N, 1.74700° W");
  EXPECT_EQ(FormatPosition(dover, CoordinateFormat::kDms), "51° 09′ 07.2″ N, 1° 44′ 49.2″ W");
  // 59.99 seconds rounds up into the next minute, and a minute into the next degree.
  const Wgs84 edge{-(10 + 59.0 / 60 + 59.99 / 3600), 179.99999, 0};
  EXPECT_EQ(FormatPosition(edge, CoordinateFormat::kDms), "11° 00′ 00.0″ S, 180° 00′ 00.0″ E");
  EXPECT_EQ(FormatPosition({0, 0, 0}, CoordinateFormat::kDecimalDegrees), "0.00000° N, 0.00000° E");
}

TEST(CoordinatesTest, UtmAndMgrsOnTheGrid) {
  // The equator at the prime meridian: zone 31 (central meridian 3° E), 333 978.557 m west of it.
  const Wgs84 origin{0, 0, 0};
  EXPECT_EQ(FormatPosition(origin, CoordinateFormat::kUtm), "31N 166021 E 0 N");
  EXPECT_EQ(FormatPosition(origin, CoordinateFormat::kMgrs), "31N AA 66021 00000");
  // South of the equator: the false northing, and the southern hemisphere named.
  const std::string south = FormatPosition({-33.9, 151.2, 0}, CoordinateFormat::kUtm);
  EXPECT_EQ(south.substr(0, 4), "56S ") << south;
  // Norway's wide zone 32V.
  EXPECT_EQ(FormatPosition({60.4, 5.3, 0}, CoordinateFormat::kMgrs).substr(0, 4), "32V ");
  // Beyond 84° N: the polar grid.
  EXPECT_EQ(FormatPosition({89, 10, 0}, CoordinateFormat::kUtm).substr(0, 10), "UPS north ");
  EXPECT_EQ(FormatPosition({89, 10, 0}, CoordinateFormat::kMgrs).substr(0, 2), "Z ");
}

TEST(CoordinatesTest, InvalidPositionsAreSaidSo) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (const CoordinateFormat f : {CoordinateFormat::kDecimalDegrees, CoordinateFormat::kDms,
                                   CoordinateFormat::kMgrs, CoordinateFormat::kUtm}) {
    EXPECT_EQ(FormatPosition({nan, 0, 0}, f), "invalid position");
    EXPECT_EQ(FormatPosition({91, 0, 0}, f), "invalid position");
    EXPECT_EQ(FormatPosition({0, 181, 0}, f), "invalid position");
    EXPECT_EQ(ParseCoordinateFormat(CoordinateFormatName(f)), f);
  }
  EXPECT_FALSE(ParseCoordinateFormat("degrees").has_value());
}

TEST(CoordinatesTest, GeodesicLengthsAndAreas) {
  // A degree of longitude on the equator is a / 180 * pi = 111 319.49 m.
  GeodesicMeasure m = MeasureGeodesic({{0, 0, 0}, {0, 1, 0}});
  EXPECT_NEAR(m.length_m, 111319.49, 0.01);
  EXPECT_EQ(m.area_m2, 0);
  // A one-degree square at the equator: 12 308 778 361 m² on WGS84 (its perimeter is two
  // degrees of equator-ish longitude and two of meridian, 110 574 m each).
  m = MeasureGeodesic({{0, 0, 0}, {0, 1, 0}, {1, 1, 0}, {1, 0, 0}});
  EXPECT_NEAR(m.area_m2, 1.2308778e10, 1e5);
  EXPECT_NEAR(m.length_m, 111319.49 + 110574.39 + 111302.65, 50);
  EXPECT_GT(m.perimeter_m, m.length_m);
  // The same square walked the other way round has the same (unsigned) area.
  EXPECT_NEAR(MeasureGeodesic({{1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, 0}}).area_m2, m.area_m2, 1);
  EXPECT_EQ(MeasureGeodesic({}).length_m, 0);
  EXPECT_EQ(MeasureGeodesic({{3, 4, 0}}).perimeter_m, 0);
}

TEST(CoordinatesTest, LengthsAndAreasAsText) {
  EXPECT_EQ(LengthText(7.25), "7.2 m");
  EXPECT_EQ(LengthText(850.4), "850 m");
  EXPECT_EQ(LengthText(12430), "12.43 km");
  EXPECT_EQ(LengthText(250e3), "250 km");
  EXPECT_EQ(AreaText(420), "420 m²");
  EXPECT_EQ(AreaText(35200), "3.52 ha");
  EXPECT_EQ(AreaText(12.6e6), "12.60 km²");
}

}  // namespace
}  // namespace saker::geo
