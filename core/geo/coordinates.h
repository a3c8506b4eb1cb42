#pragma once

// A position as an analyst reads it (decimal degrees, degrees-minutes-seconds, MGRS, UTM), and
// lengths and areas measured on the ellipsoid. A thin wrapper over GeographicLib (UTMUPS, MGRS,
// Geodesic, PolygonArea); no geodesy is written here by hand.

#include "core/geo/local_tangent_plane.h"

#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace saker::geo {

enum class CoordinateFormat {
  kDecimalDegrees,  // 51.15199° N, 1.74700° W (5 decimals: about a metre)
  kDms,             // 51° 09′ 07.2″ N, 1° 44′ 49.2″ W (tenths of a second: about 3 m)
  kMgrs,            // 30U XC 12345 67890 (1 m; UPS grid squares beyond 84N and 80S)
  kUtm,             // 30N 612345 E 5667890 N (zone and hemisphere, metres; UPS at the poles)
};

// "decimal", "dms", "mgrs", "utm"; and back (nullopt for any other text).
const char* CoordinateFormatName(CoordinateFormat format);
std::optional<CoordinateFormat> ParseCoordinateFormat(std::string_view name);

// `point` (its height ignored) as text in `format`. A latitude beyond +-90, a longitude beyond
// +-180 or a non-finite value gives "invalid position".
std::string FormatPosition(const Wgs84& point, CoordinateFormat format);

// A path measured on the WGS84 ellipsoid (geodesics between its points).
struct GeodesicMeasure {
  double length_m = 0;  // along the open path
  // Closed back to its first point: its perimeter and the area it encloses (unsigned; 0 with
  // fewer than three points).
  double perimeter_m = 0;
  double area_m2 = 0;
};
GeodesicMeasure MeasureGeodesic(const std::vector<Wgs84>& path);

// A length or an area as a person reads it: "850 m", "12.4 km"; "420 m²", "3.52 ha", "12.6 km²".
std::string LengthText(double metres);
std::string AreaText(double square_metres);

}  // namespace saker::geo
