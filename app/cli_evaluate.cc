#include "app/cli_evaluate.h"

#include "core/frontend/evaluate.h"
#include "core/frontend/front_end.h"
#include "core/sim/truth.h"

#include <filesystem>
#include <iostream>

namespace saker::app {

struct EvaluateCommand::State {
  CLI::App* command = nullptr;
  std::string video;
  std::filesystem::path truth;
  bool json = false;
  frontend::EvaluationOptions evaluation;
};

EvaluateCommand::EvaluateCommand(CLI::App& app) : state_(std::make_unique<State>()) {
  State& s = *state_;
  s.command = app.add_subcommand(
      "evaluate",
      "Run the engine on a simulated video and print its accuracy against the simulator's truth:\n"
      "frame-to-frame homography error (image-corner transfer, pixels) and moving-target "
      "detection\n"
      "(recall and precision of target tracks and per frame, detection latency). See\n"
      "docs/front-end.md for the definitions.");
  s.command->add_option("VIDEO", s.video, "Simulated video (saker-cli simulate)")->required();
  s.command->add_option("--truth", s.truth, "Its truth file (default: VIDEO with .truth.json)");
  s.command->add_flag("--json", s.json, "Print the figures as JSON");
  s.command->add_option("--gate", s.evaluation.gate_px, "Pairing distance, pixels")
      ->capture_default_str();
  s.command
      ->add_option("--min-speed", s.evaluation.min_speed_mps,
                   "Slowest truth target counted as moving, m/s")
      ->capture_default_str();
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
  StatusOr<frontend::FrontEndResult> result = frontend::RunFrontEnd(s.video, {});
  if (!result.ok()) {
    std::cerr << "saker-cli: " << result.status().message() << "\n";
    return 1;
  }
  StatusOr<frontend::Evaluation> evaluation = frontend::Evaluate(*result, *truth, s.evaluation);
  if (!evaluation.ok()) {
    std::cerr << "saker-cli: " << s.video << ": " << evaluation.status().message() << "\n";
    return 1;
  }
  if (s.json) {
    std::cout << frontend::EvaluationToJson(*evaluation).dump(2) << "\n";
  } else {
    std::cout << frontend::EvaluationToText(*evaluation);
  }
  return 0;
}

}  // namespace saker::app
