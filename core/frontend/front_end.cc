#include "core/frontend/front_end.h"

#include "core/frontend/change_thread.h"
#include "core/util/bounded_queue.h"
#include "core/util/check.h"
#include "core/util/memory.h"

#include <Eigen/LU>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <chrono>
#include <limits>
#include <optional>
#include <sstream>
#include <thread>
#include <unordered_map>
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
// detection; pieces of one object joined (a walker's across long gaps on the ground, followed
// through the frame-to-frame homographies), echoes of cars dropped (after the joining, so that a
// car's own change track has become part of it), and numbered 1, 2, ... in order of appearance.
std::vector<track::TargetTrack> CombineTargets(std::vector<track::TargetTrack> by_features,
                                               std::vector<track::TargetTrack> by_change,
                                               const std::vector<FrameResult>& frames,
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
  track::GroundMotion ground;
  for (const FrameResult& f : frames) ground.Add(f.index, f.homography_ok, f.current_from_previous);
  all = track::LinkFragments(std::move(all), options.targets, &ground);
  all = track::DropChangeEchoes(std::move(all), options.change_echoes);
  for (size_t i = 0; i < all.size(); ++i) all[i].id = track::TargetTrackId(int64_t(i) + 1);
  return all;
}

// Feature track ids of a resumed run start past every id in its checkpoint.
int64_t MaxFeatureId(const FrontEndCheckpoint& c) {
  int64_t max_id = 0;
  for (const track::KeyFrame& k : c.key_frames) {
    for (const track::StationaryPoint& p : k.points) max_id = std::max(max_id, int64_t(p.first));
  }
  for (const track::SequentialLink& l : c.links) {
    for (const track::Correspondence& m : l.correspondences) {
      max_id = std::max(max_id, int64_t(m.id));
    }
  }
  return max_id;
}

// Where a resumed run meets its checkpoint. What the resumed run's targets saw up to the seam
// belongs to the checkpoint's targets (finished there, or cut there and joined again by
// LinkFragments), so each is cut at the seam; only a target that no checkpoint target saw in the
// warm-up keeps its frames before the seam (one the first run had not confirmed yet).
class Seam {
 public:
  Seam(const FrontEndCheckpoint& checkpoint, int64_t warm_from,
       const track::TargetTrackOptions& options)
      : gate_px_(options.association_gate_px), min_frames_(options.min_frames) {
    for (const auto* list : {&checkpoint.targets, &checkpoint.change_targets,
                             &checkpoint.open_targets, &checkpoint.open_change_targets}) {
      for (const track::TargetTrack& t : *list) {
        for (const track::TargetObservation& o : t.observations) {
          if (o.frame >= warm_from) seen_[o.frame].push_back(o.position);
        }
      }
    }
  }

  // The part of `target` to keep, cut after frame `cut`, or nothing.
  std::optional<track::TargetTrack> Trim(track::TargetTrack target, int64_t cut) const {
    auto& obs = target.observations;
    const auto after =
        std::find_if(obs.begin(), obs.end(), [&](const auto& o) { return o.frame > cut; });
    if (after == obs.end()) return std::nullopt;
    const bool seen = std::any_of(obs.begin(), after, [&](const track::TargetObservation& o) {
      const auto it = seen_.find(o.frame);
      if (it == seen_.end()) return false;
      return std::any_of(it->second.begin(), it->second.end(), [&](const Eigen::Vector2d& p) {
        return (p - o.position).norm() <= gate_px_;
      });
    });
    if (!seen) return target;
    obs.erase(obs.begin(), after);
    if (int(obs.size()) < min_frames_) return std::nullopt;  // a stray end of a checkpoint target
    return target;
  }

 private:
  std::unordered_map<int64_t, std::vector<Eigen::Vector2d>> seen_;  // frame -> positions
  double gate_px_;
  int min_frames_;
};

}  // namespace

