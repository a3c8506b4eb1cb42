#include "core/export/export.h"

#include "core/geo/local_tangent_plane.h"
#include "tests/testing/test_data.h"

#include <gdal.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <ogr_api.h>
#include <ogr_srs_api.h>
#include <opencv2/core.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <limits>
#include <map>
#include <string>
#include <vector>

namespace saker::exporting {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;

constexpr geo::Wgs84 kOrigin{51.5, -1.2, 80.0};
// A video name with characters that need escaping in every format: a comma (CSV), quotes and
// markup characters (KML).
const char kVideoPath[] = "/data/flights/sortie 3, \"low\" <a&b>.ts";
const char kVideoName[] = "sortie 3, \"low\" <a&b>.ts";

mission::ActivityTrack MakeTrack(int64_t id, int visit, const std::vector<Eigen::Vector2d>& map) {
  mission::ActivityTrack track;
  track.id = id;
  track.visit = visit;
  for (size_t i = 0; i < map.size(); ++i) {
    mission::TrackPoint point;
    point.frame = 100 * id + 2 * static_cast<int64_t>(i);
    point.time_s = point.frame / 25.0;
    point.image = {320.5 + i, 240.25 - i};
    point.box_min = point.image - Eigen::Vector2d(4, 3);
    point.box_max = point.image + Eigen::Vector2d(4, 3);
    point.map = map[i];
    point.interpolated = i == 1;  // the second point was not seen
    track.points.push_back(point);
  }
  track.start_s = track.points.empty() ? 0 : track.points.front().time_s;
  track.end_s = track.points.empty() ? 0 : track.points.back().time_s;
  track.length = 12.5 * id;
  track.speed = 3.25;
  track.speed_mps = 3.25;
  track.heading_deg = 45.0 * id;
  track.confidence = 0.25 * static_cast<double>(id);
  return track;
}

// Three tracks: a line of four points, a single point, a line of three points on visit 2.
mission::Mission MakeMission(bool geo_referenced) {
  mission::Mission mission;
  mission.source.path = kVideoPath;
  mission.map.geo_referenced = geo_referenced;
  if (geo_referenced) mission.map.origin = kOrigin;
  mission.tracks.push_back(
      MakeTrack(1, 1, {{-310.0, 120.5}, {-300.0, 125.0}, {-290.0, 131.0}, {-281.5, 140.0}}));
  mission.tracks.push_back(MakeTrack(2, 1, {{850.25, -415.0}}));
  mission.tracks.push_back(MakeTrack(3, 2, {{10.0, 10.0}, {1200.0, -900.0}, {1210.0, -905.0}}));
  return mission;
}

int TotalPoints(const mission::Mission& mission) {
  int total = 0;
  for (const auto& track : mission.tracks) total += static_cast<int>(track.points.size());
  return total;
}

std::string ReadText(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

geo::LocalTangentPlane Plane() { return *geo::LocalTangentPlane::Create(kOrigin); }

// Whether a temporary of an export to `path` (a FileReplacement's ".NAME.part-...") is left.
bool HasTemporary(const fs::path& path) {
  const std::string prefix = "." + path.filename().string() + ".part-";
  for (const auto& entry : fs::directory_iterator(path.parent_path())) {
    if (entry.path().filename().string().rfind(prefix, 0) == 0) return true;
  }
  return false;
}

// Fails the test unless no output (final or partial) is left at `path`.
void ExpectNoFile(const fs::path& path) {
  EXPECT_FALSE(fs::exists(path)) << path;
  EXPECT_FALSE(HasTemporary(path)) << path;
}

// ---------------------------------------------------------------------------------------------
// GeoJSON

TEST(GeoJsonExportTest, GeoReferencedFeaturesHaveWgs84LonLatAndAttributes) {
  const auto dir = testing::MakeTempDir("saker-export");
  const fs::path path = dir / "tracks.geojson";
  const mission::Mission mission = MakeMission(true);
  ASSERT_TRUE(ExportGeoJson(mission, path.string()).ok());
  EXPECT_FALSE(HasTemporary(path));

  const Json json = Json::parse(ReadText(path));
  EXPECT_EQ(json["type"], "FeatureCollection");
  EXPECT_FALSE(json.contains("crs"));  // RFC 7946: WGS 84 implied
  ASSERT_EQ(json["features"].size(), 3u);
  const auto plane = Plane();
  for (size_t t = 0; t < mission.tracks.size(); ++t) {
    const auto& track = mission.tracks[t];
    const Json& feature = json["features"][t];
    EXPECT_EQ(feature["type"], "Feature");
    EXPECT_EQ(feature["id"], track.id);
    const Json& geometry = feature["geometry"];
    Json positions = geometry["coordinates"];
    if (track.points.size() == 1) {
      EXPECT_EQ(geometry["type"], "Point");
      positions = Json::array({positions});
    } else {
      EXPECT_EQ(geometry["type"], "LineString");
    }
    ASSERT_EQ(positions.size(), track.points.size());
    for (size_t i = 0; i < track.points.size(); ++i) {
      const geo::Wgs84 expected = plane.LatLonFromMap(track.points[i].map);
      ASSERT_EQ(positions[i].size(), 2u);
      EXPECT_NEAR(positions[i][0].get<double>(), expected.longitude_deg, 1e-9);
      EXPECT_NEAR(positions[i][1].get<double>(), expected.latitude_deg, 1e-9);
    }
    const Json& properties = feature["properties"];
    EXPECT_EQ(properties["id"], track.id);
    EXPECT_EQ(properties["visit"], track.visit);
    EXPECT_DOUBLE_EQ(properties["start_s"].get<double>(), track.start_s);
    EXPECT_DOUBLE_EQ(properties["end_s"].get<double>(), track.end_s);
    EXPECT_DOUBLE_EQ(properties["duration_s"].get<double>(), track.end_s - track.start_s);
    EXPECT_DOUBLE_EQ(properties["length"].get<double>(), track.length);
    EXPECT_DOUBLE_EQ(properties["speed"].get<double>(), track.speed);
    EXPECT_DOUBLE_EQ(properties["speed_mps"].get<double>(), *track.speed_mps);
    EXPECT_DOUBLE_EQ(properties["heading_deg"].get<double>(), track.heading_deg);
    EXPECT_EQ(properties["point_count"], track.points.size());
    EXPECT_DOUBLE_EQ(properties["confidence"].get<double>(), *track.confidence);
    ASSERT_EQ(properties["points"].size(), track.points.size());
    const Json& last = properties["points"].back();
    const auto& point = track.points.back();
    EXPECT_EQ(last["frame"], point.frame);
    EXPECT_DOUBLE_EQ(last["time_s"].get<double>(), point.time_s);
    EXPECT_DOUBLE_EQ(last["image"][0].get<double>(), point.image.x());
    EXPECT_DOUBLE_EQ(last["image"][1].get<double>(), point.image.y());
    EXPECT_DOUBLE_EQ(last["box"][0].get<double>(), point.box_min.x());
    EXPECT_DOUBLE_EQ(last["box"][3].get<double>(), point.box_max.y());
    EXPECT_DOUBLE_EQ(last["map"][0].get<double>(), point.map.x());
    EXPECT_DOUBLE_EQ(last["map"][1].get<double>(), point.map.y());
    for (size_t i = 0; i < track.points.size(); ++i) {
      EXPECT_EQ(properties["points"][i]["interpolated"].get<bool>(), track.points[i].interpolated);
    }
  }
  EXPECT_EQ(json["saker"]["video"], kVideoName);
  EXPECT_TRUE(json["saker"]["geo_referenced"].get<bool>());
}

TEST(GeoJsonExportTest, NotGeoReferencedGivesMapCoordinates) {
  const auto dir = testing::MakeTempDir("saker-export");
  const fs::path path = dir / "tracks.geojson";
  const mission::Mission mission = MakeMission(false);
  ASSERT_TRUE(ExportGeoJson(mission, path.string()).ok());
  const Json json = Json::parse(ReadText(path));
  ASSERT_EQ(json["features"].size(), 3u);
  const Json& line = json["features"][0]["geometry"]["coordinates"];
  ASSERT_EQ(line.size(), 4u);
  for (size_t i = 0; i < 4; ++i) {
    EXPECT_DOUBLE_EQ(line[i][0].get<double>(), mission.tracks[0].points[i].map.x());
    EXPECT_DOUBLE_EQ(line[i][1].get<double>(), mission.tracks[0].points[i].map.y());
  }
  EXPECT_FALSE(json.contains("crs"));
  EXPECT_FALSE(json["saker"]["geo_referenced"].get<bool>());
  EXPECT_EQ(json["saker"]["length_unit"], "px");
}

TEST(GeoJsonExportTest, NonFiniteNumbersAreWrittenAsNull) {
  const auto dir = testing::MakeTempDir("saker-export");
  const fs::path path = dir / "tracks.geojson";
  mission::Mission mission = MakeMission(true);
  mission.tracks[0].speed_mps = std::numeric_limits<double>::quiet_NaN();
  mission.tracks[0].length = std::numeric_limits<double>::infinity();
  mission.tracks[2].speed_mps.reset();
  mission.tracks[2].confidence.reset();  // unknown (a mission of schema 3)
  mission.tracks[2].points[1].map.x() = std::numeric_limits<double>::quiet_NaN();
  ASSERT_TRUE(ExportGeoJson(mission, path.string()).ok());

  const std::string text = ReadText(path);
  EXPECT_EQ(text.find("NaN"), std::string::npos);
  EXPECT_EQ(text.find("nan"), std::string::npos);
  EXPECT_EQ(text.find("Infinity"), std::string::npos);
  Json json;
  ASSERT_NO_THROW(json = Json::parse(text));  // the strict parser rejects NaN and Infinity
  const Json& first = json["features"][0]["properties"];
  EXPECT_TRUE(first["speed_mps"].is_null());
  EXPECT_TRUE(first["length"].is_null());
  EXPECT_TRUE(json["features"][2]["properties"]["speed_mps"].is_null());
  EXPECT_TRUE(json["features"][2]["properties"]["confidence"].is_null());
  // The non-finite point stays in the observations but leaves the geometry.
  EXPECT_EQ(json["features"][2]["properties"]["points"].size(), 3u);
  EXPECT_TRUE(json["features"][2]["properties"]["points"][1]["map"][0].is_null());
  EXPECT_EQ(json["features"][2]["geometry"]["coordinates"].size(), 2u);
}

// ---------------------------------------------------------------------------------------------
// KML

struct KmlFeature {
  std::string name;
  std::string description;
  std::vector<Eigen::Vector2d> lon_lat;
};

// All features of a KML file as one GDAL vector driver reads them.
std::vector<KmlFeature> ReadKmlWithGdal(const fs::path& path, const char* driver) {
  GDALAllRegister();
  const char* drivers[] = {driver, nullptr};
  GDALDatasetH ds = GDALOpenEx(path.c_str(), GDAL_OF_VECTOR, drivers, nullptr, nullptr);
  EXPECT_NE(ds, nullptr) << driver << " cannot open " << path << ": " << CPLGetLastErrorMsg();
  std::vector<KmlFeature> features;
  if (ds == nullptr) return features;
  for (int l = 0; l < GDALDatasetGetLayerCount(ds); ++l) {
    OGRLayerH layer = GDALDatasetGetLayer(ds, l);
    OGR_L_ResetReading(layer);
    while (OGRFeatureH feature = OGR_L_GetNextFeature(layer)) {
      KmlFeature f;
      OGRFeatureDefnH defn = OGR_F_GetDefnRef(feature);
      for (int i = 0; i < OGR_FD_GetFieldCount(defn); ++i) {
        const std::string field = OGR_Fld_GetNameRef(OGR_FD_GetFieldDefn(defn, i));
        if (field == "Name" || field == "name") f.name = OGR_F_GetFieldAsString(feature, i);
        if (field == "Description" || field == "description") {
          f.description = OGR_F_GetFieldAsString(feature, i);
        }
      }
      if (OGRGeometryH geometry = OGR_F_GetGeometryRef(feature)) {
        for (int i = 0; i < OGR_G_GetPointCount(geometry); ++i) {
          f.lon_lat.emplace_back(OGR_G_GetX(geometry, i), OGR_G_GetY(geometry, i));
        }
      }
      features.push_back(f);
      OGR_F_Destroy(feature);
    }
  }
  GDALClose(ds);
  return features;
}

TEST(KmlExportTest, GdalReadsPlacemarksWithWgs84Coordinates) {
  const auto dir = testing::MakeTempDir("saker-export");
  const fs::path path = dir / "tracks.kml";
  const mission::Mission mission = MakeMission(true);
  ASSERT_TRUE(ExportKml(mission, path.string()).ok());
  GDALAllRegister();
  int drivers_tried = 0;
  for (const char* driver : {"KML", "LIBKML"}) {
    if (GDALGetDriverByName(driver) == nullptr) continue;
    ++drivers_tried;
    SCOPED_TRACE(driver);
    const auto features = ReadKmlWithGdal(path, driver);
    ASSERT_EQ(features.size(), 3u);
    const KmlFeature* track3 = nullptr;
    for (const auto& f : features) {
      if (f.name == "Track 3") track3 = &f;
    }
    ASSERT_NE(track3, nullptr);
    ASSERT_EQ(track3->lon_lat.size(), 3u);
    const geo::Wgs84 expected = Plane().LatLonFromMap(mission.tracks[2].points[1].map);
    EXPECT_NEAR(track3->lon_lat[1].x(), expected.longitude_deg, 1e-9);
    EXPECT_NEAR(track3->lon_lat[1].y(), expected.latitude_deg, 1e-9);
    // The escaped markup reads back as the original text.
    EXPECT_NE(track3->description.find(kVideoName), std::string::npos) << track3->description;
  }
  EXPECT_GT(drivers_tried, 0) << "GDAL has neither the KML nor the LIBKML driver";
}

TEST(KmlExportTest, MarkupInNamesIsEscapedAndStylesFollowVisits) {
  const auto dir = testing::MakeTempDir("saker-export");
  const fs::path path = dir / "tracks.kml";
  mission::Mission mission = MakeMission(true);
  mission.source.path = std::string("/v/<Placemark>&amp; \x01 bad\xff utf8.ts");
  ASSERT_TRUE(ExportKml(mission, path.string()).ok());
  const std::string text = ReadText(path);
  EXPECT_NE(text.find("&lt;Placemark&gt;&amp;amp;"), std::string::npos);
  EXPECT_EQ(text.find("<Placemark>&"), std::string::npos);
  EXPECT_EQ(text.find('\x01'), std::string::npos);
  EXPECT_EQ(text.find('\xff'), std::string::npos);
  EXPECT_NE(text.find("<Style id=\"visit-1\">"), std::string::npos);
  EXPECT_NE(text.find("<Style id=\"visit-2\">"), std::string::npos);
  EXPECT_NE(text.find("<styleUrl>#visit-2</styleUrl>"), std::string::npos);
  EXPECT_NE(text.find("<Data name=\"speed_mps\"><value>3.25</value></Data>"), std::string::npos);
  EXPECT_NE(text.find("<Data name=\"confidence\"><value>0.75</value></Data>"), std::string::npos);
  // Track 1's second point was not seen.
  EXPECT_NE(text.find("<Data name=\"interpolated\"><value>0,1,0,0</value></Data>"),
            std::string::npos);
  // Still well-formed: a strict reader (expat, in GDAL's KML driver) finds all placemarks.
  GDALAllRegister();
  if (GDALGetDriverByName("KML") == nullptr) GTEST_SKIP() << "no KML driver in this GDAL";
  EXPECT_EQ(ReadKmlWithGdal(path, "KML").size(), 3u);
}

// Issue 29: an observation without a ground position wrote "nan" into the KML's lists. Absent
// values are empty list items, and absent single values leave their Data element out.
TEST(KmlExportTest, AbsentValuesAreLeftOutNotWrittenAsNan) {
  const auto dir = testing::MakeTempDir("saker-export");
  const fs::path path = dir / "tracks.kml";
  mission::Mission mission = MakeMission(true);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  mission.tracks[2].points[1].map = {nan, nan};  // an observation without a ground position
  mission.tracks[2].points[2].time_s = std::numeric_limits<double>::infinity();
  mission.tracks[2].speed = nan;  // a track without a speed
  mission.tracks[2].speed_mps.reset();
  mission.tracks[2].confidence.reset();
  mission.tracks[2].end_s = nan;
  ASSERT_TRUE(ExportKml(mission, path.string()).ok());
  const std::string text = ReadText(path);
  EXPECT_EQ(text.find("nan"), std::string::npos) << text;
  EXPECT_EQ(text.find("inf"), std::string::npos) << text;
  const size_t track = text.find("<Placemark id=\"track-3\">");
  ASSERT_NE(track, std::string::npos);
  const std::string placemark = text.substr(track, text.find("</Placemark>", track) - track);
  EXPECT_NE(placemark.find("<Data name=\"map_x\"><value>10,,1210</value></Data>"),
            std::string::npos)
      << placemark;
  EXPECT_EQ(placemark.find("<Data name=\"speed\">"), std::string::npos) << placemark;
  EXPECT_EQ(placemark.find("<Data name=\"speed_mps\">"), std::string::npos) << placemark;
  EXPECT_EQ(placemark.find("<Data name=\"confidence\">"), std::string::npos) << placemark;
  EXPECT_EQ(placemark.find("<value></value>"), std::string::npos) << placemark;
  EXPECT_NE(placemark.find("<LineString>"), std::string::npos);  // two positions left
  GDALAllRegister();
  if (GDALGetDriverByName("KML") == nullptr) GTEST_SKIP() << "no KML driver in this GDAL";
  EXPECT_EQ(ReadKmlWithGdal(path, "KML").size(), 3u);
}

TEST(KmlExportTest, NotGeoReferencedIsUnsupported) {
  const auto dir = testing::MakeTempDir("saker-export");
  const fs::path path = dir / "tracks.kml";
  const Status status = ExportKml(MakeMission(false), path.string());
  EXPECT_EQ(status.code(), StatusCode::kUnsupported);
  EXPECT_NE(status.message().find(path.string()), std::string::npos) << status.message();
  EXPECT_NE(status.message().find("geo-referenced"), std::string::npos) << status.message();
  ExpectNoFile(path);
}

// ---------------------------------------------------------------------------------------------
// CSV

// RFC 4180 records: quoted fields may hold commas, doubled quotes and line breaks.
std::vector<std::vector<std::string>> ParseCsv(const std::string& text) {
  std::vector<std::vector<std::string>> rows;
  std::vector<std::string> row;
  std::string field;
  bool quoted = false;
  for (size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (quoted) {
      if (c == '"' && i + 1 < text.size() && text[i + 1] == '"') {
        field += '"';
        ++i;
      } else if (c == '"') {
        quoted = false;
      } else {
        field += c;
      }
    } else if (c == '"') {
      quoted = true;
    } else if (c == ',') {
      row.push_back(field);
      field.clear();
    } else if (c == '\r' && i + 1 < text.size() && text[i + 1] == '\n') {
      row.push_back(field);
      field.clear();
      rows.push_back(row);
      row.clear();
      ++i;
    } else {
      field += c;
    }
  }
  EXPECT_TRUE(field.empty() && row.empty()) << "the last record has no CRLF";
  return rows;
}

TEST(CsvExportTest, OneRowPerObservationWithQuotedFields) {
  const auto dir = testing::MakeTempDir("saker-export");
  const fs::path path = dir / "tracks.csv";
  const mission::Mission mission = MakeMission(true);
  ASSERT_TRUE(ExportCsv(mission, path.string()).ok());
  const auto rows = ParseCsv(ReadText(path));
  ASSERT_EQ(rows.size(), static_cast<size_t>(TotalPoints(mission) + 1));
  const auto& header = rows[0];
  std::map<std::string, size_t> column;
  for (size_t i = 0; i < header.size(); ++i) column[header[i]] = i;
  // The columns in their order (readers may go by position): new ones only ever at the end.
  const std::vector<std::string> columns = {
      "video",      "track_id",  "visit",     "start_s",     "end_s",        "duration_s",
      "length",     "speed",     "speed_mps", "heading_deg", "point_count",  "point_index",
      "frame",      "time_s",    "image_x",   "image_y",     "box_min_x",    "box_min_y",
      "box_max_x",  "box_max_y", "map_x",     "map_y",       "latitude_deg", "longitude_deg",
      "confidence", "verdict",   "label",     "note",        "interpolated"};
  EXPECT_EQ(header, columns);
  for (size_t r = 1; r < rows.size(); ++r) {
    ASSERT_EQ(rows[r].size(), header.size()) << "row " << r;
    EXPECT_EQ(rows[r][column["video"]], kVideoName);  // comma and quotes survive
  }
  // Row 6: the first point of track 3 (after 4 + 1 points).
  const auto& row = rows[6];
  const auto& point = mission.tracks[2].points[0];
  EXPECT_EQ(row[column["track_id"]], "3");
  EXPECT_EQ(row[column["visit"]], "2");
  EXPECT_EQ(row[column["point_count"]], "3");
  EXPECT_EQ(row[column["point_index"]], "0");
  EXPECT_EQ(std::stoll(row[column["frame"]]), point.frame);
  EXPECT_DOUBLE_EQ(std::stod(row[column["time_s"]]), point.time_s);
  EXPECT_DOUBLE_EQ(std::stod(row[column["image_x"]]), point.image.x());
  EXPECT_DOUBLE_EQ(std::stod(row[column["box_max_y"]]), point.box_max.y());
  EXPECT_DOUBLE_EQ(std::stod(row[column["map_x"]]), point.map.x());
  EXPECT_DOUBLE_EQ(std::stod(row[column["speed_mps"]]), 3.25);
  EXPECT_DOUBLE_EQ(std::stod(row[column["confidence"]]), 0.75);
  EXPECT_EQ(row[column["interpolated"]], "0");
  EXPECT_EQ(rows[2][column["interpolated"]], "1");  // track 1's second point
  const geo::Wgs84 expected = Plane().LatLonFromMap(point.map);
  EXPECT_NEAR(std::stod(row[column["latitude_deg"]]), expected.latitude_deg, 1e-12);
  EXPECT_NEAR(std::stod(row[column["longitude_deg"]]), expected.longitude_deg, 1e-12);
}

// The analyst's verdict, label and note travel with each track in every format, bookmarks as
// points in GeoJSON and KML; a track without a review has none.
TEST(ExportTest, ReviewsAndBookmarksAreExported) {
  const auto dir = testing::MakeTempDir("saker-export");
  mission::Mission mission = MakeMission(true);
  mission.reviews = {{1, mission::Verdict::kConfirmed, mission::TargetLabel::kVehicle,
                      "red van, \"stops\" twice\nat the gate"},
                     {3, mission::Verdict::kFalse, mission::TargetLabel::kNone, ""}};
  mission.bookmarks = {{2, 41.5, {-300, 125}, "gate <north>"}};

  const fs::path geojson = dir / "reviews.geojson";
  ASSERT_TRUE(ExportGeoJson(mission, geojson.string()).ok());
  const Json json = Json::parse(ReadText(geojson));
  ASSERT_EQ(json["features"].size(), 4u);
  const Json& first = json["features"][0]["properties"];
  EXPECT_EQ(first["verdict"], "confirmed");
  EXPECT_EQ(first["label"], "vehicle");
  EXPECT_EQ(first["note"], "red van, \"stops\" twice\nat the gate");
  EXPECT_TRUE(json["features"][1]["properties"]["verdict"].is_null());
  EXPECT_TRUE(json["features"][1]["properties"]["note"].is_null());
  EXPECT_EQ(json["features"][2]["properties"]["verdict"], "false");
  const Json& bookmark = json["features"][3];
  EXPECT_EQ(bookmark["id"], "bookmark-2");
  EXPECT_EQ(bookmark["geometry"]["type"], "Point");
  EXPECT_EQ(bookmark["properties"]["note"], "gate <north>");
  EXPECT_DOUBLE_EQ(bookmark["properties"]["time_s"].get<double>(), 41.5);
  const geo::Wgs84 at = Plane().LatLonFromMap({-300, 125});
  EXPECT_NEAR(bookmark["geometry"]["coordinates"][0].get<double>(), at.longitude_deg, 1e-9);

  const fs::path kml = dir / "reviews.kml";
  ASSERT_TRUE(ExportKml(mission, kml.string()).ok());
  const std::string text = ReadText(kml);
  EXPECT_NE(text.find("<Data name=\"verdict\"><value>confirmed</value></Data>"), std::string::npos);
  EXPECT_NE(text.find("<Data name=\"label\"><value>vehicle</value></Data>"), std::string::npos);
  EXPECT_NE(text.find("gate &lt;north&gt;"), std::string::npos);  // escaped
  EXPECT_NE(text.find("id=\"bookmark-2\""), std::string::npos);

  const fs::path csv = dir / "reviews.csv";
  ASSERT_TRUE(ExportCsv(mission, csv.string()).ok());
  const auto rows = ParseCsv(ReadText(csv));
  ASSERT_EQ(rows.size(), static_cast<size_t>(TotalPoints(mission) + 1));
  std::map<std::string, size_t> column;
  for (size_t i = 0; i < rows[0].size(); ++i) column[rows[0][i]] = i;
  EXPECT_EQ(rows[1][column["verdict"]], "confirmed");
  EXPECT_EQ(rows[1][column["label"]], "vehicle");
  EXPECT_EQ(rows[1][column["note"]], "red van, \"stops\" twice\nat the gate");  // quoted
  EXPECT_EQ(rows[5][column["verdict"]], "");  // track 2: no review
  EXPECT_EQ(rows[6][column["verdict"]], "false");
}

TEST(CsvExportTest, NotGeoReferencedLeavesLatitudeAndLongitudeEmpty) {
  const auto dir = testing::MakeTempDir("saker-export");
  const fs::path path = dir / "tracks.csv";
  mission::Mission mission = MakeMission(false);
  mission.tracks[1].speed_mps.reset();
  mission.tracks[1].confidence.reset();
  ASSERT_TRUE(ExportCsv(mission, path.string()).ok());
  const auto rows = ParseCsv(ReadText(path));
  ASSERT_EQ(rows.size(), static_cast<size_t>(TotalPoints(mission) + 1));
  std::map<std::string, size_t> column;
  for (size_t i = 0; i < rows[0].size(); ++i) column[rows[0][i]] = i;
  const size_t lat = column.at("latitude_deg"), lon = column.at("longitude_deg");
  const size_t confidence = column.at("confidence");
  for (size_t r = 1; r < rows.size(); ++r) {
    EXPECT_EQ(rows[r][lat], "");
    EXPECT_EQ(rows[r][lon], "");
  }
  EXPECT_EQ(rows[5][8], "");           // track 2's absent speed_mps
  EXPECT_EQ(rows[5][confidence], "");  // ... and unknown confidence
  EXPECT_EQ(rows[1][confidence], "0.25");
  EXPECT_EQ(rows[5][0 + 1], "2");
}

// ---------------------------------------------------------------------------------------------
// GeoTIFF

// A synthetic pyramid: 180 x 128 pixels of 11 m (about 2 x 1.4 km) in 64-pixel tiles, 3 x 2
// tiles at level 0 (the right column partly outside the raster), tile (2, 1) absent.
mission::PyramidInfo TestPyramid() {
  mission::PyramidInfo pyramid;
  pyramid.tile_size = 64;
  pyramid.levels = 2;
  pyramid.width = 180;
  pyramid.height = 128;
  pyramid.map_origin = {-900.0, 600.0};
  pyramid.step_x = 11.0;
  pyramid.step_y = -11.0;
  return pyramid;
}

// BGRA pattern of tile (x, y) of `level`: every pixel differs across tiles and channels.
cv::Mat PatternTile(int level, int tx, int ty) {
  cv::Mat tile(64, 64, CV_8UC4);
  for (int r = 0; r < 64; ++r) {
    for (int c = 0; c < 64; ++c) {
      tile.at<cv::Vec4b>(r, c) = cv::Vec4b(
          static_cast<uchar>(c * 3 + tx * 40 + level), static_cast<uchar>(r * 2 + ty * 90),
          static_cast<uchar>((c ^ r) + 7 * tx), static_cast<uchar>(128 + ((c + r) & 127)));
    }
  }
  return tile;
}

StatusOr<cv::Mat> PatternReader(int level, int tx, int ty) {
  if (level == 0 && tx == 2 && ty == 1) return cv::Mat();  // absent
  return PatternTile(level, tx, ty);
}

mission::MapFrame GeoMap() { return {true, kOrigin}; }

// The file's pixels in a rectangle as RGBA, pixel-interleaved.
cv::Mat ReadRgba(GDALDatasetH ds, int x, int y, int w, int h) {
  cv::Mat rgba(h, w, CV_8UC4);
  int bands[] = {1, 2, 3, 4};
  EXPECT_EQ(GDALDatasetRasterIO(ds, GF_Read, x, y, w, h, rgba.data, w, h, GDT_Byte, 4, bands, 4,
                                static_cast<int>(rgba.step[0]), 1),
            CE_None);
  return rgba;
}

TEST(GeoTiffExportTest, GeoReferencedRasterInUtmOfTheOrigin) {
  const auto dir = testing::MakeTempDir("saker-export");
  const fs::path path = dir / "mosaic.tif";
  const auto pyramid = TestPyramid();
  auto report = ExportGeoTiff(GeoMap(), pyramid, 0, PatternReader, path.string());
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  EXPECT_EQ(report->width, 180);
  EXPECT_EQ(report->height, 128);
  EXPECT_EQ(report->crs, "EPSG:32630 (WGS 84 / UTM zone 30N)");
  EXPECT_LT(report->max_fit_error_m, 0.05);
  EXPECT_GT(report->max_fit_error_m, 0.0);
  std::cout << "GeoTIFF fit error over " << pyramid.width * pyramid.step_x << " x "
            << pyramid.height * -pyramid.step_y << " m: " << report->max_fit_error_m * 1000
            << " mm\n";
  // Everything is inside the TIFF: no partial file, no .aux.xml side file.
  std::vector<std::string> files;
  for (const auto& entry : fs::directory_iterator(dir)) {
    files.push_back(entry.path().filename().string());
  }
  EXPECT_EQ(files, std::vector<std::string>{"mosaic.tif"});

  GDALAllRegister();
  GDALDatasetH ds = GDALOpen(path.c_str(), GA_ReadOnly);
  ASSERT_NE(ds, nullptr);
  EXPECT_STREQ(GDALGetDriverShortName(GDALGetDatasetDriver(ds)), "GTiff");
  EXPECT_EQ(GDALGetRasterXSize(ds), 180);
  EXPECT_EQ(GDALGetRasterYSize(ds), 128);
  ASSERT_EQ(GDALGetRasterCount(ds), 4);
  EXPECT_EQ(GDALGetRasterColorInterpretation(GDALGetRasterBand(ds, 1)), GCI_RedBand);
  EXPECT_EQ(GDALGetRasterColorInterpretation(GDALGetRasterBand(ds, 4)), GCI_AlphaBand);
  const char* compression = GDALGetMetadataItem(ds, "COMPRESSION", "IMAGE_STRUCTURE");
  EXPECT_STREQ(compression, "DEFLATE");
  int block_x = 0, block_y = 0;
  GDALGetBlockSize(GDALGetRasterBand(ds, 1), &block_x, &block_y);
  EXPECT_EQ(block_x, 64);
  EXPECT_EQ(block_y, 64);

  // The CRS: EPSG 32630.
  OGRSpatialReferenceH file_srs = GDALGetSpatialRef(ds);
  ASSERT_NE(file_srs, nullptr);
  const char* code = OSRGetAuthorityCode(file_srs, nullptr);
  ASSERT_NE(code, nullptr);
  EXPECT_STREQ(code, "32630");

  // The raster's corners through the geotransform and PROJ back to WGS84 land where the tangent
  // plane puts the same map corners (pixel corners: half a pixel outside the first centre).
  double gt[6];
  ASSERT_EQ(GDALGetGeoTransform(ds, gt), CE_None);
  OGRSpatialReferenceH utm = OSRClone(file_srs);
  OGRSpatialReferenceH wgs84 = OSRNewSpatialReference(nullptr);
  ASSERT_EQ(OSRSetFromUserInput(wgs84, "EPSG:4326"), OGRERR_NONE);
  OSRSetAxisMappingStrategy(utm, OAMS_TRADITIONAL_GIS_ORDER);
  OSRSetAxisMappingStrategy(wgs84, OAMS_TRADITIONAL_GIS_ORDER);
  OGRCoordinateTransformationH to_wgs84 = OCTNewCoordinateTransformation(utm, wgs84);
  ASSERT_NE(to_wgs84, nullptr);
  const auto plane = Plane();
  for (const auto& [u, v] : {std::pair{0, 0}, {180, 0}, {0, 128}, {180, 128}}) {
    double x = gt[0] + u * gt[1] + v * gt[2];
    double y = gt[3] + u * gt[4] + v * gt[5];
    ASSERT_TRUE(OCTTransform(to_wgs84, 1, &x, &y, nullptr));
    const Eigen::Vector2d map_corner =
        pyramid.map_origin +
        Eigen::Vector2d((u - 0.5) * pyramid.step_x, (v - 0.5) * pyramid.step_y);
    const geo::Wgs84 expected = plane.LatLonFromMap(map_corner);
    // Degrees to metres: north by the meridian arc, east by the parallel's radius.
    const double metres_per_degree = 6378137.0 * M_PI / 180.0;
    const double north_m = (y - expected.latitude_deg) * metres_per_degree;
    const double east_m = (x - expected.longitude_deg) * metres_per_degree *
                          std::cos(expected.latitude_deg * M_PI / 180.0);
    EXPECT_LT(std::hypot(north_m, east_m), 0.05) << "corner " << u << ", " << v;
  }
  OCTDestroyCoordinateTransformation(to_wgs84);
  OSRDestroySpatialReference(utm);
  OSRDestroySpatialReference(wgs84);

  // Tile (1, 0) and the partial edge tile (2, 0) read back as the reader gave them, RGBA.
  for (const auto& [tx, width] : {std::pair{1, 64}, {2, 52}}) {
    const cv::Mat expected = PatternTile(0, tx, 0)(cv::Rect(0, 0, width, 64));
    const cv::Mat rgba = ReadRgba(ds, tx * 64, 0, width, 64);
    int mismatches = 0;
    for (int r = 0; r < 64; ++r) {
      for (int c = 0; c < width; ++c) {
        const cv::Vec4b bgra = expected.at<cv::Vec4b>(r, c);
        const cv::Vec4b got = rgba.at<cv::Vec4b>(r, c);
        mismatches += got != cv::Vec4b(bgra[2], bgra[1], bgra[0], bgra[3]);
      }
    }
    EXPECT_EQ(mismatches, 0) << "tile " << tx;
  }
  // The absent tile is transparent.
  const cv::Mat absent = ReadRgba(ds, 128, 64, 52, 64);
  std::vector<cv::Mat> channels;
  cv::split(absent, channels);
  EXPECT_EQ(cv::countNonZero(channels[3]), 0);
  GDALClose(ds);
}

TEST(GeoTiffExportTest, CoarserLevelHasBiggerPixelsOverTheSameGround) {
  const auto dir = testing::MakeTempDir("saker-export");
  const auto pyramid = TestPyramid();
  std::vector<std::array<int, 3>> requested;
  auto reader = [&](int level, int tx, int ty) -> StatusOr<cv::Mat> {
    requested.push_back({level, tx, ty});
    return PatternTile(level, tx, ty);
  };
  const fs::path full = dir / "level0.tif", coarse = dir / "level1.tif";
  ASSERT_TRUE(ExportGeoTiff(GeoMap(), pyramid, 0, PatternReader, full.string()).ok());
  auto report = ExportGeoTiff(GeoMap(), pyramid, 1, reader, coarse.string());
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  EXPECT_EQ(report->width, 90);
  EXPECT_EQ(report->height, 64);
  EXPECT_EQ(requested, (std::vector<std::array<int, 3>>{{1, 0, 0}, {1, 1, 0}}));

  double gt0[6], gt1[6];
  GDALDatasetH ds0 = GDALOpen(full.c_str(), GA_ReadOnly);
  GDALDatasetH ds1 = GDALOpen(coarse.c_str(), GA_ReadOnly);
  ASSERT_TRUE(ds0 != nullptr && ds1 != nullptr);
  ASSERT_EQ(GDALGetGeoTransform(ds0, gt0), CE_None);
  ASSERT_EQ(GDALGetGeoTransform(ds1, gt1), CE_None);
  EXPECT_NEAR(gt1[0], gt0[0], 0.01);  // same top-left corner
  EXPECT_NEAR(gt1[3], gt0[3], 0.01);
  for (int i : {1, 2, 4, 5}) EXPECT_NEAR(gt1[i], 2 * gt0[i], 1e-6) << i;
  EXPECT_GT(gt0[1], 10.9);  // about 11 m east per column (UTM scale and convergence aside)
  EXPECT_LT(gt0[5], -10.9);
  GDALClose(ds0);
  GDALClose(ds1);
}

TEST(GeoTiffExportTest, TileSizeThatIsNoTiffBlockSizeStillWritesEveryPixel) {
  // TIFF blocks must be multiples of 16 pixels; 50-pixel tiles straddle the file's blocks.
  const auto dir = testing::MakeTempDir("saker-export");
  const fs::path path = dir / "mosaic.tif";
  mission::PyramidInfo pyramid = TestPyramid();
  pyramid.tile_size = 50;
  pyramid.width = 120;
  pyramid.height = 70;
  auto tile = [](int, int tx, int ty) {
    cv::Mat bgra(50, 50, CV_8UC4);
    bgra.forEach<cv::Vec4b>([&](cv::Vec4b& p, const int* rc) {
      p = cv::Vec4b(static_cast<uchar>(rc[1] + 50 * tx), static_cast<uchar>(rc[0] + 50 * ty),
                    static_cast<uchar>(tx * 3 + ty), 255);
    });
    return bgra;
  };
  auto reader = [&](int level, int tx, int ty) -> StatusOr<cv::Mat> {
    // Edge tiles given exactly at their size inside the raster.
    const cv::Mat full = tile(level, tx, ty);
    return full(cv::Rect(0, 0, std::min(50, 120 - 50 * tx), std::min(50, 70 - 50 * ty))).clone();
  };
  ASSERT_TRUE(ExportGeoTiff(GeoMap(), pyramid, 0, reader, path.string()).ok());
  GDALAllRegister();
  GDALDatasetH ds = GDALOpen(path.c_str(), GA_ReadOnly);
  ASSERT_NE(ds, nullptr);
  const cv::Mat rgba = ReadRgba(ds, 0, 0, 120, 70);
  GDALClose(ds);
  int mismatches = 0;
  for (int r = 0; r < 70; ++r) {
    for (int c = 0; c < 120; ++c) {
      const cv::Vec4b bgra = tile(0, c / 50, r / 50).at<cv::Vec4b>(r % 50, c % 50);
      mismatches += rgba.at<cv::Vec4b>(r, c) != cv::Vec4b(bgra[2], bgra[1], bgra[0], bgra[3]);
    }
  }
  EXPECT_EQ(mismatches, 0);
}

TEST(GeoTiffExportTest, NotGeoReferencedIsAPlainRaster) {
  const auto dir = testing::MakeTempDir("saker-export");
  const fs::path path = dir / "mosaic.tif";
  auto report = ExportGeoTiff(mission::MapFrame{}, TestPyramid(), 0, PatternReader, path.string());
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  EXPECT_EQ(report->crs, "none (not geo-referenced)");
  EXPECT_EQ(report->max_fit_error_m, 0.0);
  GDALAllRegister();
  GDALDatasetH ds = GDALOpen(path.c_str(), GA_ReadOnly);
  ASSERT_NE(ds, nullptr);
  EXPECT_EQ(GDALGetRasterCount(ds), 4);
  EXPECT_EQ(GDALGetSpatialRef(ds), nullptr);
  double gt[6];
  EXPECT_NE(GDALGetGeoTransform(ds, gt), CE_None);
  GDALClose(ds);
}

TEST(GeoTiffExportTest, ReaderErrorPropagatesAndLeavesNoFile) {
  const auto dir = testing::MakeTempDir("saker-export");
  const fs::path path = dir / "mosaic.tif";
  auto failing = [](int level, int tx, int ty) -> StatusOr<cv::Mat> {
    if (tx == 1 && ty == 1) return IoError("tile store: disk gone");
    return PatternTile(level, tx, ty);
  };
  auto report = ExportGeoTiff(GeoMap(), TestPyramid(), 0, failing, path.string());
  ASSERT_FALSE(report.ok());
  EXPECT_EQ(report.status().code(), StatusCode::kIoError);
  EXPECT_NE(report.status().message().find(path.string()), std::string::npos);
  EXPECT_NE(report.status().message().find("disk gone"), std::string::npos);
  ExpectNoFile(path);

  // A failed export keeps an earlier file at the path untouched.
  { std::ofstream(path) << "earlier export"; }
  EXPECT_FALSE(ExportGeoTiff(GeoMap(), TestPyramid(), 0, failing, path.string()).ok());
  EXPECT_EQ(ReadText(path), "earlier export");
  EXPECT_FALSE(HasTemporary(path));
}

TEST(GeoTiffExportTest, BadTilesAndInputsAreErrorsNamingTheFile) {
  const auto dir = testing::MakeTempDir("saker-export");
  const fs::path path = dir / "mosaic.tif";
  const auto pyramid = TestPyramid();
  auto check = [&](const StatusOr<GeoTiffReport>& report, StatusCode code) {
    ASSERT_FALSE(report.ok());
    EXPECT_EQ(report.status().code(), code) << report.status().ToString();
    EXPECT_NE(report.status().message().find(path.string()), std::string::npos)
        << report.status().message();
    ExpectNoFile(path);
  };
  auto bgr = [](int, int, int) -> StatusOr<cv::Mat> { return cv::Mat(64, 64, CV_8UC3); };
  check(ExportGeoTiff(GeoMap(), pyramid, 0, bgr, path.string()), StatusCode::kInvalidData);
  auto small = [](int, int, int) -> StatusOr<cv::Mat> { return cv::Mat(32, 64, CV_8UC4); };
  check(ExportGeoTiff(GeoMap(), pyramid, 0, small, path.string()), StatusCode::kInvalidData);
  auto throwing = [](int, int, int) -> StatusOr<cv::Mat> { throw std::runtime_error("boom"); };
  check(ExportGeoTiff(GeoMap(), pyramid, 0, throwing, path.string()), StatusCode::kIoError);
  check(ExportGeoTiff(GeoMap(), pyramid, 2, PatternReader, path.string()),
        StatusCode::kInvalidArgument);
  check(ExportGeoTiff(GeoMap(), pyramid, -1, PatternReader, path.string()),
        StatusCode::kInvalidArgument);
  auto no_levels = pyramid;
  no_levels.levels = 0;
  check(ExportGeoTiff(GeoMap(), no_levels, 0, PatternReader, path.string()),
        StatusCode::kInvalidArgument);
  auto flat = pyramid;
  flat.step_x = 0;
  check(ExportGeoTiff(GeoMap(), flat, 0, PatternReader, path.string()),
        StatusCode::kInvalidArgument);
  check(ExportGeoTiff(mission::MapFrame{true, std::nullopt}, pyramid, 0, PatternReader,
                      path.string()),
        StatusCode::kInvalidArgument);
}

// ---------------------------------------------------------------------------------------------
// Every exporter

TEST(ExportTest, UnwritablePathIsAnErrorNamingIt) {
  const mission::Mission mission = MakeMission(true);
  for (const std::string path : {"/nonexistent-dir/x.geojson", "/nonexistent-dir/x.kml",
                                 "/nonexistent-dir/x.csv", "/nonexistent-dir/x.tif"}) {
    Status status;
    if (path.ends_with(".geojson")) status = ExportGeoJson(mission, path);
    if (path.ends_with(".kml")) status = ExportKml(mission, path);
    if (path.ends_with(".csv")) status = ExportCsv(mission, path);
    if (path.ends_with(".tif")) {
      status = ExportGeoTiff(GeoMap(), TestPyramid(), 0, PatternReader, path).status();
    }
    EXPECT_FALSE(status.ok()) << path;
    EXPECT_EQ(status.code(), StatusCode::kIoError) << status.ToString();
    EXPECT_NE(status.message().find(path), std::string::npos) << status.message();
  }
}

}  // namespace
}  // namespace saker::exporting
