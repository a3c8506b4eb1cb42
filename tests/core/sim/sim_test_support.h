#pragma once

// Helpers of the simulator's tests: decoding a simulated video, and checking that a frame and a
// homography really show the ground (the truth check).

#include "core/sim/simulator.h"
#include "core/sim/truth.h"

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include <filesystem>
#include <string>
#include <vector>

namespace saker::sim {

// A small, fast simulation: 320x180 at 100 m (0.2 m per pixel, like the default 1280x720 at
// 400 m), 10 fps, 2 s.
SimulationOptions SmallOptions(const std::filesystem::path& output);

// Every frame of a video, BGR.
std::vector<cv::Mat> DecodeAll(const std::filesystem::path& path);
// Every frame's presentation time, seconds from the first.
std::vector<double> DecodeTimes(const std::filesystem::path& path);
std::string ReadText(const std::filesystem::path& path);
cv::Mat ToCv(const Eigen::Matrix3d& h);
// Normalised cross-correlation of the grey levels of two images over `mask`.
double Ncc(const cv::Mat& a, const cv::Mat& b, const cv::Mat& mask);
// Warps decoded frame `frame` back onto the ground raster with `frame_from_ground`, and
// correlates it with the ground's own render there, away from targets and no-data pixels.
double GroundCorrelation(const SimulationSetup& setup, const Truth& truth, int64_t frame,
                         const cv::Mat& decoded, const Eigen::Matrix3d& frame_from_ground);

}  // namespace saker::sim
