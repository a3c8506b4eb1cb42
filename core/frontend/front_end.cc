#include "core/frontend/front_end.h"

#include "core/util/check.h"
#include "core/util/memory.h"

#include <Eigen/LU>
#include <opencv2/imgproc.hpp>

#include <chrono>
#include <condition_variable>
#include <deque>
#include <exception>
#include <limits>
#include <mutex>
#include <optional>
#include <sstream>
#include <thread>
#include <unordered_set>

namespace saker::frontend {
namespace {

using Clock = std::chrono::steady_clock;

// Change detection answers are applied this many frames after their frame was submitted (see
// RunFrontEnd): the change thread may fall this far behind before the calling thread waits for it.
// An answer belongs to the frame the longest baseline before the one submitted, so the change
// evidence of frame m reaches the targets after frame m + longest baseline + this lag (20 frames
// with the default baseline of 12: still within the 25 frames a target lives on unseen).
constexpr int64_t kChangeLagFrames = 8;
// How often the memory limit is checked: reading /proc costs about 10 us.
constexpr int64_t kMemoryCheckFrames = 25;

double MillisecondsSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

// A bounded queue between two threads. The producer pushes (blocking while the queue is full)
// and closes it with a status when done; the consumer pops (blocking while it is empty) until it
// is closed and empty. Either side may cancel: blocked calls return at once, what is queued is
// dropped, and later pushes and pops fail.
template <typename T>
class BoundedQueue {
 public:
  explicit BoundedQueue(size_t capacity) : capacity_(capacity) {}

  // Blocks while full; false once cancelled.
  bool Push(T item) {
    std::unique_lock<std::mutex> lock(mutex_);
    not_full_.wait(lock, [&] { return items_.size() < capacity_ || cancelled_; });
    if (cancelled_) return false;
    items_.push_back(std::move(item));
    not_empty_.notify_one();
    return true;
  }
  // The producer is done (end of the input, or an error).
  void Close(Status status = Status::Ok()) {
    std::lock_guard<std::mutex> lock(mutex_);
    closed_ = true;
    status_ = std::move(status);
    not_empty_.notify_all();
  }
  // Blocks while empty; nullopt at the end (closed and empty) or once cancelled.
  std::optional<T> Pop() {
    std::unique_lock<std::mutex> lock(mutex_);
    not_empty_.wait(lock, [&] { return !items_.empty() || closed_ || cancelled_; });
    if (cancelled_ || items_.empty()) return std::nullopt;
    T item = std::move(items_.front());
    items_.pop_front();
    not_full_.notify_one();
    return item;
  }
  // Either side gives up (cancel, error): unblocks the other.
  void Cancel() {
    std::lock_guard<std::mutex> lock(mutex_);
    cancelled_ = true;
    items_.clear();
    not_full_.notify_all();
    not_empty_.notify_all();
  }
  Status status() {
    std::lock_guard<std::mutex> lock(mutex_);
    return status_;
  }

 private:
  size_t capacity_;
  std::mutex mutex_;
  std::condition_variable not_full_, not_empty_;
  std::deque<T> items_;
  bool closed_ = false;
  bool cancelled_ = false;
  Status status_;
};

// Change detection on a thread of its own. The calling thread submits every frame and takes the
// answers back, one per frame submitted, in the same order. A frame's grey image is shared, not
// copied: the decode thread made it for this frame alone, and nobody writes to it afterwards.
// An exception on the change thread (a failed check) is rethrown on the calling thread.
// The caller takes answers at a fixed lag (RunFrontEnd), so at most `lag_frames` + 1 frames are
// ever outstanding and the answer queue, that long, never holds the change thread up.
class ChangeThread {
 public:
  struct Answer {
    int64_t submitted = 0;      // the frame submitted
    bool restart = false;       // it came without ground motion: the comparison started again
    track::ChangeFrame change;  // the answer (for the frame the longest baseline earlier)
    double ms = 0;              // time the change thread spent on it
  };

  ChangeThread(const track::ChangeOptions& options, size_t queue_frames, size_t lag_frames)
      : inputs_(queue_frames), answers_(lag_frames + 1) {
    thread_ = std::thread([this, options] { Run(options); });
  }
  // Stops the thread (it finishes the frame in hand) and joins it.
  ~ChangeThread() {
    inputs_.Cancel();
    answers_.Cancel();
    thread_.join();
  }
  ChangeThread(const ChangeThread&) = delete;
  ChangeThread& operator=(const ChangeThread&) = delete;

