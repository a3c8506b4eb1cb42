#include "core/sim/camera.h"

#include <Eigen/Geometry>
#include <Eigen/LU>

#include <cmath>
#include <sstream>

namespace saker::sim {
namespace {

constexpr double kPi = 3.14159265358979323846;

double Radians(double degrees) { return degrees * kPi / 180.0; }
double Degrees(double radians) { return radians * 180.0 / kPi; }

// Camera axes in body axes (columns): image x is the right wing (body y), image y points to the
// tail (-body x), the optical axis points down (body z).
Eigen::Matrix3d BodyFromCamera() {
  Eigen::Matrix3d m;
  m << 0, -1, 0,  //
      1, 0, 0,    //
      0, 0, 1;
  return m;
}

// North-east-down axes in east-north-up axes (columns).
Eigen::Matrix3d EnuFromNed() {
  Eigen::Matrix3d m;
  m << 0, 1, 0,  //
      1, 0, 0,   //
      0, 0, -1;
  return m;
}

}  // namespace

double CameraIntrinsics::fx() const { return 0.5 * width / std::tan(Radians(0.5 * hfov_deg)); }
double CameraIntrinsics::fy() const { return fx(); }
double CameraIntrinsics::cx() const { return 0.5 * (width - 1); }
double CameraIntrinsics::cy() const { return 0.5 * (height - 1); }

double CameraIntrinsics::vfov_deg() const { return Degrees(2.0 * std::atan(0.5 * height / fy())); }

Eigen::Matrix3d CameraIntrinsics::K() const {
  Eigen::Matrix3d k;
  k << fx(), 0, cx(),  //
      0, fy(), cy(),   //
      0, 0, 1;
  return k;
}

Status CameraIntrinsics::Validate() const {
  constexpr int kMinSize = 16;
  constexpr int kMaxSize = 8192;
  if (width < kMinSize || width > kMaxSize || height < kMinSize || height > kMaxSize) {
    std::ostringstream message;
    message << "camera image size " << width << "x" << height << " is outside " << kMinSize << ".."
            << kMaxSize << " pixels";
    return InvalidArgumentError(message.str());
  }
  if (!(hfov_deg > 0.5 && hfov_deg < 120.0)) {
    std::ostringstream message;
    message << "camera horizontal field of view " << hfov_deg
            << " deg is outside (0.5, 120) degrees";
    return InvalidArgumentError(message.str());
  }
  return Status::Ok();
}

double ZoomOptions::HfovAt(double time_s, double from_hfov_deg) const {
  if (!enabled() || time_s <= start_s) return from_hfov_deg;
  if (time_s >= start_s + duration_s) return to_hfov_deg;
  const double f = 0.5 - 0.5 * std::cos(kPi * (time_s - start_s) / duration_s);
  // Interpolate the focal length's inverse (tan of the half angle): a zoom lens moves the focal
  // length smoothly, and the image scale follows it.
  const double a = std::tan(Radians(0.5 * from_hfov_deg)), b = std::tan(Radians(0.5 * to_hfov_deg));
  return Degrees(2.0 * std::atan(a + f * (b - a)));
}

Status ZoomOptions::Validate() const {
  if (!enabled()) return Status::Ok();
  if (!std::isfinite(start_s) || !(duration_s > 0 && duration_s <= 3600)) {
    return InvalidArgumentError("zoom: the change needs a start >= 0 and a length in (0, 3600] s");
  }
  if (!(to_hfov_deg > 0.5 && to_hfov_deg < 120.0)) {
    return InvalidArgumentError("zoom: the field of view to zoom to must be in (0.5, 120) degrees");
  }
  return Status::Ok();
}

Eigen::Matrix3d CameraPose::WorldFromCamera() const {
  const Eigen::Matrix3d ned_from_body =
      (Eigen::AngleAxisd(Radians(heading_deg), Eigen::Vector3d::UnitZ()) *
       Eigen::AngleAxisd(Radians(pitch_deg), Eigen::Vector3d::UnitY()) *
       Eigen::AngleAxisd(Radians(roll_deg), Eigen::Vector3d::UnitX()))
          .toRotationMatrix();
  if (gimbal_azimuth_deg == 0 && gimbal_off_nadir_deg == 0) {
    return EnuFromNed() * ned_from_body * BodyFromCamera();
  }
  const Eigen::Matrix3d body_from_gimbal =
      (Eigen::AngleAxisd(Radians(gimbal_azimuth_deg), Eigen::Vector3d::UnitZ()) *
       Eigen::AngleAxisd(Radians(gimbal_off_nadir_deg), Eigen::Vector3d::UnitY()))
          .toRotationMatrix();
  return EnuFromNed() * ned_from_body * body_from_gimbal * BodyFromCamera();
}

Eigen::Matrix3d FrameFromGround(const CameraIntrinsics& intrinsics, const CameraPose& pose) {
  // A ground point X = (x, y, 0) is at R^T (X - C) in the camera, so
  //   pixel ~ K [r1 r2 -R^T C] (x, y, 1)
  // with r1, r2 the first two columns of R^T.
  const Eigen::Matrix3d camera_from_world = pose.WorldFromCamera().transpose();
  Eigen::Matrix3d camera_from_ground;
  camera_from_ground.col(0) = camera_from_world.col(0);
  camera_from_ground.col(1) = camera_from_world.col(1);
  camera_from_ground.col(2) = -camera_from_world * pose.position_m;
  Eigen::Matrix3d h = intrinsics.K() * camera_from_ground;
  // H(2,2) is the origin's depth; 1e-12 of the matrix scale means the origin is at the horizon.
  if (std::abs(h(2, 2)) > 1e-12 * h.norm()) return h / h(2, 2);
  return h / h.norm();
}

std::array<Eigen::Vector2d, 4> ImageCorners(const CameraIntrinsics& intrinsics) {
  const double right = intrinsics.width - 0.5;
  const double bottom = intrinsics.height - 0.5;
  return {Eigen::Vector2d(-0.5, -0.5), Eigen::Vector2d(right, -0.5), Eigen::Vector2d(right, bottom),
          Eigen::Vector2d(-0.5, bottom)};
}

std::optional<Eigen::Vector2d> GroundPointOfPixel(const CameraIntrinsics& intrinsics,
                                                  const CameraPose& pose,
                                                  const Eigen::Vector2d& pixel) {
  const double height = pose.position_m.z();
  if (!(height > 0.0)) return std::nullopt;
  const Eigen::Vector3d ray_camera((pixel.x() - intrinsics.cx()) / intrinsics.fx(),
                                   (pixel.y() - intrinsics.cy()) / intrinsics.fy(), 1.0);
  const Eigen::Vector3d ray = (pose.WorldFromCamera() * ray_camera).normalized();
  // -ray.z() is the sine of the depression below the horizon.
  if (!(-ray.z() >= std::sin(Radians(kMinRayDepressionDeg)))) return std::nullopt;
  const double distance = height / -ray.z();
  return Eigen::Vector2d(pose.position_m.x() + distance * ray.x(),
                         pose.position_m.y() + distance * ray.y());
}

std::optional<std::array<Eigen::Vector2d, 4>> GroundFootprint(const CameraIntrinsics& intrinsics,
                                                              const CameraPose& pose) {
  const std::array<Eigen::Vector2d, 4> corners = ImageCorners(intrinsics);
  std::array<Eigen::Vector2d, 4> footprint;
  for (size_t i = 0; i < corners.size(); ++i) {
    const std::optional<Eigen::Vector2d> ground = GroundPointOfPixel(intrinsics, pose, corners[i]);
    if (!ground) return std::nullopt;
    footprint[i] = *ground;
  }
  return footprint;
}

std::vector<Eigen::Vector2d> VisibleGroundOutline(const CameraIntrinsics& intrinsics,
                                                  const CameraPose& pose, double max_heights) {
  const double height = pose.position_m.z();
  std::vector<Eigen::Vector2d> outline;
  if (!(height > 0.0)) return outline;
  const double least_sin = 1.0 / std::sqrt(1.0 + max_heights * max_heights);
  const Eigen::Matrix3d world_from_camera = pose.WorldFromCamera();
  const std::array<Eigen::Vector2d, 4> corners = ImageCorners(intrinsics);
  constexpr int kPerEdge = 16;
  bool meets = false;
  for (size_t k = 0; k < corners.size(); ++k) {
    const Eigen::Vector2d& a = corners[k];
    const Eigen::Vector2d& b = corners[(k + 1) % corners.size()];
    for (int i = 0; i < kPerEdge; ++i) {
      const Eigen::Vector2d pixel = a + (b - a) * (static_cast<double>(i) / kPerEdge);
      const Eigen::Vector3d ray =
          (world_from_camera * Eigen::Vector3d((pixel.x() - intrinsics.cx()) / intrinsics.fx(),
                                               (pixel.y() - intrinsics.cy()) / intrinsics.fy(), 1))
              .normalized();
      const Eigen::Vector2d across = ray.head<2>();
      if (-ray.z() >= least_sin) {
        meets = true;
        outline.push_back(pose.position_m.head<2>() + across * (height / -ray.z()));
      } else if (across.norm() > 1e-9) {
        outline.push_back(pose.position_m.head<2>() + across.normalized() * max_heights * height);
      }
    }
  }
  if (!meets) outline.clear();
  return outline;
}

std::optional<Eigen::Vector2d> GroundCentre(const CameraIntrinsics& intrinsics,
                                            const CameraPose& pose) {
  return GroundPointOfPixel(intrinsics, pose, Eigen::Vector2d(intrinsics.cx(), intrinsics.cy()));
}

double ViewGeometry::SinDepression(double x, double y) const {
  const Eigen::Vector3d ray = world_ray_from_pixel * Eigen::Vector3d(x, y, 1.0);
  return -ray.z() / ray.norm();
}

std::optional<ViewGeometry> ViewOfHomography(const CameraIntrinsics& intrinsics,
                                             const Eigen::Matrix3d& frame_from_ground) {
  Eigen::Matrix3d m = intrinsics.K().inverse() * frame_from_ground;
  const double scale = m.col(0).norm();
  if (!(scale > 0) || !std::isfinite(scale)) return std::nullopt;
  m /= scale;
  // Columns r1, r2 (the ground's east and north axes in the camera) and t = -R C; r1 x r2 is the
  // ground's up axis in the camera whatever the sign of H, and the camera's height, -(r3 . t),
  // must be positive.
  const Eigen::Vector3d r3 = m.col(0).cross(m.col(1));
  if (r3.dot(m.col(2)) > 0) m = -m;
  Eigen::Matrix3d camera_from_world;
  camera_from_world << m.col(0), m.col(1), r3;
  ViewGeometry view;
  view.position_m = -camera_from_world.transpose() * m.col(2);
  if (!(view.position_m.z() > 0)) return std::nullopt;
  view.world_ray_from_pixel = camera_from_world.transpose() * intrinsics.K().inverse();
  view.depth_of_ground = m.row(2);
  return view;
}

double NadirGsd(const CameraIntrinsics& intrinsics, double height_m) {
  return height_m / intrinsics.fx();
}

}  // namespace saker::sim
