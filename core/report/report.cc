#include "core/report/report.h"

#include "core/geo/coordinates.h"
#include "core/geo/local_tangent_plane.h"
#include "core/util/durable_file.h"
#include "core/util/markup.h"
#include "core/video/video_reader.h"

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <memory>
#include <optional>
#include <sstream>

namespace saker::report {
namespace {

constexpr int kChipPx = 160;
constexpr int kJpegQuality = 88;

std::string Number(double value, int decimals) {
  if (!std::isfinite(value)) return "–";
  char text[64];
  std::snprintf(text, sizeof(text), "%.*f", decimals, value);
  return text;
}

std::string Clock(double seconds) {
  if (!std::isfinite(seconds)) return "–";
  const double s = std::max(seconds, 0.0);
  const int minutes = static_cast<int>(s / 60);
  char text[32];
  std::snprintf(text, sizeof(text), "%d:%04.1f", minutes, s - 60.0 * minutes);
  return text;
}

std::string Utc(int64_t utc_us) {
  const std::time_t seconds = static_cast<std::time_t>(utc_us / 1000000);
  std::tm tm{};
  if (gmtime_r(&seconds, &tm) == nullptr) return "–";
  char text[48];
  std::snprintf(text, sizeof(text), "%04d-%02d-%02dT%02d:%02d:%02d.%03dZ", tm.tm_year + 1900,
                tm.tm_mon + 1, tm.tm_mday, tm.tm_hour, tm.tm_min, tm.tm_sec,
                static_cast<int>((utc_us / 1000) % 1000));
  return text;
}

const char* VerdictWord(mission::Verdict verdict) {
  switch (verdict) {
    case mission::Verdict::kConfirmed:
      return "confirmed";
    case mission::Verdict::kFalse:
      return "false";
    case mission::Verdict::kNone:
      break;
  }
  return "";
}

StatusOr<ReportImage> Jpeg(const std::string& name, const cv::Mat& bgr) {
  ReportImage image;
  image.name = name;
  image.mime = "image/jpeg";
  image.width = bgr.cols;
  image.height = bgr.rows;
  if (!cv::imencode(".jpg", bgr, image.bytes, {cv::IMWRITE_JPEG_QUALITY, kJpegQuality})) {
    return IoError("report: cannot encode " + name);
  }
  return image;
}

// A row of a two-column facts table.
void Fact(std::ostringstream& out, const std::string& name, const std::string& value) {
  out << "<tr><th>" << HtmlText(name) << "</th><td>" << HtmlText(value) << "</td></tr>\n";
}

}  // namespace

Status ReportOptions::Validate() const {
  if (map_max_side_px < 64 || map_max_side_px > 8192) {
    return InvalidArgumentError("report: the activity map's side must be 64..8192 pixels");
  }
  if (max_track_sections < 0) {
    return InvalidArgumentError("report: max_track_sections must not be negative");
  }
  return map.Validate();
}

std::string HtmlText(const std::string& text) { return EscapeMarkup(text, MarkupQuote::kHtml); }

std::string Base64(const std::vector<uint8_t>& bytes) {
  static constexpr char kAlphabet[] =
      "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  for (size_t i = 0; i < bytes.size(); i += 3) {
    const uint32_t a = bytes[i];
    const uint32_t b = i + 1 < bytes.size() ? bytes[i + 1] : 0;
    const uint32_t c = i + 2 < bytes.size() ? bytes[i + 2] : 0;
    const uint32_t triple = (a << 16) | (b << 8) | c;
    out += kAlphabet[(triple >> 18) & 63];
    out += kAlphabet[(triple >> 12) & 63];
    out += i + 1 < bytes.size() ? kAlphabet[(triple >> 6) & 63] : '=';
    out += i + 2 < bytes.size() ? kAlphabet[triple & 63] : '=';
  }
  return out;
}

