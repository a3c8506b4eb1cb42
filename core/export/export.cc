#include "core/export/export.h"

#include "core/geo/utm.h"
#include "core/util/durable_file.h"
#include "core/util/markup.h"

#include <Eigen/Dense>
#include <cpl_error.h>
#include <cpl_string.h>
#include <gdal.h>
#include <nlohmann/json.hpp>
#include <ogr_srs_api.h>
#include <opencv2/core.hpp>

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <exception>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <sstream>
#include <string_view>
#include <utility>
#include <vector>

namespace saker::exporting {
namespace {

using Json = nlohmann::json;

// ---------------------------------------------------------------------------------------------
// Files

// Runs an exporter's body, turning any exception (from a library, a tile reader or a bug) into
// an error naming the file; exceptions never cross the API. The body's FileReplacement removes
// its temporary as the exception leaves it.
template <typename Body>
auto Guarded(const std::string& path, Body&& body) -> decltype(body()) {
  try {
    return body();
  } catch (const std::exception& e) {
    return IoError(path + ": export failed: " + e.what());
  } catch (...) {
    return IoError(path + ": export failed (unknown exception)");
  }
}

// ---------------------------------------------------------------------------------------------
// Values and text

// Shortest text that reads back as the same double; empty for NaN and infinities.
std::string FormatNumber(double value) {
  if (!std::isfinite(value)) return "";
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  return std::string(buffer, result.ptr);
}

Json JsonNumber(double value) { return std::isfinite(value) ? Json(value) : Json(nullptr); }
Json JsonNumber(const std::optional<double>& value) {
  return value ? JsonNumber(*value) : Json(nullptr);
}

std::string VideoName(const mission::Mission& mission) {
  return std::filesystem::path(mission.source.path).filename().string();
}

// Text as XML character data (core/util/markup.h).
std::string XmlText(std::string_view text) { return EscapeMarkup(text, MarkupQuote::kXml); }

// A CSV field (RFC 4180): quoted, with quotes doubled, when it holds a comma, quote or line
// break.
std::string CsvField(const std::string& text) {
  if (text.find_first_of(",\"\r\n") == std::string::npos) return text;
  std::string out = "\"";
  for (char c : text) {
    if (c == '"') out += '"';
    out += c;
  }
  out += '"';
  return out;
}

// ---------------------------------------------------------------------------------------------
// Positions

// Where the exported coordinates come from: WGS84 (longitude, latitude) through the mission's
// tangent plane when geo-referenced, the map point itself otherwise.
class Positions {
 public:
  static StatusOr<Positions> Create(const mission::MapFrame& map, const std::string& path) {
    Positions positions;
    if (!map.geo_referenced) return positions;
    if (!map.origin) {
      return InvalidArgumentError(path +
                                  ": the mission is marked geo-referenced but has no map origin");
    }
    auto plane = geo::LocalTangentPlane::Create(*map.origin);
    if (!plane.ok()) return InvalidArgumentError(path + ": " + plane.status().message());
    positions.plane_ = std::move(plane).value();
    return positions;
  }

  bool geo_referenced() const { return plane_.has_value(); }

  // (longitude, latitude) or the map point; nullopt when it is not finite.
  std::optional<Eigen::Vector2d> Of(const Eigen::Vector2d& map_point) const {
    if (!map_point.allFinite()) return std::nullopt;
    if (!plane_) return map_point;
    const geo::Wgs84 wgs84 = plane_->LatLonFromMap(map_point);
    const Eigen::Vector2d lon_lat(wgs84.longitude_deg, wgs84.latitude_deg);
    if (!lon_lat.allFinite()) return std::nullopt;
    return lon_lat;
  }

