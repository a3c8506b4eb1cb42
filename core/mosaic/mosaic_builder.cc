#include "core/mosaic/mosaic_builder.h"

#include "core/track/homography.h"
#include "core/track/image_geometry.h"
#include "core/util/check.h"
#include "core/util/timer.h"

#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>

namespace saker::mosaic {
namespace {

using track::HomographyCovariance;
using track::HomographyWithCovariance;

Eigen::Matrix3d Normalised(const Eigen::Matrix3d& h) { return h / h(2, 2); }

// Fraction of frame b's area covered by frame a mapped through b_from_a (0 when a does not map
// to a convex quadrilateral in front of the camera).
double PredictedOverlap(const Eigen::Matrix3d& b_from_a, int width, int height) {
  std::vector<cv::Point2f> quad, rect, overlap;
  for (const Eigen::Vector2d& c : track::ImageCorners(width, height)) {
    const Eigen::Vector3d q = b_from_a * c.homogeneous();
    if (!(q.z() > 1e-9)) return 0;
    quad.emplace_back(static_cast<float>(q.x() / q.z()), static_cast<float>(q.y() / q.z()));
    rect.emplace_back(static_cast<float>(c.x()), static_cast<float>(c.y()));
  }
  if (!cv::isContourConvex(quad)) return 0;
  const float area = cv::intersectConvexConvex(quad, rect, overlap, true);
  return static_cast<double>(area) /
         (static_cast<double>(width - 1) * static_cast<double>(height - 1));
}

// A covariance that says "we know nothing useful": a standard deviation of the frame size on
// every projected corner, expressed on the parameters of `h` through the corners.
HomographyCovariance UninformativeCovariance(const Eigen::Matrix3d& h, int width, int height) {
  Eigen::Matrix<double, 8, 8> j;
  const auto corners = track::ImageCorners(width, height);
  for (int i = 0; i < 4; ++i) j.block<2, 8>(2 * i, 0) = track::TransferJacobian(h, corners[i]);
  // Map units per pixel near the centre, so that the sigma is one frame in the map too.
  const Eigen::Matrix2d a = track::TransferPointJacobian(h, {width / 2.0, height / 2.0});
  const double sigma = std::sqrt(std::abs(a.determinant())) * std::max(width, height);
  const Eigen::FullPivLU<Eigen::Matrix<double, 8, 8>> lu(j);
  if (!lu.isInvertible()) return HomographyCovariance::Identity() * 1e6;
  const Eigen::Matrix<double, 8, 8> inverse = lu.inverse();
  return sigma * sigma * inverse * inverse.transpose();
}

// Covariance of k's image point p predicted in j's image, both key frames' map_from_frame
// uncertain and taken as independent.
Eigen::Matrix2d PredictionCovariance(const Eigen::Matrix3d& map_from_k,
                                     const HomographyCovariance& cov_k,
                                     const Eigen::Matrix3d& map_from_j,
                                     const HomographyCovariance& cov_j,
                                     const Eigen::Matrix3d& j_from_map, const Eigen::Vector2d& p,
                                     double floor_px) {
  const Eigen::Vector2d x = track::Transfer(map_from_k, p);
  const Eigen::Vector2d q = track::Transfer(j_from_map, x);
  const Eigen::Matrix2d in_map = track::TransferCovariance(map_from_k, cov_k, p) +
                                 track::TransferCovariance(map_from_j, cov_j, q);
  const Eigen::Matrix2d a = track::TransferPointJacobian(j_from_map, x);
  return a * in_map * a.transpose() + floor_px * floor_px * Eigen::Matrix2d::Identity();
}

struct Builder {
  const MosaicInput& input;
  const MosaicOptions& options;
  JobContext* job;
  MosaicResult result;
  std::vector<KeyFrameFeatures> features;
  AppearanceIndex index;
  int metadata_since_adjustment = 0;
  bool dirty = false;  // links or metadata added since the last adjustment

  Builder(const MosaicInput& i, const MosaicOptions& o, JobContext* j)
      : input(i), options(o), job(j), index(o.index) {}

  int width() const { return result.graph.image_width; }
  int height() const { return result.graph.image_height; }

  // The metadata corners of a frame on the map, when the map is geo-referenced.
  std::optional<MapCorners> MetadataCorners(int64_t frame_index) const {
    if (!result.graph.geo_referenced ||
        static_cast<size_t>(frame_index) >= input.metadata_corners.size()) {
      return std::nullopt;
    }
    return input.metadata_corners[static_cast<size_t>(frame_index)];
  }

  // The sequential link of the front end that ends at key frame `k`, if any.
  const track::SequentialLink* LinkInto(int k) const {
    for (const track::SequentialLink& l : input.links) {
      if (static_cast<int>(l.to) == k) return &l;
    }
    return nullptr;
  }

