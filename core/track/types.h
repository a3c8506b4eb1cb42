#pragma once

// Vocabulary of the Visual MTI front end (core/track), shared by the tracker, the motion
// segmentation, the homography estimation and the key frame chain.

#include <Eigen/Core>

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

}  // namespace saker::track
