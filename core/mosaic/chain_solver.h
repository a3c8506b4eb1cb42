#pragma once
// The in-between frames (paper: "Building aerial mosaics"): the absolute homography of every
// frame of a chain between two fixed frames, by a local adjustment over the measured
// frame-to-frame homographies. Moving targets are seen on every frame, not only on key frames, so
// every frame between two adjusted key frames needs its map_from_frame; the same solver places
// non-nodal key frames along an arc between two adjusted nodes.
//
// Model: the link residuals of the bundle adjustment (adjustment.h: the 4 ImageCorners of frame
// i predicted in frame i + 1 as M_{i+1}^-1 M_i c, minus the measured next_from_previous c,
// whitened by (J C J^T + min_link_sigma_px^2 I)^-1/2), the same step on each frame
// (M (+) d = M N^-1 (I + D(d)) N), no robust loss, the two ends held fixed. A chain couples only
// neighbours, so the Jacobian is block bidiagonal and the normal equations block tridiagonal (8x8
// blocks); Gauss-Newton solves them frame by frame in square-root information form (a QR
// factorisation of the Jacobian, equal to block elimination of the normal equations but stable
// over 10^6 frames), then back substitution: O(n) time and memory. Marginal covariances come from
// the same factorisation by the backward recursion of a Rauch-Tung-Striebel smoother, also O(n).
// Long chains (>= 512 steps) start from the solution of a coarse chain of composed steps.
// Formulas and measured speed: docs/mosaic.md.
#include "core/track/types.h"
#include "core/util/status.h"

#include <Eigen/Core>

#include <optional>
#include <vector>

namespace saker::mosaic {

// One measured step of a chain: frame i -> frame i + 1 (full-resolution pixels).
struct ChainStep {
  Eigen::Matrix3d next_from_previous = Eigen::Matrix3d::Identity();  // H(2,2) = 1
  // Of next_from_previous's 8 parameters (types.h order).
  track::HomographyCovariance covariance = track::HomographyCovariance::Zero();
};

struct ChainOptions {
  // Same meaning as AdjustmentOptions::min_link_sigma_px (> 0): floor on the std of each
  // predicted corner coordinate of a step, pixels.
  double min_link_sigma_px = 0.05;
  // Gauss-Newton iterations at most (>= 1); stops earlier after an update whose largest corner
  // move is below tolerance_px, or whose predicted cost decrease is below 1e-10 of the cost (long
  // chains, where the last fractions of a pixel lie along directions the data hardly determine).
  // Realistic closure errors (tens of pixels over hundreds of frames) take 2-3.
  int max_iterations = 5;
  // The largest move of any image corner of any frame in one iteration, in that frame's pixels,
  // below which Gauss-Newton has converged (> 0).
  double tolerance_px = 1e-3;
  // Also compute each frame's marginal 8x8 covariance (types.h parameter order), linear time.
  bool covariances = false;

  // InvalidArgument naming the first bad field.
  Status Validate() const;
};

struct ChainSolution {
  // steps.size() + 1 entries, H(2,2) = 1; the first (and the last when it was given) are the
  // fixed ends, copied unchanged.
  std::vector<Eigen::Matrix3d> map_from_frame;
  // When requested: steps.size() + 1 entries, zero for fixed frames. The covariance of the 8
  // parameters of map_from_frame, as NodeCovariances gives it (the step's covariance taken to
  // the parameters by the step's Jacobian).
  std::vector<track::HomographyCovariance> covariances;
  // Gauss-Newton updates taken (0 when nothing was solved: one end, or no free frame).
  int iterations = 0;
  // Half the sum of squared whitened residuals over all steps: at the start Gauss-Newton used
  // (the chained product with its closure error spread along the chain, or for long chains the
  // coarse chain's solution filled in; never worse than the plain chained product for short ones)
  // and at the solution.
  double initial_cost = 0, final_cost = 0;
};

// The absolute homographies of frames 0..n of a chain of n = steps.size() steps, frame 0 fixed at
// map_from_first and, when given, frame n fixed at map_from_last: the least-squares solution of
// the residuals above, Gauss-Newton on the block-tridiagonal normal equations (each update halved
// until the cost does not increase), O(n) time and memory. One thread; independent chains (the
// stretches between different key frames) can be solved concurrently.
//
// Without map_from_last the answer is the chained product map_from_{i+1} = map_from_i *
// next_from_previous_i^-1 (normalised; it zeroes every residual, no solve), and the covariances
// are those of the same least squares with only frame 0 fixed (the chained propagation, to first
// order).
//
// Edge cases: n = 0 without map_from_last returns {map_from_first}; n = 0 with map_from_last is
// InvalidArgument (frame 0 would be fixed twice). n = 1 with map_from_last has no free frame: it
// returns both ends, the cost of the one step, 0 iterations.
//
// Errors: InvalidArgument for bad options or a non-positive image size. InvalidData, naming the
// step or end, for a non-finite or unnormalised (H(2,2) != 1) homography, a singular one, a step
// that sends an image corner to or across infinity, a non-finite or asymmetric covariance, and
// for normal equations that are not positive definite at some frame.
StatusOr<ChainSolution> SolveChain(const Eigen::Matrix3d& map_from_first,
                                   const std::optional<Eigen::Matrix3d>& map_from_last,
                                   const std::vector<ChainStep>& steps, int image_width,
                                   int image_height, const ChainOptions& options = {});

}  // namespace saker::mosaic
