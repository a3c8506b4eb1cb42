#pragma once

// `saker-cli report MISSION -o REPORT.html|REPORT.pdf`: the mission report (core/report).

#include <CLI/CLI.hpp>

#include <memory>

namespace saker::app {

class ReportCommand {
 public:
  explicit ReportCommand(CLI::App& app);
  ~ReportCommand();
  bool parsed() const;
  int Run() const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace saker::app