void FrontEndCheckpoint::Append(FrontEndCheckpoint next) {
  const auto append = [](auto& to, auto& from) {
    to.insert(to.end(), std::make_move_iterator(from.begin()), std::make_move_iterator(from.end()));
  };
  through_frame = next.through_frame;
  complete = next.complete;
  append(frames, next.frames);
  append(key_frames, next.key_frames);
  append(key_frame_images, next.key_frame_images);
  append(links, next.links);
  append(breaks, next.breaks);
  if (next.complete) {
    targets = std::move(next.targets);  // the final, combined targets
    change_targets.clear();
  } else {
    append(targets, next.targets);
    append(change_targets, next.change_targets);
  }
  open_targets = std::move(next.open_targets);
  open_change_targets = std::move(next.open_change_targets);
  change_through_frame = next.change_through_frame;
}

Status FrontEndCheckpoint::Validate() const {
  if (through_frame < 0 || frames.size() != size_t(through_frame) + 1) {
    return InvalidArgumentError("checkpoint: " + std::to_string(frames.size()) +
                                " frames for frames 0.." + std::to_string(through_frame));
  }
  for (size_t i = 0; i < frames.size(); ++i) {
    if (frames[i].index != int64_t(i)) {
      return InvalidArgumentError("checkpoint: frame " + std::to_string(i) + " is numbered " +
                                  std::to_string(frames[i].index));
    }
  }
  for (size_t i = 0; i < key_frames.size(); ++i) {
    const track::KeyFrame& k = key_frames[i];
    if (int64_t(k.id) != int64_t(i) || k.frame_index < 0 || k.frame_index > through_frame ||
        (i > 0 && (k.frame_index <= key_frames[i - 1].frame_index ||
                   k.segment < key_frames[i - 1].segment))) {
      return InvalidArgumentError("checkpoint: key frame " + std::to_string(i) +
                                  " is out of order or past the checkpoint");
    }
  }
  if (!complete && (key_frames.empty() || key_frames.back().frame_index != through_frame)) {
    return InvalidArgumentError("checkpoint: does not end at a key frame");
  }
  for (size_t i = 0; i < key_frame_images.size(); ++i) {
    const int64_t id = int64_t(key_frame_images[i].image.id);
    if (id < 0 || size_t(id) >= key_frames.size() ||
        (i > 0 && id <= int64_t(key_frame_images[i - 1].image.id))) {
      return InvalidArgumentError("checkpoint: image of unknown key frame " + std::to_string(id));
    }
  }
  for (const track::SequentialLink& l : links) {
    if (int64_t(l.from) < 0 || size_t(l.from) >= key_frames.size() || int64_t(l.to) < 0 ||
        size_t(l.to) >= key_frames.size()) {
      return InvalidArgumentError("checkpoint: a link between unknown key frames");
    }
  }
  return Status::Ok();
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
  if (resume_warmup_frames < 0) {
    return InvalidArgumentError("front end: the resume warm-up must be >= 0 frames");
  }
  return Status::Ok();
}

