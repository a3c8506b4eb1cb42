#pragma once

// Resuming the front end from a checkpoint (docs/reliability.md, "Resume"): where a resumed run
// starts, the seams where its targets and key frames meet the checkpoint's, and the checkpoints a
// run hands out. FrontEndCheckpoint itself is declared in front_end.h; its Append() and
// Validate() are defined here.

#include "core/frontend/front_end.h"
#include "core/track/key_frames.h"
#include "core/track/target_tracks.h"

#include <Eigen/Core>

#include <cstddef>
#include <cstdint>
#include <optional>
#include <unordered_map>
#include <vector>

namespace saker::frontend {

// Where a run starts. Frames before `warm_from` are only decoded (for the KLV scan). From a
// checkpoint with the trackers' state (`exact`), the frames from there to the checkpoint's key
// frame (`through_frame`) go through the change detector again, which builds its image history
// from them, and the trackers take the state at that key frame: the run goes on as the first one
// would have. From a checkpoint without it, those frames warm the trackers up. Either way the key
// frame chain starts again at that key frame. A run from the start tracks every frame.
struct ResumePoint {
  bool resuming = false;
  bool complete = false;              // the checkpoint has the whole video: nothing is tracked
  bool exact = false;                 // the checkpoint has the trackers' state
  int64_t through_frame = -1;         // the checkpoint's last frame (its key frame)
  int64_t warm_from = 0;              // the first frame tracked (or replayed, when exact)
  int64_t change_through_frame = -1;  // the last frame whose change evidence it had applied
};
// `checkpoint` may be null (a run from the start). `replay_frames`: the frames an exact resume
// gives the change detector again before the key frame; `warmup_frames`: those a resume without
// state tracks before it.
ResumePoint ResumePointOf(const FrontEndCheckpoint* checkpoint, int warmup_frames,
                          int replay_frames);

// Where a resumed run's targets meet its checkpoint's. What the resumed run's targets saw up to
// the seam belongs to the checkpoint's targets (finished there, or cut there and joined again by
// LinkFragments), so each is cut at the seam; only a target that no checkpoint target saw in the
// warm-up keeps its frames before the seam (one the first run had not confirmed yet).
class TargetSeam {
 public:
  TargetSeam(const FrontEndCheckpoint& checkpoint, int64_t warm_from,
             const track::TargetTrackOptions& options, track::FrameRate rate);

  // The part of `target` to keep, cut after frame `cut`, or nothing.
  std::optional<track::TargetTrack> Trim(track::TargetTrack target, int64_t cut) const;

 private:
  std::unordered_map<int64_t, std::vector<Eigen::Vector2d>> seen_;  // frame -> positions
  double gate_px_;
  int min_frames_;
};

// Where a resumed run's key frame chain meets its checkpoint's: the chain starts again at the
// checkpoint's last key frame, so its key frames, segments and links are numbered on from the
// checkpoint's. Its feature track ids start past every id in the checkpoint unless the run goes
// on with the checkpoint's feature tracker (its state), whose ids go on by themselves. Without a
// checkpoint (or from a complete one) nothing is renumbered.
class ChainSeam {
 public:
  explicit ChainSeam(const FrontEndCheckpoint* checkpoint);

  // The chain's key frame, numbered on; `first`: the chain's first key frame, which is the
  // checkpoint's last seen again (nullopt: already in the result), or else starts a new segment
  // after a break (added to `breaks`).
  std::optional<track::KeyFrame> Continue(track::KeyFrame key, bool first,
                                          std::vector<track::ChainBreak>* breaks);
  track::SequentialLink Continue(track::SequentialLink link) const;

 private:
  track::KeyFrameId NewKeyFrameId(track::KeyFrameId id) const;
  track::FeatureTrackId NewFeatureId(track::FeatureTrackId id) const;

  const track::KeyFrame* last_ = nullptr;  // the checkpoint's last key frame
  int key_frame_base_ = 0;
  int segment_base_ = 0;
  int64_t feature_id_offset_ = 0;
};

// What a run's checkpoints have handed out so far, so that each hands out only what is new since
// the one before (FrontEndCheckpoint::Append puts the deliveries together again).
class CheckpointTail {
 public:
  CheckpointTail() = default;  // nothing handed out yet
  // Everything `result` and `change_targets` hold counts as handed out (a resumed checkpoint's).
  CheckpointTail(const FrontEndResult& result, size_t change_targets);

  // A checkpoint through `through_frame` with what the run found since the last one: frames, key
  // frames (with their images, placed by `placements`), links and breaks, and, unless `complete`,
  // the finished targets of both sources (when complete: all of `result`'s targets, the final
  // ones). The open targets and the change state are the caller's to add.
  FrontEndCheckpoint TakeNew(int64_t through_frame, bool complete, const FrontEndResult& result,
                             const std::vector<Eigen::Matrix3d>& placements,
                             const std::vector<track::TargetTrack>& change_targets);

 private:
  size_t frames_ = 0, key_frames_ = 0, images_ = 0, links_ = 0, breaks_ = 0, targets_ = 0;
  size_t change_targets_ = 0;
};

}  // namespace saker::frontend
