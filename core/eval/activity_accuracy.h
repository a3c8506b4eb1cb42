#pragma once

// The activity attributes of a processed mission against the simulator's truth. Each track is
// matched to the truth target it follows, then its average speed, direction of travel and visit
// are compared with the truth's, and picking at the truth's position is checked
// (docs/activity.md, "Accuracy").

#include "core/mission/mission.h"
#include "core/sim/truth.h"
#include "core/util/status.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <string>
#include <vector>

namespace saker::eval {

struct ActivityAccuracy {
  int64_t tracks = 0;          // tracks in the mission
  int64_t matched = 0;         // following one truth target on most of their observations
  int64_t compared_speed = 0;  // matched, geo-referenced, truth moving
  double speed_median_error_mps = 0, speed_p90_error_mps = 0;
  double speed_median_relative = 0;  // |error| / truth speed
  double speed_p90_relative = 0;
  std::vector<double> speed_relative_errors;  // per compared track, to pool several missions
  int64_t compared_direction = 0;             // matched, displaced at least 5 m in the truth
  double direction_median_error_deg = 0, direction_p90_error_deg = 0;
  int64_t compared_visit = 0;
  double visit_agreement = 0;  // fraction of matched tracks with the truth's visit index
  int64_t picks = 0;           // one per matched track: at the truth position of its middle
                               // observation, through that frame's homography
  // Fraction returning the same target, within 0.5 s and 12 px (among the tracks seen within
  // 0.5 s of that moment, as with the GUI's time filter: other targets cross the same places).
  double pick_accuracy = 0;
  double pick_median_us = 0;  // time per pick, microseconds
};

// InvalidArgument when the truth does not describe the mission's video (frame count, size).
StatusOr<ActivityAccuracy> EvaluateActivity(const mission::Mission& mission,
                                            const sim::Truth& truth, double visit_gap_s);

nlohmann::json ActivityAccuracyToJson(const ActivityAccuracy& accuracy);
std::string ActivityAccuracyToText(const ActivityAccuracy& accuracy);

}  // namespace saker::eval
