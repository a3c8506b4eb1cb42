#include "core/pipeline/open_mission.h"

#include "core/mission/mission_store.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdio>
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

int64_t FramesWithMetadata(const mission::Mission& mission) {
  int64_t n = 0;
  for (const mission::FrameRecord& f : mission.frames) {
    n += f.utc_us.has_value() || f.sensor.has_value() || f.metadata_corners.has_value();
  }
  return n;
}

namespace {

// Whether the job was told to ignore the metadata (--no-metadata), from its recorded options.
bool MetadataIgnored(const mission::Mission& mission) {
  const nlohmann::json options = nlohmann::json::parse(mission.options_json, nullptr, false);
  if (!options.is_object()) return false;
  const auto mosaic = options.find("mosaic");
  if (mosaic == options.end() || !mosaic->is_object()) return false;
  const auto use = mosaic->find("use_metadata");
  return use != mosaic->end() && use->is_boolean() && !use->get<bool>();
}

}  // namespace

std::string DescribeMapFrame(const mission::Mission& mission) {
  if (mission.map.geo_referenced && mission.map.origin) {
    char text[128];
    std::snprintf(text, sizeof(text), "east-north-up metres around %.6f, %.6f (%.1f m)",
                  mission.map.origin->latitude_deg, mission.map.origin->longitude_deg,
                  mission.map.origin->height_m);
    return text;
  }
  const int64_t with_metadata = FramesWithMetadata(mission);
  const std::string frames_with = with_metadata == 0 ? std::string("no frame has metadata")
                                                     : std::to_string(with_metadata) + " of " +
                                                           std::to_string(mission.frames.size()) +
                                                           " frames have metadata";
  if (!mission.progress.mosaic) return "none: no mosaic was made (" + frames_with + ")";
  if (with_metadata > 0 && MetadataIgnored(mission)) {
    return "the first key frame's pixels (" + frames_with + ", ignored on request: --no-metadata)";
  }
  if (with_metadata > 0) {
    return "the first key frame's pixels (" + frames_with +
           ", but no key frame's image corners gave a map origin)";
  }
  return "the first key frame's pixels (" + frames_with + ")";
}

std::string DescribeKlv(const mission::Mission& mission) {
  if (!mission.klv) return {};
  std::string text = std::to_string(mission.klv->packets) + " packets, " +
                     std::to_string(mission.klv->checksum_failures) + " failed the checksum";
  if (mission.klv->checksum_failures > 0) {
    text += mission.klv->bad_checksums_used ? " (used: --accept-bad-checksums)" : " (not used)";
  }
  return text;
}

std::vector<Finding> DescribeFindings(const mission::FrontEndFindings& f, int64_t frames,
                                      double frame_rate) {
  std::vector<Finding> found;
  char rate[32];
  std::snprintf(rate, sizeof(rate), "%.3g", frame_rate);
  if (f.low_frame_rate) {
    found.push_back({"targets: from change detection alone (low-frame-rate mode, video at " +
                         std::string(rate) + " frames a second)",
                     "low-frame-rate mode (" + std::string(rate) + " fps)"});
  }
  if (const int64_t raised = std::max(f.noise_feature_frames, f.noise_change_frames); raised > 0) {
    // Only the tests whose thresholds were raised (infrared raises the change noise alone).
    char line[160];
    std::string which;
    if (f.noise_feature_frames > 0) {
      std::snprintf(line, sizeof(line), "features: up to %.2g px", f.noise_feature_px);
      which = line;
    }
    if (f.noise_change_frames > 0) {
      std::snprintf(line, sizeof(line), "change: %.2g grey levels, %.2g px of misregistration",
                    f.noise_change_grey, f.noise_change_registration_px);
      which += (which.empty() ? "" : "; ") + std::string(line);
    }
    const std::string in = std::to_string(raised) + " of " + std::to_string(frames) + " frames";
    found.push_back(
        {"noise: the video's own noise (heavy compression?) raised the motion "
         "thresholds in " +
             in + " (" + which + "); slow and small targets may be missed",
         "noise raised the thresholds in " + in});
  }
  if (f.polarity_switches > 0) {
    const std::string n = std::to_string(f.polarity_switches);
    const bool one = f.polarity_switches == 1;
    found.push_back({"thermal polarity: " + n + (one ? " switch" : " switches") +
                         " (white-hot / black-hot), the frames after inverted back: no chain break",
                     n + " thermal polarity switch" + (one ? "" : "es")});
  }
  return found;
}

}  // namespace saker::pipeline
