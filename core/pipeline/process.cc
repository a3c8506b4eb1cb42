#include "core/pipeline/process.h"

#include "core/mission/mission_store.h"
#include "core/pipeline/checkpoint.h"
#include "core/pipeline/open_mission.h"
#include "core/pipeline/stages.h"
#include "core/util/durable_file.h"
#include "core/util/timer.h"
#include "core/video/video_reader.h"

#include <nlohmann/json.hpp>

#include <cstdio>
#include <filesystem>
#include <map>
#include <sstream>
#include <utility>

namespace saker::pipeline {
namespace {

// The options worth recording in the mission (what a person would need to reproduce it).
std::string OptionsJson(const ProcessOptions& options) {
  const nlohmann::json j = {
      {"saker_version", options.saker_version},
      {"mosaic",
       {{"adjust_mode", mosaic::AdjustmentModeName(options.mosaic.adjust_mode)},
        {"use_metadata", options.mosaic.use_metadata},
        {"metadata_sigma_m", options.mosaic.adjustment.metadata_sigma_m},
        {"max_arc_links", options.mosaic.decomposition.max_arc_links},
        {"place_in_between", options.mosaic.place_in_between}}},
      {"front_end",
       {{"key_frame_image_width", options.front_end.key_frame_image_width},
        {"key_frame_colour", options.front_end.key_frame_colour},
        {"change_detection", options.front_end.change.enabled},
        {"accept_bad_checksums", options.front_end.metadata.accept_bad_checksums}}},
      {"activity",
       {{"smoothing_s", options.activity.smoothing_s},
        {"speed_interval_s", options.activity.speed_interval_s},
        {"visit_gap_s", options.activity.visit_gap_s}}},
      {"tiles",
       {{"render", options.render_tiles},
        {"tile_size", options.pyramid.tile_size},
        {"map_units_per_px", options.pyramid.map_units_per_px}}}};
  return j.dump();
}

// The source record of `video`, opened as `info`: size, rate, duration, fingerprint.
StatusOr<mission::SourceVideo> SourceOf(const std::string& video, const video::VideoInfo& info) {
  mission::SourceVideo source;
  std::error_code error;
  source.path = std::filesystem::absolute(video, error).string();
  if (error) source.path = video;
  source.width = info.width;
  source.height = info.height;
  source.frame_rate = info.fps;
  source.duration_s = info.duration_s;
  source.frame_count = info.declared_frame_count;
  if (std::filesystem::is_regular_file(video, error)) {
    source.size_bytes = static_cast<int64_t>(std::filesystem::file_size(video, error));
    SAKER_ASSIGN_OR_RETURN(source.fingerprint, mission::FingerprintFile(video));
  }
  return source;
}

// Opens the mission of an interrupted job made from the same video, with its checkpoint. A
// mission that is complete is left as it is (summary->already_complete).
StatusOr<std::unique_ptr<mission::MissionStore>> OpenToResume(
    const std::string& video, const mission::SourceVideo& source, const std::string& mission_path,
    const ProcessOptions& options, std::optional<frontend::FrontEndCheckpoint>* checkpoint,
    ProcessSummary* summary) {
  SAKER_ASSIGN_OR_RETURN(std::unique_ptr<mission::MissionStore> store,
                         mission::MissionStore::Open(mission_path, mission::OpenMode::kReadWrite));
  SAKER_ASSIGN_OR_RETURN(const mission::Mission previous, store->Load());
  if (!previous.source.fingerprint.empty() && !source.fingerprint.empty() &&
      previous.source.fingerprint != source.fingerprint) {
    return InvalidArgumentError(mission_path + ": cannot resume with " + video +
                                ": the mission was made from another video (" +
                                previous.source.path + ")");
  }
  SAKER_ASSIGN_OR_RETURN(*checkpoint, ReadCheckpoint(*store));
  const mission::Progress& p = previous.progress;
  if (!*checkpoint && !p.cancelled && p.front_end && p.mosaic && p.activity &&
      (p.tiles || !options.render_tiles)) {
    summary->already_complete = true;
    summary->progress = p;
    summary->frames = static_cast<int64_t>(previous.frames.size());
    summary->key_frames = static_cast<int64_t>(previous.key_frames.size());
    summary->tracks = static_cast<int64_t>(previous.tracks.size());
    summary->geo_referenced = previous.map.geo_referenced;
    return store;
  }
  if (!*checkpoint) {
    summary->warnings.push_back(mission_path +
                                ": no checkpoint to resume from: processed from the start");
  }
  return store;
}

}  // namespace

Status ProcessOptions::Validate() const { return StageOptions::Validate(); }

std::string ProcessSummary::ToText() const {
  std::ostringstream out;
  if (already_complete) {
    out << "the mission is complete (" << frames << " frames, " << key_frames << " key frames, "
        << tracks << " moving-target tracks): nothing to resume\n";
    return out.str();
  }
  char line[256];
  std::snprintf(line, sizeof(line),
                "%lld frames (%lld placed on the map), %lld key frames, %lld cross-links, %lld "
                "moving-target tracks, %lld tiles; ",
                static_cast<long long>(frames), static_cast<long long>(frames_placed),
                static_cast<long long>(key_frames), static_cast<long long>(cross_links),
                static_cast<long long>(tracks), static_cast<long long>(tiles));
  out << line;
  out << (geo_referenced ? "geo-referenced (metadata)" : "not geo-referenced; map: " + map_frame)
      << "\n";
  if (overlay_frames > 0) {
    std::snprintf(line, sizeof(line),
                  "overlays: screen-fixed overlays masked out in %lld of %lld frames (%.1f %% of "
                  "the image)\n",
                  static_cast<long long>(overlay_frames), static_cast<long long>(frames),
                  100 * overlay_coverage);
    out << line;
  }
  if (horizon_frames > 0) {
    std::snprintf(line, sizeof(line),
                  "horizon: the view reaches the horizon in %lld of %lld frames; the sky and the "
                  "distant ground above it were masked out (too oblique for the ground mosaic "
                  "there)\n",
                  static_cast<long long>(horizon_frames), static_cast<long long>(frames));
    out << line;
  }
  for (const Finding& found : DescribeFindings(findings, frames, frame_rate)) {
    out << found.sentence << "\n";
  }
  if (tracks_implausible > 0 || tracks_low_confidence > 0) {
    out << "not reported: " << tracks_implausible << " tracks with an impossible ground speed, "
        << tracks_low_confidence << " below the minimum confidence\n";
  }
  std::snprintf(line, sizeof(line),
                "time: front end %.1f s, mosaic %.1f s, activity %.2f s, tiles %.1f s, saving %.2f "
                "s; total %.1f s for %.1f s of video (%.2fx real time)\n",
                front_end_s, mosaic_s, activity_s, tiles_s, save_s, total_s, video_duration_s,
                video_duration_s > 0 ? total_s / video_duration_s : 0.0);
  out << line;
  if (resumed_from_frame >= 0) {
    out << "resumed: the front end went on from its checkpoint at frame " << resumed_from_frame
        << "\n";
  }
  if (progress.cancelled) {
    out << "cancelled: the mission keeps the stages that completed and its checkpoint (carry on "
           "with --resume)\n";
  }
  for (const std::string& warning : warnings) out << "warning: " << warning << "\n";
  return out.str();
}

StatusOr<ProcessSummary> ProcessVideo(const std::string& video, const std::string& mission_path,
                                      const ProcessOptions& options, JobContext* job) {
  SAKER_RETURN_IF_ERROR(options.Validate());
  // The mission is never written over the video it is made from (nor --resume'd into it).
  SAKER_RETURN_IF_ERROR(CheckNotAnInput(mission_path, {video}));
  const Stopwatch start;
  ProcessSummary summary;
  // Open the video first: a file that is not a video must not leave (or replace) a mission. The
  // one reader gives the source record, then the front end decodes with it.
  SAKER_ASSIGN_OR_RETURN(std::unique_ptr<video::VideoReader> reader,
                         video::VideoReader::Open(video, options.front_end.EffectiveReader()));
  MissionRun run;
  run.mission.saker_version = options.saker_version;
  run.mission.options_json = OptionsJson(options);
  SAKER_ASSIGN_OR_RETURN(run.mission.source, SourceOf(video, reader->info()));
  std::unique_ptr<mission::MissionStore> store;
  std::optional<frontend::FrontEndCheckpoint> checkpoint;
  if (options.resume) {
    SAKER_ASSIGN_OR_RETURN(store, OpenToResume(video, run.mission.source, mission_path, options,
                                               &checkpoint, &summary));
    if (summary.already_complete) {
      summary.total_s = start.ElapsedSeconds();
      return summary;
    }
  } else {
    SAKER_ASSIGN_OR_RETURN(store, mission::MissionStore::Create(mission_path, options.replace));
  }
  const auto commit = [&](const mission::Mission& m, unsigned parts, const char* stage) -> Status {
    const Stopwatch begin;
    SAKER_RETURN_IF_ERROR(store->Save(m, parts));
    summary.save_s += begin.ElapsedSeconds();
    if (options.on_commit) options.on_commit(stage);
    return {};
  };
  // A cancelled stage: mark the mission, keep what completed, and say so.
  const auto cancelled = [&](const Status& status) -> Status {
    run.mission.progress.cancelled = true;
    SAKER_RETURN_IF_ERROR(commit(run.mission, 0, kStageCancelled));
    summary.progress = run.mission.progress;
    return CancelledError(mission_path +
                          ": processing cancelled; the mission keeps the stages that completed "
                          "and its checkpoint, so that --resume carries on from there (" +
                          status.message() + ")");
  };
  SAKER_RETURN_IF_ERROR(commit(run.mission, 0, kStageSource));

  // The stages, with the front end's checkpoints going into the mission as it goes and the
  // mission committed after each stage.
  CheckpointWriter checkpoints(store.get(), checkpoint ? &*checkpoint : nullptr);
  StageOptions stage_options = options;
  stage_options.front_end.on_checkpoint = [&](const frontend::FrontEndCheckpoint& c) -> Status {
    SAKER_RETURN_IF_ERROR(checkpoints.Write(c));
    return options.front_end.on_checkpoint ? options.front_end.on_checkpoint(c) : Status::Ok();
  };
  if (checkpoint) summary.resumed_from_frame = checkpoint->through_frame;
  StageHooks hooks;
  hooks.resume = checkpoint ? &*checkpoint : nullptr;
  hooks.on_done = [&](Stage stage, MissionRun* done) -> Status {
    if (stage == Stage::kFrontEnd) {
      checkpoint.reset();  // the result holds what it had
      const mission::OverlayExtent overlays = mission::ExtentOf(done->mission.overlays);
      summary.overlay_frames = overlays.frames;
      summary.overlay_coverage = overlays.coverage;
      summary.horizon_frames = done->front.horizon_frames;
      if (done->mission.findings) summary.findings = *done->mission.findings;
      summary.frame_rate = done->mission.source.frame_rate;
      if (!done->front.frames.empty() && done->mission.source.frame_rate > 0) {
        summary.video_duration_s =
            done->front.frames.back().time_s + 1.0 / done->mission.source.frame_rate;
      }
    }
    static constexpr unsigned kParts[] = {
        mission::kSaveFrames, mission::kSaveFrames | mission::kSaveGraph, mission::kSaveTracks, 0};
    return commit(done->mission, kParts[static_cast<int>(stage)], StageName(stage));
  };
  if (options.render_tiles) {
    hooks.clear_tiles = [&] { return store->ClearTiles(); };
    hooks.write_tiles = [&](const std::vector<mission::EncodedTile>& batch) {
      return store->WriteTiles(batch);
    };
  }
  summary.video_duration_s = run.mission.source.duration_s;
  const Status ran = RunStages(std::move(reader), stage_options, hooks, job, &run);
  summary.front_end_s = run.seconds[static_cast<int>(Stage::kFrontEnd)];
  summary.mosaic_s = run.seconds[static_cast<int>(Stage::kMosaic)];
  summary.activity_s = run.seconds[static_cast<int>(Stage::kActivity)];
  summary.tiles_s = run.seconds[static_cast<int>(Stage::kTiles)];
  summary.warnings.insert(summary.warnings.end(), run.warnings.begin(), run.warnings.end());
  if (!ran.ok()) {
    if (ran.code() == StatusCode::kCancelled) return cancelled(ran);
    if (run.failed == Stage::kTiles) return Status(ran.code(), mission_path + ": " + ran.message());
    return ran;
  }
  const mission::Mission& m = run.mission;
  summary.frames = static_cast<int64_t>(m.frames.size());
  summary.geo_referenced = m.map.geo_referenced;
  summary.map_frame = DescribeMapFrame(m);
  summary.key_frames = static_cast<int64_t>(m.key_frames.size());
  for (const mission::LinkRecord& l : m.links) {
    summary.cross_links += l.kind != mission::LinkKind::kSequential;
  }
  for (const mission::FrameRecord& f : m.frames) {
    summary.frames_placed += f.map_from_frame.has_value();
  }
  summary.tracks = static_cast<int64_t>(m.tracks.size());
  summary.tracks_implausible = run.activity.tracks_implausible;
  summary.tracks_low_confidence = run.activity.tracks_low_confidence;
  summary.tiles = run.tiles_written;
  // The job is complete: its checkpoint is no longer needed.
  SAKER_RETURN_IF_ERROR(store->ClearCheckpoint());
  summary.progress = m.progress;
  summary.total_s = start.ElapsedSeconds();
  return summary;
}

}  // namespace saker::pipeline
