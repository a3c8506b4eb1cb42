#pragma once

// A mission report for people who were not at the workstation: the mission's facts, the activity
// map, the track table, and for each track a chip of the target cut from the video with its
// attributes and the analyst's verdict, label and note, then the bookmarks. Built as HTML whose
// pictures are named (Report::images); Html() inlines them as data URIs, so the file stands
// alone, and the PDF writer (ui/report_pdf.h, Qt) hands them to its document instead.
// docs/exports.md ("Report").

#include "core/mission/mission.h"
#include "core/render/activity_map.h"
#include "core/util/job_context.h"
#include "core/util/status.h"

#include <cstdint>
#include <string>
#include <vector>

namespace saker::report {

struct ReportOptions {
  std::string title;               // empty: "Mission report: <video file name>"
  render::ActivityMapOptions map;  // the activity map's colouring (its max side is capped)
  int map_max_side_px = 1600;      // the activity map picture's longer side at most
  std::string video_path;          // the video the chips are cut from; empty: the mission's own
  bool chips = true;               // cut a chip per track (needs the video)
  int max_track_sections = 300;    // tracks given a section of their own (all are in the table)
  std::string saker_version;       // printed in the footer
  bool include_false = false;      // also the tracks the analyst marked false
  Status Validate() const;
};

struct ReportImage {
  std::string name;  // as the HTML's <img src="...">
  std::string mime;  // "image/jpeg"
  std::vector<uint8_t> bytes;
  int width = 0, height = 0;
};

struct Report {
  std::string title;
  std::string body;  // HTML of the body, pictures referred to by name
  std::vector<ReportImage> images;
  // What is missing and why (no video: no chips; no mosaic: no map), also said in the report.
  std::vector<std::string> warnings;
  int tracks = 0;  // tracks in the report
  // The whole document: styles, the body, every picture inlined (base64).
  std::string Html() const;
};

// Builds the report of `mission` (its tracks as given: the caller filters; tracks the analyst
// marked false are left out). `tiles` reads the mission's pyramid for the activity map. Chips
// that cannot be cut (no video, a frame that does not decode) are left out with a warning, never
// an error. `job` may cancel between tracks.
StatusOr<Report> BuildReport(const mission::Mission& mission, const render::TileReader& tiles,
                             const ReportOptions& options, JobContext* job = nullptr);

// Writes Report::Html() to `path` (through a temporary renamed into place).
Status WriteHtml(const Report& report, const std::string& path);

// Base64 of bytes (RFC 4648, with padding).
std::string Base64(const std::vector<uint8_t>& bytes);
// Text safe inside HTML: valid UTF-8, no control characters, & < > " ' escaped.
std::string HtmlText(const std::string& text);

}  // namespace saker::report
