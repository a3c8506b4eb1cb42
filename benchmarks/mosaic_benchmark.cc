// saker-bench-mosaic: bundle adjustment time against the number of key frames, on synthetic link
// graphs with loops: a raster of rows flown back and forth, sequential links along the path and
// cross-links to the neighbour in the adjacent row, noisy link measurements (corner noise with a
// stated covariance), a start chained through the sequential links (drifted). Reports residual
// blocks, iterations, the median adjustment time, the NodeCovariances time and the RMS corner
// error before / after. Target: 1000 key frames adjust in <= 1 s on 2 cores.
//
//   saker-bench-mosaic [--sizes 100,1000] [--threads 2] [--repeats 3] [--covariance-max N]
//                      [--seed S] [--max-iterations N] [--function-tolerance T]
//
// Each part is its own function called from main (BenchmarkAdjustment; loop-closure query
// timing can be added beside it).

#include "core/mosaic/adjustment.h"
#include "core/mosaic/link_graph.h"
#include "core/mosaic/loop_closure.h"
#include "core/mosaic/mosaic_builder.h"
#include "core/track/homography.h"
#include "core/util/check.h"
#include "tests/core/mosaic/synthetic_camera.h"

#include <CLI/CLI.hpp>
#include <Eigen/Dense>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <random>
#include <vector>

