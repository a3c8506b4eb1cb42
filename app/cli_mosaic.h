#pragma once

// The `mosaic` subcommand of saker-cli: video in, the front end and the mosaic engine (loop
// closure, bundle adjustment), a mosaic picture out with a summary of what was found. It is also
// the main job the demo runs.

#include "core/util/job_context.h"

#include <CLI/CLI.hpp>

#include <memory>
#include <string>

namespace saker::app {

class MosaicCommand {
 public:
  explicit MosaicCommand(CLI::App& app);
  ~MosaicCommand();
  bool parsed() const;
  int Run() const;
  // The demo's main job: the mosaic of `video` written next to it as mosaic.png.
  int RunOn(const std::string& video, const std::string& output) const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace saker::app
