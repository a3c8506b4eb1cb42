#include "core/pipeline/stages.h"

#include "core/pipeline/mosaic_input.h"
#include "core/util/check.h"
#include "core/util/timer.h"

#include <algorithm>
#include <limits>
#include <map>
#include <utility>

namespace saker::pipeline {
namespace {

// Key frames and links of the adjusted graph, nodes of the last decomposition marked.
void GraphRecords(const mosaic::MosaicResult& result, mission::Mission* m) {
  std::vector<bool> node(result.graph.nodes.size(), false);
  if (result.decomposition) {
    for (const mosaic::KeyFrameId id : result.decomposition->decomposition.nodes) {
      if (static_cast<size_t>(id) < node.size()) node[static_cast<size_t>(id)] = true;
    }
  } else {
    node.assign(node.size(), true);  // the full adjustment: every key frame a node
  }
  m->key_frames.clear();
  for (const mosaic::Node& n : result.graph.nodes) {
    mission::KeyFrameRecord k;
    k.id = static_cast<int32_t>(n.id);
    k.frame_index = n.frame_index;
    k.segment = n.segment;
    k.map_from_frame = n.map_from_frame;
    if (static_cast<size_t>(n.id) < result.covariances.size())
      k.covariance = result.covariances[static_cast<size_t>(n.id)];
    k.node = node[static_cast<size_t>(n.id)];
    m->key_frames.push_back(k);
  }
  m->links.clear();
  for (const mosaic::Link& l : result.graph.links) {
    mission::LinkRecord r;
    r.from = static_cast<int32_t>(l.from);
    r.to = static_cast<int32_t>(l.to);
    r.kind = l.kind;
    r.to_from_from = l.to_from_from;
    r.covariance = l.covariance;
    r.correspondences = static_cast<int32_t>(l.correspondences.size());
    m->links.push_back(r);
  }
}

// The stages, each filling its part of `run`. Each returns whether the later stages can run.

StatusOr<bool> FrontEndStage(std::unique_ptr<video::VideoReader> reader,
                             const StageOptions& options, const StageHooks& hooks, JobContext* job,
                             MissionRun* run) {
  SAKER_ASSIGN_OR_RETURN(
      run->front, frontend::RunFrontEnd(std::move(reader), options.front_end, job, hooks.resume));
  mission::Mission& m = run->mission;
  if (m.source.width == 0) {  // the caller recorded no source: the front end's view of it
    m.source.path = run->front.video.path;
    m.source.width = run->front.video.width;
    m.source.height = run->front.video.height;
    m.source.frame_rate = run->front.video.fps;
  }
  m.source.frame_count = static_cast<int64_t>(run->front.frames.size());
  m.klv = mission::KlvSummary{static_cast<int64_t>(run->front.scan.packets.size()),
                              run->front.scan.ChecksumFailures(),
                              options.front_end.metadata.accept_bad_checksums};
  const frontend::FrontEndResult& front = run->front;
  const frontend::VideoNoise& noise = front.noise;
  m.findings = mission::FrontEndFindings{
      front.low_frame_rate,        static_cast<int64_t>(front.polarity_switches.size()),
      noise.feature_frames,        noise.change_frames,
      noise.residual_threshold_px, noise.change_noise_grey,
      noise.change_registration_px};
  m.frames = FrameRecords(run->front, nullptr, nullptr);
  m.overlays = OverlayRecords(run->front);
  m.progress.front_end = true;
  return true;
}

StatusOr<bool> MosaicStage(const std::string& video, const StageOptions& options, JobContext* job,
                           MissionRun* run) {
  run->mosaic_input = MosaicInputOf(run->front, &run->warnings);
  StatusOr<mosaic::MosaicResult> built =
      mosaic::BuildMosaic(run->mosaic_input, options.mosaic, job);
  if (!built.ok()) {
    if (built.status().code() == StatusCode::kCancelled) return built.status();
    if (built.status().code() != StatusCode::kInvalidData) {
      return Status(built.status().code(), video + ": " + built.status().message());
    }
    // No key frame: a mission without a mosaic (frames and metadata only).
    run->no_mosaic = built.status();
    run->warnings.push_back(video + ": no mosaic: " + built.status().message());
    return false;
  }
  run->mosaic = std::move(*built);
  mission::Mission& m = run->mission;
  m.map.geo_referenced = run->mosaic->graph.geo_referenced;
  m.map.origin = run->mosaic->origin;
  m.frames = FrameRecords(run->front, &run->mosaic_input, &*run->mosaic);
  GraphRecords(*run->mosaic, &m);
  m.progress.mosaic = true;
  return true;
}

StatusOr<bool> ActivityStage(const StageOptions& options, JobContext* job, MissionRun* run) {
  if (job && job->IsCancelled()) return CancelledError("before activity mapping");
  if (job) job->ReportProgress("Activity", 0);
  mission::Mission& m = run->mission;
  m.tracks = TrackRecords(run->front);
  const std::unordered_map<int64_t, activity::TrackEvidence> evidence = TrackEvidenceOf(run->front);
  SAKER_ASSIGN_OR_RETURN(const activity::ActivitySummary mapped,
                         activity::MapActivity(m, &m.tracks, options.activity, &evidence));
  run->activity = mapped;
  if (mapped.observations_dropped > 0) {
    run->warnings.push_back(std::to_string(mapped.observations_dropped) +
                            " target observations lie on frames that could not be placed on "
                            "the map, beyond the horizon of its ground plane, or in the sky or "
                            "distant ground of a low oblique view, and are left out");
  }
  m.progress.activity = true;
  if (job) job->ReportProgress("Activity", 1);
  return true;
}

StatusOr<bool> TilesStage(const StageOptions& options, const StageHooks& hooks, JobContext* job,
                          MissionRun* run) {
  mission::Mission& m = run->mission;
  std::map<int, const track::KeyFrameImage*> images;
  for (const track::KeyFrameImage& image : run->front.key_frame_images) {
    images[static_cast<int>(image.id)] = &image;
  }
  // Each key frame's overlay mask for the picture: its frame's and the last of its chain segment
  // (the overlay was there from the start, and the evidence grows: the first masks hold part of
  // it). Unions are kept per pair, which key frames share for seconds.
  std::map<int, int64_t> segment_start;
  for (const mosaic::Node& node : run->mosaic->graph.nodes) {
    auto [it, added] = segment_start.emplace(node.segment, node.frame_index);
    if (!added) it->second = std::min(it->second, node.frame_index);
  }
  std::map<std::pair<const mission::OverlayRecord*, const mission::OverlayRecord*>,
           mission::OverlayRecord>
      unions;
  const auto overlay_of = [&](const mosaic::Node& node) -> const mission::OverlayRecord* {
    const mission::OverlayRecord* own = mission::OverlayAt(m.overlays, node.frame_index);
    const auto next_segment = segment_start.upper_bound(node.segment);
    const int64_t segment_end = next_segment != segment_start.end()
                                    ? next_segment->second
                                    : std::numeric_limits<int64_t>::max();
    // The last mask that starts in the segment, at or after the key frame's.
    const auto after = std::lower_bound(
        m.overlays.begin(), m.overlays.end(), segment_end,
        [](const mission::OverlayRecord& o, int64_t frame) { return o.first_frame < frame; });
    const mission::OverlayRecord* last =
        after != m.overlays.begin() && std::prev(after)->last_frame >= node.frame_index
            ? &*std::prev(after)
            : nullptr;
    if (own == nullptr || last == nullptr || own == last) return own != nullptr ? own : last;
    if (own->cols != last->cols || own->rows != last->rows || own->cell_px != last->cell_px) {
      return own;
    }
    auto [it, added] = unions.try_emplace({own, last}, *own);
    if (added) {
      for (size_t c = 0; c < it->second.cells.size(); ++c) it->second.cells[c] |= last->cells[c];
    }
    return &it->second;
  };
  std::vector<tiles::KeyFrameView> views;
  for (const mosaic::Node& node : run->mosaic->graph.nodes) {
    const auto it = images.find(static_cast<int>(node.id));
    if (it == images.end() || it->second->grey.empty()) continue;
    std::optional<mission::SkyLine> sky;
    if (const mission::FrameRecord* frame = mission::FrameRecordOf(m, node.frame_index)) {
      sky = frame->sky_line;
    }
    views.push_back({&it->second->grey, it->second->scale, node.map_from_frame, overlay_of(node),
                     sky, &it->second->chroma, it->second->coding});
  }
  StatusOr<mission::PyramidInfo> info = tiles::PlanPyramid(views, m.source.width, m.source.height,
                                                           m.map.geo_referenced, options.pyramid);
  if (!info.ok()) {
    run->warnings.push_back("no mosaic picture: " + info.status().message());
    return false;
  }
  if (hooks.clear_tiles) SAKER_RETURN_IF_ERROR(hooks.clear_tiles());
  SAKER_ASSIGN_OR_RETURN(const tiles::RenderSummary rendered,
                         tiles::RenderPyramid(views, m.source.width, m.source.height, *info,
                                              options.pyramid, hooks.write_tiles, job));
  run->tiles_written = rendered.tiles_written;
  m.pyramid = *info;
  m.progress.tiles = true;
  return true;
}

}  // namespace

const char* StageName(Stage stage) {
  switch (stage) {
    case Stage::kFrontEnd:
      return kStageFrontEnd;
    case Stage::kMosaic:
      return kStageMosaic;
    case Stage::kActivity:
      return kStageActivity;
    case Stage::kTiles:
      return kStageTiles;
  }
  return "?";
}

Status StageOptions::Validate() const {
  SAKER_RETURN_IF_ERROR(front_end.Validate());
  SAKER_RETURN_IF_ERROR(mosaic.Validate());
  SAKER_RETURN_IF_ERROR(activity.Validate());
  return pyramid.Validate();
}

Status RunStages(const std::string& video, const StageOptions& options, const StageHooks& hooks,
                 JobContext* job, MissionRun* run) {
  SAKER_RETURN_IF_ERROR(options.Validate());
  StatusOr<std::unique_ptr<video::VideoReader>> reader =
      video::VideoReader::Open(video, options.front_end.EffectiveReader());
  if (!reader.ok()) {
    run->failed = Stage::kFrontEnd;
    return reader.status();
  }
  return RunStages(std::move(reader).value(), options, hooks, job, run);
}

Status RunStages(std::unique_ptr<video::VideoReader> reader, const StageOptions& options,
                 const StageHooks& hooks, JobContext* job, MissionRun* run) {
  SAKER_CHECK(reader != nullptr) << "RunStages needs an opened reader";
  SAKER_RETURN_IF_ERROR(options.Validate());
  const std::string video = reader->info().path;
  for (const Stage stage : {Stage::kFrontEnd, Stage::kMosaic, Stage::kActivity, Stage::kTiles}) {
    if (static_cast<int>(stage) > static_cast<int>(hooks.last)) break;
    if (stage == Stage::kTiles && !hooks.write_tiles) break;
    const Stopwatch begin;
    StatusOr<bool> go_on = false;
    switch (stage) {
      case Stage::kFrontEnd:
        go_on = FrontEndStage(std::move(reader), options, hooks, job, run);
        break;
      case Stage::kMosaic:
        go_on = MosaicStage(video, options, job, run);
        break;
      case Stage::kActivity:
        go_on = ActivityStage(options, job, run);
        break;
      case Stage::kTiles:
        go_on = TilesStage(options, hooks, job, run);
        break;
    }
    run->seconds[static_cast<int>(stage)] = begin.ElapsedSeconds();
    if (!go_on.ok()) {
      run->failed = stage;
      return go_on.status();
    }
    if (!*go_on) break;
    if (hooks.on_done) SAKER_RETURN_IF_ERROR(hooks.on_done(stage, run));
  }
  return Status::Ok();
}

std::vector<mission::FrameRecord> FrameRecords(const frontend::FrontEndResult& front,
                                               const mosaic::MosaicInput* input,
                                               const mosaic::MosaicResult* mosaic) {
  // The metadata corners are on the map only when the mosaic is geo-referenced by them.
  const bool corners = input != nullptr && mosaic != nullptr && mosaic->origin &&
                       input->metadata_corners.size() == front.frames.size();
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
    if (corners) f.metadata_corners = input->metadata_corners[i];
    if (const std::optional<track::HorizonLine>& sky = front.frames[i].sky_line) {
      const mission::SkyLine line{sky->YAt(0), sky->slope};
      if (line.Problem().empty()) f.sky_line = line;
    }
    if (const klv::FrameMetadata* metadata = front.scan.MetadataOf(i)) {
      if (metadata->unix_time_us) f.utc_us = static_cast<int64_t>(*metadata->unix_time_us);
      if (metadata->sensor_latitude_deg && metadata->sensor_longitude_deg) {
        f.sensor = geo::Wgs84{*metadata->sensor_latitude_deg, *metadata->sensor_longitude_deg,
                              metadata->sensor_altitude_m.value_or(0)};
      }
    }
    frames.push_back(std::move(f));
  }
  return frames;
}

