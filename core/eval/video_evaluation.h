#pragma once

// The engine against the simulator's truth.
//
// EvaluateVideo runs the whole engine on a simulated video as `saker-cli evaluate` does (the front
// end, the mosaic, the activity of the mission they make) and measures each against the truth;
// the accuracy benchmark (docs/accuracy.md) runs it on every case of its corpus.

#include "core/activity/activity.h"
#include "core/eval/activity_accuracy.h"
#include "core/eval/front_end_accuracy.h"
#include "core/eval/mosaic_accuracy.h"
#include "core/frontend/front_end.h"
#include "core/mission/mission.h"
#include "core/mosaic/mosaic_builder.h"
#include "core/sim/truth.h"
#include "core/util/job_context.h"
#include "core/util/status.h"

#include <nlohmann/json.hpp>

#include <optional>
#include <string>
#include <vector>

namespace saker::eval {

struct VideoEvaluationOptions {
  frontend::FrontEndOptions front_end;
  FrontEndEvaluationOptions evaluation;
  mosaic::MosaicOptions mosaic;
  activity::ActivityOptions activity;
  // Also the paper's metadata and graph decomposition experiments (core/eval/mosaic_accuracy.h),
  // which adjust the mosaic's link graph again several times.
  bool experiments = true;
};

struct VideoEvaluation {
  frontend::FrontEndResult front_end;  // the run itself, for measures of one's own
  FrontEndEvaluation detection;        // homographies, target tracks, key frames and breaks
  MosaicAccuracy mosaic;
  ActivityAccuracy activity;
  // With `experiments`, when the mosaic allows them (nullopt otherwise, as the CLI prints them).
  std::optional<MetadataExperiment> metadata_experiment;
  std::optional<DecompositionExperiment> decomposition_experiment;
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

}  // namespace saker::eval
