#pragma once

// Screen-fixed overlays: burned-in HUD text (its digits changing every frame), reticles, static,
// rotating or pulsing logos, opaque or translucent, which stay where they are in the image while
// the ground moves under them. Left alone, their corners are taken for ground that does not
// follow the ground motion (targets) and their edges for change.
//
// The evidence is the change detector's (change_detector.h): once the frames before and after
// are warped onto a frame with the ground motion, the ground cancels and an overlay does not, so
// its pixels are marked as changed in the same place of the image frame after frame, whatever it
// does itself (stands still, turns, pulses, shows other digits). A mover crosses a place of the
// image in a few frames; an overlay stays. So the image is cut into cells of `cell_px`
// full-resolution pixels and each cell keeps the fraction of the recent frames (a window in
// seconds) in which it changed, counting only frames where it could be compared and the ground
// moved by at least `min_ground_shift_px` between the compared frames: over a hovering camera an
// overlay and the ground look alike, nothing can be concluded, and the previous mask is kept. A
// The feature tracks add their own evidence, at once rather than when the change detector answers,
// and also at the image's edges, which the change detector cannot compare while the camera moves
// (the frames before and after do not cover them): a match that stays put (it moved less than
// `fixed_fraction` of the ground's motion at it) where the ground moved at least
// `min_feature_flow_px` since the previous frame counts as a change of its cell, one that followed
// the ground as none. A cell becomes overlay once that fraction reaches `on_fraction` (after
// `min_evidence_s` of evidence) and stops being one when it falls below `off_fraction`; the mask is
// those cells, dilated by `dilate_cells`.
//
// The front end leaves the features on the mask out of the ground motion, the segmentation and
// the key frames, the change blobs on it out of the change tracks, and drops targets that lie on
// it in most of their frames (docs/front-end.md, "Overlays").

#include "core/track/change_detector.h"
#include "core/track/feature_tracker.h"
#include "core/track/horizon.h"
#include "core/track/target_tracks.h"
#include "core/track/types.h"
#include "core/util/byte_io.h"
#include "core/util/status.h"

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include <cstdint>
#include <functional>
#include <optional>
#include <vector>

