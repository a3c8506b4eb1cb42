#include "core/mosaic/adjustment.h"

#include "core/mosaic/residuals.h"
#include "core/track/homography.h"
#include "core/track/image_geometry.h"
#include "core/util/check.h"
#include "core/util/statistics.h"
#include "core/util/timer.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <Eigen/LU>
#include <ceres/ceres.h>
#include <ceres/covariance.h>
#include <ceres/manifold.h>
#include <glog/logging.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <utility>

namespace saker::mosaic {
namespace {

using internal::HomographyFrom;
using internal::HomographyStep;
using internal::kParameters;
using internal::kResiduals;
using internal::LinkResidual;
using internal::MakeLinkResidual;
using internal::Matrix3;
using internal::Project;

// (M c - metadata) / sigma over the 4 image corners c.
struct MetadataResidual {
  std::array<Eigen::Vector2d, 4> corners;
  Eigen::Matrix<double, kResiduals, 1> metadata;
  double inverse_sigma = 1;

  template <typename T>
  bool operator()(const T* map_from_frame, T* residual) const {
    const Matrix3<T> m = HomographyFrom(map_from_frame);
    for (int i = 0; i < 4; ++i) {
      if (!Project(m, corners[static_cast<size_t>(i)], residual + 2 * i)) return false;
    }
    for (int i = 0; i < kResiduals; ++i) {
      residual[i] = (residual[i] - static_cast<T>(metadata(i))) * static_cast<T>(inverse_sigma);
    }
    return true;
  }
};

ceres::SparseLinearAlgebraLibraryType SparseLibrary() {
  if (ceres::IsSparseLinearAlgebraLibraryTypeAvailable(ceres::SUITE_SPARSE)) {
    return ceres::SUITE_SPARSE;
  }
  if (ceres::IsSparseLinearAlgebraLibraryTypeAvailable(ceres::EIGEN_SPARSE)) {
    return ceres::EIGEN_SPARSE;
  }
  return ceres::NO_SPARSE;
}

// Moves the points to their centroid and scales them to a mean distance of sqrt(2) (Hartley).
Eigen::Matrix3d Conditioner(const std::vector<Eigen::Vector2d>& points) {
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const Eigen::Vector2d& p : points) mean += p;
  mean /= static_cast<double>(points.size());
  double distance = 0;
  for (const Eigen::Vector2d& p : points) distance += (p - mean).norm();
  distance /= static_cast<double>(points.size());
  const double s = distance > 0 ? std::sqrt(2.0) / distance : 1.0;
  Eigen::Matrix3d t;
  t << s, 0, -s * mean.x(), 0, s, -s * mean.y(), 0, 0, 1;
  return t;
}

// The similarity that moves homogeneous points to their median (per coordinate, dehomogenised)
// and scales them to a median distance of sqrt(2); nullopt when fewer than half are finite or
// they all coincide. The medians, not Hartley's mean, because the points are the current map's:
// a few of them may lie near or beyond a horizon, tens of kilometres off or mirrored, and a mean
// would be theirs.
std::optional<Eigen::Matrix3d> RobustConditioner(const std::vector<Eigen::Vector3d>& points) {
  std::vector<double> x, y;
  for (const Eigen::Vector3d& p : points) {
    if (p.z() == 0) continue;
    const Eigen::Vector2d d = p.hnormalized();
    if (!d.allFinite()) continue;
    x.push_back(d.x());
    y.push_back(d.y());
  }
  if (x.empty() || 2 * x.size() < points.size()) return std::nullopt;
  const Eigen::Vector2d centre(Median(x), Median(y));
  std::vector<double> distance;
  for (size_t i = 0; i < x.size(); ++i) {
    distance.push_back((Eigen::Vector2d(x[i], y[i]) - centre).norm());
  }
  const double scale = Median(distance);
  if (!(scale > 0)) return std::nullopt;
  const double s = std::sqrt(2.0) / scale;
  Eigen::Matrix3d t;
  t << s, 0, -s * centre.x(), 0, s, -s * centre.y(), 0, 0, 1;
  return t;
}

// Reweighted DLT passes of FitHomography after the plain one, and the floor on a point's |w|
// (relative to the median) in its weight.
constexpr int kReweightings = 5;
constexpr double kMinReweightingW = 1e-3;

// The homography g with g p ~ q, fitted by the DLT and reweighted towards the geometric metadata
// misfit; nullopt when the points do not determine it (fewer than 4, collinear) or it is not
// finite.
//
// p are homogeneous 3-vectors (the map's M c, any scale and sign), not dehomogenised points: a
// component whose start went through a projective error (a wrong first homography chained along
// a long flight) has key frames near or past that error's horizon, whose dehomogenised corners
// are tens to hundreds of kilometres out or mirrored. As 2-D points they dominated the algebraic
// error (its rows scale with the point's size) and the Hartley conditioning, and the fit missed
// (the figure eight of the metadata experiment: 2.0 km RMS metadata misfit after the fit, against
// 0.36 km for this one). Here the map side is conditioned by a similarity from the medians and
// each point scaled to unit norm, so every corner weighs alike, wherever the current map put it;
// q, the metadata, is well behaved and gets Hartley's conditioning.
//
// The DLT minimises an algebraic error: a point's rows are (g a)_w times its misfit in metadata
// metres, so where g is strongly projective (undoing the start's error, it is) the points it
// sends near its horizon count for little. Dividing each point's rows by |(g a)_w| of the
// previous pass turns that into the metric misfit (iteratively reweighted least squares); the
// passes are not guaranteed to improve, so the one with the least metric misfit is returned. On
// the figure eight with a 20 % keystone (seed 8), the plain DLT misfits the metadata by 20 km RMS
// (|w| over the points spans 0.008-7.7x its median) and the reweighted one by 0.39 km.
std::optional<Eigen::Matrix3d> FitHomography(const std::vector<Eigen::Vector3d>& p,
                                             const std::vector<Eigen::Vector2d>& q) {
  if (p.size() < 4 || p.size() != q.size()) return std::nullopt;
  const std::optional<Eigen::Matrix3d> tp = RobustConditioner(p);
  if (!tp) return std::nullopt;
  const Eigen::Matrix3d tq = Conditioner(q);
  std::vector<Eigen::Vector3d> a, b;
  for (size_t i = 0; i < p.size(); ++i) {
    const Eigen::Vector3d conditioned = *tp * p[i];
    if (!(conditioned.norm() > 0) || !conditioned.allFinite()) continue;
    a.push_back(conditioned.normalized());
    b.push_back(tq * q[i].homogeneous());
  }
  if (a.size() < 4) return std::nullopt;
  std::vector<double> weight(a.size(), 1.0);
  using Matrix9 = Eigen::Matrix<double, 9, 9>;
  std::optional<Eigen::Matrix3d> best;
  double best_misfit = std::numeric_limits<double>::infinity();
  for (int iteration = 0; iteration <= kReweightings; ++iteration) {
    Matrix9 normal = Matrix9::Zero();
    for (size_t i = 0; i < a.size(); ++i) {
      const Eigen::RowVector3d at = weight[i] * a[i].transpose();
      Eigen::Matrix<double, 2, 9> rows;
      rows << Eigen::RowVector3d::Zero(), -b[i].z() * at, b[i].y() * at,  //
          b[i].z() * at, Eigen::RowVector3d::Zero(), -b[i].x() * at;
      normal += rows.transpose() * rows;
    }
    const Eigen::SelfAdjointEigenSolver<Matrix9> eigen(normal);
    if (eigen.info() != Eigen::Success ||
        !(eigen.eigenvalues()(1) > 1e-12 * eigen.eigenvalues()(8))) {
      break;
    }
    const Eigen::Matrix<double, 9, 1> h = eigen.eigenvectors().col(0);
    Eigen::Matrix3d hn;
    hn << h(0), h(1), h(2), h(3), h(4), h(5), h(6), h(7), h(8);
    // The metadata misfit of this fit (in conditioned metadata units, a fixed multiple of
    // metres), and the reweighting towards it.
    double misfit = 0;
    std::vector<double> w(a.size());
    for (size_t i = 0; i < a.size(); ++i) {
      const Eigen::Vector3d mapped = hn * a[i];
      w[i] = std::abs(mapped.z());
      misfit += w[i] > 0 ? (mapped.hnormalized() - b[i].head<2>()).squaredNorm()
                         : std::numeric_limits<double>::infinity();
    }
    const Eigen::Matrix3d g = tq.inverse() * hn * *tp;
    if (g.allFinite() && misfit < best_misfit) {
      best_misfit = misfit;
      best = g;
    }
    const double median = Median(w);
    if (!(median > 0)) break;
    for (size_t i = 0; i < a.size(); ++i) {
      weight[i] = 1 / std::max(w[i], kMinReweightingW * median);
    }
  }
  return best;
}

// Whether the image (its 4 corners; w is affine in the pixel, so then the whole image) maps to
// one side of the horizon of map_from_frame, i.e. nowhere to infinity.
bool OneSideOfHorizon(const Eigen::Matrix3d& map_from_frame,
                      const std::array<Eigen::Vector2d, 4>& corners) {
  int positive = 0, negative = 0;
  for (const Eigen::Vector2d& c : corners) {
    const double w = map_from_frame.row(2).dot(c.homogeneous());
    positive += w > 0;
    negative += w < 0;
  }
  return positive == 4 || negative == 4;
}

// The Ceres problem of a graph: the parameter blocks (one per node) and what was added. The
// manifold and the loss are shared by all blocks and owned here, so this outlives the problem.
class AdjustmentProblem {
 public:
  AdjustmentProblem(const LinkGraph& graph, const AdjustmentOptions& options) {
    const size_t n = graph.nodes.size();
    parameters_.resize(n);
    for (size_t i = 0; i < n; ++i) {
      const track::HomographyParameters p =
          track::ParametersFromHomography(graph.nodes[i].map_from_frame);
      std::copy(p.data(), p.data() + kParameters, parameters_[i].data());
    }
    in_problem_.assign(n, false);
    fixed_.assign(n, false);

    manifold_ = std::make_unique<ceres::AutoDiffManifold<HomographyStep, kParameters, kParameters>>(
        new HomographyStep(HomographyStep::ForImage(graph.image_width, graph.image_height)));
    if (options.loss_scale > 0) {
      loss_ = std::make_unique<ceres::HuberLoss>(options.loss_scale * std::sqrt(kResiduals));
    }
    ceres::Problem::Options problem_options;
    problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    problem_ = std::make_unique<ceres::Problem>(problem_options);

    const std::array<Eigen::Vector2d, 4> corners =
        track::ImageCorners(graph.image_width, graph.image_height);
    for (const Link& link : graph.links) {
      auto* residual = new LinkResidual(
          MakeLinkResidual(link.to_from_from, link.covariance, corners, options.min_link_sigma_px));
      problem_->AddResidualBlock(
          new ceres::AutoDiffCostFunction<LinkResidual, kResiduals, kParameters, kParameters>(
              residual),
          loss_.get(), Block(link.from), Block(link.to));
      ++residual_blocks_;
    }

    component_ = graph.Components();
    const std::vector<int>& component = component_;
    const int components =
        component.empty() ? 0 : *std::max_element(component.begin(), component.end()) + 1;
    has_metadata_.assign(static_cast<size_t>(components), false);
    std::vector<bool>& has_metadata = has_metadata_;
    if (graph.geo_referenced && options.use_metadata) {
      for (const Node& node : graph.nodes) {
        if (!node.metadata_corners) continue;
        auto* residual = new MetadataResidual{corners, {}, 1.0 / options.metadata_sigma_m};
        for (int i = 0; i < 4; ++i) {
          residual->metadata.segment<2>(2 * i) = (*node.metadata_corners)[static_cast<size_t>(i)];
        }
        problem_->AddResidualBlock(
            new ceres::AutoDiffCostFunction<MetadataResidual, kResiduals, kParameters>(residual),
            loss_.get(), Block(node.id));
        ++residual_blocks_;
        has_metadata[static_cast<size_t>(component[static_cast<size_t>(node.id)])] = true;
      }
    }

    // Gauge: the first node (in node order) of each component without metadata stays fixed.
    std::vector<bool> seen(static_cast<size_t>(components), false);
    for (size_t i = 0; i < n; ++i) {
      const size_t c = static_cast<size_t>(component[i]);
      if (seen[c]) continue;
      seen[c] = true;
      if (has_metadata[c]) continue;
      fixed_[i] = true;
      ++fixed_nodes_;
      if (in_problem_[i]) problem_->SetParameterBlockConstant(parameters_[i].data());
    }
  }

