#pragma once

// The `simulate` and `demo` subcommands of saker-cli.

#include <CLI/CLI.hpp>

#include <memory>

namespace saker::app {

class SimulateCommand {
 public:
  // Adds `simulate` to `app`.
  explicit SimulateCommand(CLI::App& app);
  ~SimulateCommand();
  bool parsed() const;
  // Runs the simulation with a progress bar on a terminal; returns the process exit code.
  int Run() const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

class DemoCommand {
 public:
  explicit DemoCommand(CLI::App& app);
  ~DemoCommand();
  bool parsed() const;
  // --no-gui: stay on the command line even when a display is present.
  bool no_gui() const;
  // Generates the demo mission if it is not there yet, then runs the main job on it.
  // `main_job` gets the demo video's path and returns an exit code.
  template <typename MainJob>
  int Run(MainJob main_job) const {
    const int status = Prepare();
    return status != 0 ? status : main_job(VideoPath());
  }

 private:
  int Prepare() const;
  std::string VideoPath() const;
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace saker::app
