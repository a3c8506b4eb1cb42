// saker-bench-mosaic: bundle adjustment time against the number of key frames, on synthetic link
// graphs with loops: a raster of rows flown back and forth, sequential links along the path and
// cross-links to the neighbour in the adjacent row, noisy link measurements (corner noise with a
// stated covariance), a start chained through the sequential links (drifted). Reports residual
// blocks, iterations, the median adjustment time, the NodeCovariances time and the RMS corner
// error before / after. Target: 1000 key frames adjust in <= 1 s on 2 cores.
//
// Then the loop-closure candidate query time against the number of indexed key frames, and the
// in-between frames chain solver (SolveChain) against the number of frames: a synthetic video
// flying circuits, frame-to-frame homographies with corner noise and their covariance, both ends
// fixed at the truth; solve time without and with covariances, frames per second, microseconds
// per frame and its ratio to the smallest size (linear time: about 1), iterations, and the RMS
// corner error of the chained product and of the solution. Target: >= 100 000 in-between frames
// per second on 2 cores.
//
// Last, full against decomposed (node/arc) adjustment on graphs of loops (MakeLoops: circles of 60
// key frames crossing the two before them, closures and crossings as the only cross-links) of 75
// to 10 000 key frames: nodes, arcs, times, speed-up, both final costs and errors. Target: 10 000
// key frames adjust decomposed in <= 10 s on 2 cores.
//
//   saker-bench-mosaic [--sizes 100,1000] [--threads 2] [--repeats 3] [--covariance-max N]
//                      [--seed S] [--max-iterations N] [--function-tolerance T]
//                      [--chain-sizes 1000,10000,100000,1000000]
//                      [--decomposition-sizes 75,300,1000,10000] [--full-max N]
//                      [--warm-every 1000]
//
// Each part is its own function called from main (BenchmarkAdjustment, BenchmarkQuery,
// BenchmarkChain, BenchmarkDecomposition).

#include "core/mosaic/adjustment.h"
#include "core/mosaic/chain_solver.h"
#include "core/mosaic/decomposition.h"
#include "core/mosaic/link_graph.h"
#include "core/mosaic/loop_closure.h"
#include "core/mosaic/mosaic_builder.h"
#include "core/track/homography.h"
#include "core/track/image_geometry.h"
#include "core/util/check.h"
#include "core/util/statistics.h"
#include "core/util/timer.h"
#include "tests/core/mosaic/synthetic_camera.h"

#include <CLI/CLI.hpp>
#include <Eigen/Dense>

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

namespace {

using saker::Median;
using saker::Stopwatch;

using saker::mosaic::KeyFrameId;
using saker::mosaic::Link;
using saker::mosaic::LinkGraph;
using saker::track::ImageCorners;
using Matrix8 = Eigen::Matrix<double, 8, 8>;
using Vector8 = Eigen::Matrix<double, 8, 1>;

using saker::mosaic::testing_support::GroundFromImage;
using saker::mosaic::testing_support::Normalised;
using saker::mosaic::testing_support::SyntheticCamera;

constexpr int kWidth = SyntheticCamera{}.width;
constexpr int kHeight = SyntheticCamera{}.height;
constexpr double kStepM = 60;         // along-track key frame spacing (~50 % overlap)
constexpr double kRowSpacingM = 150;  // ~25 % side overlap
constexpr double kCornerSigmaPx = 0.5;

class Noise {
 public:
  explicit Noise(uint64_t seed) : engine_(seed) {}
  double Gaussian() { return normal_(engine_); }

