#pragma once

// Universal Transverse Mercator coordinates on WGS84, for the GeoTIFF export (docs/exports.md).
// A thin wrapper over GeographicLib (Krüger series, 5 nm within 3900 km of the central meridian);
// no projection maths is written here by hand.

#include "core/geo/local_tangent_plane.h"
#include "core/util/status.h"

#include <optional>
#include <utility>

namespace saker::geo {

// A position in one UTM zone: metres with the standard false easting (500 000 m) and, in the
// southern hemisphere, false northing (10 000 000 m).
struct Utm {
  int zone = 0;       // 1..60
  bool north = true;  // hemisphere of the northing's origin (decides the false northing)
  double easting = 0;
  double northing = 0;
};

// UTM of `point` (its height is ignored) in its standard zone, including the Norway and Svalbard
// exceptions, and the hemisphere of its latitude. `zone_north` = (zone, north) forces the zone and
// hemisphere instead, so that points near a zone edge or the equator share one grid (a point
// outside the forced zone gets an easting beyond the zone's usual range; a northern point in a
// southern grid a northing above 10 000 km). InvalidArgument for latitudes outside UTM's range
// (north of 84N or south of 80S, where UPS applies), longitudes outside [-180, 180], non-finite
// values, or a forced zone outside 1..60.
StatusOr<Utm> UtmFromWgs84(const Wgs84& point,
                           std::optional<std::pair<int, bool>> zone_north = std::nullopt);

// EPSG code of the WGS 84 / UTM zone: 32600 + zone (north) or 32700 + zone (south). `zone` must
// be 1..60 (checked).
int UtmEpsgCode(int zone, bool north);

}  // namespace saker::geo
