#pragma once

// A user-supplied orthophoto as the simulated ground (a GroundSource, see ground.h).
//
// Formats: PNG, JPEG and anything else OpenCV reads are decoded by OpenCV; .tif / .tiff files by
// GDAL, which also gives the ground sample distance of a GeoTIFF. Pixels become 8-bit BGR (grey is
// replicated, 16-bit is scaled by 1/257); a pixel is "no data" where its alpha is 0, or, in a
// GeoTIFF without alpha, where every colour band holds the band's nodata value (or GDAL's mask
// band says so). Orthophotos exported without alpha often fill the area outside their footprint
// with one colour instead (OpenDroneMap's PNG: opaque white); `nodata_fill_bgr` names that colour.
// No-data pixels are stored black.
//
// Placement: north up, the image's centre at options.centre_m, on the ground raster of ground.h
// at the image's own GSD. Image pixels map one to one onto raster pixels:
//   image pixel (i, j)  <->  raster pixel (i + raster_offset().x, j + raster_offset().y)
//   raster_offset.x = round(centre_m.x / gsd - (width - 1) / 2)
//   raster_offset.y = round(-centre_m.y / gsd - (height - 1) / 2)
// rounding half away from zero. When centre_m / gsd is not a whole number of pixels (or the image
// has an even size, whose centre lies between pixels), the image therefore lands up to half a
// pixel from centre_m in each axis: the ground is never resampled, so Render copies pixels
// exactly. The geotransform of a GeoTIFF gives only the GSD; its origin is ignored.

#include "core/sim/ground.h"
#include "core/util/status.h"

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include <filesystem>
#include <memory>
#include <optional>

namespace saker::sim {

// Largest accepted image side, in pixels: 20000 x 20000 BGR is 1.2 GB in memory.
inline constexpr int kMaxGroundImageSide = 20000;

struct GroundImageOptions {
  std::filesystem::path path;  // PNG, JPEG, or GeoTIFF (.tif / .tiff)
  // Metres per pixel; 0 = take it from the GeoTIFF geotransform (required for PNG / JPEG). When
  // given, it overrides the geotransform.
  double gsd_m = 0;
  Eigen::Vector2d centre_m{0, 0};  // ground point (east, north) under the image centre
  // The fill colour of the area outside the orthophoto's footprint, if it has one: pixels of
  // exactly this colour (after conversion to 8-bit BGR) in regions 4-connected to the image edge
  // are no data. Pixels of that colour inside the footprint (a white roof) stay data.
  std::optional<cv::Vec3b> nodata_fill_bgr;

  // A path, a GSD of 0 or in [1 mm, 1 km], a finite centre.
  Status Validate() const;
};

class GroundImage final : public GroundSource {
 public:
  // Errors name the file: NotFound when it is missing; InvalidData when it cannot be decoded or is
  // empty; InvalidArgument when it is too large or no GSD is known (PNG / JPEG without gsd_m, or
  // a GeoTIFF without a usable geotransform: none, rotated, non-square pixels, or in degrees);
  // Unsupported for pixel types other than 8 and 16 bits, and palette images.
  static StatusOr<std::unique_ptr<GroundImage>> Load(const GroundImageOptions& options);

  double gsd_m() const override { return gsd_m_; }
  // x, y = the west and south edges of the image's outer pixels; width, height = its size in
  // metres.
  cv::Rect2d extent_m() const override;
  // Copies the pixels of `region` (raster pixels) that the image covers; the rest is invalid.
  // Thread-safe (reads only).
  void Render(const cv::Rect& region, cv::Mat* bgr, cv::Mat* valid) const override;

  const cv::Mat& image() const { return image_; }  // CV_8UC3 BGR, black where there is no data
  const cv::Mat& mask() const { return mask_; }    // CV_8UC1, 255 = data, 0 = no data
  // Raster pixel of image pixel (0, 0) (see the placement rule above).
  cv::Point raster_offset() const { return raster_offset_; }

 private:
  GroundImage(cv::Mat image, cv::Mat mask, double gsd_m, cv::Point raster_offset);

  cv::Mat image_;
  cv::Mat mask_;
  double gsd_m_;
  cv::Point raster_offset_;
};

}  // namespace saker::sim