 private:
  std::mt19937_64 engine_;
  std::normal_distribution<double> normal_;
};

// The homography taking the 4 points `from` exactly to `to`.
Eigen::Matrix3d FourPointHomography(const std::array<Eigen::Vector2d, 4>& from,
                                    const std::array<Eigen::Vector2d, 4>& to) {
  const auto h = saker::track::HomographyFromCorners(from, to, 1.0);
  SAKER_CHECK(h.ok()) << h.status().ToString();
  return h->target_from_source;
}

// The truth corners of `from` in `to` perturbed by N(0, S) (S random, correlated, average sigma
// kCornerSigmaPx), fitted exactly; covariance C = J^-1 S J^-T.
Link MeasureLink(const std::vector<Eigen::Matrix3d>& truth, int from, int to, Noise& noise) {
  Matrix8 b;
  for (int i = 0; i < 64; ++i) b(i) = noise.Gaussian();
  const Matrix8 corner_cov =
      kCornerSigmaPx * kCornerSigmaPx * (0.6 * Matrix8::Identity() + 0.05 * b * b.transpose());
  Vector8 z;
  for (int i = 0; i < 8; ++i) z(i) = noise.Gaussian();
  const Vector8 error = Matrix8(corner_cov.llt().matrixL()) * z;
  const Eigen::Matrix3d truth_to_from_from =
      Normalised(truth[static_cast<size_t>(to)].inverse() * truth[static_cast<size_t>(from)]);
  const auto corners = ImageCorners(kWidth, kHeight);
  std::array<Eigen::Vector2d, 4> measured;
  for (size_t i = 0; i < 4; ++i) {
    measured[i] = saker::track::Transfer(truth_to_from_from, corners[i]) +
                  error.segment<2>(2 * static_cast<Eigen::Index>(i));
  }
  Link link;
  link.from = static_cast<KeyFrameId>(from);
  link.to = static_cast<KeyFrameId>(to);
  link.kind =
      to == from + 1 ? saker::mosaic::LinkKind::kSequential : saker::mosaic::LinkKind::kGeometric;
  link.to_from_from = FourPointHomography(corners, measured);
  Matrix8 j;
  for (size_t i = 0; i < 4; ++i) {
    j.middleRows<2>(2 * static_cast<Eigen::Index>(i)) =
        saker::track::TransferJacobian(link.to_from_from, corners[i]);
  }
  const Matrix8 j_inv = j.inverse();
  link.covariance = j_inv * corner_cov * j_inv.transpose();
  link.covariance = 0.5 * (link.covariance + link.covariance.transpose()).eval();
  return link;
}

struct Scene {
  std::vector<Eigen::Matrix3d> truth;
  LinkGraph graph;  // drifted start
};

// The drifted start: key frame 0 at the truth, every other chained through the sequential links.
void ChainStart(Scene* scene) {
  LinkGraph& graph = scene->graph;
  graph.nodes[0].map_from_frame = scene->truth[0];
  for (const Link& link : graph.links) {
    if (static_cast<int>(link.to) == static_cast<int>(link.from) + 1) {
      graph.nodes[static_cast<size_t>(link.to)].map_from_frame = Normalised(
          graph.nodes[static_cast<size_t>(link.from)].map_from_frame * link.to_from_from.inverse());
    }
  }
}

// About n key frames in rows of `columns`, flown back and forth (boustrophedon).
Scene MakeRaster(int n, uint64_t seed) {
  const int columns = std::max(2, static_cast<int>(std::lround(std::sqrt(1.6 * n))));
  const int rows = std::max(1, (n + columns - 1) / columns);
  Noise noise(seed);
  Scene scene;
  std::vector<std::pair<int, int>> cell;  // (row, column) per key frame along the path
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < columns && static_cast<int>(cell.size()) < n; ++c) {
      const int column = r % 2 == 0 ? c : columns - 1 - c;
      const double heading = r % 2 == 0 ? 0 : M_PI;
      const size_t k = cell.size();
      scene.truth.push_back(GroundFromImage(kStepM * column, kRowSpacingM * r, heading,
                                            0.02 * std::sin(0.37 * static_cast<double>(k)),
                                            0.02 * std::cos(0.23 * static_cast<double>(k))));
      cell.emplace_back(r, column);
    }
  }
  LinkGraph& graph = scene.graph;
  graph.image_width = kWidth;
  graph.image_height = kHeight;
  graph.geo_referenced = true;  // ENU metres, no metadata: node 0 holds the gauge
  for (size_t k = 0; k < cell.size(); ++k) {
    saker::mosaic::Node node;
    node.id = static_cast<KeyFrameId>(static_cast<int>(k));
    node.frame_index = static_cast<int64_t>(k) * 25;
    graph.nodes.push_back(node);
  }
  std::vector<int> index(static_cast<size_t>(rows * columns), -1);
  for (size_t k = 0; k < cell.size(); ++k) {
    index[static_cast<size_t>(cell[k].first * columns + cell[k].second)] = static_cast<int>(k);
  }
  for (size_t k = 0; k + 1 < cell.size(); ++k) {
    graph.links.push_back(
        MeasureLink(scene.truth, static_cast<int>(k), static_cast<int>(k) + 1, noise));
  }
  for (size_t k = 0; k < cell.size(); ++k) {
    const auto [r, c] = cell[k];
    if (r == 0) continue;
    const int below = index[static_cast<size_t>((r - 1) * columns + c)];
    // Not the turn link, which is already sequential.
    if (below >= 0 && below + 1 != static_cast<int>(k)) {
      graph.links.push_back(MeasureLink(scene.truth, below, static_cast<int>(k), noise));
    }
  }
  ChainStart(&scene);
  return scene;
}

double RmsCornerError(const LinkGraph& graph, const std::vector<Eigen::Matrix3d>& truth) {
  double sum = 0;
  for (size_t k = 0; k < graph.nodes.size(); ++k) {
    for (const Eigen::Vector2d& c : ImageCorners(kWidth, kHeight)) {
      sum += (saker::track::Transfer(graph.nodes[k].map_from_frame, c) -
              saker::track::Transfer(truth[k], c))
                 .squaredNorm();
    }
  }
  return std::sqrt(sum / static_cast<double>(4 * graph.nodes.size()));
}