  ceres::Problem& problem() { return *problem_; }
  double* parameters(size_t node) { return parameters_[node].data(); }
  bool in_problem(size_t node) const { return in_problem_[node]; }
  bool fixed(size_t node) const { return fixed_[node]; }
  int residual_blocks() const { return residual_blocks_; }
  int fixed_nodes() const { return fixed_nodes_; }
  int components() const { return static_cast<int>(has_metadata_.size()); }
  int component(size_t node) const { return component_[node]; }
  bool has_metadata(int component) const { return has_metadata_[static_cast<size_t>(component)]; }
  // The cost (Ceres's: half the sum of the robustified squares) at the current parameters.
  double Cost() {
    double cost = 0;
    problem_->Evaluate(ceres::Problem::EvaluateOptions(), &cost, nullptr, nullptr, nullptr);
    return cost;
  }

 private:
  double* Block(KeyFrameId id) {
    const size_t i = static_cast<size_t>(id);
    if (!in_problem_[i]) {
      problem_->AddParameterBlock(parameters_[i].data(), kParameters, manifold_.get());
      in_problem_[i] = true;
    }
    return parameters_[i].data();
  }

  std::vector<std::array<double, kParameters>> parameters_;  // never resized after setup
  std::vector<bool> in_problem_;
  std::vector<bool> fixed_;
  std::vector<int> component_;      // per node
  std::vector<bool> has_metadata_;  // per component
  int residual_blocks_ = 0;
  int fixed_nodes_ = 0;
  std::unique_ptr<ceres::Manifold> manifold_;
  std::unique_ptr<ceres::LossFunction> loss_;
  std::unique_ptr<ceres::Problem> problem_;  // last: destroyed before what it points to
};

// The links do not see the gauge (M_k -> G M_k for all k of a component leaves them unchanged),
// only the metadata does, and reaching a far-off gauge by local steps is slow (the step is
// nonlinear in the node parameters, and the soft metadata against the stiff links makes it
// ill-conditioned). So each component with metadata first gets the map homography G that best
// takes its nodes' corners to their metadata corners (FitHomography), applied to all its nodes,
// kept only when it lowers the total cost and sends no image across G's horizon that was not
// across the map's already.
//
// The horizon test guards the nodes without metadata: the cost cannot see one that G sends
// across its horizon (the links do not see G, and it has no metadata residual), yet its image
// would then reach infinity. It is per node, on the sign of w over that node's own corners. A
// whole-component test (every corner of every node on one side) rejects exactly the starts the
// alignment is for: each node is stored with H(2,2) = 1, so a node that a projectively wrong
// start put wholly beyond its horizon carries the opposite sign of w, and G, undoing that start,
// leaves it with w < 0 at all its corners, which is where it belongs once normalised. In the
// metadata experiment on the figure eight (86 key frames, 10 % keystone) 16 key frames of the
// start straddle its horizon; the exact inverse of the start's error straddles none but failed
// the whole-component test, so no alignment was ever applied and LM stopped 2.3 km RMS off.
bool AlignGaugesToMetadata(const LinkGraph& graph, AdjustmentProblem* adjustment) {
  bool aligned = false;
  const std::array<Eigen::Vector2d, 4> corners =
      track::ImageCorners(graph.image_width, graph.image_height);
  for (int c = 0; c < adjustment->components(); ++c) {
    if (!adjustment->has_metadata(c)) continue;
    std::vector<size_t> members;
    std::vector<Eigen::Vector3d> from;
    std::vector<Eigen::Vector2d> to;
    for (size_t i = 0; i < graph.nodes.size(); ++i) {
      if (adjustment->component(i) != c || !adjustment->in_problem(i)) continue;
      members.push_back(i);
      if (!graph.nodes[i].metadata_corners) continue;
      const Eigen::Matrix3d m = HomographyFrom(adjustment->parameters(i));
      for (int k = 0; k < 4; ++k) {
        from.push_back(m * corners[static_cast<size_t>(k)].homogeneous());
        to.push_back((*graph.nodes[i].metadata_corners)[static_cast<size_t>(k)]);
      }
    }
    const std::optional<Eigen::Matrix3d> g = FitHomography(from, to);
    if (!g) continue;
    std::vector<std::array<double, kParameters>> moved;
    bool ok = true;
    for (size_t i : members) {
      const Eigen::Matrix3d current = HomographyFrom(adjustment->parameters(i));
      const Eigen::Matrix3d m = *g * current;
      ok = ok && std::abs(m(2, 2)) > 0 &&
           (OneSideOfHorizon(m, corners) || !OneSideOfHorizon(current, corners));
      if (!ok) break;
      moved.emplace_back();
      for (int j = 0; j < kParameters; ++j)
        moved.back()[static_cast<size_t>(j)] = m(j / 3, j % 3) / m(2, 2);
    }
    if (!ok) continue;
    const double before = adjustment->Cost();
    std::vector<std::array<double, kParameters>> saved;
    for (size_t k = 0; k < members.size(); ++k) {
      double* p = adjustment->parameters(members[k]);
      saved.emplace_back();
      std::copy(p, p + kParameters, saved.back().data());
      std::copy(moved[k].begin(), moved[k].end(), p);
    }
    const double after = adjustment->Cost();
    if (after < before) {
      aligned = true;
    } else {
      for (size_t k = 0; k < members.size(); ++k) {
        std::copy(saved[k].begin(), saved[k].end(), adjustment->parameters(members[k]));
      }
    }
  }
  return aligned;
}

// Checks the cancel flag and reports progress once per iteration.
class JobCallback : public ceres::IterationCallback {
 public:
  JobCallback(JobContext* job, int max_iterations) : job_(job), max_iterations_(max_iterations) {}

