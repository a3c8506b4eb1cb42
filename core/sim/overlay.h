#pragma once

// Burned-in overlays, as real full-motion video carries them: telemetry text whose numbers change
// every frame (the ground station's HUD), a reticle at the image centre and a corner logo, static
// or animated (rotating, pulsing). They are drawn after the sensor's noise, crisp, as a ground
// station keys them into the picture, and stay fixed in the image while the ground moves under
// them: the detector must not take them for ground or for targets.
//
// The truth records each element as a box of image pixels that holds every pixel it draws in any
// frame (OverlayTruth).

#include "core/sim/truth.h"
#include "core/util/status.h"

#include <opencv2/core/mat.hpp>

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace saker::sim {

enum class LogoMotion { kNone, kStatic, kRotating, kPulsing };
const char* LogoMotionName(LogoMotion motion);  // "none", "static", "rotating", "pulsing"
std::optional<LogoMotion> ParseLogoMotion(std::string_view name);

struct OverlayOptions {
  bool hud_text = false;  // two lines of telemetry (time, frame, position, heading) top and bottom
  bool reticle = false;   // a cross with a gap at the image centre
  LogoMotion logo = LogoMotion::kNone;  // a badge in the top right corner
  double logo_turn_deg_per_s = 45;      // rotating logo: its turn rate
  double logo_pulse_hz = 0.5;           // pulsing logo: brightness cycles per second
  // 1: opaque; below 1 the overlay is blended over the picture (semi-transparent symbology).
  double opacity = 1.0;

  bool any() const { return hud_text || reticle || logo != LogoMotion::kNone; }
  Status Validate() const;
};

// What the HUD text says in one frame (the simulator fills it from the frame's truth).
struct HudTelemetry {
  uint64_t utc_us = 0;
  int64_t frame_index = 0;
  double latitude_deg = 0, longitude_deg = 0, height_m = 0;
  double heading_deg = 0;
  double hfov_deg = 0;
};

class OverlayPainter {
 public:
  OverlayPainter(const OverlayOptions& options, int width, int height);

  // The boxes of the elements (truth), empty without overlays.
  const std::vector<OverlayTruth>& regions() const { return regions_; }

  // Draws the overlay of the frame at `time_s` into `bgr` (CV_8UC3 of the painter's size).
  void Paint(const HudTelemetry& telemetry, double time_s, cv::Mat* bgr) const;

 private:
  // The HUD's two lines for a frame.
  std::pair<std::string, std::string> HudLines(const HudTelemetry& telemetry) const;
  void PaintLogo(double time_s, cv::Mat* layer, cv::Mat* alpha) const;

  OverlayOptions options_;
  int width_, height_;
  double font_scale_;
  int font_thickness_;
  cv::Point top_line_, bottom_line_;  // text origins
  cv::Point logo_centre_;
  int logo_radius_ = 0;
  cv::Point reticle_centre_;
  int reticle_arm_ = 0, reticle_gap_ = 0;
  std::vector<OverlayTruth> regions_;
};

}  // namespace saker::sim
