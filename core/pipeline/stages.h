#pragma once
// The engine's stages from a video to a mission, listed once (RunStages) and used by every job
// that runs them: ProcessVideo (which commits the mission file after each), the evaluation
// against the simulator's truth (no file, no tiles) and `saker-cli mosaic` (front end and mosaic).
//
//   front end ─▶ mosaic ─▶ activity ─▶ tiles
//
// Each stage fills its part of MissionRun::mission from what the earlier ones left in the run.

#include "core/activity/activity.h"
#include "core/frontend/front_end.h"
#include "core/mission/mission.h"
#include "core/mosaic/mosaic_builder.h"
#include "core/mosaic/mosaic_input.h"
#include "core/tiles/pyramid.h"
#include "core/util/job_context.h"
#include "core/util/status.h"
#include "core/video/video_reader.h"

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

namespace saker::pipeline {

// The names a job reports its commits by (ProcessOptions::on_commit): the source record before
// any stage, then each stage's, or "cancelled" for the commit that marks a cancelled mission.
inline constexpr char kStageSource[] = "source";
inline constexpr char kStageFrontEnd[] = "front end";
inline constexpr char kStageMosaic[] = "mosaic";
inline constexpr char kStageActivity[] = "activity";
inline constexpr char kStageTiles[] = "tiles";
inline constexpr char kStageCancelled[] = "cancelled";

enum class Stage { kFrontEnd, kMosaic, kActivity, kTiles };
const char* StageName(Stage stage);  // kStageFrontEnd, ...

// The engine's options for every stage.
struct StageOptions {
  frontend::FrontEndOptions front_end;
  mosaic::MosaicOptions mosaic;
  activity::ActivityOptions activity;
  tiles::PyramidOptions pyramid;
  Status Validate() const;
};

// One job's work in progress: the mission as it grows, and what a later stage needs of an earlier
// one.
struct MissionRun {
  mission::Mission mission;
  frontend::FrontEndResult front;
  mosaic::MosaicInput mosaic_input;
  std::optional<mosaic::MosaicResult> mosaic;  // nullopt: no mosaic (no key frame) or not run
  // Why the mosaic stage made none (InvalidData: the front end found no key frame).
  Status no_mosaic;
  int64_t tiles_written = 0;
  activity::ActivitySummary activity;  // the activity stage's (tracks dropped as implausible)
  double seconds[4] = {0, 0, 0, 0};    // per Stage, wall time
  std::optional<Stage> failed;         // the stage whose error RunStages returned
  std::vector<std::string> warnings;   // what could not be done, for a person (not errors)
};

struct StageHooks {
  Stage last = Stage::kTiles;  // the stages up to this one run
  // The front end resumes from this checkpoint (FrontEndCheckpoint), when set.
  const frontend::FrontEndCheckpoint* resume = nullptr;
  // Called after each stage that completed, with its part of run->mission filled in (a job
  // commits the mission file here). An error stops the stages with that error.
  std::function<Status(Stage, MissionRun*)> on_done;
  // Where the tiles go: cleared before the first batch, then written batch by batch. Without
  // `write_tiles` the tiles stage has nothing to write to and does not run.
  std::function<Status()> clear_tiles;
  tiles::TileSink write_tiles;
};

// Runs the stages on `video` up to hooks.last, filling `run` (its mission's source record is the
// caller's). Options are validated first, then the video is opened, once: the front end decodes
// with that reader. Errors name the video or the stage (a video that cannot be opened fails the
// front end stage); Cancelled through `job`, with what completed left in `run`. A video in which
// the front end finds no key frame is not an error: the mosaic and later stages are skipped and a
// warning says so; likewise a mosaic with no picture for the tiles.
Status RunStages(const std::string& video, const StageOptions& options, const StageHooks& hooks,
                 JobContext* job, MissionRun* run);

// The same on a video the caller has opened already, with options.front_end.EffectiveReader(),
// and not yet read from (ProcessVideo reads the source record from it first): the front end takes
// the reader. Errors name the reader's path.
Status RunStages(std::unique_ptr<video::VideoReader> reader, const StageOptions& options,
                 const StageHooks& hooks, JobContext* job, MissionRun* run);

// The plain mission records of an engine run (exposed for tests). `input` and `mosaic` (both or
// neither) place the frames and their metadata corners on the map.
std::vector<mission::FrameRecord> FrameRecords(const frontend::FrontEndResult& front,
                                               const mosaic::MosaicInput* input,
                                               const mosaic::MosaicResult* mosaic);
// The front end's overlay masks as the mission keeps them (cells of 0 and 1, row-major).
std::vector<mission::OverlayRecord> OverlayRecords(const frontend::FrontEndResult& front);
std::vector<mission::ActivityTrack> TrackRecords(const frontend::FrontEndResult& front);
// The front end's evidence for each target track (by id), for its confidence.
std::unordered_map<int64_t, activity::TrackEvidence> TrackEvidenceOf(
    const frontend::FrontEndResult& front);

}  // namespace saker::pipeline
