#pragma once

// The `evaluate` subcommand of saker-cli: run the engine on a simulated video and print its
// accuracy against the simulator's truth.

#include <CLI/CLI.hpp>

#include <memory>

namespace saker::app {

class EvaluateCommand {
 public:
  explicit EvaluateCommand(CLI::App& app);
  ~EvaluateCommand();
  bool parsed() const;
  int Run() const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace saker::app