  // Initial map_from_frame of key frame k and its covariance, from the chain (or metadata at a
  // segment start). `previous` is key frame k-1's (nullopt for k = 0).
  HomographyWithCovariance Initial(int k, const std::optional<HomographyWithCovariance>& previous,
                                   const Node& node) const {
    const track::SequentialLink* link = LinkInto(k);
    if (link != nullptr && previous) {
      StatusOr<HomographyWithCovariance> back = track::Invert(link->to_from_from, link->covariance);
      if (back.ok()) {
        StatusOr<HomographyWithCovariance> chained =
            track::Compose(previous->target_from_source, previous->covariance,
                           back->target_from_source, back->covariance);
        if (chained.ok()) return *chained;
      }
    }
    if (node.metadata_corners) {
      StatusOr<HomographyWithCovariance> h =
          track::HomographyFromCorners(track::ImageCorners(width(), height()),
                                       *node.metadata_corners, options.adjustment.metadata_sigma_m);
      if (h.ok()) return *h;
    }
    HomographyWithCovariance guess;
    if (previous) {
      guess.target_from_source = previous->target_from_source;
      guess.covariance = UninformativeCovariance(guess.target_from_source, width(), height());
    }
    // The very first key frame without metadata defines the map frame: exact, identity.
    return guess;
  }

  // The first key frame with metadata corners in a segment that began without: the segment so far
  // was chained from a guess (or, for the first segment, from the pixel frame), so it is moved as
  // a whole onto the metadata (map_from_i <- G map_from_i with G = metadata map_from_k *
  // (chained map_from_k)^-1). Later key frames chain from the moved ones.
  void AnchorSegment(int k) {
    LinkGraph& graph = result.graph;
    const Node& node = graph.nodes[static_cast<size_t>(k)];
    int first = k;
    while (first > 0 && graph.nodes[static_cast<size_t>(first - 1)].segment == node.segment)
      --first;
    for (int i = first; i < k; ++i) {
      if (graph.nodes[static_cast<size_t>(i)].metadata_corners) return;  // already anchored
    }
    if (first == k) return;  // a segment start: Initial used the metadata directly
    StatusOr<HomographyWithCovariance> anchored =
        track::HomographyFromCorners(track::ImageCorners(width(), height()), *node.metadata_corners,
                                     options.adjustment.metadata_sigma_m);
    if (!anchored.ok()) return;
    const Eigen::Matrix3d g = anchored->target_from_source * node.map_from_frame.inverse();
    for (int i = first; i <= k; ++i) {
      Node& n = graph.nodes[static_cast<size_t>(i)];
      n.map_from_frame = Normalised(g * n.map_from_frame);
      // Known to about the metadata's accuracy, like the anchor.
      std::array<Eigen::Vector2d, 4> corners;
      const auto image = track::ImageCorners(width(), height());
      for (int c = 0; c < 4; ++c)
        corners[static_cast<size_t>(c)] =
            track::Transfer(n.map_from_frame, image[static_cast<size_t>(c)]);
      StatusOr<HomographyWithCovariance> h =
          track::HomographyFromCorners(image, corners, options.adjustment.metadata_sigma_m);
      if (h.ok()) result.covariances[static_cast<size_t>(i)] = h->covariance;
    }
  }

  Status Adjust() {
    const Stopwatch start;
    AdjustmentSummary summary;
    std::optional<DecomposedSummary> decomposed;
    if (options.adjust_mode == AdjustmentMode::kDecomposed) {
      SAKER_ASSIGN_OR_RETURN(decomposed, AdjustDecomposed(&result.graph, options.adjustment,
                                                          options.decomposition, job));
      summary = decomposed->adjustment;
    } else {
      SAKER_ASSIGN_OR_RETURN(summary, mosaic::Adjust(&result.graph, options.adjustment, job));
    }
    result.timing.adjust_s += start.ElapsedSeconds();
    result.adjustments.push_back(summary);
    if (summary.cancelled) return CancelledError("mosaic: cancelled during bundle adjustment");
    const Stopwatch covariance_start;
    StatusOr<std::vector<HomographyCovariance>> covariances =
        decomposed ? DecomposedCovariances(result.graph, decomposed->decomposition,
                                           options.adjustment, options.decomposition.placement)
                   : NodeCovariances(result.graph, options.adjustment);
    result.timing.covariance_s += covariance_start.ElapsedSeconds();
    // A rank-deficient problem keeps the chain's covariances; the solution itself stands.
    if (covariances.ok()) result.covariances = std::move(covariances).value();
    if (decomposed) result.decomposition = std::move(decomposed);
    metadata_since_adjustment = 0;
    dirty = false;
    return Status::Ok();
  }

