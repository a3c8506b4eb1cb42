#include "core/frontend/resume.h"

#include <algorithm>
#include <iterator>
#include <limits>
#include <string>
#include <utility>

namespace saker::frontend {
namespace {

// Feature track ids of a resumed run start past every id in its checkpoint.
int64_t MaxFeatureId(const FrontEndCheckpoint& c) {
  int64_t max_id = 0;
  for (const track::KeyFrame& k : c.key_frames) {
    for (const track::StationaryPoint& p : k.points)
      max_id = std::max(max_id, static_cast<int64_t>(p.first));
  }
  for (const track::SequentialLink& l : c.links) {
    for (const track::Correspondence& m : l.correspondences) {
      max_id = std::max(max_id, static_cast<int64_t>(m.id));
    }
  }
  return max_id;
}

// The part of `all` past `*from`, which moves to its end.
template <typename T>
std::vector<T> Tail(const std::vector<T>& all, size_t* from) {
  std::vector<T> part(all.begin() + static_cast<std::ptrdiff_t>(*from), all.end());
  *from = all.size();
  return part;
}

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
  state = std::move(next.state);
}

Status FrontEndCheckpoint::Validate() const {
  if (through_frame < 0 || frames.size() != static_cast<size_t>(through_frame) + 1) {
    return InvalidArgumentError("checkpoint: " + std::to_string(frames.size()) +
                                " frames for frames 0.." + std::to_string(through_frame));
  }
  for (size_t i = 0; i < frames.size(); ++i) {
    if (frames[i].index != static_cast<int64_t>(i)) {
      return InvalidArgumentError("checkpoint: frame " + std::to_string(i) + " is numbered " +
                                  std::to_string(frames[i].index));
    }
  }
  for (size_t i = 0; i < key_frames.size(); ++i) {
    const track::KeyFrame& k = key_frames[i];
    if (static_cast<int64_t>(k.id) != static_cast<int64_t>(i) || k.frame_index < 0 ||
        k.frame_index > through_frame ||
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
    const int64_t id = static_cast<int64_t>(key_frame_images[i].image.id);
    if (id < 0 || static_cast<size_t>(id) >= key_frames.size() ||
        (i > 0 && id <= static_cast<int64_t>(key_frame_images[i - 1].image.id))) {
      return InvalidArgumentError("checkpoint: image of unknown key frame " + std::to_string(id));
    }
  }
  for (const track::SequentialLink& l : links) {
    if (static_cast<int64_t>(l.from) < 0 || static_cast<size_t>(l.from) >= key_frames.size() ||
        static_cast<int64_t>(l.to) < 0 || static_cast<size_t>(l.to) >= key_frames.size()) {
      return InvalidArgumentError("checkpoint: a link between unknown key frames");
    }
  }
  return Status::Ok();
}

ResumePoint ResumePointOf(const FrontEndCheckpoint* checkpoint, int warmup_frames,
                          int replay_frames) {
  ResumePoint point;
  if (checkpoint == nullptr) return point;
  point.resuming = true;
  point.complete = checkpoint->complete;
  point.exact = !checkpoint->state.empty();
  point.through_frame = checkpoint->through_frame;
  const int before = point.exact ? replay_frames : warmup_frames;
  point.warm_from = point.complete ? std::numeric_limits<int64_t>::max()
                                   : std::max<int64_t>(0, point.through_frame - before);
  point.change_through_frame = checkpoint->change_through_frame;
  return point;
}

TargetSeam::TargetSeam(const FrontEndCheckpoint& checkpoint, int64_t warm_from,
                       const track::TargetTrackOptions& options, track::FrameRate rate)
    : gate_px_(options.association_gate_px),
      min_frames_(track::TargetTrackTiming(options, rate).min_frames) {
  for (const auto* list : {&checkpoint.targets, &checkpoint.change_targets,
                           &checkpoint.open_targets, &checkpoint.open_change_targets}) {
    for (const track::TargetTrack& t : *list) {
      for (const track::TargetObservation& o : t.observations) {
        if (o.frame >= warm_from) seen_[o.frame].push_back(o.position);
      }
    }
  }
}

std::optional<track::TargetTrack> TargetSeam::Trim(track::TargetTrack target, int64_t cut) const {
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
  if (static_cast<int>(obs.size()) < min_frames_)
    return std::nullopt;  // a stray end of a checkpoint target
  return target;
}

ChainSeam::ChainSeam(const FrontEndCheckpoint* checkpoint) {
  if (checkpoint == nullptr || checkpoint->complete) return;
  if (!checkpoint->key_frames.empty()) last_ = &checkpoint->key_frames.back();
  if (checkpoint->state.empty()) feature_id_offset_ = MaxFeatureId(*checkpoint) + 1;
}

std::optional<track::KeyFrame> ChainSeam::Continue(track::KeyFrame key, bool first,
                                                   std::vector<track::ChainBreak>* breaks) {
  if (first && last_ != nullptr) {
    if (key.frame_index == last_->frame_index) {
      key_frame_base_ = static_cast<int>(last_->id);  // the same key frame, seen again
      segment_base_ = last_->segment;
      return std::nullopt;
    }
    key_frame_base_ = static_cast<int>(last_->id) + 1;
    segment_base_ = last_->segment + 1;
    breaks->push_back(
        {key.frame_index, "the resumed run could not continue the chain from key frame " +
                              std::to_string(static_cast<int>(last_->id))});
  }
  key.id = NewKeyFrameId(key.id);
  key.segment += segment_base_;
  for (track::StationaryPoint& p : key.points) p.first = NewFeatureId(p.first);
  return key;
}

track::SequentialLink ChainSeam::Continue(track::SequentialLink link) const {
  link.from = NewKeyFrameId(link.from);
  link.to = NewKeyFrameId(link.to);
  for (track::Correspondence& m : link.correspondences) m.id = NewFeatureId(m.id);
  return link;
}

track::KeyFrameId ChainSeam::NewKeyFrameId(track::KeyFrameId id) const {
  return static_cast<track::KeyFrameId>(key_frame_base_ + static_cast<int>(id));
}

track::FeatureTrackId ChainSeam::NewFeatureId(track::FeatureTrackId id) const {
  return static_cast<track::FeatureTrackId>(static_cast<int64_t>(id) + feature_id_offset_);
}

CheckpointTail::CheckpointTail(const FrontEndResult& result, size_t change_targets)
    : frames_(result.frames.size()),
      key_frames_(result.key_frames.size()),
      images_(result.key_frame_images.size()),
      links_(result.links.size()),
      breaks_(result.breaks.size()),
      targets_(result.targets.size()),
      change_targets_(change_targets) {}

FrontEndCheckpoint CheckpointTail::TakeNew(int64_t through_frame, bool complete,
                                           const FrontEndResult& result,
                                           const std::vector<Eigen::Matrix3d>& placements,
                                           const std::vector<track::TargetTrack>& change_targets) {
  FrontEndCheckpoint c;
  c.through_frame = through_frame;
  c.complete = complete;
  c.frames = Tail(result.frames, &frames_);
  c.key_frames = Tail(result.key_frames, &key_frames_);
  for (; images_ < result.key_frame_images.size(); ++images_) {
    c.key_frame_images.push_back({result.key_frame_images[images_], placements[images_]});
  }
  c.links = Tail(result.links, &links_);
  c.breaks = Tail(result.breaks, &breaks_);
  if (complete) {
    c.targets = result.targets;  // the final ones
  } else {
    c.targets = Tail(result.targets, &targets_);
    c.change_targets = Tail(change_targets, &change_targets_);
  }
  return c;
}

}  // namespace saker::frontend
