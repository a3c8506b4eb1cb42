#include "core/geo/local_tangent_plane.h"

#include "core/util/check.h"

#include <GeographicLib/LocalCartesian.hpp>

#include <cmath>
#include <sstream>

namespace saker::geo {

double WrapLongitude(double longitude_deg) {
  if (longitude_deg >= -180.0 && longitude_deg <= 180.0) return longitude_deg;
  return std::remainder(longitude_deg, 360.0);
}

double UnwrapLongitude(double longitude_deg, double reference_deg) {
  const double difference = longitude_deg - reference_deg;
  if (difference >= -180.0 && difference <= 180.0) return longitude_deg;
  return reference_deg + std::remainder(difference, 360.0);
}

Wgs84 CentreOf(const std::vector<Wgs84>& points) {
  SAKER_CHECK(!points.empty()) << "CentreOf needs at least one position";
  const double reference = points.front().longitude_deg;
  const double n = static_cast<double>(points.size());
  Wgs84 centre;
  for (const Wgs84& p : points) {
    centre.latitude_deg += p.latitude_deg / n;
    centre.longitude_deg += UnwrapLongitude(p.longitude_deg, reference) / n;
    centre.height_m += p.height_m / n;
  }
  centre.longitude_deg = WrapLongitude(centre.longitude_deg);
  return centre;
}

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
  if (std::abs(origin.latitude_deg) > kMaxMapLatitudeDeg) {
    std::ostringstream message;
    message << "map origin at latitude " << origin.latitude_deg << " is "
            << std::lround((90 - std::abs(origin.latitude_deg)) * 111.2)
            << " km from the pole: a local tangent plane cannot serve as the map there (beyond "
            << kMaxMapLatitudeDeg << " degrees its north turns away from true north within "
            << "a few kilometres); process the video without its metadata";
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
