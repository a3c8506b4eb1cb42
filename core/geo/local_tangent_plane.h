#pragma once

// The mission map frame when the video carries metadata: a local tangent
// plane, east-north-up metres, around an origin on the WGS84 ellipsoid.
// A thin wrapper over GeographicLib::LocalCartesian; no geodesy is written
// here by hand.

#include "core/util/status.h"

#include <Eigen/Core>

#include <array>
#include <memory>
#include <vector>

namespace saker::geo {

// A WGS84 position: degrees and metres above the ellipsoid.
struct Wgs84 {
  double latitude_deg = 0;
  double longitude_deg = 0;
  double height_m = 0;
};

// `longitude_deg` in [-180, 180] (whole turns taken off); a value already in range is returned
// as it is, bit for bit.
double WrapLongitude(double longitude_deg);

// `longitude_deg` moved by a whole turn to within 180 degrees of `reference_deg`, so that
// differences from the reference are short across the antimeridian (179.9 against -179.9 is
// -180.1); a longitude already within 180 degrees is returned as it is, bit for bit. Averaging or
// differencing longitudes must go through it: the plain mean of 179.99 and -179.99 is 0.
double UnwrapLongitude(double longitude_deg, double reference_deg);

// The centre of a small group of positions (a footprint's corners): their mean with longitudes
// unwrapped around the first, wrapped back into [-180, 180]. Heights are averaged too.
// `points` must not be empty (checked).
Wgs84 CentreOf(const std::vector<Wgs84>& points);

// Largest |latitude| at which a local tangent plane serves as a mission's map frame. Nearer the
// pole (within 111 km of it) the plane's north (+y) turns away from true north across a few
// kilometres (by the longitude difference times sin(latitude)), a footprint's corners can spread
// over every longitude, and UTM (for the GeoTIFF) does not reach (84N, 80S). Such a mission must
// be processed without its metadata.
inline constexpr double kMaxMapLatitudeDeg = 89.0;

// East-north-up coordinates in metres around the plane's origin. Map points
// are (east, north); the mosaic works in that plane at the origin's height.
using Enu = Eigen::Vector3d;

class LocalTangentPlane {
 public:
  // Fails with InvalidArgument when the origin is not a finite position on
  // Earth (|latitude| > 90, |longitude| > 180, NaN, or |height| > 100 km), or
  // lies nearer a pole than kMaxMapLatitudeDeg, where the plane cannot serve.
  // Points far from the origin in longitude may be given either way round the
  // antimeridian (the projection goes through Earth-centred coordinates).
  static StatusOr<LocalTangentPlane> Create(const Wgs84& origin);

  LocalTangentPlane(const LocalTangentPlane& other);
  LocalTangentPlane& operator=(const LocalTangentPlane& other);
  LocalTangentPlane(LocalTangentPlane&&) noexcept;
  LocalTangentPlane& operator=(LocalTangentPlane&&) noexcept;
  ~LocalTangentPlane();

  const Wgs84& origin() const { return origin_; }

  Enu EnuFromWgs84(const Wgs84& point) const;
  Wgs84 Wgs84FromEnu(const Enu& point) const;

  // Map metres (east, north) of a ground point given as latitude/longitude,
  // taken at the origin's height (the flat-ground assumption of the
  // homography mosaic). Used for metadata corners.
  Eigen::Vector2d MapFromLatLon(double latitude_deg, double longitude_deg) const;
  // Inverse of MapFromLatLon: latitude/longitude of a map point on the plane
  // at the origin's height (used for cursor coordinates).
  Wgs84 LatLonFromMap(const Eigen::Vector2d& map_point) const;

 private:
  struct Impl;
  explicit LocalTangentPlane(const Wgs84& origin);

  Wgs84 origin_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace saker::geo
