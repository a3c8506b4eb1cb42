#pragma once

// The simulated camera: an ideal pinhole (no distortion, square pixels) on a gimbal under the
// platform. At rest the gimbal looks straight down with the top of the image towards the nose; it
// tilts the camera off nadir towards an azimuth (forward, sideways, or staring at a point), the
// top of the image then pointing away from the platform, towards the horizon.
//
// Frames (see also ground.h):
//   ground  east-north-up metres; the ground is the plane z = 0.
//   body    x nose, y right wing, z down; attitude is yaw-pitch-roll (heading, pitch, roll applied
//           in that order) from north-east-down: R_ned_from_body = Rz(heading) Ry(pitch) Rx(roll).
//   gimbal  the camera's mount: R_body_from_gimbal = Rz(gimbal_azimuth) Ry(gimbal_off_nadir), so
//           the optical axis (gimbal z) leans from body down towards the azimuth (0 = the nose,
//           90 = the right wing).
//   camera  OpenCV: x right, y down, z forward along the optical axis. At rest (gimbal angles 0)
//           image x is the right wing, image y points to the tail (image up is the nose) and the
//           optical axis is body down.
//   image   pixels, integer = pixel centre; the outer corners are (-0.5, -0.5) .. (w-0.5, h-0.5).
//
// A ray that does not meet the ground (or meets it so far away that the answer is meaningless)
// gives no ground point: GroundPointOfPixel, GroundFootprint and GroundCentre return nullopt
// rather than a point behind the camera or thousands of kilometres away.

#include "core/util/status.h"

#include <Eigen/Core>

#include <array>
#include <optional>
#include <vector>

namespace saker::sim {

// A ray must point at least this far below the horizon to count as meeting the ground: at
// 2 degrees the ground point is already about 29 heights away, beyond anything a downward-looking
// camera is meant to see.
inline constexpr double kMinRayDepressionDeg = 2.0;

struct CameraIntrinsics {
  int width = 1280;
  int height = 720;
  double hfov_deg = 35.5;  // horizontal field of view (at 400 m height: 0.2 m per pixel)

  // Focal lengths in pixels; square pixels, so fy == fx = (width / 2) / tan(hfov / 2). The field
  // of view spans the outer pixel edges, not the outer pixel centres.
  double fx() const;
  double fy() const;
  // Principal point at the image centre: (width - 1) / 2, (height - 1) / 2.
  double cx() const;
  double cy() const;
  double vfov_deg() const;
  // [fx 0 cx; 0 fy cy; 0 0 1].
  Eigen::Matrix3d K() const;

  // Sizes in 16..8192 pixels, hfov in (0.5, 120) degrees.
  Status Validate() const;
};

// A zoom during the flight: the horizontal field of view goes from the camera's to `to_hfov_deg`
// over [start_s, start_s + duration_s] (a smooth cosine ramp, as a zoom lens drives), and stays.
struct ZoomOptions {
  double start_s = -1;     // < 0: no zoom
  double duration_s = 2;   // length of the change, seconds (> 0)
  double to_hfov_deg = 0;  // the field of view it ends at (0.5 .. 120 degrees)
  bool enabled() const { return start_s >= 0; }
  // The field of view at `time_s` for a camera whose field of view is `from_hfov_deg` at rest.
  double HfovAt(double time_s, double from_hfov_deg) const;
  Status Validate() const;
};

// The platform's pose and the gimbal's pointing. Angles in degrees.
struct CameraPose {
  Eigen::Vector3d position_m = {0, 0, 400};  // east, north, height above the ground plane
  double heading_deg = 0;                    // platform heading, clockwise from north
  double pitch_deg = 0;                      // nose up positive: the footprint moves forward
  double roll_deg = 0;                       // right wing down positive: the footprint moves left
  // The gimbal (see the frames above): off nadir 0 looks straight down; 90 would be the horizon.
  double gimbal_azimuth_deg = 0;    // clockwise from the nose
  double gimbal_off_nadir_deg = 0;  // 0 .. 90

  // Rotation taking camera axes (x right, y down, z along the optical axis) to ground-frame axes
  // (east, north, up).
  Eigen::Matrix3d WorldFromCamera() const;
};

// image_from_ground homography of the ground plane z = 0: pixel ~ H * (east, north, 1). Normalised
// so H(2,2) = 1. H(2,2) is the depth of the ground origin along the optical axis; in the one
// degenerate case where it is zero (the origin lies in the camera's principal plane, at the
// horizon of a tilted camera) the matrix is scaled to unit Frobenius norm instead.
Eigen::Matrix3d FrameFromGround(const CameraIntrinsics& intrinsics, const CameraPose& pose);

// The outer image corners in MISB order: 1 upper-left (-0.5, -0.5), 2 upper-right, 3 lower-right,
// 4 lower-left (-0.5, h - 0.5).
std::array<Eigen::Vector2d, 4> ImageCorners(const CameraIntrinsics& intrinsics);

// Ground point (east, north) seen at image point `pixel`, or nullopt when the camera is not above
// the ground or the ray points less than kMinRayDepressionDeg below the horizon.
std::optional<Eigen::Vector2d> GroundPointOfPixel(const CameraIntrinsics& intrinsics,
                                                  const CameraPose& pose,
                                                  const Eigen::Vector2d& pixel);

// Ground points of ImageCorners (MISB order), or nullopt when any corner ray misses the ground
// (see GroundPointOfPixel): e.g. a pitch of 80 degrees puts the top of the image above the horizon.
std::optional<std::array<Eigen::Vector2d, 4>> GroundFootprint(const CameraIntrinsics& intrinsics,
                                                              const CameraPose& pose);

// Ground points bounding what the camera sees out to `max_heights` camera heights: where the rays
// of the image border meet the ground, a ray that meets it farther out (or not at all: the sky)
// cut at that distance in its direction. Empty when no border ray meets the ground within it.
std::vector<Eigen::Vector2d> VisibleGroundOutline(const CameraIntrinsics& intrinsics,
                                                  const CameraPose& pose, double max_heights);

// Where the optical axis meets the ground, or nullopt as for GroundPointOfPixel.
std::optional<Eigen::Vector2d> GroundCentre(const CameraIntrinsics& intrinsics,
                                            const CameraPose& pose);

// The orientation and height of the camera behind a ground homography, for the pixels whose rays
// miss the ground (sky) or meet it too far away to be drawn (near the horizon).
struct ViewGeometry {
  // Pixel (x, y, 1) -> the direction of its ray in (east, north, up), not normalised.
  Eigen::Matrix3d world_ray_from_pixel;
  Eigen::Vector3d position_m;  // the camera's (east, north, height above the ground plane)
  // Ground point (east, north, 1) -> its depth along the optical axis (> 0 in front).
  Eigen::RowVector3d depth_of_ground;
  double height_m() const { return position_m.z(); }
  // The sine of the ray's angle below the horizon (negative above it) at pixel (x, y).
  double SinDepression(double x, double y) const;
};

// Recovered from `frame_from_ground` (FrameFromGround of `intrinsics`, at any scale and sign):
// K^-1 H is proportional to [r1 r2 t] of the camera's rotation and translation. nullopt when the
// matrix is not such a homography (singular) or puts the camera on or below the ground.
std::optional<ViewGeometry> ViewOfHomography(const CameraIntrinsics& intrinsics,
                                             const Eigen::Matrix3d& frame_from_ground);

// Metres per pixel on the ground straight below a nadir camera at `height_m`: height / fx.
double NadirGsd(const CameraIntrinsics& intrinsics, double height_m);

}  // namespace saker::sim
