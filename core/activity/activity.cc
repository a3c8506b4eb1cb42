#include "core/activity/activity.h"

#include "core/track/image_geometry.h"
#include "core/util/statistics.h"
#include "core/util/timer.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace saker::activity {
namespace {

using mission::ActivityTrack;
using mission::TrackPoint;

// The image corners (track::ImageCorners) as homogeneous columns.
Eigen::Matrix<double, 3, 4> HomogeneousImageCorners(int width, int height) {
  Eigen::Matrix<double, 3, 4> corners;
  const std::array<Eigen::Vector2d, 4> points = track::ImageCorners(width, height);
  for (int i = 0; i < 4; ++i) corners.col(i) = points[static_cast<size_t>(i)].homogeneous();
  return corners;
}

// Cross product sign test: `p` inside the convex quadrilateral `q` (either orientation).
bool InsideQuad(const Eigen::Matrix<double, 2, 4>& q, const Eigen::Vector2d& p) {
  int positive = 0, negative = 0;
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector2d a = q.col(i), b = q.col((i + 1) % 4);
    const double cross = (b - a).x() * (p - a).y() - (b - a).y() * (p - a).x();
    if (cross > 0) ++positive;
    if (cross < 0) ++negative;
  }
  return positive == 0 || negative == 0;
}

int64_t CellKey(int64_t cx, int64_t cy) {
  return static_cast<int64_t>(static_cast<uint64_t>(cx) << 32) ^
         static_cast<int64_t>(static_cast<uint32_t>(cy));
}

// Centred moving average over `window_s` (by time) of the points' map positions; the window
// shrinks towards the ends so that it stays centred (a one-sided window would pull the ends
// inwards and shorten the path).
std::vector<Eigen::Vector2d> Smoothed(const std::vector<TrackPoint>& points, double window_s) {
  std::vector<double> times(points.size());
  std::vector<Eigen::Vector2d> prefix(points.size() + 1, Eigen::Vector2d::Zero());
  for (size_t i = 0; i < points.size(); ++i) {
    times[i] = points[i].time_s;
    prefix[i + 1] = prefix[i] + points[i].map;
  }
  std::vector<Eigen::Vector2d> smooth(points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    const double half =
        std::min({0.5 * window_s, times[i] - times.front(), times.back() - times[i]});
    const size_t lo = static_cast<size_t>(
        std::lower_bound(times.begin(), times.end(), times[i] - half) - times.begin());
    const size_t hi = static_cast<size_t>(
        std::upper_bound(times.begin(), times.end(), times[i] + half) - times.begin());
    smooth[i] = (prefix[hi] - prefix[lo]) / static_cast<double>(hi - lo);
  }
  return smooth;
}

}  // namespace

Status ActivityOptions::Validate() const {
  if (!(smoothing_s >= 0) || !(speed_interval_s > 0) || !(visit_gap_s > 0) || coverage_stride < 1) {
    return InvalidArgumentError(
        "activity options: smoothing_s >= 0, speed_interval_s > 0, visit_gap_s > 0 and "
        "coverage_stride >= 1 are required");
  }
  return confidence.Validate();
}

double HeadingDegrees(const Eigen::Vector2d& displacement, bool geo_referenced) {
  const double north = geo_referenced ? displacement.y() : -displacement.y();
  double degrees = std::atan2(displacement.x(), north) * 180.0 / M_PI;
  if (degrees < 0) degrees += 360;
  return degrees >= 360 ? 0 : degrees;
}

