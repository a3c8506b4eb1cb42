#pragma once

// Ground truth of a simulated video, written beside it as JSON (format in docs/simulator.md).
//
// For every frame: its time, the ground-to-image homography, the camera pose, whether it is blank
// and whether a KLV packet went with it. For every target and every frame: ground position,
// image position, velocity, and whether it is visible in the frame.

#include "core/util/status.h"

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace saker::sim {

inline constexpr const char* kTruthFormat = "saker-sim-truth";
inline constexpr int kTruthVersion = 1;

struct FrameTruth {
  int64_t index = 0;
  double time_s = 0;
  Eigen::Matrix3d frame_from_ground = Eigen::Matrix3d::Identity();  // H(2,2) = 1
  Eigen::Vector3d position_m{0, 0, 0};  // camera: east, north, height above ground
  double heading_deg = 0, pitch_deg = 0, roll_deg = 0;
  bool blank = false;  // cloud / dropout: the frame shows no ground
  bool klv = false;    // a KLV packet was written for this frame
  // The first frame after a splice (another place or time): no homography relates it to the
  // frame before, and no target track should cross it.
  bool cut = false;
  // An encoder repeat: the same picture as the frame before (targets in it have not moved).
  bool repeated = false;
  // The camera's horizontal field of view in this frame (a zoom changes it) and the gimbal's
  // pointing relative to the platform: azimuth clockwise from the nose, angle off nadir.
  double hfov_deg = 0;
  double gimbal_azimuth_deg = 0, gimbal_off_nadir_deg = 0;
};

// A burned-in overlay element (HUD text, reticle, logo): a box of image pixels that holds every
// pixel the element draws in any frame. Targets under it are hidden from view; a track on it is a
// false track by construction.
struct OverlayTruth {
  std::string kind;  // "hud-text", "reticle", "logo"
  int x = 0, y = 0, width = 0, height = 0;
  bool Contains(const Eigen::Vector2d& pixel) const {
    return pixel.x() >= x - 0.5 && pixel.y() >= y - 0.5 && pixel.x() < x + width - 0.5 &&
           pixel.y() < y + height - 0.5;
  }
};

struct TargetSampleTruth {
  Eigen::Vector2d ground_m{0, 0};
  // Where the target's centre projects (may lie off the image); through the lens distortion when
  // the video has one (then not exactly frame_from_ground times ground_m).
  Eigen::Vector2d image_px{0, 0};
  Eigen::Vector2d velocity_mps{0, 0};
  bool visible = false;  // centre inside the image and the frame not blank
};

struct TargetTruth {
  int id = 0;
  std::string target_class;  // "car", "van", "person"
  double length_m = 0, width_m = 0;
  std::vector<TargetSampleTruth> samples;  // one per frame, indexed like Truth::frames
};

struct Truth {
  nlohmann::json generator;  // scenario, seed and every option used
  double origin_latitude_deg = 0, origin_longitude_deg = 0, origin_height_m = 0;
  int width = 0, height = 0;
  double fx = 0, fy = 0, cx = 0, cy = 0;
  double fps = 0;
  uint64_t start_utc_us = 0;
  std::vector<FrameTruth> frames;
  std::vector<TargetTruth> targets;
  std::vector<OverlayTruth> overlays;  // empty: a clean image

  // Whether `pixel` lies on a burned-in overlay (any element).
  bool OnOverlay(const Eigen::Vector2d& pixel) const;
  // Frames at which a cut starts a new shot (FrameTruth::cut), in order.
  std::vector<int64_t> CutFrames() const;
};

nlohmann::json TruthToJson(const Truth& truth);
StatusOr<Truth> TruthFromJson(const nlohmann::json& json);

// Writes atomically (a temporary file renamed into place) so a crash never leaves half a file.
Status WriteTruth(const Truth& truth, const std::filesystem::path& path);
StatusOr<Truth> ReadTruth(const std::filesystem::path& path);

}  // namespace saker::sim
