// The main window under QT_QPA_PLATFORM=offscreen: a scan runs off the GUI
// thread, and its result or error reaches the window.

#include "ui/main_window.h"

#include "tests/testing/test_data.h"

#include <gtest/gtest.h>

#include <QApplication>
#include <QLabel>
#include <QProgressBar>
#include <QSignalSpy>
#include <QTest>

namespace saker::ui {
namespace {

TEST(MainWindowTest, OpensVideoAndShowsSummary) {
  SAKER_REQUIRE_TEST_DATA(path, "kwiver/h264_klv.ts");
  MainWindow window;
  window.show();
  QSignalSpy finished(&window, &MainWindow::scanFinished);
  QSignalSpy failed(&window, &MainWindow::scanFailed);
  window.openVideo(QString::fromStdString(path.string()));
  // The call returns at once: the scan runs on a worker thread.
  EXPECT_TRUE(window.findChild<QProgressBar*>()->isVisible());
  ASSERT_TRUE(finished.wait(30000)) << "scan did not finish";
  EXPECT_EQ(failed.count(), 0);
  const QString summary = window.summaryText();
  EXPECT_TRUE(summary.contains("160x120")) << summary.toStdString();
  EXPECT_TRUE(summary.contains("30 frames")) << summary.toStdString();
  EXPECT_TRUE(summary.contains("30 of 30 with metadata, 30 with image corners"))
      << summary.toStdString();
  EXPECT_FALSE(window.findChild<QProgressBar*>()->isVisible());
  EXPECT_TRUE(window.windowTitle().contains("h264_klv.ts"));
}

TEST(MainWindowTest, MissingFileShowsErrorNamingIt) {
  MainWindow window;
  window.show();
  QSignalSpy failed(&window, &MainWindow::scanFailed);
  window.openVideo("/nonexistent/sortie-12.ts");
  ASSERT_TRUE(failed.wait(30000));
  const QString message = failed.takeFirst().at(1).toString();
  EXPECT_TRUE(message.contains("sortie-12.ts")) << message.toStdString();
}

TEST(MainWindowTest, SecondOpenSupersedesTheFirst) {
  SAKER_REQUIRE_TEST_DATA(first, "kwiver/aphill_short.ts");
  SAKER_REQUIRE_TEST_DATA(second, "kwiver/h264_no_klv.ts");
  MainWindow window;
  QSignalSpy finished(&window, &MainWindow::scanFinished);
  window.openVideo(QString::fromStdString(first.string()));
  window.openVideo(QString::fromStdString(second.string()));
  ASSERT_TRUE(finished.wait(30000));
  // Only the second scan reports; give a superseded one time to (not) arrive.
  QTest::qWait(300);
  ASSERT_EQ(finished.count(), 1);
  EXPECT_EQ(finished.at(0).at(0).toString().toStdString(), second.string());
  EXPECT_TRUE(window.summaryText().contains("none (no KLV data stream)"));
}

}  // namespace
}  // namespace saker::ui

int main(int argc, char** argv) {
  // Headless by default, also when CTest lists the tests at build time.
  if (qEnvironmentVariableIsEmpty("QT_QPA_PLATFORM")) qputenv("QT_QPA_PLATFORM", "offscreen");
  QApplication app(argc, argv);
  ::testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
