// saker: the analyst workstation GUI. A thin main(): all behaviour lives in ui/.

#include "core/video/video_reader.h"
#include "ui/main_window.h"

#include <QApplication>
#include <QCommandLineParser>

int main(int argc, char** argv) {
  QApplication app(argc, argv);
  QApplication::setApplicationName("Saker");
  QApplication::setOrganizationName("Saker");
  QApplication::setApplicationVersion(SAKER_VERSION);

  QCommandLineParser parser;
  parser.setApplicationDescription(
      "Saker: analyst workstation for airborne video with STANAG 4609 metadata.");
  parser.addHelpOption();
  parser.addVersionOption();
  parser.addPositionalArgument(
      "file",
      "A mission (.saker) to open, or a video (MPEG-TS, MPG, MP4) to process into a mission.",
      "[file]");
  parser.process(app);

  // Damage is reported in the window; FFmpeg's own stderr chatter is noise here.
  saker::video::SetFfmpegLogVerbose(false);
  saker::ui::MainWindow window;
  window.show();
  if (!parser.positionalArguments().isEmpty())
    window.openPath(parser.positionalArguments().front());
  return app.exec();
}