std::string Report::Html() const {
  std::string body_inlined = body;
  for (const ReportImage& image : images) {
    const std::string needle = "src=\"" + image.name + "\"";
    const std::string data = "src=\"data:" + image.mime + ";base64," + Base64(image.bytes) + "\"";
    for (size_t at = body_inlined.find(needle); at != std::string::npos;
         at = body_inlined.find(needle, at + data.size())) {
      body_inlined.replace(at, needle.size(), data);
    }
  }
  std::ostringstream out;
  out << "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>"
      << HtmlText(title) << "</title>\n<style>\n"
      << "body{font-family:sans-serif;margin:2em auto;max-width:60em;color:#222}\n"
      << "h1{font-size:1.6em}h2{font-size:1.25em;margin-top:1.6em;border-bottom:1px solid #ccc}\n"
      << "table{border-collapse:collapse;margin:0.5em 0}th,td{padding:2px 8px;text-align:left;"
         "border-bottom:1px solid #e4e4e4;vertical-align:top}\n"
      << "td.n{text-align:right}img.map{max-width:100%}\n"
      << "table.track{margin:1em 0;page-break-inside:avoid}table.track td{border:none}\n"
      << ".warning{color:#a40}.false{color:#999;text-decoration:line-through}\n"
      << "footer{margin-top:2em;color:#777;font-size:0.85em}\n"
      << "</style>\n</head>\n<body>\n"
      << body_inlined << "</body>\n</html>\n";
  return out.str();
}

