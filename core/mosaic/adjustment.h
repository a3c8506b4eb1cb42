#pragma once
// Bundle adjustment of the absolute homographies of the link graph (paper: "The bundle adjustment
// is a mechanism for minimising measurement residuals, by varying the absolute homographies of
// the node frames"), the metadata corner residuals, and the covariance of the result.
//
// Model (Ceres, kept out of this header):
// - One parameter block per node: the 8 parameters of map_from_frame (H(2,2) = 1, types.h order).
//   Steps are taken on a manifold: M (+) d = M N^-1 (I + D(d)) N, N the frame's pixels centred
//   and scaled to [-1, 1], D(d) the 8 entries of a homography minus identity. A step is in
//   frame-relative units whatever the map is (metres far from the origin, or pixels), so the
//   solver and the covariance are well conditioned; covariances are returned for the 8
//   parameters.
// - Link residual (8 values): the 4 ImageCorners c of the `from` image, predicted in `to` as
//   M_to^-1 M_from c (adjugate, no division by the determinant), minus the measured
//   to_from_from c, whitened by L^-1 where L L^T = J C J^T + min_link_sigma_px^2 I (J the stacked
//   TransferJacobian at the measurement, C the link's covariance; negative eigenvalues of a C
//   that is not positive semi-definite count as zero).
// - Metadata residual (8 values) per node with metadata corners, when the graph is
//   geo_referenced and use_metadata: (M_k c - metadata) / metadata_sigma_m.
// - Robust loss: Huber on each block's squared whitened norm s, quadratic up to
//   s = 8 * loss_scale^2 (an RMS of loss_scale sigmas per coordinate), linear in the norm beyond.
//   Huber, not Cauchy: convex, so a drifted start whose loop closure misfits by hundreds of
//   sigmas still converges to the closed loop instead of discarding the loop closure as an
//   outlier; inliers stay quadratic, so the covariance is the least-squares one. The price: a
//   gross outlier keeps a bounded pull (loss_scale * sqrt(8) sigmas) instead of none.
// - Gauge: a connected component without metadata residuals holds its first node fixed. A
//   component with metadata is first moved as a whole by the map homography that best takes its
//   corners to the metadata corners (the links do not see that gauge, and local steps reach a
//   far-off one only slowly): a DLT on the corners as homogeneous vectors, reweighted towards the
//   metric misfit, so that key frames a projectively wrong start put near or past its horizon
//   neither wreck nor escape the fit; kept only when it lowers the cost and sends no key frame's
//   image across its horizon that was not already.
// - Solver: Levenberg-Marquardt with non-monotonic steps (the best solution is what is kept),
//   sparse normal Cholesky (SuiteSparse, else Eigen, else dense QR), silent.
#include "core/mosaic/link_graph.h"
#include "core/track/types.h"
#include "core/util/job_context.h"
#include "core/util/status.h"

#include <Eigen/Core>

#include <string>
#include <vector>

namespace saker::mosaic {

struct AdjustmentOptions {
  // Add the metadata corner residuals when the graph is geo_referenced.
  bool use_metadata = true;
  // 1-sigma accuracy of each metadata corner coordinate, metres (> 0).
  double metadata_sigma_m = 30;
  // Floor on the std of each predicted corner coordinate of a link measurement, pixels (> 0):
  // keeps the whitening finite for links with a (near) zero covariance.
  double min_link_sigma_px = 0.05;
  // Huber threshold in sigmas: a block is down-weighted once the RMS of its whitened residuals
  // exceeds this. 0 turns the robust loss off (plain least squares).
  double loss_scale = 3;
  // Levenberg-Marquardt iterations (>= 0).
  int max_iterations = 50;
  // Ceres threads (>= 1).
  int num_threads = 2;
  // Ceres's relative cost change for convergence (> 0).
  double function_tolerance = 1e-8;

  // InvalidArgument naming the first bad field.
  Status Validate() const;
};

struct AdjustmentSummary {
  int iterations = 0;
  // Ceres's cost, half the sum of the robustified squared residuals, at the caller's start and
  // at the end.
  double initial_cost = 0;
  double final_cost = 0;
  double time_s = 0;
  // A solution no worse than the start (converged, or stopped at the iteration limit / by
  // cancel); only then is it written back.
  bool usable = false;
  bool cancelled = false;
  int fixed_nodes = 0;  // nodes held fixed for the gauge
  int residual_blocks = 0;
  std::string message;  // Ceres's termination message
  // One line for logs and the CLI.
  std::string ToString() const;
};

// Varies every node's map_from_frame to minimise all link residuals (and metadata residuals),
// warm started from graph->nodes, writing the result back (normalised, H(2,2) = 1; fixed nodes
// are not touched). Cancel: job->IsCancelled() is checked every iteration; it stops and keeps the
// best solution so far (summary.cancelled). Progress: job->ReportProgress("adjustment", f).
// InvalidArgument for bad options, InvalidData for an invalid graph (LinkGraph::Validate).
StatusOr<AdjustmentSummary> Adjust(LinkGraph* graph, const AdjustmentOptions& options,
                                   JobContext* job = nullptr);

// The 8x8 covariance of each listed node's map_from_frame (all nodes when `nodes` is empty) at
// the current solution, with the residuals and gauge of Adjust (Ceres's Covariance, sparse QR).
// Fixed nodes, and nodes in no residual, get zero. Same order as `nodes` (or graph.nodes).
// InvalidArgument for bad options or an unknown node, InvalidData for an invalid graph or when
// the problem is rank deficient (a degenerate link).
StatusOr<std::vector<track::HomographyCovariance>> NodeCovariances(
    const LinkGraph& graph, const AdjustmentOptions& options,
    const std::vector<KeyFrameId>& nodes = {});

}  // namespace saker::mosaic
