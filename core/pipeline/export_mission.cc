#include "core/pipeline/export_mission.h"

#include "core/activity/colours.h"
#include "core/export/export.h"
#include "core/tiles/pyramid.h"
#include "core/util/durable_file.h"

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

StatusOr<std::vector<ExportedFile>> ExportMission(const mission::Mission& mission,
                                                  const mission::MissionStore& store,
                                                  const ExportRequest& request, JobContext* job) {
  std::vector<ExportedFile> written;
  const auto cancelled = [&] { return job != nullptr && job->IsCancelled(); };
  const auto progress = [&](double fraction) {
    if (job != nullptr) job->ReportProgress("export", fraction);
  };
  const std::string tracks = std::to_string(mission.tracks.size()) + " tracks";
  if (!request.png.empty()) {
    if (cancelled()) return CancelledError("export cancelled");
    progress(0);
    StatusOr<render::ActivityMap> rendered = render::RenderActivityMap(
        mission, StoreTileReader(store, mission.pyramid ? mission.pyramid->tile_size : 0),
        request.map);
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
    SAKER_ASSIGN_OR_RETURN(
        const exporting::GeoTiffReport report,
        exporting::ExportGeoTiff(mission.map, *mission.pyramid, request.level,
                                 StoreTileReader(store, mission.pyramid->tile_size),
                                 request.geotiff));
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
  std::error_code error;
  if (fs::exists(to, error) && fs::equivalent(from, to, error)) {
    return InvalidArgumentError(to + ": this is the mission being copied");
  }
  if (fs::exists(to, error)) {
    if (!replace) return InvalidArgumentError(to + ": a file is already there");
    // Only a mission is ever overwritten (as MissionStore::Create with replace).
    SAKER_RETURN_IF_ERROR(mission::MissionStore::Open(to).status());
  }
  mission::MissionStore::RemoveStaleTemporaries(to);
  SAKER_ASSIGN_OR_RETURN(const std::unique_ptr<mission::MissionStore> source,
                         mission::MissionStore::Open(from));
  SAKER_ASSIGN_OR_RETURN(const mission::Mission mission, source->Load());

  // Built under a temporary name beside `to`, renamed into place when complete.
  FileReplacement replacement(to, {.side_suffixes = {"-wal", "-shm", "-journal"}});
  {
    SAKER_ASSIGN_OR_RETURN(const std::unique_ptr<mission::MissionStore> target,
                           mission::MissionStore::Create(replacement.temporary()));
    SAKER_RETURN_IF_ERROR(target->Save(mission));
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
