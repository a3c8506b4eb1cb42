#include "core/eval/video_evaluation.h"

#include "core/pipeline/stages.h"

#include <string>
#include <utility>

namespace saker::eval {

namespace {

// `status` with the video named first, as saker-cli reports a failure after the video was read.
Status NamingVideo(const std::string& video, const Status& status) {
  return Status(status.code(), video + ": " + status.message());
}

}  // namespace

StatusOr<VideoEvaluation> EvaluateVideo(const std::string& video, const sim::Truth& truth,
                                        const VideoEvaluationOptions& options, JobContext* job) {
  // The engine's stages as a job runs them, up to the activity, without a mission file.
  pipeline::StageOptions stages;
  stages.front_end = options.front_end;
  stages.mosaic = options.mosaic;
  stages.activity = options.activity;
  pipeline::StageHooks hooks;
  hooks.last = pipeline::Stage::kActivity;
  pipeline::MissionRun run;
  const Status ran = pipeline::RunStages(video, stages, hooks, job, &run);
  // The front end's errors name the video already.
  if (!ran.ok() && run.failed == pipeline::Stage::kFrontEnd) return ran;
  VideoEvaluation e;
  if (ran.ok() || run.mission.progress.front_end) {
    StatusOr<FrontEndEvaluation> detection = EvaluateFrontEnd(run.front, truth, options.evaluation);
    if (!detection.ok()) return NamingVideo(video, detection.status());
    e.detection = std::move(*detection);
  }
  if (!ran.ok()) {
    // The mosaic stage names the video in its errors, but for a cancellation.
    if (run.failed == pipeline::Stage::kMosaic && ran.code() != StatusCode::kCancelled) return ran;
    return NamingVideo(video, ran);
  }
  if (!run.mosaic) return NamingVideo(video, run.no_mosaic);  // no key frame: no map
  StatusOr<MosaicAccuracy> mosaic_accuracy = EvaluateMosaic(*run.mosaic, truth);
  if (!mosaic_accuracy.ok()) return NamingVideo(video, mosaic_accuracy.status());
  e.mosaic = std::move(*mosaic_accuracy);
  StatusOr<ActivityAccuracy> activity =
      EvaluateActivity(run.mission, truth, options.activity.visit_gap_s);
  if (!activity.ok()) return NamingVideo(video, activity.status());
  e.activity = std::move(*activity);
  if (options.experiments) {
    if (auto experiment = RunMetadataExperiment(*run.mosaic, truth); experiment.ok()) {
      e.metadata_experiment = std::move(*experiment);
    }
    if (auto experiment = RunDecompositionExperiment(
            *run.mosaic, truth, options.mosaic.decomposition, options.mosaic.adjustment);
        experiment.ok()) {
      e.decomposition_experiment = std::move(*experiment);
    }
  }
  e.front_end = std::move(run.front);
  return e;
}

nlohmann::json VideoEvaluationToJson(const VideoEvaluation& e) {
  nlohmann::json j = FrontEndEvaluationToJson(e.detection);
  j["polarity_switches"] = e.front_end.polarity_switches;
  j["mosaic"] = MosaicAccuracyToJson(e.mosaic);
  j["activity"] = ActivityAccuracyToJson(e.activity);
  if (const auto& m = e.metadata_experiment) {
    j["metadata_experiment"] = {{"start_error_m", m->start_error_m},
                                {"metadata_key_frames", m->metadata_key_frames},
                                {"metadata_sigma_m", m->metadata_sigma_m},
                                {"without_metadata_rms_m", m->without_metadata.rms_m},
                                {"without_metadata_max_m", m->without_metadata.max_m},
                                {"with_metadata_rms_m", m->with_metadata.rms_m},
                                {"with_metadata_max_m", m->with_metadata.max_m}};
  }
  if (e.decomposition_experiment) {
    j["decomposition_experiment"] = DecompositionExperimentToJson(*e.decomposition_experiment);
  }
  return j;
}

std::string VideoEvaluationToText(const VideoEvaluation& e, bool details) {
  std::string text = FrontEndEvaluationToText(e.detection, details);
  if (!e.front_end.polarity_switches.empty()) {
    text += "Polarity switches (thermal), inverted back: at frame";
    text += e.front_end.polarity_switches.size() > 1 ? "s" : "";
    for (int64_t f : e.front_end.polarity_switches) text += " " + std::to_string(f);
    text += "\n";
  }
  text += MosaicAccuracyToText(e.mosaic);
  text += ActivityAccuracyToText(e.activity);
  if (e.metadata_experiment) text += MetadataExperimentToText(*e.metadata_experiment);
  if (e.decomposition_experiment) {
    text += DecompositionExperimentToText(*e.decomposition_experiment);
  }
  return text;
}

}  // namespace saker::eval