StatusOr<FrontEndResult> RunFrontEnd(const std::string& path, const FrontEndOptions& options_in,
                                     JobContext* job, const FrontEndCheckpoint* resume) {
  SAKER_RETURN_IF_ERROR(options_in.Validate());
  if (resume != nullptr) {
    const Status valid = resume->Validate();
    if (!valid.ok()) return InvalidArgumentError(path + ": cannot resume: " + valid.message());
  }
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

  // Resuming: the checkpoint is the start of this run's result. Frames before `warm_from` are
  // only decoded; from there to the checkpoint's key frame (`resume_frame`) they warm the
  // trackers up; the key frame chain starts again at that key frame.
  const bool resume_complete = resume != nullptr && resume->complete;
  const int64_t resume_frame = resume != nullptr ? resume->through_frame : -1;
  const int64_t warm_from = resume == nullptr ? 0
                            : resume_complete
                                ? std::numeric_limits<int64_t>::max()
                                : std::max<int64_t>(0, resume_frame - options.resume_warmup_frames);
  const int64_t change_cut = resume != nullptr ? resume->change_through_frame : -1;
  int64_t feature_id_offset = 0;
  std::optional<Seam> seam;
  std::vector<track::TargetTrack> targets_by_change;
  std::vector<Eigen::Matrix3d> image_placements;  // preview_from_frame of each key frame image
  if (resume != nullptr) {
    result.frames = resume->frames;
    result.key_frames = resume->key_frames;
    result.links = resume->links;
    result.breaks = resume->breaks;
    for (const KeyFramePreview& preview : resume->key_frame_images) {
      result.key_frame_images.push_back(preview.image);
      image_placements.push_back(preview.preview_from_frame);
      if (options.on_key_frame) options.on_key_frame(preview);
    }
    result.targets = resume->targets;
    targets_by_change = resume->change_targets;
    if (!resume_complete) {
      feature_id_offset = MaxFeatureId(*resume) + 1;
      seam.emplace(*resume, warm_from, options.targets);
    }
  }
  // What the checkpoints handed out so far (the resumed checkpoint counts as handed out; its
  // open targets, finished as far as this run goes, are handed out with the next one).
  struct Delivered {
    size_t frames = 0, key_frames = 0, images = 0, links = 0, breaks = 0, targets = 0, change = 0;
  } delivered{result.frames.size(),    result.key_frames.size(), result.key_frame_images.size(),
              result.links.size(),     result.breaks.size(),     result.targets.size(),
              targets_by_change.size()};
  if (resume != nullptr && !resume_complete) {
    result.targets.insert(result.targets.end(), resume->open_targets.begin(),
                          resume->open_targets.end());
    targets_by_change.insert(targets_by_change.end(), resume->open_change_targets.begin(),
                             resume->open_change_targets.end());
  }
  // A target this run finished, cut at the seam when resuming.
  const auto keep_target = [&](track::TargetTrack t, int64_t cut,
                               std::vector<track::TargetTrack>* to) {
    if (!seam) {
      to->push_back(std::move(t));
    } else if (std::optional<track::TargetTrack> kept = seam->Trim(std::move(t), cut)) {
      to->push_back(std::move(*kept));
    }
  };

  BoundedQueue<video::Frame> queue(size_t(options.queue_frames));
  double decode_ms = 0;
  JobContext decode_job;  // cancelled when the consumer stops early
  StatusOr<ingest::VideoScan> scan = CancelledError("front end: the scan did not run");
  std::thread decoder([&] {
    auto start = Clock::now();
    scan = ingest::ScanVideo(path, scan_options, &decode_job, [&](const video::Frame& frame) {
      video::Frame copy = frame;
      // The reader reuses its buffers; a frame that is only decoded needs no pixels.
      copy.grey = frame.index >= warm_from ? frame.grey.clone() : cv::Mat();
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
  int64_t change_through = change_cut;  // the latest frame whose change answer was applied
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
        change_through = std::max(change_through, c.frame);
      }
      for (track::TargetTrack& t : change_tracks.TakeFinished()) {
        keep_target(std::move(t), change_cut, &targets_by_change);
      }
      timing.change_ms += answer->ms;
      timing.change_tracks_ms += MillisecondsSince(apply_start);
    }
    change_side_ms += MillisecondsSince(start);
  };

  // The key frames, links and breaks of `chain` enter the result as they appear, numbered after
  // the checkpoint's when resuming; the chain's first key frame is then the checkpoint's last.
  size_t chain_key_frames = 0, chain_links = 0, chain_breaks = 0;  // taken from the chain
  int key_frame_base = 0;
  int segment_base = 0;
  const auto take_from_chain = [&](const cv::Mat& grey, const Eigen::Matrix3d& placement) {
    const auto remap = [&](track::KeyFrameId id) {
      return track::KeyFrameId(key_frame_base + int(id));
    };
    const auto offset = [&](track::FeatureTrackId id) {
      return track::FeatureTrackId(int64_t(id) + feature_id_offset);
    };
    bool new_key_frame = false;
    for (; chain_key_frames < chain.key_frames().size(); ++chain_key_frames) {
      track::KeyFrame key = chain.key_frames()[chain_key_frames];
      if (chain_key_frames == 0 && resume != nullptr && !resume->key_frames.empty()) {
        const track::KeyFrame& last = resume->key_frames.back();
        if (key.frame_index == last.frame_index) {
          key_frame_base = int(last.id);  // the same key frame, seen again
          segment_base = last.segment;
          continue;
        }
        key_frame_base = int(last.id) + 1;
        segment_base = last.segment + 1;
        result.breaks.push_back({key.frame_index,
                                 "the resumed run could not continue the chain from "
                                 "key frame " +
                                     std::to_string(int(last.id))});
      }
      key.id = remap(key.id);
      key.segment += segment_base;
      for (track::StationaryPoint& p : key.points) p.first = offset(p.first);
      if (options.key_frame_image_width > 0) {
        KeyFrameImage image;
        image.id = key.id;
        image.frame_index = key.frame_index;
        image.scale = std::max(1.0, double(grey.cols) / options.key_frame_image_width);
        cv::resize(grey, image.grey, cv::Size(), 1.0 / image.scale, 1.0 / image.scale,
                   cv::INTER_AREA);
        if (options.on_key_frame) options.on_key_frame({image, placement});
        result.key_frame_images.push_back(std::move(image));
        image_placements.push_back(placement);
      }
      result.key_frames.push_back(std::move(key));
      new_key_frame = true;
    }
    for (; chain_links < chain.links().size(); ++chain_links) {
      track::SequentialLink link = chain.links()[chain_links];
      link.from = remap(link.from);
      link.to = remap(link.to);
      for (track::Correspondence& m : link.correspondences) m.id = offset(m.id);
      result.links.push_back(std::move(link));
    }
    for (; chain_breaks < chain.breaks().size(); ++chain_breaks) {
      result.breaks.push_back(chain.breaks()[chain_breaks]);
    }
    return new_key_frame;
  };

  // Hands out a checkpoint: what is new since the last one, the open targets, the state.
  auto last_checkpoint = Clock::now();
  const auto hand_out = [&](int64_t through_frame, bool complete) -> Status {
    const auto tail = [](const auto& all, size_t* from) {
      std::decay_t<decltype(all)> part(all.begin() + std::ptrdiff_t(*from), all.end());
      *from = all.size();
      return part;
    };
    FrontEndCheckpoint c;
    c.through_frame = through_frame;
    c.complete = complete;
    c.frames = tail(result.frames, &delivered.frames);
    c.key_frames = tail(result.key_frames, &delivered.key_frames);
    for (; delivered.images < result.key_frame_images.size(); ++delivered.images) {
      c.key_frame_images.push_back(
          {result.key_frame_images[delivered.images], image_placements[delivered.images]});
    }
    c.links = tail(result.links, &delivered.links);
    c.breaks = tail(result.breaks, &delivered.breaks);
    if (complete) {
      c.targets = result.targets;  // the final ones
    } else {
      c.targets = tail(result.targets, &delivered.targets);
      c.change_targets = tail(targets_by_change, &delivered.change);
      // The targets still followed, as they would end now (on copies of the trackers).
      track::TargetTracker open = targets;
      open.FinishAll();
      open.EndChangeEvidence();
      for (track::TargetTrack& t : open.TakeFinished()) {
        keep_target(std::move(t), resume_frame, &c.open_targets);
      }
      track::BlobTracker open_change = change_tracks;
      open_change.FinishAll();
      for (track::TargetTrack& t : open_change.TakeFinished()) {
        keep_target(std::move(t), change_cut, &c.open_change_targets);
      }
      c.change_through_frame = change_through;
    }
    last_checkpoint = Clock::now();
    const Status saved = options.on_checkpoint(c);
    if (!saved.ok()) return Status(saved.code(), path + ": checkpoint: " + saved.message());
    return Status::Ok();
  };

  // The placement of the current frame in the preview (KeyFramePreview): the first frame's pixels.
  Eigen::Matrix3d preview_from_current = Eigen::Matrix3d::Identity();
  while (std::optional<video::Frame> frame = queue.Pop()) {
    if (job != nullptr && job->IsCancelled()) return CancelledError("front end: cancelled");
    if (frame->index < warm_from) {
      if (job != nullptr) {
        job->ReportProgress("front end", std::min(1.0, double(frame->index + 1) / expected_frames));
      }
      continue;  // done before: only decoded, for the scan
    }
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
    for (track::TargetTrack& t : targets.TakeFinished()) {
      keep_target(std::move(t), resume_frame, &result.targets);
    }
    timing.segment_ms += MillisecondsSince(start) - (change_side_ms - change_side_before);

    apply_change_through(frame->index - kChangeLagFrames);
    segment_open = fr.tracked > 0;
    ++timing.frames;
    if (frame->index == resume_frame && !resume->key_frame_images.empty()) {
      preview_from_current = resume->key_frame_images.back().preview_from_frame;
    }
    if (frame->index < resume_frame) continue;  // warming up: the checkpoint has this frame

    // Key frames from the stationary points.
    start = Clock::now();
    std::vector<track::StationaryPoint> stationary;
    stationary.reserve(tracker.points().size());
    for (const track::TrackedPoint& p : tracker.points()) {
      if (segmenter.LabelOf(p.id) != track::MotionLabel::kMoving)
        stationary.emplace_back(p.id, p.position);
    }
    chain.AddFrame(frame->index, stationary, estimate);
    const bool new_key_frame = take_from_chain(frame->grey, preview_from_current);
    timing.key_frames_ms += MillisecondsSince(start);

    if (frame->index > resume_frame) result.frames.push_back(fr);
    if (new_key_frame && options.on_checkpoint &&
        MillisecondsSince(last_checkpoint) >= 1000 * options.checkpoint_interval_s) {
      SAKER_RETURN_IF_ERROR(hand_out(frame->index, /*complete=*/false));
    }
    if (job != nullptr) {
      job->ReportProgress("front end",
                          std::min(1.0, double(result.frames.size()) / expected_frames));
    }
  }
  SAKER_RETURN_IF_ERROR(queue.status());
  decoder.join();
  SAKER_RETURN_IF_ERROR(scan.status());
  result.scan = std::move(scan).value();
  if (result.scan.frames.size() != result.frames.size()) {
    // Only a checkpoint of another video can do this (the scan and the tracker see each frame).
    SAKER_CHECK(resume != nullptr) << "the scan saw " << result.scan.frames.size()
                                   << " frames, the tracker " << result.frames.size();
    return InvalidArgumentError(path + ": cannot resume: the checkpoint has " +
                                std::to_string(resume->frames.size()) +
                                " frames done and does not fit this video of " +
                                std::to_string(result.scan.frames.size()) + " frames");
  }
  if (!resume_complete) {
    apply_change_through(std::numeric_limits<int64_t>::max());
    targets.FinishAll();
    targets.EndChangeEvidence();
    for (track::TargetTrack& t : targets.TakeFinished()) {
      keep_target(std::move(t), resume_frame, &result.targets);
    }
    change_tracks.FinishAll();
    for (track::TargetTrack& t : change_tracks.TakeFinished()) {
      keep_target(std::move(t), change_cut, &targets_by_change);
    }
    result.targets = CombineTargets(std::move(result.targets), std::move(targets_by_change),
                                    result.frames, options);
    if (options.on_checkpoint && !result.frames.empty()) {
      SAKER_RETURN_IF_ERROR(hand_out(result.frames.back().index, /*complete=*/true));
    }
  }
  timing.wall_s = MillisecondsSince(wall_start) / 1000.0;
  if (change) timing.change_wait_ms = change->wait_ms();
  const double n = double(std::max<int64_t>(1, timing.frames));
  timing.decode_ms = decode_ms / n;
  timing.track_ms /= n, timing.homography_ms /= n, timing.segment_ms /= n, timing.change_ms /= n,
      timing.change_tracks_ms /= n, timing.change_wait_ms /= n, timing.key_frames_ms /= n;
  return result;
}

}  // namespace saker::frontend
