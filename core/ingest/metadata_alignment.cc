#include "core/ingest/metadata_alignment.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <sstream>

namespace saker::ingest {

Status AlignmentOptions::Validate() const {
  if (!(async_tolerance_s >= 0 && async_tolerance_s <= 60)) {
    std::ostringstream m;
    m << "alignment option async_tolerance_s must be in [0, 60] s, got " << async_tolerance_s;
    return InvalidArgumentError(m.str());
  }
  if (!(sync_tolerance_s >= 0 && sync_tolerance_s <= 0.1)) {
    std::ostringstream m;
    m << "alignment option sync_tolerance_s must be in [0, 0.1] s, got " << sync_tolerance_s;
    return InvalidArgumentError(m.str());
  }
  return Status::Ok();
}

const char* MatchKindName(MatchKind kind) {
  switch (kind) {
    case MatchKind::kNone:
      return "none";
    case MatchKind::kSynchronous:
      return "synchronous";
    case MatchKind::kNearest:
      return "nearest";
  }
  return "unknown";
}

namespace {

// Distance from `t` to the nearest of the sorted `times`.
double DistanceToNearest(const std::vector<double>& times, double t) {
  auto it = std::lower_bound(times.begin(), times.end(), t);
  double best = INFINITY;
  if (it != times.end()) best = std::min(best, std::abs(*it - t));
  if (it != times.begin()) best = std::min(best, std::abs(*std::prev(it) - t));
  return best;
}

struct TimedRef {
  double time_s;
  size_t packet;
};

}  // namespace

std::vector<StreamTiming> ClassifyStreams(const std::vector<double>& frame_times,
                                          const std::vector<AlignablePacket>& packets,
                                          const std::vector<StreamTiming>& declared,
                                          const AlignmentOptions& options) {
  std::vector<double> sorted_frames = frame_times;
  std::sort(sorted_frames.begin(), sorted_frames.end());

  struct Tally {
    int timed = 0;
    int on_frame = 0;
  };
  std::map<int, Tally> tally;
  for (const auto& p : packets) {
    auto& t = tally[p.stream_index];
    if (!std::isfinite(p.time_s) || p.time_inferred) continue;
    ++t.timed;
    if (DistanceToNearest(sorted_frames, p.time_s) <= options.sync_tolerance_s) ++t.on_frame;
  }
  std::vector<StreamTiming> result;
  for (const auto& [stream, t] : tally) {
    bool synchronous = t.timed > 0 && t.on_frame == t.timed;
    for (const auto& d : declared) {
      if (d.stream_index == stream && d.synchronous) synchronous = true;
    }
    result.push_back({stream, synchronous});
  }
  return result;
}

std::vector<FrameMatch> AlignFrames(const std::vector<double>& frame_times,
                                    const std::vector<AlignablePacket>& packets,
                                    const std::vector<StreamTiming>& timing,
                                    const AlignmentOptions& options) {
  // Per stream, its usable packets sorted by time (stable for duplicates, so
  // the first-received packet of a duplicated timestamp wins).
  std::map<int, std::vector<TimedRef>> by_stream;
  for (size_t i = 0; i < packets.size(); ++i) {
    const auto& p = packets[i];
    if (!p.usable || !std::isfinite(p.time_s)) continue;
    by_stream[p.stream_index].push_back({p.time_s, i});
  }
  for (auto& [stream, refs] : by_stream) {
    std::stable_sort(refs.begin(), refs.end(),
                     [](const TimedRef& a, const TimedRef& b) { return a.time_s < b.time_s; });
  }
  auto is_sync = [&timing](int stream) {
    for (const auto& t : timing) {
      if (t.stream_index == stream) return t.synchronous;
    }
    return false;
  };

  std::vector<FrameMatch> matches(frame_times.size());
  for (size_t f = 0; f < frame_times.size(); ++f) {
    const double t = frame_times[f];
    FrameMatch best;
    bool best_corners = false;
    for (const auto& [stream, refs] : by_stream) {
      const bool sync = is_sync(stream);
      const double tolerance = sync ? options.sync_tolerance_s : options.async_tolerance_s;
      // Nearest packet of this stream: check both neighbours of t.
      auto it = std::lower_bound(refs.begin(), refs.end(), t,
                                 [](const TimedRef& r, double v) { return r.time_s < v; });
      const TimedRef* candidate = nullptr;
      double candidate_distance = INFINITY;
      for (auto c : {it, it == refs.begin() ? refs.end() : std::prev(it)}) {
        if (c == refs.end()) continue;
        const double d = std::abs(c->time_s - t);
        if (d < candidate_distance) {
          candidate_distance = d;
          candidate = &*c;
        }
      }
      if (candidate == nullptr || candidate_distance > tolerance) continue;
      const bool corners = packets[candidate->packet].has_corners;
      const bool better = best.kind == MatchKind::kNone || (corners && !best_corners) ||
                          (corners == best_corners && candidate_distance < std::abs(best.offset_s));
      if (better) {
        best.kind = sync ? MatchKind::kSynchronous : MatchKind::kNearest;
        best.packet = candidate->packet;
        best.offset_s = candidate->time_s - t;
        best_corners = corners;
      }
    }
    matches[f] = best;
  }
  return matches;
}

}  // namespace saker::ingest