  ceres::CallbackReturnType operator()(const ceres::IterationSummary& summary) override {
    if (job_ == nullptr) return ceres::SOLVER_CONTINUE;
    if (job_->IsCancelled()) {
      cancelled_ = true;
      // Ceres keeps the best state: the parameters hold the last successful step.
      return ceres::SOLVER_TERMINATE_SUCCESSFULLY;
    }
    job_->ReportProgress("adjustment", std::min(1.0, static_cast<double>(summary.iteration) /
                                                         std::max(1, max_iterations_)));
    return ceres::SOLVER_CONTINUE;
  }

  bool cancelled() const { return cancelled_; }

 private:
  JobContext* job_;
  int max_iterations_;
  bool cancelled_ = false;
};

// Ceres reports a rank-deficient covariance Jacobian with a glog warning on stderr (glog writes
// there until the application initialises it); NodeCovariances returns it as a Status instead, so
// glog's warnings are held back while Ceres computes. Nested and concurrent uses share one saved
// level.
class QuietGlogWarnings {
 public:
  QuietGlogWarnings() {
    const std::lock_guard<std::mutex> lock(mutex_);
    if (depth_++ == 0) {
      saved_ = FLAGS_minloglevel;
      FLAGS_minloglevel = std::max<int>(saved_, google::GLOG_ERROR);
    }
  }
  ~QuietGlogWarnings() {
    const std::lock_guard<std::mutex> lock(mutex_);
    if (--depth_ == 0) FLAGS_minloglevel = saved_;
  }
  QuietGlogWarnings(const QuietGlogWarnings&) = delete;
  QuietGlogWarnings& operator=(const QuietGlogWarnings&) = delete;