 private:
  std::optional<geo::LocalTangentPlane> plane_;
};

std::vector<Eigen::Vector2d> TrackPositions(const mission::ActivityTrack& track,
                                            const Positions& positions) {
  std::vector<Eigen::Vector2d> out;
  out.reserve(track.points.size());
  for (const auto& point : track.points) {
    if (auto position = positions.Of(point.map)) out.push_back(*position);
  }
  return out;
}

// The analyst's review of a track as text fields: verdict, label, note (each empty when unset).
struct ReviewFields {
  std::string verdict, label, note;
};
ReviewFields ReviewFieldsOf(const mission::Mission& mission, int64_t track_id) {
  const mission::TrackReview* review = mission::ReviewOf(mission, track_id);
  if (review == nullptr) return {};
  return {mission::VerdictName(review->verdict), mission::TargetLabelName(review->label),
          review->note};
}

// ---------------------------------------------------------------------------------------------
// GeoJSON

// Text, or null when empty.
Json TextOrNull(const std::string& text) { return text.empty() ? Json(nullptr) : Json(text); }

Json GeoJsonGeometry(const std::vector<Eigen::Vector2d>& positions) {
  if (positions.empty()) return nullptr;
  auto position = [](const Eigen::Vector2d& p) { return Json::array({p.x(), p.y()}); };
  if (positions.size() == 1) {
    return {{"type", "Point"}, {"coordinates", position(positions[0])}};
  }
  Json coordinates = Json::array();
  for (const auto& p : positions) coordinates.push_back(position(p));
  return {{"type", "LineString"}, {"coordinates", std::move(coordinates)}};
}

Json GeoJsonFeature(const mission::ActivityTrack& track, const ReviewFields& review,
                    const Positions& positions) {
  Json points = Json::array();
  for (const auto& p : track.points) {
    points.push_back({
        {"frame", p.frame},
        {"time_s", JsonNumber(p.time_s)},
        {"image", {JsonNumber(p.image.x()), JsonNumber(p.image.y())}},
        {"box",
         {JsonNumber(p.box_min.x()), JsonNumber(p.box_min.y()), JsonNumber(p.box_max.x()),
          JsonNumber(p.box_max.y())}},
        {"map", {JsonNumber(p.map.x()), JsonNumber(p.map.y())}},
        {"interpolated", p.interpolated},
    });
  }
  Json properties = {
      {"id", track.id},
      {"visit", track.visit},
      {"start_s", JsonNumber(track.start_s)},
      {"end_s", JsonNumber(track.end_s)},
      {"duration_s", JsonNumber(track.end_s - track.start_s)},
      {"length", JsonNumber(track.length)},
      {"speed", JsonNumber(track.speed)},
      {"speed_mps", JsonNumber(track.speed_mps)},
      {"heading_deg", JsonNumber(track.heading_deg)},
      {"point_count", track.points.size()},
      {"confidence", JsonNumber(track.confidence)},
      {"verdict", TextOrNull(review.verdict)},
      {"label", TextOrNull(review.label)},
      {"note", TextOrNull(review.note)},
      {"points", std::move(points)},
  };
  return {{"type", "Feature"},
          {"id", track.id},
          {"geometry", GeoJsonGeometry(TrackPositions(track, positions))},
          {"properties", std::move(properties)}};
}

// ---------------------------------------------------------------------------------------------
// KML

// ColorBrewer Set1 as KML colours (aabbggrr), one per visit, cycling.
constexpr std::array<const char*, 8> kVisitColours = {
    "ff1c1ae4", "ffb87e37", "ff4aaf4d", "ffa34e98", "ff007fff", "ff33ffff", "ff2856a6", "ffbf81f7",
};

std::string VisitStyleId(int visit) { return "visit-" + std::to_string(visit); }

std::string KmlStyle(int visit) {
  const int n = static_cast<int>(kVisitColours.size());
  const char* colour = kVisitColours[((visit - 1) % n + n) % n];
  std::ostringstream out;
  out << "<Style id=\"" << VisitStyleId(visit) << "\">"
      << "<LineStyle><color>" << colour << "</color><width>3</width></LineStyle>"
      << "<IconStyle><color>" << colour << "</color></IconStyle>"
      << "</Style>\n";
  return out.str();
}

// A Data element; none for an absent value (a non-finite number), which has no text in KML.
void KmlData(const std::string& name, const std::string& value, std::string& out) {
  if (value.empty()) return;
  out += "<Data name=\"" + XmlText(name) + "\"><value>" + XmlText(value) + "</value></Data>";
}

// A per-observation list for ExtendedData: comma-separated in point order, an absent
// (non-finite) value an empty item, as in the CSV.
template <typename Get>
std::string KmlList(const mission::ActivityTrack& track, Get get) {
  std::string out;
  for (size_t i = 0; i < track.points.size(); ++i) {
    if (i > 0) out += ',';
    out += FormatNumber(get(track.points[i]));
  }
  return out;
}

std::string KmlPlacemark(const mission::ActivityTrack& track, const ReviewFields& review,
                         const Positions& positions, const std::string& video) {
  using Point = mission::TrackPoint;
  std::string out = "<Placemark id=\"track-" + std::to_string(track.id) + "\">";
  out += "<name>Track " + std::to_string(track.id) + "</name>";
  std::ostringstream description;
  description << "Visit " << track.visit << ", ";
  if (std::isfinite(track.start_s) && std::isfinite(track.end_s)) {
    description << FormatNumber(track.start_s) << " - " << FormatNumber(track.end_s) << " s, ";
  }
  description << track.points.size() << " points";
  if (!video.empty()) description << ", video " << video;
  if (!review.verdict.empty()) description << "; analyst: " << review.verdict;
  if (!review.label.empty()) description << "; " << review.label;
  if (!review.note.empty()) description << "; " << review.note;
  out += "<description>" + XmlText(description.str()) + "</description>";
  out += "<styleUrl>#" + VisitStyleId(track.visit) + "</styleUrl>";
  out += "<ExtendedData>";
  KmlData("id", std::to_string(track.id), out);
  KmlData("visit", std::to_string(track.visit), out);
  KmlData("start_s", FormatNumber(track.start_s), out);
  KmlData("end_s", FormatNumber(track.end_s), out);
  KmlData("duration_s", FormatNumber(track.end_s - track.start_s), out);
  KmlData("length", FormatNumber(track.length), out);
  KmlData("speed", FormatNumber(track.speed), out);
  KmlData("speed_mps", track.speed_mps ? FormatNumber(*track.speed_mps) : "", out);
  KmlData("heading_deg", FormatNumber(track.heading_deg), out);
  KmlData("point_count", std::to_string(track.points.size()), out);
  KmlData("confidence", track.confidence ? FormatNumber(*track.confidence) : "", out);
  KmlData("verdict", review.verdict, out);
  KmlData("label", review.label, out);
  KmlData("note", review.note, out);
  KmlData("frames", KmlList(track, [](const Point& p) { return static_cast<double>(p.frame); }),
          out);
  KmlData("times_s", KmlList(track, [](const Point& p) { return p.time_s; }), out);
  KmlData("image_x", KmlList(track, [](const Point& p) { return p.image.x(); }), out);
  KmlData("image_y", KmlList(track, [](const Point& p) { return p.image.y(); }), out);
  KmlData("box_min_x", KmlList(track, [](const Point& p) { return p.box_min.x(); }), out);
  KmlData("box_min_y", KmlList(track, [](const Point& p) { return p.box_min.y(); }), out);
  KmlData("box_max_x", KmlList(track, [](const Point& p) { return p.box_max.x(); }), out);
  KmlData("box_max_y", KmlList(track, [](const Point& p) { return p.box_max.y(); }), out);
  KmlData("map_x", KmlList(track, [](const Point& p) { return p.map.x(); }), out);
  KmlData("map_y", KmlList(track, [](const Point& p) { return p.map.y(); }), out);
  KmlData("interpolated", KmlList(track, [](const Point& p) { return p.interpolated ? 1.0 : 0.0; }),
          out);
  out += "</ExtendedData>";

  const std::vector<Eigen::Vector2d> lon_lat = TrackPositions(track, positions);
  std::string coordinates;
  for (const auto& p : lon_lat) {
    if (!coordinates.empty()) coordinates += ' ';
    coordinates += FormatNumber(p.x()) + "," + FormatNumber(p.y());
  }
  if (lon_lat.size() == 1) {
    out += "<Point><coordinates>" + coordinates + "</coordinates></Point>";
  } else if (lon_lat.size() > 1) {
    out += "<LineString><tessellate>1</tessellate><coordinates>" + coordinates +
           "</coordinates></LineString>";
  }
  out += "</Placemark>\n";
  return out;
}

// ---------------------------------------------------------------------------------------------
// GeoTIFF

void RegisterGdalOnce() {
  static std::once_flag once;
  std::call_once(once, [] { GDALAllRegister(); });
}

// Collects GDAL's first failure message on this thread while alive (instead of GDAL printing
// it), so errors can be returned with the file's name.
class GdalErrors {
 public:
  GdalErrors() {
    CPLErrorReset();
    CPLPushErrorHandlerEx(&GdalErrors::Handler, this);
  }
  ~GdalErrors() { CPLPopErrorHandler(); }
  GdalErrors(const GdalErrors&) = delete;
  GdalErrors& operator=(const GdalErrors&) = delete;