// Predicted RMS corner error (map units) from node covariances (of the listed nodes, or all).
double PredictedRms(const LinkGraph& graph,
                    const std::vector<saker::track::HomographyCovariance>& covariances,
                    const std::vector<KeyFrameId>& nodes) {
  double sum = 0;
  for (size_t k = 0; k < covariances.size(); ++k) {
    const size_t node = nodes.empty() ? k : static_cast<size_t>(nodes[k]);
    for (const Eigen::Vector2d& c : ImageCorners(kWidth, kHeight)) {
      sum += saker::track::TransferCovariance(graph.nodes[node].map_from_frame, covariances[k], c)
                 .trace();
    }
  }
  return std::sqrt(sum / static_cast<double>(4 * covariances.size()));
}

// Bundle adjustment and covariance timing per graph size. Returns the median adjustment time
// per size (same order as `sizes`), or an empty vector on failure.
std::vector<double> BenchmarkAdjustment(const std::vector<int>& sizes,
                                        const saker::mosaic::AdjustmentOptions& options,
                                        int repeats, int covariance_max, uint64_t seed) {
  const int threads = options.num_threads;
  std::printf(
      "Bundle adjustment: raster graphs, map in metres (0.156 m/px), corner noise %.2f px, "
      "%d threads, median of %d runs\n",
      kCornerSigmaPx, threads, repeats);
  std::printf("%6s %6s %7s %6s %9s %13s %11s %10s %10s\n", "nodes", "links", "blocks", "iters",
              "adjust_s", "cov_s", "rms_start", "rms_adj", "rms_pred");
  std::vector<double> times;
  for (int n : sizes) {
    const Scene scene = MakeRaster(n, seed + static_cast<uint64_t>(n));
    std::vector<double> run_times;
    saker::mosaic::AdjustmentSummary summary;
    LinkGraph adjusted;
    for (int r = 0; r < repeats; ++r) {
      adjusted = scene.graph;
      const Stopwatch start;
      auto result = saker::mosaic::Adjust(&adjusted, options);
      run_times.push_back(start.ElapsedSeconds());
      if (!result.ok()) {
        std::fprintf(stderr, "adjustment failed: %s\n", result.status().ToString().c_str());
        return {};
      }
      summary = *result;
    }
    // Covariances of all nodes, or of covariance_max nodes spread over the graph beyond that.
    std::vector<KeyFrameId> wanted;
    const bool all = static_cast<int>(adjusted.nodes.size()) <= covariance_max;
    if (!all) {
      for (int k = 0; k < covariance_max; ++k) {
        wanted.push_back(
            static_cast<KeyFrameId>(static_cast<int>(adjusted.nodes.size()) * k / covariance_max));
      }
    }
    const Stopwatch cov_start;
    const auto covariances = saker::mosaic::NodeCovariances(adjusted, options, wanted);
    const double cov_s = cov_start.ElapsedSeconds();
    if (!covariances.ok()) {
      std::fprintf(stderr, "covariances failed: %s\n", covariances.status().ToString().c_str());
      return {};
    }
    char cov_text[40];
    std::snprintf(cov_text, sizeof(cov_text), all ? "%.3f" : "%.3f (%d)", cov_s,
                  static_cast<int>(wanted.size()));
    const double t = Median(run_times);
    times.push_back(t);
    std::printf("%6zu %6zu %7d %6d %9.3f %13s %11.2f %10.2f %10.2f\n", adjusted.nodes.size(),
                adjusted.links.size(), summary.residual_blocks, summary.iterations, t, cov_text,
                RmsCornerError(scene.graph, scene.truth), RmsCornerError(adjusted, scene.truth),
                PredictedRms(adjusted, *covariances, wanted));
    std::printf("       %s\n", summary.ToString().c_str());
  }
  if (times.size() >= 2) {
    std::printf("time(%d) / time(%d) = %.1f (key frame ratio %.1f)\n", sizes.back(), sizes.front(),
                times.back() / times.front(), static_cast<double>(sizes.back()) / sizes.front());
  }
  std::printf(
      "rms_*: RMS corner error against the truth in metres (gauge: node 0 at its truth) of the\n"
      "chained start, of the adjusted solution, and as the node covariances predict it;\n"
      "cov_s: NodeCovariances of all nodes, \"(k)\": of k spread nodes (--covariance-max).\n");
  return times;
}

// Synthetic SIFT-like descriptors: each key frame sees a random selection of "places" (cluster
// centres in descriptor space) with noise, so words and posting lists behave as with real
// imagery; the query frame shares half its places with one indexed frame.
cv::Mat PlaceDescriptors(const cv::Mat& places, int count, std::mt19937_64& random) {
  cv::Mat d(count, 128, CV_32F);
  std::uniform_int_distribution<int> pick(0, places.rows - 1);
  std::normal_distribution<float> noise(0.0f, 12.0f);
  for (int i = 0; i < count; ++i) {
    const float* c = places.ptr<float>(pick(random));
    float* row = d.ptr<float>(i);
    for (int j = 0; j < 128; ++j) row[j] = std::max(0.0f, c[j] + noise(random));
  }
  return d;
}