 private:
  static inline std::mutex mutex_;
  static inline int depth_ = 0;
  static inline int saved_ = 0;
};

Status Check(const LinkGraph& graph, const AdjustmentOptions& options) {
  SAKER_RETURN_IF_ERROR(options.Validate());
  return graph.Validate();
}

}  // namespace

Status AdjustmentOptions::Validate() const {
  const auto positive = [](double v) { return std::isfinite(v) && v > 0; };
  if (!positive(metadata_sigma_m)) {
    return InvalidArgumentError("adjustment: metadata_sigma_m must be positive and finite");
  }
  if (!positive(min_link_sigma_px)) {
    return InvalidArgumentError("adjustment: min_link_sigma_px must be positive and finite");
  }
  if (!std::isfinite(loss_scale) || loss_scale < 0) {
    return InvalidArgumentError("adjustment: loss_scale must be >= 0 (0: no robust loss)");
  }
  if (max_iterations < 0) return InvalidArgumentError("adjustment: max_iterations must be >= 0");
  if (num_threads < 1) return InvalidArgumentError("adjustment: num_threads must be >= 1");
  if (!positive(function_tolerance)) {
    return InvalidArgumentError("adjustment: function_tolerance must be positive and finite");
  }
  return Status::Ok();
}

std::string AdjustmentSummary::ToString() const {
  char buffer[256];
  std::snprintf(buffer, sizeof(buffer),
                "adjustment: %s%s, %d iterations, cost %.6g -> %.6g, %d residual blocks, %d fixed "
                "nodes, %.3f s",
                usable ? "usable" : "NOT usable", cancelled ? " (cancelled)" : "", iterations,
                initial_cost, final_cost, residual_blocks, fixed_nodes, time_s);
  return std::string(buffer) + (message.empty() ? "" : " (" + message + ")");
}