CoverageIndex::CoverageIndex(const mission::Mission& mission, int stride) {
  const Eigen::Matrix<double, 3, 4> image = HomogeneousImageCorners(
      std::max(mission.source.width, 2), std::max(mission.source.height, 2));
  std::vector<double> sizes;
  int64_t placed = 0;
  for (const mission::FrameRecord& frame : mission.frames) {
    if (!frame.map_from_frame) continue;
    if (placed++ % stride != 0) continue;
    const Eigen::Matrix<double, 3, 4> h = *frame.map_from_frame * image;
    // A footprint reaching the horizon (a corner mapped to or beyond infinity) is not a place.
    if ((h.row(2).array() <= 1e-9 * h.row(2).cwiseAbs().maxCoeff()).any()) continue;
    Footprint footprint;
    footprint.time_s = frame.time_s;
    footprint.corners = h.topRows<2>().array().rowwise() / h.row(2).array();
    if (!footprint.corners.allFinite()) continue;
    sizes.push_back((footprint.corners.col(0) - footprint.corners.col(2)).norm());
    footprints_.push_back(footprint);
  }
  if (footprints_.empty()) return;
  const double median = Median(std::move(sizes));
  cell_ = std::max(median / 2, 1e-6);
  for (size_t i = 0; i < footprints_.size(); ++i) {
    if ((footprints_[i].corners.col(0) - footprints_[i].corners.col(2)).norm() > 20 * median) {
      continue;  // a wildly stretched footprint (a poor homography) would flood the grid
    }
    const Eigen::Vector2d lo = footprints_[i].corners.rowwise().minCoeff();
    const Eigen::Vector2d hi = footprints_[i].corners.rowwise().maxCoeff();
    for (int64_t cx = static_cast<int64_t>(std::floor(lo.x() / cell_));
         cx <= static_cast<int64_t>(std::floor(hi.x() / cell_)); ++cx) {
      for (int64_t cy = static_cast<int64_t>(std::floor(lo.y() / cell_));
           cy <= static_cast<int64_t>(std::floor(hi.y() / cell_)); ++cy) {
        grid_[CellKey(cx, cy)].push_back(static_cast<int32_t>(i));
      }
    }
  }
}

std::vector<CoverageIndex::Interval> CoverageIndex::Visits(const Eigen::Vector2d& point,
                                                           double gap_s) const {
  std::vector<Interval> visits;
  if (!point.allFinite()) return visits;
  const auto cell = grid_.find(CellKey(static_cast<int64_t>(std::floor(point.x() / cell_)),
                                       static_cast<int64_t>(std::floor(point.y() / cell_))));
  if (cell == grid_.end()) return visits;
  std::vector<double> times;
  for (const int32_t i : cell->second) {
    if (InsideQuad(footprints_[static_cast<size_t>(i)].corners, point))
      times.push_back(footprints_[static_cast<size_t>(i)].time_s);
  }
  std::sort(times.begin(), times.end());
  for (const double t : times) {
    if (visits.empty() || t - visits.back().end_s > gap_s) {
      visits.push_back({t, t});
    } else {
      visits.back().end_s = t;
    }
  }
  return visits;
}

