#include "app/cli_evaluate.h"

#include "app/cli_mosaic.h"
#include "core/frontend/evaluate.h"
#include "core/frontend/front_end.h"
#include "core/mosaic/evaluate.h"
#include "core/mosaic/mosaic_builder.h"
#include "core/pipeline/evaluate.h"
#include "core/pipeline/process.h"
#include "core/sim/truth.h"

#include <filesystem>
#include <iostream>

namespace saker::app {

struct EvaluateCommand::State {
  CLI::App* command = nullptr;
  std::string video;
  std::filesystem::path truth;
  bool json = false;
  bool details = false;
  bool no_metadata = false;
  bool no_change = false;
  std::string adjust = "decomposed";
  mosaic::DecompositionOptions decomposition;
  frontend::EvaluationOptions evaluation;
};

EvaluateCommand::EvaluateCommand(CLI::App& app) : state_(std::make_unique<State>()) {
  State& s = *state_;
  s.command = app.add_subcommand(
      "evaluate",
      "Run the engine on a simulated video and print its accuracy against the simulator's truth:\n"
      "frame-to-frame homography error (image-corner transfer, pixels) and moving-target "
      "detection\n"
      "(recall and precision of target tracks and per frame, detection latency); the mosaic's\n"
      "loop closures and the key frames' corner error before and after bundle adjustment; the\n"
      "adjustment's nodes, arcs and time; the in-between frames' corner error; and two of the\n"
      "paper's experiments (metadata, graph decomposition). See docs/front-end.md and\n"
      "docs/mosaic.md for the definitions.");
  s.command->add_option("VIDEO", s.video, "Simulated video (saker-cli simulate)")->required();
  s.command->add_option("--truth", s.truth, "Its truth file (default: VIDEO with .truth.json)");
  s.command->add_flag("--json", s.json, "Print the figures as JSON");
  s.command->add_flag("--details", s.details,
                      "Also list the missed target sightings and the false tracks, with the track "
                      "or target each was paired with most");
  s.command->add_flag("--no-metadata", s.no_metadata,
                      "Build the mosaic without the metadata corners");
  s.command->add_option("--gate", s.evaluation.gate_px, "Pairing distance, pixels")
      ->capture_default_str();
  s.command
      ->add_option("--min-speed", s.evaluation.min_speed_mps,
                   "Slowest truth target counted as moving, m/s")
      ->capture_default_str();
  s.command
      ->add_option("--sighting-gap", s.evaluation.max_sighting_gap_frames,
                   "Frames a target may be out of view within one sighting; longer, and it is "
                   "counted again when it comes back")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  AddAdjustOption(s.command, &s.adjust);
  s.command
      ->add_option("--max-arc-links", s.decomposition.max_arc_links,
                   "Decomposed: longest arc, in sequential links")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  s.command
      ->add_option("--cross-link-spacing", s.decomposition.cross_link_spacing,
                   "Decomposed: keep one cross-link per loop closure, leaving out those within "
                   "this many key frames of a stronger one at both ends (0: keep all)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  s.command->add_flag("--no-change-detection", s.no_change,
                      "Run the front end without change detection (feature tracks only)");
}

EvaluateCommand::~EvaluateCommand() = default;
bool EvaluateCommand::parsed() const { return state_->command->parsed(); }

int EvaluateCommand::Run() const {
  const State& s = *state_;
  std::filesystem::path truth_path = s.truth;
  if (truth_path.empty())
    truth_path = std::filesystem::path(s.video).replace_extension(".truth.json");
  StatusOr<sim::Truth> truth = sim::ReadTruth(truth_path);
  if (!truth.ok()) {
    std::cerr << "saker-cli: " << truth.status().message() << "\n";
    return 1;
  }
  frontend::FrontEndOptions front_end;
  front_end.change.enabled = !s.no_change;
  StatusOr<frontend::FrontEndResult> result = frontend::RunFrontEnd(s.video, front_end);
  if (!result.ok()) {
    std::cerr << "saker-cli: " << result.status().message() << "\n";
    return 1;
  }
  StatusOr<frontend::Evaluation> evaluation = frontend::Evaluate(*result, *truth, s.evaluation);
  if (!evaluation.ok()) {
    std::cerr << "saker-cli: " << s.video << ": " << evaluation.status().message() << "\n";
    return 1;
  }
  mosaic::MosaicOptions mosaic_options;
  mosaic_options.use_metadata = !s.no_metadata;
  mosaic_options.adjust_mode = *mosaic::ParseAdjustmentMode(s.adjust);
  mosaic_options.decomposition = s.decomposition;
  StatusOr<mosaic::MosaicResult> built = mosaic::BuildMosaic(*result, mosaic_options);
  if (!built.ok()) {
    std::cerr << "saker-cli: " << s.video << ": " << built.status().message() << "\n";
    return 1;
  }
  StatusOr<mosaic::MosaicAccuracy> mosaic_accuracy = mosaic::EvaluateMosaic(*built, *truth);
  if (!mosaic_accuracy.ok()) {
    std::cerr << "saker-cli: " << s.video << ": " << mosaic_accuracy.status().message() << "\n";
    return 1;
  }
  activity::ActivityOptions activity_options;
  StatusOr<mission::Mission> mission = pipeline::MissionFromRun(*result, *built, activity_options);
  if (!mission.ok()) {
    std::cerr << "saker-cli: " << s.video << ": " << mission.status().message() << "\n";
    return 1;
  }
  StatusOr<pipeline::ActivityAccuracy> activity_accuracy =
      pipeline::EvaluateActivity(*mission, *truth, activity_options.visit_gap_s);
  if (!activity_accuracy.ok()) {
    std::cerr << "saker-cli: " << s.video << ": " << activity_accuracy.status().message() << "\n";
    return 1;
  }
  StatusOr<mosaic::MetadataExperiment> experiment = mosaic::RunMetadataExperiment(*built, *truth);
  StatusOr<mosaic::DecompositionExperiment> decomposition = mosaic::RunDecompositionExperiment(
      *built, *truth, s.decomposition, mosaic_options.adjustment);
  if (s.json) {
    nlohmann::json j = frontend::EvaluationToJson(*evaluation);
    j["mosaic"] = mosaic::MosaicAccuracyToJson(*mosaic_accuracy);
    j["activity"] = pipeline::ActivityAccuracyToJson(*activity_accuracy);
    if (experiment.ok()) {
      j["metadata_experiment"] = {{"start_error_m", experiment->start_error_m},
                                  {"metadata_key_frames", experiment->metadata_key_frames},
                                  {"metadata_sigma_m", experiment->metadata_sigma_m},
                                  {"without_metadata_rms_m", experiment->without_metadata.rms_m},
                                  {"without_metadata_max_m", experiment->without_metadata.max_m},
                                  {"with_metadata_rms_m", experiment->with_metadata.rms_m},
                                  {"with_metadata_max_m", experiment->with_metadata.max_m}};
    }
    if (decomposition.ok()) {
      j["decomposition_experiment"] = mosaic::DecompositionExperimentToJson(*decomposition);
    }
    std::cout << j.dump(2) << "\n";
  } else {
    std::cout << frontend::EvaluationToText(*evaluation, s.details);
    std::cout << mosaic::MosaicAccuracyToText(*mosaic_accuracy);
    std::cout << pipeline::ActivityAccuracyToText(*activity_accuracy);
    if (experiment.ok()) std::cout << mosaic::MetadataExperimentToText(*experiment);
    if (decomposition.ok()) std::cout << mosaic::DecompositionExperimentToText(*decomposition);
  }
  return 0;
}

}  // namespace saker::app
