#include "ui/main_window.h"

#include "core/ingest/report.h"
#include "core/ingest/video_scan.h"
#include "core/util/job_context.h"

#include <opencv2/imgproc.hpp>

#include <QApplication>
#include <QCloseEvent>
#include <QDragEnterEvent>
#include <QDropEvent>
#include <QFileDialog>
#include <QFileInfo>
#include <QFontDatabase>
#include <QIcon>
#include <QImage>
#include <QLabel>
#include <QMenuBar>
#include <QMessageBox>
#include <QMimeData>
#include <QPixmap>
#include <QPlainTextEdit>
#include <QPointer>
#include <QProgressBar>
#include <QPushButton>
#include <QResizeEvent>
#include <QSplitter>
#include <QStatusBar>
#include <QThreadPool>

// Resources compiled into a static library must be registered explicitly.
static void InitSakerResources() { Q_INIT_RESOURCE(saker); }

namespace saker::ui {

namespace {

constexpr int kProgressSteps = 1000;

QImage ImageFromBgr(const cv::Mat& bgr) {
  cv::Mat rgb;
  cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
  return QImage(rgb.data, rgb.cols, rgb.rows, static_cast<qsizetype>(rgb.step),
                QImage::Format_RGB888)
      .copy();
}

}  // namespace

MainWindow::MainWindow(QWidget* parent) : QMainWindow(parent) {
  InitSakerResources();
  setWindowTitle(tr("Saker"));
  setWindowIcon(QIcon(":/saker/icons/saker.svg"));
  setAcceptDrops(true);
  resize(1100, 650);

  frame_view_ = new QLabel(this);
  frame_view_->setAlignment(Qt::AlignCenter);
  frame_view_->setMinimumSize(320, 240);
  frame_view_->setText(tr("Open a video (File > Open Video…) or drop one here."));
  frame_view_->setWordWrap(true);

  summary_ = new QPlainTextEdit(this);
  summary_->setReadOnly(true);
  summary_->setFont(QFontDatabase::systemFont(QFontDatabase::FixedFont));
  summary_->setLineWrapMode(QPlainTextEdit::WidgetWidth);

  auto* splitter = new QSplitter(this);
  splitter->addWidget(frame_view_);
  splitter->addWidget(summary_);
  splitter->setStretchFactor(0, 3);
  splitter->setStretchFactor(1, 2);
  splitter->setSizes({640, 460});
  setCentralWidget(splitter);

  progress_ = new QProgressBar(this);
  progress_->setRange(0, kProgressSteps);
  progress_->setMaximumWidth(240);
  cancel_button_ = new QPushButton(tr("Cancel"), this);
  connect(cancel_button_, &QPushButton::clicked, this, &MainWindow::cancelScan);
  statusBar()->addPermanentWidget(progress_);
  statusBar()->addPermanentWidget(cancel_button_);
  setBusy(false);
  statusBar()->showMessage(tr("Ready"));

  createMenus();
}

MainWindow::~MainWindow() {
  // A running scan holds only its shared context and a QPointer to us; cancel
  // it so the worker stops at its next frame.
  if (job_) job_->RequestCancel();
}

void MainWindow::createMenus() {
  QMenu* file = menuBar()->addMenu(tr("&File"));
  QAction* open = file->addAction(tr("&Open Video…"), this, &MainWindow::chooseVideo);
  open->setShortcut(QKeySequence::Open);
  file->addSeparator();
  QAction* quit = file->addAction(tr("&Quit"), this, &QWidget::close);
  quit->setShortcut(QKeySequence::Quit);

  QMenu* help = menuBar()->addMenu(tr("&Help"));
  help->addAction(tr("&About Saker"), this, &MainWindow::showAbout);
}

void MainWindow::chooseVideo() {
  const QString path = QFileDialog::getOpenFileName(
      this, tr("Open Video"), QString(),
      tr("Airborne video (*.ts *.mpg *.mpeg *.m2ts *.mp4 *.mov *.mkv);;All files (*)"));
  if (!path.isEmpty()) openVideo(path);
}

void MainWindow::openVideo(const QString& path) {
  if (job_) job_->RequestCancel();
  const quint64 generation = ++job_generation_;
  setWindowTitle(tr("%1 — Saker").arg(QFileInfo(path).fileName()));
  statusBar()->showMessage(tr("Reading %1…").arg(path));
  summary_->clear();
  first_frame_ = QImage();
  frame_view_->setPixmap({});
  frame_view_->setText(tr("Reading…"));
  progress_->setValue(0);
  setBusy(true);

  QPointer<MainWindow> self(this);
  // Progress arrives on the worker thread; hop to the GUI thread, and ignore
  // it once this scan has been superseded.
  auto progress = [self, generation](const std::string&, double fraction) {
    QMetaObject::invokeMethod(
        qApp,
        [self, generation, fraction] {
          if (self && self->job_generation_ == generation) {
            self->progress_->setValue(static_cast<int>(fraction * kProgressSteps));
          }
        },
        Qt::QueuedConnection);
  };
  auto job = std::make_shared<JobContext>(progress);
  job_ = job;
  QThreadPool::globalInstance()->start([self, job, generation, path] {
    ingest::ScanOptions options;
    options.reader.want_bgr = true;
    cv::Mat first_frame;
    auto on_frame = [&first_frame](const video::Frame& frame) {
      if (first_frame.empty() && !frame.bgr.empty()) first_frame = frame.bgr.clone();
    };
    auto scan = ingest::ScanVideo(path.toStdString(), options, job.get(), on_frame);
    QString text;
    QString error;
    if (scan.ok()) {
      text = QString::fromStdString(ingest::ProbeToText(*scan));
    } else {
      error = QString::fromStdString(scan.status().message());
    }
    const QImage image = first_frame.empty() ? QImage() : ImageFromBgr(first_frame);
    QMetaObject::invokeMethod(
        qApp,
        [self, generation, path, text, error, image] {
          if (!self || self->job_generation_ != generation) return;
          self->job_.reset();
          self->setBusy(false);
          if (!error.isEmpty()) {
            self->frame_view_->setText(error);
            self->statusBar()->showMessage(error);
            emit self->scanFailed(path, error);
            return;
          }
          self->summary_->setPlainText(text);
          self->first_frame_ = image;
          if (!image.isNull()) {
            self->showFirstFrame();
          } else {
            self->frame_view_->setText(tr("No frame could be decoded."));
          }
          self->statusBar()->showMessage(tr("Read %1").arg(path));
          emit self->scanFinished(path);
        },
        Qt::QueuedConnection);
  });
}

void MainWindow::showFirstFrame() {
  if (first_frame_.isNull()) return;
  frame_view_->setPixmap(
      QPixmap::fromImage(first_frame_)
          .scaled(frame_view_->size(), Qt::KeepAspectRatio, Qt::SmoothTransformation));
}

void MainWindow::resizeEvent(QResizeEvent* event) {
  QMainWindow::resizeEvent(event);
  showFirstFrame();
}

QString MainWindow::summaryText() const { return summary_->toPlainText(); }

void MainWindow::cancelScan() {
  if (!job_) return;
  job_->RequestCancel();
  ++job_generation_;  // drop whatever the worker still reports
  job_.reset();
  setBusy(false);
  frame_view_->setText(tr("Cancelled."));
  statusBar()->showMessage(tr("Cancelled"));
}

void MainWindow::setBusy(bool busy) {
  progress_->setVisible(busy);
  cancel_button_->setVisible(busy);
}

void MainWindow::showAbout() {
  QMessageBox::about(this, tr("About Saker"),
                     tr("<b>Saker %1</b><p>Analyst workstation for airborne video: moving "
                        "targets on mosaic maps from UAV video with STANAG 4609 metadata.</p>")
                         .arg(QApplication::applicationVersion()));
}

void MainWindow::dragEnterEvent(QDragEnterEvent* event) {
  if (event->mimeData()->hasUrls()) event->acceptProposedAction();
}

void MainWindow::dropEvent(QDropEvent* event) {
  const auto urls = event->mimeData()->urls();
  if (!urls.isEmpty() && urls.front().isLocalFile()) {
    openVideo(urls.front().toLocalFile());
    event->acceptProposedAction();
  }
}

void MainWindow::closeEvent(QCloseEvent* event) {
  if (job_) job_->RequestCancel();
  event->accept();
}

}  // namespace saker::ui