std::vector<mission::OverlayRecord> OverlayRecords(const frontend::FrontEndResult& front) {
  std::vector<mission::OverlayRecord> overlays;
  overlays.reserve(front.overlays.size());
  for (const track::OverlayMask& mask : front.overlays) {
    if (mask.cells.empty()) continue;
    CV_Assert(mask.cells.type() == CV_8U);
    mission::OverlayRecord o;
    o.first_frame = mask.first_frame;
    o.last_frame = mask.last_frame;
    // The mission's masks are disjoint: where the front end's overlap (a mask handed out by a
    // late change answer beside one closed at a chain break), the earlier one keeps the frames.
    if (!overlays.empty()) o.first_frame = std::max(o.first_frame, overlays.back().last_frame + 1);
    if (o.first_frame > o.last_frame || o.first_frame < 0) continue;
    o.cell_px = mask.cell_px;
    o.cols = mask.cells.cols;
    o.rows = mask.cells.rows;
    o.cells.reserve(static_cast<size_t>(o.cols) * static_cast<size_t>(o.rows));
    for (int y = 0; y < o.rows; ++y) {
      const uint8_t* row = mask.cells.ptr<uint8_t>(y);
      for (int x = 0; x < o.cols; ++x) o.cells.push_back(row[x] != 0 ? 1 : 0);
    }
    overlays.push_back(std::move(o));
  }
  return overlays;
}