// Loop-closure candidate query time against the number of indexed key frames, next to one
// pairwise appearance matching measured in the same run: a query that cost O(n) matchings would
// grow n-fold.
void BenchmarkQuery(const std::vector<int>& sizes, uint64_t seed) {
  using saker::mosaic::KeyFrameFeatures;
  std::mt19937_64 random(seed);
  cv::Mat places(5000, 128, CV_32F);
  std::uniform_real_distribution<float> uniform(0.0f, 60.0f);
  for (int i = 0; i < places.rows; ++i)
    for (int j = 0; j < 128; ++j) places.at<float>(i, j) = uniform(random);
  const int per_frame = 900;
  const auto frame = [&](int id) {
    KeyFrameFeatures f;
    f.id = static_cast<saker::mosaic::KeyFrameId>(id);
    f.descriptors = PlaceDescriptors(places, per_frame, random);
    for (int i = 0; i < per_frame; ++i) {
      f.points.emplace_back(std::uniform_real_distribution<double>(0, 1279)(random),
                            std::uniform_real_distribution<double>(0, 719)(random));
      f.track_ids.push_back(static_cast<saker::track::FeatureTrackId>(i));
    }
    return f;
  };
  // The baseline: one appearance matching of two frames (descriptor matching + RANSAC).
  const KeyFrameFeatures a = frame(0), b = frame(1);
  std::vector<double> pair_times;
  for (int r = 0; r < 5; ++r) {
    const Stopwatch start;
    (void)saker::mosaic::MatchAppearance(a, b, 1280, 720, {});
    pair_times.push_back(start.ElapsedSeconds());
  }
  const double pair_s = Median(pair_times);
  std::printf(
      "\nLoop-closure candidates: appearance index (bag of words), %d descriptors per key "
      "frame\n",
      per_frame);
  std::printf("one pairwise appearance matching (baseline): %.2f ms\n", pair_s * 1e3);
  std::printf("%6s %10s %10s %16s\n", "n", "add_ms", "query_ms", "query/matching");
  saker::mosaic::AppearanceIndex index({});
  int added = 0;
  for (int n : sizes) {
    const Stopwatch add_start;
    const int before = added;
    for (; added < n; ++added) index.Add(frame(added));
    const double add_ms = added > before ? add_start.ElapsedSeconds() * 1e3 / (added - before) : 0;
    std::vector<double> query_times;
    for (int r = 0; r < 20; ++r) {
      const KeyFrameFeatures q = frame(1000000 + r);
      const Stopwatch start;
      (void)index.Query(q, 4);
      query_times.push_back(start.ElapsedSeconds());
    }
    const double q = Median(query_times);
    std::printf("%6d %10.2f %10.2f %16.2f\n", n, add_ms, q * 1e3, q / pair_s);
  }
  std::printf(
      "query/matching: the query's cost in pairwise matchings; O(n) matching would be n.\n");
}

// A video flying circuits of a 1500 m radius circle at 1.6 m per frame (40 m/s at 25 frames per
// second, about 10 px at 0.156 m/px), pitching and rolling a little: the truth of frame k.
Eigen::Matrix3d CircuitFrame(int64_t k) {
  constexpr double kRadiusM = 1500, kFrameStepM = 1.6;
  const double t = static_cast<double>(k) * kFrameStepM / kRadiusM;
  return GroundFromImage(kRadiusM * std::cos(t), kRadiusM * std::sin(t), t + M_PI / 2,
                         0.03 * std::sin(0.05 * static_cast<double>(k)),
                         0.02 * std::cos(0.031 * static_cast<double>(k)));
}

// Where `estimate` puts each frame's image corners against the truth, metres: the RMS over all
// frames and corners, and the median over the frames of their corners' RMS.
struct ChainError {
  double rms_m = 0, median_m = 0;
};
ChainError ChainErrorM(const std::vector<Eigen::Matrix3d>& estimate) {
  const auto corners = ImageCorners(kWidth, kHeight);
  double sum = 0;
  std::vector<double> per_frame;
  per_frame.reserve(estimate.size());
  for (size_t k = 0; k < estimate.size(); ++k) {
    const Eigen::Matrix3d truth = CircuitFrame(static_cast<int64_t>(k));
    double frame = 0;
    for (const Eigen::Vector2d& c : corners) {
      const Eigen::Vector3d p = estimate[k] * c.homogeneous(), q = truth * c.homogeneous();
      frame += (p.head<2>() / p.z() - q.head<2>() / q.z()).squaredNorm();
    }
    sum += frame;
    per_frame.push_back(std::sqrt(frame / 4));
  }
  return {std::sqrt(sum / static_cast<double>(4 * estimate.size())), Median(std::move(per_frame))};
}

