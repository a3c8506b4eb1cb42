// main() of the GUI tests: a QApplication, headless unless QT_QPA_PLATFORM says otherwise (also
// when CTest lists the tests at build time).

#include <gtest/gtest.h>

#include <QApplication>
#include <QFile>
#include <QSettings>
#include <QStandardPaths>

int main(int argc, char** argv) {
  if (qEnvironmentVariableIsEmpty("QT_QPA_PLATFORM")) qputenv("QT_QPA_PLATFORM", "offscreen");
  QApplication app(argc, argv);
  // Settings (recent files, located videos) go to a test location, never the user's, one per
  // process (CTest runs tests in parallel), removed at the end.
  QStandardPaths::setTestModeEnabled(true);
  QApplication::setOrganizationName("SakerTests");
  QApplication::setApplicationName(
      QString("SakerTests-%1").arg(QCoreApplication::applicationPid()));
  ::testing::InitGoogleTest(&argc, argv);
  const int result = RUN_ALL_TESTS();
  QFile::remove(QSettings().fileName());
  return result;
}
