#include "app/cli_mission.h"

#include "app/cli_common.h"
#include "app/cli_interrupt.h"
#include "app/cli_mosaic.h"
#include "core/activity/colours.h"
#include "core/activity/confidence.h"
#include "core/mission/mission_store.h"
#include "core/mosaic/decomposition.h"
#include "core/pipeline/checkpoint.h"
#include "core/pipeline/export_mission.h"
#include "core/pipeline/open_mission.h"
#include "core/pipeline/process.h"
#include "core/render/activity_map.h"
#include "core/util/memory.h"

#include <nlohmann/json.hpp>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <map>

namespace saker::app {
// ---------------------------------------------------------------------------------------------
struct ProcessCommand::State {
  CLI::App* command = nullptr;
  std::string video;
  std::string mission;
  bool replace = false;
  bool json = false;
  bool quiet = false;
  bool no_metadata = false;
  bool no_tiles = false;
  bool fixed_thresholds = false;  // --noise-thresholds fixed
  std::string adjust = "decomposed";
  pipeline::ProcessOptions options;
};

ProcessCommand::ProcessCommand(CLI::App& app) : state_(std::make_unique<State>()) {
  State& s = *state_;
  s.command = app.add_subcommand(
      "process",
      "Process a video into a mission file: front end (moving targets, key frames), loop\n"
      "closure and bundle adjustment, every frame placed on the map, activity mapping (speed,\n"
      "direction, visit and confidence of every track; tracks faster than 70 m/s on the ground\n"
      "are not reported), and the mosaic's tile pyramid. Each stage is saved as it\n"
      "completes; Ctrl-C cancels cleanly and leaves a valid mission holding the stages that\n"
      "completed. The front end checkpoints its work into the mission (every 30 s, at a key\n"
      "frame): after Ctrl-C, a crash or a power cut, --resume carries on from the last\n"
      "checkpoint instead of starting again. See docs/missions.md and docs/reliability.md.");
  s.command->add_option("VIDEO", s.video, "Video file (MPEG-TS, MP4, ...)")->required();
  s.command->add_option("-o,--output", s.mission, "Mission file to write (.saker)")->required();
  s.command->add_flag("--replace", s.replace,
                      "Replace an existing mission file (never a file that is not a mission, nor "
                      "one that another job is writing)");
  s.command
      ->add_flag("--resume", s.options.resume,
                 "Carry on an interrupted job in the existing mission file (made from the same "
                 "video) from its last checkpoint; a complete mission is left as it is")
      ->excludes("--replace");
  s.command
      ->add_option("--checkpoint-every", s.options.front_end.checkpoint_interval_s,
                   "Seconds between the front end's checkpoints (taken at the next key frame; 0: "
                   "at every key frame)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  s.command->add_flag("--json", s.json, "Print the summary as JSON");
  s.command->add_flag("-q,--quiet", s.quiet, "No progress on stderr");
  s.command->add_flag("--no-metadata", s.no_metadata,
                      "Ignore the metadata corners (map frame = the first key frame's pixels)");
  s.command->add_flag("--no-tiles", s.no_tiles, "Do not render the mosaic's tile pyramid");
  AddAcceptBadChecksumsFlag(s.command, &s.options.front_end.metadata.accept_bad_checksums);
  AddOverlayMaskOption(s.command, &s.options.front_end.overlays.enabled);
  AddHorizonMaskOption(s.command, &s.options.front_end.horizon.enabled);
  AddNoiseThresholdsOption(s.command, &s.fixed_thresholds);
  AddLowFrameRateOption(s.command, &s.options.front_end.low_frame_rate.mode);
  AddAdjustOption(s.command, &s.adjust);
  s.command
      ->add_option("--visit-gap", s.options.activity.visit_gap_s,
                   "Seconds out of view after which the camera's return over a place is a new "
                   "visit")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  AddMinConfidenceOption(s.command, &s.options.activity.confidence.min_confidence,
                         "are not stored in the mission");
  s.options.front_end.max_memory_mib = DefaultMemoryLimitMiB();
  s.command
      ->add_option("--max-memory", s.options.front_end.max_memory_mib,
                   "Stop with an error, naming the frame reached, when Saker's memory exceeds this "
                   "many MiB, or before decoding when the decoder and frame queues would take it "
                   "over (default: three quarters of this machine's memory; 0: no limit)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
}

ProcessCommand::~ProcessCommand() = default;
bool ProcessCommand::parsed() const { return state_->command->parsed(); }
int ProcessCommand::Run() const { return RunOn(state_->video, state_->mission, state_->replace); }

int ProcessCommand::RunOn(const std::string& video, const std::string& mission,
                          bool replace) const {
  const State& s = *state_;
  pipeline::ProcessOptions options = s.options;
  if (s.fixed_thresholds) options.front_end.UseFixedThresholds();
  options.replace = replace;
  options.saker_version = SAKER_VERSION;
  options.mosaic.use_metadata = !s.no_metadata;
  options.mosaic.adjust_mode = *mosaic::ParseAdjustmentMode(s.adjust);
  options.render_tiles = !s.no_tiles;
  const bool show_progress = !s.quiet && !s.json;
  JobContext job = ProgressContext(!show_progress);
  StatusOr<pipeline::ProcessSummary> summary = [&] {
    const ScopedInterrupt interrupt(&job);
    return pipeline::ProcessVideo(video, mission, options, &job);
  }();
  ClearProgressLine(show_progress);
  if (!summary.ok()) return Fail(summary.status());
  if (s.json) {
    const pipeline::ProcessSummary& p = *summary;
    nlohmann::json warnings = p.warnings;
    std::cout << nlohmann::json{{"video", video},
                                {"mission", mission},
                                {"frames", p.frames},
                                {"frames_placed", p.frames_placed},
                                {"key_frames", p.key_frames},
                                {"cross_links", p.cross_links},
                                {"tracks", p.tracks},
                                {"tracks_implausible", p.tracks_implausible},
                                {"tracks_low_confidence", p.tracks_low_confidence},
                                {"tiles", p.tiles},
                                {"geo_referenced", p.geo_referenced},
                                {"low_frame_rate", p.findings.low_frame_rate},
                                {"overlay_frames", p.overlay_frames},
                                {"overlay_coverage", p.overlay_coverage},
                                {"polarity_switches", p.findings.polarity_switches},
                                {"horizon_frames", p.horizon_frames},
                                {"noise_feature_frames", p.findings.noise_feature_frames},
                                {"noise_change_frames", p.findings.noise_change_frames},
                                {"front_end_s", p.front_end_s},
                                {"mosaic_s", p.mosaic_s},
                                {"activity_s", p.activity_s},
                                {"tiles_s", p.tiles_s},
                                {"save_s", p.save_s},
                                {"total_s", p.total_s},
                                {"video_duration_s", p.video_duration_s},
                                {"resumed_from_frame", p.resumed_from_frame},
                                {"already_complete", p.already_complete},
                                {"warnings", warnings}}
                     .dump(2)
              << "\n";
  } else {
    std::cout << mission << ": " << summary->ToText();
  }
  return kExitOk;
}

// ---------------------------------------------------------------------------------------------
struct ExportCommand::State {
  CLI::App* command = nullptr;
  std::string mission;
  std::string png, geotiff, geojson, kml, csv;
  std::string colour_by = "speed";
  int level = 0;
  render::ActivityMapOptions map;
  double start_s = -1, end_s = -1;
  double min_confidence = 0;
  bool include_false = false;
};

ExportCommand::ExportCommand(CLI::App& app) : state_(std::make_unique<State>()) {
  State& s = *state_;
  s.command = app.add_subcommand(
      "export",
      "Export a mission for other tools: the activity map picture (mosaic with the tracks\n"
      "coloured, legend, scale bar and north arrow when geo-referenced), the mosaic as GeoTIFF\n"
      "(UTM of the map origin when geo-referenced), the tracks as GeoJSON (WGS84), KML and CSV\n"
      "with every attribute, confidence included. Give one or more outputs; \"-\" writes one to\n"
      "standard output.\n"
      "An output may not be the mission or its video. Ctrl-C cancels and leaves no partial\n"
      "file. See docs/exports.md.");
  s.command->add_option("MISSION", s.mission, "Mission file (.saker)")->required();
  s.command->add_option("--png", s.png, "Activity map picture to write (.png or .jpg)");
  s.command->add_option("--geotiff", s.geotiff, "Mosaic GeoTIFF to write (.tif)");
  s.command->add_option("--geojson", s.geojson, "Tracks as GeoJSON");
  s.command->add_option("--kml", s.kml, "Tracks as KML (geo-referenced missions)");
  s.command->add_option("--csv", s.csv, "Track observations as CSV");
  s.command
      ->add_option("--color-by,--colour-by", s.colour_by,
                   "Track colours on the activity map; density: a heat map of the tracks' "
                   "observations per cell instead of the tracks")
      ->capture_default_str()
      ->check(CLI::IsMember({"speed", "direction", "visit", "time", "density"}));
  s.command
      ->add_option("--level", s.level,
                   "GeoTIFF resolution: pyramid level (0 = full, each level halves it)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  s.command
      ->add_option("--max-side", s.map.max_side_px, "Activity map: longer side of the mosaic, px")
      ->capture_default_str()
      ->check(CLI::Range(64, 30000));
  s.command->add_option("--from", s.start_s, "Activity map: only tracks seen after this second");
  s.command->add_option("--to", s.end_s, "Activity map: only tracks seen before this second");
  AddMinConfidenceOption(s.command, &s.min_confidence,
                         "are left out of every output (the activity map included)");
  s.command->add_flag("--include-false", s.include_false,
                      "Also export the tracks the analyst marked false (left out by default; the "
                      "exports carry each track's verdict, label and note)");
}

ExportCommand::~ExportCommand() = default;
bool ExportCommand::parsed() const { return state_->command->parsed(); }

int ExportCommand::Run() const {
  const State& s = *state_;
  if (s.png.empty() && s.geotiff.empty() && s.geojson.empty() && s.kml.empty() && s.csv.empty()) {
    std::cerr << "saker-cli export: give at least one of --png, --geotiff, --geojson, --kml, "
                 "--csv\n";
    return kExitUsage;
  }
  StatusOr<std::unique_ptr<mission::MissionStore>> store =
      mission::MissionStore::Open(s.mission, mission::OpenMode::kSnapshot);
  if (!store.ok()) return Fail(store.status());
  StatusOr<mission::Mission> m = (*store)->Load();
  if (!m.ok()) return Fail(m.status());
  std::erase_if(m->tracks, [&](const mission::ActivityTrack& t) {
    return !activity::PassesConfidence(t, s.min_confidence) ||
           (!s.include_false && mission::IsMarkedFalse(*m, t.id));
  });
  pipeline::ExportRequest request;
  request.png = s.png;
  request.map = s.map;
  request.map.colour_by = *activity::ParseColourMode(s.colour_by);
  if (s.start_s >= 0) request.map.start_s = s.start_s;
  if (s.end_s >= 0) request.map.end_s = s.end_s;
  request.geotiff = s.geotiff;
  request.level = s.level;
  request.geojson = s.geojson;
  request.kml = s.kml;
  request.csv = s.csv;
  JobContext job;
  StatusOr<std::vector<pipeline::ExportedFile>> written = [&] {
    const ScopedInterrupt interrupt(&job);
    return pipeline::ExportMission(*m, **store, request, &job);
  }();
  if (!written.ok()) return Fail(written.status());
  // An export to standard output keeps it for the file alone.
  bool to_stdout = false;
  for (const pipeline::ExportedFile& file : *written) {
    to_stdout = to_stdout || file.path == "-" || file.path == "/dev/stdout";
  }
  std::ostream& out = to_stdout ? std::cerr : std::cout;
  for (const pipeline::ExportedFile& file : *written) {
    out << "wrote " << (file.path == "-" ? "standard output" : file.path) << " (" << file.what
        << ")\n";
  }
  return kExitOk;
}

int ExportCommand::WriteActivityMap(const std::string& mission, const std::string& png) {
  State& s = *state_;
  s.mission = mission;
  s.png = png;
  return Run();
}

// ---------------------------------------------------------------------------------------------
struct CopyCommand::State {
  CLI::App* command = nullptr;
  std::string from, to;
  bool replace = false;
};

CopyCommand::CopyCommand(CLI::App& app) : state_(std::make_unique<State>()) {
  State& s = *state_;
  s.command = app.add_subcommand(
      "copy",
      "Copy a mission to a new file, tiles included (the GUI's Save As). The copy is built\n"
      "beside the target and renamed into place, so an interruption leaves either no copy or a\n"
      "complete one, and never touches the original.");
  s.command->add_option("MISSION", s.from, "Mission file to copy (.saker)")->required();
  s.command->add_option("NEW", s.to, "The copy (.saker)")->required();
  s.command->add_flag("--replace", s.replace,
                      "Replace an existing mission file (never a file that is not a mission, nor "
                      "one that a job is writing)");
}

CopyCommand::~CopyCommand() = default;
bool CopyCommand::parsed() const { return state_->command->parsed(); }

int CopyCommand::Run() const {
  const State& s = *state_;
  JobContext job;
  const Status copied = [&] {
    const ScopedInterrupt interrupt(&job);
    return pipeline::CopyMission(s.from, s.to, s.replace, &job);
  }();
  if (!copied.ok()) return Fail(copied);
  std::cout << "wrote " << s.to << "\n";
  return kExitOk;
}

// ---------------------------------------------------------------------------------------------
struct InfoCommand::State {
  CLI::App* command = nullptr;
  std::string mission;
  bool json = false;
};

InfoCommand::InfoCommand(CLI::App& app) : state_(std::make_unique<State>()) {
  State& s = *state_;
  s.command = app.add_subcommand(
      "info",
      "What a mission holds: its video (and whether it is still where it was, which frame\n"
      "recall needs), the stages completed, frames, the screen-fixed overlay masks and the\n"
      "frames whose sky was masked (low oblique views), what else the front end found (the\n"
      "low-frame-rate mode, thresholds raised by the video's noise, thermal polarity\n"
      "switches), key frames, links, tracks by visit and confidence, the map frame and the\n"
      "mosaic pyramid. Opens the file read-only; never reprocesses.");
  s.command->add_option("MISSION", s.mission, "Mission file (.saker)")->required();
  s.command->add_flag("--json", s.json, "Print as JSON");
}

InfoCommand::~InfoCommand() = default;
bool InfoCommand::parsed() const { return state_->command->parsed(); }

int InfoCommand::Run() const {
  const State& s = *state_;
  pipeline::OpenMissionOptions open_options;
  open_options.read_previews = false;
  StatusOr<pipeline::OpenedMission> opened = pipeline::OpenMission(s.mission, open_options);
  if (!opened.ok()) return Fail(opened.status());
  const mission::Mission* m = &opened->mission;
  const int64_t* tiles = &opened->tiles;
  const std::optional<pipeline::CheckpointState>& checkpoint = opened->checkpoint;
  // Is the video still there, and the same file?
  std::string video_state;
  const pipeline::VideoLocation& video = opened->video;
  switch (video.state) {
    case pipeline::VideoLocation::State::kFound:
      video_state = video.path == m->source.path ? "present" : "moved: found at " + video.path;
      break;
    case pipeline::VideoLocation::State::kChanged:
      video_state = "changed: the file at " + video.path + " is not the video that was processed";
      break;
    case pipeline::VideoLocation::State::kMissing:
      video_state = "missing: frame recall needs it (the mosaic and tracks do not)";
      break;
  }
  std::map<int, int> visits;
  int64_t observations = 0, interpolated = 0;
  for (const mission::ActivityTrack& t : m->tracks) {
    ++visits[t.visit];
    observations += static_cast<int64_t>(t.points.size());
    for (const mission::TrackPoint& p : t.points) interpolated += p.interpolated;
  }
  const activity::ConfidenceSpread confidence = activity::SpreadOf(m->tracks);
  int64_t placed = 0;
  for (const mission::FrameRecord& f : m->frames) placed += f.map_from_frame.has_value();
  std::map<std::string, int> links;
  for (const mission::LinkRecord& l : m->links) ++links[mission::LinkKindName(l.kind)];
  const mission::Progress& p = m->progress;
  std::string stages;
  for (const auto& [done, name] :
       std::vector<std::pair<bool, const char*>>{{p.front_end, "front end"},
                                                 {p.mosaic, "mosaic"},
                                                 {p.activity, "activity"},
                                                 {p.tiles, "tiles"}}) {
    if (done) stages += std::string(stages.empty() ? "" : ", ") + name;
  }
  if (stages.empty()) stages = "none";
  // The screen-fixed overlay masks: the frames they cover and the image fraction they take there.
  const mission::OverlayExtent overlay_extent = mission::ExtentOf(m->overlays);
  const int64_t overlay_frames = overlay_extent.frames;
  const double overlay_coverage = overlay_extent.coverage;
  const bool overlays_kept = m->schema_version >= 5;
  // Low oblique views: the frames whose sky above the horizon was masked.
  const bool sky_kept = m->schema_version >= 6;
  const int64_t sky_frames =
      std::count_if(m->frames.begin(), m->frames.end(),
                    [](const mission::FrameRecord& f) { return f.sky_line.has_value(); });
  // The analyst's reviews.
  struct {
    int64_t confirmed = 0, marked_false = 0, labelled = 0, noted = 0;
  } reviews;
  for (const mission::TrackReview& r : m->reviews) {
    reviews.confirmed += r.verdict == mission::Verdict::kConfirmed ? 1 : 0;
    reviews.marked_false += r.verdict == mission::Verdict::kFalse ? 1 : 0;
    reviews.labelled += r.label != mission::TargetLabel::kNone ? 1 : 0;
    reviews.noted += r.note.empty() ? 0 : 1;
  }
  if (s.json) {
    nlohmann::json visit_json = nlohmann::json::object();
    for (const auto& [v, n] : visits) visit_json[std::to_string(v)] = n;
    nlohmann::json j = {{"mission", s.mission},
                        {"schema_version", m->schema_version},
                        {"saker_version", m->saker_version},
                        {"video", m->source.path},
                        {"video_state", video_state},
                        {"width", m->source.width},
                        {"height", m->source.height},
                        {"frame_rate", m->source.frame_rate},
                        {"frames", m->frames.size()},
                        {"frames_placed", placed},
                        {"key_frames", m->key_frames.size()},
                        {"links", links},
                        {"tracks", m->tracks.size()},
                        {"observations", observations},
                        {"interpolated_observations", interpolated},
                        {"tracks_by_visit", visit_json},
                        {"tracks_by_confidence",
                         {{"below_0_5", confidence.low},
                          {"0_5_to_0_8", confidence.medium},
                          {"at_least_0_8", confidence.high},
                          {"unknown", confidence.unknown}}},
                        {"geo_referenced", m->map.geo_referenced},
                        {"map_frame", pipeline::DescribeMapFrame(*m)},
                        {"frames_with_metadata", pipeline::FramesWithMetadata(*m)},
                        {"tiles", *tiles},
                        {"completed",
                         {{"front_end", p.front_end},
                          {"mosaic", p.mosaic},
                          {"activity", p.activity},
                          {"tiles", p.tiles}}},
                        {"cancelled", p.cancelled}};
    if (sky_kept) j["sky_frames"] = sky_frames;
    if (const std::optional<mission::FrontEndFindings>& f = m->findings) {
      j["findings"] = {{"low_frame_rate", f->low_frame_rate},
                       {"polarity_switches", f->polarity_switches},
                       {"noise_feature_frames", f->noise_feature_frames},
                       {"noise_change_frames", f->noise_change_frames},
                       {"noise_feature_px", f->noise_feature_px},
                       {"noise_change_grey", f->noise_change_grey},
                       {"noise_change_registration_px", f->noise_change_registration_px}};
    }
    j["reviews"] = {{"confirmed", reviews.confirmed},
                    {"false", reviews.marked_false},
                    {"labelled", reviews.labelled},
                    {"with_notes", reviews.noted},
                    {"bookmarks", m->bookmarks.size()}};
    if (overlays_kept) {
      j["overlay_masks"] = {{"masks", m->overlays.size()},
                            {"frames", overlay_frames},
                            {"coverage", overlay_coverage}};
    }
    if (checkpoint) {
      j["checkpoint"] = {{"through_frame", checkpoint->through_frame},
                         {"complete", checkpoint->complete},
                         {"key_frames", checkpoint->key_frames}};
    }
    if (m->klv) {
      j["klv"] = {{"packets", m->klv->packets},
                  {"checksum_failures", m->klv->checksum_failures},
                  {"bad_checksums_used", m->klv->bad_checksums_used}};
    }
    if (m->map.origin) {
      j["origin"] = {{"latitude_deg", m->map.origin->latitude_deg},
                     {"longitude_deg", m->map.origin->longitude_deg},
                     {"height_m", m->map.origin->height_m}};
    }
    std::cout << j.dump(2) << "\n";
    return kExitOk;
  }
  std::cout << s.mission << " (schema " << m->schema_version << ", written by Saker "
            << m->saker_version << ")\n";
  std::cout << "  video: " << m->source.path << " (" << video_state << ")\n";
  std::cout << "         " << m->source.width << "x" << m->source.height << ", "
            << m->source.frame_rate << " fps, " << m->frames.size() << " frames\n";
  std::cout << "  completed: " << stages << (p.cancelled ? " (then cancelled)" : "") << "\n";
  if (checkpoint) {
    std::cout << "  checkpoint: ";
    if (checkpoint->complete) {
      std::cout << "the front end's result (a later stage was interrupted)";
    } else {
      std::cout << "the front end up to frame " << checkpoint->through_frame << " ("
                << checkpoint->key_frames << " key frames)";
    }
    std::cout << "; carry on with: saker-cli process VIDEO -o " << s.mission << " --resume\n";
  }
  std::cout << "  map: " << pipeline::DescribeMapFrame(*m) << "\n";
  std::cout << "  metadata: " << pipeline::FramesWithMetadata(*m) << " of " << m->frames.size()
            << " frames";
  if (const std::string klv = pipeline::DescribeKlv(*m); !klv.empty()) std::cout << "; KLV " << klv;
  std::cout << "\n";
  std::cout << "  frames placed on the map: " << placed << " of " << m->frames.size() << "\n";
  std::cout << "  overlay masks: ";
  if (!overlays_kept) {
    std::cout << "not kept (written before Saker kept them)\n";
  } else if (m->overlays.empty()) {
    std::cout << "none (no screen-fixed text or logo was found)\n";
  } else {
    char line[160];
    std::snprintf(line, sizeof(line), "%zu over %lld frames, %.1f %% of the image there\n",
                  m->overlays.size(), static_cast<long long>(overlay_frames),
                  100 * overlay_coverage);
    std::cout << line;
  }
  std::cout << "  sky masked: ";
  if (!sky_kept) {
    std::cout << "not kept (written before Saker kept it)\n";
  } else if (sky_frames == 0) {
    std::cout << "none (no frame reaches the horizon)\n";
  } else {
    std::cout << sky_frames << " of " << m->frames.size()
              << " frames reach the horizon; their sky and distant ground are left out of the "
                 "mosaic\n";
  }
  std::cout << "  front end found: ";
  if (!m->findings) {
    std::cout << (p.front_end ? "not kept (written before Saker kept it)\n" : "not run yet\n");
  } else if (const std::vector<pipeline::Finding> found = pipeline::DescribeFindings(
                 *m->findings, static_cast<int64_t>(m->frames.size()), m->source.frame_rate);
             found.empty()) {
    std::cout << "nothing unusual (full frame rate, thresholds not raised by noise)\n";
  } else {
    for (size_t i = 0; i < found.size(); ++i) {
      std::cout << (i == 0 ? "" : "                   ") << found[i].sentence << "\n";
    }
  }
  std::cout << "  key frames: " << m->key_frames.size() << "; links:";
  for (const auto& [kind, n] : links) std::cout << " " << n << " " << kind;
  std::cout << "\n  tracks: " << m->tracks.size() << " (" << observations << " observations";
  if (interpolated > 0) std::cout << ", " << interpolated << " of them interpolated across gaps";
  std::cout << ")";
  for (const auto& [v, n] : visits) std::cout << "; visit " << v << ": " << n;
  if (!m->tracks.empty()) {
    std::cout << "\n  track confidence: " << confidence.high << " at 0.8 or more, "
              << confidence.medium << " from 0.5 to 0.8, " << confidence.low << " below 0.5";
    if (confidence.unknown > 0) {
      std::cout << ", " << confidence.unknown << " unknown (written before Saker kept it)";
    }
  }
  if (!m->reviews.empty() || !m->bookmarks.empty()) {
    std::cout << "\n  analyst: " << reviews.confirmed << " tracks confirmed, "
              << reviews.marked_false << " marked false (left out of exports unless "
              << "--include-false), " << reviews.labelled << " labelled, " << reviews.noted
              << " with notes; " << m->bookmarks.size() << " bookmarks";
  }
  std::cout << "\n  mosaic tiles: " << *tiles;
  if (m->pyramid) {
    std::cout << " (" << m->pyramid->levels << " levels, " << m->pyramid->width << "x"
              << m->pyramid->height << " px at full resolution)";
  }
  std::cout << "\n";
  return kExitOk;
}

}  // namespace saker::app