std::vector<mission::ActivityTrack> TrackRecords(const frontend::FrontEndResult& front) {
  std::vector<mission::ActivityTrack> tracks;
  tracks.reserve(front.targets.size());
  for (const track::TargetTrack& target : front.targets) {
    mission::ActivityTrack t;
    t.id = static_cast<int64_t>(target.id);
    for (const track::TargetObservation& o : target.observations) {
      mission::TrackPoint p;
      p.frame = o.frame;
      p.image = o.position;
      p.box_min = o.box_min;
      p.box_max = o.box_max;
      p.interpolated = o.interpolated;
      t.points.push_back(p);
    }
    if (!t.points.empty()) tracks.push_back(std::move(t));
  }
  return tracks;
}

std::unordered_map<int64_t, activity::TrackEvidence> TrackEvidenceOf(
    const frontend::FrontEndResult& front) {
  std::unordered_map<int64_t, activity::TrackEvidence> evidence;
  for (const track::TargetTrack& target : front.targets) {
    activity::TrackEvidence& e = evidence[static_cast<int64_t>(target.id)];
    for (const track::TargetObservation& o : target.observations) {
      if (o.interpolated) continue;  // no evidence
      ++e.observations;
      e.feature_sightings += static_cast<int64_t>(o.features.size());
      e.looked += o.change != track::ChangeEvidence::kNotLooked;
      e.changed += o.change == track::ChangeEvidence::kChanged;
    }
  }
  return evidence;
}

}  // namespace saker::pipeline