  // Frames must increase. Blocks while the queue is full.
  void Submit(int64_t frame, cv::Mat grey, std::optional<Eigen::Matrix3d> motion) {
    SAKER_CHECK(outstanding_.empty() || frame > outstanding_.back());
    const auto start = Clock::now();
    const bool pushed = inputs_.Push({frame, std::move(grey), std::move(motion)});
    wait_ms_ += MillisecondsSince(start);
    if (!pushed) RethrowOrFail();
    outstanding_.push_back(frame);
  }
  // The answer to the oldest frame submitted and not yet taken, when that frame is at most
  // `frame` (blocking until the answer is ready); otherwise nullopt, at once.
  std::optional<Answer> NextThrough(int64_t frame) {
    if (outstanding_.empty() || outstanding_.front() > frame) return std::nullopt;
    const auto start = Clock::now();
    std::optional<Answer> answer = answers_.Pop();
    wait_ms_ += MillisecondsSince(start);
    if (!answer) RethrowOrFail();
    SAKER_CHECK(answer->submitted == outstanding_.front());
    outstanding_.pop_front();
    return answer;
  }
  // Time the calling thread spent waiting in Submit and NextThrough, milliseconds.
  double wait_ms() const { return wait_ms_; }

 private:
  struct Input {
    int64_t frame = 0;
    cv::Mat grey;
    std::optional<Eigen::Matrix3d> motion;
  };

  void Run(const track::ChangeOptions& options) {
    try {
      track::ChangeDetector detector(options);
      while (std::optional<Input> input = inputs_.Pop()) {
        const auto start = Clock::now();
        Answer answer;
        answer.submitted = input->frame;
        answer.restart = !input->motion;
        answer.change = detector.Process(input->frame, input->grey, input->motion);
        input.reset();  // the frame is no longer needed here
        answer.ms = MillisecondsSince(start);
        if (!answers_.Push(std::move(answer))) return;
      }
    } catch (...) {
      error_ = std::current_exception();  // published by the queues' locks below
      inputs_.Cancel();
    }
    answers_.Close();
  }
  [[noreturn]] void RethrowOrFail() {
    if (error_) std::rethrow_exception(error_);
    throw CheckError("front end: the change detection thread stopped early");
  }

  BoundedQueue<Input> inputs_;
  BoundedQueue<Answer> answers_;
  std::exception_ptr error_;         // set by the change thread before it closes answers_
  std::deque<int64_t> outstanding_;  // frames submitted whose answers are not taken yet
  double wait_ms_ = 0;
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
  if (change_queue_frames < 1 || change_queue_frames > 256) {
    return InvalidArgumentError("front end: the change detection queue must hold 1..256 frames");
  }
  if (max_memory_mib < 0) {
    return InvalidArgumentError("front end: the memory limit must be >= 0 MiB (0: none)");
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
  // A target that ends waits for the change evidence of its last frames (it comes late).
  options.targets.wait_for_change = options.change.enabled;

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

  BoundedQueue<video::Frame> queue(size_t(options.queue_frames));
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
    BoundedQueue<video::Frame>& queue;
    JobContext& job;
    std::thread& thread;
    ~Joiner() {
      job.RequestCancel();
      queue.Cancel();
      if (thread.joinable()) thread.join();
    }
  } joiner{queue, decode_job, decoder};

  track::FeatureTracker tracker(options.tracker);
  track::MotionSegmenter segmenter(options.segmentation);
  track::TargetTracker targets(options.targets);
  track::KeyFrameChain chain(options.key_frames);
  track::BlobTracker change_tracks(options.change_tracks);
  std::vector<track::TargetTrack> targets_by_change;
  FrontEndTiming& timing = result.timing;
  const auto wall_start = Clock::now();
  bool segment_open = false;

