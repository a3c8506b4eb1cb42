#pragma once

// The streaming Visual MTI front end: video in; per frame the ground motion from the previous
// frame with its covariance; moving-target tracks; key frames and the sequential links between
// them. decode -> track -> segment -> homography -> key frames / targets.
//
// Three threads: decoding feeds a bounded queue; the calling thread tracks, estimates the ground
// motion, segments and keeps the key frames; change detection runs on a third thread fed by a
// second bounded queue, and its answers are applied on the calling thread at a fixed lag, so the
// result is the same however the threads run (docs/front-end.md). Frames are not kept: memory
// holds the live feature tracks, the key frames (their stationary points and a downscaled grey
// image for later matching), the per-frame homographies and the target tracks.

#include "core/ingest/video_scan.h"
#include "core/track/change_detector.h"
#include "core/track/feature_tracker.h"
#include "core/track/homography.h"
#include "core/track/horizon.h"
#include "core/track/key_frames.h"
#include "core/track/motion_segmentation.h"
#include "core/track/overlay_mask.h"
#include "core/track/target_tracks.h"
#include "core/util/job_context.h"
#include "core/util/status.h"
#include "core/video/video_reader.h"

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace saker::frontend {

using KeyFrameImage = track::KeyFrameImage;

// A key frame as the front end first places it, so that a viewer can show the mosaic growing
// while the video is processed: `preview_from_frame` chains the frame-to-frame homographies from
// the video's first frame (its pixels are the preview's frame; across a chain break the placement
// carries over unchanged). Unadjusted, so it drifts; the mosaic replaces it.
struct KeyFramePreview {
  KeyFrameImage image;  // shares its pixels with the result's copy, which is never modified
  Eigen::Matrix3d preview_from_frame = Eigen::Matrix3d::Identity();
};

struct FrontEndCheckpoint;

// The low-frame-rate mode (issue 24, item 2; docs/front-end.md, "Low frame rates"). Frames a
// second or more apart are what wide-area motion imagery gives: feature tracks that far apart
// cannot be trusted to label motion (a corner's neighbourhood changes, Lucas-Kanade slips onto
// the next car), so the mode takes its targets from change detection alone. Each frame is
// compared with its registered neighbours before and after (change.baseline_s is one frame at
// these rates), the blobs of every size up to a lorry are kept, and a blob tracker with a
// motion model and gates that follow a plausible top speed on the ground links them. The feature
// tracks still give the ground motion and the key frames.
struct LowFrameRateOptions {
  enum class Mode { kAuto, kOn, kOff };
  Mode mode = Mode::kAuto;
  // kAuto: the mode runs for videos of fewer frames a second than this. At 5 frames a second it
  // finds much more than the feature targets, at 10 about as much, at 25 less (tuning seeds,
  // 2026-11-29; docs/front-end.md, Low frame rates).
  double below_fps = 8;
  // The edges of the view, which the frames before and after do not both see, are compared with
  // the two frames before or the two after (ChangeOptions::one_sided_edges).
  bool one_sided_edges = true;
  // The change detector's baseline (ChangeOptions::baseline_s) is at least this long in the mode:
  // at 5 frames a second 3 frames instead of 2 (0.48 s), where a walker moves 1.4 px a frame and
  // left too little change over two. Tuning seeds of `nadir-5fps`: precision / recall 0.959 /
  // 0.847 with 2 frames, 0.970 / 0.918 with 3, 0.917 / 0.929 with 4 (2 fps: 1 frame either way;
  // 2 frames took it from 0.930 / 0.908 to 0.874 / 0.898).
  double min_baseline_s = 0.6;
  // The change detector's registration allowance in the mode (ChangeOptions::registration_px):
  // frames half a second or more apart differ by more parallax and interpolation than frames
  // at video rates; 0.2 px there raised the false tracks (tuning seeds: 1 fps orbit precision
  // 0.843 -> 0.772, 5 fps 0.970 -> 0.936) for little recall.
  double registration_px = 0.3;
  track::BlobTrackOptions blobs = LowFrameRateBlobs();
  Status Validate() const;
  // The blob tracker's options in the mode: a car moves tens of pixels between frames and its
  // changed part (the leading edge of a slow one) is a few pixels off its centre.
  static track::BlobTrackOptions LowFrameRateBlobs();
};
const char* LowFrameRateModeName(LowFrameRateOptions::Mode mode);
// "auto", "on" or "off"; nullopt for anything else.
std::optional<LowFrameRateOptions::Mode> ParseLowFrameRateMode(const std::string& text);

struct FrontEndOptions {
  track::TrackerOptions tracker;
  track::SegmentationOptions segmentation;
  track::TargetTrackOptions targets;
  track::HomographyOptions frame_homography;  // frame to frame, from stationary tracks
  track::KeyFrameOptions key_frames;
  track::ChangeOptions change;  // change detection (enabled by default)
  track::BlobTrackOptions change_tracks;
  // A target track needs a change under at least this fraction of the observations where the
  // change detector could look (a corner sliding along a road marking has none); 0 turns it off.
  double min_change_support = 0.5;
  // Change-only tracks beside a car, and pieces of a car beside its longer track, are dropped.
  track::ChangeEchoOptions change_echoes;
  // Screen-fixed overlays (HUD text, reticles, logos), found from the change detector's evidence
  // and kept out of the ground motion, the change tracks and the targets (docs/front-end.md,
  // "Overlays").
  track::OverlayOptions overlays;
  // Low oblique views: the sky above the horizon and the distant ground just below it, found in
  // the image and kept out of the ground motion, the key frames, the change tracks and the targets
  // (docs/front-end.md, "Oblique views").
  track::HorizonOptions horizon;
  LowFrameRateOptions low_frame_rate;
  bool parallax_check = true;    // estimate the epipole (fundamental matrix) for the MTI test
  int min_parallax_points = 20;  // matches on F but off the ground plane needed to use F's epipole
  int queue_frames = 6;          // decoded frames waiting for the tracker, at most
  int change_queue_frames = 8;   // frames waiting for the change detection thread, at most (its
                                 // answers are taken 8 frames late: more than 8 changes nothing)
  int key_frame_image_width = 640;  // width of the picture kept per key frame (0: none)
  // Keep the key frames' chroma when the video is colour (8-bit YUV), for a colour mosaic: the
  // chroma planes are copied from the decoder (half the luma's bytes for 4:2:0) and a key frame's
  // picture costs half a grey one more. Off, or on grey video: grey pictures.
  bool key_frame_colour = true;
  int decoder_threads = 0;  // 0 = automatic
  // How frames are tied to their KLV metadata: the tolerances, and whether packets that failed
  // their checksum may be used (not by default).
  ingest::AlignmentOptions metadata;
  // The process's resident memory allowed while the front end runs, MiB (0: no limit; the
  // pipeline and saker-cli default to util's DefaultMemoryLimitMiB). Beyond it the front end stops
  // with a ResourceExhausted error that names the video and the frame, rather than let the
  // machine run out of memory. Checked before decoding (the memory in use plus
  // FramePipelineBytes() for the video's picture size must fit), then every 25 frames of 720p
  // (every frame from 23 megapixels on, 8K).
  int64_t max_memory_mib = 0;
  // Called on the calling thread with each new key frame (needs key_frame_image_width > 0).
  std::function<void(const KeyFramePreview&)> on_key_frame;
  // Checkpoints (FrontEndCheckpoint): at a key frame once this many seconds have passed since
  // the previous checkpoint (0: at every key frame), and at the end. An error returned by
  // `on_checkpoint` (a full disk) stops the front end with that error.
  double checkpoint_interval_s = 30;
  std::function<Status(const FrontEndCheckpoint&)> on_checkpoint;
  // Resuming from a checkpoint without the trackers' state (one of an older Saker), the run starts
  // tracking this long before the checkpoint's key frame (at least 10 frames), so that the
  // trackers are nearly as warm there as in a run that never stopped. A checkpoint with the state
  // needs no warm-up.
  double resume_warmup_s = 4;
  Status Validate() const;

  // What the reader and the trackers run with, derived from the fields above rather than set by
  // the caller. The reader decodes grey frames only, with `decoder_threads`. The feature tracker
  // keeps live tracks only, each with its latest two positions (all the front end looks at); a
  // target that ends waits for the change evidence of its last frames when change detection is on
  // (that evidence comes late, docs/front-end.md "Threads"); for a video of `fps` frames a second
  // in the low-frame-rate mode, no gap is filled.
  video::ReaderOptions EffectiveReader() const;
  // The feature tracker for a video of `rate`: no finished tracks, and only the history the
  // still features' window reads (OverlayOptions::still_window_s).
  track::TrackerOptions EffectiveTracker(track::FrameRate rate) const;
  track::TargetTrackOptions EffectiveTargets(double fps) const;
  // Whether the low-frame-rate mode runs for a video of `fps` frames a second (a rate the video
  // does not give counts as 25); it needs change detection.
  bool LowFrameRateFor(double fps) const;
  // The change detection and blob tracks for a video of `fps`: the mode's when it runs.
  track::ChangeOptions EffectiveChange(double fps) const;
  track::BlobTrackOptions EffectiveChangeTracks(double fps) const;
  // The fixed motion thresholds alone, as tuned on clean video, none raised by the video's
  // measured noise (SegmentationOptions::noise_multiple, ChangeOptions::measured_*): for
  // measuring what the measuring gains or costs.
  void UseFixedThresholds();
  // The most memory the decoder and the frame queues can hold for pictures of `width` x `height`,
  // bytes: the decoder's pictures (4:2:0, up to 16 references, one being decoded and one per
  // decoder thread) and the grey frames queued for the tracker and change detection or held
  // until change detection answers. An upper bound, so that the limit is never overshot.
  int64_t FramePipelineBytes(int width, int height) const;
};

// What the front end found about one frame.
struct FrameResult {
  int64_t index = 0;
  double time_s = 0;
  int64_t pts = 0;             // in the video stream's time base, as video::Frame::pts
  bool key_frame = false;      // a key frame of the video stream (random access seeks to these)
  bool homography_ok = false;  // current_from_previous is valid (never for a segment's first frame)
  Eigen::Matrix3d current_from_previous = Eigen::Matrix3d::Identity();
  track::HomographyCovariance covariance = track::HomographyCovariance::Zero();
  int tracked = 0;  // live feature tracks
  int inliers = 0;  // stationary correspondences supporting the homography
  int moving = 0;   // features labelled moving
  // A low oblique view's sky mask in this frame: the pixels above this line (the horizon, moved
  // down by the mask's margin) were left out as sky and distant ground (HorizonTracker).
  std::optional<track::HorizonLine> sky_line;
};

// Time spent per frame in each stage (milliseconds, averaged), and the whole run.
struct FrontEndTiming {
  double decode_ms = 0;  // on the decode thread (overlaps the rest)
  double track_ms = 0;
  double homography_ms = 0;     // frame to frame + fundamental
  double segment_ms = 0;        // motion segmentation and target tracks
  double change_ms = 0;         // change detection, on its own thread (overlaps the rest)
  double change_tracks_ms = 0;  // blob tracks and the targets' change evidence
  double change_wait_ms = 0;    // the calling thread waiting for the change detection thread
  double key_frames_ms = 0;
  double wall_s = 0;
  int64_t frames = 0;
};

// See FrontEndResult::noise.
struct VideoNoise {
  int64_t feature_frames = 0;  // frames whose feature-motion thresholds were raised
  int64_t change_frames = 0;   // change answers whose allowances were raised
  // The largest thresholds used: stage 1's motion (pixels over SegmentationOptions::short_s),
  // the change detector's noise (grey levels) and misregistration (pixels).
  double residual_threshold_px = 0, change_noise_grey = 0, change_registration_px = 0;
  bool raised() const { return feature_frames > 0 || change_frames > 0; }
};

struct FrontEndResult {
  video::VideoInfo video;
  std::vector<FrameResult> frames;
  std::vector<track::KeyFrame> key_frames;
  std::vector<KeyFrameImage> key_frame_images;
  std::vector<track::SequentialLink> links;
  std::vector<track::ChainBreak> breaks;
  std::vector<track::TargetTrack> targets;  // confirmed target tracks, by id
  // The screen-fixed overlay masks, in frame order: each applies to its frames, within one chain
  // segment; frames that no mask covers had none found. A resumed run has those from the
  // checkpoint's key frame on only.
  std::vector<track::OverlayMask> overlays;
  // The frames at which a thermal camera switched polarity (white-hot to black-hot or back); the
  // front end inverted the frames from each back to the first frame's polarity
  // (track::PolarityWatch), so the chain goes on across it.
  std::vector<int64_t> polarity_switches;
  bool low_frame_rate = false;  // the low-frame-rate mode ran (LowFrameRateOptions)
  // Frames of this run whose sky and distant ground above the horizon were masked (a resumed run
  // counts from its resume).
  int64_t horizon_frames = 0;
  // How much the video's own noise (heavy compression, sensor noise) raised the motion tests'
  // thresholds above their fixed values (SegmentationOptions::noise_multiple,
  // ChangeOptions::measured_noise_multiple); a resumed run counts from its resume.
  VideoNoise noise;
  // The same pass's KLV: packets, per-frame metadata (scan.MetadataOf(frame)), warnings.
  ingest::VideoScan scan;
  FrontEndTiming timing;
};

// What the front end has done by a key frame, so that an interrupted job resumes from there
// rather than starting again (docs/reliability.md, "Resume"). The front end hands out each
// checkpoint as what is new since its previous one (`frames` ... `change_targets`, to be appended
// in order) plus its open targets and state, which replace the previous ones; Append() merges the
// deliveries into the whole checkpoint that RunFrontEnd resumes from.
struct FrontEndCheckpoint {
  int64_t through_frame = -1;  // frames [0, through_frame] are done; a key frame unless complete
  bool complete = false;       // the whole video is done; `targets` are the final ones then
  std::vector<FrameResult> frames;
  std::vector<track::KeyFrame> key_frames;
  std::vector<KeyFramePreview> key_frame_images;  // in key frame order; may be empty
  std::vector<track::SequentialLink> links;
  std::vector<track::ChainBreak> breaks;
  std::vector<track::TargetTrack> targets;         // finished ones found by feature tracks
  std::vector<track::TargetTrack> change_targets;  // finished ones found by change detection
  // Replaced at every checkpoint: the confirmed targets still followed at `through_frame`, cut
  // there (a resumed run joins them to its own continuations), and the last frame whose change
  // evidence had been applied.
  std::vector<track::TargetTrack> open_targets;
  std::vector<track::TargetTrack> open_change_targets;
  int64_t change_through_frame = -1;
  // Replaced at every checkpoint: the trackers' state after `through_frame` (feature tracks,
  // motion labels, targets followed, change tracks), so that a resumed run goes on exactly as the
  // first would have. Empty in a checkpoint of an older Saker: a run resumed from it warms its
  // trackers up again before the checkpoint, and its targets may differ near the seam.
  std::vector<uint8_t> state;

  // Appends the next delivery of the same run (or of its resumption).
  void Append(FrontEndCheckpoint next);
  // InvalidArgument unless the parts fit together: frames 0..through_frame in order, key frame
  // ids 0, 1, ... on those frames, links and images between known key frames.
  Status Validate() const;
};

// Runs the front end over a whole video. Fails when the video cannot be opened or decoded;
// frames without a usable homography are chain breaks, not errors. `job` may cancel.
// `resume`: carry on from this checkpoint of an earlier run on the same video with the same
// options. The video is decoded from its start again (the KLV scan needs every frame) but
// frames before the checkpoint are only decoded, apart from the warm-up; the result is that of
// one run, up to the seam at the checkpoint's key frame (docs/reliability.md).
StatusOr<FrontEndResult> RunFrontEnd(const std::string& path, const FrontEndOptions& options,
                                     JobContext* job = nullptr,
                                     const FrontEndCheckpoint* resume = nullptr);

// The same on a video the caller has opened already, with options.EffectiveReader(), and not yet
// read from (a job that read its size and rate first does not open it again): the front end takes
// the reader and decodes with it. Errors name the reader's path.
StatusOr<FrontEndResult> RunFrontEnd(std::unique_ptr<video::VideoReader> reader,
                                     const FrontEndOptions& options, JobContext* job = nullptr,
                                     const FrontEndCheckpoint* resume = nullptr);

}  // namespace saker::frontend
