#pragma once

// Plausibility and confidence of a mapped target track (docs/activity.md, "Confidence and
// plausibility").
//
// There is no class label, so a track is judged on what any real ground mover shows and a false
// alarm (parallax, a flickering texture, a tracker that jumped between targets) does not:
//
//   seen     = 1 - exp(-duration_s / seen_scale_s)
//              how long it was seen, in seconds (not frames: the same footage at 5 and 25 fps
//              scores alike). 2 s: 0.63, 5 s: 0.92.
//   motion   = jitter * steadiness, from straight-line fits of the map path: the track is cut
//              into pieces of fit_window_s (1 s; a last piece shorter than half that joins the
//              one before) and each piece of at least 3 observations gets a least-squares fit
//              position(t) = a + v t.
//              jitter     = m^2 / (m^2 + r^2): r^2 is the observations' scatter about their fits
//                           (residual sum of squares over n - 2 degrees of freedom per axis,
//                           pooled), m the distance the track moves in one window (|v| x
//                           fit_window_s, |v|^2 averaged over the pieces with the fits' own noise,
//                           2 sigma^2 / sum (t - mean t)^2, subtracted). Both are unbiased at any
//                           frame rate, and the ratio is scale-free: a track whose positions
//                           scatter as much as it moves in a second scores 0.5.
//              steadiness = 1 - reversals / turns: a turn is a pair of consecutive pieces whose
//                           velocities are both significant (|v| over twice its standard error),
//                           a reversal one whose directions differ by more than 90 degrees.
//              With no piece of 3 observations motion is unmeasured and counts 0.5 (no evidence
//              either way).
//   support  = 1 - (1 - features) * (1 - change)
//              features = 1 - exp(-mean supporting features per observation / features_scale)
//              change   = the fraction of the observations the change detector looked at where
//                         it saw a change (0 when it looked at none)
//              either detector supporting the track is evidence; the product is the chance both
//              missed it.
//   speed    = 1 up to plausible_speed_mps, falling linearly to 0 at max_speed_mps, when the map
//              is in metres (geo-referenced); 1 otherwise (the scale is unknown).
//
//   confidence = cbrt(seen * motion * support) * speed
//
// The geometric mean lets no factor make up for another that is zero and keeps the result from
// shrinking merely because there are three of them. A track whose average ground speed exceeds
// max_speed_mps is implausible: no ground vehicle drives that fast, so it is not reported (the
// activity stage drops it and counts it).

#include "core/mission/mission.h"
#include "core/util/status.h"

#include <cstdint>
#include <vector>

namespace saker::activity {

struct ConfidenceOptions {
  double seen_scale_s = 2;  // seconds seen for a `seen` factor of 1 - 1/e (0.63)
  // Pieces of the path fitted with straight lines for the motion factor: long enough for a few
  // observations at any frame rate, short enough that a vehicle's path is straight within one.
  double fit_window_s = 1;
  // Mean supporting features per observation for a `features` factor of 0.63: a car carries a
  // few corners, a single-feature track is the tracker's weakest kind.
  double features_scale = 2;
  // Ground speeds, metres per second, on geo-referenced maps: up to plausible_speed_mps (144
  // km/h, fast motorway traffic) a speed says nothing against a track; above max_speed_mps (252
  // km/h) no ground vehicle goes and the track is not reported.
  double plausible_speed_mps = 40;
  double max_speed_mps = 70;
  // Tracks whose confidence is below this are not reported either (saker-cli process
  // --min-confidence); 0 keeps every plausible one.
  double min_confidence = 0;

  Status Validate() const;  // InvalidArgument naming the field and its limit
};

// The front end's evidence for one track, counted over its observations.
struct TrackEvidence {
  int64_t observations = 0;
  int64_t feature_sightings = 0;  // supporting features, summed over the observations
  int64_t looked = 0;             // observations the change detector compared
  int64_t changed = 0;            // ... of them, where it saw a change
};

// Each factor of the confidence, in [0, 1], and the result.
struct ConfidenceFactors {
  double seen = 0;
  double jitter = 0;
  double steadiness = 0;
  double motion = 0;  // jitter * steadiness
  double features = 0;
  double change = 0;
  double support = 0;
  double speed = 1;
  double confidence = 0;
  bool plausible = true;  // false: the average ground speed exceeds max_speed_mps
};

// The confidence of `track`, mapped by MapActivity (map positions, times, start, end and
// speed_mps filled in), from its `evidence`.
ConfidenceFactors AssessTrack(const mission::ActivityTrack& track, const TrackEvidence& evidence,
                              const ConfidenceOptions& options);

// Whether `track` is shown or exported at a minimum confidence of `min_confidence`: every track
// at 0; above it, a track whose confidence is known and at least that (a threshold asks for
// evidence, and a track of unknown confidence has none on record).
bool PassesConfidence(const mission::ActivityTrack& track, double min_confidence);

// How many tracks are of high (>= 0.8), medium (>= 0.5), low and unknown confidence, for
// summaries (saker-cli info).
struct ConfidenceSpread {
  int64_t high = 0;
  int64_t medium = 0;
  int64_t low = 0;
  int64_t unknown = 0;
};
ConfidenceSpread SpreadOf(const std::vector<mission::ActivityTrack>& tracks);

}  // namespace saker::activity
