#include "core/track/image_geometry.h"

#include "core/util/check.h"

#include <Eigen/Eigenvalues>
#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <limits>

namespace saker::track {

std::array<Eigen::Vector2d, 4> ImageCorners(int width, int height) {
  const double x = width - 1, y = height - 1;
  return {Eigen::Vector2d(0, 0), Eigen::Vector2d(x, 0), Eigen::Vector2d(x, y),
          Eigen::Vector2d(0, y)};
}

StatusOr<HomographyWithCovariance> HomographyFromCorners(
    const std::array<Eigen::Vector2d, 4>& image, const std::array<Eigen::Vector2d, 4>& map,
    double sigma) {
  // u = (h00 x + h01 y + h02) / (h20 x + h21 y + 1), likewise v: linear in the 8 parameters.
  Eigen::Matrix<double, 8, 8> a;
  Eigen::Matrix<double, 8, 1> b;
  for (int i = 0; i < 4; ++i) {
    const double x = image[static_cast<size_t>(i)].x(), y = image[static_cast<size_t>(i)].y();
    const double u = map[static_cast<size_t>(i)].x(), v = map[static_cast<size_t>(i)].y();
    a.row(2 * i) << x, y, 1, 0, 0, 0, -x * u, -y * u;
    a.row(2 * i + 1) << 0, 0, 0, x, y, 1, -x * v, -y * v;
    b(2 * i) = u;
    b(2 * i + 1) = v;
  }
  const Eigen::FullPivLU<Eigen::Matrix<double, 8, 8>> lu(a);
  if (!lu.isInvertible() || !a.allFinite() || !b.allFinite()) {
    return InvalidDataError("homography from corners: the four corners do not define a homography");
  }
  HomographyWithCovariance h;
  h.target_from_source = HomographyFromParameters(lu.solve(b));
  Eigen::Matrix<double, 8, 8> j;
  for (int i = 0; i < 4; ++i) {
    j.block<2, 8>(2 * i, 0) = TransferJacobian(h.target_from_source, image[static_cast<size_t>(i)]);
  }
  const Eigen::FullPivLU<Eigen::Matrix<double, 8, 8>> lu_j(j);
  if (!lu_j.isInvertible()) {
    return InvalidDataError("homography from corners: the four corners do not define a homography");
  }
  const Eigen::Matrix<double, 8, 8> inverse = lu_j.inverse();
  h.covariance = sigma * sigma * inverse * inverse.transpose();
  return h;
}

std::optional<GroundScale> GroundScale::FromCorners(const std::array<Eigen::Vector2d, 4>& ground,
                                                    int width, int height) {
  if (width < 2 || height < 2) return std::nullopt;
  for (const Eigen::Vector2d& g : ground) {
    if (!g.allFinite()) return std::nullopt;
  }
  const StatusOr<HomographyWithCovariance> h =
      HomographyFromCorners(ImageCorners(width, height), ground, 1.0);
  if (!h.ok() || !h->target_from_source.allFinite()) return std::nullopt;
  const GroundScale scale(h->target_from_source);
  // The whole image on the ground side of the horizon (w > 0: the first corner's w is 1, since
  // the homography's last element is). Then the rectangle maps onto a convex quadrilateral, so
  // crossed corners are refused too.
  for (const Eigen::Vector2d& corner : ImageCorners(width, height)) {
    if (!(scale.ground_from_image_.row(2).dot(corner.homogeneous()) > 0)) return std::nullopt;
  }
  const double centre_scale = scale.MetresPerPixel(Eigen::Vector2d(width - 1, height - 1) / 2);
  if (!(centre_scale >= 1e-3 && centre_scale <= 1e3)) return std::nullopt;
  return scale;
}

GroundScale::GroundScale(const Eigen::Matrix3d& ground_from_image)
    : ground_from_image_(ground_from_image), determinant_(ground_from_image.determinant()) {}

double GroundScale::MetresPerPixel(const Eigen::Vector2d& image_point) const {
  // The Jacobian determinant of a homography at a point is det(H) / w^3.
  const double w = ground_from_image_.row(2).dot(image_point.homogeneous());
  if (!(w > 0)) return std::numeric_limits<double>::infinity();
  return std::sqrt(std::abs(determinant_) / (w * w * w));
}

Ellipse ConfidenceEllipse(const Eigen::Vector2d& centre, const Eigen::Matrix2d& covariance,
                          double confidence) {
  SAKER_CHECK(confidence > 0 && confidence < 1) << "confidence " << confidence;
  SAKER_CHECK(covariance.allFinite());
  const double k2 = -2.0 * std::log1p(-confidence);
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eigen(0.5 *
                                                             (covariance + covariance.transpose()));
  // Eigenvalues ascending: the major axis is the second eigenvector.
  const Eigen::Vector2d major = eigen.eigenvectors().col(1);
  Ellipse e;
  e.centre = centre;
  e.semi_major = std::sqrt(k2 * std::max(0.0, eigen.eigenvalues()(1)));
  e.semi_minor = std::sqrt(k2 * std::max(0.0, eigen.eigenvalues()(0)));
  double angle = std::atan2(major.y(), major.x());
  if (angle <= -M_PI / 2) angle += M_PI;
  if (angle > M_PI / 2) angle -= M_PI;
  e.angle_rad = angle;
  return e;
}

std::vector<Eigen::Vector2d> EllipsePolygon(const Ellipse& ellipse, int points) {
  SAKER_CHECK(points >= 3) << "points " << points;
  const double c = std::cos(ellipse.angle_rad), s = std::sin(ellipse.angle_rad);
  std::vector<Eigen::Vector2d> polygon;
  polygon.reserve(static_cast<size_t>(points));
  for (int i = 0; i < points; ++i) {
    const double t = 2.0 * M_PI * i / points;
    const double a = ellipse.semi_major * std::cos(t), b = ellipse.semi_minor * std::sin(t);
    polygon.push_back(ellipse.centre + Eigen::Vector2d(c * a - s * b, s * a + c * b));
  }
  return polygon;
}

}  // namespace saker::track