StatusOr<ActivitySummary> MapActivity(const mission::Mission& mission,
                                      std::vector<ActivityTrack>* tracks,
                                      const ActivityOptions& options,
                                      const std::unordered_map<int64_t, TrackEvidence>* evidence) {
  SAKER_RETURN_IF_ERROR(options.Validate());
  const Stopwatch begin;
  ActivitySummary summary;
  summary.tracks_in = static_cast<int64_t>(tracks->size());
  // Frame records by index (mission frames are in increasing index, usually 0..n-1).
  std::unordered_map<int64_t, size_t> frame_at;
  frame_at.reserve(mission.frames.size());
  for (size_t i = 0; i < mission.frames.size(); ++i) frame_at[mission.frames[i].index] = i;

  // Per frame, the least w of the ground it maps (mission::FarthestMappedW; NaN: none), so that
  // an observation in the sky or the distant ground of a low oblique view, where the map is
  // smeared, is not placed: the mosaic's tiles leave those parts out too.
  std::unordered_map<size_t, double> farthest_w;
  const auto mapped = [&](size_t f, const Eigen::Vector2d& p, const Eigen::Vector3d& m) {
    const mission::FrameRecord& frame = mission.frames[f];
    if (frame.sky_line && frame.sky_line->Masks(p)) return false;
    auto [it, added] = farthest_w.try_emplace(f, std::numeric_limits<double>::quiet_NaN());
    if (added) {
      const std::optional<double> w = mission::FarthestMappedW(
          *frame.map_from_frame,
          mission::BelowSkyLine(frame.sky_line, mission.source.width, mission.source.height));
      if (w) it->second = *w;
    }
    return m.z() >= it->second;  // false for NaN
  };
  std::vector<ActivityTrack> placed;
  placed.reserve(tracks->size());
  for (ActivityTrack& track : *tracks) {
    std::vector<TrackPoint> points;
    points.reserve(track.points.size());
    for (TrackPoint& point : track.points) {
      const auto it = frame_at.find(point.frame);
      if (it == frame_at.end()) {
        return InvalidArgumentError("activity: track " + std::to_string(track.id) +
                                    " has an observation on frame " + std::to_string(point.frame) +
                                    ", which the mission does not have");
      }
      const mission::FrameRecord& frame = mission.frames[it->second];
      if (!frame.map_from_frame) {
        ++summary.observations_dropped;
        continue;
      }
      const Eigen::Vector3d m = *frame.map_from_frame * point.image.homogeneous();
      if (!(m.z() > 0) || !m.allFinite() || !mapped(it->second, point.image, m)) {
        ++summary.observations_dropped;
        continue;
      }
      point.time_s = frame.time_s;
      point.map = m.hnormalized();
      points.push_back(point);
    }
    if (points.empty()) continue;
    track.points = std::move(points);
    placed.push_back(std::move(track));
  }
  *tracks = std::move(placed);

  const CoverageIndex coverage(mission, options.coverage_stride);
  const bool geo = mission.map.geo_referenced;
  for (ActivityTrack& track : *tracks) {
    const std::vector<TrackPoint>& points = track.points;
    track.start_s = points.front().time_s;
    track.end_s = points.back().time_s;
    const std::vector<Eigen::Vector2d> smooth = Smoothed(points, options.smoothing_s);
    // Path length over the smoothed path sampled every speed_interval_s (and at the end).
    double length = 0;
    size_t last = 0;
    for (size_t i = 1; i < points.size(); ++i) {
      if (points[i].time_s - points[last].time_s >= options.speed_interval_s ||
          i + 1 == points.size()) {
        length += (smooth[i] - smooth[last]).norm();
        last = i;
      }
    }
    track.length = length;
    const double duration = track.end_s - track.start_s;
    track.speed = duration > 0 ? length / duration : 0;
    // The speed over the track's interior, where the smoothing window is whole: towards the ends
    // it shrinks to the raw points, whose noise lengthens the path (walkers, a pixel or two of
    // motion a sample, were 6 % fast at the median).
    const double half = 0.5 * options.smoothing_s;
    const size_t first = static_cast<size_t>(
        std::lower_bound(points.begin(), points.end(), track.start_s + half,
                         [](const TrackPoint& p, double t) { return p.time_s < t; }) -
        points.begin());
    const size_t end = static_cast<size_t>(
        std::upper_bound(points.begin(), points.end(), track.end_s - half,
                         [](double t, const TrackPoint& p) { return t < p.time_s; }) -
        points.begin());
    if (first + 1 < end &&
        points[end - 1].time_s - points[first].time_s >= options.speed_interval_s) {
      double interior = 0;
      size_t from = first;
      for (size_t i = first + 1; i < end; ++i) {
        if (points[i].time_s - points[from].time_s >= options.speed_interval_s || i + 1 == end) {
          interior += (smooth[i] - smooth[from]).norm();
          from = i;
        }
      }
      track.speed = interior / (points[end - 1].time_s - points[first].time_s);
    }
    track.speed_mps = geo ? std::optional<double>(track.speed) : std::nullopt;
    track.heading_deg = HeadingDegrees(smooth.back() - smooth.front(), geo);
    // Visit: the pass over the track's middle position during which it was seen.
    const size_t middle = points.size() / 2;
    const std::vector<CoverageIndex::Interval> visits =
        coverage.Visits(smooth[middle], options.visit_gap_s);
    const double t = points[middle].time_s;
    track.visit = 1;
    double best = std::numeric_limits<double>::infinity();
    for (size_t v = 0; v < visits.size(); ++v) {
      const double off = std::max({0.0, visits[v].start_s - t, t - visits[v].end_s});
      if (off < best) best = off, track.visit = static_cast<int>(v) + 1;
    }
  }
  // Plausibility and confidence (confidence.h): tracks that cannot be ground traffic, or that the
  // evidence supports too little, are not reported.
  std::vector<ActivityTrack> reported;
  reported.reserve(tracks->size());
  for (ActivityTrack& track : *tracks) {
    const TrackEvidence* found = nullptr;
    if (evidence) {
      const auto it = evidence->find(track.id);
      if (it != evidence->end()) found = &it->second;
    }
    const ConfidenceFactors f =
        AssessTrack(track, found ? *found : TrackEvidence{}, options.confidence);
    if (!f.plausible) {
      ++summary.tracks_implausible;
      continue;
    }
    if (found) {
      track.confidence = f.confidence;
      if (f.confidence < options.confidence.min_confidence) {
        ++summary.tracks_low_confidence;
        continue;
      }
    }
    summary.max_visit = std::max(summary.max_visit, track.visit);
    reported.push_back(std::move(track));
  }
  *tracks = std::move(reported);
  summary.tracks_out = static_cast<int64_t>(tracks->size());
  summary.time_s = begin.ElapsedSeconds();
  return summary;
}

