#include "app/cli_report.h"

#include "app/cli_common.h"
#include "app/cli_interrupt.h"
#include "core/activity/colours.h"
#include "core/activity/confidence.h"
#include "core/pipeline/export_mission.h"
#include "core/pipeline/open_mission.h"
#include "core/report/report.h"

#ifdef SAKER_HAVE_PDF
#include "ui/report_pdf.h"

#include <QGuiApplication>
#endif

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <string>

namespace saker::app {

struct ReportCommand::State {
  CLI::App* command = nullptr;
  std::string mission;
  std::string output;
  std::string colour_by = "speed";
  std::string video;
  bool include_false = false;
  bool no_chips = false;
  double min_confidence = 0;
};

ReportCommand::ReportCommand(CLI::App& app) : state_(std::make_unique<State>()) {
  State& s = *state_;
  s.command = app.add_subcommand(
      "report",
      "Write the mission report: its facts, the activity map, the track table, a chip of each "
      "track cut from the video with the analyst's verdicts and notes, the bookmarks. HTML (one "
      "self-contained file) or PDF, by the output's extension");
  s.command->add_option("MISSION", s.mission, "Mission file (.saker)")->required();
  s.command->add_option("-o,--output", s.output, "The report: REPORT.html or REPORT.pdf")
      ->required();
  s.command->add_option("--color-by,--colour-by", s.colour_by, "Track colours on the activity map")
      ->capture_default_str()
      ->check(CLI::IsMember({"speed", "direction", "visit", "time", "density"}));
  s.command->add_option("--video", s.video,
                        "The mission's video, for the chips, when it is not where the mission "
                        "says (nor beside the mission file)");
  s.command->add_flag("--no-chips", s.no_chips, "Leave the chips out (no video needed)");
  s.command->add_flag("--include-false", s.include_false,
                      "Also report the tracks the analyst marked false");
  AddMinConfidenceOption(s.command, &s.min_confidence, "are left out of the report");
}

ReportCommand::~ReportCommand() = default;
bool ReportCommand::parsed() const { return state_->command->parsed(); }

int ReportCommand::Run() const {
  const State& s = *state_;
  std::string extension = std::filesystem::path(s.output).extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  const bool pdf = extension == ".pdf";
  if (!pdf && extension != ".html" && extension != ".htm") {
    std::cerr << "saker-cli report: " << s.output
              << ": give a report name ending in .html or .pdf\n";
    return kExitUsage;
  }
#ifndef SAKER_HAVE_PDF
  if (pdf) {
    std::cerr << "saker-cli report: " << s.output
              << ": PDF needs Saker built with its Qt GUI (SAKER_BUILD_GUI); write .html\n";
    return kExitUsage;
  }
#endif
  StatusOr<pipeline::OpenedMission> opened = pipeline::OpenMission(s.mission);
  if (!opened.ok()) return Fail(opened.status());
  mission::Mission& m = opened->mission;
  std::erase_if(m.tracks, [&](const mission::ActivityTrack& t) {
    return !activity::PassesConfidence(t, s.min_confidence);
  });
  StatusOr<std::unique_ptr<mission::MissionStore>> store =
      mission::MissionStore::Open(s.mission, mission::OpenMode::kSnapshot);
  if (!store.ok()) return Fail(store.status());
  if (m.pyramid) {
    if (const Status declared = pipeline::CheckDeclaredPyramid(*m.pyramid, **store);
        !declared.ok()) {
      return Fail(declared);
    }
  }
  report::ReportOptions options;
  options.map.colour_by = *activity::ParseColourMode(s.colour_by);
  options.video_path = !s.video.empty() ? s.video : opened->video.path;
  options.chips = !s.no_chips;
  options.include_false = s.include_false;
  options.saker_version = SAKER_VERSION;
  JobContext job;
  StatusOr<report::Report> built = [&] {
    const ScopedInterrupt interrupt(&job);
    return report::BuildReport(
        m, pipeline::StoreTileReader(**store, m.pyramid ? m.pyramid->tile_size : 0), options, &job);
  }();
  if (!built.ok()) return Fail(built.status());
  Status written;
  if (pdf) {
#ifdef SAKER_HAVE_PDF
    // Qt's PDF writer needs a GUI application; an offscreen one needs no display.
    if (qEnvironmentVariableIsEmpty("QT_QPA_PLATFORM")) qputenv("QT_QPA_PLATFORM", "offscreen");
    int argc = 1;
    char name[] = "saker-cli";
    char* argv[] = {name, nullptr};
    QGuiApplication application(argc, argv);
    written = ui::WriteReportPdf(*built, s.output);
#endif
  } else {
    written = report::WriteHtml(*built, s.output);
  }
  if (!written.ok()) return Fail(written);
  for (const std::string& warning : built->warnings) std::cerr << "warning: " << warning << "\n";
  std::cout << "wrote " << s.output << " (report: " << built->tracks << " tracks, "
            << built->images.size() << " pictures)\n";
  return kExitOk;
}

}  // namespace saker::app
