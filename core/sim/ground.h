#pragma once

// The simulated ground: an image of the flat world at a fixed ground sample distance.
//
// Ground frame: east-north metres on the ground plane (z = 0), origin at the world's geographic
// origin; the same frame as a mission's map frame when the mission origin is the world origin.
//
// Ground raster: the ground sampled every gsd_m metres, north up. Raster pixel (col, row) has its
// centre at ground point (col * gsd_m, -row * gsd_m), so raster coordinates are
//   u = x / gsd_m,  v = -y / gsd_m
// and integer coordinates are pixel centres (the OpenCV convention, used for every image in Saker).
// The raster is unbounded in every direction: indices may be negative, and a source says where it
// has data through its validity mask.

#include "core/util/status.h"

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>
#include <opencv2/core/types.hpp>

namespace saker::sim {

// raster_from_ground for a raster of `gsd_m` metres per pixel (see above).
Eigen::Matrix3d RasterFromGround(double gsd_m);

class GroundSource {
 public:
  virtual ~GroundSource() = default;

  // Metres per raster pixel.
  virtual double gsd_m() const = 0;

  // Ground-frame bounds (metres) of the area where the source may have data: the whole image of
  // an orthophoto, the generated area of a procedural world. Outside, Render gives invalid pixels.
  virtual cv::Rect2d extent_m() const = 0;

  // Renders raster pixels `region` (raster pixel coordinates, may be negative) into `bgr`
  // (CV_8UC3, region.size()) and `valid` (CV_8UC1, 255 where the ground has data, 0 for "no data":
  // outside the extent, or transparent pixels of an orthophoto). Invalid pixels are black in `bgr`.
  // Safe to call from several threads at once.
  virtual void Render(const cv::Rect& region, cv::Mat* bgr, cv::Mat* valid) const = 0;
};

}  // namespace saker::sim
