#include "core/pipeline/process.h"

#include "core/mission/mission_store.h"
#include "core/pipeline/checkpoint.h"
#include "core/video/video_reader.h"

#include <nlohmann/json.hpp>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <map>
#include <sstream>

namespace saker::pipeline {
namespace {

using Clock = std::chrono::steady_clock;

double Seconds(Clock::time_point since) {
  return std::chrono::duration<double>(Clock::now() - since).count();
}

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
        {"change_detection", options.front_end.change.enabled}}},
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

mission::LinkKind MissionLinkKind(mosaic::LinkKind kind) {
  switch (kind) {
    case mosaic::LinkKind::kSequential:
      return mission::LinkKind::kSequential;
    case mosaic::LinkKind::kGeometric:
      return mission::LinkKind::kGeometric;
    case mosaic::LinkKind::kAppearance:
      return mission::LinkKind::kAppearance;
  }
  return mission::LinkKind::kSequential;
}

// Key frames and links of the adjusted graph, nodes of the last decomposition marked.
void GraphRecords(const mosaic::MosaicResult& result, mission::Mission* m) {
  std::vector<bool> node(result.graph.nodes.size(), false);
  if (result.decomposition) {
    for (const mosaic::KeyFrameId id : result.decomposition->decomposition.nodes) {
      if (size_t(id) < node.size()) node[size_t(id)] = true;
    }
  } else {
    node.assign(node.size(), true);  // the full adjustment: every key frame a node
  }
  m->key_frames.clear();
  for (const mosaic::Node& n : result.graph.nodes) {
    mission::KeyFrameRecord k;
    k.id = int32_t(n.id);
    k.frame_index = n.frame_index;
    k.segment = n.segment;
    k.map_from_frame = n.map_from_frame;
    if (size_t(n.id) < result.covariances.size()) k.covariance = result.covariances[size_t(n.id)];
    k.node = node[size_t(n.id)];
    m->key_frames.push_back(k);
  }
  m->links.clear();
  for (const mosaic::Link& l : result.graph.links) {
    mission::LinkRecord r;
    r.from = int32_t(l.from);
    r.to = int32_t(l.to);
    r.kind = MissionLinkKind(l.kind);
    r.to_from_from = l.to_from_from;
    r.covariance = l.covariance;
    r.correspondences = int32_t(l.correspondences.size());
    m->links.push_back(r);
  }
}

}  // namespace

Status ProcessOptions::Validate() const {
  SAKER_RETURN_IF_ERROR(mosaic.Validate());
  SAKER_RETURN_IF_ERROR(activity.Validate());
  SAKER_RETURN_IF_ERROR(pyramid.Validate());
  return {};
}

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
                "moving-target tracks, %lld tiles; %s\n",
                (long long)frames, (long long)frames_placed, (long long)key_frames,
                (long long)cross_links, (long long)tracks, (long long)tiles,
                geo_referenced ? "geo-referenced (metadata)" : "not geo-referenced (no metadata)");
  out << line;
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

std::vector<mission::FrameRecord> FrameRecords(const frontend::FrontEndResult& front,
                                               const mosaic::MosaicResult* mosaic) {
  std::optional<geo::LocalTangentPlane> plane;
  if (mosaic && mosaic->origin) {
    if (auto created = geo::LocalTangentPlane::Create(*mosaic->origin); created.ok()) {
      plane = std::move(*created);
    }
  }
  std::vector<mission::FrameRecord> frames;
  frames.reserve(front.frames.size());
  for (size_t i = 0; i < front.frames.size(); ++i) {
    mission::FrameRecord f;
    f.index = front.frames[i].index;
    f.time_s = front.frames[i].time_s;
    f.pts = front.frames[i].pts;
    f.key_frame = front.frames[i].key_frame;
    if (mosaic && i < mosaic->in_between.map_from_frame.size()) {
      f.map_from_frame = mosaic->in_between.map_from_frame[i];
    }
    if (const klv::FrameMetadata* metadata = front.scan.MetadataOf(i)) {
      if (metadata->unix_time_us) f.utc_us = int64_t(*metadata->unix_time_us);
      if (metadata->sensor_latitude_deg && metadata->sensor_longitude_deg) {
        f.sensor = geo::Wgs84{*metadata->sensor_latitude_deg, *metadata->sensor_longitude_deg,
                              metadata->sensor_altitude_m.value_or(0)};
      }
      if (plane && metadata->corners) {
        std::array<Eigen::Vector2d, 4> corners;
        for (size_t c = 0; c < 4; ++c) {
          corners[c] = plane->MapFromLatLon((*metadata->corners)[c].latitude_deg,
                                            (*metadata->corners)[c].longitude_deg);
        }
        f.metadata_corners = corners;
      }
    }
    frames.push_back(std::move(f));
  }
  return frames;
}