  // Change detection runs on its own thread (its destructor stops and joins it, whatever happens
  // below). Its answers are applied at a fixed lag, so that the result never depends on how the
  // threads ran: once frame n is through segmentation, the answers for every frame up to
  // n - kChangeLagFrames are applied, waiting for them if need be; at a chain break every answer
  // up to the frame before it, at the end all of them. Applying an answer is what the
  // single-threaded front end did right after its frame: the blob tracks (ended first when the
  // frame had no ground motion), the change evidence of the targets, the finished blob tracks.
  std::optional<ChangeThread> change;
  if (options.change.enabled) {
    change.emplace(options.change, size_t(options.change_queue_frames), size_t(kChangeLagFrames));
  }
  double change_side_ms = 0;  // the calling thread's time for change detection (waits included)
  const auto apply_change_through = [&](int64_t frame) {
    if (!change) return;
    const auto start = Clock::now();
    while (std::optional<ChangeThread::Answer> answer = change->NextThrough(frame)) {
      const auto apply_start = Clock::now();
      if (answer->restart) change_tracks.FinishAll();
      const track::ChangeFrame& c = answer->change;
      if (c.answered()) {
        change_tracks.AddFrame(c.frame, c.blobs, c.frame_motion);
        // Within the target's box, and a few pixels round a single point.
        targets.RecordChange(c.frame, [&](const track::TargetObservation& o) {
          if (!c.Compared(o.position)) return track::ChangeEvidence::kNotLooked;
          const double radius = std::max(3.0, 0.5 * (o.box_max - o.box_min).maxCoeff());
          return c.ChangedNear(o.position, radius) ? track::ChangeEvidence::kChanged
                                                   : track::ChangeEvidence::kNone;
        });
      }
      for (track::TargetTrack& t : change_tracks.TakeFinished()) {
        targets_by_change.push_back(std::move(t));
      }
      timing.change_ms += answer->ms;
      timing.change_tracks_ms += MillisecondsSince(apply_start);
    }
    change_side_ms += MillisecondsSince(start);
  };

  // The placement of the current frame in the preview (KeyFramePreview): the first frame's pixels.
  Eigen::Matrix3d preview_from_current = Eigen::Matrix3d::Identity();
  while (std::optional<video::Frame> frame = queue.Pop()) {
    if (job != nullptr && job->IsCancelled()) return CancelledError("front end: cancelled");
    if (options.max_memory_mib > 0 && frame->index % kMemoryCheckFrames == 0) {
      const int64_t resident_mib = ResidentMemoryBytes() / (1024 * 1024);
      if (resident_mib > options.max_memory_mib) {
        std::ostringstream message;
        message.setf(std::ios::fixed);
        message.precision(1);
        message << path << ": processing stopped at frame " << frame->index << " (" << frame->time_s
                << " s): Saker is using " << resident_mib << " MiB, over its memory limit of "
                << options.max_memory_mib
                << " MiB. Process a shorter part of the video or raise the limit (--max-memory).";
        return ResourceExhaustedError(message.str());
      }
    }
    FrameResult fr;
    fr.index = frame->index;
    fr.time_s = frame->time_s;
    fr.pts = frame->pts;
    fr.key_frame = frame->key_frame;

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

    // Change detection (small movers, and what the image shows under each target) starts on the
    // frame as soon as its ground motion is known.
    if (change) {
      start = Clock::now();
      std::optional<Eigen::Matrix3d> motion;
      if (estimate) motion = estimate->target_from_source;
      change->Submit(frame->index, frame->grey, motion);
      change_side_ms += MillisecondsSince(start);
    }

    start = Clock::now();
    const double change_side_before = change_side_ms;
    if (estimate) {
      preview_from_current = preview_from_current * estimate->target_from_source.inverse();
      preview_from_current /= preview_from_current(2, 2);
      fr.homography_ok = true;
      fr.current_from_previous = estimate->target_from_source;
      fr.covariance = estimate->covariance;
      fr.inliers = int(estimate->inliers.size());
      segmenter.AddFrame(tracker.matches(), estimate->target_from_source, epipole);
      targets.AddFrame(frame->index, segmenter.moving());
      fr.moving = int(segmenter.moving().size());
    } else if (segment_open) {
      // No reliable ground motion (blank, featureless, a cut): the chain breaks here; the next
      // frame starts afresh. The targets first take the change evidence of the segment's frames.
      apply_change_through(frame->index - 1);
      segmenter.Reset();
      targets.FinishAll();
      targets.EndChangeEvidence();  // the change detector starts again too
      tracker.Reset();
      tracker.Process(frame->index, frame->grey);
    }
    for (track::TargetTrack& t : targets.TakeFinished()) result.targets.push_back(std::move(t));
    timing.segment_ms += MillisecondsSince(start) - (change_side_ms - change_side_before);

    apply_change_through(frame->index - kChangeLagFrames);

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
      if (options.on_key_frame) options.on_key_frame({image, preview_from_current});
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
  apply_change_through(std::numeric_limits<int64_t>::max());
  targets.FinishAll();
  targets.EndChangeEvidence();
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
  if (change) timing.change_wait_ms = change->wait_ms();
  const double n = double(std::max<int64_t>(1, timing.frames));
  timing.decode_ms = decode_ms / n;
  timing.track_ms /= n, timing.homography_ms /= n, timing.segment_ms /= n, timing.change_ms /= n,
      timing.change_tracks_ms /= n, timing.change_wait_ms /= n, timing.key_frames_ms /= n;
  return result;
}

}  // namespace saker::frontend