TrackIndex::TrackIndex(const std::vector<ActivityTrack>* tracks) : tracks_(tracks) {
  Eigen::Vector2d lo(std::numeric_limits<double>::infinity(),
                     std::numeric_limits<double>::infinity());
  Eigen::Vector2d hi = -lo;
  for (const ActivityTrack& track : *tracks) {
    for (const TrackPoint& point : track.points) {
      if (!point.map.allFinite()) continue;
      lo = lo.cwiseMin(point.map);
      hi = hi.cwiseMax(point.map);
      ++count_;
    }
  }
  if (count_ == 0) return;
  // About four observations per occupied cell on a uniform spread.
  const double extent = std::max((hi - lo).maxCoeff(), 1e-6);
  cell_ = std::max(extent / std::sqrt(static_cast<double>(count_) / 4.0), extent * 1e-6);
  for (size_t t = 0; t < tracks->size(); ++t) {
    const std::vector<TrackPoint>& points = (*tracks)[t].points;
    for (size_t p = 0; p < points.size(); ++p) {
      if (!points[p].map.allFinite()) continue;
      grid_[CellKey(static_cast<int64_t>(std::floor(points[p].map.x() / cell_)),
                    static_cast<int64_t>(std::floor(points[p].map.y() / cell_)))]
          .emplace_back(static_cast<uint32_t>(t), static_cast<uint32_t>(p));
    }
  }
}

std::optional<Pick> TrackIndex::Nearest(const Eigen::Vector2d& map_point, double tolerance,
                                        const std::function<bool(size_t)>& accept) const {
  if (count_ == 0 || !map_point.allFinite() || !(tolerance >= 0)) return std::nullopt;
  std::optional<Pick> best;
  const auto consider = [&](uint32_t t, uint32_t p) {
    if (accept && !accept(t)) return;
    const double d = ((*tracks_)[t].points[p].map - map_point).norm();
    if (d <= tolerance && (!best || d < best->distance)) best = Pick{t, p, d};
  };
  const int64_t x0 = static_cast<int64_t>(std::floor((map_point.x() - tolerance) / cell_));
  const int64_t x1 = static_cast<int64_t>(std::floor((map_point.x() + tolerance) / cell_));
  const int64_t y0 = static_cast<int64_t>(std::floor((map_point.y() - tolerance) / cell_));
  const int64_t y1 = static_cast<int64_t>(std::floor((map_point.y() + tolerance) / cell_));
  if (static_cast<double>(x1 - x0 + 1) * static_cast<double>(y1 - y0 + 1) >
      static_cast<double>(grid_.size())) {
    for (const auto& [key, entries] : grid_) {  // fewer occupied cells than cells in range
      for (const auto& [t, p] : entries) consider(t, p);
    }
    return best;
  }
  for (int64_t cx = x0; cx <= x1; ++cx) {
    for (int64_t cy = y0; cy <= y1; ++cy) {
      const auto cell = grid_.find(CellKey(cx, cy));
      if (cell == grid_.end()) continue;
      for (const auto& [t, p] : cell->second) consider(t, p);
    }
  }
  return best;
}

}  // namespace saker::activity
