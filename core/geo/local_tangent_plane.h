#pragma once

// The mission map frame when the video carries metadata: a local tangent
// plane, east-north-up metres, around an origin on the WGS84 ellipsoid.
// A thin wrapper over GeographicLib::LocalCartesian; no geodesy is written
// here by hand.

#include "core/util/status.h"

#include <Eigen/Core>

#include <array>
#include <memory>

namespace saker::geo {

// A WGS84 position: degrees and metres above the ellipsoid.
struct Wgs84 {
  double latitude_deg = 0;
  double longitude_deg = 0;
  double height_m = 0;
};

// East-north-up coordinates in metres around the plane's origin. Map points
// are (east, north); the mosaic works in that plane at the origin's height.
using Enu = Eigen::Vector3d;

class LocalTangentPlane {
 public:
  // Fails with InvalidArgument when the origin is not a finite position on
  // Earth (|latitude| > 90, |longitude| > 180, NaN, or |height| > 100 km).
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
