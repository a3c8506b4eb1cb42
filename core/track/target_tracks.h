#pragma once

// Target tracks: moving features grouped into objects and linked over time.
//
// A car carries several corners. In each frame the moving features are grouped when they are
// close together and move alike (ground-relative velocity); each group is then tied to the target
// that already owns most of its features, else to the target whose predicted position (constant
// velocity) is nearest within a gate, else it starts a new target. A target survives gaps of a
// few frames (a car losing its corners under a tree shadow). Two targets seen side by side and
// moving alike are one object whose corners were first found apart: they are merged. A target
// becomes confirmed once seen for enough frames (longer when it never had more than one
// feature), which suppresses short-lived false alarms.

#include "core/track/motion_segmentation.h"
#include "core/track/scene_cut.h"
#include "core/track/types.h"
#include "core/util/byte_io.h"
#include "core/util/status.h"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstdint>
#include <functional>
#include <optional>
#include <vector>

namespace saker::track {

// Durations are in seconds and speeds in pixels a second (FrameRate); the defaults are the
// frame counts that were tuned at 25 frames a second. Floors in frames are given in brackets.
struct TargetTrackOptions {
  // Features closer than this and moving alike are one object. The distance applies from
  // group_full_speed_px_s of ground-relative speed (a car) and shrinks to 35 % of it for slow
  // things (a walker); the velocity difference allowed is group_speed_px_s or 30 % of the speed,
  // whichever is larger.
  double group_distance_px = 22;
  double group_full_speed_px_s = 37.5;
  double group_speed_px_s = 12.5;
  double association_gate_px = 18;  // predicted-position gate for linking a group to a target,
  double gate_growth_px_s = 25;     // growing by this for each second unseen after the first frame
  double max_gap_s = 1;             // time a target may go unseen before it ends [2 frames]
  double min_duration_s = 0.24;     // seen this long before a target with 2+ features is confirmed
                                    // [3 frames]
  double min_duration_single_s = 1.28;  // ... and one only ever seen as a single feature [4]
  double min_travel_px = 8;             // ground-relative distance travelled before confirmation
  double box_margin_px = 4;             // added around the features for the target's box
  // LinkFragments: a track that starts within link_gap_s of another's end, near where that one
  // was heading, continues it [2 frames]; tracks side by side for duplicate_overlap_s are one
  // [2 frames].
  double link_gap_s = 2.4;
  double duplicate_overlap_s = 0.2;
  // DropShadows: a slow track (a walker's, mean ground speed up to ground_link_max_speed_px_s)
  // beside other slow tracks in at least this fraction of its frames is dropped (above 1: never).
  double shadow_fraction = 0.6;
  // With the ground's motion (GroundMotion), the pieces of slow objects (mean ground speed up to
  // ground_link_max_speed_px_s: people) are joined on the ground across gaps of up to
  // ground_link_gap_s [2 frames], the gate growing by ground_link_growth_px_s for each second of
  // gap (see LinkFragments).
  double ground_link_max_speed_px_s = 25;
  double ground_link_gap_s = 8;
  double ground_link_growth_px_s = 6.25;
  // FillGaps: a track's frames unseen for up to fill_gap_s between two of its observations are
  // given interpolated ones [1 frame; 0: none].
  double fill_gap_s = 1;
  // Change evidence (RecordChange) comes some frames late. When set, a target that ends waits
  // until RecordChange has reached its last frame, or EndChangeEvidence() says that no more will
  // come, before it is finished: it leaves with the evidence of every frame that gets one.
  bool wait_for_change = false;
  Status Validate() const;
};

// TargetTrackOptions at one frame rate: durations in frames, speeds in pixels a frame.
struct TargetTrackTiming {
  TargetTrackTiming(const TargetTrackOptions& options, FrameRate rate);
  double group_full_speed_px = 0;
  double group_velocity_px = 0;
  double gate_growth_px = 0;  // per frame unseen
  int max_gap_frames = 0;
  int min_frames = 0;
  int min_frames_single = 0;
  int link_gap_frames = 0;
  int duplicate_overlap_frames = 0;
  double ground_link_max_speed_px = 0;
  int ground_link_gap_frames = 0;
  double ground_link_growth_px = 0;  // per frame of gap
  int fill_gap_frames = 0;           // 0: FillGaps fills nothing
};

// What the change detector (change_detector.h) saw at an observation.
enum class ChangeEvidence : uint8_t {
  kNotLooked,  // no comparison there (too early in a segment, at the frame's edge, turned off)
  kNone,       // the image did not change there
  kChanged,
};

struct TargetObservation {
  int64_t frame = 0;
  Eigen::Vector2d position{0, 0};  // mean of the supporting features, pixels
  Eigen::Vector2d box_min{0, 0};   // box around the supporting features (with margin)
  Eigen::Vector2d box_max{0, 0};
  Eigen::Vector2d velocity{0, 0};        // ground-relative, pixels per frame
  std::vector<FeatureTrackId> features;  // none for a track found by change detection
  ChangeEvidence change = ChangeEvidence::kNotLooked;
  // Not seen: placed between the observations on either side of a short gap (FillGaps). It has no
  // features and no change evidence, and is no evidence for the track.
  bool interpolated = false;
};

struct TargetTrack {
  TargetTrackId id{};
  std::vector<TargetObservation> observations;  // frames where it was seen, increasing
  bool confirmed = false;
  size_t max_features = 0;
  // Pixels per frame in the image (camera + own motion), smoothed; after a merge (MergeAlike),
  // from the merged positions of the last frames.
  Eigen::Vector2d image_velocity{0, 0};
  int64_t last_frame() const { return observations.empty() ? -1 : observations.back().frame; }
};

class TargetTracker {
 public:
  TargetTracker(const TargetTrackOptions& options, FrameRate rate);