StatusOr<AdjustmentSummary> Adjust(LinkGraph* graph, const AdjustmentOptions& options,
                                   JobContext* job) {
  SAKER_CHECK(graph != nullptr);
  const Stopwatch start;
  SAKER_RETURN_IF_ERROR(Check(*graph, options));

  AdjustmentProblem adjustment(*graph, options);
  AdjustmentSummary summary;
  summary.fixed_nodes = adjustment.fixed_nodes();
  summary.residual_blocks = adjustment.residual_blocks();
  if (adjustment.residual_blocks() == 0 || adjustment.problem().NumResidualBlocks() == 0) {
    summary.usable = true;
    summary.message = "nothing to adjust";
    if (job != nullptr) job->ReportProgress("adjustment", 1);
    return summary;
  }

  // The caller's start is what "no worse than the start" refers to; the alignment only ever
  // lowers the cost.
  const bool metadata = graph->geo_referenced && options.use_metadata;
  const double start_cost = metadata ? adjustment.Cost() : 0;
  const bool aligned = metadata && AlignGaugesToMetadata(*graph, &adjustment);

  ceres::Solver::Options solver;
  solver.minimizer_type = ceres::TRUST_REGION;
  solver.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  solver.sparse_linear_algebra_library_type = SparseLibrary();
  solver.linear_solver_type = solver.sparse_linear_algebra_library_type == ceres::NO_SPARSE
                                  ? ceres::DENSE_QR
                                  : ceres::SPARSE_NORMAL_CHOLESKY;
  solver.max_num_iterations = options.max_iterations;
  solver.num_threads = options.num_threads;
  solver.function_tolerance = options.function_tolerance;
  // A long drifted chain closed by cross-links leaves soft, curved directions (near-gauge
  // perspective) along which monotonic LM crawls; non-monotonic steps measured 17 iterations
  // instead of > 50 on the 1000 key frame benchmark. Ceres still returns the best solution seen.
  solver.use_nonmonotonic_steps = true;
  solver.logging_type = ceres::SILENT;
  solver.minimizer_progress_to_stdout = false;
  JobCallback callback(job, options.max_iterations);
  solver.callbacks.push_back(&callback);
  std::string invalid;
  if (!solver.IsValid(&invalid)) {
    return InvalidArgumentError("adjustment: solver options: " + invalid);
  }

  ceres::Solver::Summary ceres_summary;
  ceres::Solve(solver, &adjustment.problem(), &ceres_summary);

  summary.iterations = std::max(0, static_cast<int>(ceres_summary.iterations.size()) - 1);
  summary.initial_cost = aligned ? start_cost : ceres_summary.initial_cost;
  summary.final_cost = ceres_summary.final_cost;
  summary.cancelled = callback.cancelled();
  summary.message = ceres_summary.message;
  bool finite = true;
  for (size_t i = 0; i < graph->nodes.size(); ++i) {
    const double* p = adjustment.parameters(i);
    finite = finite && std::all_of(p, p + kParameters, [](double v) { return std::isfinite(v); });
  }
  summary.usable = ceres_summary.IsSolutionUsable() && finite &&
                   ceres_summary.final_cost <= ceres_summary.initial_cost;
  if (summary.usable) {
    for (size_t i = 0; i < graph->nodes.size(); ++i) {
      if (adjustment.fixed(i) || !adjustment.in_problem(i)) continue;
      graph->nodes[i].map_from_frame = track::HomographyFromParameters(
          Eigen::Map<const track::HomographyParameters>(adjustment.parameters(i)));
    }
  }
  if (job != nullptr) job->ReportProgress("adjustment", 1);
  summary.time_s = start.ElapsedSeconds();
  return summary;
}

