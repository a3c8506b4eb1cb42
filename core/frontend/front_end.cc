#include "core/frontend/front_end.h"

#include "core/frontend/change_thread.h"
#include "core/frontend/resume.h"
#include "core/frontend/scale_follower.h"
#include "core/track/picture.h"
#include "core/util/bounded_queue.h"
#include "core/util/byte_io.h"
#include "core/util/check.h"
#include "core/util/memory.h"
#include "core/util/timer.h"

#include <Eigen/LU>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <deque>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <unordered_map>
#include <utility>

namespace saker::frontend {
namespace {

// Change detection answers are applied this many frames after their frame was submitted (see
// FrontEnd::ApplyChangeThrough): the change thread may fall this far behind before the calling
// thread waits for it. An answer belongs to the frame the longest baseline before the one
// submitted, so the change evidence of frame m reaches the targets after frame m + longest
// baseline + this lag (20 frames with the default baseline of 12: still within the 25 frames a
// target lives on unseen).
constexpr int64_t kChangeLagFrames = 8;
// The resume warm-up (FrontEndOptions::resume_warmup_s) is at least this many frames at any rate.
constexpr int kMinWarmupFrames = 10;
// How often the memory limit is checked: reading /proc costs about 10 us. Every 25 frames of
// 720p: every frame for pictures of this many pixels and more (8K).
constexpr int64_t kMemoryCheckPixels = int64_t{25} * 1280 * 720;
// FramePipelineBytes: the H.264 decoder keeps up to 16 reference pictures.
constexpr int64_t kDecoderReferencePictures = 16;
// The layout of the trackers' state in a checkpoint (FrontEndCheckpoint::state). Layouts 1 (before
// the overlay detector's state was added), 2 (before the polarity switches) and 3 (before the
// segmentation's feature noise) are still read: their runs start without overlay evidence,
// without the switches before the checkpoint, or with the noise measured afresh.
constexpr uint32_t kStateLayout = 4;
constexpr uint32_t kStateLayoutWithoutNoise = 3;
constexpr uint32_t kStateLayoutWithoutPolarity = 2;
constexpr uint32_t kStateLayoutWithoutOverlays = 1;

// The frames an exact resume gives the change detector again before the checkpoint's key frame:
// its answers not yet applied there (kChangeLagFrames of them), the image history each needs, and
// the detector's lag more, so that every frame in the first such answer's history has been a
// centre frame itself and has its noise measured (ChangeDetector::SetAllowances takes the median
// over the frames held). Without that lag the first answers after a resume took their median
// over fewer frames than the uninterrupted run did; it showed once the measured misregistration
// rose above the fixed allowance of clean video (0.2 px, session 33).
int ChangeReplayFrames(const track::ChangeOptions& change, track::FrameRate rate) {
  if (!change.enabled) return 0;
  return static_cast<int>(kChangeLagFrames) + track::ChangeDetector::HistoryFrames(change, rate) -
         1 + track::ChangeDetector::LagFrames(change, rate);
}

// A decoded frame and the ground's scale in it from the metadata, when known.
struct DecodedFrame {
  video::Frame frame;
  std::optional<track::GroundScale> scale;
};

// Decoding on a thread of its own: ingest::ScanVideo reads every frame and KLV packet of the
// opened `reader` in one pass (the frames as the reader decodes them: FrontEndOptions::
// EffectiveReader) and queues the frames for the calling thread with the ground's scale in them
// (ScaleFollower); the rest of the metadata is tied to the frames when the scan ends. Frames
// before `pixels_from` are only decoded, for the scan, and come without pixels. The destructor
// stops and joins the thread, whatever happened.
class DecodeThread {
 public:
  DecodeThread(std::unique_ptr<video::VideoReader> reader, size_t queue_frames, int64_t pixels_from,
               const ingest::AlignmentOptions& alignment)
      : queue_(queue_frames) {
    const video::VideoInfo& info = reader->info();
    const std::string path = info.path;
    auto scales = std::make_shared<ScaleFollower>(info.fps);
    ingest::ScanOptions scan_options;
    scan_options.alignment = alignment;
    scan_options.on_packet = [scales](const ingest::MetadataPacket& p) { scales->AddPacket(p); };
    thread_ = std::thread(
        [this, reader = std::move(reader), pixels_from, scan_options, path, scales]() mutable {
          // An exception must not leave this thread (std::terminate): out of memory while decoding
          // is an error of the run like any other.
          try {
            Stopwatch watch;
            scan_ = ingest::ScanVideo(
                std::move(reader), scan_options, &job_, [&](const video::Frame& frame) {
                  DecodedFrame copy{
                      frame, scales->ForFrame(frame.byte_pos, frame.grey.cols, frame.grey.rows)};
                  // The reader reuses its buffers; a frame that is only decoded needs no pixels.
                  copy.frame.grey = frame.index >= pixels_from ? frame.grey.clone() : cv::Mat();
                  // Fresh for every frame (never reused), so shared rather than copied.
                  if (frame.index < pixels_from) copy.frame.chroma = cv::Mat();
                  decode_ms_ += watch.ElapsedMs();
                  if (!queue_.Push(std::move(copy))) job_.RequestCancel();
                  watch.Restart();
                });
          } catch (...) {
            scan_ = StatusFromCurrentException(path + ": decoding");
          }
          queue_.Close(scan_.ok() ? Status::Ok() : scan_.status());
        });
  }
  ~DecodeThread() {
    job_.RequestCancel();
    queue_.Cancel();
    if (thread_.joinable()) thread_.join();
  }
  DecodeThread(const DecodeThread&) = delete;
  DecodeThread& operator=(const DecodeThread&) = delete;

  // The next frame; nullopt at the end of the video or when decoding failed.
  std::optional<DecodedFrame> Pop() { return queue_.Pop(); }
  // Once Pop() gave nullopt: the scan, or the error that stopped it.
  StatusOr<ingest::VideoScan> Finish() {
    SAKER_RETURN_IF_ERROR(queue_.status());
    thread_.join();
    return std::move(scan_);
  }
  // Time spent decoding, milliseconds (after Finish()).
  double decode_ms() const { return decode_ms_; }