std::vector<mission::ActivityTrack> TrackRecords(const frontend::FrontEndResult& front) {
  std::vector<mission::ActivityTrack> tracks;
  tracks.reserve(front.targets.size());
  for (const track::TargetTrack& target : front.targets) {
    mission::ActivityTrack t;
    t.id = int64_t(target.id);
    for (const track::TargetObservation& o : target.observations) {
      mission::TrackPoint p;
      p.frame = o.frame;
      p.image = o.position;
      p.box_min = o.box_min;
      p.box_max = o.box_max;
      t.points.push_back(p);
    }
    if (!t.points.empty()) tracks.push_back(std::move(t));
  }
  return tracks;
}

StatusOr<mission::Mission> MissionFromRun(const frontend::FrontEndResult& front,
                                          const mosaic::MosaicResult& mosaic,
                                          const activity::ActivityOptions& options) {
  mission::Mission m;
  m.source.path = front.video.path;
  m.source.width = front.video.width;
  m.source.height = front.video.height;
  m.source.frame_rate = front.video.fps;
  m.source.frame_count = int64_t(front.frames.size());
  m.map.geo_referenced = mosaic.graph.geo_referenced;
  m.map.origin = mosaic.origin;
  m.frames = FrameRecords(front, &mosaic);
  GraphRecords(mosaic, &m);
  m.tracks = TrackRecords(front);
  SAKER_RETURN_IF_ERROR(activity::MapActivity(m, &m.tracks, options).status());
  m.progress.front_end = m.progress.mosaic = m.progress.activity = true;
  return m;
}

