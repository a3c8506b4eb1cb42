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
#include <optional>
#include <string_view>
#include <vector>

namespace saker::sim {

// What the sensor sees: visible colour, or thermal infrared shown white-hot (warm is bright) or
// black-hot (warm is dark).
enum class SensorLook { kEo, kIrWhiteHot, kIrBlackHot };
const char* SensorLookName(SensorLook look);  // "eo", "ir-white-hot", "ir-black-hot"
std::optional<SensorLook> ParseSensorLook(std::string_view name);

struct ImagingOptions {
  SensorLook look = SensorLook::kEo;
  // Infrared: the operator switches polarity (white-hot <-> black-hot) at this time; < 0: never.
  double polarity_switch_s = -1;
  double haze = 0;            // 0 .. 0.8: a veil of bright airlight that takes that much contrast
  double motion_blur_px = 0;  // length of a smear along the image's vertical axis, pixels
  // Radial lens distortion: a pixel at distance r from the image centre (as a fraction of the
  // half diagonal) moves to r (1 + k1 r^2); negative is barrel, positive pincushion. Frames then
  // relate to the ground by homographies only approximately (see LensDistort).
  double lens_k1 = 0;
  double noise_sigma = 1.5;     // sensor noise, grey levels (1 sigma), per pixel and channel
  double blur_sigma_px = 0.0;   // extra Gaussian blur (optics, motion), pixels
  double gain_drift = 0.0;      // relative amplitude of a slow brightness drift (0.1 = +-10 %)
  double gain_period_s = 30.0;  // period of that drift
  double blank_start_s = -1;    // start of the blank interval (cloud), seconds; < 0: none
  double blank_duration_s = 0;  // its length
  Status Validate() const;
  bool IsBlank(double time_s) const;
  bool infrared() const { return look != SensorLook::kEo; }
  // Whether warm things are bright at `time_s` (infrared looks, after any polarity switch).
  bool WhiteHotAt(double time_s) const;
};

// Where the lens puts an ideal pinhole pixel (ImagingOptions::lens_k1); the identity for k1 = 0.
Eigen::Vector2d LensDistort(const Eigen::Vector2d& pixel, int width, int height, double k1);

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

  // Whether a target at `ground_m` is drawn in the frame seen through `frame_from_ground`: in
  // front of the camera and nearer than the haze (see RenderGround). The truth's visibility
  // follows it, together with the frame's bounds.
  bool Shows(const Eigen::Matrix3d& frame_from_ground, const Eigen::Vector2d& ground_m) const;

  // Only the ground, no targets and no imaging effects (for tests and the truth check).
  //
  // The ground is sampled from the level of detail that fits each part of the frame: a nadir view
  // has one scale, but in an oblique view the far rows see many times more ground per pixel than
  // the near ones. Rows are then rendered in bands, each from its own level (a coarser source of
  // `coarser_levels` when there is one, else the ground reduced by image pyramid), blended over a
  // few rows where bands meet.
  //
  // Near the horizon (a low oblique view) the ground is drawn out to kDrawDistanceHeights camera
  // heights, fading into haze from kHazeStartHeights on; the rays that miss it show the sky: a
  // gradient from the haze at the horizon to blue overhead, with clouds fixed in direction (they
  // move in the frame with the camera's rotation alone, as distant things do). `valid` is 0 on
  // haze and sky.
  cv::Mat RenderGround(const Eigen::Matrix3d& frame_from_ground, cv::Mat* valid = nullptr) const;

  // The ground is drawn out to this many camera heights (a ray 7.1 degrees below the horizon) and
  // fades into haze from kHazeStartHeights (11.3 degrees); targets beyond that are not drawn.
  static constexpr double kDrawDistanceHeights = 8.0;
  static constexpr double kHazeStartHeights = 5.0;

  // Sources of the same ground at 2, 4, 8... times the ground's metres per pixel (element k at
  // 2^(k+1) times), used instead of reducing the full-detail raster where a frame needs them.
  // They must outlive the renderer.
  void SetCoarserLevels(std::vector<const GroundSource*> coarser_levels);

 private:
  // Frame rows [row0, row1) rendered from level `level` (raster pixels of 2^level times the
  // ground's size), into `bgr` and `valid` of (row1 - row0) rows.
  // `outline`, when not empty, bounds the part of the rows that shows ground (frame points); by
  // default the rows' corners do.
  void RenderRows(const Eigen::Matrix3d& frame_from_ground, int row0, int row1, int level,
                  cv::Mat* bgr, cv::Mat* valid,
                  const std::vector<Eigen::Vector2d>& outline = {}) const;
  // RenderGround's bands of rows, each from its level of detail, over rows [first_row, height)
  // whose ground spans columns `spans` (one [x0, x1] pair a row, all of them by default).
  cv::Mat RenderBands(const Eigen::Matrix3d& frame_from_ground, int first_row,
                      const std::vector<std::pair<double, double>>& spans, cv::Mat* valid) const;
  // Haze and sky over the rows of a view that reaches the horizon, blended into `frame`.
  void DrawSkyAndHaze(const ViewGeometry& view, cv::Mat* frame, cv::Mat* valid) const;
  // Infrared: the ground's thermal image (white-hot) and the targets made warm.
  static cv::Mat ThermalGround(const cv::Mat& bgr);
  static std::vector<Target> ThermalTargets(const std::vector<Target>& targets);
  // The level of detail for a part of the frame whose raster pixels per frame pixel are `ratio`.
  static int LevelFor(double ratio);

  const GroundSource& ground_;
  std::vector<const GroundSource*> coarser_levels_;
  cv::Mat distortion_x_, distortion_y_;  // remap tables of the lens distortion (CV_32F), if any
  CameraIntrinsics camera_;
  ImagingOptions imaging_;
  uint64_t seed_;
  // Cloud cover by direction: columns azimuth 0..360 degrees, rows elevation 0..kSkyRowsDeg.
  cv::Mat clouds_;
};

}  // namespace saker::sim
