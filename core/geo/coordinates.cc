#include "core/geo/coordinates.h"

#include <GeographicLib/Geodesic.hpp>
#include <GeographicLib/MGRS.hpp>
#include <GeographicLib/PolygonArea.hpp>
#include <GeographicLib/UTMUPS.hpp>

#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <exception>

namespace saker::geo {
namespace {

bool Valid(const Wgs84& p) {
  return std::isfinite(p.latitude_deg) && std::isfinite(p.longitude_deg) &&
         std::abs(p.latitude_deg) <= 90 && std::abs(p.longitude_deg) <= 180;
}

std::string Decimal(double latitude, double longitude) {
  char text[64];
  std::snprintf(text, sizeof(text), "%.5f° %c, %.5f° %c", std::abs(latitude),
                latitude >= 0 ? 'N' : 'S', std::abs(longitude), longitude >= 0 ? 'E' : 'W');
  return text;
}

// Degrees, minutes and tenths of seconds, rounded once as a whole (no "60.0″").
std::string DmsOf(double degrees, char positive, char negative) {
  const auto tenths = static_cast<int64_t>(std::llround(std::abs(degrees) * 36000.0));
  const int64_t whole = tenths / 36000;
  const int64_t minutes = tenths / 600 % 60;
  const double seconds = static_cast<double>(tenths % 600) / 10.0;
  char text[48];
  std::snprintf(text, sizeof(text), "%lld° %02lld′ %04.1f″ %c", static_cast<long long>(whole),
                static_cast<long long>(minutes), seconds, degrees >= 0 ? positive : negative);
  return text;
}

// GeographicLib's MGRS ("30UXC1234567890") with the usual spaces: grid zone, 100 km square,
// easting, northing.
std::string SpacedMgrs(const std::string& mgrs) {
  size_t at = 0;
  while (at < mgrs.size() && std::isdigit(static_cast<unsigned char>(mgrs[at]))) ++at;
  const size_t zone_end = at + 1;  // the band letter (UPS: the single zone letter)
  const size_t square_end = zone_end + 2;
  if (square_end > mgrs.size()) return mgrs;
  const std::string digits = mgrs.substr(square_end);
  const size_t half = digits.size() / 2;
  return mgrs.substr(0, zone_end) + " " + mgrs.substr(zone_end, 2) + " " + digits.substr(0, half) +
         " " + digits.substr(half);
}

}  // namespace

const char* CoordinateFormatName(CoordinateFormat format) {
  switch (format) {
    case CoordinateFormat::kDecimalDegrees:
      return "decimal";
    case CoordinateFormat::kDms:
      return "dms";
    case CoordinateFormat::kMgrs:
      return "mgrs";
    case CoordinateFormat::kUtm:
      return "utm";
  }
  return "decimal";
}

std::optional<CoordinateFormat> ParseCoordinateFormat(std::string_view name) {
  for (const CoordinateFormat f : {CoordinateFormat::kDecimalDegrees, CoordinateFormat::kDms,
                                   CoordinateFormat::kMgrs, CoordinateFormat::kUtm}) {
    if (name == CoordinateFormatName(f)) return f;
  }
  return std::nullopt;
}

std::string FormatPosition(const Wgs84& point, CoordinateFormat format) {
  if (!Valid(point)) return "invalid position";
  const double lat = point.latitude_deg;
  const double lon = point.longitude_deg;
  switch (format) {
    case CoordinateFormat::kDecimalDegrees:
      return Decimal(lat, lon);
    case CoordinateFormat::kDms:
      return DmsOf(lat, 'N', 'S') + ", " + DmsOf(lon, 'E', 'W');
    case CoordinateFormat::kMgrs:
    case CoordinateFormat::kUtm:
      break;
  }
  try {
    int zone = 0;
    bool north = true;
    double x = 0, y = 0;
    GeographicLib::UTMUPS::Forward(lat, lon, zone, north, x, y);
    if (format == CoordinateFormat::kMgrs) {
      std::string mgrs;
      GeographicLib::MGRS::Forward(zone, north, x, y, lat, 5, mgrs);
      return SpacedMgrs(mgrs);
    }
    char text[96];
    if (zone == GeographicLib::UTMUPS::UPS) {
      std::snprintf(text, sizeof(text), "UPS %s %.0f E %.0f N", north ? "north" : "south", x, y);
    } else {
      std::snprintf(text, sizeof(text), "%d%c %.0f E %.0f N", zone, north ? 'N' : 'S', x, y);
    }
    return text;
  } catch (const std::exception&) {
    return "invalid position";
  }
}

GeodesicMeasure MeasureGeodesic(const std::vector<Wgs84>& path) {
  GeodesicMeasure measure;
  if (path.size() < 2) return measure;
  const GeographicLib::Geodesic& earth = GeographicLib::Geodesic::WGS84();
  for (size_t i = 1; i < path.size(); ++i) {
    double s12 = 0;
    earth.Inverse(path[i - 1].latitude_deg, path[i - 1].longitude_deg, path[i].latitude_deg,
                  path[i].longitude_deg, s12);
    measure.length_m += s12;
  }
  GeographicLib::PolygonArea polygon(earth);
  for (const Wgs84& p : path) polygon.AddPoint(p.latitude_deg, p.longitude_deg);
  double perimeter = 0, area = 0;
  // Signed (either way round), then its size: unsigned, GeographicLib gives a clockwise polygon
  // the rest of the Earth.
  polygon.Compute(/*reverse=*/false, /*sign=*/true, perimeter, area);
  measure.perimeter_m = perimeter;
  measure.area_m2 = path.size() >= 3 ? std::abs(area) : 0;
  return measure;
}

std::string LengthText(double metres) {
  char text[48];
  if (!std::isfinite(metres)) return "-";
  if (metres < 1000) {
    std::snprintf(text, sizeof(text), metres < 10 ? "%.1f m" : "%.0f m", metres);
  } else {
    std::snprintf(text, sizeof(text), metres < 100e3 ? "%.2f km" : "%.0f km", metres / 1000);
  }
  return text;
}

std::string AreaText(double square_metres) {
  char text[48];
  if (!std::isfinite(square_metres)) return "-";
  if (square_metres < 10e3) {
    std::snprintf(text, sizeof(text), "%.0f m²", square_metres);
  } else if (square_metres < 1e6) {
    std::snprintf(text, sizeof(text), "%.2f ha", square_metres / 1e4);
  } else {
    std::snprintf(text, sizeof(text), "%.2f km²", square_metres / 1e6);
  }
  return text;
}

}  // namespace saker::geo
