#pragma once

// Saker's main window. In this first version it opens a video, scans it on a
// worker thread (the GUI never waits for it) and shows the first frame with
// the probe summary: streams, KLV metadata, frames with image corners.

#include <QImage>
#include <QMainWindow>
#include <QString>
#include <memory>

class QLabel;
class QPlainTextEdit;
class QProgressBar;
class QPushButton;

namespace saker {
class JobContext;
}

namespace saker::ui {

class MainWindow : public QMainWindow {
  Q_OBJECT

 public:
  explicit MainWindow(QWidget* parent = nullptr);
  ~MainWindow() override;

  // Starts scanning `path` in the background; a scan already running is
  // cancelled first. Emits scanFinished or scanFailed on the GUI thread.
  void openVideo(const QString& path);

  // The text the summary panel shows (for tests and copy/paste).
  QString summaryText() const;

 signals:
  void scanFinished(const QString& path);
  void scanFailed(const QString& path, const QString& message);

 protected:
  void dragEnterEvent(QDragEnterEvent* event) override;
  void dropEvent(QDropEvent* event) override;
  void closeEvent(QCloseEvent* event) override;
  void resizeEvent(QResizeEvent* event) override;

 private:
  void createMenus();
  void chooseVideo();
  void cancelScan();
  void showAbout();
  void setBusy(bool busy);
  void showFirstFrame();  // scaled to the view, kept in proportion

  QLabel* frame_view_ = nullptr;
  QPlainTextEdit* summary_ = nullptr;
  QProgressBar* progress_ = nullptr;
  QPushButton* cancel_button_ = nullptr;
  QImage first_frame_;  // full resolution, rescaled on resize
  // The running scan's context; shared with the worker so cancel is safe
  // whichever side finishes first.
  std::shared_ptr<JobContext> job_;
  quint64 job_generation_ = 0;  // results of a superseded scan are dropped
};

}  // namespace saker::ui
