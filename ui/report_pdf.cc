#include "ui/report_pdf.h"

#include "core/util/durable_file.h"

#include <QByteArray>
#include <QImage>
#include <QMarginsF>
#include <QPageLayout>
#include <QPageSize>
#include <QPdfWriter>
#include <QString>
#include <QTextDocument>
#include <QUrl>
#include <filesystem>
#include <system_error>

namespace saker::ui {

Status WriteReportPdf(const report::Report& report, const std::string& path) {
  return ReplaceFile(path, [&](const std::string& temporary) -> Status {
    QTextDocument document;
    document.setDocumentMargin(0);
    for (const report::ReportImage& image : report.images) {
      QImage picture;
      if (!picture.loadFromData(image.bytes.data(), static_cast<int>(image.bytes.size()))) {
        return IoError(path + ": cannot read back the report's picture " + image.name);
      }
      document.addResource(QTextDocument::ImageResource, QUrl(QString::fromStdString(image.name)),
                           picture);
    }
    QPdfWriter writer(QString::fromStdString(temporary));
    writer.setTitle(QString::fromStdString(report.title));
    writer.setCreator(QStringLiteral("Saker"));
    writer.setPageLayout(QPageLayout(QPageSize(QPageSize::A4), QPageLayout::Portrait,
                                     QMarginsF(15, 15, 15, 15), QPageLayout::Millimeter));
    writer.setResolution(150);
    const QSizeF page = writer.pageLayout().paintRectPixels(writer.resolution()).size();
    document.setPageSize(page);
    // Pictures wider than the page (the activity map) scaled to its width.
    std::string body = report.body;
    for (const report::ReportImage& image : report.images) {
      if (image.width <= page.width()) continue;
      const std::string size = "width=\"" + std::to_string(image.width) + "\" height=\"" +
                               std::to_string(image.height) + "\"";
      const int width = static_cast<int>(page.width());
      const int height = static_cast<int>(page.width() * image.height / image.width);
      const std::string fitted =
          "width=\"" + std::to_string(width) + "\" height=\"" + std::to_string(height) + "\"";
      for (size_t at = body.find(size); at != std::string::npos; at = body.find(size, at)) {
        body.replace(at, size.size(), fitted);
      }
    }
    document.setDefaultStyleSheet(
        QStringLiteral("h1{font-size:16pt} h2{font-size:13pt} th{text-align:left;padding:1px 6px} "
                       "td{padding:1px 6px} .warning{color:#a40}"));
    document.setHtml(QString::fromStdString(body));
    document.print(&writer);
    std::error_code error;
    if (std::filesystem::file_size(temporary, error) == 0 || error) {
      return IoError(path + ": the PDF writer wrote nothing (an unwritable folder?)");
    }
    return Status::Ok();
  });
}

}  // namespace saker::ui
