#include "core/geo/local_tangent_plane.h"

#include <GeographicLib/LocalCartesian.hpp>

#include <cmath>
#include <sstream>

namespace saker::geo {

struct LocalTangentPlane::Impl {
  explicit Impl(const Wgs84& o) : projection(o.latitude_deg, o.longitude_deg, o.height_m) {}
  GeographicLib::LocalCartesian projection;
};

StatusOr<LocalTangentPlane> LocalTangentPlane::Create(const Wgs84& origin) {
  const bool finite = std::isfinite(origin.latitude_deg) && std::isfinite(origin.longitude_deg) &&
                      std::isfinite(origin.height_m);
  if (!finite || std::abs(origin.latitude_deg) > 90 || std::abs(origin.longitude_deg) > 180 ||
      std::abs(origin.height_m) > 100e3) {
    std::ostringstream message;
    message << "map origin is not a position on Earth: latitude " << origin.latitude_deg
            << ", longitude " << origin.longitude_deg << ", height " << origin.height_m << " m";
    return InvalidArgumentError(message.str());
  }
  return LocalTangentPlane(origin);
}

LocalTangentPlane::LocalTangentPlane(const Wgs84& origin)
    : origin_(origin), impl_(std::make_unique<Impl>(origin)) {}
LocalTangentPlane::LocalTangentPlane(const LocalTangentPlane& other)
    : origin_(other.origin_), impl_(std::make_unique<Impl>(*other.impl_)) {}
LocalTangentPlane& LocalTangentPlane::operator=(const LocalTangentPlane& other) {
  if (this != &other) {
    origin_ = other.origin_;
    impl_ = std::make_unique<Impl>(*other.impl_);
  }
  return *this;
}
LocalTangentPlane::LocalTangentPlane(LocalTangentPlane&&) noexcept = default;
LocalTangentPlane& LocalTangentPlane::operator=(LocalTangentPlane&&) noexcept = default;
LocalTangentPlane::~LocalTangentPlane() = default;

Enu LocalTangentPlane::EnuFromWgs84(const Wgs84& point) const {
  Enu enu;
  impl_->projection.Forward(point.latitude_deg, point.longitude_deg, point.height_m, enu.x(),
                            enu.y(), enu.z());
  return enu;
}

Wgs84 LocalTangentPlane::Wgs84FromEnu(const Enu& point) const {
  Wgs84 wgs84;
  impl_->projection.Reverse(point.x(), point.y(), point.z(), wgs84.latitude_deg,
                            wgs84.longitude_deg, wgs84.height_m);
  return wgs84;
}

Eigen::Vector2d LocalTangentPlane::MapFromLatLon(double latitude_deg, double longitude_deg) const {
  return EnuFromWgs84({latitude_deg, longitude_deg, origin_.height_m}).head<2>();
}

Wgs84 LocalTangentPlane::LatLonFromMap(const Eigen::Vector2d& map_point) const {
  // The point on the ellipsoid-parallel surface through the origin whose
  // horizontal ENU position is map_point: iterate the vertical offset, since
  // the tangent plane drops below that surface away from the origin.
  double up = 0;
  Wgs84 result;
  for (int i = 0; i < 5; ++i) {
    result = Wgs84FromEnu({map_point.x(), map_point.y(), up});
    up -= result.height_m - origin_.height_m;
  }
  return result;
}

}  // namespace saker::geo
