#pragma once

// Renders what the simulated camera sees: the ground through the frame's homography, the moving
// targets, then the imaging effects (optical blur, slow gain drift, sensor noise, and a blank
// interval standing for cloud or a link dropout).

#include "core/sim/camera.h"
#include "core/sim/ground.h"
#include "core/sim/targets.h"
#include "core/util/status.h"

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include <cstdint>

namespace saker::sim {

struct ImagingOptions {
  double noise_sigma = 1.5;     // sensor noise, grey levels (1 sigma), per pixel and channel
  double blur_sigma_px = 0.0;   // extra Gaussian blur (optics, motion), pixels
  double gain_drift = 0.0;      // relative amplitude of a slow brightness drift (0.1 = +-10 %)
  double gain_period_s = 30.0;  // period of that drift
  double blank_start_s = -1;    // start of the blank interval (cloud), seconds; < 0: none
  double blank_duration_s = 0;  // its length
  Status Validate() const;
  bool IsBlank(double time_s) const;
};

class FrameRenderer {
 public:
  // `ground` must outlive the renderer.
  FrameRenderer(const GroundSource& ground, const CameraIntrinsics& camera,
                const ImagingOptions& imaging, uint64_t seed);

  // The frame at `time_s` seen through `frame_from_ground`, with `targets` drawn in (may be
  // empty; `shadow_per_m` as for DrawTargets). `valid`, when not null, receives 255 where the
  // frame shows ground with data. The noise of frame `frame_index` depends only on the seed and
  // the index. Safe to call from several threads.
  cv::Mat Render(const Eigen::Matrix3d& frame_from_ground, const std::vector<Target>& targets,
                 const Eigen::Vector2d& shadow_per_m, int64_t frame_index, double time_s,
                 cv::Mat* valid = nullptr) const;

  // Only the ground, no targets and no imaging effects (for tests and the truth check).
  cv::Mat RenderGround(const Eigen::Matrix3d& frame_from_ground, cv::Mat* valid = nullptr) const;

 private:
  const GroundSource& ground_;
  CameraIntrinsics camera_;
  ImagingOptions imaging_;
  uint64_t seed_;
};

}  // namespace saker::sim
