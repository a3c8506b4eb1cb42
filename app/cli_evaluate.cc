#include "app/cli_evaluate.h"

#include "app/cli_common.h"
#include "app/cli_mosaic.h"
#include "core/eval/front_end_accuracy.h"
#include "core/eval/video_evaluation.h"
#include "core/mosaic/mosaic_builder.h"
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
  bool overlay_mask = frontend::FrontEndOptions{}.overlays.enabled;
  bool fixed_thresholds = false;  // --noise-thresholds fixed
  bool horizon_mask = frontend::FrontEndOptions{}.horizon.enabled;
  frontend::LowFrameRateOptions::Mode low_frame_rate = frontend::LowFrameRateOptions::Mode::kAuto;
  std::string adjust = "decomposed";
  mosaic::DecompositionOptions decomposition;
  eval::FrontEndEvaluationOptions evaluation;
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
  AddOverlayMaskOption(s.command, &s.overlay_mask);
  AddHorizonMaskOption(s.command, &s.horizon_mask);
  AddNoiseThresholdsOption(s.command, &s.fixed_thresholds);
  AddLowFrameRateOption(s.command, &s.low_frame_rate);
}

EvaluateCommand::~EvaluateCommand() = default;
bool EvaluateCommand::parsed() const { return state_->command->parsed(); }

int EvaluateCommand::Run() const {
  const State& s = *state_;
  std::filesystem::path truth_path = s.truth;
  if (truth_path.empty())
    truth_path = std::filesystem::path(s.video).replace_extension(".truth.json");
  StatusOr<sim::Truth> truth = sim::ReadTruth(truth_path);
  if (!truth.ok()) return Fail(truth.status());
  eval::VideoEvaluationOptions options;
  options.front_end.change.enabled = !s.no_change;
  options.front_end.overlays.enabled = s.overlay_mask;
  options.front_end.horizon.enabled = s.horizon_mask;
  if (s.fixed_thresholds) options.front_end.UseFixedThresholds();
  options.front_end.low_frame_rate.mode = s.low_frame_rate;
  options.evaluation = s.evaluation;
  options.mosaic.use_metadata = !s.no_metadata;
  options.mosaic.adjust_mode = *mosaic::ParseAdjustmentMode(s.adjust);
  options.mosaic.decomposition = s.decomposition;
  const StatusOr<eval::VideoEvaluation> evaluation = eval::EvaluateVideo(s.video, *truth, options);
  if (!evaluation.ok()) return Fail(evaluation.status());
  if (s.json) {
    std::cout << eval::VideoEvaluationToJson(*evaluation).dump(2) << "\n";
  } else {
    std::cout << eval::VideoEvaluationToText(*evaluation, s.details);
  }
  return 0;
}

}  // namespace saker::app