 private:
  BoundedQueue<DecodedFrame> queue_;
  JobContext job_;  // cancelled when the consumer stops early
  StatusOr<ingest::VideoScan> scan_ = CancelledError("front end: the scan did not run");
  double decode_ms_ = 0;
  std::thread thread_;  // last: started once everything above exists
};

// The epipole for the parallax test, only when the scene shows parallax. Over flat ground the
// fundamental matrix is not determined (any epipole fits a plane), and a random epipole would
// let slow movers pass as parallax. So F is fitted to all ground matches, and its epipole is used
// only when enough matches fit F but not the homography: points off the ground plane.
std::optional<Eigen::Vector3d> ParallaxEpipole(const std::vector<track::Correspondence>& ground,
                                               const track::HomographyEstimate& plane,
                                               const FrontEndOptions& options) {
  StatusOr<track::FundamentalEstimate> f = track::EstimateFundamental(ground, {});
  if (!f.ok()) return std::nullopt;
  int off_plane = 0;
  for (size_t i = 0; i < ground.size(); ++i) {
    if (!f->inliers[i]) continue;
    const double transfer =
        (track::Transfer(plane.target_from_source, ground[i].source) - ground[i].target).norm();
    off_plane += transfer > options.frame_homography.ransac_threshold_px;
  }
  const int needed = std::max(options.min_parallax_points, static_cast<int>(ground.size() / 20));
  if (off_plane < needed) return std::nullopt;
  return f->epipole_target;
}

// The targets of the feature tracks, less those the image does not support, and those of change
// detection; pieces of one object joined (a walker's across long gaps on the ground, followed
// through the frame-to-frame homographies), pieces and echoes of cars dropped (after the joining,
// so that a car's own pieces have become part of its track), short gaps filled (not in the
// low-frame-rate mode), and numbered 1, 2, ... in order of appearance.
std::vector<track::TargetTrack> CombineTargets(std::vector<track::TargetTrack> by_features,
                                               std::vector<track::TargetTrack> by_change,
                                               const std::vector<FrameResult>& frames,
                                               const FrontEndOptions& options,
                                               track::FrameRate rate,
                                               const track::SceneContinuity& scenes) {
  std::vector<track::TargetTrack> all;
  for (track::TargetTrack& t : by_features) {
    if (track::SupportedByChange(t, options.min_change_support)) all.push_back(std::move(t));
  }
  for (track::TargetTrack& t : by_change) all.push_back(std::move(t));
  std::stable_sort(all.begin(), all.end(), [](const auto& a, const auto& b) {
    return a.observations.front().frame < b.observations.front().frame;
  });
  for (size_t i = 0; i < all.size(); ++i)
    all[i].id = static_cast<track::TargetTrackId>(static_cast<int64_t>(i) + 1);
  track::GroundMotion ground;
  for (const FrameResult& f : frames) ground.Add(f.index, f.homography_ok, f.current_from_previous);
  const track::TargetTrackOptions targets = options.EffectiveTargets(rate.fps());
  all = track::LinkFragments(std::move(all), targets, rate, &ground, &scenes);
  all = track::DropShadows(std::move(all), targets, rate);
  all = track::DropCarPieces(std::move(all), options.change_echoes, rate);
  all = track::DropChangeEchoes(std::move(all), options.change_echoes, rate);
  all = track::FillGaps(std::move(all), targets, rate, ground);
  for (size_t i = 0; i < all.size(); ++i)
    all[i].id = static_cast<track::TargetTrackId>(static_cast<int64_t>(i) + 1);
  return all;
}

// One run of the front end over a video (RunFrontEnd), resumed from `resume` when not null. Run()
// takes the decoded frames one at a time (ProcessFrame: track, ground motion, change detection
// submitted, segmentation and targets, change answers applied, key frames, checkpoints) and then
// finishes the targets. What the trackers follow and what the run has found are members.
class FrontEnd {
 public:
  // `reader`: the video, opened with options.EffectiveReader() and not yet read from.
  FrontEnd(std::unique_ptr<video::VideoReader> reader, const FrontEndOptions& options,
           JobContext* job, const FrontEndCheckpoint* resume);
  FrontEnd(const FrontEnd&) = delete;
  FrontEnd& operator=(const FrontEnd&) = delete;

  StatusOr<FrontEndResult> Run();

 private:
  Status StartFromCheckpoint();
  Status Replay(const video::Frame& frame);
  std::vector<uint8_t> SaveState() const;
  void ReportProgress(double frames_done) const;
  // Before decoding pictures of this size: the memory in use and what the frame pipeline may
  // take for them (FramePipelineBytes, less what it holds for the previous size) must fit in the
  // limit.
  Status CheckMemoryBudget(int width, int height);
  Status CheckMemory(const video::Frame& frame);
  // `on_ground`: the frame's metadata puts all of it on the ground (it has a ground scale), so
  // it shows no horizon (HorizonTracker::Add).
  Status ProcessFrame(const video::Frame& frame, bool on_ground);
  std::optional<track::HomographyEstimate> EstimateGroundMotion(
      std::optional<Eigen::Vector3d>* epipole);
  void SubmitForChange(const video::Frame& frame,
                       const std::optional<track::HomographyEstimate>& estimate);
  void Segment(const video::Frame& frame, const std::optional<track::HomographyEstimate>& estimate,
               const std::optional<Eigen::Vector3d>& epipole, FrameResult* frame_result);
  void ApplyChangeThrough(int64_t frame);
  void ApplyChangeAnswer(const ChangeThread::Answer& answer);
  // Starts the change thread, its processing copy as wide as the ground's scale of the video's
  // first frame asks (ChangeOptions::ProcessingWidth): decided on the first frame of the file,
  // whether or not it is processed, so that a resumed run decides as the first run did.
  void StartChangeDetection(const track::GroundScale* scale);
  // Keeps frame `index`'s ground scale (when the metadata gives one) until its change answer
  // comes, for the blob tracks' speed limits; forgets those of frames answered long ago.
  void NoteGroundScale(int64_t index, std::optional<track::GroundScale> scale);
  void KeepTarget(track::TargetTrack target, int64_t cut, std::vector<track::TargetTrack>* to);
  // Masks the sky above `horizon` in frame `index`: for its targets, the count, and its frame
  // result (`current`, the frame being processed; else the one in the result, when it is there).
  void MaskSky(int64_t index, const track::HorizonLine& horizon, FrameResult* current);
  // The edge of frame `frame`'s sky mask (its horizon moved down by the margin), if it has one,
  // and whether `p` of that frame lies above it.
  std::optional<track::HorizonLine> SkyEdge(int64_t frame) const;
  bool AboveHorizon(int64_t frame, const Eigen::Vector2d& p) const;
  bool MostlyAboveHorizon(const track::TargetTrack& target) const;
  void SelectGroundMatches();
  void NoteOverlayMask(int64_t frame);
  void CloseOverlayMask(int64_t last_frame);
  bool AddToChain(const video::Frame& frame,
                  const std::optional<track::HomographyEstimate>& estimate);
  void AddKeyFrameImage(const track::KeyFrame& key, const video::Frame& frame);
  Status HandOutCheckpoint(int64_t through_frame, bool complete);
  StatusOr<FrontEndResult> Finish(ingest::VideoScan scan, double decode_ms);
  void FinishTargets();

  std::unique_ptr<video::VideoReader> reader_;  // until Run() hands it to the decode thread
  const std::string path_;
  // The video's frame rate, at which the options' durations and speeds apply (a rate the video
  // does not give counts as 25 frames a second).
  const track::FrameRate rate_;
  const FrontEndOptions options_;     // the run's own copy, callbacks included
  const bool low_frame_rate_;         // the low-frame-rate mode runs (LowFrameRateOptions)
  const int change_baseline_frames_;  // the change detector's (short) baseline at this rate
  // A change answer is applied at most this many frames after its frame (ApplyChangeThrough):
  // the ground scales kept for it (NoteGroundScale).
  const int64_t scale_keep_frames_;
  JobContext* const job_;
  const FrontEndCheckpoint* const resume_;
  const ResumePoint start_;
  std::optional<TargetSeam> target_seam_;  // when resuming from an incomplete checkpoint
  ChainSeam chain_seam_;
  double expected_frames_ = 1;  // for progress only
  cv::Size budget_size_;        // the picture size CheckMemoryBudget last checked

  FrontEndResult result_;
  std::vector<track::TargetTrack> targets_by_change_;
  std::vector<Eigen::Matrix3d> image_placements_;  // preview_from_frame of each key frame image
  CheckpointTail delivered_;                       // what the checkpoints handed out so far
  Stopwatch since_checkpoint_;

