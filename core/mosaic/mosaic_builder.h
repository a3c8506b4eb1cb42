#pragma once
// The mosaic engine end to end: the front end's key frames and sequential links become a link
// graph; each new key frame is described (SIFT at its Harris points), matched against earlier key
// frames for loop closure, and the graph is bundle adjusted whenever a cross-link is added (as the
// paper does). docs/mosaic.md describes the rules and the figures.
//
// Per key frame k, in order:
//  1. Its absolute homography is initialised by chaining the sequential link from k-1
//     (map_from_k = map_from_{k-1} * (k-1)_from_k), its covariance propagated to first order; at
//     a segment start (the first key frame, or after a chain break) from its metadata corners
//     when it has them, else as a guess from the previous key frame (a separate component until a
//     loop closure re-attaches it).
//  2. For every earlier key frame j (except the last `skip_recent`, which the chain already
//     joins), the predicted homography j_from_k = map_from_j^-1 * map_from_k and the uncertainty
//     of k's centre predicted in j (both key frames' covariances, as if independent, which errs on
//     the safe side). Where that uncertainty is smaller than the frame (lost_fraction) and the
//     predicted overlap is large enough, features are matched inside their uncertainty ellipses
//     (geometric matching). Where it is larger, the camera is lost with respect to j, and the
//     appearance index proposes a few candidates for SIFT + RANSAC matching; this also runs when
//     geometric candidates existed but none matched (the prediction was over-confident).
//  3. Any cross-link found triggers a bundle adjustment of all key frames so far, warm started,
//     and the covariances are recomputed from it. With metadata, the graph is also adjusted every
//     `adjust_every_metadata` key frames with metadata corners, and once at the end. The
//     adjustment is full or decomposed into nodes and arcs (decomposition.h, `adjust_mode`).
// At the end every video frame is placed on the map (in_between.h).
#include "core/geo/local_tangent_plane.h"
#include "core/mosaic/adjustment.h"
#include "core/mosaic/decomposition.h"
#include "core/mosaic/in_between.h"
#include "core/mosaic/link_graph.h"
#include "core/mosaic/loop_closure.h"
#include "core/mosaic/mosaic_input.h"
#include "core/util/job_context.h"
#include "core/util/status.h"

#include <Eigen/Core>

#include <optional>
#include <vector>

namespace saker::mosaic {

struct MosaicOptions {
  AdjustmentOptions adjustment;
  // Full bundle adjustment of every key frame, or of the nodes of the node/arc decomposition.
  AdjustmentMode adjust_mode = AdjustmentMode::kDecomposed;
  DecompositionOptions decomposition;  // its placement options also place the in-between frames
  bool place_in_between = true;        // solve every frame's map_from_frame at the end
  DescribeOptions describe;
  MatchOptions match;
  AppearanceIndexOptions index;
  bool use_metadata = true;  // geo-reference with the metadata corners when key frames have them
  // "Uncertainty smaller than a frame": geometric matching is used while the semi-major axis of
  // the predicted position's ellipse (at match.confidence) is below this fraction of the frame's
  // smaller side; beyond it appearance matching is used.
  double lost_fraction = 1.0;
  // Added in quadrature to the predicted position's standard deviation (pixels): the first-order
  // covariance of a long chain is optimistic about unmodelled drift.
  double prediction_floor_px = 10;
  int skip_recent = 2;                 // key frames before k never cross-linked with k
  double min_predicted_overlap = 0.2;  // of the frame, for a geometric candidate
  int max_cross_links = 3;             // per new key frame
  int appearance_candidates = 4;       // proposals from the appearance index per key frame
  int adjust_every_metadata = 8;       // key frames with metadata between adjustments; 0 = off
  Status Validate() const;
};

struct LoopClosure {
  KeyFrameId from{};  // the new key frame
  KeyFrameId to{};    // the earlier one
  LinkKind kind = LinkKind::kGeometric;
  int inliers = 0;
};

struct MosaicTiming {
  double describe_s = 0;
  double match_s = 0;
  double adjust_s = 0;
  double covariance_s = 0;
  double in_between_s = 0;
  double total_s = 0;
};

struct MosaicResult {
  LinkGraph graph;  // key frames with their adjusted map_from_frame, all links
  // map_from_frame of each key frame from the sequential chain alone, before any loop closure or
  // adjustment (the drift the adjustment removes).
  std::vector<Eigen::Matrix3d> chained;
  // Covariance of each key frame's map_from_frame after the last adjustment (zero for a key
  // frame held fixed for the gauge), or propagated along the chain when none ran.
  std::vector<track::HomographyCovariance> covariances;
  std::vector<LoopClosure> closures;
  std::vector<AdjustmentSummary> adjustments;
  // The last decomposed adjustment's nodes, arcs and times (adjust_mode kDecomposed).
  std::optional<DecomposedSummary> decomposition;
  // Every video frame's map_from_frame (place_in_between).
  InBetweenFrames in_between;
  std::optional<geo::Wgs84> origin;  // of the map frame, when geo_referenced
  int key_frames_with_metadata = 0;
  MosaicTiming timing;
};

// Builds the mosaic of one video. InvalidData when the input has no key frame (no trackable
// ground in the whole video); InvalidArgument when its parts do not fit (MosaicInput::Validate);
// Cancelled through `job` (between key frames, and inside an adjustment, which keeps its best
// solution). The map is geo-referenced when the input has an origin and `use_metadata`.
StatusOr<MosaicResult> BuildMosaic(const MosaicInput& input, const MosaicOptions& options,
                                   JobContext* job = nullptr);

}  // namespace saker::mosaic