// In-between frames: SolveChain time against the chain length, both ends fixed at the truth. The
// per-step noise is the solver's floor (min_link_sigma_px): a consecutive-frame homography from
// many tracks. A single chain of 10^6 such steps is 1600 km long: the projective drift of a
// homography chain then throws a few frames towards the horizon, whatever the solver (the rms
// columns; the median shows the typical frame), and with 0.1 px per step it drifts so far that
// Gauss-Newton does not converge within its iterations at 10^6 (docs/mosaic.md).
void BenchmarkChain(const std::vector<int>& sizes, uint64_t seed) {
  constexpr double kChainSigmaPx = 0.05;
  std::printf(
      "\nIn-between frames (SolveChain): circuits of a 1500 m circle, 1.6 m per frame, corner "
      "noise %.2f px per step, both ends fixed at the truth, 1 thread\n",
      kChainSigmaPx);
  std::printf("%8s %5s %9s %10s %9s %6s %6s %9s %9s %11s %10s %11s %10s\n", "frames", "runs",
              "solve_s", "frames/s", "us/frame", "ratio", "iters", "cov_s", "cov_us/f",
              "rms_chained", "rms_solved", "med_chained", "med_solved");
  const auto corners = ImageCorners(kWidth, kHeight);
  double first_us = 0;
  for (int n : sizes) {
    // The measured steps: the truth's corners moved by isotropic noise, fitted exactly, with the
    // covariance that noise implies.
    Noise noise(seed + static_cast<uint64_t>(n));
    std::vector<saker::mosaic::ChainStep> steps(static_cast<size_t>(n));
    Eigen::Matrix3d previous = CircuitFrame(0);
    const Eigen::Matrix3d first = previous;
    for (int k = 0; k < n; ++k) {
      const Eigen::Matrix3d next = CircuitFrame(k + 1);
      const Eigen::Matrix3d exact = Normalised(next.inverse() * previous);
      std::array<Eigen::Vector2d, 4> measured;
      for (size_t i = 0; i < 4; ++i) {
        measured[i] = saker::track::Transfer(exact, corners[i]) +
                      kChainSigmaPx * Eigen::Vector2d(noise.Gaussian(), noise.Gaussian());
      }
      const auto h = saker::track::HomographyFromCorners(corners, measured, kChainSigmaPx);
      SAKER_CHECK(h.ok()) << h.status().ToString();
      steps[static_cast<size_t>(k)].next_from_previous = h->target_from_source;
      steps[static_cast<size_t>(k)].covariance = h->covariance;
      previous = next;
    }
    const Eigen::Matrix3d last = previous;

    // Repeated up to about 10^6 frames' worth (at least once, at most 9 times), the median
    // reported.
    const int runs = std::clamp(1000000 / n, 1, 9);
    saker::mosaic::ChainOptions options;
    std::vector<double> times;
    saker::mosaic::ChainSolution solution;
    for (int r = 0; r < runs; ++r) {
      solution = {};  // freed before the next run, so memory stays that of one
      const Stopwatch start;
      auto result = saker::mosaic::SolveChain(first, last, steps, kWidth, kHeight, options);
      times.push_back(start.ElapsedSeconds());
      if (!result.ok()) {
        std::fprintf(stderr, "chain solve failed: %s\n", result.status().ToString().c_str());
        return;
      }
      solution = std::move(result).value();
    }
    const int iterations = solution.iterations;
    const ChainError solved = ChainErrorM(solution.map_from_frame);
    solution = {};
    options.covariances = true;
    const Stopwatch cov_start;
    const auto with_covariances =
        saker::mosaic::SolveChain(first, last, steps, kWidth, kHeight, options);
    const double cov_s = cov_start.ElapsedSeconds();
    if (!with_covariances.ok()) {
      std::fprintf(stderr, "chain solve failed: %s\n",
                   with_covariances.status().ToString().c_str());
      return;
    }
    std::vector<Eigen::Matrix3d> chained = {first};
    chained.reserve(static_cast<size_t>(n) + 1);
    for (const saker::mosaic::ChainStep& step : steps) {
      chained.push_back(Normalised(chained.back() * step.next_from_previous.inverse()));
    }
    const double t = Median(times);
    const double us = t * 1e6 / n;
    if (first_us == 0) first_us = us;
    const ChainError before = ChainErrorM(chained);
    std::printf("%8d %5d %9.4f %10.0f %9.3f %6.2f %6d %9.4f %9.3f %11.4g %10.4g %11.4g %10.4g\n", n,
                runs, t, n / t, us, us / first_us, iterations, cov_s, cov_s * 1e6 / n, before.rms_m,
                solved.rms_m, before.median_m, solved.median_m);
  }
  std::printf(
      "solve_s: median over `runs` of SolveChain without covariances (checks, whitening, start, "
      "Gauss-Newton); ratio: us/frame against the\nfirst size (linear time: ~1); cov_s: one "
      "SolveChain with covariances; rms_*: RMS corner error against the truth in metres of the\n"
      "chained product (first end only) and of the solution; med_*: the median over frames.\n");
}

