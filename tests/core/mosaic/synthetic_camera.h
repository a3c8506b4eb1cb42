#pragma once

// A synthetic downward-looking pinhole camera over a flat ground plane, shared by the mosaic
// tests and saker-bench-mosaic.

#include <Eigen/Dense>

#include <cmath>

namespace saker::mosaic::testing_support {

// The camera's image size, focal length and flying height.
struct SyntheticCamera {
  int width = 1280;
  int height = 720;
  double focal_px = 1000;
  double altitude_m = 156;  // 0.156 m per pixel: a 200 m x 112 m footprint
};

inline Eigen::Matrix3d Normalised(const Eigen::Matrix3d& h) { return h / h(2, 2); }

// map_from_frame of a downward pinhole camera at (x, y, altitude) over the ground plane (map =
// ground metres), flying towards `heading` (image up), tilted by small pitch and roll.
inline Eigen::Matrix3d GroundFromImage(double x, double y, double heading, double pitch,
                                       double roll, const SyntheticCamera& camera = {}) {
  Eigen::Matrix3d k;
  k << camera.focal_px, 0, 0.5 * (camera.width - 1), 0, camera.focal_px, 0.5 * (camera.height - 1),
      0, 0, 1;
  Eigen::Matrix3d world_from_camera;
  world_from_camera.col(0) = Eigen::Vector3d(std::sin(heading), -std::cos(heading), 0);
  world_from_camera.col(1) = Eigen::Vector3d(-std::cos(heading), -std::sin(heading), 0);
  world_from_camera.col(2) = Eigen::Vector3d(0, 0, -1);
  world_from_camera = world_from_camera *
                      Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitX()).toRotationMatrix() *
                      Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitY()).toRotationMatrix();
  const Eigen::Matrix3d camera_from_world = world_from_camera.transpose();
  const Eigen::Vector3d centre(x, y, camera.altitude_m);
  Eigen::Matrix3d image_from_ground;
  image_from_ground.col(0) = k * camera_from_world.col(0);
  image_from_ground.col(1) = k * camera_from_world.col(1);
  image_from_ground.col(2) = -k * camera_from_world * centre;
  return Normalised(image_from_ground.inverse());
}

}  // namespace saker::mosaic::testing_support
