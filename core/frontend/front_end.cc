#include "core/frontend/front_end.h"

#include "core/util/check.h"

#include <opencv2/imgproc.hpp>

#include <chrono>
#include <condition_variable>
#include <deque>
#include <mutex>
#include <optional>
#include <thread>
#include <unordered_set>

namespace saker::frontend {
namespace {

using Clock = std::chrono::steady_clock;

double MillisecondsSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

// A bounded queue of decoded frames between the decode thread and the tracker.
class FrameQueue {
 public:
  explicit FrameQueue(size_t capacity) : capacity_(capacity) {}

  // Blocks while full; false when the consumer has stopped.
  bool Push(video::Frame frame) {
    std::unique_lock<std::mutex> lock(mutex_);
    not_full_.wait(lock, [&] { return frames_.size() < capacity_ || stopped_; });
    if (stopped_) return false;
    frames_.push_back(std::move(frame));
    not_empty_.notify_one();
    return true;
  }
  // The producer is done (end of video or an error).
  void Close(Status status) {
    std::lock_guard<std::mutex> lock(mutex_);
    closed_ = true;
    status_ = std::move(status);
    not_empty_.notify_all();
  }
  // Blocks while empty; nullopt at the end.
  std::optional<video::Frame> Pop() {
    std::unique_lock<std::mutex> lock(mutex_);
    not_empty_.wait(lock, [&] { return !frames_.empty() || closed_; });
    if (frames_.empty()) return std::nullopt;
    video::Frame frame = std::move(frames_.front());
    frames_.pop_front();
    not_full_.notify_one();
    return frame;
  }
  // The consumer gives up (cancel or error): unblocks the producer.
  void Stop() {
    std::lock_guard<std::mutex> lock(mutex_);
    stopped_ = true;
    not_full_.notify_all();
  }
  Status status() {
    std::lock_guard<std::mutex> lock(mutex_);
    return status_;
  }