// About n key frames flying loops: circles of 60 key frames (radius ~570 m) whose centres are
// 400 m apart, joined by straight transits, so each circle crosses the two before it twice each.
// Cross-links: each loop's closure (its last key frame with its first) and, at each crossing with
// the two previous loops, the nearest pair of key frames: "several loops", and few cross-links, as
// a long surveillance flight has them.
Scene MakeLoops(int n, uint64_t seed) {
  constexpr int kLoop = 60;
  const double radius = kLoop * kStepM / (2 * M_PI);
  constexpr double kSpacingM = 400;
  Noise noise(seed);
  Scene scene;
  std::vector<Eigen::Vector2d> centre;
  std::vector<int> loop_of;  // per key frame: its loop, or -1 on a transit
  for (int loop = 0; static_cast<int>(scene.truth.size()) < n; ++loop) {
    const Eigen::Vector2d c(kSpacingM * loop, 0);
    for (int j = 0; j < kLoop && static_cast<int>(scene.truth.size()) < n; ++j) {
      const double angle = M_PI + 2 * M_PI * j / kLoop;  // from the west point, anticlockwise
      const size_t k = scene.truth.size();
      const Eigen::Vector2d p = c + radius * Eigen::Vector2d(std::cos(angle), std::sin(angle));
      scene.truth.push_back(GroundFromImage(p.x(), p.y(), angle + M_PI / 2,
                                            0.02 * std::sin(0.37 * static_cast<double>(k)),
                                            0.02 * std::cos(0.23 * static_cast<double>(k))));
      centre.push_back(p);
      loop_of.push_back(loop);
    }
    // Transit from this west point to the next circle's, heading east.
    const double from = c.x() - radius, to = from + kSpacingM;
    for (double x = from + kStepM;
         x < to - 0.5 * kStepM && static_cast<int>(scene.truth.size()) < n; x += kStepM) {
      const size_t k = scene.truth.size();
      scene.truth.push_back(GroundFromImage(x, 0, 0, 0.02 * std::sin(0.37 * static_cast<double>(k)),
                                            0.02 * std::cos(0.23 * static_cast<double>(k))));
      centre.emplace_back(x, 0);
      loop_of.push_back(-1);
    }
  }
  LinkGraph& graph = scene.graph;
  graph.image_width = kWidth;
  graph.image_height = kHeight;
  graph.geo_referenced = true;  // ENU metres, no metadata: node 0 holds the gauge
  for (size_t k = 0; k < scene.truth.size(); ++k) {
    saker::mosaic::Node node;
    node.id = static_cast<KeyFrameId>(static_cast<int>(k));
    node.frame_index = static_cast<int64_t>(k) * 25;
    graph.nodes.push_back(node);
  }
  for (size_t k = 0; k + 1 < scene.truth.size(); ++k) {
    graph.links.push_back(
        MeasureLink(scene.truth, static_cast<int>(k), static_cast<int>(k) + 1, noise));
  }
  // Per loop: its key frames.
  std::vector<std::vector<int>> members;
  for (size_t k = 0; k < loop_of.size(); ++k) {
    if (loop_of[k] < 0) continue;
    if (static_cast<size_t>(loop_of[k]) >= members.size())
      members.resize(static_cast<size_t>(loop_of[k]) + 1);
    members[static_cast<size_t>(loop_of[k])].push_back(static_cast<int>(k));
  }
  for (size_t loop = 0; loop < members.size(); ++loop) {
    const std::vector<int>& m = members[loop];
    if (static_cast<int>(m.size()) == kLoop)
      graph.links.push_back(MeasureLink(scene.truth, m.back(), m.front(), noise));
    // The crossings with the two previous loops: the closest pair in each half (north, south).
    for (size_t back = 1; back <= std::min<size_t>(2, loop); ++back) {
      for (const double side : {1.0, -1.0}) {
        double best = 40;  // metres: overlapping footprints
        std::pair<int, int> pair{-1, -1};
        for (int a : members[loop - back]) {
          if (side * centre[static_cast<size_t>(a)].y() <= 0) continue;
          for (int b : m) {
            const double d =
                (centre[static_cast<size_t>(a)] - centre[static_cast<size_t>(b)]).norm();
            if (d < best) best = d, pair = {a, b};
          }
        }
        if (pair.first >= 0) {
          graph.links.push_back(MeasureLink(scene.truth, pair.second, pair.first, noise));
        }
      }
    }
  }
  ChainStart(&scene);
  return scene;
}

// The first m key frames of `graph` and the links among them.
LinkGraph Prefix(const LinkGraph& graph, int m) {
  LinkGraph prefix = graph;
  prefix.nodes.resize(static_cast<size_t>(m));
  prefix.links.clear();
  for (const Link& link : graph.links) {
    if (static_cast<int>(link.from) < m && static_cast<int>(link.to) < m)
      prefix.links.push_back(link);
  }
  return prefix;
}