  // Loop closure for the newest key frame k. Returns the number of cross-links added.
  int CloseLoops(int k) {
    const KeyFrameFeatures& fk = features[static_cast<size_t>(k)];
    if (fk.points.empty()) return 0;
    const Node& node_k = result.graph.nodes[static_cast<size_t>(k)];
    const double limit = options.lost_fraction * std::min(width(), height());
    struct Candidate {
      int j;
      double overlap;
      Eigen::Matrix3d j_from_k;
    };
    std::vector<Candidate> geometric;
    bool lost = false;
    const Eigen::Vector2d centre((width() - 1) / 2.0, (height() - 1) / 2.0);
    for (int j = 0; j + options.skip_recent < k; ++j) {
      if (features[static_cast<size_t>(j)].points.empty()) continue;
      if (result.graph.Linked(static_cast<KeyFrameId>(j), static_cast<KeyFrameId>(k))) continue;
      const Node& node_j = result.graph.nodes[static_cast<size_t>(j)];
      const Eigen::FullPivLU<Eigen::Matrix3d> lu(node_j.map_from_frame);
      if (!lu.isInvertible()) continue;
      const Eigen::Matrix3d j_from_map = lu.inverse();
      const Eigen::Matrix3d j_from_k = Normalised(j_from_map * node_k.map_from_frame);
      const Eigen::Matrix2d cov =
          PredictionCovariance(node_k.map_from_frame, result.covariances[static_cast<size_t>(k)],
                               node_j.map_from_frame, result.covariances[static_cast<size_t>(j)],
                               j_from_map, centre, options.prediction_floor_px);
      // A covariance that is not finite (a degenerate solve) says nothing: lost.
      if (!cov.allFinite() ||
          !(track::ConfidenceEllipse(centre, cov, options.match.confidence).semi_major < limit)) {
        lost = true;
        continue;
      }
      const double overlap = PredictedOverlap(j_from_k, width(), height());
      if (overlap >= options.min_predicted_overlap) geometric.push_back({j, overlap, j_from_k});
    }
    std::sort(geometric.begin(), geometric.end(),
              [](const Candidate& a, const Candidate& b) { return a.overlap > b.overlap; });

    int added = 0;
    const auto add = [&](Link link) {
      result.closures.push_back(
          {link.from, link.to, link.kind, static_cast<int>(link.correspondences.size())});
      result.graph.links.push_back(std::move(link));
      ++added;
      dirty = true;
    };
    for (const Candidate& c : geometric) {
      if (added >= options.max_cross_links) break;
      const Node& node_j = result.graph.nodes[static_cast<size_t>(c.j)];
      const Eigen::Matrix3d j_from_map = node_j.map_from_frame.inverse();
      const auto covariance_in_j = [&](const Eigen::Vector2d& p) {
        return PredictionCovariance(
            node_k.map_from_frame, result.covariances[static_cast<size_t>(k)],
            node_j.map_from_frame, result.covariances[static_cast<size_t>(c.j)], j_from_map, p,
            options.prediction_floor_px);
      };
      std::optional<Link> link = MatchGeometric(fk, features[static_cast<size_t>(c.j)], c.j_from_k,
                                                covariance_in_j, width(), height(), options.match);
      if (link) add(std::move(*link));
    }
    if (added == 0 && (lost || !geometric.empty())) {
      const auto skip = [&](KeyFrameId id) {
        return static_cast<int>(id) + options.skip_recent >= k ||
               result.graph.Linked(id, static_cast<KeyFrameId>(k));
      };
      for (const auto& [id, score] : index.Query(fk, options.appearance_candidates, skip)) {
        if (added >= options.max_cross_links) break;
        std::optional<Link> link = MatchAppearance(fk, features[static_cast<size_t>(id)], width(),
                                                   height(), options.match);
        if (link) add(std::move(*link));
      }
    }
    return added;
  }

