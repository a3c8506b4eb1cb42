#include "core/track/target_tracks.h"

#include "core/util/check.h"

#include <algorithm>
#include <limits>
#include <map>
#include <numeric>
#include <optional>
#include <tuple>
#include <unordered_map>

namespace saker::track {
namespace {

// Union-find over the moving points of one frame.
class Groups {
 public:
  explicit Groups(size_t n) : parent_(n) { std::iota(parent_.begin(), parent_.end(), 0); }
  size_t Find(size_t i) {
    while (parent_[i] != i) i = parent_[i] = parent_[parent_[i]];
    return i;
  }
  void Join(size_t a, size_t b) { parent_[Find(a)] = Find(b); }

 private:
  std::vector<size_t> parent_;
};

// Whether two moving things (features or targets) belong to one object: close together, and
// moving alike. Both limits scale with speed: a car is long and its corners far apart, a walker
// is a few pixels and walkers passing each other must stay apart; velocity noise is relative.
bool Alike(const Eigen::Vector2d& pa, const Eigen::Vector2d& va, const Eigen::Vector2d& pb,
           const Eigen::Vector2d& vb, const TargetTrackOptions& options,
           const TargetTrackTiming& timing) {
  const double speed = std::max(va.norm(), vb.norm());
  const double distance =
      options.group_distance_px * std::clamp(speed / timing.group_full_speed_px, 0.35, 1.0);
  const double velocity = std::max(timing.group_velocity_px, 0.6 * speed);
  return (pa - pb).squaredNorm() <= distance * distance &&
         (va - vb).squaredNorm() <= velocity * velocity;
}

// Two observations of one frame made one: position and velocity weighted by feature count (a
// featureless one, from change detection, counts as one), boxes and features joined.
void MergeObservation(const TargetObservation& o, TargetObservation* into) {
  TargetObservation& m = *into;
  const double na = static_cast<double>(std::max<size_t>(1, m.features.size()));
  const double nb = static_cast<double>(std::max<size_t>(1, o.features.size()));
  m.position = (m.position * na + o.position * nb) / (na + nb);
  m.velocity = (m.velocity * na + o.velocity * nb) / (na + nb);
  m.box_min = m.box_min.cwiseMin(o.box_min);
  m.box_max = m.box_max.cwiseMax(o.box_max);
  m.features.insert(m.features.end(), o.features.begin(), o.features.end());
  std::sort(m.features.begin(), m.features.end());
  m.change = std::max(m.change, o.change);
}

// Mean distance between two tracks over the frames both saw, and how many frames that is.
std::pair<double, int> SideBySide(const TargetTrack& a, const TargetTrack& b) {
  double sum = 0;
  int n = 0;
  ForCommonFrames(a, b, [&](const TargetObservation& oa, const TargetObservation& ob) {
    sum += (oa.position - ob.position).norm();
    ++n;
  });
  return {n > 0 ? sum / n : std::numeric_limits<double>::infinity(), n};
}

// Whether two observations' boxes touch (come within `margin` of each other).
bool Touching(const TargetObservation& a, const TargetObservation& b, double margin) {
  const Eigen::Vector2d gap = (a.box_min - b.box_max).cwiseMax(b.box_min - a.box_max).cwiseMax(0.0);
  return gap.norm() <= margin;
}

// How far apart two tracks of one object may run on average: as for grouping features (walkers
// side by side stay two, a car's two halves are one), and up to 30 % more than the grouping
// distance for pieces of one long vehicle (a van's front and rear corners keep their distance).
double PiecesApart(const TargetTrackOptions& options, const TargetTrackTiming& timing,
                   double speed_a, double speed_b) {
  return options.group_distance_px *
         std::clamp(std::max(speed_a, speed_b) / timing.group_full_speed_px * 1.3, 0.35, 1.3);
}

// The moving features of `frame` grouped into observations (features alike in place and motion,
// Alike), in a deterministic order.
std::vector<TargetObservation> GroupMoving(int64_t frame, const std::vector<MovingPoint>& moving,
                                           const TargetTrackOptions& options,
                                           const TargetTrackTiming& timing) {
  const size_t n = moving.size();
  Groups groups(n);
  for (size_t i = 0; i < n; ++i) {
    for (size_t j = i + 1; j < n; ++j) {
      if (Alike(moving[i].position, moving[i].residual_velocity, moving[j].position,
                moving[j].residual_velocity, options, timing)) {
        groups.Join(i, j);
      }
    }
  }
  std::unordered_map<size_t, std::vector<size_t>> members;
  for (size_t i = 0; i < n; ++i) members[groups.Find(i)].push_back(i);
  std::vector<TargetObservation> observations;
  for (auto& [root, indices] : members) {
    TargetObservation o;
    o.frame = frame;
    o.box_min = o.box_max = moving[indices[0]].position;
    for (size_t i : indices) {
      o.position += moving[i].position;
      o.velocity += moving[i].residual_velocity;
      o.box_min = o.box_min.cwiseMin(moving[i].position);
      o.box_max = o.box_max.cwiseMax(moving[i].position);
      o.features.push_back(moving[i].id);
    }
    o.position /= static_cast<double>(indices.size());
    o.velocity /= static_cast<double>(indices.size());
    o.box_min -= Eigen::Vector2d::Constant(options.box_margin_px);
    o.box_max += Eigen::Vector2d::Constant(options.box_margin_px);
    std::sort(o.features.begin(), o.features.end());
    observations.push_back(std::move(o));
  }
  // Deterministic order whatever the hash map did.
  std::sort(observations.begin(), observations.end(),
            [](const TargetObservation& a, const TargetObservation& b) {
              return a.features[0] < b.features[0];
            });
  return observations;
}

// Image velocity at the end of a track, from its last few observations.
Eigen::Vector2d EndVelocity(const TargetTrack& t) {
  const size_t n = t.observations.size();
  if (n < 2) return t.image_velocity;
  const TargetObservation& last = t.observations[n - 1];
  const TargetObservation& earlier = t.observations[n - std::min<size_t>(n, 6)];
  if (last.frame == earlier.frame) return t.image_velocity;
  return (last.position - earlier.position) / static_cast<double>(last.frame - earlier.frame);
}

}  // namespace

Status TargetTrackOptions::Validate() const {
  if (!(group_distance_px > 0 && group_speed_px_s > 0 && group_full_speed_px_s > 0 &&
        association_gate_px > 0)) {
    return InvalidArgumentError(
        "targets: grouping distances, speeds and the gate must be positive");
  }
  if (!(max_gap_s >= 0 && max_gap_s <= 3600) || !(min_duration_s >= 0 && min_duration_s <= 3600) ||
      !(min_duration_single_s >= 0 && min_duration_single_s <= 3600)) {
    return InvalidArgumentError(
        "targets: the gap and the confirmation durations must be in [0, 3600] s");
  }
  if (!(box_margin_px >= 0)) return InvalidArgumentError("targets: box margin must be >= 0");
  if (!(link_gap_s >= 0 && link_gap_s <= 3600) ||
      !(ground_link_gap_s >= 0 && ground_link_gap_s <= 3600) ||
      !(duplicate_overlap_s >= 0 && duplicate_overlap_s <= 3600) ||
      !(fill_gap_s >= 0 && fill_gap_s <= 3600) || !(shadow_fraction >= 0) ||
      !(gate_growth_px_s >= 0) || !(ground_link_growth_px_s >= 0) ||
      !(ground_link_max_speed_px_s >= 0)) {
    return InvalidArgumentError(
        "targets: link and fill gaps and overlaps must be in [0, 3600] s, the gates' growth, "
        "the ground link speed and the shadow fraction >= 0");
  }
  return Status::Ok();
}

TargetTrackTiming::TargetTrackTiming(const TargetTrackOptions& options, FrameRate rate)
    : group_full_speed_px(rate.PerFrame(options.group_full_speed_px_s)),
      group_velocity_px(rate.PerFrame(options.group_speed_px_s)),
      gate_growth_px(rate.PerFrame(options.gate_growth_px_s)),
      max_gap_frames(rate.Frames(options.max_gap_s, 2)),
      min_frames(rate.Frames(options.min_duration_s, 3)),
      min_frames_single(rate.Frames(options.min_duration_single_s, 4)),
      link_gap_frames(rate.Frames(options.link_gap_s, 2)),
      duplicate_overlap_frames(rate.Frames(options.duplicate_overlap_s, 2)),
      ground_link_max_speed_px(rate.PerFrame(options.ground_link_max_speed_px_s)),
      ground_link_gap_frames(rate.Frames(options.ground_link_gap_s, 2)),
      ground_link_growth_px(rate.PerFrame(options.ground_link_growth_px_s)),
      fill_gap_frames(options.fill_gap_s > 0 ? rate.Frames(options.fill_gap_s, 1) : 0) {}

TargetTracker::TargetTracker(const TargetTrackOptions& options, FrameRate rate)
    : options_(options), timing_(options, rate) {}

void TargetTracker::AddFrame(int64_t frame, const std::vector<MovingPoint>& moving) {
  std::vector<TargetObservation> observations = GroupMoving(frame, moving, options_, timing_);
  const std::vector<int> assigned = Assign(frame, observations);
  Extend(frame, std::move(observations), assigned);
  MergeAlike(frame);
  Confirm();
  EndUnseen(frame);
}

std::vector<int> TargetTracker::Assign(int64_t frame,
                                       const std::vector<TargetObservation>& observations) const {
  std::unordered_map<int64_t, size_t> owner;  // feature id -> active target index
  for (size_t t = 0; t < active_.size(); ++t) {
    for (FeatureTrackId f : active_[t].observations.back().features)
      owner[static_cast<int64_t>(f)] = t;
  }
  std::vector<int> assigned(observations.size(), -1);
  std::vector<bool> target_taken(active_.size(), false);
  // Most shared features first, over all groups: when an object's corners split into two groups
  // (some left behind on the road), the larger share keeps the target.
  struct Vote {
    int count;
    size_t group, target;
  };
  std::vector<Vote> votes;
  for (size_t g = 0; g < observations.size(); ++g) {
    std::map<size_t, int> counts;
    for (FeatureTrackId f : observations[g].features) {
      if (auto it = owner.find(static_cast<int64_t>(f)); it != owner.end()) ++counts[it->second];
    }
    for (const auto& [t, c] : counts) votes.push_back({c, g, t});
  }
  std::sort(votes.begin(), votes.end(), [](const Vote& a, const Vote& b) {
    return a.count != b.count ? a.count > b.count
                              : std::tie(a.group, a.target) < std::tie(b.group, b.target);
  });
  for (const Vote& v : votes) {
    if (assigned[v.group] >= 0 || target_taken[v.target]) continue;
    assigned[v.group] = static_cast<int>(v.target);
    target_taken[v.target] = true;
  }
  for (size_t g = 0; g < observations.size(); ++g) {
    if (assigned[g] >= 0) continue;
    double best = std::numeric_limits<double>::infinity();
    for (size_t t = 0; t < active_.size(); ++t) {
      if (target_taken[t]) continue;
      const TargetObservation& last = active_[t].observations.back();
      const double gate = options_.association_gate_px +
                          timing_.gate_growth_px * static_cast<double>(frame - last.frame - 1);
      const Eigen::Vector2d predicted =
          last.position + active_[t].image_velocity * static_cast<double>(frame - last.frame);
      const double distance = (observations[g].position - predicted).norm();
      if (distance <= gate && distance < best) best = distance, assigned[g] = static_cast<int>(t);
    }
    if (assigned[g] >= 0) target_taken[static_cast<size_t>(assigned[g])] = true;
  }
  return assigned;
}

void TargetTracker::Extend(int64_t frame, std::vector<TargetObservation> observations,
                           const std::vector<int>& assigned) {
  for (size_t g = 0; g < observations.size(); ++g) {
    if (assigned[g] >= 0) {
      TargetTrack& target = active_[static_cast<size_t>(assigned[g])];
      const TargetObservation& last = target.observations.back();
      const Eigen::Vector2d velocity =
          (observations[g].position - last.position) / static_cast<double>(frame - last.frame);
      // Smoothed: feature sets change from frame to frame and move the mean a little.
      target.image_velocity =
          target.observations.size() == 1 ? velocity : 0.5 * (target.image_velocity + velocity);
      target.max_features = std::max(target.max_features, observations[g].features.size());
      target.observations.push_back(std::move(observations[g]));
    } else {
      TargetTrack target;
      target.id = TargetTrackId{next_id_++};
      target.max_features = observations[g].features.size();
      target.observations.push_back(std::move(observations[g]));
      active_.push_back(std::move(target));
    }
  }
}

void TargetTracker::Confirm() {
  for (TargetTrack& target : active_) {
    const int needed = target.max_features >= 2 ? timing_.min_frames : timing_.min_frames_single;
    double travel = 0;
    for (const TargetObservation& o : target.observations) travel += o.velocity.norm();
    target.confirmed |=
        static_cast<int>(target.observations.size()) >= needed && travel >= options_.min_travel_px;
  }
}

void TargetTracker::EndUnseen(int64_t frame) {
  std::vector<TargetTrack> still;
  for (TargetTrack& target : active_) {
    if (frame - target.last_frame() > timing_.max_gap_frames) {
      if (target.confirmed) End(std::move(target));
    } else {
      still.push_back(std::move(target));
    }
  }
  active_ = std::move(still);
}

void TargetTracker::MergeAlike(int64_t frame) {
  for (size_t a = 0; a < active_.size(); ++a) {
    for (size_t b = a + 1; b < active_.size(); ++b) {
      const TargetObservation& oa = active_[a].observations.back();
      const TargetObservation& ob = active_[b].observations.back();
      if (oa.frame != frame || ob.frame != frame) continue;
      // Touching boxes, moving alike: the corners of one object found in two places; and
      // touching in most of the frames both were seen before, too. Two objects that meet (a car
      // catching up with a van at a junction) must not become one, with both histories averaged
      // into a track between them.
      const double speed = std::max(oa.velocity.norm(), ob.velocity.norm());
      const double velocity = std::max(timing_.group_velocity_px, 0.6 * speed);
      if (!Touching(oa, ob, options_.box_margin_px) ||
          (oa.velocity - ob.velocity).norm() > velocity) {
        continue;
      }
      int common = 0, touching = 0;
      ForCommonFrames(active_[a], active_[b],
                      [&](const TargetObservation& pa, const TargetObservation& pb) {
                        ++common;
                        touching += Touching(pa, pb, options_.box_margin_px);
                      });
      if (2 * touching < common) continue;
      // Keep the older target (smaller id); fold the other's observations into it by frame.
      size_t keep = active_[a].id < active_[b].id ? a : b, drop = keep == a ? b : a;
      std::map<int64_t, TargetObservation> by_frame;
      for (TargetObservation& o : active_[keep].observations)
        by_frame.emplace(o.frame, std::move(o));
      for (TargetObservation& o : active_[drop].observations) {
        auto [it, inserted] = by_frame.emplace(o.frame, o);
        if (!inserted) {
          MergeObservation(o, &it->second);
        }
      }
      TargetTrack& kept = active_[keep];
      kept.observations.clear();
      for (auto& [f, o] : by_frame) kept.observations.push_back(std::move(o));
      kept.max_features = std::max({kept.max_features, active_[drop].max_features,
                                    kept.observations.back().features.size()});
      kept.confirmed = kept.confirmed || active_[drop].confirmed;
      // Its latest positions are now the merged ones: the velocity the two had each measured
      // against their own last position would carry the offset between them, frame after frame
      // (a walker's two corners, merged every frame, gave it 6 px a frame it did not move, and
      // after a gap the prediction reached another walker 13 m away).
      kept.image_velocity = EndVelocity(kept);
      active_.erase(active_.begin() + static_cast<long>(drop));
      --b;  // the next candidate moved into slot b
      if (drop < a) --a;
    }
  }
}

void TargetTracker::RecordChange(
    int64_t frame, const std::function<ChangeEvidence(const TargetObservation&)>& look) {
  const auto record = [&](TargetTrack& target) {
    for (auto o = target.observations.rbegin(); o != target.observations.rend(); ++o) {
      if (o->frame < frame) break;
      if (o->frame == frame) o->change = look(*o);
    }
  };
  for (TargetTrack& target : active_) record(target);
  for (TargetTrack& target : waiting_) record(target);
  change_through_ = std::max(change_through_, frame);
  std::vector<TargetTrack> still;
  for (TargetTrack& target : waiting_) {
    if (target.last_frame() <= change_through_) {
      finished_.push_back(std::move(target));
    } else {
      still.push_back(std::move(target));
    }
  }
  waiting_ = std::move(still);
}

void TargetTracker::EndChangeEvidence() {
  for (TargetTrack& target : waiting_) finished_.push_back(std::move(target));
  waiting_.clear();
}

void TargetTracker::End(TargetTrack&& target) {
  if (options_.wait_for_change && target.last_frame() > change_through_) {
    waiting_.push_back(std::move(target));
  } else {
    finished_.push_back(std::move(target));
  }
}

std::vector<TargetTrack> TargetTracker::TakeFinished() {
  std::vector<TargetTrack> out = std::move(finished_);
  finished_.clear();
  return out;
}

void TargetTracker::FinishAll() {
  for (TargetTrack& target : active_) {
    if (target.confirmed) End(std::move(target));
  }
  active_.clear();
}

namespace {

// Folds `from` into `into` by frame (averaging frames both saw, weighted by feature counts).
void FoldInto(TargetTrack& into, TargetTrack&& from) {
  std::map<int64_t, TargetObservation> by_frame;
  for (TargetObservation& o : into.observations) by_frame.emplace(o.frame, std::move(o));
  for (TargetObservation& o : from.observations) {
    auto [it, inserted] = by_frame.emplace(o.frame, o);
    if (!inserted) MergeObservation(o, &it->second);
  }
  into.observations.clear();
  for (auto& [f, o] : by_frame) into.observations.push_back(std::move(o));
  into.max_features = std::max(into.max_features, from.max_features);
  into.confirmed = into.confirmed || from.confirmed;
}

double DistanceToSegment(const Eigen::Vector2d& p, const Eigen::Vector2d& a,
                         const Eigen::Vector2d& b) {
  const Eigen::Vector2d ab = b - a;
  const double length2 = ab.squaredNorm();
  const double t = length2 > 0 ? std::clamp((p - a).dot(ab) / length2, 0.0, 1.0) : 0.0;
  return (p - (a + t * ab)).norm();
}

}  // namespace

double MeanSpeed(const TargetTrack& t) {
  double sum = 0;
  for (const TargetObservation& o : t.observations) sum += o.velocity.norm();
  return t.observations.empty() ? 0 : sum / static_cast<double>(t.observations.size());
}

void GroundMotion::Add(int64_t frame, bool linked, const Eigen::Matrix3d& current_from_previous) {
  if (segment_.empty()) first_frame_ = frame;
  const int64_t next = first_frame_ + static_cast<int64_t>(segment_.size());
  SAKER_CHECK(frame >= next) << "frame " << frame << " added after frame " << next - 1;
  if (frame > next) {  // frames missing: unknown, and the chain is broken there
    segment_.resize(static_cast<size_t>(frame - first_frame_), -1);
    frame_from_segment_.resize(segment_.size(), Eigen::Matrix3d::Identity());
    linked = false;
  }
  if (!linked || segment_.empty()) {
    segment_.push_back(segments_++);
    frame_from_segment_.push_back(Eigen::Matrix3d::Identity());
    return;
  }
  Eigen::Matrix3d h = current_from_previous * frame_from_segment_.back();
  if (std::abs(h(2, 2)) > 1e-12) h /= h(2, 2);
  segment_.push_back(segment_.back());
  frame_from_segment_.push_back(h);
}

std::optional<Eigen::Vector2d> GroundMotion::Map(const Eigen::Vector2d& point, int64_t from,
                                                 int64_t to) const {
  if (!SameSegment(from, to)) return std::nullopt;
  const auto i = static_cast<size_t>(from - first_frame_),
             j = static_cast<size_t>(to - first_frame_);
  const Eigen::Vector3d p =
      frame_from_segment_[j] * frame_from_segment_[i].inverse() * point.homogeneous();
  if (!(std::abs(p.z()) > 1e-12)) return std::nullopt;
  return Eigen::Vector2d(p.hnormalized());
}

bool GroundMotion::SameSegment(int64_t a, int64_t b) const {
  const int64_t n = static_cast<int64_t>(segment_.size());
  const int64_t i = a - first_frame_, j = b - first_frame_;
  return i >= 0 && j >= 0 && i < n && j < n && segment_[static_cast<size_t>(i)] >= 0 &&
         segment_[static_cast<size_t>(i)] == segment_[static_cast<size_t>(j)];
}

std::vector<TargetTrack> LinkFragments(std::vector<TargetTrack> tracks,
                                       const TargetTrackOptions& options, FrameRate rate,
                                       const GroundMotion* ground, const SceneContinuity* scenes) {
  const TargetTrackTiming timing(options, rate);
  // Merges are made one at a time, always the first in a fixed order: duplicates before
  // continuations, each by track index, the tracks ordered by their first frame. Merging keeps
  // that order (a track only ever absorbs one that starts no earlier), and after a merge only
  // pairs involving the grown track can newly be duplicates, so those are the only pairs checked
  // again. Pairs that share no frame are skipped by their frame spans and continuations are looked
  // up by start frame, so an hour of video (thousands of fragments) links in a fraction of a
  // second rather than the O(n^3) of rescanning every pair after every merge.
  std::sort(tracks.begin(), tracks.end(), [](const TargetTrack& a, const TargetTrack& b) {
    return a.observations.front().frame != b.observations.front().frame
               ? a.observations.front().frame < b.observations.front().frame
               : a.id < b.id;
  });
  std::vector<double> speed(tracks.size());  // MeanSpeed of each track, kept up to date
  for (size_t i = 0; i < tracks.size(); ++i) speed[i] = MeanSpeed(tracks[i]);
  const auto first = [&](size_t i) { return tracks[i].observations.front().frame; };
  const auto last = [&](size_t i) { return tracks[i].observations.back().frame; };

  // Whether tracks a < b ran side by side for a while (a track's two halves, a car seen twice),
  // or b took over from a: started beside a in a's last frames (fewer than a duplicate needs) and
  // went on after a ended.
  const auto duplicates = [&](size_t a, size_t b) {
    if (first(b) > last(a) || first(a) > last(b)) return false;  // no frame in common
    const auto [distance, frames] = SideBySide(tracks[a], tracks[b]);
    const bool handover = first(a) < first(b) && last(a) < last(b) &&
                          last(a) - first(b) < timing.duplicate_overlap_frames;
    return (frames >= timing.duplicate_overlap_frames || (handover && frames > 0)) &&
           distance <= PiecesApart(options, timing, speed[a], speed[b]);
  };
  // Folds track `from` into track `into` (into < from) and removes it.
  const auto fold = [&](size_t into, size_t from) {
    FoldInto(tracks[into], std::move(tracks[from]));
    tracks.erase(tracks.begin() + static_cast<long>(from));
    speed.erase(speed.begin() + static_cast<long>(from));
    speed[into] = MeanSpeed(tracks[into]);
  };
  // The first duplicate of track a after it in the order, or none.
  const auto next_duplicate = [&](size_t a) -> std::optional<size_t> {
    for (size_t b = a + 1; b < tracks.size() && first(b) <= last(a); ++b) {
      if (duplicates(a, b)) return b;
    }
    return std::nullopt;
  };
  // Track t has grown: merges the duplicates that made, in the order a full rescan would.
  const auto settle = [&](size_t t) {
    for (;;) {
      size_t x = 0;
      while (x < t && !duplicates(x, t)) ++x;
      if (x < t) {
        fold(x, t);
        t = x;
      } else if (const std::optional<size_t> y = next_duplicate(t)) {
        fold(t, *y);
      } else {
        return;
      }
    }
  };
  // The best-placed track starting soon after track a's end, where a's motion leads.
  const auto continuation = [&](size_t a) -> std::optional<size_t> {
    const TargetObservation& end = tracks[a].observations.back();
    const Eigen::Vector2d velocity = EndVelocity(tracks[a]);
    double best = std::numeric_limits<double>::infinity();
    std::optional<size_t> best_b;
    const auto after = std::partition_point(
        tracks.begin(), tracks.end(),
        [&](const TargetTrack& t) { return t.observations.front().frame <= end.frame; });
    // Walkers stop and go on; a car that is lost is looked for where it was heading.
    const bool on_ground = ground != nullptr && speed[a] <= timing.ground_link_max_speed_px;
    const int64_t max_gap = on_ground
                                ? std::max(timing.link_gap_frames, timing.ground_link_gap_frames)
                                : timing.link_gap_frames;
    for (size_t b = static_cast<size_t>(after - tracks.begin()); b < tracks.size(); ++b) {
      const TargetObservation& start = tracks[b].observations.front();
      const int64_t gap = start.frame - end.frame;
      if (gap > max_gap) break;
      if (scenes != nullptr && !scenes->SameScene(end.frame, start.frame)) continue;
      double distance = std::numeric_limits<double>::infinity(), gate = 0;
      const std::optional<Eigen::Vector2d> stopped =
          on_ground ? ground->Map(end.position, end.frame, start.frame) : std::nullopt;
      const std::optional<Eigen::Vector2d> went_on =
          stopped ? ground->Map(end.position + end.velocity * static_cast<double>(gap), end.frame,
                                start.frame)
                  : std::nullopt;
      if (stopped && went_on) {
        distance = DistanceToSegment(start.position, *stopped, *went_on);
        gate =
            options.association_gate_px + timing.ground_link_growth_px * static_cast<double>(gap);
      } else if (gap <= timing.link_gap_frames) {
        distance = (start.position - (end.position + velocity * static_cast<double>(gap))).norm();
        gate = options.association_gate_px + timing.gate_growth_px * static_cast<double>(gap);
      }
      if (distance <= gate && distance < best) best = distance, best_b = b;
    }
    return best_b;
  };

  // Duplicates: the first pair in order, until none is left.
  for (size_t a = 0; a < tracks.size();) {
    if (const std::optional<size_t> b = next_duplicate(a)) {
      fold(a, *b);
      settle(a);
    } else {
      ++a;
    }
  }
  // Continuations: the first track in order that has one, then the duplicates that made.
  for (bool merged = true; merged;) {
    merged = false;
    for (size_t a = 0; a < tracks.size() && !merged; ++a) {
      if (const std::optional<size_t> b = continuation(a)) {
        fold(a, *b);  // *b > a: it starts after a ends
        settle(a);
        merged = true;
      }
    }
  }
  std::sort(tracks.begin(), tracks.end(),
            [](const TargetTrack& a, const TargetTrack& b) { return a.id < b.id; });
  return tracks;
}

std::vector<TargetTrack> FillGaps(std::vector<TargetTrack> tracks,
                                  const TargetTrackOptions& options, FrameRate rate,
                                  const GroundMotion& ground) {
  const TargetTrackTiming timing(options, rate);
  if (timing.fill_gap_frames <= 0) return tracks;
  for (TargetTrack& track : tracks) {
    std::vector<TargetObservation> filled;
    filled.reserve(track.observations.size());
    for (size_t k = 0; k < track.observations.size(); ++k) {
      const TargetObservation& b = track.observations[k];
      const TargetObservation* a = k > 0 ? &track.observations[k - 1] : nullptr;
      const int64_t unseen = a != nullptr ? b.frame - a->frame - 1 : 0;
      // b where it was, in a's frame: the ground's motion carries it.
      const std::optional<Eigen::Vector2d> b_in_a = unseen > 0 && unseen <= timing.fill_gap_frames
                                                        ? ground.Map(b.position, b.frame, a->frame)
                                                        : std::nullopt;
      for (int64_t f = b_in_a ? a->frame + 1 : b.frame; f < b.frame; ++f) {
        const double w = static_cast<double>(f - a->frame) / static_cast<double>(unseen + 1);
        const std::optional<Eigen::Vector2d> p =
            ground.Map((1 - w) * a->position + w * *b_in_a, a->frame, f);
        if (!p) continue;
        const TargetObservation& nearer = w <= 0.5 ? *a : b;
        TargetObservation o;
        o.frame = f;
        o.position = *p;
        o.box_min = *p + (nearer.box_min - nearer.position);
        o.box_max = *p + (nearer.box_max - nearer.position);
        o.velocity = (1 - w) * a->velocity + w * b.velocity;
        o.interpolated = true;
        filled.push_back(std::move(o));
      }
      filled.push_back(b);
    }
    track.observations = std::move(filled);
  }
  return tracks;
}

void SaveTargetTrack(const TargetTrack& track, ByteWriter* out) {
  out->Put<int64_t>(static_cast<int64_t>(track.id));
  out->Put<uint8_t>(track.confirmed);
  out->Put<uint64_t>(track.max_features);
  out->PutMatrix(track.image_velocity);
  out->Put<uint64_t>(track.observations.size());
  for (const TargetObservation& o : track.observations) {
    out->Put<int64_t>(o.frame);
    out->PutMatrix(o.position);
    out->PutMatrix(o.box_min);
    out->PutMatrix(o.box_max);
    out->PutMatrix(o.velocity);
    out->Put<uint8_t>(static_cast<uint8_t>(o.change));
    out->Put<uint64_t>(o.features.size());
    for (const FeatureTrackId f : o.features) out->Put<int64_t>(static_cast<int64_t>(f));
  }
}

bool RestoreTargetTrack(ByteReader* in, TargetTrack* track) {
  int64_t id = 0;
  uint8_t confirmed = 0;
  uint64_t max_features = 0;
  size_t observations = 0;
  if (!in->Get(&id) || !in->Get(&confirmed) || !in->Get(&max_features) ||
      !in->GetMatrix(&track->image_velocity) || !in->GetCount(81, &observations)) {
    return false;
  }
  track->id = static_cast<TargetTrackId>(id);
  track->confirmed = confirmed != 0;
  track->max_features = static_cast<size_t>(max_features);
  track->observations.resize(observations);
  for (TargetObservation& o : track->observations) {
    uint8_t change = 0;
    size_t features = 0;
    if (!in->Get(&o.frame) || !in->GetMatrix(&o.position) || !in->GetMatrix(&o.box_min) ||
        !in->GetMatrix(&o.box_max) || !in->GetMatrix(&o.velocity) || !in->Get(&change) ||
        change > static_cast<uint8_t>(ChangeEvidence::kChanged) || !in->GetCount(8, &features)) {
      return false;
    }
    o.change = static_cast<ChangeEvidence>(change);
    o.features.resize(features);
    for (FeatureTrackId& f : o.features) {
      int64_t feature = 0;
      if (!in->Get(&feature)) return false;
      f = static_cast<FeatureTrackId>(feature);
    }
  }
  return true;
}

namespace {

void SaveTargetTracks(const std::vector<TargetTrack>& tracks, ByteWriter* out) {
  out->Put<uint64_t>(tracks.size());
  for (const TargetTrack& t : tracks) SaveTargetTrack(t, out);
}

bool RestoreTargetTracks(ByteReader* in, std::vector<TargetTrack>* tracks) {
  size_t count = 0;
  if (!in->GetCount(49, &count)) return false;
  tracks->resize(count);
  for (TargetTrack& t : *tracks) {
    if (!RestoreTargetTrack(in, &t)) return false;
  }
  return true;
}

}  // namespace

void TargetTracker::SaveState(ByteWriter* out) const {
  SaveTargetTracks(active_, out);
  SaveTargetTracks(waiting_, out);
  SaveTargetTracks(finished_, out);
  out->Put<int64_t>(change_through_);
  out->Put<int64_t>(next_id_);
}

bool TargetTracker::RestoreState(ByteReader* in) {
  return RestoreTargetTracks(in, &active_) && RestoreTargetTracks(in, &waiting_) &&
         RestoreTargetTracks(in, &finished_) && in->Get(&change_through_) && in->Get(&next_id_);
}

std::vector<TargetTrack> DropShadows(std::vector<TargetTrack> tracks,
                                     const TargetTrackOptions& options, FrameRate rate) {
  if (!(options.shadow_fraction <= 1)) return tracks;
  const TargetTrackTiming timing(options, rate);
  const size_t n = tracks.size();
  std::vector<double> speed(n);
  std::vector<bool> slow(n), dropped(n, false);
  // Each frame's observations of slow tracks: (track, position).
  std::unordered_map<int64_t, std::vector<std::pair<size_t, Eigen::Vector2d>>> by_frame;
  for (size_t i = 0; i < n; ++i) {
    speed[i] = MeanSpeed(tracks[i]);
    slow[i] = speed[i] <= timing.ground_link_max_speed_px;
    if (!slow[i]) continue;
    for (const TargetObservation& o : tracks[i].observations)
      by_frame[o.frame].emplace_back(i, o.position);
  }
  // Calls visit(j) for each track beside track i's observation `o` (a slow track not dropped).
  const auto for_beside = [&](size_t i, const TargetObservation& o, const auto& visit) {
    for (const auto& [j, position] : by_frame[o.frame]) {
      if (j != i && !dropped[j] &&
          (position - o.position).norm() <= PiecesApart(options, timing, speed[i], speed[j])) {
        visit(j);
      }
    }
  };
  // Frames of track i with a track beside it.
  const auto count_beside = [&](size_t i) {
    size_t beside = 0;
    for (const TargetObservation& o : tracks[i].observations) {
      bool any = false;
      for_beside(i, o, [&](size_t) { any = true; });
      beside += any;
    }
    return beside;
  };
  std::vector<size_t> beside(n, 0);
  for (size_t i = 0; i < n; ++i) {
    if (slow[i]) beside[i] = count_beside(i);
  }
  // The most shadowed first (the shorter, then the later, on a tie); dropping it frees the
  // tracks beside it, whose counts are taken again.
  for (;;) {
    std::optional<size_t> worst;
    double worst_fraction = 0;
    for (size_t i = 0; i < n; ++i) {
      if (!slow[i] || dropped[i] || tracks[i].observations.empty()) continue;
      const double fraction =
          static_cast<double>(beside[i]) / static_cast<double>(tracks[i].observations.size());
      const bool worse = !worst || fraction > worst_fraction ||
                         (fraction == worst_fraction &&
                          (tracks[i].observations.size() < tracks[*worst].observations.size() ||
                           (tracks[i].observations.size() == tracks[*worst].observations.size() &&
                            tracks[i].id > tracks[*worst].id)));
      if (worse) worst = i, worst_fraction = fraction;
    }
    if (!worst || worst_fraction < options.shadow_fraction || worst_fraction == 0) break;
    dropped[*worst] = true;
    std::vector<size_t> affected;
    for (const TargetObservation& o : tracks[*worst].observations) {
      for_beside(*worst, o, [&](size_t j) { affected.push_back(j); });
    }
    std::sort(affected.begin(), affected.end());
    affected.erase(std::unique(affected.begin(), affected.end()), affected.end());
    for (const size_t j : affected) beside[j] = count_beside(j);
  }
  std::vector<TargetTrack> kept;
  kept.reserve(n);
  for (size_t i = 0; i < n; ++i) {
    if (!dropped[i]) kept.push_back(std::move(tracks[i]));
  }
  return kept;
}

}  // namespace saker::track
