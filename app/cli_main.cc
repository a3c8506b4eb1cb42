// saker-cli: the headless client of the Saker engine. Everything the GUI can
// do is reachable from here: `probe`, `klv`, `simulate`, `evaluate`, `mosaic`,
// `process`, `export`, `copy`, `info` and `demo`.

#include "app/cli_common.h"
#include "app/cli_evaluate.h"
#include "app/cli_mission.h"
#include "app/cli_mosaic.h"
#include "app/cli_report.h"
#include "app/cli_simulate.h"
#include "core/ingest/report.h"
#include "core/ingest/video_scan.h"
#include "core/util/check.h"
#include "core/util/status.h"
#include "core/video/video_reader.h"

#include <CLI/CLI.hpp>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <string>

namespace {

constexpr const char* kVersion = SAKER_VERSION;

// Exit codes, documented in --help.
using saker::app::kExitBug;
using saker::app::kExitOk;
using saker::app::kExitUsage;
constexpr int kExitInputError = saker::app::kExitFailed;  // the file could not be read as a video

int RunScan(const std::string& file, bool json, bool dump_klv, double tolerance_s,
            bool accept_bad_checksums) {
  saker::ingest::ScanOptions options;
  options.alignment.async_tolerance_s = tolerance_s;
  options.alignment.accept_bad_checksums = accept_bad_checksums;
  auto scan = saker::ingest::ScanVideo(file, options);
  if (!scan.ok()) {
    std::cerr << "saker-cli: " << scan.status().message() << "\n";
    return kExitInputError;
  }
  if (dump_klv) {
    if (json) {
      std::cout << saker::ingest::KlvDumpToJson(*scan).dump(2) << "\n";
    } else {
      std::cout << saker::ingest::KlvDumpToText(*scan);
    }
  } else if (json) {
    std::cout << saker::ingest::ProbeToJson(*scan).dump(2) << "\n";
  } else {
    std::cout << saker::ingest::ProbeToText(*scan);
  }
  return kExitOk;
}

}  // namespace

// The end of the demo: with a display, the mission opens in the GUI (saker, built beside this
// program), which replaces this process; headless, say where the results are.
static int OpenInGui(const std::string& mission, const std::string& png) {
  const char* x11 = std::getenv("DISPLAY");
  const char* wayland = std::getenv("WAYLAND_DISPLAY");
  const bool display = (x11 != nullptr && *x11 != '\0') || (wayland != nullptr && *wayland != '\0');
  std::error_code error;
  const std::filesystem::path gui =
      std::filesystem::read_symlink("/proc/self/exe", error).parent_path() / "saker";
  if (!display || error || access(gui.c_str(), X_OK) != 0) {
    std::cout << "\nNo display" << (display ? " or no GUI build" : "") << ": the activity map is "
              << png << ". On a desktop, open the mission with `"
              << (error ? std::string("saker") : gui.string()) << " " << mission << "`.\n";
    return kExitOk;
  }
  std::cout << "\nOpening " << mission << " in the Saker window (" << gui.string() << ")\n"
            << std::flush;
  execl(gui.c_str(), gui.c_str(), mission.c_str(), static_cast<char*>(nullptr));
  std::cerr << "saker-cli: cannot start " << gui.string() << ": " << std::strerror(errno)
            << "; the activity map is " << png << "\n";
  return kExitInputError;
}