  bool failed() const { return failed_; }
  // The first failure's text, or `fallback` when GDAL gave none.
  std::string message(const std::string& fallback) const {
    return message_.empty() ? fallback : message_;
  }

 private:
  static void CPL_STDCALL Handler(CPLErr error_class, CPLErrorNum, const char* text) {
    auto* self = static_cast<GdalErrors*>(CPLGetErrorHandlerUserData());
    if (self == nullptr || error_class < CE_Failure) return;
    if (!self->failed_ && text != nullptr) self->message_ = text;
    self->failed_ = true;
  }

  bool failed_ = false;
  std::string message_;
};

struct DatasetCloser {
  void operator()(void* dataset) const { GDALClose(static_cast<GDALDatasetH>(dataset)); }
};
using DatasetPtr = std::unique_ptr<void, DatasetCloser>;

struct SrsDeleter {
  void operator()(void* srs) const {
    OSRDestroySpatialReference(static_cast<OGRSpatialReferenceH>(srs));
  }
};
using SrsPtr = std::unique_ptr<void, SrsDeleter>;

// Pixel size of pyramid level `level`: ceil(size / 2^level).
int LevelSize(int size, int level) {
  return static_cast<int>((static_cast<int64_t>(size) + (int64_t{1} << level) - 1) >> level);
}

Status ValidateGeoTiffInputs(const mission::PyramidInfo& pyramid, int level,
                             const TileReader& read_tile, const std::string& path) {
  std::ostringstream problem;
  if (pyramid.tile_size < 1 || pyramid.tile_size > 16384) {
    problem << "tile size " << pyramid.tile_size << " is not 1..16384";
  } else if (pyramid.levels < 1 || pyramid.levels > 30) {
    problem << "the pyramid has " << pyramid.levels << " levels (1..30 expected)";
  } else if (pyramid.width < 1 || pyramid.height < 1) {
    problem << "the pyramid is " << pyramid.width << " x " << pyramid.height << " pixels";
  } else if (!pyramid.map_origin.allFinite() || !std::isfinite(pyramid.step_x) ||
             !std::isfinite(pyramid.step_y) || pyramid.step_x == 0 || pyramid.step_y == 0) {
    problem << "the pyramid's map placement is not finite and non-degenerate (origin "
            << pyramid.map_origin.transpose() << ", steps " << pyramid.step_x << ", "
            << pyramid.step_y << ")";
  } else if (level < 0 || level >= pyramid.levels) {
    problem << "level " << level << " is outside the pyramid's levels 0.." << pyramid.levels - 1;
  } else if (!read_tile) {
    problem << "no tile reader";
  }
  const std::string text = problem.str();
  return text.empty() ? Status::Ok() : InvalidArgumentError(path + ": " + text);
}

// The geotransform of a geo-referenced raster, fitted to the exact mapping.
struct GeoFit {
  int epsg = 0;
  std::string crs;
  std::array<double, 6> geotransform{};
  double max_error_m = 0;
};

// Fits UTM = affine(pixel corner coordinates) by least squares to the exact map -> WGS84 -> UTM
// mapping of a 9 x 9 grid over the raster, and measures the misfit on a 17 x 17 grid (which
// contains the fitted points and the midpoints between them).
StatusOr<GeoFit> FitUtmGeotransform(const geo::Wgs84& origin, const mission::PyramidInfo& pyramid,
                                    int level, int width, int height, const std::string& path) {
  auto created = geo::LocalTangentPlane::Create(origin);
  if (!created.ok()) return InvalidArgumentError(path + ": " + created.status().message());
  const geo::LocalTangentPlane& plane = *created;
  auto origin_utm = geo::UtmFromWgs84(origin);
  if (!origin_utm.ok()) {
    return UnsupportedError(path + ": the map origin is outside UTM's range, so the GeoTIFF " +
                            "cannot be written in UTM (" + origin_utm.status().message() + ")");
  }
  const std::pair<int, bool> zone(origin_utm->zone, origin_utm->north);

  // Map point of pixel corner coordinates (u, v) of this level: level-0 pixel centres sit at
  // map_origin + (col, row) * step, so the raster's outer corner is half a level-0 pixel before
  // the first centre, and a level pixel spans 2^level level-0 pixels.
  const double scale = std::ldexp(1.0, level);
  const Eigen::Vector2d corner =
      pyramid.map_origin - 0.5 * Eigen::Vector2d(pyramid.step_x, pyramid.step_y);
  auto exact = [&](double u, double v) -> StatusOr<Eigen::Vector2d> {
    const Eigen::Vector2d map =
        corner + Eigen::Vector2d(u * scale * pyramid.step_x, v * scale * pyramid.step_y);
    auto utm = geo::UtmFromWgs84(plane.LatLonFromMap(map), zone);
    if (!utm.ok()) {
      return UnsupportedError(path + ": the raster reaches outside UTM's range (" +
                              utm.status().message() + ")");
    }
    return Eigen::Vector2d(utm->easting, utm->northing);
  };

  // Centred, normalised pixel coordinates keep the least-squares problem well conditioned.
  const double uc = 0.5 * width, vc = 0.5 * height;
  const double su = std::max(1.0, 0.5 * width), sv = std::max(1.0, 0.5 * height);
  constexpr int kFitGrid = 9;
  Eigen::MatrixXd design(kFitGrid * kFitGrid, 3);
  Eigen::MatrixXd target(kFitGrid * kFitGrid, 2);
  for (int j = 0; j < kFitGrid; ++j) {
    for (int i = 0; i < kFitGrid; ++i) {
      const double u = width * static_cast<double>(i) / (kFitGrid - 1);
      const double v = height * static_cast<double>(j) / (kFitGrid - 1);
      SAKER_ASSIGN_OR_RETURN(const Eigen::Vector2d utm, exact(u, v));
      const int row = j * kFitGrid + i;
      design.row(row) << 1.0, (u - uc) / su, (v - vc) / sv;
      target.row(row) = utm.transpose();
    }
  }
  const Eigen::MatrixXd c = design.colPivHouseholderQr().solve(target);  // 3 x 2
  GeoFit fit;
  // GDAL: X = gt[0] + u * gt[1] + v * gt[2], Y = gt[3] + u * gt[4] + v * gt[5].
  fit.geotransform = {c(0, 0) - c(1, 0) * uc / su - c(2, 0) * vc / sv, c(1, 0) / su, c(2, 0) / sv,
                      c(0, 1) - c(1, 1) * uc / su - c(2, 1) * vc / sv, c(1, 1) / su, c(2, 1) / sv};
  constexpr int kCheckGrid = 2 * (kFitGrid - 1) + 1;
  for (int j = 0; j < kCheckGrid; ++j) {
    for (int i = 0; i < kCheckGrid; ++i) {
      const double u = width * static_cast<double>(i) / (kCheckGrid - 1);
      const double v = height * static_cast<double>(j) / (kCheckGrid - 1);
      SAKER_ASSIGN_OR_RETURN(const Eigen::Vector2d utm, exact(u, v));
      const auto& g = fit.geotransform;
      const Eigen::Vector2d affine(g[0] + u * g[1] + v * g[2], g[3] + u * g[4] + v * g[5]);
      fit.max_error_m = std::max(fit.max_error_m, (affine - utm).norm());
    }
  }
  fit.epsg = geo::UtmEpsgCode(zone.first, zone.second);
  fit.crs = "EPSG:" + std::to_string(fit.epsg) + " (WGS 84 / UTM zone " +
            std::to_string(zone.first) + (zone.second ? "N" : "S") + ")";
  return fit;
}

// Checks a tile from the reader: CV_8UC4, and between the part inside the raster and a full
// tile in each direction.
Status CheckTile(const cv::Mat& tile, int level, int tx, int ty, int inside_w, int inside_h,
                 int tile_size, const std::string& path) {
  if (tile.type() == CV_8UC4 && tile.cols >= inside_w && tile.cols <= tile_size &&
      tile.rows >= inside_h && tile.rows <= tile_size) {
    return Status::Ok();
  }
  std::ostringstream message;
  message << path << ": tile (level " << level << ", x " << tx << ", y " << ty << ") is "
          << tile.cols << " x " << tile.rows << " of OpenCV type " << tile.type()
          << "; expected CV_8UC4 (type " << CV_8UC4 << ") of " << tile_size << " x " << tile_size
          << " pixels (or " << inside_w << " x " << inside_h << " at the raster edge)";
  return InvalidDataError(message.str());
}

// The GTiff creation options: tiled in `block`-pixel blocks, DEFLATE with the horizontal
// predictor, RGBA with an unassociated alpha, BigTIFF when it may be needed. CSLDestroy it.
char** GeoTiffCreationOptions(int block_px) {
  const std::string block = std::to_string(block_px);
  char** options = nullptr;
  options = CSLSetNameValue(options, "TILED", "YES");
  options = CSLSetNameValue(options, "BLOCKXSIZE", block.c_str());
  options = CSLSetNameValue(options, "BLOCKYSIZE", block.c_str());
  options = CSLSetNameValue(options, "COMPRESS", "DEFLATE");
  options = CSLSetNameValue(options, "PREDICTOR", "2");
  options = CSLSetNameValue(options, "PHOTOMETRIC", "RGB");
  options = CSLSetNameValue(options, "ALPHA", "UNASSOCIATED");
  options = CSLSetNameValue(options, "INTERLEAVE", "PIXEL");
  options = CSLSetNameValue(options, "BIGTIFF", "IF_SAFER");
  return options;
}

// Sets the bands' colour interpretation (RGBA) and, for a geo-referenced map, the geotransform
// and the CRS.
Status DescribeBands(GDALDatasetH ds, const std::optional<GeoFit>& fit, const std::string& path,
                     const GdalErrors& errors) {
  constexpr std::array<GDALColorInterp, 4> kInterp = {GCI_RedBand, GCI_GreenBand, GCI_BlueBand,
                                                      GCI_AlphaBand};
  for (int b = 0; b < 4; ++b) {
    if (GDALSetRasterColorInterpretation(GDALGetRasterBand(ds, b + 1), kInterp[b]) != CE_None) {
      return IoError(path + ": cannot set the colour interpretation of band " +
                     std::to_string(b + 1) + " (" + errors.message("no reason") + ")");
    }
  }
  if (!fit) return Status::Ok();
  std::array<double, 6> geotransform = fit->geotransform;  // GDAL takes it non-const
  if (GDALSetGeoTransform(ds, geotransform.data()) != CE_None) {
    return IoError(path + ": cannot set the geotransform (" + errors.message("no reason") + ")");
  }
  SrsPtr srs(OSRNewSpatialReference(nullptr));
  if (!srs || OSRImportFromEPSG(srs.get(), fit->epsg) != OGRERR_NONE) {
    return IoError(path + ": cannot set up " + fit->crs + " (is PROJ's database installed?) (" +
                   errors.message("no reason") + ")");
  }
  if (GDALSetSpatialRef(ds, srs.get()) != CE_None) {
    return IoError(path + ": cannot set the CRS (" + errors.message("no reason") + ")");
  }
  return Status::Ok();
}

// Copies the pyramid level's tiles (`ts` pixels) into the dataset, row by row; with
// `flush_rows` (file blocks equal to the tiles) each finished row is flushed, so memory holds one
// row of tiles at most.
Status WriteTiles(GDALDatasetH ds, const TileReader& read_tile, int level,
                  const GeoTiffReport& report, int ts, bool flush_rows, const std::string& path,
                  const GdalErrors& errors) {
  // The reader's BGRA goes to the file's bands 3, 2, 1, 4 (RGBA).
  std::array<int, 4> band_map = {3, 2, 1, 4};
  const cv::Mat transparent(ts, ts, CV_8UC4, cv::Scalar::all(0));
  const int tiles_x = (report.width + ts - 1) / ts;
  const int tiles_y = (report.height + ts - 1) / ts;
  for (int ty = 0; ty < tiles_y; ++ty) {
    for (int tx = 0; tx < tiles_x; ++tx) {
      const int x0 = tx * ts, y0 = ty * ts;
      const int w = std::min(ts, report.width - x0), h = std::min(ts, report.height - y0);
      StatusOr<cv::Mat> tile = read_tile(level, tx, ty);
      if (!tile.ok()) {
        return Status(tile.status().code(), path + ": reading tile (level " +
                                                std::to_string(level) + ", x " +
                                                std::to_string(tx) + ", y " + std::to_string(ty) +
                                                ") failed: " + tile.status().message());
      }
      const cv::Mat& pixels = tile->empty() ? transparent : *tile;
      if (!tile->empty()) {
        SAKER_RETURN_IF_ERROR(CheckTile(pixels, level, tx, ty, w, h, ts, path));
      }
      const CPLErr written = GDALDatasetRasterIOEx(
          ds, GF_Write, x0, y0, w, h, const_cast<uchar*>(pixels.data), w, h, GDT_Byte, 4,
          band_map.data(), 4, static_cast<GSpacing>(pixels.step[0]), 1, nullptr);
      if (written != CE_None || errors.failed()) {
        return IoError(path + ": writing tile (" + std::to_string(tx) + ", " + std::to_string(ty) +
                       ") failed (" + errors.message("no reason") + ")");
      }
    }
    if (flush_rows) GDALFlushCache(ds);
  }
  return Status::Ok();
}

StatusOr<GeoTiffReport> WriteGeoTiff(const mission::MapFrame& map,
                                     const mission::PyramidInfo& pyramid, int level,
                                     const TileReader& read_tile, const std::string& path) {
  SAKER_RETURN_IF_ERROR(ValidateGeoTiffInputs(pyramid, level, read_tile, path));
  GeoTiffReport report;
  report.width = LevelSize(pyramid.width, level);
  report.height = LevelSize(pyramid.height, level);

  std::optional<GeoFit> fit;
  if (map.geo_referenced) {
    if (!map.origin) {
      return InvalidArgumentError(path +
                                  ": the mission is marked geo-referenced but has no map origin");
    }
    SAKER_ASSIGN_OR_RETURN(
        fit, FitUtmGeotransform(*map.origin, pyramid, level, report.width, report.height, path));
    report.crs = fit->crs;
    report.max_fit_error_m = fit->max_error_m;
  } else {
    report.crs = "none (not geo-referenced)";
  }

  RegisterGdalOnce();
  GdalErrors errors;
  GDALDriverH driver = GDALGetDriverByName("GTiff");
  if (driver == nullptr) return UnsupportedError(path + ": GDAL has no GTiff driver");

  // GeoTIFF tiles must be multiples of 16 pixels: the pyramid's own tiles when they are, so each
  // file block is written once, whole, and flushed after each row of tiles.
  const int ts = pyramid.tile_size;
  const bool aligned_blocks = ts % 16 == 0;
  char** options = GeoTiffCreationOptions(aligned_blocks ? ts : 256);
  // GDAL may write an ".aux.xml" beside the file for what TIFF tags cannot hold.
  FileReplacement replacement(path, {.side_suffixes = {".aux.xml"}});
  const std::string& partial = replacement.temporary();
  DatasetPtr dataset(
      GDALCreate(driver, partial.c_str(), report.width, report.height, 4, GDT_Byte, options));
  CSLDestroy(options);
  // From here on, every failure removes the partial file (after the dataset is closed).
  auto fail = [&](Status status) -> Status {
    dataset.reset();
    replacement.Discard();
    return status;
  };
  if (!dataset) {
    return fail(
        IoError(path + ": cannot create the file (" + errors.message("GDAL gave no reason") + ")"));
  }
  GDALDatasetH ds = dataset.get();
  if (Status described = DescribeBands(ds, fit, path, errors); !described.ok()) {
    return fail(described);
  }
  if (Status written = WriteTiles(ds, read_tile, level, report, ts, aligned_blocks, path, errors);
      !written.ok()) {
    return fail(written);
  }
  dataset.reset();  // closes the file, writing what remains
  if (errors.failed()) {
    return fail(IoError(path + ": writing the file failed (" + errors.message("no reason") + ")"));
  }
  SAKER_RETURN_IF_ERROR(replacement.Commit());
  return report;
}

}  // namespace

Status ExportGeoJson(const mission::Mission& mission, const std::string& path) {
  return Guarded(path, [&]() -> Status {
    SAKER_ASSIGN_OR_RETURN(const Positions positions, Positions::Create(mission.map, path));
    Json features = Json::array();
    for (const auto& track : mission.tracks) {
      features.push_back(GeoJsonFeature(track, ReviewFieldsOf(mission, track.id), positions));
    }
    // The analyst's bookmarks: points with their time and note.
    for (const mission::Bookmark& bookmark : mission.bookmarks) {
      const std::optional<Eigen::Vector2d> at = positions.Of(bookmark.map);
      features.push_back({{"type", "Feature"},
                          {"id", "bookmark-" + std::to_string(bookmark.id)},
                          {"geometry", at ? GeoJsonGeometry({*at}) : Json(nullptr)},
                          {"properties",
                           {{"bookmark", bookmark.id},
                            {"time_s", JsonNumber(bookmark.time_s)},
                            {"map", {JsonNumber(bookmark.map.x()), JsonNumber(bookmark.map.y())}},
                            {"note", bookmark.note}}}});
    }
    // A foreign member (RFC 7946 section 6.1) says what the numbers mean.
    Json about = {
        {"video", VideoName(mission)},
        {"geo_referenced", positions.geo_referenced()},
        {"coordinates", positions.geo_referenced()
                            ? "WGS 84 longitude, latitude (degrees)"
                            : "map pixels of the first key frame (x right, y down); no CRS"},
        {"length_unit", positions.geo_referenced() ? "m" : "px"},
    };
    if (positions.geo_referenced()) {
      about["map_origin"] = {{"latitude_deg", mission.map.origin->latitude_deg},
                             {"longitude_deg", mission.map.origin->longitude_deg},
                             {"height_m", mission.map.origin->height_m}};
    }
    const Json collection = {
        {"type", "FeatureCollection"}, {"saker", std::move(about)}, {"features", features}};
    std::string text = collection.dump(-1, ' ', false, Json::error_handler_t::replace);
    text += '\n';
    return ReplaceFileContents(path, text);
  });
}

Status ExportKml(const mission::Mission& mission, const std::string& path) {
  return Guarded(path, [&]() -> Status {
    if (!mission.map.geo_referenced) {
      return UnsupportedError(
          path + ": KML needs a geo-referenced mission (KML positions are WGS 84 longitude and " +
          "latitude, and this mission's map is in video pixels); export GeoJSON or CSV instead");
    }
    SAKER_ASSIGN_OR_RETURN(const Positions positions, Positions::Create(mission.map, path));
    const std::string video = VideoName(mission);
    std::string out =
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
        "<kml xmlns=\"http://www.opengis.net/kml/2.2\">\n<Document>\n";
    out += "<name>" + XmlText("Saker tracks" + (video.empty() ? "" : ": " + video)) + "</name>\n";
    std::set<int> visits;
    for (const auto& track : mission.tracks) visits.insert(track.visit);
    for (int visit : visits) out += KmlStyle(visit);
    for (const auto& track : mission.tracks) {
      out += KmlPlacemark(track, ReviewFieldsOf(mission, track.id), positions, video);
    }
    for (const mission::Bookmark& bookmark : mission.bookmarks) {
      const std::optional<Eigen::Vector2d> at = positions.Of(bookmark.map);
      if (!at) continue;
      out += "<Placemark id=\"bookmark-" + std::to_string(bookmark.id) + "\"><name>" +
             XmlText("Bookmark " + std::to_string(bookmark.id) +
                     (bookmark.note.empty() ? "" : ": " + bookmark.note)) +
             "</name><description>" + XmlText(FormatNumber(bookmark.time_s) + " s") +
             "</description><ExtendedData>";
      KmlData("time_s", FormatNumber(bookmark.time_s), out);
      KmlData("note", bookmark.note, out);
      out += "</ExtendedData><Point><coordinates>" + FormatNumber(at->x()) + "," +
             FormatNumber(at->y()) + "</coordinates></Point></Placemark>\n";
    }
    out += "</Document>\n</kml>\n";
    return ReplaceFileContents(path, out);
  });
}

Status ExportCsv(const mission::Mission& mission, const std::string& path) {
  return Guarded(path, [&]() -> Status {
    SAKER_ASSIGN_OR_RETURN(const Positions positions, Positions::Create(mission.map, path));
    static constexpr const char* kHeader =
        "video,track_id,visit,start_s,end_s,duration_s,length,speed,speed_mps,heading_deg,"
        "point_count,point_index,frame,time_s,image_x,image_y,box_min_x,box_min_y,box_max_x,"
        "box_max_y,map_x,map_y,latitude_deg,longitude_deg,confidence,verdict,label,note,"
        "interpolated\r\n";
    const std::string video = CsvField(VideoName(mission));
    std::string out = kHeader;
    for (const auto& track : mission.tracks) {
      const ReviewFields review = ReviewFieldsOf(mission, track.id);
      const std::string review_fields =
          "," + review.verdict + "," + review.label + "," + CsvField(review.note);
      const std::string track_fields =
          video + "," + std::to_string(track.id) + "," + std::to_string(track.visit) + "," +
          FormatNumber(track.start_s) + "," + FormatNumber(track.end_s) + "," +
          FormatNumber(track.end_s - track.start_s) + "," + FormatNumber(track.length) + "," +
          FormatNumber(track.speed) + "," +
          (track.speed_mps ? FormatNumber(*track.speed_mps) : "") + "," +
          FormatNumber(track.heading_deg) + "," + std::to_string(track.points.size());
      for (size_t i = 0; i < track.points.size(); ++i) {
        const auto& p = track.points[i];
        out += track_fields;
        for (const std::string& field :
             {std::to_string(i), std::to_string(p.frame), FormatNumber(p.time_s),
              FormatNumber(p.image.x()), FormatNumber(p.image.y()), FormatNumber(p.box_min.x()),
              FormatNumber(p.box_min.y()), FormatNumber(p.box_max.x()), FormatNumber(p.box_max.y()),
              FormatNumber(p.map.x()), FormatNumber(p.map.y())}) {
          out += "," + field;
        }
        std::optional<Eigen::Vector2d> lon_lat;
        if (positions.geo_referenced()) lon_lat = positions.Of(p.map);
        out += "," + (lon_lat ? FormatNumber(lon_lat->y()) : "");
        out += "," + (lon_lat ? FormatNumber(lon_lat->x()) : "");
        out += "," + (track.confidence ? FormatNumber(*track.confidence) : "");
        out += review_fields;
        out += p.interpolated ? ",1\r\n" : ",0\r\n";
      }
    }
    return ReplaceFileContents(path, out);
  });
}

StatusOr<GeoTiffReport> ExportGeoTiff(const mission::MapFrame& map,
                                      const mission::PyramidInfo& pyramid, int level,
                                      const TileReader& read_tile, const std::string& path) {
  return Guarded(path, [&]() -> StatusOr<GeoTiffReport> {
    return WriteGeoTiff(map, pyramid, level, read_tile, path);
  });
}

}  // namespace saker::exporting
