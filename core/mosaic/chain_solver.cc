#include "core/mosaic/chain_solver.h"

#include "core/mosaic/link_graph.h"
#include "core/mosaic/residuals.h"
#include "core/track/homography.h"
#include "core/track/image_geometry.h"

#include <Eigen/LU>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <limits>
#include <string>
#include <utility>

namespace saker::mosaic {
namespace {

using internal::HomographyFrom;
using internal::HomographyStep;
using internal::kParameters;
using internal::kResiduals;
using internal::LinkResidual;
using internal::LinkResidualJacobians;
using internal::MakeLinkResidual;

using Matrix8 = Eigen::Matrix<double, kParameters, kParameters>;
using Vector8 = Eigen::Matrix<double, kParameters, 1>;
using Jacobian = Eigen::Matrix<double, kResiduals, kParameters>;
using Residual = Eigen::Matrix<double, kResiduals, 1>;
using Parameters = std::array<double, kParameters>;
using Corners = std::array<Eigen::Vector2d, 4>;

static_assert(kResiduals == kParameters);  // the stacked system of Eliminate is square per frame

constexpr double kInfinity = std::numeric_limits<double>::infinity();
// A rejected Gauss-Newton step is halved at most this often before the solver gives up on it.
constexpr int kMaxHalvings = 12;
// A matrix whose rows, scaled to unit length, span less volume than this is singular.
constexpr double kSingularVolume = 1e-12;
// Chains of at least kCoarseMinSteps steps start from the solution of the coarse chain whose
// steps are kCoarseBlock consecutive steps composed (recursively), solved with up to
// kCoarseIterations iterations.
constexpr size_t kCoarseBlock = 16;
constexpr size_t kCoarseMinSteps = 512;
constexpr int kCoarseIterations = 20;
// Gauss-Newton stops after a step whose predicted cost decrease is below this part of the cost.
constexpr double kRelativeDecrease = 1e-10;

std::string StepName(size_t i) {
  return "chain: step " + std::to_string(i) + " (frame " + std::to_string(i) + " -> " +
         std::to_string(i + 1) + ")";
}

Parameters ParametersOf(const Eigen::Matrix3d& h) {
  Parameters p;
  for (int i = 0; i < kParameters; ++i) p[static_cast<size_t>(i)] = h(i / 3, i % 3) / h(2, 2);
  return p;
}

bool Finite(const Parameters& p) {
  return std::all_of(p.begin(), p.end(), [](double v) { return std::isfinite(v); });
}

bool FiniteAndNormalised(const Eigen::Matrix3d& h) {
  return h.allFinite() && std::abs(h(2, 2) - 1.0) < 1e-9;
}

// Whether h N^-1 (h on the frame's normalised pixels), its rows scaled to unit length, spans no
// volume: invariant to the map's units and origin, 1 for orthogonal rows.
bool Singular(const Eigen::Matrix3d& h, const HomographyStep& step) {
  Eigen::Matrix3d a = h * step.PixelFromNormalised<double>();
  for (int r = 0; r < 3; ++r) {
    const double norm = a.row(r).norm();
    if (!(norm > 0)) return true;
    a.row(r) /= norm;
  }
  return !(std::abs(a.determinant()) > kSingularVolume);
}

Status CheckEnd(const Eigen::Matrix3d& h, const char* name, const HomographyStep& step) {
  if (!FiniteAndNormalised(h)) {
    return InvalidDataError(std::string("chain: ") + name +
                            " is not finite or not normalised (H(2,2) = 1)");
  }
  if (Singular(h, step)) return InvalidDataError(std::string("chain: ") + name + " is singular");
  return Status::Ok();
}

Status CheckStep(const ChainStep& s, size_t i, const HomographyStep& step, const Corners& corners) {
  const Eigen::Matrix3d& h = s.next_from_previous;
  if (!FiniteAndNormalised(h)) {
    return InvalidDataError(StepName(i) +
                            ": next_from_previous is not finite or not normalised (H(2,2) = 1)");
  }
  if (Singular(h, step)) return InvalidDataError(StepName(i) + ": next_from_previous is singular");
  for (const Eigen::Vector2d& c : corners) {
    if (!(h.row(2).dot(c.homogeneous()) > 0)) {
      return InvalidDataError(StepName(i) +
                              ": next_from_previous sends an image corner to or across infinity");
    }
  }
  const track::HomographyCovariance& cov = s.covariance;
  if (!cov.allFinite() ||
      (cov - cov.transpose()).cwiseAbs().maxCoeff() > 1e-9 * (1 + cov.cwiseAbs().maxCoeff())) {
    return InvalidDataError(StepName(i) + ": the covariance is not finite or not symmetric");
  }
  return Status::Ok();
}

// ---------------------------------------------------------------------------------------------
// One level of the solver: links between consecutive frames 0..n, Gauss-Newton on the free ones.

// Half the sum of the squared whitened residuals of all steps; infinity when one cannot be
// evaluated (a corner mapped to infinity) or is not finite.
double Cost(const std::vector<LinkResidual>& links, const std::vector<Parameters>& frames) {
  double cost = 0;
  Residual r;
  for (size_t i = 0; i < links.size(); ++i) {
    if (!links[i](frames[i].data(), frames[i + 1].data(), r.data())) return kInfinity;
    cost += 0.5 * r.squaredNorm();
  }
  return std::isfinite(cost) ? cost : kInfinity;
}

// The linearised problem is min sum_i |J_i^from d_i + J_i^to d_{i+1} + r_i|^2 over the steps d of
// the free frames (a fixed frame's d is 0): its Jacobian is block bidiagonal, its normal matrix
// block tridiagonal. It is solved in square-root information form, a QR factorisation frame by
// frame (the square-root information smoother): frame k enters with a prior |R_k d_k - rho_k|^2
// (what the steps before it say about it, R_k upper triangular), and the stack
//
//   [ R_k      0          | rho_k ]           [ T11  T12 | t1 ]
//   [ J^from   J^to       | -r_k  ]   --Q^T->  [ 0    T22 | t2 ]
//
// (Householder reflections) leaves T11 d_k + T12 d_{k+1} = t1, and the prior of frame k + 1,
// R_{k+1} = T22, rho_{k+1} = t2. Back substitution: d_k = w_k - G_k d_{k+1} with G_k = T11^-1 T12
// and w_k = T11^-1 t1. T11^T T11 is S_k, the Schur complement of the normal matrix on frame k
// given frames 1..k-1, and T11^T t1 its right-hand side: the same as block Gaussian elimination
// of the normal equations, but without forming them. That matters on long chains: what frame 0
// says about frame k along its softest direction (a slow bend of everything before it) decays
// far faster than along the stiff ones, and after some 10^5 precise steps the normal-equation
// update S_{k+1} = A_{k+1} - B_k^T S_k^-1 B_k cancels to rounding noise and S turned indefinite
// (measured: 10^6 steps of 0.01 px); orthogonal reflections keep R^T R positive semidefinite.
struct FrameFactor {
  Matrix8 gain = Matrix8::Zero();  // G_k (zero for the last free frame)
  Vector8 step = Vector8::Zero();  // w_k, then d_k after the back substitution
};

// Rows 0-7 [R_k 0 rho_k], rows 8-15 [J^from J^to -r_k]; columns 0-7 frame k, 8-15 frame k + 1,
// 16 the right-hand side.
using Stack = Eigen::Matrix<double, 16, 17>;

// Householder reflections that zero the entries below the diagonal of columns 0-15 (the top rows'
// R is upper triangular already, so column j < 8 reflects only row j with rows 8-15).
//
// A reflection of the pivot x0 and the entries `tail` below it: alpha = -sign(x0) |x|, v = x -
// alpha e_0, and H c = c + (v^T c) / (alpha v_0) v (since v^T v = -2 alpha v_0).
void Triangularise(Stack* a) {
  // Columns 0-7: the pivot row j and the 8 rows 8-15 (vectorised).
  for (int j = 0; j < 8; ++j) {
    auto tail = a->col(j).segment<8>(8);
    const double tail_squared = tail.squaredNorm();
    if (tail_squared == 0) continue;  // nothing to zero (frame 0 fixed: a zero column)
    const double x0 = (*a)(j, j);
    const double norm = std::sqrt(x0 * x0 + tail_squared);
    const double alpha = x0 > 0 ? -norm : norm;
    const double v0 = x0 - alpha, inverse = 1 / (alpha * v0);
    for (int c = j + 1; c < 17; ++c) {
      auto column = a->col(c).segment<8>(8);
      const double f = (v0 * (*a)(j, c) + tail.dot(column)) * inverse;
      (*a)(j, c) += f * v0;
      column += f * tail;
    }
    (*a)(j, j) = alpha;
    tail.setZero();
  }
  // Columns 8-15: the bottom rows j..15 alone.
  for (int j = 8; j < 16; ++j) {
    double tail_squared = 0;
    for (int i = j + 1; i < 16; ++i) tail_squared += (*a)(i, j) * (*a)(i, j);
    if (tail_squared == 0) continue;
    const double x0 = (*a)(j, j);
    const double norm = std::sqrt(x0 * x0 + tail_squared);
    const double alpha = x0 > 0 ? -norm : norm;
    const double v0 = x0 - alpha, inverse = 1 / (alpha * v0);
    for (int c = j + 1; c < 17; ++c) {
      double dot = v0 * (*a)(j, c);
      for (int i = j + 1; i < 16; ++i) dot += (*a)(i, j) * (*a)(i, c);
      const double f = dot * inverse;
      (*a)(j, c) += f * v0;
      for (int i = j + 1; i < 16; ++i) (*a)(i, c) += f * (*a)(i, j);
    }
    (*a)(j, j) = alpha;
    for (int i = j + 1; i < 16; ++i) (*a)(i, j) = 0;
  }
}

// x <- T^-1 x for the upper triangular T in rows and columns `at`..`at`+7 of a; false when T is
// singular.
template <typename X>
bool SolveUpper(const Stack& a, int at, X* x) {
  for (int i = 7; i >= 0; --i) {
    const double pivot = a(at + i, at + i);
    if (!(std::abs(pivot) > 0)) return false;
    for (int k = i + 1; k < 8; ++k) x->row(i) -= a(at + i, at + k) * x->row(k);
    x->row(i) /= pivot;
  }
  return true;
}

// Linearises every step at `frames` (frames 1..last_free free, the others fixed) and factors the
// linearised problem into `factors` (indexed by frame); when `schur_inverse` is given, S_k^-1 goes
// to [k]. `decrease` (when given) gets the cost decrease the linear model predicts for the
// Gauss-Newton step, b^T H^-1 b / 2 = sum |t1_k|^2 / 2. InvalidData when a residual cannot be
// evaluated or some frame is not determined (T11 singular).
Status Eliminate(const std::vector<LinkResidual>& links, const HomographyStep& step,
                 const std::vector<Parameters>& frames, size_t last_free,
                 std::vector<FrameFactor>* factors, std::vector<Matrix8>* schur_inverse,
                 double* decrease = nullptr) {
  const size_t n = links.size();
  Stack a;
  Residual r;
  Jacobian d_from, d_to;
  double t1_squared = 0;
  const auto undetermined = [](size_t k) {
    return InvalidDataError("chain: frame " + std::to_string(k) +
                            " is not determined by its steps (a degenerate step)");
  };
  // Frame k's factors from the top rows of `a` (after Triangularise, or the prior alone).
  const auto factor = [&](size_t k, bool coupled) -> bool {
    FrameFactor& f = (*factors)[k];
    f.step = a.block<8, 1>(0, 16);
    t1_squared += f.step.squaredNorm();
    if (!SolveUpper(a, 0, &f.step)) return false;
    if (coupled) {
      f.gain = a.block<8, 8>(0, 8);
      SolveUpper(a, 0, &f.gain);
    } else {
      f.gain.setZero();
    }
    if (schur_inverse != nullptr) {
      Matrix8 inverse = Matrix8::Identity();
      SolveUpper(a, 0, &inverse);  // T11^-1; S^-1 = T11^-1 T11^-T
      (*schur_inverse)[k].noalias() = inverse.lazyProduct(inverse.transpose());
    }
    return true;
  };
  a.setZero();  // frame 0 fixed: no prior, and its columns stay zero
  for (size_t i = 0; i < n; ++i) {
    if (!LinkResidualJacobians(links[i], step, frames[i].data(), frames[i + 1].data(), &r, &d_from,
                               &d_to) ||
        !r.allFinite() || !d_from.allFinite() || !d_to.allFinite()) {
      return InvalidDataError(StepName(i) + ": an image corner maps to infinity");
    }
    const bool from_free = i >= 1 && i <= last_free;
    const bool to_free = i + 1 <= last_free;
    if (from_free) {
      a.block<8, 8>(8, 0) = d_from;
    } else {
      a.block<8, 8>(8, 0).setZero();
    }
    if (to_free) {
      a.block<8, 8>(8, 8) = d_to;
    } else {
      a.block<8, 8>(8, 8).setZero();
    }
    a.block<8, 1>(8, 16) = -r;
    Triangularise(&a);
    if (from_free && !factor(i, to_free)) return undetermined(i);
    // The prior of frame i + 1 moves to the top rows (the bottom rows are all rewritten).
    a.block<8, 8>(0, 0) = a.block<8, 8>(8, 8);
    a.block<8, 8>(0, 8).setZero();
    a.block<8, 1>(0, 16) = a.block<8, 1>(8, 16);
  }
  if (last_free == n && !factor(n, false)) return undetermined(n);  // one end: frame n's prior
  if (decrease != nullptr) *decrease = 0.5 * t1_squared;
  return Status::Ok();
}

// d_k = w_k - G_k d_{k+1}, from the last free frame back to frame 1.
void BackSubstitute(size_t last_free, std::vector<FrameFactor>* factors) {
  for (size_t k = last_free; k-- > 1;) {
    FrameFactor& f = (*factors)[k];
    f.step.noalias() -= f.gain.lazyProduct((*factors)[k + 1].step);
  }
}

// The largest move of an image corner, in the frame's pixels, of the step d.
double CornerMove(const HomographyStep& step, const Vector8& d, const Corners& corners) {
  Eigen::Matrix3d e;
  e << 1 + d(0), d(1), d(2), d(3), 1 + d(4), d(5), d(6), d(7), 1;
  const Eigen::Matrix3d m =
      step.PixelFromNormalised<double>() * e * step.NormalisedFromPixel<double>();
  double move = 0;
  for (const Eigen::Vector2d& c : corners) {
    const Eigen::Vector3d p = m * c.homogeneous();
    if (!(p.z() > 0)) return kInfinity;
    move = std::max(move, (p.head<2>() / p.z() - c).norm());
  }
  return std::isfinite(move) ? move : kInfinity;
}

// The marginal covariances of the free frames from the factors of Eliminate (with S_k^-1 in
// `covariances`, replaced in place): Sigma_last = S_last^-1, Sigma_k = S_k^-1 + G_k Sigma_{k+1}
// G_k^T (the Rauch-Tung-Striebel recursion: given frame k + 1, frame k has precision S_k and mean
// -G_k d_{k+1}). Then taken from the step to the 8 parameters, P Sigma P^T (P = d Plus / d step),
// as Ceres's Covariance does with the manifold in NodeCovariances.
void Covariances(const HomographyStep& step, const std::vector<Parameters>& frames,
                 size_t last_free, const std::vector<FrameFactor>& factors,
                 std::vector<Matrix8>* covariances) {
  std::vector<Matrix8>& sigma = *covariances;
  for (size_t k = last_free; k-- > 1;) {
    Matrix8 propagated;
    propagated.noalias() = factors[k].gain.lazyProduct(sigma[k + 1]);
    sigma[k].noalias() += propagated.lazyProduct(factors[k].gain.transpose());
  }
  for (size_t k = 1; k <= last_free; ++k) {
    const Matrix8 p = step.PlusJacobian(frames[k].data());
    Matrix8 ps, c;
    ps.noalias() = p.lazyProduct(sigma[k]);
    c.noalias() = ps.lazyProduct(p.transpose());
    sigma[k] = 0.5 * (c + c.transpose());
  }
}

struct GaussNewtonSummary {
  int iterations = 0;
  double initial_cost = 0, final_cost = 0;
};

// Gauss-Newton on frames 1..n-1 of `frames` (n = links.size() >= 2), frames 0 and n fixed, from
// the start in `frames`: each step halved until the cost does not increase; stops after
// max_iterations, after a step whose largest corner move is below tolerance_px or whose predicted
// cost decrease is below kRelativeDecrease of the cost, or when no halving helps.
//
// The second test is for long chains: their softest modes (a slow bend of the whole chain) are so
// soft that the residuals' curvature, which Gauss-Newton leaves out, is comparable to their
// stiffness, and Gauss-Newton converges only linearly along them (each step a fifth of the last
// on 10^4 frames), by moves of a pixel or less that change the cost by 1e-9 of itself: a
// thousandth of a sigma or less, where the cost can hardly tell them from rounding.
StatusOr<GaussNewtonSummary> GaussNewton(const std::vector<LinkResidual>& links,
                                         const HomographyStep& step, const Corners& corners,
                                         int max_iterations, double tolerance_px,
                                         std::vector<Parameters>* frames) {
  const size_t n = links.size(), last_free = n - 1;
  GaussNewtonSummary summary;
  double cost = Cost(links, *frames);
  if (!std::isfinite(cost)) return InvalidDataError("chain: the start's residuals are not finite");
  summary.initial_cost = cost;
  std::vector<FrameFactor> factors(n + 1);
  std::vector<Parameters> trial = *frames;
  for (int iteration = 0; iteration < max_iterations; ++iteration) {
    double decrease = 0;
    SAKER_RETURN_IF_ERROR(Eliminate(links, step, *frames, last_free, &factors, nullptr, &decrease));
    BackSubstitute(last_free, &factors);
    double move = 0;
    for (size_t k = 1; k <= last_free; ++k) {
      move = std::max(move, CornerMove(step, factors[k].step, corners));
    }
    double scale = 1, trial_cost = kInfinity;
    bool accepted = false;
    for (int halving = 0; halving <= kMaxHalvings; ++halving, scale *= 0.5) {
      bool ok = true;
      for (size_t k = 1; ok && k <= last_free; ++k) {
        const Vector8 d = scale * factors[k].step;
        ok = step.Plus((*frames)[k].data(), d.data(), trial[k].data()) && Finite(trial[k]);
      }
      trial_cost = ok ? Cost(links, trial) : kInfinity;
      if (trial_cost <= cost) {
        accepted = true;
        break;
      }
      if (scale * move < tolerance_px) break;  // smaller steps change nothing
    }
    if (!accepted) break;
    frames->swap(trial);
    const double previous_cost = cost;
    cost = trial_cost;
    ++summary.iterations;
    if (scale * move < tolerance_px || decrease <= kRelativeDecrease * previous_cost) break;
  }
  summary.final_cost = cost;
  return summary;
}

// ---------------------------------------------------------------------------------------------
// The start.

// Frames begin+1..end-1 chained forward from frames[begin] through the steps; returns the chained
// map_from_end (frames[end] is left as it is).
Eigen::Matrix3d ChainForward(const std::vector<ChainStep>& steps, size_t begin, size_t end,
                             std::vector<Parameters>* frames) {
  Eigen::Matrix3d m = HomographyFrom((*frames)[begin].data());
  for (size_t k = begin + 1; k <= end; ++k) {
    m = m * steps[k - 1].next_from_previous.inverse();
    m /= m(2, 2);
    if (k < end) (*frames)[k] = ParametersOf(m);
  }
  return m;
}

// The closure error of frames begin+1..end-1 (chained, chained_end their continuation) against
// the fixed frames[end] spread along them: map_from_k <- ((1 - t) I + t C) map_from_k with
// t = (k - begin) / (end - begin) and C = map_from_end * chained_end^-1, near the identity.
void SpreadClosure(const Eigen::Matrix3d& chained_end, size_t begin, size_t end,
                   std::vector<Parameters>* frames) {
  const Eigen::Matrix3d c = HomographyFrom((*frames)[end].data()) * chained_end.inverse();
  if (!c.allFinite()) return;
  const double length = static_cast<double>(end - begin);
  for (size_t k = begin + 1; k < end; ++k) {
    const double t = static_cast<double>(k - begin) / length;
    const Eigen::Matrix3d blend = (1 - t) * Eigen::Matrix3d::Identity() + t * c;
    const Parameters spread = ParametersOf(blend * HomographyFrom((*frames)[k].data()));
    if (Finite(spread)) (*frames)[k] = spread;
  }
}

// The start of Gauss-Newton for frames 1..n-1 (frames 0 and n set in `frames`, n >= 2).
//
// Short chains: the chained product from frame 0, or the same with the closure error spread along
// the chain (SpreadClosure), whichever costs less; usually the spread one, by far (the chained
// product puts the whole closure error on the last step).
//
// Long chains drift far (hundreds to thousands of pixels of closure error over 10^4 frames), and
// from a linear spread Gauss-Newton then needs many iterations: a step's residual depends on the
// moves of its two frames through their product (M_{i+1}^-1 M_i), and moves of hundreds of pixels
// with turns leave second-order terms far larger than the noise (measured on 10^4 frames of
// 0.1 px: the first step's linear model predicts a cost of 1.7, the cost is above 10^5, and
// convergence takes over 5 iterations). So the start comes from the coarse chain: every
// kCoarseBlock consecutive steps composed into one (track::Compose, covariance propagated to first
// order), solved the same way (recursively), its frames taken as anchors, and each stretch between
// two anchors chained and spread. The anchors are then within a pixel or two of the solution and
// each stretch's closure error is local (10^4 and 10^5 frames: 3 iterations). Falls back to the
// short-chain start when a composition fails or sees a corner across the horizon.
void Start(const std::vector<ChainStep>& steps, const std::vector<LinkResidual>& links,
           const HomographyStep& step, const Corners& corners, const ChainOptions& options,
           double floor_px, std::vector<Parameters>* frames) {
  const size_t n = steps.size();
  if (n >= kCoarseMinSteps) {
    const size_t coarse_n = (n + kCoarseBlock - 1) / kCoarseBlock;
    std::vector<ChainStep> coarse(coarse_n);
    std::vector<LinkResidual> coarse_links;
    coarse_links.reserve(coarse_n);
    std::vector<Parameters> anchors(coarse_n + 1);
    bool ok = true;
    for (size_t j = 0; ok && j < coarse_n; ++j) {
      const size_t begin = j * kCoarseBlock, end = std::min(n, begin + kCoarseBlock);
      track::HomographyWithCovariance composed{steps[begin].next_from_previous,
                                               steps[begin].covariance};
      for (size_t k = begin + 1; ok && k < end; ++k) {
        StatusOr<track::HomographyWithCovariance> next =
            track::Compose(steps[k].next_from_previous, steps[k].covariance,
                           composed.target_from_source, composed.covariance);
        ok = next.ok() && next->target_from_source.allFinite() && next->covariance.allFinite();
        if (ok) composed = std::move(next).value();
      }
      // Steps far apart can see each other's corners across the horizon: no coarse chain then.
      for (const Eigen::Vector2d& c : corners) {
        ok = ok && composed.target_from_source.row(2).dot(c.homogeneous()) > 0;
      }
      if (!ok) break;
      coarse[j].next_from_previous = composed.target_from_source;
      coarse[j].covariance = composed.covariance;
      // The floor of each fine step, summed as variances.
      const double coarse_floor = floor_px * std::sqrt(static_cast<double>(end - begin));
      coarse_links.push_back(MakeLinkResidual(composed.target_from_source, composed.covariance,
                                              corners, coarse_floor));
      ok = coarse_links.back().whitening.allFinite();
    }
    if (ok) {
      anchors.front() = frames->front();
      anchors.back() = frames->back();
      Start(coarse, coarse_links, step, corners, options, floor_px, &anchors);
      const StatusOr<GaussNewtonSummary> solved = GaussNewton(
          coarse_links, step, corners, std::max(options.max_iterations, kCoarseIterations),
          options.tolerance_px, &anchors);
      if (solved.ok()) {
        for (size_t j = 1; j < coarse_n; ++j) (*frames)[j * kCoarseBlock] = anchors[j];
        for (size_t j = 0; j < coarse_n; ++j) {
          const size_t begin = j * kCoarseBlock, end = std::min(n, begin + kCoarseBlock);
          SpreadClosure(ChainForward(steps, begin, end, frames), begin, end, frames);
        }
        return;
      }
    }
  }
  const Eigen::Matrix3d chained_end = ChainForward(steps, 0, n, frames);
  std::vector<Parameters> spread = *frames;
  SpreadClosure(chained_end, 0, n, &spread);
  if (Cost(links, spread) < Cost(links, *frames)) frames->swap(spread);
}

}  // namespace

Status ChainOptions::Validate() const {
  if (!std::isfinite(min_link_sigma_px) || !(min_link_sigma_px > 0)) {
    return InvalidArgumentError("chain: min_link_sigma_px must be positive and finite");
  }
  if (max_iterations < 1) return InvalidArgumentError("chain: max_iterations must be >= 1");
  if (!std::isfinite(tolerance_px) || !(tolerance_px > 0)) {
    return InvalidArgumentError("chain: tolerance_px must be positive and finite");
  }
  return Status::Ok();
}

StatusOr<ChainSolution> SolveChain(const Eigen::Matrix3d& map_from_first,
                                   const std::optional<Eigen::Matrix3d>& map_from_last,
                                   const std::vector<ChainStep>& steps, int image_width,
                                   int image_height, const ChainOptions& options) {
  SAKER_RETURN_IF_ERROR(options.Validate());
  if (image_width <= 0 || image_height <= 0) {
    return InvalidArgumentError("chain: the image size must be positive");
  }
  const size_t n = steps.size();
  if (n == 0 && map_from_last) {
    return InvalidArgumentError(
        "chain: map_from_last given for an empty chain (frame 0 would be fixed twice)");
  }
  const HomographyStep step = HomographyStep::ForImage(image_width, image_height);
  const Corners corners = track::ImageCorners(image_width, image_height);
  SAKER_RETURN_IF_ERROR(CheckEnd(map_from_first, "map_from_first", step));
  if (map_from_last) SAKER_RETURN_IF_ERROR(CheckEnd(*map_from_last, "map_from_last", step));
  for (size_t i = 0; i < n; ++i) SAKER_RETURN_IF_ERROR(CheckStep(steps[i], i, step, corners));

  std::vector<LinkResidual> links;
  links.reserve(n);
  for (const ChainStep& s : steps) {
    links.push_back(
        MakeLinkResidual(s.next_from_previous, s.covariance, corners, options.min_link_sigma_px));
  }

  ChainSolution solution;
  std::vector<Parameters> frames(n + 1);
  frames[0] = ParametersOf(map_from_first);
  // Frames 1..last_free are solved for (none when both ends are fixed and n = 1).
  const size_t last_free = map_from_last ? n - 1 : n;
  if (map_from_last && n >= 2) {
    frames[n] = ParametersOf(*map_from_last);
    Start(steps, links, step, corners, options, options.min_link_sigma_px, &frames);
    SAKER_ASSIGN_OR_RETURN(
        const GaussNewtonSummary summary,
        GaussNewton(links, step, corners, options.max_iterations, options.tolerance_px, &frames));
    solution.iterations = summary.iterations;
    solution.initial_cost = summary.initial_cost;
    solution.final_cost = summary.final_cost;
  } else {
    // The chained product (n = 1 with both ends: nothing free, the last end as given).
    for (size_t i = 0; i < n; ++i) {
      frames[i + 1] =
          ParametersOf(HomographyFrom(frames[i].data()) * steps[i].next_from_previous.inverse());
      if (!Finite(frames[i + 1])) {
        return InvalidDataError(StepName(i) +
                                ": the chained map_from_frame is not finite (H(2,2) = 0)");
      }
    }
    if (map_from_last) frames[n] = ParametersOf(*map_from_last);
    const double cost = Cost(links, frames);
    if (!std::isfinite(cost)) return InvalidDataError("chain: the residuals are not finite");
    solution.initial_cost = solution.final_cost = cost;
  }

  if (options.covariances) {
    solution.covariances.assign(n + 1, track::HomographyCovariance::Zero());
    if (last_free >= 1) {
      std::vector<FrameFactor> factors(n + 1);
      SAKER_RETURN_IF_ERROR(
          Eliminate(links, step, frames, last_free, &factors, &solution.covariances));
      Covariances(step, frames, last_free, factors, &solution.covariances);
    }
  }

  solution.map_from_frame.reserve(n + 1);
  solution.map_from_frame.push_back(map_from_first);
  for (size_t k = 1; k <= n; ++k) {
    solution.map_from_frame.push_back(k == n && map_from_last ? *map_from_last
                                                              : HomographyFrom(frames[k].data()));
  }
  return solution;
}

}  // namespace saker::mosaic
