#include "core/eval/front_end_accuracy.h"

#include "core/sim/camera.h"
#include "core/sim/frame_renderer.h"
#include "core/util/statistics.h"

#include <Eigen/Geometry>
#include <Eigen/LU>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <sstream>

namespace saker::eval {
namespace {

// The pairing distance for a target in a frame: the option, or half the target's length in the
// image plus a margin when that is larger (features on a car's bumper are a detection of the car).
double Gate(const sim::TargetTruth& target, const sim::TargetSampleTruth& sample,
            const sim::FrameTruth& frame, const FrontEndEvaluationOptions& options) {
  const Eigen::Matrix3d& h = frame.frame_from_ground;
  // Pixels per ground metre where the target is: the square root of the Jacobian determinant of
  // the homography at its ground point (an oblique view's far rows have fewer).
  const Eigen::Vector3d q = h * sample.ground_m.homogeneous();
  const Eigen::Vector2d image = q.head<2>() / q.z();
  Eigen::Matrix2d jacobian = h.topLeftCorner<2, 2>() - image * h.block<1, 2>(2, 0);
  jacobian /= q.z();
  const double scale = std::sqrt(std::abs(jacobian.determinant()));
  return std::max(options.gate_px, 0.5 * target.length_m * scale + 4.0);
}

std::array<Eigen::Vector2d, 4> GroundCorners(const sim::Truth& truth, const sim::FrameTruth& frame,
                                             double w, double h) {
  std::array<Eigen::Vector2d, 4> corners = {
      Eigen::Vector2d(-0.5, -0.5), Eigen::Vector2d(w - 0.5, -0.5),
      Eigen::Vector2d(w - 0.5, h - 0.5), Eigen::Vector2d(-0.5, h - 0.5)};
  sim::CameraIntrinsics camera;
  camera.width = truth.width;
  camera.height = truth.height;
  camera.hfov_deg = frame.hfov_deg;
  const std::optional<sim::ViewGeometry> view = ViewOfHomography(camera, frame.frame_from_ground);
  if (!view) return corners;
  const double least_sin = 1.0 / std::hypot(1.0, sim::FrameRenderer::kHazeStartHeights);
  for (Eigen::Vector2d& c : corners) {
    while (c.y() < h - 1 && view->SinDepression(c.x(), c.y()) < least_sin) c.y() += 1;
  }
  return corners;
}

HomographyAccuracy EvaluateHomographies(const frontend::FrontEndResult& result,
                                        const sim::Truth& truth) {
  HomographyAccuracy accuracy;
  std::vector<double> errors;
  const double w = truth.width, h = truth.height;
  for (size_t i = 1; i < result.frames.size() && i < truth.frames.size(); ++i) {
    // The frame's corners; in a view reaching the horizon, each moved down its column to where the
    // previous frame shows ground nearer than the haze.
    const std::array<Eigen::Vector2d, 4> corners = GroundCorners(truth, truth.frames[i - 1], w, h);
    const frontend::FrameResult& frame = result.frames[i];
    if (truth.frames[i].blank || truth.frames[i - 1].blank) continue;
    if (!frame.homography_ok) {
      ++accuracy.failed;
      continue;
    }
    const Eigen::Matrix3d truth_map =
        truth.frames[i].frame_from_ground * truth.frames[i - 1].frame_from_ground.inverse();
    double error = 0;
    for (const Eigen::Vector2d& c : corners) {
      error += ((frame.current_from_previous * c.homogeneous()).hnormalized() -
                (truth_map * c.homogeneous()).hnormalized())
                   .norm() /
               4.0;
    }
    errors.push_back(error);
  }
  accuracy.frames = static_cast<int64_t>(errors.size());
  if (!errors.empty()) {
    double sum = 0;
    for (double e : errors) sum += e;
    accuracy.mean_px = sum / static_cast<double>(errors.size());
    accuracy.median_px = Median(errors);
    accuracy.p95_px = Quantile(errors, 0.95);
    accuracy.max_px = *std::max_element(errors.begin(), errors.end());
  }
  accuracy.errors_px = std::move(errors);
  return accuracy;
}

enum class Classes { kAll, kVehicles, kPeople };

// The sightings of a target: frame ranges [begin, end) in which it is in view, joined across
// shorter absences (a car under a tree); a target that leaves the view and comes back much later
// (the aircraft's next pass) is seen again.
std::vector<std::pair<int64_t, int64_t>> Sightings(const sim::TargetTruth& target, int max_gap) {
  std::vector<std::pair<int64_t, int64_t>> sightings;
  int64_t last_visible = -1;
  for (size_t f = 0; f < target.samples.size(); ++f) {
    if (!target.samples[f].visible) continue;
    const int64_t frame = static_cast<int64_t>(f);
    if (sightings.empty() || frame - last_visible > static_cast<int64_t>(max_gap) + 1) {
      sightings.emplace_back(frame, frame + 1);
    }
    sightings.back().second = frame + 1;
    last_visible = frame;
  }
  return sightings;
}

// The truth targets of `classes`.
std::vector<const sim::TargetTruth*> TruthTargets(const sim::Truth& truth, Classes classes) {
  std::vector<const sim::TargetTruth*> considered;
  for (const sim::TargetTruth& t : truth.targets) {
    const bool person = t.target_class == "person";
    if (classes == Classes::kAll || (classes == Classes::kPeople) == person)
      considered.push_back(&t);
  }
  return considered;
}

// Whether a truth target is a mover in `frame`: in view, at least options.min_speed_mps.
bool IsMover(const sim::TargetTruth& t, size_t frame, const FrontEndEvaluationOptions& options) {
  const sim::TargetSampleTruth& s = t.samples[frame];
  return s.visible && s.velocity_mps.norm() >= options.min_speed_mps;
}

// Which target tracks were paired with which truth targets, and in how many frames.
struct Pairing {
  // (track, truth) -> the frames they were paired in, increasing.
  std::map<std::pair<size_t, size_t>, std::vector<int64_t>> track_truth_pairs;
  std::vector<int> track_paired_frames;  // per track
};

// Greedy pairing per frame, nearest first, against every considered truth target in view; a
// pair with a non-mover still makes a detection correct (a car that has just stopped). The
// detections, the pairs with movers and the movers' frames are counted into `a`.
Pairing PairDetections(const frontend::FrontEndResult& result, const sim::Truth& truth,
                       const std::vector<const sim::TargetTruth*>& considered,
                       const FrontEndEvaluationOptions& options, DetectionAccuracy* a) {
  const size_t frames = truth.frames.size();
  // Detections per frame: (track index, observation index).
  std::vector<std::vector<std::pair<size_t, size_t>>> detections(frames);
  for (size_t k = 0; k < result.targets.size(); ++k) {
    for (size_t o = 0; o < result.targets[k].observations.size(); ++o) {
      const int64_t f = result.targets[k].observations[o].frame;
      if (f >= 0 && static_cast<size_t>(f) < frames)
        detections[static_cast<size_t>(f)].emplace_back(k, o);
    }
  }
  Pairing pairing;
  pairing.track_paired_frames.assign(result.targets.size(), 0);
  for (size_t f = 0; f < frames; ++f) {
    struct Candidate {
      double distance;
      size_t detection, truth;
    };
    std::vector<Candidate> candidates;
    for (size_t d = 0; d < detections[f].size(); ++d) {
      const auto [k, o] = detections[f][d];
      const Eigen::Vector2d& p = result.targets[k].observations[o].position;
      for (size_t t = 0; t < considered.size(); ++t) {
        const sim::TargetSampleTruth& s = considered[t]->samples[f];
        if (!s.visible) continue;
        const double distance = (p - s.image_px).norm();
        if (distance <= Gate(*considered[t], s, truth.frames[f], options))
          candidates.push_back({distance, d, t});
      }
    }
    std::sort(candidates.begin(), candidates.end(),
              [](const Candidate& x, const Candidate& y) { return x.distance < y.distance; });
    std::vector<bool> detection_used(detections[f].size(), false),
        truth_used(considered.size(), false);
    for (const Candidate& c : candidates) {
      if (detection_used[c.detection] || truth_used[c.truth]) continue;
      detection_used[c.detection] = truth_used[c.truth] = true;
      const size_t k = detections[f][c.detection].first;
      ++pairing.track_paired_frames[k];
      pairing.track_truth_pairs[{k, c.truth}].push_back(static_cast<int64_t>(f));
      if (IsMover(*considered[c.truth], f, options)) ++a->paired;
    }
    a->detections += static_cast<int64_t>(detections[f].size());
    for (size_t t = 0; t < considered.size(); ++t)
      a->truth_mover_frames += IsMover(*considered[t], f, options);
  }
  return pairing;
}

// The overlay mask that applies to `frame` (nullptr: none); the masks are in frame order.
const track::OverlayMask* MaskAt(const std::vector<track::OverlayMask>& masks, int64_t frame) {
  const auto it =
      std::upper_bound(masks.begin(), masks.end(), frame,
                       [](int64_t f, const track::OverlayMask& m) { return f < m.first_frame; });
  if (it == masks.begin()) return nullptr;
  const track::OverlayMask& mask = *std::prev(it);
  return frame <= mask.last_frame ? &mask : nullptr;
}

OverlayMaskAccuracy EvaluateOverlayMask(const frontend::FrontEndResult& result,
                                        const sim::Truth& truth) {
  OverlayMaskAccuracy a;
  if (truth.frames.empty()) return a;
  double masked = 0, off_overlay = 0, covered = 0;
  for (const track::OverlayMask& mask : result.overlays) {
    if (mask.cells.empty()) continue;
    const int64_t frames = std::max<int64_t>(0, mask.last_frame - mask.first_frame + 1);
    int64_t on = 0, off = 0, truth_on = 0;
    for (int y = 0; y < mask.cells.rows; ++y) {
      for (int x = 0; x < mask.cells.cols; ++x) {
        const Eigen::Vector2d centre((x + 0.5) * mask.cell_px - 0.5,
                                     (y + 0.5) * mask.cell_px - 0.5);
        const bool overlay = truth.OnOverlay(centre);
        const bool set = mask.cells.at<uint8_t>(y, x) != 0;
        on += set;
        off += set && !overlay;
        truth_on += overlay && set;
      }
    }
    const double cells = static_cast<double>(mask.cells.total());
    a.frames += frames;
    masked += static_cast<double>(frames) * static_cast<double>(on) / cells;
    off_overlay += static_cast<double>(frames) * static_cast<double>(off) / cells;
    covered += static_cast<double>(frames) * static_cast<double>(truth_on);
  }
  const double frames = static_cast<double>(truth.frames.size());
  a.masked_fraction = masked / frames;
  a.off_overlay_fraction = off_overlay / frames;
  if (!truth.overlays.empty()) {
    // Frames without a mask cover none of the overlays.
    int64_t truth_cells_per_frame = 0;
    const int cell =
        result.overlays.empty() ? track::OverlayOptions{}.cell_px : result.overlays.front().cell_px;
    for (int y = 0; y * cell < truth.height; ++y) {
      for (int x = 0; x * cell < truth.width; ++x) {
        truth_cells_per_frame += truth.OnOverlay({(x + 0.5) * cell - 0.5, (y + 0.5) * cell - 0.5});
      }
    }
    const double all = static_cast<double>(truth_cells_per_frame) * frames;
    a.overlay_covered = all > 0 ? covered / all : 1.0;
  }
  return a;
}

// Track-level figures, per sighting of a considered truth target long enough to count: whether
// a track found it, and how late (appended to `latencies`).
void ScoreSightings(const frontend::FrontEndResult& result, const sim::Truth& truth,
                    const std::vector<const sim::TargetTruth*>& considered, const Pairing& pairing,
                    const FrontEndEvaluationOptions& options, DetectionAccuracy* a,
                    std::vector<double>* latencies) {
  const double fps = truth.fps > 0 ? truth.fps : 25;
  for (size_t t = 0; t < considered.size(); ++t) {
    for (const auto& [begin, end] : Sightings(*considered[t], options.max_sighting_gap_frames)) {
      int mover_frames = 0;
      int64_t first_mover = -1;
      int on_mask = 0;
      for (int64_t f = begin; f < end; ++f) {
        if (IsMover(*considered[t], static_cast<size_t>(f), options)) {
          ++mover_frames;
          if (first_mover < 0) first_mover = f;
          const track::OverlayMask* mask = MaskAt(result.overlays, f);
          on_mask += mask != nullptr &&
                     mask->Contains(considered[t]->samples[static_cast<size_t>(f)].image_px);
        }
      }
      if (mover_frames < options.min_mover_frames) continue;
      ++a->truth_targets;
      SightingOutcome outcome{considered[t]->id, considered[t]->target_class, begin, end,
                              mover_frames};
      outcome.on_mask_frames = on_mask;
      for (size_t k = 0; k < result.targets.size(); ++k) {
        const auto it = pairing.track_truth_pairs.find({k, t});
        if (it == pairing.track_truth_pairs.end()) continue;
        const std::vector<int64_t>& paired = it->second;
        const auto first = std::lower_bound(paired.begin(), paired.end(), begin);
        const auto last = std::lower_bound(paired.begin(), paired.end(), end);
        if (last == first) continue;
        ++outcome.tracks_paired;
        if (last - first > outcome.best_track_frames) {
          outcome.best_track_frames = static_cast<int>(last - first);
          outcome.best_track = static_cast<int64_t>(result.targets[k].id);
        }
        if (!outcome.found && 2 * (last - first) >= mover_frames) {
          outcome.found = true;
          outcome.latency_s = static_cast<double>(std::max<int64_t>(0, *first - first_mover)) / fps;
          ++a->found_targets;
          latencies->push_back(outcome.latency_s);
        }
      }
      a->sightings.push_back(std::move(outcome));
    }
  }
}

// Per target track: correct when paired in at least half of its observations, and the truth
// target it was paired with most.
void ScoreTracks(const frontend::FrontEndResult& result, const sim::Truth& truth,
                 const std::vector<const sim::TargetTruth*>& considered, const Pairing& pairing,
                 DetectionAccuracy* a) {
  for (size_t k = 0; k < result.targets.size(); ++k) {
    const track::TargetTrack& track = result.targets[k];
    ++a->detected_tracks;
    TrackOutcome outcome;
    outcome.track_id = static_cast<int64_t>(track.id);
    outcome.first_frame = track.observations.front().frame;
    outcome.last_frame = track.observations.back().frame;
    outcome.observations = static_cast<int64_t>(track.observations.size());
    outcome.from_features = track.max_features > 0;
    outcome.first_position = track.observations.front().position;
    for (const track::TargetObservation& o : track.observations) {
      outcome.on_overlay += truth.OnOverlay(o.position);
    }
    outcome.correct =
        2 * pairing.track_paired_frames[k] >= static_cast<int>(track.observations.size());
    for (const auto& [key, frames_paired] : pairing.track_truth_pairs) {
      if (key.first == k && static_cast<int>(frames_paired.size()) > outcome.best_target_frames) {
        outcome.best_target_frames = static_cast<int>(frames_paired.size());
        outcome.best_target = considered[key.second]->id;
      }
    }
    if (outcome.correct) ++a->correct_tracks;
    a->tracks.push_back(outcome);
  }
}

DetectionAccuracy EvaluateTargets(const frontend::FrontEndResult& result, const sim::Truth& truth,
                                  const FrontEndEvaluationOptions& options, Classes classes) {
  DetectionAccuracy a;
  const std::vector<const sim::TargetTruth*> considered = TruthTargets(truth, classes);
  const Pairing pairing = PairDetections(result, truth, considered, options, &a);
  std::vector<double> latencies;
  ScoreSightings(result, truth, considered, pairing, options, &a, &latencies);
  ScoreTracks(result, truth, considered, pairing, &a);
  a.track_recall = a.truth_targets > 0
                       ? static_cast<double>(a.found_targets) / static_cast<double>(a.truth_targets)
                       : 1.0;
  a.track_precision = a.detected_tracks > 0 ? static_cast<double>(a.correct_tracks) /
                                                  static_cast<double>(a.detected_tracks)
                                            : 1.0;
  a.frame_recall = a.truth_mover_frames > 0
                       ? static_cast<double>(a.paired) / static_cast<double>(a.truth_mover_frames)
                       : 1.0;
  for (int n : pairing.track_paired_frames) a.paired_detections += n;
  a.frame_precision = a.detections > 0 ? static_cast<double>(a.paired_detections) /
                                             static_cast<double>(a.detections)
                                       : 1.0;
  a.median_latency_s = Median(latencies);
  return a;
}

nlohmann::json DetectionToJson(const DetectionAccuracy& a) {
  return {{"truth_targets", a.truth_targets},
          {"found_targets", a.found_targets},
          {"detected_tracks", a.detected_tracks},
          {"correct_tracks", a.correct_tracks},
          {"track_recall", a.track_recall},
          {"track_precision", a.track_precision},
          {"truth_mover_frames", a.truth_mover_frames},
          {"detections", a.detections},
          {"frame_recall", a.frame_recall},
          {"frame_precision", a.frame_precision},
          {"median_latency_s", a.median_latency_s}};
}

// The figures, plus every sighting and every track.
nlohmann::json DetectionOutcomesToJson(const DetectionAccuracy& a) {
  nlohmann::json j = DetectionToJson(a);
  j["sightings"] = nlohmann::json::array();
  for (const SightingOutcome& s : a.sightings) {
    j["sightings"].push_back({{"target", s.target_id},
                              {"class", s.target_class},
                              {"begin_frame", s.begin},
                              {"end_frame", s.end},
                              {"mover_frames", s.mover_frames},
                              {"found", s.found},
                              {"best_track", s.best_track},
                              {"best_track_frames", s.best_track_frames},
                              {"tracks_paired", s.tracks_paired},
                              {"on_mask_frames", s.on_mask_frames}});
  }
  j["tracks"] = nlohmann::json::array();
  for (const TrackOutcome& t : a.tracks) {
    j["tracks"].push_back({{"track", t.track_id},
                           {"first_frame", t.first_frame},
                           {"last_frame", t.last_frame},
                           {"observations", t.observations},
                           {"from_features", t.from_features},
                           {"correct", t.correct},
                           {"best_target", t.best_target},
                           {"best_target_frames", t.best_target_frames},
                           {"on_overlay", t.on_overlay}});
  }
  return j;
}

}  // namespace

StatusOr<FrontEndEvaluation> EvaluateFrontEnd(const frontend::FrontEndResult& result,
                                              const sim::Truth& truth,
                                              const FrontEndEvaluationOptions& options) {
  if (result.frames.size() != truth.frames.size()) {
    return InvalidArgumentError("evaluate: the video has " + std::to_string(result.frames.size()) +
                                " frames but the truth describes " +
                                std::to_string(truth.frames.size()));
  }
  if (result.video.width != truth.width || result.video.height != truth.height) {
    return InvalidArgumentError("evaluate: the video is " + std::to_string(result.video.width) +
                                "x" + std::to_string(result.video.height) + " but the truth is " +
                                std::to_string(truth.width) + "x" + std::to_string(truth.height));
  }
  FrontEndEvaluation e;
  e.homography = EvaluateHomographies(result, truth);
  e.overlay_mask = EvaluateOverlayMask(result, truth);
  e.targets = EvaluateTargets(result, truth, options, Classes::kAll);
  e.vehicles = EvaluateTargets(result, truth, options, Classes::kVehicles);
  e.people = EvaluateTargets(result, truth, options, Classes::kPeople);
  e.key_frames = static_cast<int64_t>(result.key_frames.size());
  e.chain_breaks = static_cast<int64_t>(result.breaks.size());
  return e;
}

nlohmann::json FrontEndEvaluationToJson(const FrontEndEvaluation& e) {
  return {{"homography",
           {{"frames", e.homography.frames},
            {"failed", e.homography.failed},
            {"median_px", e.homography.median_px},
            {"mean_px", e.homography.mean_px},
            {"p95_px", e.homography.p95_px},
            {"max_px", e.homography.max_px}}},
          {"targets", DetectionOutcomesToJson(e.targets)},
          {"vehicles", DetectionToJson(e.vehicles)},
          {"people", DetectionToJson(e.people)},
          {"overlay_mask",
           {{"frames", e.overlay_mask.frames},
            {"masked_fraction", e.overlay_mask.masked_fraction},
            {"off_overlay_fraction", e.overlay_mask.off_overlay_fraction},
            {"overlay_covered", e.overlay_mask.overlay_covered}}},
          {"key_frames", e.key_frames},
          {"chain_breaks", e.chain_breaks}};
}

std::string FrontEndEvaluationToText(const FrontEndEvaluation& e, bool details) {
  std::ostringstream out;
  out.setf(std::ios::fixed);
  out.precision(3);
  out << "Homographies: " << e.homography.frames << " frames, corner error median "
      << e.homography.median_px << " px, mean " << e.homography.mean_px << ", 95% "
      << e.homography.p95_px << ", max " << e.homography.max_px << "; " << e.homography.failed
      << " frames without an estimate\n";
  const auto line = [&](const char* name, const DetectionAccuracy& a) {
    out << name << ": " << a.found_targets << " of " << a.truth_targets << " found (recall "
        << a.track_recall << "), " << a.correct_tracks << " of " << a.detected_tracks
        << " tracks correct (precision " << a.track_precision << "); per frame recall "
        << a.frame_recall << ", precision " << a.frame_precision << "; median latency "
        << a.median_latency_s << " s\n";
  };
  line("Targets", e.targets);
  out << "  vehicles: " << e.vehicles.found_targets << " of " << e.vehicles.truth_targets
      << " found (recall " << e.vehicles.track_recall << "), per frame recall "
      << e.vehicles.frame_recall << "\n  people:   " << e.people.found_targets << " of "
      << e.people.truth_targets << " found (recall " << e.people.track_recall
      << "), per frame recall " << e.people.frame_recall << "\n";
  out << "Key frames: " << e.key_frames << ", chain breaks: " << e.chain_breaks << "\n";
  if (e.overlay_mask.frames > 0) {
    out << "Overlay mask: in " << e.overlay_mask.frames << " frames; on average "
        << 100 * e.overlay_mask.masked_fraction << " % of the image masked, "
        << 100 * e.overlay_mask.off_overlay_fraction << " % off the overlays; "
        << 100 * e.overlay_mask.overlay_covered << " % of the overlays covered\n";
  }
  if (details) {
    for (const SightingOutcome& s : e.targets.sightings) {
      if (s.found) continue;
      out << "  missed: target " << s.target_id << " (" << s.target_class << "), frames " << s.begin
          << "-" << s.end - 1 << ", moving in " << s.mover_frames << "; ";
      if (s.best_track == 0) {
        out << "no track near it";
      } else {
        out << "best track " << s.best_track << " in " << s.best_track_frames << " frames, "
            << s.tracks_paired << " track(s) paired with it";
      }
      if (s.on_mask_frames > 0) out << "; on the overlay mask in " << s.on_mask_frames;
      out << "\n";
    }
    for (const TrackOutcome& t : e.targets.tracks) {
      if (t.correct) continue;
      out << "  false: track " << t.track_id << " ("
          << (t.from_features ? "features" : "change detection") << "), frames " << t.first_frame
          << "-" << t.last_frame << ", " << t.observations << " observations from ("
          << std::lround(t.first_position.x()) << ", " << std::lround(t.first_position.y()) << ")"
          << (t.on_overlay > 0 ? ", " + std::to_string(t.on_overlay) + " on the overlays" : "")
          << "; ";
      if (t.best_target == 0) {
        out << "paired with no target\n";
      } else {
        out << "paired with target " << t.best_target << " in " << t.best_target_frames << "\n";
      }
    }
  }
  return out.str();
}

}  // namespace saker::eval
