#pragma once

// Every export of a saved mission behind one call, so that the command line (`saker-cli export`)
// and the GUI's Export menu write the same files: the activity map picture, the mosaic GeoTIFF,
// the tracks as GeoJSON, KML and CSV (docs/exports.md). Also a copy of a mission to a new file
// (the GUI's Save As).

#include "core/mission/mission.h"
#include "core/mission/mission_store.h"
#include "core/render/activity_map.h"
#include "core/util/job_context.h"
#include "core/util/status.h"

#include <string>
#include <vector>

namespace saker::pipeline {

// What to write; empty paths are skipped.
struct ExportRequest {
  std::string png;  // activity map picture (.png, .jpg or .tif)
  render::ActivityMapOptions map;
  std::string geotiff;            // mosaic
  int level = 0;                  // the GeoTIFF's pyramid level (0 = full resolution)
  std::string geojson, kml, csv;  // tracks

  bool empty() const;
};

// One file written, with a line for a person ("activity map, 12 tracks coloured by speed, ...").
struct ExportedFile {
  std::string path;
  std::string what;
};

// The decoded tiles of an open mission whose pyramid has tiles of `tile_size` pixels (each tile's
// PNG header is checked against it before decoding); errors name the mission file and the tile.
render::TileReader StoreTileReader(const mission::MissionStore& store, int tile_size);

// The longest side a mission's mosaic may declare: the largest the tile planner makes
// (tiles::PyramidOptions::max_side_px).
inline constexpr int kMaxMosaicSidePx = 1 << 22;

// Checks a mission's declared mosaic size before anything reads it: within kMaxMosaicSidePx, and
// reached by the tiles the mission holds (a few lookups), so a damaged or hostile file declaring
// a huge raster over a few tiles is refused (InvalidData naming the mission) instead of keeping
// an export busy for hours.
Status CheckDeclaredPyramid(const mission::PyramidInfo& pyramid,
                            const mission::MissionStore& store);

// Checks the request's output paths: none is one of the job's inputs (the mission file, its log,
// the source video: the same file by device and inode, CheckNotAnInput) and no file is given for
// two outputs. InvalidArgument naming the path.
Status CheckExportTargets(const mission::Mission& mission, const mission::MissionStore& store,
                          const ExportRequest& request);

// Writes what `request` asks for from `mission` (as loaded from `store`, whose tiles it reads;
// the caller may have filtered its tracks). CheckExportTargets and CheckDeclaredPyramid come
// first, so a refused request writes nothing. Stops at the first failure, whose message names the
// file; the files written before it stay. `job` may cancel between files and between the tiles
// of the picture or the GeoTIFF.
StatusOr<std::vector<ExportedFile>> ExportMission(const mission::Mission& mission,
                                                  const mission::MissionStore& store,
                                                  const ExportRequest& request,
                                                  JobContext* job = nullptr);

// Copies the mission at `from` to a new mission file `to` (everything: tiles and an unfinished
// job's checkpoint included), which must not be `from`; `replace` allows overwriting another
// mission there. The copy is complete or absent: it is built beside `to` and renamed into place.
Status CopyMission(const std::string& from, const std::string& to, bool replace,
                   JobContext* job = nullptr);

}  // namespace saker::pipeline
