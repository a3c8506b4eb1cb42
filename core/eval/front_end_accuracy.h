#pragma once

// Accuracy of the front end against the simulator's truth (saker-cli evaluate).
//
// Homographies: for each frame with an estimate, the truth map from the previous frame is
// T = F_now * F_before^-1 (F = the truth frame_from_ground); the error is the distance between
// where the estimate and the truth send the four image corners, in pixels.
//
// Targets: a truth target is a *mover* in a frame when it is visible and its ground speed is at
// least `min_speed_mps`. Each *sighting* of a target counts: the frames it is in view, joined
// across absences of up to `max_sighting_gap_frames` (passing under a tree); a target that leaves
// the view and comes back on the aircraft's next pass is a new sighting, since telling that it is
// the same walker would take re-identification, which Saker does not attempt. Sightings with at
// least `min_mover_frames` mover frames are the ones to find. In each frame, detections
// (target-track observations) and truth movers are paired greedily by image distance within a gate:
// `gate_px`, or half the target's length in the image plus 4 px when larger (corners on a car's
// bumper are a detection of the car). A truth target is found when one detected track is paired
// with it in at least half of the sighting's mover frames
// ("follows it for most of its visible life"); a detected track is correct when it is paired with
// some truth target (mover or not) in at least half of its frames. Recall and precision of tracks
// follow, and per-frame ones from the pairs. Latency: from a found target's first mover frame to
// the first frame its track is paired.

#include "core/frontend/front_end.h"
#include "core/sim/truth.h"

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include <string>
#include <vector>

namespace saker::eval {

struct FrontEndEvaluationOptions {
  double min_speed_mps = 1.0;
  int min_mover_frames = 25;
  double gate_px = 12;
  int max_sighting_gap_frames = 50;  // out of view longer than this: a new sighting
};

struct HomographyAccuracy {
  int64_t frames = 0;  // frames with both an estimate and truth
  int64_t failed = 0;  // frames (after a segment's first) without an estimate
  double median_px = 0, mean_px = 0, p95_px = 0, max_px = 0;  // corner transfer error
  std::vector<double> errors_px;  // per frame counted in `frames`, to pool several videos
};

// How one truth sighting fared: the track paired with it most, and in how many of its frames.
struct SightingOutcome {
  int target_id = 0;
  std::string target_class;
  int64_t begin = 0, end = 0;  // frames [begin, end)
  int mover_frames = 0;
  bool found = false;
  double latency_s = 0;    // found: first mover frame to the first frame the finding track pairs
  int64_t best_track = 0;  // id of the track paired with it most (0: none)
  int best_track_frames = 0;
  int tracks_paired = 0;   // distinct tracks paired with it in the sighting
  int on_mask_frames = 0;  // mover frames in which it stood on the front end's overlay mask
};

// How one detected track fared: the truth target it was paired with most.
struct TrackOutcome {
  int64_t track_id = 0;
  int64_t first_frame = 0, last_frame = 0;
  int64_t observations = 0;
  bool from_features = true;  // false: found by change detection alone
  bool correct = false;
  int best_target = 0;  // truth target id paired with it most (0: none)
  int best_target_frames = 0;
  int64_t on_overlay = 0;  // observations on the truth's burned-in overlays
  Eigen::Vector2d first_position{0, 0};
};

struct DetectionAccuracy {
  int64_t truth_targets = 0;  // sightings of movers long enough to count
  int64_t found_targets = 0;
  int64_t detected_tracks = 0;  // confirmed target tracks
  int64_t correct_tracks = 0;
  double track_recall = 0, track_precision = 0;
  int64_t truth_mover_frames = 0;  // (target, frame) pairs
  int64_t detections = 0;          // (track, frame) observations
  int64_t paired = 0;              // pairs with a mover (frame recall's numerator)
  int64_t paired_detections = 0;   // detections paired with any target (frame precision's)
  double frame_recall = 0, frame_precision = 0;
  double median_latency_s = 0;
  // Per sighting and per track, for finding out why a target was missed or a track is false
  // (saker-cli evaluate --details).
  std::vector<SightingOutcome> sightings;
  std::vector<TrackOutcome> tracks;
};

// The front end's overlay masks (FrontEndResult::overlays) against the truth's overlay boxes,
// counted in mask cells (a cell is on an overlay when its centre is) and averaged over every frame
// of the video (a frame without a mask masks nothing).
struct OverlayMaskAccuracy {
  int64_t frames = 0;               // frames a mask applies to
  double masked_fraction = 0;       // of the image, masked
  double off_overlay_fraction = 0;  // of the image, masked but on no overlay (wrongly masked)
  // Of the truth overlays' cells, the fraction masked (1 without overlays in the truth).
  double overlay_covered = 1;
};

struct FrontEndEvaluation {
  HomographyAccuracy homography;
  OverlayMaskAccuracy overlay_mask;
  DetectionAccuracy targets;  // every class
  // Recall by class (precision needs every class: a correct track on a person is not a false
  // alarm of the vehicle detector).
  DetectionAccuracy vehicles;  // cars and vans only; precision not meaningful
  DetectionAccuracy people;    // people only; precision not meaningful
  int64_t key_frames = 0, chain_breaks = 0;
};

// Fails when the truth does not describe the video (frame count or size differ).
StatusOr<FrontEndEvaluation> EvaluateFrontEnd(const frontend::FrontEndResult& result,
                                              const sim::Truth& truth,
                                              const FrontEndEvaluationOptions& options = {});

nlohmann::json FrontEndEvaluationToJson(const FrontEndEvaluation& evaluation);
// With `details`, also the missed sightings and the false tracks, one a line.
std::string FrontEndEvaluationToText(const FrontEndEvaluation& evaluation, bool details = false);

}  // namespace saker::eval