namespace saker::track {

struct OverlayOptions {
  // On by default: on the corpus's clean conditions it changes no figure by more than one track
  // (docs/accuracy.md, "Overlays"), and on video with overlays it removes their tracks.
  bool enabled = true;
  double window_s = 8;             // a cell's change fraction is over this much recent evidence
  int min_window_frames = 15;      // ... and at least this many frames
  double min_evidence_s = 4;       // a cell is judged once it has this much evidence
  int min_evidence_frames = 5;     // ... and at least this many frames
  double min_ground_shift_px = 3;  // ground motion between the compared frames, full resolution
  double on_fraction = 0.8;        // a cell changed in this fraction of its frames is overlay
  double off_fraction = 0.2;       // an overlay cell below this fraction is not any more
  double min_feature_flow_px = 1;  // ground motion at a feature, one frame, for its evidence
  double fixed_fraction = 0.2;     // a feature moving less than this fraction of it stays put
  // Before the mask knows an overlay (its evidence takes seconds, and none comes while the ground
  // moves less than min_feature_flow_px a frame), the features that kept still in the image over
  // the last `still_window_s` while the median feature moved at least `still_min_flow_px` (less
  // than fixed_fraction of that median, and less than `still_max_px`) are left out of the ground
  // motion (StillFeatures), judged over windows of down to `still_min_window_frames` for young
  // tracks. The ground's features about the centre of an orbit's turn or a zoom move little too,
  // and go with them: over one frame of an orbit turning 0.24 degrees a frame, those within 95 px
  // of the centre move less than 0.4 px (within 10 px over the whole window), a few in a hundred
  // of the frame's. Chosen on the tuning seeds against 0.15 px, which keeps more of those but
  // also more of an overlay's corners that jitter with the codec (docs/accuracy.md, session 34).
  double still_window_s = 0.5;
  int still_min_window_frames = 1;
  double still_min_flow_px = 1;
  double still_max_px = 0.5;
  int cell_px = 8;       // mask cell side, full-resolution pixels
  int dilate_cells = 2;  // the mask is grown by this many cells
  // A target whose observations lie on the mask in at least this fraction of its frames is
  // dropped (1 turns it off).
  double max_target_fraction = 0.5;
  // A target that stays put in the image (at least `fixed_share` of its observations within
  // `fixed_radius_px` of their median, or within `fixed_ground_fraction` of the ground's motion
  // there when that is more: the change blob of a line of HUD text drifts and jumps by a few
  // pixels as other digits change) while the ground under it moves by `fixed_min_ground_px` in all
  // is screen-fixed: it is judged on the mask grown by `fixed_near_cells`, so that the end of a
  // text line the evidence has not covered yet (digits that changed, the image's edge) goes with
  // the rest of it. A car under the gimbal's cross-hair is screen-fixed too, and stays unless it
  // is beside the mask.
  double fixed_radius_px = 3;
  double fixed_ground_fraction = 0.15;
  double fixed_share = 0.8;
  double fixed_min_ground_px = 12;
  int fixed_near_cells = 3;
  Status Validate() const;
};

// An overlay mask and the frames it applies to (a part of one chain segment).
struct OverlayMask {
  int64_t first_frame = 0;
  int64_t last_frame = 0;
  int cell_px = 8;  // full-resolution pixels per cell
  cv::Mat cells;    // CV_8U, non-zero on the overlay; cell (x, y) covers pixels [x, x+1) * cell_px
  // Whether the full-resolution pixel `p` lies on the overlay.
  bool Contains(const Eigen::Vector2d& p) const;
  // Whether a cell within `near_cells` cells of p's (a square around it) is on the overlay.
  bool ContainsNear(const Eigen::Vector2d& p, int near_cells) const;
  // The fraction of the image the mask covers.
  double Coverage() const;
};

// Whether `target` lies on the overlay masks a run handed out (`masks`, in frame order, none
// across a chain break) in at least `max_fraction` of its observations. An observation is judged
// by the mask of its frame and every later one of its chain segment: the evidence takes seconds to
// gather and grows, and an overlay is there from the start, so the tracks its corners made before
// the mask covered them are overlay tracks too. `breaks`: the frames that start a new chain
// segment, increasing.
// `near_cells`: an observation within this many cells of the mask counts as on it (0: on the
// mask's own cells only).
bool OnOverlayMasks(const TargetTrack& target, const std::vector<OverlayMask>& masks,
                    const std::vector<int64_t>& breaks, double max_fraction, int near_cells = 0);

// Whether `target` stayed put in the image while the ground moved by at least `min_ground_px`
// there: at least `share` of its observations within `radius_px` of their median position, or
// within `ground_fraction` of the ground's motion when that is more (the blob of a line of HUD
// text drifts by a few pixels as its digits change).
// `ground_shift_px(first_frame, last_frame, p)` is the ground's motion at image point p summed
// over the frames after `first_frame` up to `last_frame`.
bool ScreenFixed(
    const TargetTrack& target, double radius_px, double share, double ground_fraction,
    double min_ground_px,
    const std::function<double(int64_t, int64_t, const Eigen::Vector2d&)>& ground_shift_px);

// The features of `matches` (the latest frame's) that kept still in the image while the others
// moved: each is judged over the longest of the last `window_frames` frames, their half, and so
// on down to `min_window_frames`, that it was tracked through and over which the median motion of
// the matches tracked that long (at least 8 of them) is at least `min_flow_px`; it kept still
// when it moved less than `fraction` of that median and less than `max_px`. Young tracks (a
// segment's first frames, a corner found on a digit that just changed) are judged over the shorter
// windows. Screen-fixed overlays (HUD text, a reticle) keep still from their first frames; the
// centre of the camera's turn or zoom does too, but few of the ground's features lie there. Ordered
// by id.
std::vector<FeatureTrackId> StillFeatures(const FeatureTracker& tracker,
                                          const std::vector<Correspondence>& matches,
                                          int window_frames, int min_window_frames,
                                          double min_flow_px, double fraction, double max_px);

class OverlayDetector {
 public:
  // `rate`: the video's, for the windows in seconds.
  OverlayDetector(const OverlayOptions& options, FrameRate rate);

  // One answer of the change detector, whose frames are `baseline_frames` apart. Unanswered ones
  // are ignored. `sky`: the edge of the frame's sky mask (a low oblique view's horizon), above
  // which nothing is learnt: still clouds keep their place in the image as an overlay would.
  void AddChange(const ChangeFrame& change, int baseline_frames,
                 const std::optional<HorizonLine>& sky = std::nullopt);
  // The feature matches of a frame of `frame_size` pixels and the ground motion into it from the
  // previous frame; `sky` as for AddChange.
  void AddFeatures(const std::vector<Correspondence>& matches,
                   const Eigen::Matrix3d& current_from_previous, const cv::Size& frame_size,
                   const std::optional<HorizonLine>& sky = std::nullopt);

  // The current mask (cells of `options.cell_px`; empty before any evidence).
  const OverlayMask& mask() const { return mask_; }
  bool Contains(const Eigen::Vector2d& p) const { return mask_.Contains(p); }
  // Counts the changes of the mask, so that a caller sees when it changed.
  int64_t version() const { return version_; }
  // Whether `target` lies on the mask in at least `max_target_fraction` of its observations.
  bool Covers(const TargetTrack& target) const;

  // The evidence and the mask, so that a resumed run goes on exactly from the latest frame.
  // RestoreState is false when `in` is malformed.
  void SaveState(ByteWriter* out) const;
  bool RestoreState(ByteReader* in);

 private:
  void Resize(const cv::Size& full);
  // One frame of evidence for the cell at (x, y): whether it changed.
  void Add(int x, int y, bool changed);
  void UpdateMask();

  OverlayOptions options_;
  int window_frames_, min_evidence_frames_;
  cv::Size full_size_;
  cv::Mat fraction_;  // CV_32F per cell: the change fraction over the window
  cv::Mat count_;     // CV_32F per cell: frames of evidence, at most the window
  cv::Mat on_;        // CV_8U per cell: overlay (before dilation)
  OverlayMask mask_;
  int64_t version_ = 0;
  cv::Mat changed_, valid_;  // scratch: the answer's masks at cell size
};

}  // namespace saker::track
