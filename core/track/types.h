#pragma once

// Vocabulary of the Visual MTI front end (core/track), shared by the tracker, the motion
// segmentation, the homography estimation and the key frame chain.

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

namespace saker::track {

// A feature track: one Harris corner followed from frame to frame. Ids are never reused.
enum class FeatureTrackId : int64_t {};

// A moving-target track: features of one moving object grouped and linked over time.
enum class TargetTrackId : int64_t {};

// A key frame, numbered in the order they are chosen.
enum class KeyFrameId : int32_t {};

// The 8 free parameters of a homography H with H(2,2) = 1, in this order everywhere (covariances,
// Jacobians, the mission file, the tests): h00 h01 h02 h10 h11 h12 h20 h21 (row-major).
using HomographyParameters = Eigen::Matrix<double, 8, 1>;
using HomographyCovariance = Eigen::Matrix<double, 8, 8>;

// The same feature seen in two frames (pixels; integer coordinates are pixel centres).
struct Correspondence {
  FeatureTrackId id{};
  Eigen::Vector2d source{0, 0};
  Eigen::Vector2d target{0, 0};
};

// The frame rate at which the front end's options apply. Windows, gaps and confirmation lengths
// are given in seconds and speeds in pixels a second, so that the same defaults serve video of 1
// to 60 frames a second; each component turns them into frames (with a floor in frames, below
// which a window means nothing) for the rate of the video it is given.
class FrameRate {
 public:
  // Rates outside [kMinFps, kMaxFps] are clamped to it, and one that is not a positive finite
  // number (a stream that does not say) counts as kDefaultFps: a damaged header claiming 90 000
  // frames a second must not make windows of thousands of frames.
  static constexpr double kDefaultFps = 25;
  static constexpr double kMinFps = 0.1;
  static constexpr double kMaxFps = 120;

  FrameRate() = default;
  explicit FrameRate(double fps)
      : fps_(std::isfinite(fps) && fps > 0 ? std::clamp(fps, kMinFps, kMaxFps) : kDefaultFps) {}

  double fps() const { return fps_; }
  double interval_s() const { return 1 / fps_; }
  // `seconds` as a whole number of frames (rounded), at least `floor`.
  int Frames(double seconds, int floor) const {
    const double frames = std::round(std::clamp(seconds, 0.0, 1e6) * fps_);
    return std::max(floor, static_cast<int>(frames));
  }
  // A speed in pixels a second as pixels a frame.
  double PerFrame(double px_per_s) const { return px_per_s / fps_; }
  // A span of `frames` frames in seconds.
  double Seconds(double frames) const { return frames / fps_; }

 private:
  double fps_ = kDefaultFps;
};

}  // namespace saker::track
