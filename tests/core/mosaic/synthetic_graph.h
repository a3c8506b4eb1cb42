#pragma once

// Synthetic link graphs with known truth, shared by the mosaic tests: key frame paths (a circle,
// an S curve, a figure eight) seen by the synthetic camera, links measured from the truth with
// stated corner noise, start values chained through the sequential links, and corner errors.

#include "core/mosaic/link_graph.h"
#include "core/mosaic/mosaic_builder.h"
#include "core/track/homography.h"
#include "core/track/image_geometry.h"
#include "core/util/check.h"
#include "tests/core/mosaic/synthetic_camera.h"
#include "tests/testing/noise.h"

#include <Eigen/Dense>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

namespace saker::mosaic::testing_support {

using Matrix8 = Eigen::Matrix<double, 8, 8>;
using Vector8 = Eigen::Matrix<double, 8, 1>;
using saker::testing::Noise;

constexpr int kWidth = SyntheticCamera{}.width;
constexpr int kHeight = SyntheticCamera{}.height;

// n key frames flying a circle of the given radius (metres), one full turn.
inline std::vector<Eigen::Matrix3d> CirclePath(int n, double radius) {
  std::vector<Eigen::Matrix3d> truth;
  for (int k = 0; k < n; ++k) {
    const double t = 2 * M_PI * k / n;
    truth.push_back(GroundFromImage(radius * std::cos(t), radius * std::sin(t), t + M_PI / 2,
                                    0.03 * std::sin(3 * t), 0.02 * std::cos(2 * t)));
  }
  return truth;
}

// n key frames `step` metres apart along a gentle S curve heading east.
inline std::vector<Eigen::Matrix3d> CurvePath(int n, double step) {
  std::vector<Eigen::Matrix3d> truth;
  double x = 0, y = 0;
  for (int k = 0; k < n; ++k) {
    const double heading = 0.5 * std::sin(2 * M_PI * k / n);
    truth.push_back(GroundFromImage(x, y, heading, 0.02 * std::sin(0.7 * k), 0.02 * std::cos(k)));
    x += step * std::cos(heading);
    y += step * std::sin(heading);
  }
  return truth;
}

// n key frames flying one figure eight (a lemniscate of Gerono, `half_width` metres from the
// crossing to each lobe's tip). With phase 0 it starts at the crossing: it is passed again at
// n / 2, at right angles, and the flight ends next to the start. With phase pi / 2 it starts at a
// lobe's tip and passes the crossing at n / 4 and 3 n / 4 (the paper's figure 9).
inline std::vector<Eigen::Matrix3d> FigureEightPath(int n, double half_width,
                                                    const SyntheticCamera& camera,
                                                    double phase = 0) {
  std::vector<Eigen::Matrix3d> truth;
  for (int k = 0; k < n; ++k) {
    const double t = 2 * M_PI * k / n + phase;
    const double heading = std::atan2(std::cos(2 * t), std::cos(t));
    truth.push_back(GroundFromImage(half_width * std::sin(t),
                                    half_width * std::sin(t) * std::cos(t), heading,
                                    0.02 * std::sin(0.7 * k), 0.02 * std::cos(0.4 * k), camera));
  }
  return truth;
}

// The homography taking the 4 points `from` exactly to `to`.
inline Eigen::Matrix3d FourPointHomography(const std::array<Eigen::Vector2d, 4>& from,
                                           const std::array<Eigen::Vector2d, 4>& to) {
  const auto h = track::HomographyFromCorners(from, to, 1.0);
  SAKER_CHECK(h.ok()) << h.status().ToString();
  return h->target_from_source;
}

inline Eigen::Matrix<double, 8, 8> StackedJacobian(const Eigen::Matrix3d& h) {
  Eigen::Matrix<double, 8, 8> j;
  const auto corners = track::ImageCorners(kWidth, kHeight);
  for (int i = 0; i < 4; ++i)
    j.middleRows<2>(2 * i) = track::TransferJacobian(h, corners[static_cast<size_t>(i)]);
  return j;
}

// A random, correlated covariance of the 8 measured corner coordinates of a link, with an
// average per-coordinate sigma of about sigma_px.
inline Matrix8 CornerCovariance(double sigma_px, Noise& noise) {
  Matrix8 b;
  for (int i = 0; i < 64; ++i) b(i) = noise.Gaussian();
  return sigma_px * sigma_px * (0.6 * Matrix8::Identity() + 0.4 / 8 * b * b.transpose());
}

// A link measured as the exact homography of the truth corners perturbed by N(0, corner_cov), its
// covariance the one that noise implies for the parameters: C = J^-1 corner_cov J^-T.
inline Link MeasureLink(const std::vector<Eigen::Matrix3d>& truth, int from, int to,
                        const Matrix8& corner_cov, Noise* noise) {
  const Eigen::Matrix3d truth_to_from_from =
      Normalised(truth[static_cast<size_t>(to)].inverse() * truth[static_cast<size_t>(from)]);
  const auto corners = track::ImageCorners(kWidth, kHeight);
  const Vector8 error = noise != nullptr ? noise->Draw<8>(corner_cov) : Vector8::Zero();
  std::array<Eigen::Vector2d, 4> measured;
  for (int i = 0; i < 4; ++i) {
    measured[static_cast<size_t>(i)] =
        track::Transfer(truth_to_from_from, corners[static_cast<size_t>(i)]) +
        error.segment<2>(2 * i);
  }
  Link link;
  link.from = static_cast<KeyFrameId>(from);
  link.to = static_cast<KeyFrameId>(to);
  link.kind = to == from + 1 ? LinkKind::kSequential : LinkKind::kGeometric;
  link.to_from_from = FourPointHomography(corners, measured);
  const Matrix8 j_inv = StackedJacobian(link.to_from_from).inverse();
  link.covariance = j_inv * corner_cov * j_inv.transpose();
  link.covariance = 0.5 * (link.covariance + link.covariance.transpose()).eval();
  return link;
}

// Metadata corners: where the true map_from_frame puts the image corners, plus noise of sigma m.
inline std::array<Eigen::Vector2d, 4> NoisyMetadata(const Eigen::Matrix3d& map_from_frame,
                                                    const std::array<Eigen::Vector2d, 4>& corners,
                                                    double sigma, Noise* noise) {
  std::array<Eigen::Vector2d, 4> metadata;
  for (size_t i = 0; i < 4; ++i) {
    metadata[i] = track::Transfer(map_from_frame, corners[i]) +
                  sigma * Eigen::Vector2d(noise->Gaussian(), noise->Gaussian());
  }
  return metadata;
}

inline LinkGraph EmptyGraph(int n, bool geo_referenced) {
  LinkGraph graph;
  graph.image_width = kWidth;
  graph.image_height = kHeight;
  graph.geo_referenced = geo_referenced;
  for (int i = 0; i < n; ++i) {
    Node node;
    node.id = static_cast<KeyFrameId>(i);
    node.frame_index = 25 * i;
    graph.nodes.push_back(node);
  }
  return graph;
}

// Start values as the front end has them: node 0 given, every other node chained through the
// sequential links (k - 1 -> k), so errors accumulate along the path.
inline void ChainStart(LinkGraph* graph, const Eigen::Matrix3d& first) {
  graph->nodes[0].map_from_frame = first;
  for (size_t k = 1; k < graph->nodes.size(); ++k) {
    for (const Link& link : graph->links) {
      if (static_cast<size_t>(link.from) == k - 1 && static_cast<size_t>(link.to) == k) {
        graph->nodes[k].map_from_frame =
            Normalised(graph->nodes[k - 1].map_from_frame * link.to_from_from.inverse());
      }
    }
  }
}

// RMS over the nodes in [begin, end) and their 4 corners of the distance between the solution's
// and the truth's map positions (map units).
inline double RmsCornerError(const LinkGraph& graph, const std::vector<Eigen::Matrix3d>& truth,
                             size_t begin = 0, size_t end = SIZE_MAX) {
  end = std::min(end, graph.nodes.size());
  double sum = 0;
  int count = 0;
  for (size_t k = begin; k < end; ++k) {
    for (const Eigen::Vector2d& c : track::ImageCorners(kWidth, kHeight)) {
      sum += (track::Transfer(graph.nodes[k].map_from_frame, c) - track::Transfer(truth[k], c))
                 .squaredNorm();
      ++count;
    }
  }
  return std::sqrt(sum / std::max(1, count));
}

inline double MaxCornerError(const LinkGraph& graph, const std::vector<Eigen::Matrix3d>& truth,
                             size_t begin = 0) {
  double worst = 0;
  for (size_t k = begin; k < graph.nodes.size(); ++k) {
    for (const Eigen::Vector2d& c : track::ImageCorners(kWidth, kHeight)) {
      worst = std::max(
          worst, (track::Transfer(graph.nodes[k].map_from_frame, c) - track::Transfer(truth[k], c))
                     .norm());
    }
  }
  return worst;
}

// Truth in the first key frame's pixels instead of metres.
inline std::vector<Eigen::Matrix3d> InPixelMap(const std::vector<Eigen::Matrix3d>& truth) {
  std::vector<Eigen::Matrix3d> pixels;
  for (const Eigen::Matrix3d& m : truth) pixels.push_back(Normalised(truth[0].inverse() * m));
  return pixels;
}

}  // namespace saker::mosaic::testing_support