StatusOr<ProcessSummary> ProcessVideo(const std::string& video, const std::string& mission_path,
                                      const ProcessOptions& options, JobContext* job) {
  SAKER_RETURN_IF_ERROR(options.Validate());
  const auto start = Clock::now();
  ProcessSummary summary;
  // Open the video first: a file that is not a video must not leave (or replace) a mission.
  mission::Mission m;
  m.saker_version = options.saker_version;
  m.options_json = OptionsJson(options);
  {
    SAKER_ASSIGN_OR_RETURN(std::unique_ptr<video::VideoReader> reader,
                           video::VideoReader::Open(video));
    const video::VideoInfo& info = reader->info();
    std::error_code error;
    m.source.path = std::filesystem::absolute(video, error).string();
    if (error) m.source.path = video;
    m.source.width = info.width;
    m.source.height = info.height;
    m.source.frame_rate = info.fps;
    m.source.duration_s = info.duration_s;
    m.source.frame_count = info.declared_frame_count;
    if (std::filesystem::is_regular_file(video, error)) {
      m.source.size_bytes = int64_t(std::filesystem::file_size(video, error));
      SAKER_ASSIGN_OR_RETURN(m.source.fingerprint, mission::FingerprintFile(video));
    }
  }
  std::unique_ptr<mission::MissionStore> store;
  std::optional<frontend::FrontEndCheckpoint> checkpoint;
  if (options.resume) {
    SAKER_ASSIGN_OR_RETURN(
        store, mission::MissionStore::Open(mission_path, mission::OpenMode::kReadWrite));
    SAKER_ASSIGN_OR_RETURN(const mission::Mission previous, store->Load());
    if (!previous.source.fingerprint.empty() && !m.source.fingerprint.empty() &&
        previous.source.fingerprint != m.source.fingerprint) {
      return InvalidArgumentError(mission_path + ": cannot resume with " + video +
                                  ": the mission was made from another video (" +
                                  previous.source.path + ")");
    }
    SAKER_ASSIGN_OR_RETURN(checkpoint, ReadCheckpoint(*store));
    const mission::Progress& p = previous.progress;
    if (!checkpoint && !p.cancelled && p.front_end && p.mosaic && p.activity &&
        (p.tiles || !options.render_tiles)) {
      summary.already_complete = true;
      summary.progress = p;
      summary.frames = int64_t(previous.frames.size());
      summary.key_frames = int64_t(previous.key_frames.size());
      summary.tracks = int64_t(previous.tracks.size());
      summary.geo_referenced = previous.map.geo_referenced;
      summary.total_s = Seconds(start);
      return summary;
    }
    if (!checkpoint) {
      summary.warnings.push_back(mission_path +
                                 ": no checkpoint to resume from: processed from the start");
    }
  } else {
    SAKER_ASSIGN_OR_RETURN(store, mission::MissionStore::Create(mission_path, options.replace));
  }
  const auto commit = [&](unsigned parts, const char* stage) -> Status {
    const auto begin = Clock::now();
    SAKER_RETURN_IF_ERROR(store->Save(m, parts));
    summary.save_s += Seconds(begin);
    if (options.on_commit) options.on_commit(stage);
    return {};
  };
  // A cancelled stage: mark the mission, keep what completed, and say so.
  const auto cancelled = [&](const Status& status) -> Status {
    m.progress.cancelled = true;
    SAKER_RETURN_IF_ERROR(commit(0, "cancelled"));
    summary.progress = m.progress;
    return CancelledError(mission_path +
                          ": processing cancelled; the mission keeps the stages that completed "
                          "and its checkpoint, so that --resume carries on from there (" +
                          status.message() + ")");
  };
  SAKER_RETURN_IF_ERROR(commit(0, "source"));

  // Front end, with its checkpoints going into the mission as it goes.
  auto begin = Clock::now();
  CheckpointWriter checkpoints(store.get(), checkpoint ? &*checkpoint : nullptr);
  frontend::FrontEndOptions front_options = options.front_end;
  front_options.on_checkpoint = [&](const frontend::FrontEndCheckpoint& c) -> Status {
    SAKER_RETURN_IF_ERROR(checkpoints.Write(c));
    return options.front_end.on_checkpoint ? options.front_end.on_checkpoint(c) : Status::Ok();
  };
  if (checkpoint) summary.resumed_from_frame = checkpoint->through_frame;
  StatusOr<frontend::FrontEndResult> front =
      frontend::RunFrontEnd(video, front_options, job, checkpoint ? &*checkpoint : nullptr);
  checkpoint.reset();  // the result holds what it had
  if (!front.ok()) {
    if (front.status().code() == StatusCode::kCancelled) return cancelled(front.status());
    return front.status();
  }
  summary.front_end_s = Seconds(begin);
  summary.frames = int64_t(front->frames.size());
  summary.video_duration_s = m.source.duration_s;
  m.source.frame_count = summary.frames;
  if (!front->frames.empty() && m.source.frame_rate > 0) {
    summary.video_duration_s = front->frames.back().time_s + 1.0 / m.source.frame_rate;
  }
  m.frames = FrameRecords(*front, nullptr);
  m.progress.front_end = true;
  SAKER_RETURN_IF_ERROR(commit(mission::kSaveFrames, "front end"));

  // Mosaic: key frames, loop closure, adjustment, in-between frames.
  begin = Clock::now();
  StatusOr<mosaic::MosaicResult> mosaic_result = mosaic::BuildMosaic(*front, options.mosaic, job);
  summary.mosaic_s = Seconds(begin);
  if (!mosaic_result.ok()) {
    if (mosaic_result.status().code() == StatusCode::kCancelled) {
      return cancelled(mosaic_result.status());
    }
    if (mosaic_result.status().code() != StatusCode::kInvalidData) {
      return Status(mosaic_result.status().code(), video + ": " + mosaic_result.status().message());
    }
    // No key frame: a mission without a mosaic (frames and metadata only).
    summary.warnings.push_back(video + ": no mosaic: " + mosaic_result.status().message());
    SAKER_RETURN_IF_ERROR(store->ClearCheckpoint());
    summary.progress = m.progress;
    summary.total_s = Seconds(start);
    return summary;
  }
  const mosaic::MosaicResult& result = *mosaic_result;
  m.map.geo_referenced = result.graph.geo_referenced;
  m.map.origin = result.origin;
  m.frames = FrameRecords(*front, &result);
  GraphRecords(result, &m);
  m.progress.mosaic = true;
  summary.geo_referenced = m.map.geo_referenced;
  summary.key_frames = int64_t(m.key_frames.size());
  for (const mission::LinkRecord& l : m.links) {
    summary.cross_links += l.kind != mission::LinkKind::kSequential;
  }
  for (const mission::FrameRecord& f : m.frames)
    summary.frames_placed += f.map_from_frame.has_value();
  SAKER_RETURN_IF_ERROR(commit(mission::kSaveFrames | mission::kSaveGraph, "mosaic"));

  // Activity: tracks on the map with their attributes.
  if (job && job->IsCancelled()) return cancelled(CancelledError("before activity mapping"));
  begin = Clock::now();
  if (job) job->ReportProgress("Activity", 0);
  m.tracks = TrackRecords(*front);
  SAKER_ASSIGN_OR_RETURN(const activity::ActivitySummary mapped,
                         activity::MapActivity(m, &m.tracks, options.activity));
  if (mapped.observations_dropped > 0) {
    summary.warnings.push_back(std::to_string(mapped.observations_dropped) +
                               " target observations lie on frames that could not be placed on "
                               "the map and are left out");
  }
  summary.activity_s = Seconds(begin);
  summary.tracks = int64_t(m.tracks.size());
  m.progress.activity = true;
  SAKER_RETURN_IF_ERROR(commit(mission::kSaveTracks, "activity"));
  if (job) job->ReportProgress("Activity", 1);

  // Tiles of the mosaic picture.
  if (options.render_tiles) {
    begin = Clock::now();
    std::map<int, const frontend::KeyFrameImage*> images;
    for (const frontend::KeyFrameImage& image : front->key_frame_images) {
      images[int(image.id)] = &image;
    }
    std::vector<tiles::KeyFrameView> views;
    for (const mosaic::Node& node : result.graph.nodes) {
      const auto it = images.find(int(node.id));
      if (it == images.end() || it->second->grey.empty()) continue;
      views.push_back({&it->second->grey, it->second->scale, node.map_from_frame});
    }
    StatusOr<mission::PyramidInfo> info = tiles::PlanPyramid(views, m.source.width, m.source.height,
                                                             m.map.geo_referenced, options.pyramid);
    if (info.ok()) {
      SAKER_RETURN_IF_ERROR(store->ClearTiles());
      const auto rendered = tiles::RenderPyramid(
          views, m.source.width, m.source.height, *info, options.pyramid,
          [&](const std::vector<mission::EncodedTile>& batch) { return store->WriteTiles(batch); },
          job);
      if (!rendered.ok()) {
        if (rendered.status().code() == StatusCode::kCancelled) return cancelled(rendered.status());
        return Status(rendered.status().code(), mission_path + ": " + rendered.status().message());
      }
      summary.tiles = rendered->tiles_written;
      m.pyramid = *info;
      m.progress.tiles = true;
      SAKER_RETURN_IF_ERROR(commit(0, "tiles"));
    } else {
      summary.warnings.push_back("no mosaic picture: " + info.status().message());
    }
    summary.tiles_s = Seconds(begin);
  }
  // The job is complete: its checkpoint is no longer needed.
  SAKER_RETURN_IF_ERROR(store->ClearCheckpoint());
  summary.progress = m.progress;
  summary.total_s = Seconds(start);
  return summary;
}

}  // namespace saker::pipeline