  // The moving features of frame `frame` (frames increase).
  void AddFrame(int64_t frame, const std::vector<MovingPoint>& moving);

  // Targets still being followed.
  const std::vector<TargetTrack>& active() const { return active_; }
  // Confirmed targets that ended but wait for change evidence (wait_for_change).
  const std::vector<TargetTrack>& waiting() const { return waiting_; }
  // Records what the change detector saw at the observations of `frame` (a recent one: the change
  // detector answers some frames late) of the active and the waiting targets; frames increase
  // from call to call. Waiting targets whose last frame is now answered are finished.
  void RecordChange(int64_t frame,
                    const std::function<ChangeEvidence(const TargetObservation&)>& look);
  // No more change evidence will come for the frames seen so far (a chain break, the end of the
  // video): the waiting targets are finished.
  void EndChangeEvidence();
  // Confirmed targets that ended since the last call, in the order they were finished
  // (unconfirmed ones are dropped).
  std::vector<TargetTrack> TakeFinished();
  // Ends every active target (at the end of the video or at a chain break).
  void FinishAll();

  // The targets followed and waiting, so that a resumed run goes on exactly from the latest frame
  // (docs/reliability.md, "Resume"). RestoreState is false when `in` is malformed.
  void SaveState(ByteWriter* out) const;
  bool RestoreState(ByteReader* in);

 private:
  // The steps of AddFrame, after grouping the frame's moving features into observations. Ties
  // each observation to an active target, most shared features first, then the nearest
  // prediction within the gate: the target's index, or -1.
  std::vector<int> Assign(int64_t frame, const std::vector<TargetObservation>& observations) const;
  // Adds each observation to its target (smoothing the target's image velocity), or starts a
  // target with it.
  void Extend(int64_t frame, std::vector<TargetObservation> observations,
              const std::vector<int>& assigned);
  void MergeAlike(int64_t frame);
  // Confirms the targets seen often enough that have travelled far enough.
  void Confirm();
  // Ends the targets unseen for longer than max_gap_s.
  void EndUnseen(int64_t frame);
  // A confirmed target that ended: finished, or waiting for its change evidence.
  void End(TargetTrack&& target);

