#include "core/pipeline/export_mission.h"

#include "core/activity/colours.h"
#include "core/export/export.h"
#include "core/tiles/pyramid.h"
#include "core/util/durable_file.h"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <system_error>

namespace saker::pipeline {

namespace fs = std::filesystem;

bool ExportRequest::empty() const {
  return png.empty() && geotiff.empty() && geojson.empty() && kml.empty() && csv.empty();
}

render::TileReader StoreTileReader(const mission::MissionStore& store, int tile_size) {
  return [&store, tile_size](int level, int x, int y) -> StatusOr<cv::Mat> {
    SAKER_ASSIGN_OR_RETURN(const std::optional<std::vector<uint8_t>> bytes,
                           store.ReadTile(level, x, y));
    if (!bytes) return cv::Mat();
    StatusOr<cv::Mat> tile = tiles::DecodeTile(*bytes, tile_size);
    if (!tile.ok()) {
      return Status(tile.status().code(), store.path() + ": tile " + std::to_string(level) + "/" +
                                              std::to_string(x) + "/" + std::to_string(y) + ": " +
                                              tile.status().message());
    }
    return tile;
  };
}

namespace {

// Whether any tile of `level` lies in columns [x0, x1) of rows [y0, y1).
StatusOr<bool> AnyTileIn(const mission::MissionStore& store, int level, int x0, int x1, int y0,
                         int y1) {
  for (int y = std::max(0, y0); y < y1; ++y) {
    for (int x = std::max(0, x0); x < x1; ++x) {
      SAKER_ASSIGN_OR_RETURN(const std::optional<std::vector<uint8_t>> tile,
                             store.ReadTile(level, x, y));
      if (tile) return true;
    }
  }
  return false;
}

}  // namespace

Status CheckDeclaredPyramid(const mission::PyramidInfo& pyramid,
                            const mission::MissionStore& store) {
  const std::string declared = store.path() + ": the mission declares a mosaic of " +
                               std::to_string(pyramid.width) + " x " +
                               std::to_string(pyramid.height) + " pixels";
  if (pyramid.width < 1 || pyramid.height < 1 || pyramid.width > kMaxMosaicSidePx ||
      pyramid.height > kMaxMosaicSidePx) {
    return InvalidDataError(declared + " (1.." + std::to_string(kMaxMosaicSidePx) +
                            " per side expected): the file is damaged or not Saker's");
  }
  if (pyramid.tile_size < 16 || pyramid.tile_size > 4096) {
    return InvalidDataError(store.path() + ": the mission's mosaic tiles are " +
                            std::to_string(pyramid.tile_size) +
                            " pixels (16..4096 expected): the file is damaged or not Saker's");
  }
  // The pyramid is planned around the frames' footprints, so its tiles reach the raster's right
  // and bottom edges (within a tile: an edge may be touched by a sliver of one frame only).
  const int columns = (pyramid.width + pyramid.tile_size - 1) / pyramid.tile_size;
  const int rows = (pyramid.height + pyramid.tile_size - 1) / pyramid.tile_size;
  SAKER_ASSIGN_OR_RETURN(const bool right, AnyTileIn(store, 0, columns - 2, columns, 0, rows));
  SAKER_ASSIGN_OR_RETURN(const bool bottom, AnyTileIn(store, 0, 0, columns, rows - 2, rows));
  if (!right || !bottom) {
    return InvalidDataError(declared + ", but its tiles do not reach its " +
                            (right ? "bottom" : "right") +
                            " edge: the declared size is wrong (the file is damaged)");
  }
  return Status::Ok();
}

Status CheckExportTargets(const mission::Mission& mission, const mission::MissionStore& store,
                          const ExportRequest& request) {
  const std::vector<std::string> inputs = {store.path(), store.path() + "-wal",
                                           store.path() + "-shm", store.path() + "-journal",
                                           mission.source.path};
  std::vector<std::string> targets;
  for (const std::string* path :
       {&request.png, &request.geotiff, &request.geojson, &request.kml, &request.csv}) {
    if (path->empty()) continue;
    SAKER_RETURN_IF_ERROR(CheckNotAnInput(*path, inputs));
    // Two outputs in one file would leave only the last.
    if (std::find(targets.begin(), targets.end(), *path) != targets.end() ||
        !CheckNotAnInput(*path, targets).ok()) {
      return InvalidArgumentError(*path + ": given for two outputs; each needs a file of its own");
    }
    targets.push_back(*path);
  }
  return Status::Ok();
}

StatusOr<std::vector<ExportedFile>> ExportMission(const mission::Mission& mission,
                                                  const mission::MissionStore& store,
                                                  const ExportRequest& request, JobContext* job) {
  // Every check before any work: a refused request writes nothing.
  SAKER_RETURN_IF_ERROR(CheckExportTargets(mission, store, request));
  if (mission.pyramid && !(request.png.empty() && request.geotiff.empty())) {
    SAKER_RETURN_IF_ERROR(CheckDeclaredPyramid(*mission.pyramid, store));
  }
  std::vector<ExportedFile> written;
  const auto cancelled = [&] { return job != nullptr && job->IsCancelled(); };
  // Cancelling stops a long picture or GeoTIFF between two tiles (its temporary is removed).
  const render::TileReader stored =
      StoreTileReader(store, mission.pyramid ? mission.pyramid->tile_size : 0);
  const render::TileReader read_tile = [&](int level, int x, int y) -> StatusOr<cv::Mat> {
    if (cancelled()) return CancelledError("export cancelled");
    return stored(level, x, y);
  };
  const auto progress = [&](double fraction) {
    if (job != nullptr) job->ReportProgress("export", fraction);
  };
  const std::string tracks = std::to_string(mission.tracks.size()) + " tracks";
  if (!request.png.empty()) {
    if (cancelled()) return CancelledError("export cancelled");
    progress(0);
    StatusOr<render::ActivityMap> rendered =
        render::RenderActivityMap(mission, read_tile, request.map);
    if (!rendered.ok()) {
      const std::string& message = rendered.status().message();  // a tile's names the file
      return Status(rendered.status().code(),
                    message.rfind(store.path(), 0) == 0 ? message : store.path() + ": " + message);
    }
    const render::ActivityMap& map = *rendered;
    SAKER_RETURN_IF_ERROR(render::WritePicture(map.bgr, request.png));
    written.push_back(
        {request.png, "activity map, " + std::to_string(map.tracks) + " tracks coloured by " +
                          activity::ColourModeName(request.map.colour_by) + ", " +
                          std::to_string(map.bgr.cols) + "x" + std::to_string(map.bgr.rows)});
  }
  if (!request.geotiff.empty()) {
    if (cancelled()) return CancelledError("export cancelled");
    progress(0.3);
    if (!mission.pyramid) {
      return InvalidArgumentError(store.path() +
                                  ": the mission has no mosaic tiles (processed with --no-tiles, "
                                  "cancelled, or no key frame)");
    }
    SAKER_ASSIGN_OR_RETURN(const exporting::GeoTiffReport report,
                           exporting::ExportGeoTiff(mission.map, *mission.pyramid, request.level,
                                                    read_tile, request.geotiff));
    char fit[64] = "";
    if (mission.map.geo_referenced) {
      std::snprintf(fit, sizeof(fit), ", affine fit within %.3f m", report.max_fit_error_m);
    }
    written.push_back({request.geotiff, "mosaic " + std::to_string(report.width) + "x" +
                                            std::to_string(report.height) + ", CRS " + report.crs +
                                            fit});
  }
  const std::pair<const std::string*, Status (*)(const mission::Mission&, const std::string&)>
      track_exports[] = {{&request.geojson, &exporting::ExportGeoJson},
                         {&request.kml, &exporting::ExportKml},
                         {&request.csv, &exporting::ExportCsv}};
  for (const auto& [path, write] : track_exports) {
    if (path->empty()) continue;
    if (cancelled()) return CancelledError("export cancelled");
    progress(0.9);
    SAKER_RETURN_IF_ERROR(write(mission, *path));
    written.push_back({*path, tracks});
  }
  progress(1);
  return written;
}

Status CopyMission(const std::string& from, const std::string& to, bool replace, JobContext* job) {
  SAKER_RETURN_IF_ERROR(CheckNotAnInput(to, {from}));
  std::error_code error;
  if (fs::exists(to, error)) {
    if (!replace) return InvalidArgumentError(to + ": a file is already there");
    // Only a mission is ever overwritten (as MissionStore::Create with replace).
    SAKER_RETURN_IF_ERROR(mission::MissionStore::Open(to, mission::OpenMode::kSnapshot).status());
  }
  mission::MissionStore::RemoveStaleTemporaries(to);
  SAKER_ASSIGN_OR_RETURN(const std::unique_ptr<mission::MissionStore> source,
                         mission::MissionStore::Open(from, mission::OpenMode::kSnapshot));
  SAKER_ASSIGN_OR_RETURN(const mission::Mission mission, source->Load());

  // Built under a temporary name beside `to`, renamed into place when complete.
  FileReplacement replacement(to, {.side_suffixes = {"-wal", "-shm", "-journal"}});
  {
    StatusOr<std::unique_ptr<mission::MissionStore>> created =
        mission::MissionStore::Create(replacement.temporary());
    if (!created.ok()) {
      return Status(created.status().code(), to + ": " + replacement.Reason(created.status()));
    }
    const std::unique_ptr<mission::MissionStore>& target = *created;
    SAKER_RETURN_IF_ERROR(target->Save(mission, mission::kSaveAll | mission::kSaveReviews));
    if (mission.pyramid) {
      const mission::PyramidInfo& p = *mission.pyramid;
      std::vector<mission::EncodedTile> batch;
      for (int level = 0; level < p.levels; ++level) {
        const int size = p.tile_size << level;  // level-0 pixels per tile of this level
        const int columns = (p.width + size - 1) / size, rows = (p.height + size - 1) / size;
        for (int y = 0; y < rows; ++y) {
          if (job != nullptr && job->IsCancelled()) return CancelledError(to + ": copy cancelled");
          for (int x = 0; x < columns; ++x) {
            SAKER_ASSIGN_OR_RETURN(std::optional<std::vector<uint8_t>> bytes,
                                   source->ReadTile(level, x, y));
            if (bytes) batch.push_back({level, x, y, std::move(*bytes)});
          }
          if (batch.size() >= 64) {
            SAKER_RETURN_IF_ERROR(target->WriteTiles(batch));
            batch.clear();
          }
        }
        if (job != nullptr) job->ReportProgress("copy", static_cast<double>(level + 1) / p.levels);
      }
      SAKER_RETURN_IF_ERROR(target->WriteTiles(batch));
    }
    // An unfinished job's checkpoint too, so that the copy can be resumed.
    SAKER_ASSIGN_OR_RETURN(const std::vector<mission::CheckpointRecord> checkpoint,
                           source->ReadCheckpoint());
    if (!checkpoint.empty()) SAKER_RETURN_IF_ERROR(target->WriteCheckpoint(checkpoint));
  }  // closed: the WAL is checkpointed into the file
  // A log of the mission being replaced (or an orphaned one) must not be replayed onto the copy.
  SAKER_RETURN_IF_ERROR(mission::MissionStore::FoldLog(to));
  return replacement.Commit();
}

}  // namespace saker::pipeline