StatusOr<Report> BuildReport(const mission::Mission& mission, const render::TileReader& tiles,
                             const ReportOptions& options, JobContext* job) {
  SAKER_RETURN_IF_ERROR(options.Validate());
  Report report;
  const std::string video_name = std::filesystem::path(mission.source.path).filename().string();
  report.title = options.title.empty() ? "Mission report: " + video_name : options.title;
  std::optional<geo::LocalTangentPlane> plane;
  if (mission.map.geo_referenced && mission.map.origin) {
    if (auto created = geo::LocalTangentPlane::Create(*mission.map.origin); created.ok()) {
      plane = std::move(created).value();
    }
  }
  const auto position = [&](const Eigen::Vector2d& map) -> std::string {
    if (!plane) return "x " + Number(map.x(), 0) + ", y " + Number(map.y(), 0) + " px";
    const geo::Wgs84 p = plane->LatLonFromMap(map);
    return geo::FormatPosition(p, geo::CoordinateFormat::kDecimalDegrees) + " (" +
           geo::FormatPosition(p, geo::CoordinateFormat::kMgrs) + ")";
  };

  // The tracks reported: as given, less those marked false.
  std::vector<const mission::ActivityTrack*> tracks;
  for (const mission::ActivityTrack& t : mission.tracks) {
    if (options.include_false || !mission::IsMarkedFalse(mission, t.id)) tracks.push_back(&t);
  }
  std::sort(tracks.begin(), tracks.end(), [](const auto* a, const auto* b) {
    return a->start_s != b->start_s ? a->start_s < b->start_s : a->id < b->id;
  });
  report.tracks = static_cast<int>(tracks.size());
  const bool geo = mission.map.geo_referenced;
  const std::string speed_unit = geo ? "m/s" : "px/s";

  std::ostringstream out;
  out << "<h1>" << HtmlText(report.title) << "</h1>\n";

  // The mission's facts.
  out << "<h2>Mission</h2>\n<table>\n";
  Fact(out, "Video", video_name);
  Fact(out, "Picture",
       std::to_string(mission.source.width) + " x " + std::to_string(mission.source.height) + ", " +
           Number(mission.source.frame_rate, 2) + " fps");
  const double duration =
      mission.frames.empty() ? 0 : mission.frames.back().time_s - mission.frames.front().time_s;
  Fact(out, "Duration",
       Clock(duration) + " (" + std::to_string(mission.frames.size()) + " frames)");
  std::optional<int64_t> first_utc, last_utc;
  for (const mission::FrameRecord& f : mission.frames) {
    if (!f.utc_us) continue;
    if (!first_utc) first_utc = f.utc_us;
    last_utc = f.utc_us;
  }
  if (first_utc) Fact(out, "Time (UTC)", Utc(*first_utc) + " to " + Utc(*last_utc));
  Fact(out, "Map",
       plane ? "geo-referenced, origin " + position(Eigen::Vector2d::Zero())
             : "not geo-referenced (the first key frame's pixels)");
  Fact(out, "Tracks",
       std::to_string(tracks.size()) + " reported" +
           (tracks.size() != mission.tracks.size()
                ? " (" + std::to_string(mission.tracks.size() - tracks.size()) +
                      " left out: marked false or filtered)"
                : ""));
  int confirmed = 0, noted = 0;
  for (const mission::TrackReview& r : mission.reviews) {
    confirmed += r.verdict == mission::Verdict::kConfirmed ? 1 : 0;
    noted += r.note.empty() ? 0 : 1;
  }
  Fact(out, "Analyst",
       std::to_string(confirmed) + " confirmed, " + std::to_string(noted) + " with notes, " +
           std::to_string(mission.bookmarks.size()) + " bookmarks");
  out << "</table>\n";

  // The activity map.
  out << "<h2>Activity map</h2>\n";
  {
    render::ActivityMapOptions map = options.map;
    map.max_side_px = std::min(map.max_side_px, options.map_max_side_px);
    mission::Mission shown = mission;
    shown.tracks.clear();
    for (const auto* t : tracks) shown.tracks.push_back(*t);
    StatusOr<render::ActivityMap> picture = render::RenderActivityMap(shown, tiles, map);
    if (picture.ok()) {
      cv::Mat bgr = picture->bgr;
      const double scale =
          static_cast<double>(options.map_max_side_px) / std::max(bgr.cols, bgr.rows);
      if (scale < 1) cv::resize(bgr, bgr, cv::Size(), scale, scale, cv::INTER_AREA);
      SAKER_ASSIGN_OR_RETURN(ReportImage image, Jpeg("activity-map.jpg", bgr));
      out << "<p><img class=\"map\" src=\"activity-map.jpg\" width=\"" << image.width
          << "\" height=\"" << image.height << "\" alt=\"activity map\"></p>\n";
      report.images.push_back(std::move(image));
    } else {
      report.warnings.push_back("no activity map: " + picture.status().message());
      out << "<p class=\"warning\">" << HtmlText(report.warnings.back()) << "</p>\n";
    }
  }

  // The track table.
  out << "<h2>Tracks</h2>\n<table>\n<tr><th>Track</th><th>Start</th><th>Duration (s)</th>"
      << "<th>Speed (" << speed_unit << ")</th><th>Heading</th><th>Visit</th>"
      << "<th>Confidence</th><th>Verdict</th><th>Label</th><th>Note</th></tr>\n";
  for (const mission::ActivityTrack* t : tracks) {
    const mission::TrackReview* review = mission::ReviewOf(mission, t->id);
    const double speed = geo && t->speed_mps ? *t->speed_mps : t->speed;
    out << "<tr><td class=\"n\">" << t->id << "</td><td class=\"n\">" << Clock(t->start_s)
        << "</td><td class=\"n\">" << Number(t->end_s - t->start_s, 1) << "</td><td class=\"n\">"
        << Number(speed, 1) << "</td><td class=\"n\">" << Number(t->heading_deg, 0)
        << "°</td><td class=\"n\">" << t->visit << "</td><td class=\"n\">"
        << (t->confidence ? Number(*t->confidence, 2) : "–") << "</td><td>"
        << (review ? VerdictWord(review->verdict) : "") << "</td><td>"
        << (review ? mission::TargetLabelName(review->label) : "") << "</td><td>"
        << (review ? HtmlText(review->note) : "") << "</td></tr>\n";
  }
  out << "</table>\n";

  // A section per track, with its chip.
  std::unique_ptr<video::VideoReader> reader;
  const std::string video = options.video_path.empty() ? mission.source.path : options.video_path;
  if (options.chips && !tracks.empty()) {
    video::ReaderOptions reader_options;
    reader_options.want_bgr = true;
    StatusOr<std::unique_ptr<video::VideoReader>> opened =
        video::VideoReader::Open(video, reader_options);
    if (opened.ok()) {
      reader = std::move(opened).value();
    } else {
      report.warnings.push_back("no chips: " + opened.status().message());
    }
  }
  out << "<h2>Track details</h2>\n";
  if (!report.warnings.empty() && !reader && options.chips && !tracks.empty()) {
    out << "<p class=\"warning\">" << HtmlText(report.warnings.back()) << "</p>\n";
  }
  int chip_failures = 0;
  const size_t sections = std::min(tracks.size(), static_cast<size_t>(options.max_track_sections));
  for (size_t k = 0; k < sections; ++k) {
    if (job && job->IsCancelled()) return CancelledError("report: cancelled");
    const mission::ActivityTrack& t = *tracks[k];
    if (job) job->ReportProgress("Report", static_cast<double>(k) / std::max<size_t>(1, sections));
    if (t.points.empty()) continue;
    const mission::TrackPoint& middle = t.points[t.points.size() / 2];
    // A table rather than a flex box: Qt's rich text (the PDF) lays out tables, not flex.
    out << "<table class=\"track\"><tr><td>\n";
    if (reader) {
      StatusOr<video::Frame> frame = reader->ReadFrame(middle.frame);
      if (frame.ok() && !frame->bgr.empty()) {
        const double side = std::max({48.0, 2.5 * (middle.box_max - middle.box_min).maxCoeff()});
        cv::Rect area(static_cast<int>(std::lround(middle.image.x() - side / 2)),
                      static_cast<int>(std::lround(middle.image.y() - side / 2)),
                      static_cast<int>(std::lround(side)), static_cast<int>(std::lround(side)));
        area &= cv::Rect(0, 0, frame->bgr.cols, frame->bgr.rows);
        if (area.area() > 0) {
          cv::Mat chip;
          cv::resize(frame->bgr(area), chip, cv::Size(kChipPx, kChipPx), 0, 0, cv::INTER_CUBIC);
          const std::string name = "chip-" + std::to_string(t.id) + ".jpg";
          SAKER_ASSIGN_OR_RETURN(ReportImage image, Jpeg(name, chip));
          out << "<img src=\"" << name << "\" width=\"" << kChipPx << "\" height=\"" << kChipPx
              << "\" alt=\"track " << t.id << "\">\n";
          report.images.push_back(std::move(image));
        }
      } else {
        ++chip_failures;
      }
    }
    const mission::TrackReview* review = mission::ReviewOf(mission, t.id);
    const mission::FrameRecord* record = mission::FrameRecordOf(mission, middle.frame);
    const double speed = geo && t.speed_mps ? *t.speed_mps : t.speed;
    out << "</td><td><b>Track " << t.id << "</b>";
    if (review && review->verdict != mission::Verdict::kNone) {
      out << " — " << VerdictWord(review->verdict);
    }
    if (review && review->label != mission::TargetLabel::kNone) {
      out << ", " << mission::TargetLabelName(review->label);
    }
    out << "<br>\n" << Clock(t.start_s) << " to " << Clock(t.end_s) << " in the video";
    if (record && record->utc_us)
      out << " (frame " << middle.frame << ": " << Utc(*record->utc_us) << ")";
    out << "<br>\n"
        << Number(speed, 1) << " " << speed_unit << ", heading " << Number(t.heading_deg, 0)
        << "°, visit " << t.visit << ", confidence "
        << (t.confidence ? Number(*t.confidence, 2) : "unknown") << "<br>\nAt "
        << HtmlText(position(middle.map)) << "\n";
    if (review && !review->note.empty()) out << "<br>\n<i>" << HtmlText(review->note) << "</i>\n";
    out << "</td></tr></table>\n";
  }
  if (chip_failures > 0) {
    report.warnings.push_back(std::to_string(chip_failures) +
                              " chips could not be cut (frames that did not decode)");
  }
  if (sections < tracks.size()) {
    out << "<p>" << tracks.size() - sections << " more tracks are in the table above.</p>\n";
  }

  // Bookmarks.
  if (!mission.bookmarks.empty()) {
    out << "<h2>Bookmarks</h2>\n<table>\n<tr><th>#</th><th>Time</th><th>Place</th><th>Note</th>"
        << "</tr>\n";
    for (const mission::Bookmark& b : mission.bookmarks) {
      out << "<tr><td class=\"n\">" << b.id << "</td><td class=\"n\">" << Clock(b.time_s)
          << "</td><td>" << HtmlText(position(b.map)) << "</td><td>" << HtmlText(b.note)
          << "</td></tr>\n";
    }
    out << "</table>\n";
  }
  out << "<footer>Made by Saker " << HtmlText(options.saker_version) << " from "
      << HtmlText(video_name) << ".</footer>\n";
  report.body = out.str();
  if (job) job->ReportProgress("Report", 1);
  return report;
}

Status WriteHtml(const Report& report, const std::string& path) {
  return ReplaceFileContents(path, report.Html());
}

}  // namespace saker::report