namespace {

using saker::mosaic::ImageCorners;
using saker::mosaic::KeyFrameId;
using saker::mosaic::Link;
using saker::mosaic::LinkGraph;
using Clock = std::chrono::steady_clock;
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

double Seconds(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

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
  const auto h = saker::mosaic::HomographyFromCorners(from, to, 1.0);
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
      Normalised(truth[size_t(to)].inverse() * truth[size_t(from)]);
  const auto corners = ImageCorners(kWidth, kHeight);
  std::array<Eigen::Vector2d, 4> measured;
  for (size_t i = 0; i < 4; ++i) {
    measured[i] = saker::track::Transfer(truth_to_from_from, corners[i]) +
                  error.segment<2>(2 * Eigen::Index(i));
  }
  Link link;
  link.from = KeyFrameId(from);
  link.to = KeyFrameId(to);
  link.kind =
      to == from + 1 ? saker::mosaic::LinkKind::kSequential : saker::mosaic::LinkKind::kGeometric;
  link.to_from_from = FourPointHomography(corners, measured);
  Matrix8 j;
  for (size_t i = 0; i < 4; ++i) {
    j.middleRows<2>(2 * Eigen::Index(i)) =
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

// About n key frames in rows of `columns`, flown back and forth (boustrophedon).
Scene MakeRaster(int n, uint64_t seed) {
  const int columns = std::max(2, int(std::lround(std::sqrt(1.6 * n))));
  const int rows = std::max(1, (n + columns - 1) / columns);
  Noise noise(seed);
  Scene scene;
  std::vector<std::pair<int, int>> cell;  // (row, column) per key frame along the path
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < columns && int(cell.size()) < n; ++c) {
      const int column = r % 2 == 0 ? c : columns - 1 - c;
      const double heading = r % 2 == 0 ? 0 : M_PI;
      const size_t k = cell.size();
      scene.truth.push_back(GroundFromImage(kStepM * column, kRowSpacingM * r, heading,
                                            0.02 * std::sin(0.37 * double(k)),
                                            0.02 * std::cos(0.23 * double(k))));
      cell.emplace_back(r, column);
    }
  }
  LinkGraph& graph = scene.graph;
  graph.image_width = kWidth;
  graph.image_height = kHeight;
  graph.geo_referenced = true;  // ENU metres, no metadata: node 0 holds the gauge
  for (size_t k = 0; k < cell.size(); ++k) {
    saker::mosaic::Node node;
    node.id = KeyFrameId(int(k));
    node.frame_index = int64_t(k) * 25;
    graph.nodes.push_back(node);
  }
  std::vector<int> index(size_t(rows * columns), -1);
  for (size_t k = 0; k < cell.size(); ++k) {
    index[size_t(cell[k].first * columns + cell[k].second)] = int(k);
  }
  for (size_t k = 0; k + 1 < cell.size(); ++k) {
    graph.links.push_back(MeasureLink(scene.truth, int(k), int(k) + 1, noise));
  }
  for (size_t k = 0; k < cell.size(); ++k) {
    const auto [r, c] = cell[k];
    if (r == 0) continue;
    const int below = index[size_t((r - 1) * columns + c)];
    // Not the turn link, which is already sequential.
    if (below >= 0 && below + 1 != int(k)) {
      graph.links.push_back(MeasureLink(scene.truth, below, int(k), noise));
    }
  }
  graph.nodes[0].map_from_frame = scene.truth[0];
  for (const Link& link : graph.links) {
    if (int(link.to) == int(link.from) + 1) {
      graph.nodes[size_t(link.to)].map_from_frame =
          Normalised(graph.nodes[size_t(link.from)].map_from_frame * link.to_from_from.inverse());
    }
  }
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
  return std::sqrt(sum / double(4 * graph.nodes.size()));
}

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

// Predicted RMS corner error (map units) from node covariances (of the listed nodes, or all).
double PredictedRms(const LinkGraph& graph,
                    const std::vector<saker::track::HomographyCovariance>& covariances,
                    const std::vector<KeyFrameId>& nodes) {
  double sum = 0;
  for (size_t k = 0; k < covariances.size(); ++k) {
    const size_t node = nodes.empty() ? k : size_t(nodes[k]);
    for (const Eigen::Vector2d& c : ImageCorners(kWidth, kHeight)) {
      sum += saker::track::TransferCovariance(graph.nodes[node].map_from_frame, covariances[k], c)
                 .trace();
    }
  }
  return std::sqrt(sum / double(4 * covariances.size()));
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
    const Scene scene = MakeRaster(n, seed + uint64_t(n));
    std::vector<double> run_times;
    saker::mosaic::AdjustmentSummary summary;
    LinkGraph adjusted;
    for (int r = 0; r < repeats; ++r) {
      adjusted = scene.graph;
      const auto start = Clock::now();
      auto result = saker::mosaic::Adjust(&adjusted, options);
      run_times.push_back(Seconds(start));
      if (!result.ok()) {
        std::fprintf(stderr, "adjustment failed: %s\n", result.status().ToString().c_str());
        return {};
      }
      summary = *result;
    }
    // Covariances of all nodes, or of covariance_max nodes spread over the graph beyond that.
    std::vector<KeyFrameId> wanted;
    const bool all = int(adjusted.nodes.size()) <= covariance_max;
    if (!all) {
      for (int k = 0; k < covariance_max; ++k) {
        wanted.push_back(KeyFrameId(int(adjusted.nodes.size()) * k / covariance_max));
      }
    }
    const auto cov_start = Clock::now();
    const auto covariances = saker::mosaic::NodeCovariances(adjusted, options, wanted);
    const double cov_s = Seconds(cov_start);
    if (!covariances.ok()) {
      std::fprintf(stderr, "covariances failed: %s\n", covariances.status().ToString().c_str());
      return {};
    }
    char cov_text[40];
    std::snprintf(cov_text, sizeof(cov_text), all ? "%.3f" : "%.3f (%d)", cov_s,
                  int(wanted.size()));
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
                times.back() / times.front(), double(sizes.back()) / sizes.front());
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
    f.id = saker::mosaic::KeyFrameId(id);
    f.descriptors = PlaceDescriptors(places, per_frame, random);
    for (int i = 0; i < per_frame; ++i) {
      f.points.emplace_back(std::uniform_real_distribution<double>(0, 1279)(random),
                            std::uniform_real_distribution<double>(0, 719)(random));
      f.track_ids.push_back(saker::track::FeatureTrackId(i));
    }
    return f;
  };
  // The baseline: one appearance matching of two frames (descriptor matching + RANSAC).
  const KeyFrameFeatures a = frame(0), b = frame(1);
  std::vector<double> pair_times;
  for (int r = 0; r < 5; ++r) {
    const auto start = Clock::now();
    (void)saker::mosaic::MatchAppearance(a, b, 1280, 720, {});
    pair_times.push_back(Seconds(start));
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
    const auto add_start = Clock::now();
    const int before = added;
    for (; added < n; ++added) index.Add(frame(added));
    const double add_ms = added > before ? Seconds(add_start) * 1e3 / (added - before) : 0;
    std::vector<double> query_times;
    for (int r = 0; r < 20; ++r) {
      const KeyFrameFeatures q = frame(1000000 + r);
      const auto start = Clock::now();
      (void)index.Query(q, 4);
      query_times.push_back(Seconds(start));
    }
    const double q = Median(query_times);
    std::printf("%6d %10.2f %10.2f %16.2f\n", n, add_ms, q * 1e3, q / pair_s);
  }
  std::printf(
      "query/matching: the query's cost in pairwise matchings; O(n) matching would be n.\n");
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "saker-bench-mosaic: bundle adjustment time against the number of key frames on synthetic "
      "raster link graphs with loops (sequential links plus cross-links between adjacent rows, "
      "noisy measurements, drifted start). Target: 1000 key frames in <= 1 s on 2 cores. Then the\n"
      "loop-closure candidate query of the appearance index against the number of key frames,\n"
      "next to one pairwise appearance matching measured in the same run."};
  std::vector<int> sizes = {100, 1000};
  saker::mosaic::AdjustmentOptions options;
  int& threads = options.num_threads;
  int repeats = 3;
  uint64_t seed = 1234;
  int covariance_max = 1000;
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
  CLI11_PARSE(app, argc, argv);
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
  return 0;
}
