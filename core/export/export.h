#pragma once

// Exports of a processed mission for the operator's other tools (docs/exports.md): the activity
// tracks as GeoJSON, KML and CSV, the mosaic as a GeoTIFF.
//
// Every exporter writes to "<path>.partial" beside the target and renames it over `path` only
// when the whole file is written, so a failed export leaves neither a partial file nor a damaged
// earlier export. Errors are returned (never thrown) and name the file.

#include "core/mission/mission.h"
#include "core/util/status.h"

#include <opencv2/core/mat.hpp>

#include <functional>
#include <string>

namespace saker::exporting {  // not "export", a keyword

// Tracks as an RFC 7946 GeoJSON FeatureCollection: one Feature per track, with a LineString (a
// single-point track: Point; no finite position: null geometry) and every track attribute as
// properties, the observations in a "points" array. Geo-referenced missions give WGS84
// [longitude, latitude]; otherwise the coordinates are map pixels and the file has no CRS.
// Non-finite numbers are written as null (and left out of the geometry).
Status ExportGeoJson(const mission::Mission& mission, const std::string& path);

// Tracks as KML 2.2: one Placemark per track with a LineString (single point: Point), the track
// attributes and per-observation lists in ExtendedData, and one style per visit. Geo-referenced
// missions only: KML has no other coordinate system (Unsupported otherwise).
Status ExportKml(const mission::Mission& mission, const std::string& path);

// Observations as RFC 4180 CSV (UTF-8, CRLF, header row): one row per track point with the
// track's attributes repeated. Latitude/longitude columns are empty when the mission is not
// geo-referenced; absent or non-finite values are empty fields.
Status ExportCsv(const mission::Mission& mission, const std::string& path);

// Gives tile (x, y) of pyramid level `level` as CV_8UC4 BGRA (alpha 0 where there is no picture)
// of tile_size x tile_size pixels (or exactly the part inside the raster, for edge tiles), or an
// empty Mat when the tile is absent (fully transparent).
using TileReader = std::function<StatusOr<cv::Mat>(int level, int x, int y)>;

// What ExportGeoTiff wrote.
struct GeoTiffReport {
  std::string crs;  // e.g. "EPSG:32630 (WGS 84 / UTM zone 30N)", or "none (not geo-referenced)"
  int width = 0;    // raster size in pixels (of the exported level)
  int height = 0;
  // Geo-referenced: largest distance, in metres, between the file's affine geotransform and the
  // exact ENU -> WGS84 -> UTM mapping over the raster (centimetres over a few km); 0 otherwise.
  double max_fit_error_m = 0;
};

// The mosaic at pyramid level `level` (0 = full resolution; level l has ceil(width / 2^l) x
// ceil(height / 2^l) pixels) as a tiled, DEFLATE-compressed RGBA GeoTIFF (band 4 is alpha),
// written tile by tile from `read_tile` so the raster is never held in memory whole.
// Geo-referenced: in the UTM zone of the map origin, with an affine geotransform fitted by least
// squares to the exact mapping of the ENU map grid. Otherwise a plain raster with neither CRS nor
// geotransform.
StatusOr<GeoTiffReport> ExportGeoTiff(const mission::MapFrame& map,
                                      const mission::PyramidInfo& pyramid, int level,
                                      const TileReader& read_tile, const std::string& path);

}  // namespace saker::exporting
