#pragma once

// The mission report (core/report/report.h) as PDF, through Qt's PDF writer: the report's HTML
// laid out by QTextDocument on A4 pages, its pictures handed to the document by name. Needs a
// QGuiApplication (the command-line tool makes an offscreen one); may run off the GUI thread.

#include "core/report/report.h"
#include "core/util/status.h"

#include <string>

namespace saker::ui {

// Writes `report` to `path` as PDF (through a temporary renamed into place); the error names the
// file.
Status WriteReportPdf(const report::Report& report, const std::string& path);

}  // namespace saker::ui
