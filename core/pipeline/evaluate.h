#pragma once

// The engine against the simulator's truth.
//
// EvaluateVideo runs the whole engine on a simulated video as `saker-cli evaluate` does (the front
// end, the mosaic, the activity of the mission they make) and measures each against the truth;
// the accuracy benchmark (docs/accuracy.md) runs it on every case of its corpus.
//
// EvaluateActivity: the activity attributes of a processed mission. Each track is matched to the
// truth target it follows, then its average speed, direction of travel and visit are compared with
// the truth's, and picking at the truth's position is checked (docs/activity.md, "Accuracy").

#include "core/activity/activity.h"
#include "core/frontend/evaluate.h"
#include "core/frontend/front_end.h"
#include "core/mission/mission.h"
#include "core/mosaic/evaluate.h"
#include "core/mosaic/mosaic_builder.h"
#include "core/sim/truth.h"
#include "core/util/job_context.h"
#include "core/util/status.h"

#include <nlohmann/json.hpp>

#include <optional>
#include <string>
#include <vector>

namespace saker::pipeline {

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

// The q-quantile (q in [0, 1]) that the activity figures quote: the element of rank
// round(q (n - 1)) in increasing order; 0 for no values. Exposed so that figures pooled over
// several missions are the same statistic as one mission's.
double ActivityQuantile(std::vector<double> values, double q);

struct VideoEvaluationOptions {
  frontend::FrontEndOptions front_end;
  frontend::EvaluationOptions evaluation;
  mosaic::MosaicOptions mosaic;
  activity::ActivityOptions activity;
  // Also the paper's metadata and graph decomposition experiments (core/mosaic/evaluate.h),
  // which adjust the mosaic's link graph again several times.
  bool experiments = true;
};

struct VideoEvaluation {
  frontend::FrontEndResult front_end;  // the run itself, for measures of one's own
  frontend::Evaluation detection;      // homographies, target tracks, key frames and breaks
  mosaic::MosaicAccuracy mosaic;
  ActivityAccuracy activity;
  // With `experiments`, when the mosaic allows them (nullopt otherwise, as the CLI prints them).
  std::optional<mosaic::MetadataExperiment> metadata_experiment;
  std::optional<mosaic::DecompositionExperiment> decomposition_experiment;
};

// The front end, the mosaic and the mission's activity on `video` against its `truth`. Errors
// name the video: it cannot be read, or the truth does not describe it. `job` may cancel the
// front end and the mosaic.
StatusOr<VideoEvaluation> EvaluateVideo(const std::string& video, const sim::Truth& truth,
                                        const VideoEvaluationOptions& options,
                                        JobContext* job = nullptr);

// What `saker-cli evaluate` prints (`details`: the missed sightings and false tracks too).
nlohmann::json VideoEvaluationToJson(const VideoEvaluation& evaluation);
std::string VideoEvaluationToText(const VideoEvaluation& evaluation, bool details);

}  // namespace saker::pipeline
