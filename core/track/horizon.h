#pragma once

// The horizon of a low oblique view (a small drone's camera looking ahead): above it the sky,
// whose clouds move with the camera's turns alone, and just below it ground so foreshortened and
// hazy that a pixel spans tens of metres. Neither follows the ground-plane homography of the
// nearer ground, so their features and changes are not evidence of ground motion or of movers.
//
// The sky is found in the image: the straight line (within `max_tilt_deg` of level) that best
// splits the frame into a smooth part above and a textured part below, scored on the local
// gradient of an image reduced to about 256 pixels across (where soft clouds are smooth and the
// ground's detail is not) by the gradient's variance between the two parts (Otsu's criterion). The
// split counts as a horizon only when the part above is much smoother than the part below
// (`max_texture_ratio`) and covers `min_sky_fraction` to `max_sky_fraction` of the frame. Smooth
// water below the horizon (a calm sea) can go with the sky: the line then tilts, and the water,
// whose waves would be taken for movers, is masked too. A view whose frame is all ground has no
// such line; a nadir view over smooth fields may, which is why the front end asks for the horizon
// in most of the recent frames before it masks anything (HorizonTracker), and where the frame's
// metadata puts the whole image on the ground, trusts that over the image.
//
// The mask is the part above the line, and `margin_fraction` of the frame's height below it: the
// distant ground (docs/front-end.md, "Oblique views").

#include "core/track/types.h"
#include "core/util/status.h"

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include <cstdint>
#include <deque>
#include <optional>

namespace saker::track {

struct HorizonOptions {
  bool enabled = true;
  double max_tilt_deg = 25;        // lines tried: within this of level (the camera's roll)
  double min_sky_fraction = 0.05;  // of the frame's area above the line
  double max_sky_fraction = 0.75;
  double max_texture_ratio = 0.35;  // the sky's mean gradient against the ground's, at most
  double margin_fraction = 0.05;    // of the frame's height, masked below the line too
  double window_s = 1.0;            // a horizon found in most of the frames of this window
  int min_window_frames = 3;        // ... and at least this many frames
  Status Validate() const;
};

// y = y_at_centre + slope * (x - centre_x) in full-resolution frame pixels (y down).
struct HorizonLine {
  double centre_x = 0;
  double y_at_centre = 0;
  double slope = 0;
  double YAt(double x) const { return y_at_centre + slope * (x - centre_x); }
};

// The horizon of `grey` (CV_8UC1), or nullopt when it shows none.
std::optional<HorizonLine> FindHorizon(const cv::Mat& grey, const HorizonOptions& options);

// The horizon over the recent frames: a line once it was found in more than half of the frames of
// the window (the latest line found), none otherwise. Frames are added in order.
class HorizonTracker {
 public:
  HorizonTracker(const HorizonOptions& options, const FrameRate& rate);

  // Finds the horizon of the next frame and returns the mask's line for it (nullopt: no mask).
  // `on_ground`: the frame's metadata puts its four corners on the ground with the ground's
  // horizon outside the image (GroundScale::FromCorners), so a line found in it is not the
  // horizon (a straight road with smooth fields beyond it, seen from above) and counts as none.
  std::optional<HorizonLine> Add(const cv::Mat& grey, bool on_ground = false);
  // The line of the latest frame added (nullopt: no mask), and whether `p` is masked by it.
  const std::optional<HorizonLine>& line() const { return line_; }
  // The horizon found in the latest frame itself, confirmed or not.
  const std::optional<HorizonLine>& found() const { return found_line_; }
  // Frames in the window the majority is taken over.
  int window_frames() const { return window_frames_; }
  bool Masks(const Eigen::Vector2d& p) const;
  // Masked rows below the line, pixels.
  double margin_px() const { return margin_px_; }
  // A chain break: what was seen before says nothing of the frames after.
  void Reset();

 private:
  HorizonOptions options_;
  int window_frames_ = 3;
  std::deque<bool> found_;  // the latest window's frames: horizon found
  std::optional<HorizonLine> latest_;
  std::optional<HorizonLine> found_line_;
  std::optional<HorizonLine> line_;
  double margin_px_ = 0;
};

}  // namespace saker::track
