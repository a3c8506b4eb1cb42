#pragma once

// Image geometry shared by the mosaic, the activity map and the GUI: the four image corners in
// MISB order, the homography those corners define with a map, and the uncertainty ellipse of a
// transferred point (its covariance from homography.h's TransferCovariance).

#include "core/track/homography.h"
#include "core/util/status.h"

#include <Eigen/Core>

#include <array>
#include <optional>
#include <vector>

namespace saker::track {

// The image corners in MISB order: upper-left, upper-right, lower-right, lower-left; the centres
// of the outermost pixels (0, 0) .. (width - 1, height - 1).
std::array<Eigen::Vector2d, 4> ImageCorners(int width, int height);

// The homography taking the four image corners to four map points, with the 8x8 covariance
// implied by an isotropic standard deviation `sigma` on each map coordinate. InvalidData when the
// points are degenerate (three collinear).
StatusOr<HomographyWithCovariance> HomographyFromCorners(
    const std::array<Eigen::Vector2d, 4>& image, const std::array<Eigen::Vector2d, 4>& map,
    double sigma);

// The ground's scale in an image, from where the metadata puts the image's four corners on the
// ground (a flat ground): the metres one pixel spans at any image point. The front end's gates
// follow a plausible top speed on the ground through it (issue 24, items 1 and 4).
class GroundScale {
 public:
  // `ground`: the corners on the ground in metres (east, north: a map frame such as
  // geo::LocalTangentPlane's), in MISB order (ImageCorners), of an image `width` x `height`.
  // nullopt when they are not finite, do not make a quadrilateral the whole image maps onto
  // (three in a line, crossed, or the horizon inside the image), or give a scale outside 1 mm to
  // 1 km a pixel at the image centre.
  static std::optional<GroundScale> FromCorners(const std::array<Eigen::Vector2d, 4>& ground,
                                                int width, int height);
  // The square root of the ground area one pixel at `image_point` covers, metres (the local
  // scale: an oblique view's far edge spans more than its near one); infinity at and beyond the
  // horizon of the corners' plane.
  double MetresPerPixel(const Eigen::Vector2d& image_point) const;
  // Ground metres (the corners' frame) from image pixels.
  const Eigen::Matrix3d& ground_from_image() const { return ground_from_image_; }

 private:
  explicit GroundScale(const Eigen::Matrix3d& ground_from_image);
  Eigen::Matrix3d ground_from_image_;
  double determinant_ = 0;  // of ground_from_image_
};

// Uncertainty ellipse of a 2-D Gaussian at a confidence level (2-dof chi-square:
// k^2 = -2 ln(1 - confidence)).
struct Ellipse {
  Eigen::Vector2d centre{0, 0};
  double semi_major = 0, semi_minor = 0;
  double angle_rad = 0;  // of the major axis, from +x towards +y, in (-pi/2, pi/2]
};
// confidence in (0, 1) and a finite covariance (SAKER_CHECK); negative eigenvalues from rounding
// count as zero.
Ellipse ConfidenceEllipse(const Eigen::Vector2d& centre, const Eigen::Matrix2d& covariance,
                          double confidence);
// `points` (>= 3, SAKER_CHECK) points on the ellipse, counter-clockwise in x-right y-up terms
// (from +x towards +y), starting at the end of the major axis.
std::vector<Eigen::Vector2d> EllipsePolygon(const Ellipse& ellipse, int points = 36);

}  // namespace saker::track
