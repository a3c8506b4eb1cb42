#pragma once

// The mission subcommands of saker-cli: `process` (a video into a mission file, Ctrl-C cancels
// cleanly and keeps what completed), `export` (activity map picture, GeoTIFF mosaic, tracks as
// GeoJSON / KML / CSV), `copy` (Save As) and `info` (what a mission holds, and whether its video
// is still there).

#include <CLI/CLI.hpp>

#include <memory>
#include <string>

namespace saker::app {

class ProcessCommand {
 public:
  explicit ProcessCommand(CLI::App& app);
  ~ProcessCommand();
  bool parsed() const;
  int Run() const;
  // The demo's main job: `video` processed into `mission` (replacing an earlier demo mission).
  int RunOn(const std::string& video, const std::string& mission, bool replace) const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

class ExportCommand {
 public:
  explicit ExportCommand(CLI::App& app);
  ~ExportCommand();
  bool parsed() const;
  int Run() const;
  // The demo's activity map: `mission` drawn to `png`, coloured by speed.
  int WriteActivityMap(const std::string& mission, const std::string& png);

 private:
  struct State;
  std::unique_ptr<State> state_;
};

// `copy`: the GUI's Save As. The copy is complete or absent (built beside the target, renamed).
class CopyCommand {
 public:
  explicit CopyCommand(CLI::App& app);
  ~CopyCommand();
  bool parsed() const;
  int Run() const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

class InfoCommand {
 public:
  explicit InfoCommand(CLI::App& app);
  ~InfoCommand();
  bool parsed() const;
  int Run() const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace saker::app