  track::FeatureTracker tracker_;
  track::MotionSegmenter segmenter_;
  track::TargetTracker target_tracker_;
  track::KeyFrameChain chain_;
  track::BlobTracker change_tracks_;
  track::OverlayDetector overlays_;
  int still_window_frames_ = 1;  // OverlayOptions::still_window_s at the video's rate
  track::HorizonTracker horizon_;
  // The horizon of each frame whose sky was masked (the change answers and the targets come
  // frames later).
  std::unordered_map<int64_t, track::HorizonLine> horizon_lines_;
  // Recent frames whose own horizon was found while the window had not confirmed it (within the
  // window, in order).
  std::deque<std::pair<int64_t, track::HorizonLine>> unconfirmed_sky_;
  // Which chain breaks are scene cuts, for joining the pieces of tracks (frames this run tracked;
  // a resumed run does not know the frames before its warm-up, and joins across those breaks).
  track::SceneContinuity scenes_;
  track::PolarityWatch polarity_;
  // The mask handed out last, still growing (its frames), and the detector's version it is.
  std::optional<track::OverlayMask> open_overlay_;
  int64_t open_overlay_version_ = -1;
  // The latest frame's ground motion (current_from_previous), none after a frame without one.
  std::optional<Eigen::Matrix3d> last_motion_;
  int64_t overlay_min_frames_ = 1;  // frames a mask handed out covers before it may be replaced
  // The latest frame's matches off the overlay mask: the ground motion's and the segmentation's.
  std::vector<track::Correspondence> ground_matches_;
  bool segment_open_ = false;
  // The placement of the current frame in the preview (KeyFramePreview): the first frame's pixels.
  Eigen::Matrix3d preview_from_current_ = Eigen::Matrix3d::Identity();
  size_t chain_key_frames_ = 0, chain_links_ = 0, chain_breaks_ = 0;  // taken from `chain_`