 private:
  size_t capacity_;
  std::mutex mutex_;
  std::condition_variable not_full_, not_empty_;
  std::deque<video::Frame> frames_;
  bool closed_ = false;
  bool stopped_ = false;
  Status status_;
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
  const int needed = std::max(options.min_parallax_points, int(ground.size() / 20));
  if (off_plane < needed) return std::nullopt;
  return f->epipole_target;
}

// The targets of the feature tracks, less those the image does not support, and those of change
// detection; pieces of one object joined, and numbered 1, 2, ... in order of appearance.
std::vector<track::TargetTrack> CombineTargets(std::vector<track::TargetTrack> by_features,
                                               std::vector<track::TargetTrack> by_change,
                                               const FrontEndOptions& options) {
  std::vector<track::TargetTrack> all;
  for (track::TargetTrack& t : by_features) {
    if (track::SupportedByChange(t, options.min_change_support)) all.push_back(std::move(t));
  }
  for (track::TargetTrack& t : by_change) all.push_back(std::move(t));
  std::stable_sort(all.begin(), all.end(), [](const auto& a, const auto& b) {
    return a.observations.front().frame < b.observations.front().frame;
  });
  for (size_t i = 0; i < all.size(); ++i) all[i].id = track::TargetTrackId(int64_t(i) + 1);
  all = track::LinkFragments(std::move(all), options.targets);
  for (size_t i = 0; i < all.size(); ++i) all[i].id = track::TargetTrackId(int64_t(i) + 1);
  return all;
}

}  // namespace

Status FrontEndOptions::Validate() const {
  SAKER_RETURN_IF_ERROR(tracker.Validate());
  SAKER_RETURN_IF_ERROR(segmentation.Validate());
  SAKER_RETURN_IF_ERROR(targets.Validate());
  SAKER_RETURN_IF_ERROR(frame_homography.Validate());
  SAKER_RETURN_IF_ERROR(key_frames.Validate());
  SAKER_RETURN_IF_ERROR(change.Validate());
  SAKER_RETURN_IF_ERROR(change_tracks.Validate());
  if (!(min_change_support >= 0 && min_change_support <= 1)) {
    return InvalidArgumentError("front end: the change support fraction must be in [0, 1]");
  }
  if (queue_frames < 1 || queue_frames > 256) {
    return InvalidArgumentError("front end: the frame queue must hold 1..256 frames");
  }
  if (key_frame_image_width < 0) {
    return InvalidArgumentError("front end: the key frame image width must be >= 0");
  }
  return Status::Ok();
}

StatusOr<FrontEndResult> RunFrontEnd(const std::string& path, const FrontEndOptions& options_in,
                                     JobContext* job) {
  SAKER_RETURN_IF_ERROR(options_in.Validate());
  FrontEndOptions options = options_in;
  // The front end needs live tracks only, and of each only its latest positions.
  options.tracker.keep_finished = false;
  options.tracker.max_history = 2;

  // The scan decodes every frame and every KLV packet in one pass on the decode thread; the
  // frames go through the queue, the metadata is tied to the frames when the scan ends.
  ingest::ScanOptions scan_options;
  scan_options.reader.want_bgr = false;
  scan_options.reader.want_grey = true;
  scan_options.reader.decoder_threads = options.decoder_threads;
  FrontEndResult result;
  {
    // Opened here first so that a bad file fails at once, with the reader's message.
    SAKER_ASSIGN_OR_RETURN(std::unique_ptr<video::VideoReader> probe,
                           video::VideoReader::Open(path, scan_options.reader));
    result.video = probe->info();
  }
  // For progress only: the declared count, else duration x rate.
  double expected_frames = double(result.video.declared_frame_count);
  if (expected_frames <= 0) expected_frames = result.video.duration_s * result.video.fps;
  expected_frames = std::max(1.0, expected_frames);

  FrameQueue queue(size_t(options.queue_frames));
  double decode_ms = 0;
  JobContext decode_job;  // cancelled when the consumer stops early
  StatusOr<ingest::VideoScan> scan = CancelledError("front end: the scan did not run");
  std::thread decoder([&] {
    auto start = Clock::now();
    scan = ingest::ScanVideo(path, scan_options, &decode_job, [&](const video::Frame& frame) {
      video::Frame copy = frame;
      copy.grey = frame.grey.clone();  // the reader reuses its buffers
      decode_ms += MillisecondsSince(start);
      if (!queue.Push(std::move(copy))) decode_job.RequestCancel();
      start = Clock::now();
    });
    queue.Close(scan.ok() ? Status::Ok() : scan.status());
  });
  // Whatever happens below, the decode thread is stopped and joined.
  struct Joiner {
    FrameQueue& queue;
    JobContext& job;
    std::thread& thread;
    ~Joiner() {
      job.RequestCancel();
      queue.Stop();
      while (queue.Pop()) {
      }
      if (thread.joinable()) thread.join();
    }
  } joiner{queue, decode_job, decoder};

  track::FeatureTracker tracker(options.tracker);
  track::MotionSegmenter segmenter(options.segmentation);
  track::TargetTracker targets(options.targets);
  track::KeyFrameChain chain(options.key_frames);
  track::ChangeDetector change(options.change);
  track::BlobTracker change_tracks(options.change_tracks);
  std::vector<track::TargetTrack> targets_by_change;
  FrontEndTiming& timing = result.timing;
  const auto wall_start = Clock::now();
  bool segment_open = false;

  while (std::optional<video::Frame> frame = queue.Pop()) {
    if (job != nullptr && job->IsCancelled()) return CancelledError("front end: cancelled");
    FrameResult fr;
    fr.index = frame->index;
    fr.time_s = frame->time_s;

    auto start = Clock::now();
    tracker.Process(frame->index, frame->grey);
    timing.track_ms += MillisecondsSince(start);
    fr.tracked = int(tracker.points().size());

    // Ground motion from the tracks that are not (yet) known to move.
    start = Clock::now();
    std::vector<track::Correspondence> ground;
    ground.reserve(tracker.matches().size());
    for (const track::Correspondence& m : tracker.matches()) {
      if (segmenter.LabelOf(m.id) != track::MotionLabel::kMoving) ground.push_back(m);
    }
    std::optional<track::HomographyEstimate> estimate;
    if (segment_open && !ground.empty()) {
      StatusOr<track::HomographyEstimate> h =
          track::EstimateHomography(ground, options.frame_homography);
      if (h.ok()) estimate = std::move(h).value();
    }
    std::optional<Eigen::Vector3d> epipole;
    if (estimate && options.parallax_check) epipole = ParallaxEpipole(ground, *estimate, options);
    timing.homography_ms += MillisecondsSince(start);

    start = Clock::now();
    if (estimate) {
      fr.homography_ok = true;
      fr.current_from_previous = estimate->target_from_source;
      fr.covariance = estimate->covariance;
      fr.inliers = int(estimate->inliers.size());
      segmenter.AddFrame(tracker.matches(), estimate->target_from_source, epipole);
      targets.AddFrame(frame->index, segmenter.moving());
      fr.moving = int(segmenter.moving().size());
    } else if (segment_open) {
      // No reliable ground motion (blank, featureless, a cut): the chain breaks here; the next
      // frame starts afresh.
      segmenter.Reset();
      targets.FinishAll();
      tracker.Reset();
      tracker.Process(frame->index, frame->grey);
    }
    for (track::TargetTrack& t : targets.TakeFinished()) result.targets.push_back(std::move(t));
    timing.segment_ms += MillisecondsSince(start);

    // Change detection: small movers, and what the image shows under each target.
    start = Clock::now();
    if (options.change.enabled) {
      std::optional<Eigen::Matrix3d> motion;
      if (estimate) motion = estimate->target_from_source;
      change.Process(frame->index, frame->grey, motion);
      if (!estimate) change_tracks.FinishAll();
      if (change.frame() >= 0) {
        change_tracks.AddFrame(change.frame(), change.blobs(), change.frame_motion());
        // Within the target's box, and a few pixels round a single point.
        targets.RecordChange(change.frame(), [&](const track::TargetObservation& o) {
          if (!change.Compared(o.position)) return track::ChangeEvidence::kNotLooked;
          const double radius = std::max(3.0, 0.5 * (o.box_max - o.box_min).maxCoeff());
          return change.ChangedNear(o.position, radius) ? track::ChangeEvidence::kChanged
                                                        : track::ChangeEvidence::kNone;
        });
      }
      for (track::TargetTrack& t : change_tracks.TakeFinished()) {
        targets_by_change.push_back(std::move(t));
      }
    }
    timing.change_ms += MillisecondsSince(start);

    // Key frames from the stationary points.
    start = Clock::now();
    std::vector<track::StationaryPoint> stationary;
    stationary.reserve(tracker.points().size());
    for (const track::TrackedPoint& p : tracker.points()) {
      if (segmenter.LabelOf(p.id) != track::MotionLabel::kMoving)
        stationary.emplace_back(p.id, p.position);
    }
    const size_t key_frames_before = chain.key_frames().size();
    chain.AddFrame(frame->index, stationary, estimate);
    if (chain.key_frames().size() > key_frames_before && options.key_frame_image_width > 0) {
      const track::KeyFrame& key = chain.key_frames().back();
      KeyFrameImage image;
      image.id = key.id;
      image.frame_index = key.frame_index;
      image.scale = std::max(1.0, double(frame->grey.cols) / options.key_frame_image_width);
      cv::resize(frame->grey, image.grey, cv::Size(), 1.0 / image.scale, 1.0 / image.scale,
                 cv::INTER_AREA);
      result.key_frame_images.push_back(std::move(image));
    }
    timing.key_frames_ms += MillisecondsSince(start);
    segment_open = fr.tracked > 0;

    result.frames.push_back(fr);
    ++timing.frames;
    if (job != nullptr) {
      job->ReportProgress("front end",
                          std::min(1.0, double(result.frames.size()) / expected_frames));
    }
  }
  SAKER_RETURN_IF_ERROR(queue.status());
  decoder.join();
  SAKER_RETURN_IF_ERROR(scan.status());
  result.scan = std::move(scan).value();
  SAKER_CHECK(result.scan.frames.size() == result.frames.size())
      << "the scan saw " << result.scan.frames.size() << " frames, the tracker "
      << result.frames.size();
  targets.FinishAll();
  for (track::TargetTrack& t : targets.TakeFinished()) result.targets.push_back(std::move(t));
  change_tracks.FinishAll();
  for (track::TargetTrack& t : change_tracks.TakeFinished()) {
    targets_by_change.push_back(std::move(t));
  }
  result.targets = CombineTargets(std::move(result.targets), std::move(targets_by_change), options);
  result.key_frames = chain.key_frames();
  result.links = chain.links();
  result.breaks = chain.breaks();
  timing.wall_s = MillisecondsSince(wall_start) / 1000.0;
  const double n = double(std::max<int64_t>(1, timing.frames));
  timing.decode_ms = decode_ms / n;
  timing.track_ms /= n, timing.homography_ms /= n, timing.segment_ms /= n, timing.change_ms /= n,
      timing.key_frames_ms /= n;
  return result;
}

}  // namespace saker::frontend