// Key frames from `first` on chained through the sequential links from key frame first - 1.
void ChainFrom(LinkGraph* graph, int first) {
  for (const Link& link : graph->links) {
    if (static_cast<int>(link.to) == static_cast<int>(link.from) + 1 &&
        static_cast<int>(link.to) >= first) {
      graph->nodes[static_cast<size_t>(link.to)].map_from_frame =
          Normalised(graph->nodes[static_cast<size_t>(link.from)].map_from_frame *
                     link.to_from_from.inverse());
    }
  }
}

// The start the mosaic builder has when the flight reaches its last key frame: it adjusted as the
// flight went (the builder adjusts at every loop closure; here, harsher, every `every` key
// frames: the graph so far, decomposed, warm started from the previous solution and the chain
// beyond it), and the key frames since the last adjustment are chained. Returns the time spent.
double WarmStart(const Scene& scene, int every, const saker::mosaic::AdjustmentOptions& options,
                 LinkGraph* start) {
  *start = scene.graph;
  const int n = static_cast<int>(scene.graph.nodes.size());
  double seconds = 0;
  for (int m = every; m < n; m += every) {
    LinkGraph prefix = Prefix(*start, m);
    const Stopwatch begin;
    const auto summary = saker::mosaic::AdjustDecomposed(&prefix, options, {});
    seconds += begin.ElapsedSeconds();
    SAKER_CHECK(summary.ok()) << summary.status().ToString();
    for (int k = 0; k < m; ++k)
      start->nodes[static_cast<size_t>(k)] = prefix.nodes[static_cast<size_t>(k)];
    ChainFrom(start, m);
  }
  return seconds;
}

// Full against decomposed adjustment on MakeLoops graphs: nodes and arcs, times, the speed-up,
// both final costs (the same problem solved: they should be close) and both solutions' RMS corner
// error against the truth, from two starts: the chain through every link ("chained", drifted
// tens of kilometres at 10 000 key frames) and, above `warm_every` key frames, the builder's
// ("warm": adjusted every `warm_every` key frames on the way, WarmStart). The full adjustment is
// skipped above `full_max` key frames (0: never).
void BenchmarkDecomposition(const std::vector<int>& sizes,
                            const saker::mosaic::AdjustmentOptions& options, int full_max,
                            int warm_every, uint64_t seed) {
  std::printf(
      "\nFull versus decomposed adjustment (loops of 60 key frames, closures and crossings):\n");
  std::printf("%7s %7s %6s %5s %5s %8s %8s %8s %8s %8s %10s %10s %9s %9s %9s\n", "keyfr", "start",
              "links", "nodes", "arcs", "full_s", "decomp_s", "nodes_s", "place_s", "speedup",
              "full_cost", "dec_cost", "start_rms", "full_rms", "dec_rms");
  for (const int n : sizes) {
    const Scene scene = MakeLoops(n, seed + static_cast<uint64_t>(n));
    std::vector<std::pair<const char*, LinkGraph>> starts = {{"chained", scene.graph}};
    double warm_s = 0;
    if (warm_every > 0 && n > warm_every) {
      starts.emplace_back("warm", LinkGraph{});
      warm_s = WarmStart(scene, warm_every, options, &starts.back().second);
    }
    for (const auto& [name, graph] : starts) {
      char full_s[16] = "-", speedup[16] = "-", full_cost[16] = "-", full_rms[16] = "-";
      double full_seconds = 0;
      if (full_max <= 0 || n <= full_max) {
        LinkGraph full = graph;
        const Stopwatch start;
        const auto summary = saker::mosaic::Adjust(&full, options);
        full_seconds = start.ElapsedSeconds();
        SAKER_CHECK(summary.ok()) << summary.status().ToString();
        std::snprintf(full_s, sizeof(full_s), "%.3f", full_seconds);
        std::snprintf(full_cost, sizeof(full_cost), "%.1f", summary->final_cost);
        std::snprintf(full_rms, sizeof(full_rms), "%.2f", RmsCornerError(full, scene.truth));
      }
      LinkGraph decomposed = graph;
      const Stopwatch start;
      const auto summary = saker::mosaic::AdjustDecomposed(&decomposed, options, {});
      const double decomposed_s = start.ElapsedSeconds();
      SAKER_CHECK(summary.ok()) << summary.status().ToString();
      if (full_seconds > 0) {
        std::snprintf(speedup, sizeof(speedup), "%.1fx", full_seconds / decomposed_s);
      }
      std::printf("%7d %7s %6zu %5d %5d %8s %8.3f %8.3f %8.3f %8s %10s %10.1f %9.2f %9s %9.2f\n", n,
                  name, graph.links.size(), summary->nodes, summary->arcs, full_s, decomposed_s,
                  summary->adjust_s, summary->place_s, speedup, full_cost,
                  summary->adjustment.final_cost, RmsCornerError(graph, scene.truth), full_rms,
                  RmsCornerError(decomposed, scene.truth));
      std::fflush(stdout);
    }
    if (warm_s > 0) {
      std::printf("%7s (the warm start's own adjustments, every %d key frames: %.3f s)\n", "",
                  warm_every, warm_s);
    }
  }
  std::printf(
      "cost: the adjustment's final cost (half the sum of squared whitened residuals; for the\n"
      "decomposed one over the reduced graph); rms: key frame corners against the truth, "
      "metres.\n");
}

