#include "core/activity/confidence.h"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <utility>
#include <vector>

namespace saker::activity {
namespace {

using mission::TrackPoint;

// A straight-line least-squares fit position(t) = mean + v (t - mean t) of a piece of a path.
struct PieceFit {
  Eigen::Vector2d velocity{0, 0};
  double stt = 0;  // sum of (t - mean t)^2: the velocity's variance per axis is sigma^2 / stt
  double residual_squares = 0;  // sum of the squared distances from the line
  int points = 0;
};

PieceFit FitPiece(const std::vector<TrackPoint>& points, size_t begin, size_t end) {
  PieceFit fit;
  fit.points = static_cast<int>(end - begin);
  double mean_t = 0;
  Eigen::Vector2d mean_p = Eigen::Vector2d::Zero();
  for (size_t i = begin; i < end; ++i) {
    mean_t += points[i].time_s;
    mean_p += points[i].map;
  }
  mean_t /= fit.points;
  mean_p /= fit.points;
  Eigen::Vector2d stp = Eigen::Vector2d::Zero();
  for (size_t i = begin; i < end; ++i) {
    const double dt = points[i].time_s - mean_t;
    fit.stt += dt * dt;
    stp += dt * (points[i].map - mean_p);
  }
  if (fit.stt > 0) fit.velocity = stp / fit.stt;
  for (size_t i = begin; i < end; ++i) {
    const Eigen::Vector2d line = mean_p + fit.velocity * (points[i].time_s - mean_t);
    fit.residual_squares += (points[i].map - line).squaredNorm();
  }
  return fit;
}

// The path's pieces of `window_s` (a last one shorter than half of it joins the one before), as
// [begin, end) index ranges.
std::vector<std::pair<size_t, size_t>> Pieces(const std::vector<TrackPoint>& points,
                                              double window_s) {
  std::vector<std::pair<size_t, size_t>> pieces;
  size_t begin = 0;
  for (size_t i = 1; i <= points.size(); ++i) {
    if (i == points.size() || points[i].time_s - points[begin].time_s >= window_s) {
      pieces.emplace_back(begin, i);
      begin = i;
    }
  }
  if (pieces.size() >= 2) {
    const auto& last = pieces.back();
    if (points[last.second - 1].time_s - points[last.first].time_s < 0.5 * window_s) {
      pieces[pieces.size() - 2].second = last.second;
      pieces.pop_back();
    }
  }
  return pieces;
}

// jitter and steadiness (confidence.h); false when no piece has 3 observations.
bool MotionFactors(const std::vector<TrackPoint>& points, double window_s, double* jitter,
                   double* steadiness) {
  std::vector<PieceFit> fits;
  double residual_squares = 0;
  int degrees = 0;  // per axis
  for (const auto& [begin, end] : Pieces(points, window_s)) {
    if (end - begin < 3) continue;
    fits.push_back(FitPiece(points, begin, end));
    if (!(fits.back().stt > 0)) {
      fits.pop_back();
      continue;
    }
    residual_squares += fits.back().residual_squares;
    degrees += fits.back().points - 2;
  }
  if (fits.empty() || degrees <= 0) return false;
  const double sigma2 = residual_squares / (2.0 * degrees);  // per axis
  double speed2 = 0;
  int weight = 0;
  for (const PieceFit& f : fits) {
    speed2 += f.points * (f.velocity.squaredNorm() - 2 * sigma2 / f.stt);
    weight += f.points;
  }
  const double step2 = std::max(0.0, speed2 / weight) * window_s * window_s;
  const double scatter2 = 2 * sigma2;
  *jitter = step2 + scatter2 > 0 ? step2 / (step2 + scatter2) : 0;
  int turns = 0, reversals = 0;
  const auto significant = [&](const PieceFit& f) {
    return f.velocity.squaredNorm() > 4 * 2 * sigma2 / f.stt;  // beyond two standard errors
  };
  for (size_t i = 1; i < fits.size(); ++i) {
    if (!significant(fits[i - 1]) || !significant(fits[i])) continue;
    ++turns;
    reversals += fits[i - 1].velocity.dot(fits[i].velocity) < 0;
  }
  *steadiness = turns > 0 ? 1.0 - static_cast<double>(reversals) / turns : 1;
  return true;
}

}  // namespace

Status ConfidenceOptions::Validate() const {
  if (!(seen_scale_s > 0) || !(features_scale > 0)) {
    return InvalidArgumentError("confidence options: seen_scale_s and features_scale must be > 0");
  }
  if (!(plausible_speed_mps > 0) || !(max_speed_mps > plausible_speed_mps)) {
    return InvalidArgumentError(
        "confidence options: 0 < plausible_speed_mps < max_speed_mps is required");
  }
  if (!(min_confidence >= 0 && min_confidence <= 1)) {
    return InvalidArgumentError("confidence options: min_confidence must be in [0, 1]");
  }
  return {};
}

ConfidenceFactors AssessTrack(const mission::ActivityTrack& track, const TrackEvidence& evidence,
                              const ConfidenceOptions& options) {
  ConfidenceFactors f;
  if (track.speed_mps) {
    const double v = *track.speed_mps;
    f.plausible = !(v > options.max_speed_mps);
    f.speed = std::clamp(
        (options.max_speed_mps - v) / (options.max_speed_mps - options.plausible_speed_mps), 0.0,
        1.0);
  }
  const double duration = track.end_s - track.start_s;
  f.seen = duration > 0 ? 1 - std::exp(-duration / options.seen_scale_s) : 0;
  // Interpolated points lie on a line by construction: the motion is judged on the seen ones.
  std::vector<TrackPoint> seen;
  seen.reserve(track.points.size());
  std::copy_if(track.points.begin(), track.points.end(), std::back_inserter(seen),
               [](const TrackPoint& p) { return !p.interpolated; });
  if (!MotionFactors(seen, options.fit_window_s, &f.jitter, &f.steadiness)) {
    f.jitter = 0.5;  // unmeasured: no evidence either way
    f.steadiness = 1;
  }
  f.motion = f.jitter * f.steadiness;
  if (evidence.observations > 0) {
    const double per_observation = static_cast<double>(evidence.feature_sightings) /
                                   static_cast<double>(evidence.observations);
    f.features = 1 - std::exp(-per_observation / options.features_scale);
  }
  if (evidence.looked > 0) {
    f.change = static_cast<double>(evidence.changed) / static_cast<double>(evidence.looked);
  }
  f.support = 1 - (1 - f.features) * (1 - f.change);
  f.confidence = std::cbrt(f.seen * f.motion * f.support) * f.speed;
  // A path with non-finite parts proves nothing (std::clamp would pass a NaN through).
  if (!f.plausible || !std::isfinite(f.confidence)) f.confidence = 0;
  f.confidence = std::clamp(f.confidence, 0.0, 1.0);
  return f;
}

bool PassesConfidence(const mission::ActivityTrack& track, double min_confidence) {
  return min_confidence <= 0 || (track.confidence && *track.confidence >= min_confidence);
}

ConfidenceSpread SpreadOf(const std::vector<mission::ActivityTrack>& tracks) {
  ConfidenceSpread spread;
  for (const mission::ActivityTrack& t : tracks) {
    if (!t.confidence) {
      ++spread.unknown;
    } else if (*t.confidence >= 0.8) {
      ++spread.high;
    } else if (*t.confidence >= 0.5) {
      ++spread.medium;
    } else {
      ++spread.low;
    }
  }
  return spread;
}

}  // namespace saker::activity
