#pragma once
// Opening a saved mission for a person: the mission, what an interrupted job left (its checkpoint
// and, before there is a mosaic, its key frames as the front end placed them), and the video it
// was made from, found by its fingerprint (frame recall needs it; the map and tracks do not).
// The GUI opens missions through it and `saker-cli info` reports through it.

#include "core/frontend/front_end.h"
#include "core/mission/mission.h"
#include "core/pipeline/checkpoint.h"
#include "core/util/status.h"

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace saker::pipeline {

// Where a mission's video is.
struct VideoLocation {
  enum class State {
    kFound,    // `path` is the video (same fingerprint)
    kMissing,  // no file at any place looked at; `path` is the recorded one
    kChanged,  // `path` holds a file, but not the video that was processed
  };
  State state = State::kMissing;
  std::string path;
  std::vector<std::string> looked_at;  // every place tried, in order
};

struct OpenMissionOptions {
  // Where a person last located the video of this fingerprint, if anywhere (the GUI remembers
  // it in its settings); looked at after the recorded path.
  std::function<std::optional<std::string>(const std::string& fingerprint)> remembered_video;
  // Decode an interrupted job's key frame images when the mission has no mosaic yet.
  bool read_previews = true;
};

struct OpenedMission {
  mission::Mission mission;
  int64_t tiles = 0;                          // tiles stored (the mosaic picture)
  std::optional<CheckpointState> checkpoint;  // an interrupted job's
  std::vector<frontend::KeyFramePreview> previews;
  VideoLocation video;
  // The file cannot be written here (read-only storage or permissions): a viewer says so, and
  // no job can resume it in place.
  bool read_only = false;
};

// Frames of `mission` that carry metadata: a KLV time stamp or a sensor position (only from
// packets that passed their checksum, unless the job accepted bad ones).
int64_t FramesWithMetadata(const mission::Mission& mission);

// What the mission's map frame is, in words, for `saker-cli info`, the process summary and the
// GUI: "east-north-up metres around LAT, LON (H m)" when geo-referenced, otherwise what the map
// is (the first key frame's pixels, or none when no mosaic was made) and why the metadata did not
// place it (there was none, it was ignored on request, or none of it gave a map origin). Never
// "no metadata" for a mission whose frames carry some.
std::string DescribeMapFrame(const mission::Mission& mission);

// The video's KLV as the mission counted it: "P packets, C failed the checksum (not used)";
// empty for missions written before Saker counted it.
std::string DescribeKlv(const mission::Mission& mission);

// One thing the front end found about a video: a sentence for the process summary and
// `saker-cli info`, and the same in a few words for a narrow panel (the GUI's mission facts).
struct Finding {
  std::string sentence;  // "noise: the video's own noise (heavy compression?) raised ..."
  std::string brief;     // "noise raised the thresholds in 352 of 362 frames"
};

// What the front end found about a video of `frames` frames at `frame_rate` (FrontEndFindings),
// only what applies: the low-frame-rate mode, thresholds raised by the video's noise, a thermal
// camera's polarity switches.
std::vector<Finding> DescribeFindings(const mission::FrontEndFindings& findings, int64_t frames,
                                      double frame_rate);

// Opens the mission file at `path` read-only (a snapshot: nothing is left beside it; a mission on
// read-only storage opens too) and locates its video: at the recorded path, at the
// remembered place, then beside the mission file under the recorded name. Errors (the file is
// missing, not a mission, damaged) name the file; a missing video is not an error.
StatusOr<OpenedMission> OpenMission(const std::string& path,
                                    const OpenMissionOptions& options = {});

// Where the video is, the same way (exposed for a person's "locate" action and tests).
VideoLocation LocateVideo(const mission::SourceVideo& source, const std::string& mission_path,
                          const OpenMissionOptions& options = {});

}  // namespace saker::pipeline
