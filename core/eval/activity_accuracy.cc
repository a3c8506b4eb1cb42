#include "core/eval/activity_accuracy.h"

#include "core/activity/activity.h"
#include "core/util/statistics.h"
#include "core/util/timer.h"

#include <Eigen/Geometry>
#include <Eigen/LU>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <sstream>

namespace saker::eval {
namespace {

constexpr double kGatePx = 12;         // a track point follows a truth target this close
constexpr double kPickToleranceM = 5;  // map units (metres when geo-referenced)
constexpr double kPickWindowS = 0.5;   // the picked observation's time against the truth's

// The truth target a track follows on most of its observations, or -1.
int MatchTarget(const mission::ActivityTrack& track, const sim::Truth& truth) {
  std::map<int, int> votes;
  for (const mission::TrackPoint& p : track.points) {
    if (p.frame < 0 || static_cast<size_t>(p.frame) >= truth.frames.size()) continue;
    int best = -1;
    double best_d = kGatePx;
    for (size_t t = 0; t < truth.targets.size(); ++t) {
      const sim::TargetSampleTruth& s = truth.targets[t].samples[static_cast<size_t>(p.frame)];
      if (!s.visible) continue;
      const double d = (s.image_px - p.image).norm();
      if (d < best_d) best_d = d, best = static_cast<int>(t);
    }
    if (best >= 0) ++votes[best];
  }
  for (const auto& [target, n] : votes) {
    if (2 * n > static_cast<int>(track.points.size())) return target;
  }
  return -1;
}

// InvalidArgument unless `truth` describes the mission's video: its frames, its size and a sample
// of every target in every frame.
Status CheckTruthFits(const mission::Mission& mission, const sim::Truth& truth) {
  if (truth.frames.size() != mission.frames.size() || truth.width != mission.source.width ||
      truth.height != mission.source.height) {
    return InvalidArgumentError("evaluate: the truth does not describe this mission's video (" +
                                std::to_string(truth.frames.size()) + " frames of " +
                                std::to_string(truth.width) + "x" + std::to_string(truth.height) +
                                " against " + std::to_string(mission.frames.size()) + " of " +
                                std::to_string(mission.source.width) + "x" +
                                std::to_string(mission.source.height) + ")");
  }
  for (const sim::TargetTruth& target : truth.targets) {
    if (target.samples.size() != truth.frames.size()) {
      return InvalidArgumentError("evaluate: truth target " + std::to_string(target.id) +
                                  " does not have a sample per frame");
    }
  }
  return Status::Ok();
}

// The truth as a mission of frames only: every frame's footprint on the truth ground.
mission::Mission TruthCoverMission(const sim::Truth& truth) {
  mission::Mission truth_cover;
  truth_cover.source.width = truth.width;
  truth_cover.source.height = truth.height;
  for (const sim::FrameTruth& f : truth.frames) {
    mission::FrameRecord record;
    record.index = f.index;
    record.time_s = f.time_s;
    if (!f.blank) record.map_from_frame = f.frame_from_ground.inverse();
    truth_cover.frames.push_back(record);
  }
  return truth_cover;
}

// The 1-based number of the visit nearest in time to `time_s`.
int NearestVisit(const std::vector<activity::CoverageIndex::Interval>& visits, double time_s) {
  int truth_visit = 1;
  double best = std::numeric_limits<double>::infinity();
  for (size_t v = 0; v < visits.size(); ++v) {
    const double off = std::max({0.0, visits[v].start_s - time_s, time_s - visits[v].end_s});
    if (off < best) best = off, truth_visit = static_cast<int>(v) + 1;
  }
  return truth_visit;
}

}  // namespace

StatusOr<ActivityAccuracy> EvaluateActivity(const mission::Mission& mission,
                                            const sim::Truth& truth, double visit_gap_s) {
  SAKER_RETURN_IF_ERROR(CheckTruthFits(mission, truth));
  // The truth's coverage: every frame's footprint on the truth ground, for the truth's visits.
  const mission::Mission truth_cover = TruthCoverMission(truth);
  const activity::CoverageIndex truth_coverage(truth_cover, 5);

  ActivityAccuracy a;
  a.tracks = static_cast<int64_t>(mission.tracks.size());
  std::vector<double> speed_errors, relative, direction_errors, pick_times;
  int64_t visits_agree = 0, picks_ok = 0;
  const activity::TrackIndex index(&mission.tracks);
  std::vector<int> matches;
  for (const mission::ActivityTrack& track : mission.tracks) {
    matches.push_back(MatchTarget(track, truth));
  }
  for (size_t i = 0; i < mission.tracks.size(); ++i) {
    const mission::ActivityTrack& track = mission.tracks[i];
    const int target = matches[i];
    if (target < 0) continue;
    ++a.matched;
    const std::vector<sim::TargetSampleTruth>& samples =
        truth.targets[static_cast<size_t>(target)].samples;
    const int64_t first = track.points.front().frame, last = track.points.back().frame;
    // Truth path length and displacement over the track's span.
    double length = 0;
    for (int64_t f = first; f < last; ++f) {
      length +=
          (samples[static_cast<size_t>(f + 1)].ground_m - samples[static_cast<size_t>(f)].ground_m)
              .norm();
    }
    const double duration = truth.frames[static_cast<size_t>(last)].time_s -
                            truth.frames[static_cast<size_t>(first)].time_s;
    const Eigen::Vector2d displacement =
        samples[static_cast<size_t>(last)].ground_m - samples[static_cast<size_t>(first)].ground_m;
    if (track.speed_mps && duration > 0) {
      const double truth_speed = length / duration;
      if (truth_speed > 0.3) {
        ++a.compared_speed;
        speed_errors.push_back(std::abs(*track.speed_mps - truth_speed));
        relative.push_back(std::abs(*track.speed_mps - truth_speed) / truth_speed);
      }
    }
    if (displacement.norm() >= 5 && mission.map.geo_referenced) {
      ++a.compared_direction;
      const double truth_heading = activity::HeadingDegrees(displacement, true);
      double d = std::abs(track.heading_deg - truth_heading);
      direction_errors.push_back(std::min(d, 360 - d));
    }
    // Visit: the truth's passes over the target's ground position at the track's middle.
    const mission::TrackPoint& middle = track.points[track.points.size() / 2];
    const auto visits =
        truth_coverage.Visits(samples[static_cast<size_t>(middle.frame)].ground_m, visit_gap_s);
    if (!visits.empty()) {
      ++a.compared_visit;
      visits_agree += NearestVisit(visits, middle.time_s) == track.visit;
    }
    // Pick where the mosaic shows the truth's position of the middle observation: the truth's
    // image position through the frame's own homography (the mosaic's absolute accuracy is
    // measured separately).
    const mission::FrameRecord& frame = mission.frames[static_cast<size_t>(middle.frame)];
    if (!frame.map_from_frame) continue;
    const Eigen::Vector2d at =
        (*frame.map_from_frame * samples[static_cast<size_t>(middle.frame)].image_px.homogeneous())
            .hnormalized();
    ++a.picks;
    const Stopwatch watch;
    // Other targets cross the same places at other times: like the analyst with the GUI's time
    // filter, pick among the tracks seen around that moment.
    const double t = middle.time_s;
    const std::optional<activity::Pick> pick = index.Nearest(at, kPickToleranceM, [&](size_t k) {
      return mission.tracks[k].start_s <= t + kPickWindowS &&
             mission.tracks[k].end_s >= t - kPickWindowS;
    });
    pick_times.push_back(watch.ElapsedUs());
    // Right: an observation of the same truth target (a target may have more than one track),
    // at about the same time, on the target.
    if (!pick || matches[pick->track] != target) continue;
    const mission::TrackPoint& picked = mission.tracks[pick->track].points[pick->point];
    const bool in_time = std::abs(picked.time_s - middle.time_s) <= kPickWindowS;
    const bool on_target =
        (samples[static_cast<size_t>(picked.frame)].image_px - picked.image).norm() <= kGatePx;
    picks_ok += in_time && on_target;
  }
  a.speed_median_error_mps = Quantile(speed_errors, 0.5);
  a.speed_p90_error_mps = Quantile(speed_errors, 0.9);
  a.speed_median_relative = Quantile(relative, 0.5);
  a.speed_p90_relative = Quantile(relative, 0.9);
  a.speed_relative_errors = std::move(relative);
  a.direction_median_error_deg = Quantile(direction_errors, 0.5);
  a.direction_p90_error_deg = Quantile(direction_errors, 0.9);
  a.visit_agreement = a.compared_visit > 0 ? static_cast<double>(visits_agree) /
                                                 static_cast<double>(a.compared_visit)
                                           : 0;
  a.pick_accuracy = a.picks > 0 ? static_cast<double>(picks_ok) / static_cast<double>(a.picks) : 0;
  a.pick_median_us = Quantile(pick_times, 0.5);
  return a;
}

nlohmann::json ActivityAccuracyToJson(const ActivityAccuracy& a) {
  return {{"tracks", a.tracks},
          {"matched", a.matched},
          {"speed",
           {{"compared", a.compared_speed},
            {"median_error_mps", a.speed_median_error_mps},
            {"p90_error_mps", a.speed_p90_error_mps},
            {"median_relative_error", a.speed_median_relative},
            {"p90_relative_error", a.speed_p90_relative}}},
          {"direction",
           {{"compared", a.compared_direction},
            {"median_error_deg", a.direction_median_error_deg},
            {"p90_error_deg", a.direction_p90_error_deg}}},
          {"visit", {{"compared", a.compared_visit}, {"agreement", a.visit_agreement}}},
          {"pick",
           {{"picks", a.picks}, {"accuracy", a.pick_accuracy}, {"median_us", a.pick_median_us}}}};
}

std::string ActivityAccuracyToText(const ActivityAccuracy& a) {
  char text[768];
  std::snprintf(
      text, sizeof(text),
      "activity: %lld tracks, %lld following a truth target\n"
      "  speed: median error %.2f m/s (%.0f %%), 90th percentile %.2f m/s (%.0f %%) over "
      "%lld tracks\n"
      "  direction: median error %.1f deg, 90th percentile %.1f deg over %lld tracks\n"
      "  visit: %.0f %% agree with the truth over %lld tracks\n"
      "  pick at the truth position: %.0f %% right (same target, within 0.5 s and 12 px) of "
      "%lld, %.1f us each\n",
      static_cast<long long>(a.tracks), static_cast<long long>(a.matched), a.speed_median_error_mps,
      100 * a.speed_median_relative, a.speed_p90_error_mps, 100 * a.speed_p90_relative,
      static_cast<long long>(a.compared_speed), a.direction_median_error_deg,
      a.direction_p90_error_deg, static_cast<long long>(a.compared_direction),
      100 * a.visit_agreement, static_cast<long long>(a.compared_visit), 100 * a.pick_accuracy,
      static_cast<long long>(a.picks), a.pick_median_us);
  return text;
}

}  // namespace saker::eval