int main(int argc, char** argv) {
  CLI::App app{
      "saker-cli: headless Saker, the analyst workstation for airborne video.\n"
      "Reads MPEG-TS / MPG / MP4 video (H.264, H.265, MPEG-2) with STANAG 4609 KLV metadata\n"
      "(MISB ST 0601 local set, MISB EG 0104 universal set).\n\n"
      "Exit codes: 0 success, 1 the input could not be read or the job failed, out of memory\n"
      "included (message on stderr), 2 bad command line, 3 internal error (please report it),\n"
      "130 cancelled by Ctrl-C."};
  app.set_version_flag("--version", std::string("saker-cli ") + kVersion);
  app.require_subcommand(1);

  std::string file;
  bool json = false;
  bool verbose = false;
  app.add_flag("-v,--verbose", verbose, "Also show FFmpeg's own decoder warnings on stderr");
  double tolerance_s = 0.5;
  bool accept_bad_checksums = false;

  auto* probe = app.add_subcommand(
      "probe",
      "Summarise a video: container, streams, resolution, fps, frame count, KLV streams with\n"
      "packet counts and checksum failures, frames with corner metadata, UTC time span.");
  probe->add_option("FILE", file, "Video file or stream URL")->required();
  probe->add_flag("--json", json, "Print the summary as JSON");
  probe
      ->add_option("--async-tolerance", tolerance_s,
                   "Seconds within which an asynchronous KLV packet is tied to a frame")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 60.0));
  saker::app::AddAcceptBadChecksumsFlag(probe, &accept_bad_checksums);

  auto* klv = app.add_subcommand(
      "klv",
      "Dump every KLV packet: stream, time, the frames it is tied to, every decoded tag with\n"
      "its raw bytes. Tags Saker does not interpret (nested sets such as security and VMTI)\n"
      "are listed raw.");
  klv->add_option("FILE", file, "Video file or stream URL")->required();
  klv->add_flag("--json", json, "Print the packets as JSON");
  klv->add_option("--async-tolerance", tolerance_s,
                  "Seconds within which an asynchronous KLV packet is tied to a frame")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 60.0));
  saker::app::AddAcceptBadChecksumsFlag(klv, &accept_bad_checksums);

  saker::app::SimulateCommand simulate(app);
  saker::app::DemoCommand demo(app);
  saker::app::EvaluateCommand evaluate(app);
  saker::app::MosaicCommand mosaic(app);
  saker::app::ProcessCommand process(app);
  saker::app::ExportCommand export_command(app);
  saker::app::CopyCommand copy(app);
  saker::app::InfoCommand info(app);
  saker::app::ReportCommand report(app);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // Prints help, the version, or the parse error; --help and --version are
    // successes, anything else is a bad command line.
    return app.exit(e) == 0 ? kExitOk : kExitUsage;
  }
  saker::video::SetFfmpegLogVerbose(verbose);

  try {
    if (probe->parsed())
      return RunScan(file, json, /*dump_klv=*/false, tolerance_s, accept_bad_checksums);
    if (klv->parsed())
      return RunScan(file, json, /*dump_klv=*/true, tolerance_s, accept_bad_checksums);
    if (simulate.parsed()) return simulate.Run();
    if (evaluate.parsed()) return evaluate.Run();
    if (mosaic.parsed()) return mosaic.Run();
    if (process.parsed()) return process.Run();
    if (export_command.parsed()) return export_command.Run();
    if (copy.parsed()) return copy.Run();
    if (info.parsed()) return info.Run();
    if (report.parsed()) return report.Run();
    if (demo.parsed()) {
      // The main job: the demo video processed into a mission, and its activity map.
      return demo.Run([&](const std::string& video) {
        const std::filesystem::path folder = std::filesystem::path(video).parent_path();
        const std::string mission = (folder / "demo.saker").string();
        if (const int code = process.RunOn(video, mission, /*replace=*/true); code != kExitOk) {
          return code;
        }
        const std::string png = (folder / "activity.png").string();
        if (const int code = export_command.WriteActivityMap(mission, png); code != kExitOk) {
          return code;
        }
        return demo.no_gui() ? kExitOk : OpenInGui(mission, png);
      });
    }
  } catch (const saker::CheckError& e) {
    std::cerr << "saker-cli: internal error, please report it: " << e.what() << "\n";
    return kExitBug;
  } catch (...) {
    // Memory running out (std::bad_alloc, cv::Exception) or an unexpected exception: a message,
    // never std::terminate. The mission keeps what its last commit holds.
    const saker::Status status = saker::StatusFromCurrentException("saker-cli");
    std::cerr << status.message() << "\n";
    return status.code() == saker::StatusCode::kResourceExhausted ? kExitInputError : kExitBug;
  }
  return kExitOk;
}
