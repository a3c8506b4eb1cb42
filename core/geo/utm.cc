#include "core/geo/utm.h"

#include <GeographicLib/TransverseMercator.hpp>
#include <GeographicLib/UTMUPS.hpp>

#include <cmath>
#include <exception>
#include <sstream>

namespace saker::geo {
namespace {

constexpr double kFalseEasting = 500e3;
constexpr double kFalseNorthingSouth = 10000e3;

}  // namespace

StatusOr<Utm> UtmFromWgs84(const Wgs84& point, std::optional<std::pair<int, bool>> zone_north) {
  const double lat = point.latitude_deg;
  const double lon = point.longitude_deg;
  if (!std::isfinite(lat) || !std::isfinite(lon) || lat > 84.0 || lat < -80.0 ||
      std::abs(lon) > 180.0) {
    std::ostringstream message;
    message << "UTM is defined from 80S to 84N and longitudes -180..180; got latitude " << lat
            << ", longitude " << lon;
    return InvalidArgumentError(message.str());
  }
  if (zone_north && (zone_north->first < 1 || zone_north->first > 60)) {
    return InvalidArgumentError("UTM zone must be 1..60, got " + std::to_string(zone_north->first));
  }
  try {
    Utm utm;
    utm.zone = zone_north ? zone_north->first : GeographicLib::UTMUPS::StandardZone(lat, lon);
    utm.north = zone_north ? zone_north->second : lat >= 0;
    // The zone's transverse Mercator directly (rather than UTMUPS::Forward) so that the
    // hemisphere can be forced as well as the zone.
    const double central_meridian = 6.0 * utm.zone - 183.0;
    double x = 0, y = 0;
    GeographicLib::TransverseMercator::UTM().Forward(central_meridian, lat, lon, x, y);
    utm.easting = x + kFalseEasting;
    utm.northing = y + (utm.north ? 0.0 : kFalseNorthingSouth);
    return utm;
  } catch (const std::exception& e) {
    return InvalidArgumentError(std::string("UTM projection failed: ") + e.what());
  }
}

int UtmEpsgCode(int zone, bool north) {
  SAKER_CHECK(zone >= 1 && zone <= 60) << "UTM zone " << zone;
  return (north ? 32600 : 32700) + zone;
}

}  // namespace saker::geo
