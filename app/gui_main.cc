// saker: the analyst workstation GUI. A thin main(): all behaviour lives in ui/.

#include "core/util/status.h"
#include "core/video/video_reader.h"
#include "ui/main_window.h"

#include <QApplication>
#include <QCommandLineParser>
#include <QCoreApplication>
#include <QStringList>
#include <iostream>

namespace {

void SetIdentity() {
  QCoreApplication::setApplicationName("Saker");
  QCoreApplication::setOrganizationName("Saker");
  QCoreApplication::setApplicationVersion(SAKER_VERSION);
}

// Parses the command line; --help, --version and errors print and exit here.
QStringList ParseArguments(const QCoreApplication& app) {
  QCommandLineParser parser;
  parser.setApplicationDescription(
      "Saker: analyst workstation for airborne video with STANAG 4609 metadata.\n"
      "Opens a mission, or processes a video into one; docs/user-guide.md describes the window.\n"
      "On a machine without a display, use saker-cli (or run this under xvfb-run).");
  parser.addHelpOption();
  parser.addVersionOption();
  parser.addPositionalArgument(
      "file",
      "A mission (.saker) to open, or a video (MPEG-TS, MPG, MP4) to process into a mission.",
      "[file]");
  parser.process(app);
  return parser.positionalArguments();
}

bool HasDisplay() {
  return !qEnvironmentVariableIsEmpty("DISPLAY") ||
         !qEnvironmentVariableIsEmpty("WAYLAND_DISPLAY") ||
         !qEnvironmentVariableIsEmpty("QT_QPA_PLATFORM");
}

}  // namespace

int main(int argc, char** argv) {
  // Help and version need no display: they are answered before the GUI starts.
  QStringList files;
  {
    QCoreApplication console(argc, argv);
    SetIdentity();
    files = ParseArguments(console);
  }
  if (!HasDisplay()) {
    std::cerr << "saker: no display to open the window on (neither DISPLAY nor WAYLAND_DISPLAY "
                 "is set). On a headless machine use saker-cli, or run `xvfb-run -a saker`.\n";
    return 1;
  }
  try {
    QApplication app(argc, argv);
    SetIdentity();

    // Damage is reported in the window; FFmpeg's own stderr chatter is noise here.
    saker::video::SetFfmpegLogVerbose(false);
    saker::ui::MainWindow window;
    window.show();
    if (!files.isEmpty()) window.openPath(files.front());
    return app.exec();
  } catch (...) {
    // Jobs report their own exceptions (TaskRunner); one that reaches here (memory running out
    // on the GUI thread) ends the window with a message rather than std::terminate. A mission
    // keeps what its last commit holds. Exit codes as saker-cli's.
    const saker::Status status = saker::StatusFromCurrentException("saker");
    std::cerr << status.message() << "\n";
    return status.code() == saker::StatusCode::kResourceExhausted ? 1 : 3;
  }
}