// A comma-separated list of sizes of at least 2 ("" is the empty list); false, with a message
// naming `option`, for anything else.
bool ParseSizes(const std::string& text, const char* option, std::vector<int>* sizes) {
  for (size_t begin = 0; begin < text.size();) {
    const size_t end = std::min(text.find(',', begin), text.size());
    const std::string item = text.substr(begin, end - begin);
    int n = 0;
    const auto [rest, error] = std::from_chars(item.data(), item.data() + item.size(), n);
    if (error != std::errc() || rest != item.data() + item.size() || n < 2) {
      std::fprintf(stderr, "%s: \"%s\" is not a size of at least 2\n", option, item.c_str());
      return false;
    }
    sizes->push_back(n);
    begin = end + 1;
  }
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "saker-bench-mosaic: bundle adjustment time against the number of key frames on synthetic "
      "raster link graphs with loops (sequential links plus cross-links between adjacent rows, "
      "noisy measurements, drifted start). Target: 1000 key frames in <= 1 s on 2 cores. Then the\n"
      "loop-closure candidate query of the appearance index against the number of key frames,\n"
      "next to one pairwise appearance matching measured in the same run. Then the in-between\n"
      "frames chain solver against the number of frames (target: >= 100 000 frames per second).\n"
      "Then full against decomposed (node/arc) adjustment on link graphs of loops (target: 10 000\n"
      "key frames decomposed in <= 10 s on 2 cores)."};
  std::vector<int> sizes = {100, 1000};
  saker::mosaic::AdjustmentOptions options;
  int& threads = options.num_threads;
  int repeats = 3;
  uint64_t seed = 1234;
  int covariance_max = 1000;
  std::string chain_sizes_text = "1000,10000,100000,1000000";
  std::string decomposition_sizes_text = "75,300,1000,10000";
  int full_max = 0;
  int warm_every = 1000;
  app.add_option("--sizes", sizes, "Numbers of key frames")->delimiter(',')->capture_default_str();
  app.add_option("--threads", threads, "Ceres threads")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--max-iterations", options.max_iterations, "Levenberg-Marquardt iterations")
      ->capture_default_str();
  app.add_option("--function-tolerance", options.function_tolerance,
                 "Relative cost change for convergence")
      ->capture_default_str();
  app.add_option("--seed", seed, "Noise seed (the graph of n key frames uses seed + n)")
      ->capture_default_str();
  app.add_option("--repeats", repeats, "Adjustment runs per size (the median is reported)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--covariance-max", covariance_max,
                 "Covariances of all nodes up to this many; of this many spread nodes beyond")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--chain-sizes", chain_sizes_text,
                 "Frames of the in-between chain solver benchmark, comma separated (\"\": skip it)")
      ->capture_default_str();
  app.add_option("--decomposition-sizes", decomposition_sizes_text,
                 "Key frames of the full-versus-decomposed benchmark, comma separated (\"\": skip "
                 "it)")
      ->capture_default_str();
  app.add_option("--full-max", full_max,
                 "Skip the full adjustment above this many key frames (0: never)")
      ->capture_default_str();
  app.add_option("--warm-every", warm_every,
                 "Also start the full-versus-decomposed comparison from the builder's warm start, "
                 "adjusted every this many key frames (0: chained start only)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  std::vector<int> chain_sizes, decomposition_sizes;
  if (!ParseSizes(chain_sizes_text, "--chain-sizes", &chain_sizes) ||
      !ParseSizes(decomposition_sizes_text, "--decomposition-sizes", &decomposition_sizes)) {
    return 2;
  }
  for (int n : sizes) {
    if (n < 2) {
      std::fprintf(stderr, "--sizes: each size must be at least 2\n");
      return 2;
    }
  }
  if (const saker::Status valid = options.Validate(); !valid.ok()) {
    std::fprintf(stderr, "%s\n", valid.ToString().c_str());
    return 2;
  }
  if (BenchmarkAdjustment(sizes, options, repeats, covariance_max, seed).empty()) return 1;
  BenchmarkQuery(sizes, seed);
  if (!chain_sizes.empty()) BenchmarkChain(chain_sizes, seed);
  if (!decomposition_sizes.empty()) {
    BenchmarkDecomposition(decomposition_sizes, options, full_max, warm_every, seed);
  }
  return 0;
}
