#pragma once

// One entry point from a video to a saved mission: ingest and front end, key frames, loop
// closure and adjustment, in-between frames, activity mapping, the mosaic's tile pyramid. Each
// stage's result is committed to the mission file as it completes (one transaction each), so a
// viewer can open the mission while it is processed, a cancelled job keeps what completed and a
// crash leaves the last committed state. docs/missions.md.

#include "core/activity/activity.h"
#include "core/frontend/front_end.h"
#include "core/mission/mission.h"
#include "core/mosaic/mosaic_builder.h"
#include "core/pipeline/stages.h"
#include "core/tiles/pyramid.h"
#include "core/util/job_context.h"
#include "core/util/status.h"

#include <functional>
#include <string>

namespace saker::pipeline {

// The engine's options (StageOptions: front_end, mosaic, activity, pyramid) and the job's.
struct ProcessOptions : StageOptions {
  bool render_tiles = true;  // false: no mosaic picture in the mission (faster)
  bool replace = false;      // overwrite an existing mission file (never a foreign file)
  // Carry on an interrupted job (saker-cli process --resume): the mission at `mission_path` must
  // exist and have been made from this video. The front end resumes from the checkpoint the
  // mission holds (from the start when it holds none) and the later stages run again; a mission
  // that is complete is left as it is. docs/reliability.md, "Resume".
  bool resume = false;
  std::string saker_version;  // recorded in the mission
  // Called on the processing thread after each commit, with the stage just saved (kStageSource,
  // then a stage's name, stages.h; kStageCancelled marks a cancelled job): a viewer reloads the
  // mission then.
  std::function<void(const std::string& stage)> on_commit;

  Status Validate() const;
};

struct ProcessSummary {
  mission::Progress progress;  // what completed
  int64_t frames = 0;
  int64_t frames_placed = 0;
  int64_t key_frames = 0;
  int64_t cross_links = 0;
  int64_t tracks = 0;
  int64_t tracks_implausible = 0;     // not reported: impossible ground speed
  int64_t tracks_low_confidence = 0;  // not reported: below activity.confidence.min_confidence
  int64_t tiles = 0;
  bool geo_referenced = false;
  double frame_rate = 0;  // the video's, frames a second
  // Screen-fixed overlays (burned-in text, logos) masked out: in this many frames, covering this
  // mean fraction of the image in them (0 and 0: none found, or the mask was off).
  int64_t overlay_frames = 0;
  double overlay_coverage = 0;
  // Frames of a low oblique view whose sky and distant ground above the horizon were masked out
  // (FrontEndResult::horizon_frames).
  int64_t horizon_frames = 0;
  // What else the front end found about the video (the low-frame-rate mode, thresholds raised by
  // its noise, thermal polarity switches), as the mission keeps it.
  mission::FrontEndFindings findings;
  std::string map_frame;  // DescribeMapFrame (open_mission.h): what the map is, and why
  double front_end_s = 0, mosaic_s = 0, activity_s = 0, tiles_s = 0, save_s = 0, total_s = 0;
  double video_duration_s = 0;
  int64_t resumed_from_frame = -1;    // the checkpoint's last frame a resumed job went on from
  bool already_complete = false;      // resume found nothing left to do
  std::vector<std::string> warnings;  // what could not be done, for a person (not errors)
  std::string ToText() const;         // a few lines for a person
};

// Processes `video` into a new mission file at `mission_path` (or resumes, options.resume).
// The video is opened once: one reader gives the source record, then the front end decodes with
// it. Errors name the file. The front end's checkpoints go into the mission as it runs and are
// dropped when the job completes. When `job` is cancelled the mission keeps the stages that
// completed and its checkpoint, is marked cancelled, and the result is a Cancelled status saying
// so. A video in which the front end finds no key frame still gives
// a mission (frames and metadata; no mosaic), and the summary says so.
StatusOr<ProcessSummary> ProcessVideo(const std::string& video, const std::string& mission_path,
                                      const ProcessOptions& options, JobContext* job = nullptr);

}  // namespace saker::pipeline
