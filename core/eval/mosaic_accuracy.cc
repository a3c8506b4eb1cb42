#include "core/eval/mosaic_accuracy.h"

#include "core/geo/local_tangent_plane.h"
#include "core/track/homography.h"
#include "core/track/image_geometry.h"
#include "core/util/statistics.h"
#include "core/util/timer.h"

#include <Eigen/Geometry>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <random>
#include <sstream>

namespace saker::eval {
namespace {

// Errors of map_from_frame per key frame against the truth ground positions of its corners, the
// estimate first passed through `truth_from_map`.
CornerErrors Errors(const std::vector<Eigen::Matrix3d>& map_from_frame,
                    const std::vector<std::array<Eigen::Vector2d, 4>>& truth_ground,
                    const std::vector<Eigen::Matrix3d>& frame_from_truth,
                    const Eigen::Matrix3d& truth_from_map, int width, int height) {
  CornerErrors e;
  double sum_px = 0, sum_m = 0;
  int n = 0;
  const auto corners = track::ImageCorners(width, height);
  for (size_t k = 0; k < map_from_frame.size(); ++k) {
    for (int c = 0; c < 4; ++c) {
      const Eigen::Vector3d q =
          truth_from_map * map_from_frame[k] * corners[static_cast<size_t>(c)].homogeneous();
      const Eigen::Vector2d ground = q.hnormalized();
      const double m = (ground - truth_ground[k][static_cast<size_t>(c)]).norm();
      const Eigen::Vector3d image = frame_from_truth[k] * ground.homogeneous();
      const double px = (image.hnormalized() - corners[static_cast<size_t>(c)]).norm();
      sum_m += m * m;
      sum_px += px * px;
      e.max_m = std::max(e.max_m, m);
      ++n;
    }
  }
  if (n > 0) {
    e.rms_m = std::sqrt(sum_m / n);
    e.rms_px = std::sqrt(sum_px / n);
  }
  return e;
}

// The homography taking every key frame's corners in `from` to the same corners in `to` best
// (least squares over all of them).
Eigen::Matrix3d FitCorners(const std::vector<std::array<Eigen::Vector2d, 4>>& from,
                           const std::vector<std::array<Eigen::Vector2d, 4>>& to) {
  std::vector<cv::Point2d> p, q;
  for (size_t k = 0; k < from.size(); ++k) {
    for (int c = 0; c < 4; ++c) {
      p.emplace_back(from[k][static_cast<size_t>(c)].x(), from[k][static_cast<size_t>(c)].y());
      q.emplace_back(to[k][static_cast<size_t>(c)].x(), to[k][static_cast<size_t>(c)].y());
    }
  }
  Eigen::Matrix3d g = Eigen::Matrix3d::Identity();
  const cv::Mat h = cv::findHomography(p, q, 0);
  if (!h.empty()) cv::cv2eigen(h, g);
  return g;
}

// The homography from the estimated map onto the truth ground that fits all corners best.
Eigen::Matrix3d GaugeFit(const std::vector<Eigen::Matrix3d>& map_from_frame,
                         const std::vector<std::array<Eigen::Vector2d, 4>>& truth_ground, int width,
                         int height) {
  const auto corners = track::ImageCorners(width, height);
  std::vector<std::array<Eigen::Vector2d, 4>> estimated(map_from_frame.size());
  for (size_t k = 0; k < map_from_frame.size(); ++k) {
    for (int c = 0; c < 4; ++c) {
      estimated[k][static_cast<size_t>(c)] =
          track::Transfer(map_from_frame[k], corners[static_cast<size_t>(c)]);
    }
  }
  return FitCorners(estimated, truth_ground);
}

// The truth of every key frame: its ground-to-image homography and its corners on the ground.
struct KeyFrameTruth {
  std::vector<Eigen::Matrix3d> frame_from_ground;
  std::vector<std::array<Eigen::Vector2d, 4>> ground;
};
StatusOr<KeyFrameTruth> TruthOfKeyFrames(const mosaic::LinkGraph& graph, const sim::Truth& truth,
                                         const std::string& what) {
  const auto corners = track::ImageCorners(graph.image_width, graph.image_height);
  KeyFrameTruth t;
  for (size_t k = 0; k < graph.nodes.size(); ++k) {
    const int64_t f = graph.nodes[k].frame_index;
    if (f < 0 || static_cast<size_t>(f) >= truth.frames.size()) {
      return InvalidArgumentError(what + ": the truth does not cover key frame " +
                                  std::to_string(k));
    }
    t.frame_from_ground.push_back(truth.frames[static_cast<size_t>(f)].frame_from_ground);
    const Eigen::Matrix3d ground_from_frame = t.frame_from_ground.back().inverse();
    std::array<Eigen::Vector2d, 4> ground;
    for (int c = 0; c < 4; ++c) {
      ground[static_cast<size_t>(c)] =
          track::Transfer(ground_from_frame, corners[static_cast<size_t>(c)]);
    }
    t.ground.push_back(ground);
  }
  return t;
}

// Every placed frame that is not a key frame against the truth, through the key frames' gauge
// fit; the excess over the neighbouring key frames' error for frames between two of them.
StatusOr<InBetweenAccuracy> EvaluateInBetween(const mosaic::MosaicResult& mosaic,
                                              const sim::Truth& truth,
                                              const Eigen::Matrix3d& truth_from_map,
                                              const CornerErrors& key_frames_error) {
  const mosaic::LinkGraph& graph = mosaic.graph;
  const std::vector<std::optional<Eigen::Matrix3d>>& placed = mosaic.in_between.map_from_frame;
  if (placed.size() > truth.frames.size()) {
    return InvalidArgumentError("evaluate: the mosaic placed " + std::to_string(placed.size()) +
                                " frames but the truth has " + std::to_string(truth.frames.size()));
  }
  const int w = graph.image_width, h = graph.image_height;
  const auto corners = track::ImageCorners(w, h);
  // Per frame: truth ground corners and each frame's own RMS error in pixels.
  const auto frame_errors = [&](size_t f, const Eigen::Matrix3d& map_from_frame) {
    const Eigen::Matrix3d& frame_from_ground = truth.frames[f].frame_from_ground;
    const Eigen::Matrix3d ground_from_frame = frame_from_ground.inverse();
    std::array<Eigen::Vector2d, 4> ground;
    for (int c = 0; c < 4; ++c) {
      ground[static_cast<size_t>(c)] =
          track::Transfer(ground_from_frame, corners[static_cast<size_t>(c)]);
    }
    return Errors({map_from_frame}, {ground}, {frame_from_ground}, truth_from_map, w, h);
  };
  std::vector<double> key_error_px(placed.size(), -1);
  std::vector<bool> is_key(placed.size(), false);
  for (const mosaic::Node& node : graph.nodes) {
    const size_t f = static_cast<size_t>(node.frame_index);
    if (f >= placed.size()) continue;
    is_key[f] = true;
    key_error_px[f] = frame_errors(f, node.map_from_frame).rms_px;
  }
  // The nearest key frame before each frame (its error), and after.
  std::vector<double> before(placed.size(), -1), after(placed.size(), -1);
  for (size_t f = 0, last = SIZE_MAX; f < placed.size(); ++f) {
    if (is_key[f]) last = f;
    if (last != SIZE_MAX) before[f] = key_error_px[last];
  }
  for (size_t f = placed.size(), next = SIZE_MAX; f-- > 0;) {
    if (is_key[f]) next = f;
    if (next != SIZE_MAX) after[f] = key_error_px[next];
  }

  InBetweenAccuracy a;
  a.key_frames_error = key_frames_error;
  double sum_px = 0, sum_m = 0;
  int corners_counted = 0;
  std::vector<double> excess;
  for (size_t f = 0; f < placed.size(); ++f) {
    if (!placed[f] || is_key[f]) continue;
    const CornerErrors e = frame_errors(f, *placed[f]);
    ++a.frames;
    sum_px += 4 * e.rms_px * e.rms_px;
    sum_m += 4 * e.rms_m * e.rms_m;
    corners_counted += 4;
    a.frames_error.max_m = std::max(a.frames_error.max_m, e.max_m);
    if (before[f] >= 0 && after[f] >= 0) {
      excess.push_back(std::max(0.0, e.rms_px - std::max(before[f], after[f])));
    }
  }
  if (corners_counted > 0) {
    a.frames_error.rms_px = std::sqrt(sum_px / corners_counted);
    a.frames_error.rms_m = std::sqrt(sum_m / corners_counted);
  }
  a.between = static_cast<int>(excess.size());
  if (!excess.empty()) {
    a.median_excess_px = Median(excess);
    a.max_excess_px = *std::max_element(excess.begin(), excess.end());
  }
  return a;
}

}  // namespace

StatusOr<MosaicAccuracy> EvaluateMosaic(const mosaic::MosaicResult& mosaic,
                                        const sim::Truth& truth) {
  const mosaic::LinkGraph& graph = mosaic.graph;
  if (graph.image_width != truth.width || graph.image_height != truth.height) {
    return InvalidArgumentError("evaluate: the mosaic's frames are " +
                                std::to_string(graph.image_width) + "x" +
                                std::to_string(graph.image_height) + " but the truth's " +
                                std::to_string(truth.width) + "x" + std::to_string(truth.height));
  }
  MosaicAccuracy a;
  a.key_frames = static_cast<int>(graph.nodes.size());
  a.geo_referenced = graph.geo_referenced;
  a.closures = mosaic.closures;
  if (graph.nodes.empty()) return a;

  // Truth positions of every key frame's corners, on the truth ground and, when geo-referenced,
  // in the mosaic's map frame.
  std::optional<geo::LocalTangentPlane> truth_plane, map_plane;
  if (graph.geo_referenced && mosaic.origin) {
    SAKER_ASSIGN_OR_RETURN(truth_plane, geo::LocalTangentPlane::Create({truth.origin_latitude_deg,
                                                                        truth.origin_longitude_deg,
                                                                        truth.origin_height_m}));
    SAKER_ASSIGN_OR_RETURN(map_plane, geo::LocalTangentPlane::Create(*mosaic.origin));
  }
  const auto corners = track::ImageCorners(graph.image_width, graph.image_height);
  std::vector<std::array<Eigen::Vector2d, 4>> ground(graph.nodes.size()),
      in_map(graph.nodes.size());
  std::vector<Eigen::Matrix3d> frame_from_ground(graph.nodes.size()), adjusted, chained;
  for (size_t k = 0; k < graph.nodes.size(); ++k) {
    const int64_t f = graph.nodes[k].frame_index;
    if (f < 0 || static_cast<size_t>(f) >= truth.frames.size()) {
      return InvalidArgumentError("evaluate: key frame " + std::to_string(k) + " is frame " +
                                  std::to_string(f) + " but the truth has " +
                                  std::to_string(truth.frames.size()) + " frames");
    }
    frame_from_ground[k] = truth.frames[static_cast<size_t>(f)].frame_from_ground;
    const Eigen::Matrix3d ground_from_frame = frame_from_ground[k].inverse();
    for (int c = 0; c < 4; ++c) {
      ground[k][static_cast<size_t>(c)] =
          track::Transfer(ground_from_frame, corners[static_cast<size_t>(c)]);
      if (truth_plane) {
        const geo::Wgs84 w = truth_plane->Wgs84FromEnu(
            {ground[k][static_cast<size_t>(c)].x(), ground[k][static_cast<size_t>(c)].y(), 0.0});
        in_map[k][static_cast<size_t>(c)] = map_plane->EnuFromWgs84(w).head<2>();
      }
    }
    adjusted.push_back(graph.nodes[k].map_from_frame);
    chained.push_back(k < mosaic.chained.size() ? mosaic.chained[k]
                                                : graph.nodes[k].map_from_frame);
  }
  const int w = graph.image_width, h = graph.image_height;
  const Eigen::Matrix3d truth_from_adjusted = GaugeFit(adjusted, ground, w, h);
  a.before = Errors(chained, ground, frame_from_ground, GaugeFit(chained, ground, w, h), w, h);
  a.after = Errors(adjusted, ground, frame_from_ground, truth_from_adjusted, w, h);
  a.adjust_mode = mosaic.decomposition ? "decomposed" : "full";
  a.nodes = mosaic.decomposition ? mosaic.decomposition->nodes : a.key_frames;
  a.arcs = mosaic.decomposition ? mosaic.decomposition->arcs : 0;
  a.adjust_s = mosaic.timing.adjust_s;
  if (!mosaic.in_between.map_from_frame.empty()) {
    SAKER_ASSIGN_OR_RETURN(a.in_between,
                           EvaluateInBetween(mosaic, truth, truth_from_adjusted, a.after));
  }
  if (truth_plane) {
    // The map frame and the truth ground are related by geodesy alone (two tangent planes): fit
    // it on the truth corners expressed in both, no estimate involved.
    const Eigen::Matrix3d ground_from_map = FitCorners(in_map, ground);
    a.before_absolute = Errors(chained, ground, frame_from_ground, ground_from_map, w, h);
    a.after_absolute = Errors(adjusted, ground, frame_from_ground, ground_from_map, w, h);
  }
  return a;
}

StatusOr<MetadataExperiment> RunMetadataExperiment(const mosaic::MosaicResult& mosaic,
                                                   const sim::Truth& truth,
                                                   const MetadataExperimentOptions& options) {
  const mosaic::LinkGraph& graph = mosaic.graph;
  if (graph.nodes.size() < 2) {
    return InvalidArgumentError("metadata experiment: needs at least two key frames");
  }
  if (options.metadata_key_frames < 1 || !(options.start_error_fraction >= 0) ||
      !(options.metadata_sigma_m >= 0)) {
    return InvalidArgumentError("metadata experiment: bad options");
  }
  const int w = graph.image_width, h = graph.image_height;
  const auto corners = track::ImageCorners(w, h);
  const size_t n = graph.nodes.size();
  SAKER_ASSIGN_OR_RETURN(const KeyFrameTruth key_truth,
                         TruthOfKeyFrames(graph, truth, "metadata experiment"));
  const std::vector<Eigen::Matrix3d>& frame_from_ground = key_truth.frame_from_ground;
  const std::vector<std::array<Eigen::Vector2d, 4>>& ground = key_truth.ground;
  // The wrong start: the true map_from_frame of key frame 0 (truth ground as the map) after a
  // keystone distortion of the image: the top corners moved inwards by the stated fraction of the
  // width. A perspective error like this is what a poor initialisation gives; far from the start
  // it is magnified, as in the paper's figure 11.
  std::array<Eigen::Vector2d, 4> distorted = corners;
  const double shift = options.start_error_fraction * w;
  distorted[0].x() += shift;
  distorted[1].x() -= shift;
  SAKER_ASSIGN_OR_RETURN(track::HomographyWithCovariance keystone,
                         track::HomographyFromCorners(corners, distorted, 1.0));

  mosaic::LinkGraph start = graph;
  start.geo_referenced = true;
  start.nodes[0].map_from_frame = frame_from_ground[0].inverse() * keystone.target_from_source;
  start.nodes[0].map_from_frame /= start.nodes[0].map_from_frame(2, 2);
  for (size_t k = 1; k < n; ++k) {
    // Chain from the previous key frame through the sequential link into k, if there is one;
    // else keep the previous one's (a break).
    Eigen::Matrix3d m = start.nodes[k - 1].map_from_frame;
    for (const mosaic::Link& l : graph.links) {
      if (l.kind == mosaic::LinkKind::kSequential && static_cast<size_t>(l.to) == k &&
          static_cast<size_t>(l.from) == k - 1) {
        m = m * l.to_from_from.inverse();
      }
    }
    start.nodes[k].map_from_frame = m / m(2, 2);
  }
  for (mosaic::Node& node : start.nodes) node.metadata_corners.reset();
  std::vector<Eigen::Matrix3d> wrong;
  for (const mosaic::Node& node : start.nodes) wrong.push_back(node.map_from_frame);

  MetadataExperiment e;
  e.start_error_m =
      Errors({wrong[0]}, {ground[0]}, {frame_from_ground[0]}, Eigen::Matrix3d::Identity(), w, h)
          .rms_m;
  const auto solved = [&](const mosaic::LinkGraph& g) {
    std::vector<Eigen::Matrix3d> m;
    for (const mosaic::Node& node : g.nodes) m.push_back(node.map_from_frame);
    return Errors(m, ground, frame_from_ground, Eigen::Matrix3d::Identity(), w, h);
  };
  mosaic::AdjustmentOptions adjustment;
  mosaic::LinkGraph without = start;
  SAKER_ASSIGN_OR_RETURN(mosaic::AdjustmentSummary s1, mosaic::Adjust(&without, adjustment));
  (void)s1;
  e.without_metadata = solved(without);

  // Metadata on key frames spread evenly along the flight (the paper's nodal key frames).
  double sigma = options.metadata_sigma_m;
  if (sigma <= 0) sigma = (ground[0][1] - ground[0][0]).norm();
  e.metadata_sigma_m = sigma;
  std::mt19937_64 random(options.seed);
  std::normal_distribution<double> noise(0.0, sigma);
  mosaic::LinkGraph with = start;
  const int count = std::min<int>(options.metadata_key_frames, static_cast<int>(n));
  for (int i = 0; i < count; ++i) {
    const size_t k = count == 1
                         ? 0
                         : static_cast<size_t>(std::lround(
                               static_cast<double>(i) * static_cast<double>(n - 1) / (count - 1)));
    std::array<Eigen::Vector2d, 4> noisy = ground[k];
    for (Eigen::Vector2d& p : noisy) p += Eigen::Vector2d(noise(random), noise(random));
    if (!with.nodes[k].metadata_corners) ++e.metadata_key_frames;
    with.nodes[k].metadata_corners = noisy;
  }
  adjustment.metadata_sigma_m = sigma;
  SAKER_ASSIGN_OR_RETURN(mosaic::AdjustmentSummary summary, mosaic::Adjust(&with, adjustment));
  (void)summary;
  e.with_metadata = solved(with);
  return e;
}

std::string MetadataExperimentToText(const MetadataExperiment& e) {
  std::ostringstream out;
  out.setf(std::ios::fixed);
  out.precision(1);
  out << "Metadata experiment: start homography off by " << e.start_error_m
      << " m RMS at its corners\n"
      << "  without metadata: key frame corners RMS " << e.without_metadata.rms_m << " m, max "
      << e.without_metadata.max_m << " m\n"
      << "  with metadata on " << e.metadata_key_frames << " key frames (sigma "
      << e.metadata_sigma_m << " m): RMS " << e.with_metadata.rms_m << " m, max "
      << e.with_metadata.max_m << " m\n";
  return out.str();
}

StatusOr<DecompositionExperiment> RunDecompositionExperiment(
    const mosaic::MosaicResult& mosaic, const sim::Truth& truth,
    const mosaic::DecompositionOptions& decomposition,
    const mosaic::AdjustmentOptions& adjustment) {
  const mosaic::LinkGraph& graph = mosaic.graph;
  const size_t n = graph.nodes.size();
  if (mosaic.chained.size() != n) {
    return InvalidArgumentError("decomposition experiment: the mosaic has no chained start");
  }
  const int w = graph.image_width, h = graph.image_height;
  const auto corners = track::ImageCorners(w, h);
  SAKER_ASSIGN_OR_RETURN(const KeyFrameTruth key_truth,
                         TruthOfKeyFrames(graph, truth, "decomposition experiment"));
  const std::vector<Eigen::Matrix3d>& frame_from_ground = key_truth.frame_from_ground;
  const std::vector<std::array<Eigen::Vector2d, 4>>& ground = key_truth.ground;
  mosaic::LinkGraph start = graph;
  for (size_t k = 0; k < n; ++k) start.nodes[k].map_from_frame = mosaic.chained[k];
  const auto solution = [](const mosaic::LinkGraph& g) {
    std::vector<Eigen::Matrix3d> m;
    for (const mosaic::Node& node : g.nodes) m.push_back(node.map_from_frame);
    return m;
  };

  DecompositionExperiment e;
  e.key_frames = static_cast<int>(n);
  mosaic::LinkGraph full = start;
  Stopwatch watch;
  SAKER_RETURN_IF_ERROR(mosaic::Adjust(&full, adjustment).status());
  e.full_s = watch.LapSeconds();

  mosaic::LinkGraph decomposed = start;
  SAKER_ASSIGN_OR_RETURN(mosaic::DecomposedSummary summary,
                         mosaic::AdjustDecomposed(&decomposed, adjustment, decomposition));
  e.decomposed_s = watch.ElapsedSeconds();
  e.node_adjust_s = summary.adjust_s;
  e.nodes = summary.nodes;
  e.arcs = summary.arcs;
  e.cross_links = summary.cross_links;
  e.left_out_cross_links = summary.left_out_cross_links;
  e.inserted_nodes = summary.inserted_nodes;

  double sum = 0;
  for (size_t k = 0; k < n; ++k) {
    // Compared in key frame k's pixels: both solutions' corners taken back through the full one.
    const Eigen::Matrix3d k_from_map = full.nodes[k].map_from_frame.inverse();
    for (const Eigen::Vector2d& c : corners) {
      const double d =
          (track::Transfer(k_from_map * decomposed.nodes[k].map_from_frame, c) - c).norm();
      sum += d * d;
      e.difference_max_px = std::max(e.difference_max_px, d);
    }
  }
  e.difference_rms_px = std::sqrt(sum / static_cast<double>(4 * std::max<size_t>(1, n)));
  const std::vector<Eigen::Matrix3d> full_m = solution(full), decomposed_m = solution(decomposed);
  e.full = Errors(full_m, ground, frame_from_ground, GaugeFit(full_m, ground, w, h), w, h);
  e.decomposed =
      Errors(decomposed_m, ground, frame_from_ground, GaugeFit(decomposed_m, ground, w, h), w, h);
  return e;
}

std::string DecompositionExperimentToText(const DecompositionExperiment& e) {
  std::ostringstream out;
  out.setf(std::ios::fixed);
  out.precision(2);
  out << "Decomposition experiment: " << e.key_frames << " key frames -> " << e.nodes << " nodes, "
      << e.arcs << " arcs, " << e.cross_links << " cross-links (" << e.left_out_cross_links
      << " left out), " << e.inserted_nodes << " nodes inserted\n"
      << "  full adjustment " << 1000 * e.full_s << " ms, decomposed " << 1000 * e.decomposed_s
      << " ms (nodes " << 1000 * e.node_adjust_s
      << " ms): " << (e.decomposed_s > 0 ? e.full_s / e.decomposed_s : 0.0) << "x faster\n"
      << "  decomposed against full: key frame corners RMS " << e.difference_rms_px << " px, max "
      << e.difference_max_px << " px\n"
      << "  against the truth, gauge removed: full RMS " << e.full.rms_px << " px / "
      << e.full.rms_m << " m, decomposed RMS " << e.decomposed.rms_px << " px / "
      << e.decomposed.rms_m << " m\n";
  return out.str();
}

nlohmann::json DecompositionExperimentToJson(const DecompositionExperiment& e) {
  return {{"key_frames", e.key_frames},
          {"nodes", e.nodes},
          {"arcs", e.arcs},
          {"cross_links", e.cross_links},
          {"left_out_cross_links", e.left_out_cross_links},
          {"inserted_nodes", e.inserted_nodes},
          {"full_s", e.full_s},
          {"decomposed_s", e.decomposed_s},
          {"node_adjust_s", e.node_adjust_s},
          {"difference_rms_px", e.difference_rms_px},
          {"difference_max_px", e.difference_max_px},
          {"full_rms_px", e.full.rms_px},
          {"decomposed_rms_px", e.decomposed.rms_px}};
}

nlohmann::json MosaicAccuracyToJson(const MosaicAccuracy& a) {
  const auto errors = [](const CornerErrors& e) {
    return nlohmann::json{{"rms_px", e.rms_px}, {"rms_m", e.rms_m}, {"max_m", e.max_m}};
  };
  nlohmann::json closures = nlohmann::json::array();
  for (const mosaic::LoopClosure& c : a.closures) {
    closures.push_back({{"from", static_cast<int>(c.from)},
                        {"to", static_cast<int>(c.to)},
                        {"kind", mosaic::LinkKindName(c.kind)},
                        {"inliers", c.inliers}});
  }
  nlohmann::json j = {{"key_frames", a.key_frames},
                      {"geo_referenced", a.geo_referenced},
                      {"before", errors(a.before)},
                      {"after", errors(a.after)},
                      {"loop_closures", closures}};
  if (a.before_absolute) j["before_absolute"] = errors(*a.before_absolute);
  if (a.after_absolute) j["after_absolute"] = errors(*a.after_absolute);
  j["adjustment"] = {
      {"mode", a.adjust_mode}, {"nodes", a.nodes}, {"arcs", a.arcs}, {"time_s", a.adjust_s}};
  if (a.in_between) {
    j["in_between"] = {{"frames", a.in_between->frames},
                       {"error", errors(a.in_between->frames_error)},
                       {"key_frames_error", errors(a.in_between->key_frames_error)},
                       {"between_key_frames", a.in_between->between},
                       {"median_excess_px", a.in_between->median_excess_px},
                       {"max_excess_px", a.in_between->max_excess_px}};
  }
  return j;
}

std::string MosaicAccuracyToText(const MosaicAccuracy& a) {
  std::ostringstream out;
  out.setf(std::ios::fixed);
  out.precision(2);
  out << "Mosaic: " << a.key_frames << " key frames, "
      << (a.geo_referenced ? "geo-referenced (metadata corners)" : "no metadata") << "\n";
  out << "  key frame corners, gauge removed: RMS " << a.before.rms_px << " px / " << a.before.rms_m
      << " m before adjustment, " << a.after.rms_px << " px / " << a.after.rms_m << " m after";
  if (a.after.rms_m > 0) out << " (" << a.before.rms_m / a.after.rms_m << "x smaller)";
  out << "\n";
  out << "  adjustment: " << a.adjust_mode;
  if (a.adjust_mode == "decomposed") out << ", " << a.nodes << " nodes, " << a.arcs << " arcs";
  out << ", " << 1000 * a.adjust_s << " ms in all\n";
  if (a.in_between) {
    const InBetweenAccuracy& b = *a.in_between;
    out << "  in-between frames: " << b.frames << " placed, corners RMS " << b.frames_error.rms_px
        << " px / " << b.frames_error.rms_m << " m (key frames " << b.key_frames_error.rms_px
        << " px); worse than both neighbouring key frames by median " << b.median_excess_px
        << " px, max " << b.max_excess_px << " px\n";
  }
  if (a.before_absolute && a.after_absolute) {
    out << "  key frame corners in map coordinates: RMS " << a.before_absolute->rms_m
        << " m before, " << a.after_absolute->rms_m << " m after (max " << a.after_absolute->max_m
        << " m)\n";
  }
  out << "  loop closures: " << a.closures.size();
  for (const mosaic::LoopClosure& c : a.closures) {
    out << "\n    key frame " << static_cast<int>(c.from) << " -> " << static_cast<int>(c.to)
        << " (" << mosaic::LinkKindName(c.kind) << ", " << c.inliers << " inliers)";
  }
  out << "\n";
  return out.str();
}

}  // namespace saker::eval
