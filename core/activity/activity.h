#pragma once

// Activity mapping: every moving target's track placed on the map through its frames' absolute
// homographies, with its attributes (average speed, direction of travel, visit), and the spatial
// index the GUI's click uses to find the nearest observation. Works on the mission's plain data,
// so a loaded mission can be re-mapped without reprocessing. Definitions in docs/activity.md.

#include "core/activity/confidence.h"
#include "core/mission/mission.h"
#include "core/util/status.h"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstdint>
#include <functional>
#include <optional>
#include <unordered_map>
#include <vector>

namespace saker::activity {

struct ActivityOptions {
  // Positions are smoothed over this window (centred moving average) before the path length and
  // the direction are measured, and the path is sampled at `speed_interval_s`, so that the
  // detector's frame-to-frame jitter does not inflate the length.
  double smoothing_s = 0.5;
  double speed_interval_s = 1.0;
  // A place seen again after the camera left it for longer than this starts a new visit.
  double visit_gap_s = 10;
  // Frames whose footprint is tested for the coverage behind visits: every frame, or every n-th
  // (the footprint moves little from one frame to the next).
  int coverage_stride = 5;
  // Confidence and plausibility (confidence.h), for tracks whose evidence is given.
  ConfidenceOptions confidence;

  Status Validate() const;
};

struct ActivitySummary {
  int64_t tracks_in = 0;
  int64_t tracks_out = 0;  // tracks with at least one placed observation
  // On frames without a map_from_frame, mapped beyond the horizon of the map's ground plane, or
  // in the part of their frame that is not mapped (above its sky line, or in ground seen more
  // than mission::kMaxScaleSpread times coarser than the frame's nearest: a low oblique view).
  int64_t observations_dropped = 0;
  int64_t tracks_implausible = 0;     // removed: average ground speed above max_speed_mps
  int64_t tracks_low_confidence = 0;  // removed: confidence below min_confidence
  int max_visit = 0;                  // the largest visit index given
  double time_s = 0;
};

// Fills the map position of every point of `tracks` (points on frames without a map_from_frame,
// or in the sky or distant ground of their frame, are dropped; tracks left empty are removed) and
// each track's start and end time, length, speed, speed_mps (geo-referenced missions), heading and
// visit, from the mission's frames (its `frames`, `map` and `source` width and height). Point frame
// indices must be those of `mission.frames`. Tracks whose average ground speed is impossible
// (geo-referenced missions, above options.confidence.max_speed_mps) are removed. With `evidence`
// (by track id), each track it holds gets its confidence (AssessTrack) and those below
// options.confidence.min_confidence are removed; the others keep theirs. InvalidArgument for bad
// options or a point on an unknown frame.
StatusOr<ActivitySummary> MapActivity(
    const mission::Mission& mission, std::vector<mission::ActivityTrack>* tracks,
    const ActivityOptions& options = {},
    const std::unordered_map<int64_t, TrackEvidence>* evidence = nullptr);

// The direction of travel of a map displacement, degrees clockwise from map north in [0, 360):
// north is +y on a geo-referenced map, -y (up the first key frame's image) otherwise.
double HeadingDegrees(const Eigen::Vector2d& displacement, bool geo_referenced);

// When the camera's footprint covered a map point: the visits (passes) over it, in time order.
class CoverageIndex {
 public:
  // Footprints of every `stride`-th placed frame of `mission`.
  CoverageIndex(const mission::Mission& mission, int stride);

  struct Interval {
    double start_s = 0;
    double end_s = 0;
  };
  // The visits over `point`: covered times joined when less than `gap_s` apart.
  std::vector<Interval> Visits(const Eigen::Vector2d& point, double gap_s) const;

 private:
  struct Footprint {
    double time_s = 0;
    Eigen::Matrix<double, 2, 4> corners;  // map, in order round the image
  };
  std::vector<Footprint> footprints_;  // by time
  double cell_ = 1;
  std::unordered_map<int64_t, std::vector<int32_t>> grid_;  // cell key -> footprints touching it
};

// The nearest track observation to a map point, for picking.
struct Pick {
  size_t track = 0;     // index into the tracks given to TrackIndex
  size_t point = 0;     // index into that track's points
  double distance = 0;  // map units
};

// Uniform-grid spatial index over every observation of a set of tracks (which must outlive it).
class TrackIndex {
 public:
  explicit TrackIndex(const std::vector<mission::ActivityTrack>* tracks);
  // The observation nearest `map_point` within `tolerance` map units; nullopt when none is.
  // `accept`, when given, filters tracks by index (for the GUI's time and speed filters).
  std::optional<Pick> Nearest(const Eigen::Vector2d& map_point, double tolerance,
                              const std::function<bool(size_t)>& accept = {}) const;
  size_t size() const { return count_; }

 private:
  const std::vector<mission::ActivityTrack>* tracks_;
  double cell_ = 1;
  size_t count_ = 0;
  std::unordered_map<int64_t, std::vector<std::pair<uint32_t, uint32_t>>> grid_;
};

}  // namespace saker::activity