StatusOr<std::vector<track::HomographyCovariance>> NodeCovariances(
    const LinkGraph& graph, const AdjustmentOptions& options,
    const std::vector<KeyFrameId>& nodes) {
  SAKER_RETURN_IF_ERROR(Check(graph, options));
  std::vector<size_t> wanted;
  if (nodes.empty()) {
    for (size_t i = 0; i < graph.nodes.size(); ++i) wanted.push_back(i);
  } else {
    for (KeyFrameId id : nodes) {
      if (static_cast<int>(id) < 0 || static_cast<size_t>(id) >= graph.nodes.size()) {
        return InvalidArgumentError("node covariances: key frame " +
                                    std::to_string(static_cast<int>(id)) + " is not in the graph");
      }
      wanted.push_back(static_cast<size_t>(id));
    }
  }

  AdjustmentProblem adjustment(graph, options);
  std::vector<std::pair<const double*, const double*>> blocks;
  std::vector<bool> requested(graph.nodes.size(), false);
  for (size_t i : wanted) {
    if (requested[i] || adjustment.fixed(i) || !adjustment.in_problem(i)) continue;
    requested[i] = true;
    blocks.emplace_back(adjustment.parameters(i), adjustment.parameters(i));
  }

  std::vector<track::HomographyCovariance> result(wanted.size(),
                                                  track::HomographyCovariance::Zero());
  if (blocks.empty()) return result;

  ceres::Covariance::Options covariance_options;
  covariance_options.sparse_linear_algebra_library_type = SparseLibrary();
  covariance_options.algorithm_type =
      covariance_options.sparse_linear_algebra_library_type == ceres::NO_SPARSE ? ceres::DENSE_SVD
                                                                                : ceres::SPARSE_QR;
  covariance_options.num_threads = options.num_threads;
  covariance_options.apply_loss_function = true;
  ceres::Covariance covariance(covariance_options);
  bool computed = false;
  {
    const QuietGlogWarnings quiet;
    computed = covariance.Compute(blocks, &adjustment.problem());
  }
  if (!computed) {
    return InvalidDataError(
        "node covariances: the adjustment problem is rank deficient (a degenerate link or "
        "metadata geometry leaves some key frame undetermined)");
  }
  for (size_t k = 0; k < wanted.size(); ++k) {
    const size_t i = wanted[k];
    if (adjustment.fixed(i) || !adjustment.in_problem(i)) continue;
    Eigen::Matrix<double, kParameters, kParameters, Eigen::RowMajor> block;
    if (!covariance.GetCovarianceBlock(adjustment.parameters(i), adjustment.parameters(i),
                                       block.data())) {
      return InvalidDataError("node covariances: no covariance for key frame " + std::to_string(i));
    }
    result[k] = 0.5 * (block + block.transpose());
  }
  return result;
}

}  // namespace saker::mosaic
