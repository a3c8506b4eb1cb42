#include "core/pipeline/open_mission.h"

#include "core/mission/mission_store.h"

#include <algorithm>
#include <filesystem>
#include <memory>
#include <system_error>
#include <utility>

namespace saker::pipeline {

VideoLocation LocateVideo(const mission::SourceVideo& source, const std::string& mission_path,
                          const OpenMissionOptions& options) {
  VideoLocation location;
  location.path = source.path;
  std::vector<std::string> candidates{source.path};
  if (options.remembered_video) {
    if (std::optional<std::string> remembered = options.remembered_video(source.fingerprint)) {
      candidates.push_back(*remembered);
    }
  }
  const std::filesystem::path recorded(source.path);
  if (recorded.has_filename()) {
    candidates.push_back(
        (std::filesystem::path(mission_path).parent_path() / recorded.filename()).string());
  }
  bool changed = false;
  for (const std::string& candidate : candidates) {
    if (candidate.empty() || std::find(location.looked_at.begin(), location.looked_at.end(),
                                       candidate) != location.looked_at.end()) {
      continue;
    }
    location.looked_at.push_back(candidate);
    std::error_code error;
    if (!std::filesystem::is_regular_file(candidate, error)) continue;
    const StatusOr<std::string> fingerprint = mission::FingerprintFile(candidate);
    if (fingerprint.ok() && *fingerprint == source.fingerprint) {
      location.state = VideoLocation::State::kFound;
      location.path = candidate;
      return location;
    }
    if (!changed) {  // the first file that is not the video is the one to name
      changed = true;
      location.state = VideoLocation::State::kChanged;
      location.path = candidate;
    }
  }
  return location;
}

StatusOr<OpenedMission> OpenMission(const std::string& path, const OpenMissionOptions& options) {
  SAKER_ASSIGN_OR_RETURN(const std::unique_ptr<mission::MissionStore> store,
                         mission::MissionStore::Open(path, mission::OpenMode::kSnapshot));
  OpenedMission opened;
  SAKER_ASSIGN_OR_RETURN(opened.mission, store->Load());
  SAKER_ASSIGN_OR_RETURN(opened.tiles, store->CountTiles());
  SAKER_ASSIGN_OR_RETURN(opened.checkpoint, ReadCheckpointState(*store));
  if (options.read_previews && opened.checkpoint && !opened.mission.progress.mosaic) {
    SAKER_ASSIGN_OR_RETURN(std::optional<frontend::FrontEndCheckpoint> checkpoint,
                           ReadCheckpoint(*store));
    if (checkpoint) opened.previews = std::move(checkpoint->key_frame_images);
  }
  opened.video = LocateVideo(opened.mission.source, path, options);
  opened.read_only = !mission::MissionStore::IsWritable(path);
  return opened;
}

}  // namespace saker::pipeline
