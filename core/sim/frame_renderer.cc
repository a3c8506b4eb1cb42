#include "core/sim/frame_renderer.h"

#include "core/sim/random.h"
#include "core/util/check.h"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>

namespace saker::sim {

Status ImagingOptions::Validate() const {
  if (!(noise_sigma >= 0 && noise_sigma <= 100)) {
    return InvalidArgumentError("imaging: noise must be between 0 and 100 grey levels");
  }
  if (!(blur_sigma_px >= 0 && blur_sigma_px <= 20)) {
    return InvalidArgumentError("imaging: blur must be between 0 and 20 pixels");
  }
  if (!(gain_drift >= 0 && gain_drift < 1)) {
    return InvalidArgumentError("imaging: gain drift must be in [0, 1)");
  }
  if (!(gain_period_s > 0)) return InvalidArgumentError("imaging: gain period must be positive");
  if (!(blank_duration_s >= 0) || !std::isfinite(blank_start_s)) {
    return InvalidArgumentError("imaging: the blank interval needs a start and a length >= 0");
  }
  return Status::Ok();
}

bool ImagingOptions::IsBlank(double time_s) const {
  return blank_start_s >= 0 && time_s >= blank_start_s && time_s < blank_start_s + blank_duration_s;
}

FrameRenderer::FrameRenderer(const GroundSource& ground, const CameraIntrinsics& camera,
                             const ImagingOptions& imaging, uint64_t seed)
    : ground_(ground), camera_(camera), imaging_(imaging), seed_(seed) {}

cv::Mat FrameRenderer::RenderGround(const Eigen::Matrix3d& frame_from_ground,
                                    cv::Mat* valid) const {
  const double gsd = ground_.gsd_m();
  const Eigen::Matrix3d raster_from_frame = RasterFromGround(gsd) * frame_from_ground.inverse();
  // The raster area under the frame: its corners, with a margin for the interpolation kernel.
  double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300;
  std::vector<cv::Point2f> quad;
  for (const Eigen::Vector2d& corner : ImageCorners(camera_)) {
    const Eigen::Vector3d q = raster_from_frame * corner.homogeneous();
    SAKER_CHECK(q.z() > 0);  // every corner ray hits the ground in front of the camera
    const Eigen::Vector2d p = q.hnormalized();
    x0 = std::min(x0, p.x()), x1 = std::max(x1, p.x());
    y0 = std::min(y0, p.y()), y1 = std::max(y1, p.y());
    quad.emplace_back(float(p.x()), float(p.y()));
  }
  // Raster pixels per frame pixel: above ~1.5, sample a reduced level of the raster to avoid
  // aliasing (the warp's bilinear kernel only filters one pixel).
  const double ratio = std::sqrt(cv::contourArea(quad) / (double(camera_.width) * camera_.height));
  int levels = 0;
  while (levels < 6 && ratio / double(1 << levels) > 1.5) ++levels;
  const int step = 1 << levels;
  const int margin = 3 * step;
  cv::Rect region(int(std::floor(x0)) - margin, int(std::floor(y0)) - margin, 0, 0);
  region.width = int(std::ceil(x1)) + margin - region.x;
  region.height = int(std::ceil(y1)) + margin - region.y;
  region.width += (step - region.width % step) % step;
  region.height += (step - region.height % step) % step;
  SAKER_CHECK(double(region.width) * region.height < 400e6);
  cv::Mat bgr, mask;
  ground_.Render(region, &bgr, &mask);
  for (int k = 0; k < levels; ++k) {
    cv::pyrDown(bgr, bgr);
    cv::pyrDown(mask, mask);
  }
  // frame_from_level = frame_from_raster * raster_from_level; pyrDown keeps the even pixels, so
  // level pixel i sits on raster pixel region.x + step * i.
  Eigen::Matrix3d raster_from_level;
  raster_from_level << step, 0, region.x, 0, step, region.y, 0, 0, 1;
  const Eigen::Matrix3d frame_from_level = raster_from_frame.inverse() * raster_from_level;
  cv::Mat m(3, 3, CV_64F);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) m.at<double>(r, c) = frame_from_level(r, c);
  }
  cv::Mat frame;
  const cv::Size size(camera_.width, camera_.height);
  cv::warpPerspective(bgr, frame, m, size, cv::INTER_LINEAR, cv::BORDER_CONSTANT,
                      cv::Scalar::all(0));
  if (valid != nullptr) {
    cv::warpPerspective(mask, *valid, m, size, cv::INTER_LINEAR, cv::BORDER_CONSTANT,
                        cv::Scalar(0));
    cv::threshold(*valid, *valid, 254, 255, cv::THRESH_BINARY);
  }
  return frame;
}

cv::Mat FrameRenderer::Render(const Eigen::Matrix3d& frame_from_ground,
                              const std::vector<Target>& targets,
                              const Eigen::Vector2d& shadow_per_m, int64_t frame_index,
                              double time_s, cv::Mat* valid) const {
  cv::Mat frame;
  Random random(HashCombine(seed_, uint64_t(frame_index) * 0x9E37u + 17));
  if (imaging_.IsBlank(time_s)) {
    // Cloud: bright, almost featureless, slowly varying.
    cv::Mat small(9, 16, CV_8UC3);
    for (int r = 0; r < small.rows; ++r) {
      for (int c = 0; c < small.cols; ++c) {
        const uint8_t v = uint8_t(random.Uniform(215, 240));
        small.at<cv::Vec3b>(r, c) = cv::Vec3b(v, v, uint8_t(v - 3));
      }
    }
    cv::resize(small, frame, cv::Size(camera_.width, camera_.height), 0, 0, cv::INTER_CUBIC);
    if (valid != nullptr) *valid = cv::Mat::zeros(frame.size(), CV_8U);
  } else {
    frame = RenderGround(frame_from_ground, valid);
    DrawTargets(targets, shadow_per_m, frame_from_ground, &frame);
  }
  if (imaging_.blur_sigma_px > 0) {
    cv::GaussianBlur(frame, frame, cv::Size(), imaging_.blur_sigma_px);
  }
  if (imaging_.gain_drift > 0) {
    const double gain =
        1.0 + imaging_.gain_drift * std::sin(2 * M_PI * time_s / imaging_.gain_period_s);
    frame.convertTo(frame, -1, gain);
  }
  if (imaging_.noise_sigma > 0) {
    cv::Mat noise(frame.size(), CV_16SC3);
    cv::RNG rng(random.Next());
    rng.fill(noise, cv::RNG::NORMAL, 0.0, imaging_.noise_sigma);
    cv::Mat widened;
    frame.convertTo(widened, CV_16SC3);
    widened += noise;
    widened.convertTo(frame, CV_8UC3);
  }
  return frame;
}

}  // namespace saker::sim