  StatusOr<MosaicResult> Run() {
    const Stopwatch start;
    LinkGraph& graph = result.graph;
    graph.image_width = input.image_width;
    graph.image_height = input.image_height;
    if (input.key_frames.empty()) {
      return InvalidDataError(
          "mosaic: the front end found no key frame (no trackable ground in the video)");
    }
    SAKER_RETURN_IF_ERROR(input.Validate());
    if (options.use_metadata && input.origin) {
      result.origin = input.origin;
      graph.geo_referenced = true;
    }

    // The chain alone, for the "before" figures.
    std::optional<HomographyWithCovariance> previous_chained;
    const size_t count = input.key_frames.size();
    features.resize(count);
    for (size_t k = 0; k < count; ++k) {
      if (job != nullptr && job->IsCancelled()) return CancelledError("mosaic: cancelled");
      const track::KeyFrame& kf = input.key_frames[k];
      SAKER_CHECK(static_cast<size_t>(kf.id) == k) << "key frame ids must be their indices";
      Node node;
      node.id = kf.id;
      node.frame_index = kf.frame_index;
      node.segment = kf.segment;
      if (static_cast<size_t>(kf.frame_index) < input.frames.size())
        node.time_s = input.frames[static_cast<size_t>(kf.frame_index)].time_s;
      node.metadata_corners = MetadataCorners(kf.frame_index);
      result.key_frames_with_metadata += node.metadata_corners.has_value();

      const HomographyWithCovariance chained = Initial(static_cast<int>(k), previous_chained, node);
      result.chained.push_back(chained.target_from_source);
      previous_chained = chained;

      // The running solution continues from the adjusted previous key frame.
      std::optional<HomographyWithCovariance> running_previous;
      if (k > 0) {
        running_previous =
            HomographyWithCovariance{graph.nodes.back().map_from_frame, result.covariances.back()};
      }
      HomographyWithCovariance initial = Initial(static_cast<int>(k), running_previous, node);
      node.map_from_frame = initial.target_from_source;
      graph.nodes.push_back(node);
      result.covariances.push_back(initial.covariance);
      if (node.metadata_corners) AnchorSegment(static_cast<int>(k));
      if (const track::SequentialLink* l = LinkInto(static_cast<int>(k))) {
        Link link;
        link.from = l->from;
        link.to = l->to;
        link.kind = LinkKind::kSequential;
        link.to_from_from = l->to_from_from;
        link.covariance = l->covariance;
        link.correspondences = l->correspondences;
        graph.links.push_back(std::move(link));
      }
      if (node.metadata_corners) {
        ++metadata_since_adjustment;
        dirty = true;
      }

      Stopwatch describe_start;
      if (k < input.key_frame_images.size() && input.key_frame_images[k].id == kf.id) {
        const track::KeyFrameImage& image = input.key_frame_images[k];
        features[k] = DescribeKeyFrame(kf.id, image.grey, image.scale, kf.points, options.describe);
      } else {
        features[k].id = kf.id;
      }
      result.timing.describe_s += describe_start.ElapsedSeconds();

      const Stopwatch match_start;
      const int added = CloseLoops(static_cast<int>(k));
      index.Add(features[k]);
      result.timing.match_s += match_start.ElapsedSeconds();

      const bool metadata_due = options.adjust_every_metadata > 0 &&
                                metadata_since_adjustment >= options.adjust_every_metadata;
      if (added > 0 || metadata_due) SAKER_RETURN_IF_ERROR(Adjust());
      if (job != nullptr)
        job->ReportProgress("mosaic", static_cast<double>(k + 1) / static_cast<double>(count));
    }
    // A last adjustment for what arrived since (metadata residuals; cross-links always adjust at
    // once), and so that the covariances describe the final graph.
    if (dirty || result.adjustments.empty()) SAKER_RETURN_IF_ERROR(Adjust());
    if (options.place_in_between) {
      const Stopwatch place_start;
      SAKER_ASSIGN_OR_RETURN(
          result.in_between,
          PlaceInBetweenFrames(input.frames, graph, options.decomposition.placement, job));
      result.timing.in_between_s = place_start.ElapsedSeconds();
    }
    result.timing.total_s = start.ElapsedSeconds();
    return std::move(result);
  }
};

}  // namespace

Status MosaicOptions::Validate() const {
  SAKER_RETURN_IF_ERROR(adjustment.Validate());
  SAKER_RETURN_IF_ERROR(describe.Validate());
  SAKER_RETURN_IF_ERROR(match.Validate());
  SAKER_RETURN_IF_ERROR(index.Validate());
  SAKER_RETURN_IF_ERROR(decomposition.Validate());
  if (!(lost_fraction > 0)) return InvalidArgumentError("mosaic: lost_fraction must be positive");
  if (!(prediction_floor_px >= 0)) {
    return InvalidArgumentError("mosaic: the prediction floor must be >= 0 pixels");
  }
  if (skip_recent < 1) return InvalidArgumentError("mosaic: skip_recent must be at least 1");
  if (!(min_predicted_overlap >= 0 && min_predicted_overlap <= 1)) {
    return InvalidArgumentError("mosaic: the predicted overlap must be in [0, 1]");
  }
  if (max_cross_links < 1 || appearance_candidates < 0 || adjust_every_metadata < 0) {
    return InvalidArgumentError(
        "mosaic: need max_cross_links >= 1, appearance_candidates >= 0, "
        "adjust_every_metadata >= 0");
  }
  return Status::Ok();
}

StatusOr<MosaicResult> BuildMosaic(const MosaicInput& input, const MosaicOptions& options,
                                   JobContext* job) {
  SAKER_RETURN_IF_ERROR(options.Validate());
  Builder builder(input, options, job);
  return builder.Run();
}

}  // namespace saker::mosaic