  // Change detection runs on its own thread (ChangeThread); its answers are applied at a fixed
  // lag (ApplyChangeThrough).
  std::optional<ChangeThread> change_;
  double change_side_ms_ = 0;  // the calling thread's time for change detection (waits included)
  int64_t change_through_;     // the latest frame whose change answer was applied
  int64_t change_applied_submitted_ = -1;  // the latest frame submitted whose answer was applied
  // The ground's scale of the frames whose change answers may still come (NoteGroundScale).
  std::map<int64_t, track::GroundScale> ground_scales_;
  // Resuming exactly: the checkpoint's state from the feature tracker on, which needs the image of
  // the checkpoint's key frame (Replay).
  std::optional<ByteReader> tracker_state_;
};

FrontEnd::FrontEnd(std::unique_ptr<video::VideoReader> reader, const FrontEndOptions& options,
                   JobContext* job, const FrontEndCheckpoint* resume)
    : reader_(std::move(reader)),
      path_(reader_->info().path),
      rate_(reader_->info().fps),
      options_(options),
      low_frame_rate_(options.LowFrameRateFor(rate_.fps())),
      change_baseline_frames_(track::ChangeDetector::BaselineFrames(options.change, rate_).front()),
      scale_keep_frames_(ChangeReplayFrames(options.EffectiveChange(rate_.fps()), rate_) + 1),
      job_(job),
      resume_(resume),
      start_(ResumePointOf(resume, rate_.Frames(options.resume_warmup_s, kMinWarmupFrames),
                           ChangeReplayFrames(options.EffectiveChange(rate_.fps()), rate_))),
      chain_seam_(resume),
      tracker_(options.EffectiveTracker(rate_), rate_),
      segmenter_(options.segmentation, rate_),
      target_tracker_(options.EffectiveTargets(rate_.fps()), rate_),
      chain_(options.key_frames),
      change_tracks_(options.EffectiveChangeTracks(rate_.fps()), rate_),
      overlays_(options.overlays, rate_),
      still_window_frames_(
          rate_.Frames(options.overlays.still_window_s, options.overlays.still_min_window_frames)),
      horizon_(options.horizon, rate_),
      change_through_(start_.change_through_frame) {
  overlay_min_frames_ = rate_.Frames(options.overlays.window_s, 1);
  if (start_.resuming && !start_.complete && !start_.exact) {
    target_seam_.emplace(*resume, start_.warm_from, options.EffectiveTargets(rate_.fps()), rate_);
  }
  result_.video = reader_->info();
  result_.low_frame_rate = low_frame_rate_;
  // For progress only: the declared count, else duration x rate.
  expected_frames_ = static_cast<double>(result_.video.declared_frame_count);
  if (expected_frames_ <= 0) expected_frames_ = result_.video.duration_s * result_.video.fps;
  expected_frames_ = std::max(1.0, expected_frames_);
}

StatusOr<FrontEndResult> FrontEnd::Run() {
  // Before the decoder and the queues allocate anything of the video's size.
  SAKER_RETURN_IF_ERROR(CheckMemoryBudget(result_.video.width, result_.video.height));
  SAKER_RETURN_IF_ERROR(StartFromCheckpoint());
  DecodeThread decode(std::move(reader_), static_cast<size_t>(options_.queue_frames),
                      start_.warm_from, options_.metadata);
  const Stopwatch wall;
  since_checkpoint_.Restart();
  bool first = true;
  while (std::optional<DecodedFrame> decoded = decode.Pop()) {
    if (job_ != nullptr && job_->IsCancelled()) return CancelledError("front end: cancelled");
    video::Frame* frame = &decoded->frame;
    if (std::exchange(first, false)) {
      StartChangeDetection(decoded->scale ? &*decoded->scale : nullptr);
    }
    if (frame->index < start_.warm_from) {
      ReportProgress(static_cast<double>(frame->index + 1));
      continue;  // done before: only decoded, for the scan
    }
    const bool on_ground = decoded->scale.has_value();
    NoteGroundScale(frame->index, std::move(decoded->scale));
    const bool replay = start_.exact && frame->index <= start_.through_frame;
    // A thermal camera's polarity switch: the frames after it go on inverted back, in the first
    // frame's polarity (PolarityWatch; when replaying, as the checkpoint recorded).
    if (replay ? polarity_.Replay(frame->index, frame->grey)
               : polarity_.Add(frame->index, frame->grey)) {
      cv::Mat inverted;  // a copy: the decoder's picture may be shared
      cv::bitwise_not(frame->grey, inverted);
      frame->grey = inverted;
    }
    if (replay) {
      SAKER_RETURN_IF_ERROR(Replay(*frame));
      continue;
    }
    SAKER_RETURN_IF_ERROR(CheckMemory(*frame));
    SAKER_RETURN_IF_ERROR(ProcessFrame(*frame, on_ground));
  }
  SAKER_ASSIGN_OR_RETURN(ingest::VideoScan scan, decode.Finish());
  StatusOr<FrontEndResult> result = Finish(std::move(scan), decode.decode_ms());
  if (result.ok()) result->timing.wall_s = wall.ElapsedSeconds();
  return result;
}

// Resuming: the checkpoint is the start of this run's result. What it holds counts as handed out.
// With the trackers' state, the trackers go on from it (the feature tracker at the key frame,
// Replay); without, the open targets, finished as far as this run goes, are handed out with the
// next checkpoint.
Status FrontEnd::StartFromCheckpoint() {
  if (resume_ != nullptr) {
    result_.frames = resume_->frames;
    result_.key_frames = resume_->key_frames;
    result_.links = resume_->links;
    result_.breaks = resume_->breaks;
    for (const KeyFramePreview& preview : resume_->key_frame_images) {
      result_.key_frame_images.push_back(preview.image);
      image_placements_.push_back(preview.preview_from_frame);
      if (options_.on_key_frame) options_.on_key_frame(preview);
    }
    result_.targets = resume_->targets;
    targets_by_change_ = resume_->change_targets;
  }
  delivered_ = CheckpointTail(result_, targets_by_change_.size());
  if (!start_.resuming || start_.complete) return Status::Ok();
  if (!start_.exact) {
    result_.targets.insert(result_.targets.end(), resume_->open_targets.begin(),
                           resume_->open_targets.end());
    targets_by_change_.insert(targets_by_change_.end(), resume_->open_change_targets.begin(),
                              resume_->open_change_targets.end());
    return Status::Ok();
  }
  ByteReader& in = tracker_state_.emplace(resume_->state);
  uint32_t layout = 0;
  uint8_t segment_open = 0;
  const bool known =
      in.Get(&layout) &&
      (layout == kStateLayout || layout == kStateLayoutWithoutNoise ||
       layout == kStateLayoutWithoutPolarity || layout == kStateLayoutWithoutOverlays);
  if (!known || !in.Get(&segment_open) || !in.Get(&change_applied_submitted_) ||
      !segmenter_.RestoreState(&in) || !target_tracker_.RestoreState(&in) ||
      !change_tracks_.RestoreState(&in) ||
      (layout >= kStateLayoutWithoutPolarity && !overlays_.RestoreState(&in)) ||
      (layout >= kStateLayoutWithoutNoise && !polarity_.RestoreState(&in)) ||
      (layout >= kStateLayout && !segmenter_.RestoreNoise(&in))) {
    return InvalidArgumentError(path_ + ": cannot resume: the checkpoint's tracker state is " +
                                (known ? "malformed" : "of another Saker"));
  }
  segment_open_ = segment_open != 0;
  return Status::Ok();
}

// Resuming exactly, a frame up to the checkpoint's key frame: the change detector takes it again
// (its answers that the checkpoint had applied are dropped), and at the key frame the feature
// tracker and the key frame chain go on from the checkpoint's state.
Status FrontEnd::Replay(const video::Frame& frame) {
  if (change_) {
    const FrameResult& done = resume_->frames[static_cast<size_t>(frame.index)];
    std::optional<Eigen::Matrix3d> motion;
    if (done.homography_ok) motion = done.current_from_previous;
    change_->Submit(frame.index, frame.grey, motion);
    while (change_->NextThrough(change_applied_submitted_)) {
      // answered and applied before the checkpoint: dropped
    }
  }
  if (frame.index < start_.through_frame) return Status::Ok();
  if (!tracker_.RestoreState(&*tracker_state_, frame.grey) || !tracker_state_->AtEnd()) {
    return InvalidArgumentError(path_ +
                                ": cannot resume: the checkpoint's tracker state is malformed");
  }
  chain_.ContinueFrom(resume_->key_frames.back());
  if (!resume_->key_frame_images.empty()) {
    preview_from_current_ = resume_->key_frame_images.back().preview_from_frame;
  }
  return Status::Ok();
}

// The trackers' state after the latest frame (FrontEndCheckpoint::state); the feature tracker
// last, as Replay restores it after the rest.
std::vector<uint8_t> FrontEnd::SaveState() const {
  ByteWriter out;
  out.Put<uint32_t>(kStateLayout);
  out.Put<uint8_t>(segment_open_);
  out.Put<int64_t>(change_applied_submitted_);
  segmenter_.SaveState(&out);
  target_tracker_.SaveState(&out);
  change_tracks_.SaveState(&out);
  overlays_.SaveState(&out);
  polarity_.SaveState(&out);
  segmenter_.SaveNoise(&out);
  tracker_.SaveState(&out);
  return out.Take();
}

void FrontEnd::ReportProgress(double frames_done) const {
  if (job_ != nullptr) {
    job_->ReportProgress("front end", std::min(1.0, frames_done / expected_frames_));
  }
}

Status FrontEnd::CheckMemoryBudget(int width, int height) {
  // What the pipeline holds for the previous size is in the resident memory already.
  const int64_t held = options_.FramePipelineBytes(budget_size_.width, budget_size_.height);
  budget_size_ = cv::Size(width, height);
  if (options_.max_memory_mib <= 0) return Status::Ok();
  const int64_t resident_mib = ResidentMemoryBytes() / (1024 * 1024);
  const int64_t needed = options_.FramePipelineBytes(width, height);
  const int64_t needed_mib = needed / (1024 * 1024);
  const int64_t more_mib = std::max<int64_t>(0, needed - held) / (1024 * 1024);
  if (resident_mib + more_mib <= options_.max_memory_mib) return Status::Ok();
  return ResourceExhaustedError(
      path_ + ": processing stopped before decoding pictures of " + std::to_string(width) + "x" +
      std::to_string(height) + ": decoding them and queueing the frames needs up to " +
      std::to_string(needed_mib) + " MiB, which with the " + std::to_string(resident_mib) +
      " MiB Saker is using is over its memory limit of " + std::to_string(options_.max_memory_mib) +
      " MiB. Raise the limit (--max-memory) or process a smaller video.");
}

Status FrontEnd::CheckMemory(const video::Frame& frame) {
  if (options_.max_memory_mib <= 0) return Status::Ok();
  if (!frame.grey.empty() &&
      (frame.grey.cols != budget_size_.width || frame.grey.rows != budget_size_.height)) {
    // The picture size changed mid-stream: the queues will fill with frames of the new size.
    SAKER_RETURN_IF_ERROR(CheckMemoryBudget(frame.grey.cols, frame.grey.rows));
  }
  const int64_t pixels = std::max<int64_t>(1, frame.grey.total());
  const int64_t interval = std::max<int64_t>(1, kMemoryCheckPixels / pixels);
  if (frame.index % interval != 0) return Status::Ok();
  const int64_t resident_mib = ResidentMemoryBytes() / (1024 * 1024);
  if (resident_mib <= options_.max_memory_mib) return Status::Ok();
  std::ostringstream message;
  message.setf(std::ios::fixed);
  message.precision(1);
  message << path_ << ": processing stopped at frame " << frame.index << " (" << frame.time_s
          << " s): Saker is using " << resident_mib << " MiB, over its memory limit of "
          << options_.max_memory_mib
          << " MiB. Process a shorter part of the video or raise the limit (--max-memory).";
  return ResourceExhaustedError(message.str());
}

// Track, ground motion, change detection submitted, segmentation and targets; then, from the
// checkpoint's key frame on (the frames before it only warm up), key frames and checkpoints.
Status FrontEnd::ProcessFrame(const video::Frame& frame, bool on_ground) {
  FrameResult fr;
  fr.index = frame.index;
  fr.time_s = frame.time_s;
  fr.pts = frame.pts;
  fr.key_frame = frame.key_frame;
  FrontEndTiming& timing = result_.timing;
  const Stopwatch watch;
  if (const std::optional<track::HorizonLine> line = horizon_.Add(frame.grey, on_ground)) {
    // The frames just before, whose own horizon was found before the window confirmed it, are
    // masked too (the first frames of a video that starts with the horizon in view).
    for (const auto& [index, earlier] : unconfirmed_sky_) MaskSky(index, earlier, nullptr);
    unconfirmed_sky_.clear();
    MaskSky(frame.index, *line, &fr);
  } else if (const std::optional<track::HorizonLine>& found = horizon_.found()) {
    unconfirmed_sky_.emplace_back(frame.index, *found);
  }
  while (!unconfirmed_sky_.empty() &&
         unconfirmed_sky_.front().first <= frame.index - horizon_.window_frames()) {
    unconfirmed_sky_.pop_front();
  }
  // In the low-frame-rate mode the ground moves far between frames: the flow starts where the
  // previous frame's ground motion would take the points.
  tracker_.Process(frame.index, frame.grey,
                   low_frame_rate_ && last_motion_ ? &*last_motion_ : nullptr);
  SelectGroundMatches();
  timing.track_ms += watch.ElapsedMs();
  fr.tracked = static_cast<int>(tracker_.points().size());

  std::optional<Eigen::Vector3d> epipole;
  const std::optional<track::HomographyEstimate> estimate = EstimateGroundMotion(&epipole);
  last_motion_.reset();
  if (estimate) last_motion_ = estimate->target_from_source;
  if (estimate) {
    // Every match, those on the mask too: an overlay's corners keep it (not in the sky).
    overlays_.AddFeatures(tracker_.matches(), estimate->target_from_source, frame.grey.size(),
                          SkyEdge(frame.index));
  }
  // Without change detection the features are the only evidence, and the mask is handed out at
  // once (with it, at the change answers' fixed lag).
  if (!change_) NoteOverlayMask(frame.index);
  SubmitForChange(frame, estimate);
  Segment(frame, estimate, epipole, &fr);
  ApplyChangeThrough(frame.index - kChangeLagFrames);
  segment_open_ = fr.tracked > 0;
  ++timing.frames;
  if (frame.index == start_.through_frame && !resume_->key_frame_images.empty()) {
    preview_from_current_ = resume_->key_frame_images.back().preview_from_frame;
  }
  if (frame.index < start_.through_frame) return Status::Ok();  // the checkpoint has this frame

  const bool new_key_frame = AddToChain(frame, estimate);
  if (frame.index > start_.through_frame) result_.frames.push_back(fr);
  if (new_key_frame && options_.on_checkpoint &&
      since_checkpoint_.ElapsedSeconds() >= options_.checkpoint_interval_s) {
    SAKER_RETURN_IF_ERROR(HandOutCheckpoint(frame.index, /*complete=*/false));
  }
  ReportProgress(static_cast<double>(result_.frames.size()));
  return Status::Ok();
}

// Ground motion from the tracks that are not (yet) known to move, and the epipole when the scene
// shows parallax.
std::optional<track::HomographyEstimate> FrontEnd::EstimateGroundMotion(
    std::optional<Eigen::Vector3d>* epipole) {
  const Stopwatch watch;
  // Features that kept still in the image while the rest moved are an overlay the mask does not
  // know yet: within the robust fit's threshold of the ground when it moves slowly, they pulled
  // the first second's estimates towards no motion (by 0.6 px at the corners against 0.04 on the
  // same flight without the overlay). They stay in the segmentation (a car the camera follows
  // keeps still in the image too).
  const std::vector<track::FeatureTrackId> still =
      options_.overlays.enabled
          ? track::StillFeatures(tracker_, ground_matches_, still_window_frames_,
                                 options_.overlays.still_min_window_frames,
                                 options_.overlays.still_min_flow_px,
                                 options_.overlays.fixed_fraction, options_.overlays.still_max_px)
          : std::vector<track::FeatureTrackId>{};
  std::vector<track::Correspondence> ground;
  ground.reserve(ground_matches_.size());
  for (const track::Correspondence& m : ground_matches_) {
    if (segmenter_.LabelOf(m.id) != track::MotionLabel::kMoving &&
        !std::binary_search(still.begin(), still.end(), m.id)) {
      ground.push_back(m);
    }
  }
  std::optional<track::HomographyEstimate> estimate;
  if (segment_open_ && !ground.empty()) {
    StatusOr<track::HomographyEstimate> h =
        track::EstimateHomography(ground, options_.frame_homography);
    if (h.ok()) estimate = std::move(h).value();
  }
  if (estimate && options_.parallax_check) *epipole = ParallaxEpipole(ground, *estimate, options_);
  result_.timing.homography_ms += watch.ElapsedMs();
  return estimate;
}

// Change detection (small movers, and what the image shows under each target) starts on the
// frame as soon as its ground motion is known.
void FrontEnd::SubmitForChange(const video::Frame& frame,
                               const std::optional<track::HomographyEstimate>& estimate) {
  if (!change_) return;
  const Stopwatch watch;
  std::optional<Eigen::Matrix3d> motion;
  if (estimate) motion = estimate->target_from_source;
  change_->Submit(frame.index, frame.grey, motion);
  change_side_ms_ += watch.ElapsedMs();
}

void FrontEnd::Segment(const video::Frame& frame,
                       const std::optional<track::HomographyEstimate>& estimate,
                       const std::optional<Eigen::Vector3d>& epipole, FrameResult* frame_result) {
  const Stopwatch watch;
  const double change_side_before = change_side_ms_;
  scenes_.Add(frame.index, /*new_segment=*/!estimate.has_value(), frame.grey);
  if (estimate) {
    preview_from_current_ = preview_from_current_ * estimate->target_from_source.inverse();
    preview_from_current_ /= preview_from_current_(2, 2);
    frame_result->homography_ok = true;
    frame_result->current_from_previous = estimate->target_from_source;
    frame_result->covariance = estimate->covariance;
    frame_result->inliers = static_cast<int>(estimate->inliers.size());
    segmenter_.AddFrame(ground_matches_, estimate->target_from_source, epipole);
    const double threshold = segmenter_.residual_threshold_px();
    if (threshold > options_.segmentation.residual_threshold_px ||
        segmenter_.window_displacement_px() > options_.segmentation.min_window_displacement_px) {
      VideoNoise& noise = result_.noise;
      ++noise.feature_frames;
      noise.residual_threshold_px = std::max(noise.residual_threshold_px, threshold);
    }
    // At low frame rates the moving labels only keep movers out of the ground motion: the targets
    // come from change detection.
    target_tracker_.AddFrame(
        frame.index, low_frame_rate_ ? std::vector<track::MovingPoint>{} : segmenter_.moving());
    frame_result->moving = static_cast<int>(segmenter_.moving().size());
  } else if (segment_open_) {
    // No reliable ground motion (blank, featureless, a cut): the chain breaks here; the next
    // frame starts afresh. The targets first take the change evidence of the segment's frames.
    ApplyChangeThrough(frame.index - 1);
    CloseOverlayMask(frame.index - 1);  // a mask applies within one chain segment
    segmenter_.Reset();
    target_tracker_.FinishAll();
    target_tracker_.EndChangeEvidence();  // the change detector starts again too
    tracker_.Reset();
    tracker_.Process(frame.index, frame.grey);
  }
  for (track::TargetTrack& t : target_tracker_.TakeFinished()) {
    KeepTarget(std::move(t), start_.through_frame, &result_.targets);
  }
  result_.timing.segment_ms += watch.ElapsedMs() - (change_side_ms_ - change_side_before);
}

void FrontEnd::StartChangeDetection(const track::GroundScale* scale) {
  if (!options_.change.enabled) return;
  track::ChangeOptions change = options_.EffectiveChange(rate_.fps());
  change.processing_width =
      change.ProcessingWidth(cv::Size(result_.video.width, result_.video.height), scale);
  change_.emplace(change, rate_, static_cast<size_t>(options_.change_queue_frames),
                  static_cast<size_t>(kChangeLagFrames));
}

void FrontEnd::NoteGroundScale(int64_t index, std::optional<track::GroundScale> scale) {
  if (!change_) return;
  ground_scales_.erase(ground_scales_.begin(),
                       ground_scales_.lower_bound(index - scale_keep_frames_));
  if (scale) ground_scales_.insert_or_assign(index, std::move(*scale));
}

// The change answers for every frame up to `frame`, waiting for them if need be. Applied at a
// fixed lag, so that the result never depends on how the threads ran: once frame n is through
// segmentation, the answers up to n - kChangeLagFrames; at a chain break every answer up to the
// frame before it, at the end all of them.
void FrontEnd::ApplyChangeThrough(int64_t frame) {
  if (!change_) return;
  const Stopwatch watch;
  while (std::optional<ChangeThread::Answer> answer = change_->NextThrough(frame)) {
    ApplyChangeAnswer(*answer);
    change_applied_submitted_ = answer->submitted;
  }
  change_side_ms_ += watch.ElapsedMs();
}

// What the single-threaded front end did right after the frame: the blob tracks (ended first
// when the frame had no ground motion), the change evidence of the targets, the finished blob
// tracks.
void FrontEnd::ApplyChangeAnswer(const ChangeThread::Answer& answer) {
  const Stopwatch watch;
  if (answer.restart) change_tracks_.FinishAll();
  const track::ChangeFrame& c = answer.change;
  if (c.answered()) {
    if (c.allowances_raised) {
      VideoNoise& noise = result_.noise;
      ++noise.change_frames;
      noise.change_noise_grey = std::max(noise.change_noise_grey, c.noise_grey);
      noise.change_registration_px = std::max(noise.change_registration_px, c.registration_px);
    }
    // The overlay learns from every change (not in the sky), then none on it goes on to the
    // change tracks.
    overlays_.AddChange(c, change_baseline_frames_, SkyEdge(c.frame));
    NoteOverlayMask(c.frame);
    std::vector<track::ChangeBlob> blobs;
    blobs.reserve(c.blobs.size());
    for (const track::ChangeBlob& b : c.blobs) {
      if (!overlays_.Contains(b.position) && !AboveHorizon(c.frame, b.position)) {
        blobs.push_back(b);
      }
    }
    const auto scale = ground_scales_.find(c.frame);
    change_tracks_.AddFrame(c.frame, blobs, c.frame_motion,
                            c.registration_px / options_.change.clean_registration_px,
                            scale != ground_scales_.end() ? &scale->second : nullptr);
    // Within the target's box, and a few pixels round a single point.
    target_tracker_.RecordChange(c.frame, [&](const track::TargetObservation& o) {
      if (!c.Compared(o.position)) return track::ChangeEvidence::kNotLooked;
      const double radius = std::max(3.0, 0.5 * (o.box_max - o.box_min).maxCoeff());
      return c.ChangedNear(o.position, radius) ? track::ChangeEvidence::kChanged
                                               : track::ChangeEvidence::kNone;
    });
    change_through_ = std::max(change_through_, c.frame);
  }
  for (track::TargetTrack& t : change_tracks_.TakeFinished()) {
    KeepTarget(std::move(t), start_.change_through_frame, &targets_by_change_);
  }
  result_.timing.change_ms += answer.ms;
  result_.timing.change_tracks_ms += watch.ElapsedMs();
}

std::optional<track::HorizonLine> FrontEnd::SkyEdge(int64_t frame) const {
  const auto it = horizon_lines_.find(frame);
  if (it == horizon_lines_.end()) return std::nullopt;
  const track::HorizonLine& horizon = it->second;
  return track::HorizonLine{horizon.centre_x, horizon.y_at_centre + horizon_.margin_px(),
                            horizon.slope};
}

bool FrontEnd::AboveHorizon(int64_t frame, const Eigen::Vector2d& p) const {
  const std::optional<track::HorizonLine> edge = SkyEdge(frame);
  return edge && p.y() < edge->YAt(p.x());
}

void FrontEnd::MaskSky(int64_t index, const track::HorizonLine& horizon, FrameResult* current) {
  if (!horizon_lines_.emplace(index, horizon).second) return;
  if (index >= start_.through_frame) ++result_.horizon_frames;
  const track::HorizonLine edge = *SkyEdge(index);
  if (current != nullptr) {
    current->sky_line = edge;
    return;
  }
  const auto it = std::lower_bound(result_.frames.begin(), result_.frames.end(), index,
                                   [](const FrameResult& f, int64_t i) { return f.index < i; });
  if (it != result_.frames.end() && it->index == index) it->sky_line = edge;
}

// Whether the target lies above the horizon (or in the distant ground below it) in at least the
// overlay's fraction of its frames: sky, clouds or haze, not a mover on the ground.
bool FrontEnd::MostlyAboveHorizon(const track::TargetTrack& target) const {
  if (horizon_lines_.empty() || target.observations.empty()) return false;
  int64_t above = 0;
  for (const track::TargetObservation& o : target.observations) {
    if (AboveHorizon(o.frame, o.position)) ++above;
  }
  return static_cast<double>(above) >=
         options_.overlays.max_target_fraction * static_cast<double>(target.observations.size());
}

// A target this run finished, cut at the seam when resuming; none that lies on the overlay mask
// or above the horizon.
void FrontEnd::KeepTarget(track::TargetTrack target, int64_t cut,
                          std::vector<track::TargetTrack>* to) {
  if (overlays_.Covers(target) || MostlyAboveHorizon(target)) return;
  if (!target_seam_) {
    to->push_back(std::move(target));
  } else if (std::optional<track::TargetTrack> kept = target_seam_->Trim(std::move(target), cut)) {
    to->push_back(std::move(*kept));
  }
}

// The tracker's matches whose latest position is off the overlay mask and below the horizon.
void FrontEnd::SelectGroundMatches() {
  ground_matches_.clear();
  for (const track::Correspondence& m : tracker_.matches()) {
    if (!overlays_.Contains(m.target) && !horizon_.Masks(m.target)) ground_matches_.push_back(m);
  }
}

// Whether `now` has a quarter more overlay cells (and at least 4) that `before` did not have, or
// another grid.
bool MaskGrew(const track::OverlayMask& before, const track::OverlayMask& now) {
  if (before.cells.size() != now.cells.size() || before.cell_px != now.cell_px) return true;
  cv::Mat added;
  cv::compare(now.cells, before.cells, added, cv::CMP_GT);
  const int grown = cv::countNonZero(added);
  return grown >= std::max(4, cv::countNonZero(before.cells) / 4);
}

// After the overlay detector took the change answer of `frame`: the mask handed out goes on to
// cover it, or is closed and replaced when the detector's mask changed: at once when it grew
// (MaskGrew), otherwise at most once per overlay window, so that flickering cells do not make a
// mask per frame.
void FrontEnd::NoteOverlayMask(int64_t frame) {
  const bool changed = overlays_.version() != open_overlay_version_;
  // A mask that grew is handed out at once: the evidence builds up over seconds, and the first
  // mask of a segment is a fraction of the overlay.
  const bool grew = changed && open_overlay_ && MaskGrew(*open_overlay_, overlays_.mask());
  if (open_overlay_ &&
      (!changed || (!grew && frame - open_overlay_->first_frame < overlay_min_frames_))) {
    open_overlay_->last_frame = std::max(open_overlay_->last_frame, frame);
    return;
  }
  CloseOverlayMask(frame - 1);
  open_overlay_version_ = overlays_.version();
  if (overlays_.mask().Coverage() <= 0) return;
  open_overlay_ = overlays_.mask();
  open_overlay_->cells = overlays_.mask().cells.clone();
  open_overlay_->first_frame = frame;
  open_overlay_->last_frame = frame;
}

// Ends the mask handed out at `last_frame` (when it started by then) and adds it to the result.
void FrontEnd::CloseOverlayMask(int64_t last_frame) {
  if (!open_overlay_) return;
  open_overlay_->last_frame = std::max(open_overlay_->first_frame, last_frame);
  result_.overlays.push_back(std::move(*open_overlay_));
  open_overlay_.reset();
  open_overlay_version_ = -1;
}

// Key frames from the stationary points. The key frames, links and breaks of the chain enter the
// result as they appear, numbered after the checkpoint's when resuming. True for a new key frame.
bool FrontEnd::AddToChain(const video::Frame& frame,
                          const std::optional<track::HomographyEstimate>& estimate) {
  const Stopwatch watch;
  std::vector<track::StationaryPoint> stationary;
  stationary.reserve(tracker_.points().size());
  for (const track::TrackedPoint& p : tracker_.points()) {
    if (segmenter_.LabelOf(p.id) != track::MotionLabel::kMoving &&
        !overlays_.Contains(p.position) && !horizon_.Masks(p.position)) {
      stationary.emplace_back(p.id, p.position);
    }
  }
  chain_.AddFrame(frame.index, stationary, estimate);
  bool new_key_frame = false;
  for (; chain_key_frames_ < chain_.key_frames().size(); ++chain_key_frames_) {
    std::optional<track::KeyFrame> key = chain_seam_.Continue(
        chain_.key_frames()[chain_key_frames_], chain_key_frames_ == 0, &result_.breaks);
    if (!key) continue;
    if (options_.key_frame_image_width > 0) AddKeyFrameImage(*key, frame);
    result_.key_frames.push_back(std::move(*key));
    new_key_frame = true;
  }
  for (; chain_links_ < chain_.links().size(); ++chain_links_) {
    result_.links.push_back(chain_seam_.Continue(chain_.links()[chain_links_]));
  }
  for (; chain_breaks_ < chain_.breaks().size(); ++chain_breaks_) {
    result_.breaks.push_back(chain_.breaks()[chain_breaks_]);
  }
  result_.timing.key_frames_ms += watch.ElapsedMs();
  return new_key_frame;
}

void FrontEnd::AddKeyFrameImage(const track::KeyFrame& key, const video::Frame& frame) {
  KeyFrameImage image;
  image.id = key.id;
  image.frame_index = key.frame_index;
  track::MakeKeyFramePicture(frame.grey, frame.chroma, frame.coding, options_.key_frame_image_width,
                             &image);
  if (options_.on_key_frame) options_.on_key_frame({image, preview_from_current_});
  result_.key_frame_images.push_back(std::move(image));
  image_placements_.push_back(preview_from_current_);
}

// Hands out a checkpoint: what is new since the last one, the open targets, the state.
Status FrontEnd::HandOutCheckpoint(int64_t through_frame, bool complete) {
  FrontEndCheckpoint c =
      delivered_.TakeNew(through_frame, complete, result_, image_placements_, targets_by_change_);
  if (!complete) {
    // The targets still followed, as they would end now (on copies of the trackers).
    track::TargetTracker open = target_tracker_;
    open.FinishAll();
    open.EndChangeEvidence();
    for (track::TargetTrack& t : open.TakeFinished()) {
      KeepTarget(std::move(t), start_.through_frame, &c.open_targets);
    }
    track::BlobTracker open_change = change_tracks_;
    open_change.FinishAll();
    for (track::TargetTrack& t : open_change.TakeFinished()) {
      KeepTarget(std::move(t), start_.change_through_frame, &c.open_change_targets);
    }
    c.change_through_frame = change_through_;
    c.state = SaveState();
  }
  since_checkpoint_.Restart();
  const Status saved = options_.on_checkpoint(c);
  if (!saved.ok()) return Status(saved.code(), path_ + ": checkpoint: " + saved.message());
  return Status::Ok();
}

StatusOr<FrontEndResult> FrontEnd::Finish(ingest::VideoScan scan, double decode_ms) {
  result_.scan = std::move(scan);
  if (result_.scan.frames.size() != result_.frames.size()) {
    // Only a checkpoint of another video can do this (the scan and the tracker see each frame).
    SAKER_CHECK(resume_ != nullptr) << "the scan saw " << result_.scan.frames.size()
                                    << " frames, the tracker " << result_.frames.size();
    return InvalidArgumentError(path_ + ": cannot resume: the checkpoint has " +
                                std::to_string(resume_->frames.size()) +
                                " frames done and does not fit this video of " +
                                std::to_string(result_.scan.frames.size()) + " frames");
  }
  result_.polarity_switches = polarity_.switches();
  if (!start_.complete) {
    FinishTargets();
    if (options_.on_checkpoint && !result_.frames.empty()) {
      SAKER_RETURN_IF_ERROR(HandOutCheckpoint(result_.frames.back().index, /*complete=*/true));
    }
  }
  FrontEndTiming& timing = result_.timing;
  if (change_) timing.change_wait_ms = change_->wait_ms();
  const double n = static_cast<double>(std::max<int64_t>(1, timing.frames));
  timing.decode_ms = decode_ms / n;
  timing.track_ms /= n, timing.homography_ms /= n, timing.segment_ms /= n, timing.change_ms /= n,
      timing.change_tracks_ms /= n, timing.change_wait_ms /= n, timing.key_frames_ms /= n;
  return std::move(result_);
}

// The end of the video: every change answer applied, every target ended, the last overlay mask
// closed and the targets on the masks dropped (also those ended before their mask existed), both
// sources combined.
void FrontEnd::FinishTargets() {
  ApplyChangeThrough(std::numeric_limits<int64_t>::max());
  target_tracker_.FinishAll();
  target_tracker_.EndChangeEvidence();
  for (track::TargetTrack& t : target_tracker_.TakeFinished()) {
    KeepTarget(std::move(t), start_.through_frame, &result_.targets);
  }
  change_tracks_.FinishAll();
  for (track::TargetTrack& t : change_tracks_.TakeFinished()) {
    KeepTarget(std::move(t), start_.change_through_frame, &targets_by_change_);
  }
  if (!result_.frames.empty()) CloseOverlayMask(result_.frames.back().index);
  if (!result_.overlays.empty()) {
    std::vector<int64_t> breaks;
    for (const track::ChainBreak& b : result_.breaks) breaks.push_back(b.frame_index);
    std::sort(breaks.begin(), breaks.end());
    // The ground's motion at an image point summed over frames (first, last] of the result.
    const auto ground_shift = [&](int64_t first, int64_t last, const Eigen::Vector2d& p) {
      auto it =
          std::upper_bound(result_.frames.begin(), result_.frames.end(), first,
                           [](int64_t frame, const FrameResult& f) { return frame < f.index; });
      double shift = 0;
      for (; it != result_.frames.end() && it->index <= last; ++it) {
        if (!it->homography_ok) continue;
        const Eigen::Vector3d q = it->current_from_previous * p.homogeneous();
        if (q.z() > 0) shift += (q.hnormalized() - p).norm();
      }
      return shift;
    };
    const track::OverlayOptions& o = options_.overlays;
    const auto on_overlay = [&](const track::TargetTrack& t) {
      const bool fixed =
          track::ScreenFixed(t, o.fixed_radius_px, o.fixed_share, o.fixed_ground_fraction,
                             o.fixed_min_ground_px, ground_shift);
      return track::OnOverlayMasks(t, result_.overlays, breaks, o.max_target_fraction,
                                   fixed ? o.fixed_near_cells : 0);
    };
    std::erase_if(result_.targets, on_overlay);
    std::erase_if(targets_by_change_, on_overlay);
  }
  result_.targets = CombineTargets(std::move(result_.targets), std::move(targets_by_change_),
                                   result_.frames, options_, rate_, scenes_);
}

// The options and the checkpoint of a run on `path`.
Status ValidateRun(const std::string& path, const FrontEndOptions& options,
                   const FrontEndCheckpoint* resume) {
  SAKER_RETURN_IF_ERROR(options.Validate());
  if (resume != nullptr) {
    const Status valid = resume->Validate();
    if (!valid.ok()) return InvalidArgumentError(path + ": cannot resume: " + valid.message());
  }
  return Status::Ok();
}

}  // namespace

video::ReaderOptions FrontEndOptions::EffectiveReader() const {
  video::ReaderOptions reader;
  reader.want_bgr = false;
  reader.want_grey = true;
  reader.want_chroma = key_frame_colour && key_frame_image_width > 0;
  reader.decoder_threads = decoder_threads;
  return reader;
}

int64_t FrontEndOptions::FramePipelineBytes(int width, int height) const {
  const int64_t pixels = static_cast<int64_t>(std::max(width, 0)) * std::max(height, 0);
  const int64_t threads = decoder_threads > 0
                              ? decoder_threads
                              : std::min<int64_t>(16, std::thread::hardware_concurrency() + 1);
  const int64_t decoder_pictures = kDecoderReferencePictures + 1 + threads;
  // Queued for the tracker, for change detection, waiting for its answers; current and previous;
  // the latest one SceneContinuity keeps for its segment's last look.
  const int64_t grey_frames = queue_frames + change_queue_frames + kChangeLagFrames + 3;
  // The chroma (4:2:0: half the luma's bytes) of the frames queued for the tracker and the
  // current one, until the key frame decision.
  const int64_t chroma_frames = EffectiveReader().want_chroma ? queue_frames + 2 : 0;
  return pixels * 3 / 2 * decoder_pictures + pixels * grey_frames + pixels / 2 * chroma_frames;
}

track::TrackerOptions FrontEndOptions::EffectiveTracker(track::FrameRate rate) const {
  track::TrackerOptions effective = tracker;
  effective.keep_finished = false;
  effective.max_history =
      1 + std::max(1, rate.Frames(overlays.still_window_s, overlays.still_min_window_frames));
  return effective;
}

bool FrontEndOptions::LowFrameRateFor(double fps) const {
  switch (low_frame_rate.mode) {
    case LowFrameRateOptions::Mode::kOn:
      return change.enabled;
    case LowFrameRateOptions::Mode::kOff:
      return false;
    case LowFrameRateOptions::Mode::kAuto:
      return change.enabled && track::FrameRate(fps).fps() < low_frame_rate.below_fps;
  }
  return false;
}

track::ChangeOptions FrontEndOptions::EffectiveChange(double fps) const {
  track::ChangeOptions effective = change;
  if (LowFrameRateFor(fps)) {
    effective.one_sided_edges = low_frame_rate.one_sided_edges;
    effective.evidence_baseline_s = 0;  // no feature targets to give evidence to
    effective.baseline_s = std::max(effective.baseline_s, low_frame_rate.min_baseline_s);
    effective.registration_px = low_frame_rate.registration_px;
  }
  return effective;
}

void FrontEndOptions::UseFixedThresholds() {
  segmentation.noise_multiple = segmentation.window_noise_multiple = 0;
  change.measured_noise_multiple = change.measured_registration_multiple = 0;
}

track::BlobTrackOptions FrontEndOptions::EffectiveChangeTracks(double fps) const {
  return LowFrameRateFor(fps) ? low_frame_rate.blobs : change_tracks;
}

track::BlobTrackOptions LowFrameRateOptions::LowFrameRateBlobs() {
  track::BlobTrackOptions blobs;
  blobs.gate_px = 8;
  blobs.gate_growth_px_s = 20;
  blobs.gate_speed_fraction = 0.45;
  blobs.min_travel_px = 8;
  blobs.max_fit_rms_px = 3;
  blobs.noisy_fit_rms_px = 3;   // not narrowed by noise (1 fps raises it in most frames)
  blobs.noisy_max_area_px = 0;  // cars are blobs of any size at these rates, noisy or not
  blobs.new_track_speed_px_s = 250;
  return blobs;
}

Status LowFrameRateOptions::Validate() const {
  if (!(below_fps > 0 && below_fps <= track::FrameRate::kMaxFps)) {
    return InvalidArgumentError(
        "low frame rates: the rate below which the mode runs must be in "
        "(0, 120] frames a second");
  }
  if (!(min_baseline_s >= 0 && min_baseline_s <= 10)) {
    return InvalidArgumentError(
        "low frame rates: the change detector's shortest baseline must be in [0, 10] s");
  }
  if (!(registration_px >= 0 && registration_px <= 10)) {
    return InvalidArgumentError(
        "low frame rates: the change detector's registration allowance must be in [0, 10] px");
  }
  return blobs.Validate();
}

const char* LowFrameRateModeName(LowFrameRateOptions::Mode mode) {
  switch (mode) {
    case LowFrameRateOptions::Mode::kAuto:
      return "auto";
    case LowFrameRateOptions::Mode::kOn:
      return "on";
    case LowFrameRateOptions::Mode::kOff:
      return "off";
  }
  return "auto";
}

std::optional<LowFrameRateOptions::Mode> ParseLowFrameRateMode(const std::string& text) {
  for (const auto mode : {LowFrameRateOptions::Mode::kAuto, LowFrameRateOptions::Mode::kOn,
                          LowFrameRateOptions::Mode::kOff}) {
    if (text == LowFrameRateModeName(mode)) return mode;
  }
  return std::nullopt;
}

track::TargetTrackOptions FrontEndOptions::EffectiveTargets(double fps) const {
  track::TargetTrackOptions effective = targets;
  effective.wait_for_change = change.enabled;
  // A frame or two unseen in the low-frame-rate mode is a second or more: on the tuning seeds
  // filling those cost precision and found nothing (docs/front-end.md, "Gaps filled").
  if (LowFrameRateFor(fps)) effective.fill_gap_s = 0;
  return effective;
}

Status FrontEndOptions::Validate() const {
  SAKER_RETURN_IF_ERROR(tracker.Validate());
  SAKER_RETURN_IF_ERROR(segmentation.Validate());
  SAKER_RETURN_IF_ERROR(targets.Validate());
  SAKER_RETURN_IF_ERROR(frame_homography.Validate());
  SAKER_RETURN_IF_ERROR(key_frames.Validate());
  SAKER_RETURN_IF_ERROR(change.Validate());
  SAKER_RETURN_IF_ERROR(change_tracks.Validate());
  SAKER_RETURN_IF_ERROR(change_echoes.Validate());
  SAKER_RETURN_IF_ERROR(overlays.Validate());
  SAKER_RETURN_IF_ERROR(horizon.Validate());
  SAKER_RETURN_IF_ERROR(low_frame_rate.Validate());
  SAKER_RETURN_IF_ERROR(metadata.Validate());
  if (!(min_change_support >= 0 && min_change_support <= 1)) {
    return InvalidArgumentError("front end: the change support fraction must be in [0, 1]");
  }
  if (queue_frames < 1 || queue_frames > 256) {
    return InvalidArgumentError("front end: the frame queue must hold 1..256 frames");
  }
  if (change_queue_frames < 1 || change_queue_frames > 256) {
    return InvalidArgumentError("front end: the change detection queue must hold 1..256 frames");
  }
  if (max_memory_mib < 0) {
    return InvalidArgumentError("front end: the memory limit must be >= 0 MiB (0: none)");
  }
  if (key_frame_image_width < 0) {
    return InvalidArgumentError("front end: the key frame image width must be >= 0");
  }
  if (!(checkpoint_interval_s >= 0)) {
    return InvalidArgumentError("front end: the checkpoint interval must be >= 0 s");
  }
  if (!(resume_warmup_s >= 0 && resume_warmup_s <= 3600)) {
    return InvalidArgumentError("front end: the resume warm-up must be in [0, 3600] s");
  }
  return Status::Ok();
}

StatusOr<FrontEndResult> RunFrontEnd(const std::string& path, const FrontEndOptions& options,
                                     JobContext* job, const FrontEndCheckpoint* resume) {
  SAKER_RETURN_IF_ERROR(ValidateRun(path, options, resume));
  // Opened before anything runs, so that a file that is not a video fails at once with the
  // reader's message.
  SAKER_ASSIGN_OR_RETURN(std::unique_ptr<video::VideoReader> reader,
                         video::VideoReader::Open(path, options.EffectiveReader()));
  return RunFrontEnd(std::move(reader), options, job, resume);
}

StatusOr<FrontEndResult> RunFrontEnd(std::unique_ptr<video::VideoReader> reader,
                                     const FrontEndOptions& options, JobContext* job,
                                     const FrontEndCheckpoint* resume) {
  SAKER_CHECK(reader != nullptr) << "RunFrontEnd needs an opened reader";
  // Checked here rather than on the decode thread, which could not report it.
  SAKER_CHECK(reader->options().want_grey && reader->stats().frames_decoded == 0)
      << reader->info().path
      << ": the front end needs a reader opened with FrontEndOptions::EffectiveReader() and not "
         "yet read from";
  SAKER_RETURN_IF_ERROR(ValidateRun(reader->info().path, options, resume));
  const std::string path = reader->info().path;
  FrontEnd front_end(std::move(reader), options, job, resume);
  try {
    return front_end.Run();
  } catch (const CheckError&) {
    throw;  // a bug: reported as one by the caller
  } catch (...) {
    // Out of memory on this thread or the change detection thread: an error naming the video.
    return StatusFromCurrentException(path + ": processing stopped");
  }
}

}  // namespace saker::frontend