  TargetTrackOptions options_;
  TargetTrackTiming timing_;
  std::vector<TargetTrack> active_;
  std::vector<TargetTrack> waiting_;  // ended, waiting for change evidence (in order of ending)
  std::vector<TargetTrack> finished_;
  int64_t change_through_ = -1;  // the latest frame RecordChange was given
  int64_t next_id_ = 1;
};

// A target track as bytes, bit for bit, and back (false when `in` is malformed): for the state a
// checkpoint keeps (TargetTracker::SaveState, BlobTracker::SaveState).
void SaveTargetTrack(const TargetTrack& track, ByteWriter* out);
bool RestoreTargetTrack(ByteReader* in, TargetTrack* track);

// Mean ground-relative speed of a track's observations, pixels per frame (0 for none).
double MeanSpeed(const TargetTrack& track);

// Calls visit(a_observation, b_observation) for every frame both tracks saw, in frame order.
template <typename Visit>
void ForCommonFrames(const TargetTrack& a, const TargetTrack& b, Visit visit) {
  size_t i = 0, j = 0;
  while (i < a.observations.size() && j < b.observations.size()) {
    if (a.observations[i].frame < b.observations[j].frame) {
      ++i;
    } else if (a.observations[i].frame > b.observations[j].frame) {
      ++j;
    } else {
      visit(a.observations[i++], b.observations[j++]);
    }
  }
}

// The ground's motion through a video: each frame's homography from the previous one, chained
// within chain segments, so that a point of one frame can be found in a later one.
class GroundMotion {
 public:
  // Frames come in increasing order, one after another; `linked` is false where a frame has no
  // homography from the previous one (the first frame of a chain segment).
  void Add(int64_t frame, bool linked, const Eigen::Matrix3d& current_from_previous);
  // Where the ground point at `point` in frame `from` lies in frame `to`; none when a chain break
  // lies between them or either frame was not added.
  std::optional<Eigen::Vector2d> Map(const Eigen::Vector2d& point, int64_t from, int64_t to) const;
  // Whether frames `a` and `b` were added and lie in one chain segment (no break between them).
  bool SameSegment(int64_t a, int64_t b) const;

 private:
  int64_t first_frame_ = 0;
  int segments_ = 0;
  std::vector<int> segment_;  // chain segment of each frame (-1: a frame never added)
  std::vector<Eigen::Matrix3d> frame_from_segment_;  // from the segment's first frame
};

// Joins the pieces of one object's track, once the video is over. A track that starts shortly
// after another ended, where that one was heading, continues it. Without `ground`: the image
// position extrapolated with the image velocity, within association_gate_px plus
// gate_growth_px_s for each second of gap, for gaps up to link_gap_s. With it, a slow object (a
// walker) is followed on the ground: it may have gone on at its ground speed or slowed down, even
// stopped, so the later track must start near the path between where it was last seen and where
// it would be at its last speed, both carried into the later frame by the ground's motion; within
// association_gate_px plus ground_link_growth_px_s for each second of gap, for gaps up to
// ground_link_gap_s (across a chain break, the image test applies). Cars keep the image test:
// along a road the path of a lost car reaches the car ahead of it. With `scenes`, no track
// continues another across a scene cut (SceneContinuity): the pieces are in two scenes. Two tracks
// that run side by side (within the distance pieces of one object keep: group_distance_px, less
// for slow things) for at least duplicate_overlap_s are one, and so is a track that took over from
// another: started beside it in its last frames (overlapping by less than duplicate_overlap_s)
// and went on after it ended. Ids of the earlier pieces are kept; the result is ordered by id.
// `rate` is the video's.
std::vector<TargetTrack> LinkFragments(std::vector<TargetTrack> tracks,
                                       const TargetTrackOptions& options, FrameRate rate,
                                       const GroundMotion* ground = nullptr,
                                       const SceneContinuity* scenes = nullptr);

// Drops the second tracks of slow objects already followed, once the pieces are joined. A slow
// track (mean ground speed at most ground_link_max_speed_px_s: a walker's) is beside another slow
// track in a frame when they lie within the distance pieces of one object keep (as for
// duplicates). The track beside others in the largest fraction of its frames, if that is at least
// shadow_fraction, is dropped (on a tie the shorter, then the later), and so on with the counts of
// the tracks left. A walker's features can be followed twice and the copy drift onto a neighbour
// it passes: it runs beside the walker's track and then the neighbour's, so no pairwise duplicate
// test (the mean distance over the common frames) joins it, and as a second track on each it
// takes their pairings and makes both look partial. The order of the rest is kept.
std::vector<TargetTrack> DropShadows(std::vector<TargetTrack> tracks,
                                     const TargetTrackOptions& options, FrameRate rate);

// Fills the short gaps of each track, once the tracks are final: each frame of a gap of at most
// fill_gap_s unseen between two observations (in one chain segment of `ground`) gets one placed as
// if the object had moved at constant velocity over the ground between them (the later observation
// carried into the earlier frame by the ground's motion, the point between them carried into the
// frame), its box as large as the nearer one's, marked `interpolated`. A track followed through a
// short occlusion or a few frames where its corners or its change fell below the thresholds is
// one track through them, as an analyst sees it, rather than a dotted one. Gaps across a chain
// break, and the longer gaps LinkFragments bridged (where the object may have stopped or turned),
// are left unseen.
std::vector<TargetTrack> FillGaps(std::vector<TargetTrack> tracks,
                                  const TargetTrackOptions& options, FrameRate rate,
                                  const GroundMotion& ground);

}  // namespace saker::track
