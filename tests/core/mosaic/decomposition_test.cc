#include "core/mosaic/decomposition.h"

#include "core/mosaic/adjustment.h"
#include "core/mosaic/link_graph.h"
#include "core/track/homography.h"
#include "core/track/image_geometry.h"
#include "tests/core/mosaic/synthetic_camera.h"
#include "tests/core/mosaic/synthetic_graph.h"
#include "tests/testing/noise.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <vector>

namespace saker::mosaic {
namespace {

using saker::testing::Noise;
using testing_support::ChainStart;
using testing_support::CornerCovariance;
using testing_support::EmptyGraph;
using testing_support::FigureEightPath;
using testing_support::kHeight;
using testing_support::kWidth;
using testing_support::Matrix8;
using testing_support::MeasureLink;
using testing_support::RmsCornerError;

// A link from -> to (sequential unless told) with an identity measurement: structure tests only.
Link IdentityLink(int from, int to, LinkKind kind = LinkKind::kSequential) {
  Link link;
  link.from = static_cast<KeyFrameId>(from);
  link.to = static_cast<KeyFrameId>(to);
  link.kind = kind;
  link.covariance = 1e-6 * track::HomographyCovariance::Identity();
  return link;
}

std::vector<int> Ids(const std::vector<KeyFrameId>& ids) {
  std::vector<int> out;
  for (KeyFrameId id : ids) out.push_back(static_cast<int>(id));
  return out;
}

// The largest distance between two solutions' key frame corners, in map units.
double MaxDifference(const LinkGraph& a, const LinkGraph& b) {
  double worst = 0;
  for (size_t k = 0; k < a.nodes.size(); ++k) {
    for (const Eigen::Vector2d& c : track::ImageCorners(kWidth, kHeight)) {
      worst = std::max(worst, (track::Transfer(a.nodes[k].map_from_frame, c) -
                               track::Transfer(b.nodes[k].map_from_frame, c))
                                  .norm());
    }
  }
  return worst;
}

// `frames` key frames round a circle: sequential links (0.5 px), the loop closure and `extra`
// cross-links (1 px), a start chained from the truth of key frame 0.
LinkGraph CircleGraph(int frames, double radius, uint64_t seed,
                      const std::vector<std::pair<int, int>>& extra,
                      std::vector<Eigen::Matrix3d>* truth) {
  *truth = testing_support::CirclePath(frames, radius);
  Noise noise(seed);
  LinkGraph graph = EmptyGraph(frames, false);
  for (int k = 0; k + 1 < frames; ++k) {
    graph.links.push_back(MeasureLink(*truth, k, k + 1, CornerCovariance(0.5, noise), &noise));
  }
  graph.links.push_back(MeasureLink(*truth, frames - 1, 0, CornerCovariance(1.0, noise), &noise));
  for (const auto& [from, to] : extra) {
    graph.links.push_back(MeasureLink(*truth, from, to, CornerCovariance(1.0, noise), &noise));
  }
  ChainStart(&graph, (*truth)[0]);
  return graph;
}

double Seconds(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

TEST(DecompositionTest, NodesAreCrossLinkEndsChainEndsMetadataAndSplitsOfLongArcs) {
  // Two segments: 0..9 and 10..14; a cross-link 7 -> 2; metadata on 12.
  LinkGraph graph = EmptyGraph(15, true);
  for (int k = 0; k < 14; ++k) {
    if (k != 9) graph.links.push_back(IdentityLink(k, k + 1));
  }
  graph.links.push_back(IdentityLink(7, 2, LinkKind::kGeometric));
  graph.nodes[12].metadata_corners = track::ImageCorners(kWidth, kHeight);
  ASSERT_TRUE(graph.Validate().ok());

  DecompositionOptions options;
  Decomposition d = Decompose(graph, options, /*metadata_nodes=*/true);
  EXPECT_EQ(Ids(d.nodes), (std::vector<int>{0, 2, 7, 9, 10, 12, 14}));
  ASSERT_EQ(d.arcs.size(), 5u);
  EXPECT_EQ(static_cast<int>(d.arcs[1].from), 2);
  EXPECT_EQ(static_cast<int>(d.arcs[1].to), 7);
  EXPECT_EQ(d.arcs[1].links.size(), 5u);
  EXPECT_EQ(d.cross_links.size(), 1u);

  // Without metadata nodes 12 is inside an arc; with short arcs, long runs are split evenly.
  d = Decompose(graph, options, /*metadata_nodes=*/false);
  EXPECT_EQ(Ids(d.nodes), (std::vector<int>{0, 2, 7, 9, 10, 14}));
  options.max_arc_links = 2;
  d = Decompose(graph, options, false);
  for (const Arc& arc : d.arcs) EXPECT_LE(arc.links.size(), 2u);
  EXPECT_EQ(Ids(d.nodes), (std::vector<int>{0, 2, 4, 5, 7, 9, 10, 12, 14}));

  // Extra nodes (the linearity check's) are honoured.
  options.max_arc_links = 50;
  d = Decompose(graph, options, false, {static_cast<KeyFrameId>(4)});
  EXPECT_EQ(Ids(d.nodes), (std::vector<int>{0, 2, 4, 7, 9, 10, 14}));
}

TEST(DecompositionTest, CrossLinkSpacingKeepsTheStrongestOfALoopClosure) {
  LinkGraph graph = EmptyGraph(30, false);
  for (int k = 0; k < 29; ++k) graph.links.push_back(IdentityLink(k, k + 1));
  // One loop closure seen as three cross-links, the middle one the strongest, and another far off.
  for (int i = -1; i <= 1; ++i) {
    Link link = IdentityLink(25 + i, 5 + i, LinkKind::kGeometric);
    link.correspondences.resize(i == 0 ? 40 : 20);
    graph.links.push_back(link);
  }
  graph.links.push_back(IdentityLink(29, 0, LinkKind::kAppearance));
  DecompositionOptions options;
  EXPECT_EQ(Decompose(graph, options, false).NodeCount(), 8);  // 0 4 5 6 24 25 26 29
  options.cross_link_spacing = 2;
  const Decomposition d = Decompose(graph, options, false);
  EXPECT_EQ(Ids(d.nodes), (std::vector<int>{0, 5, 25, 29}));
  EXPECT_EQ(d.cross_links.size(), 2u);
  EXPECT_EQ(d.left_out_links.size(), 2u);
}

TEST(DecompositionTest, ReducedGraphChainsEachArc) {
  // A noise-free chain: the arc's chained homography is the truth between its end nodes, and its
  // covariance grows with its length.
  const std::vector<Eigen::Matrix3d> truth = testing_support::CurvePath(12, 60);
  Noise noise(3);
  LinkGraph graph = EmptyGraph(12, false);
  for (int k = 0; k + 1 < 12; ++k) {
    graph.links.push_back(MeasureLink(truth, k, k + 1, CornerCovariance(0.5, noise), nullptr));
  }
  ChainStart(&graph, truth[0]);
  DecompositionOptions options;
  options.max_arc_links = 4;
  const Decomposition d = Decompose(graph, options, false);
  StatusOr<LinkGraph> reduced = ReducedGraph(graph, d);
  ASSERT_TRUE(reduced.ok()) << reduced.status().ToString();
  ASSERT_TRUE(reduced->Validate().ok());
  ASSERT_EQ(reduced->nodes.size(), d.nodes.size());
  ASSERT_EQ(reduced->links.size(), d.arcs.size());
  for (size_t a = 0; a < d.arcs.size(); ++a) {
    const Link& link = reduced->links[a];
    const Eigen::Matrix3d expected =
        testing_support::Normalised(truth[static_cast<size_t>(d.arcs[a].to)].inverse() *
                                    truth[static_cast<size_t>(d.arcs[a].from)]);
    for (const Eigen::Vector2d& c : track::ImageCorners(kWidth, kHeight)) {
      EXPECT_NEAR((track::Transfer(link.to_from_from, c) - track::Transfer(expected, c)).norm(), 0,
                  1e-6);
    }
    const Eigen::Matrix2d single =
        track::TransferCovariance(graph.links[d.arcs[a].links[0]].to_from_from,
                                  graph.links[d.arcs[a].links[0]].covariance, {0, 0});
    const Eigen::Matrix2d chained =
        track::TransferCovariance(link.to_from_from, link.covariance, {0, 0});
    if (d.arcs[a].links.size() > 1) {
      EXPECT_GT(chained.trace(), single.trace());
    }
  }
}

// The figure-of-eight of the paper's figures 9 and 10: 76 key frames starting at a lobe's tip,
// loop closures at the crossing (key frames 19 and 57) and at start / finish. The paper used one
// cross-link per loop closure: 4 nodes and 3 arcs then stand for the 76 key frames.
struct FigureEight {
  std::vector<Eigen::Matrix3d> truth;
  LinkGraph graph;
};

// `per_closure` cross-links per loop closure (1 or 3), the first the strongest.
FigureEight MakeFigureEight(int per_closure) {
  constexpr int kFrames = 76;
  FigureEight e;
  e.truth = FigureEightPath(kFrames, 740, testing_support::SyntheticCamera{}, M_PI / 2);
  Noise noise(11);
  e.graph = EmptyGraph(kFrames, false);
  for (int k = 0; k + 1 < kFrames; ++k) {
    e.graph.links.push_back(MeasureLink(e.truth, k, k + 1, CornerCovariance(0.5, noise), &noise));
  }
  const auto cross = [&](int from, int to, int inliers) {
    Link link = MeasureLink(e.truth, from, to, CornerCovariance(1.0, noise), &noise);
    link.correspondences.resize(static_cast<size_t>(inliers));
    e.graph.links.push_back(link);
  };
  cross(57, 19, 60);
  cross(75, 0, 60);
  if (per_closure == 3) cross(58, 20, 40), cross(56, 18, 40), cross(75, 1, 40), cross(74, 0, 40);
  ChainStart(&e.graph, e.truth[0]);
  return e;
}

struct Comparison {
  double drift = 0, full_error = 0, decomposed_error = 0, difference = 0;
  DecomposedSummary summary;
};

Comparison Compare(const FigureEight& e, const DecompositionOptions& options) {
  Comparison c;
  c.drift = RmsCornerError(e.graph, e.truth);
  AdjustmentOptions adjustment;
  LinkGraph full = e.graph;
  auto start = std::chrono::steady_clock::now();
  StatusOr<AdjustmentSummary> full_summary = Adjust(&full, adjustment);
  const double full_s = Seconds(start);
  EXPECT_TRUE(full_summary.ok() && full_summary->usable);
  LinkGraph decomposed = e.graph;
  StatusOr<DecomposedSummary> summary = AdjustDecomposed(&decomposed, adjustment, options);
  EXPECT_TRUE(summary.ok()) << summary.status().ToString();
  if (!summary.ok()) return c;
  c.summary = *summary;
  c.full_error = RmsCornerError(full, e.truth);
  c.decomposed_error = RmsCornerError(decomposed, e.truth);
  c.difference = MaxDifference(full, decomposed);
  std::printf(
      "%s\ndrift %.2f m RMS; full %.2f m RMS in %.1f ms; decomposed %.2f m RMS (nodes %.1f ms); "
      "largest difference %.3f m\n",
      summary->ToString().c_str(), c.drift, c.full_error, 1000 * full_s, c.decomposed_error,
      1000 * summary->adjust_s, c.difference);
  return c;
}

TEST(DecompositionTest, FigureEightWithFourNodesAgreesWithTheFullAdjustment) {
  const Comparison c = Compare(MakeFigureEight(1), {});
  EXPECT_EQ(Ids(c.summary.decomposition.nodes), (std::vector<int>{0, 19, 57, 75}));
  EXPECT_EQ(c.summary.arcs, 3);
  EXPECT_EQ(c.summary.inserted_nodes, 0);
  EXPECT_TRUE(c.summary.adjustment.usable);
  // Both close to the truth (the loop closures remove most of the drift), and almost identical.
  EXPECT_LT(c.full_error, 0.3 * c.drift);
  EXPECT_LT(c.decomposed_error, 1.1 * c.full_error);
  EXPECT_LT(c.difference, 0.5 * c.full_error);
}

TEST(DecompositionTest, SeveralCrossLinksPerClosureEitherKeptOrLeftOut) {
  const FigureEight e = MakeFigureEight(3);
  // All kept: every cross-link end is a node (10 nodes), the result close to the full one.
  const Comparison all = Compare(e, {});
  EXPECT_EQ(all.summary.nodes, 10);
  EXPECT_LT(all.difference, 0.5 * all.full_error);
  // One per closure (cross_link_spacing): 4 nodes, less information than the full adjustment,
  // which uses all six cross-links, so further from it, but still close to the truth.
  DecompositionOptions options;
  options.cross_link_spacing = 2;
  const Comparison few = Compare(e, options);
  EXPECT_EQ(few.summary.nodes, 4);
  EXPECT_EQ(few.summary.left_out_cross_links, 4);
  EXPECT_LT(few.decomposed_error, 0.3 * few.drift);
}

// A chain whose links are biased (a rotation and a scale error each, as a mis-modelled lens
// would give) around a circle: the loop closure bends the chain far beyond what its first-order
// covariance describes. The decomposed adjustment with one long arc then misplaces its nodes; the
// linearity check sees the flex and inserts nodes until the result approaches the full one.
TEST(DecompositionTest, NodesInsertedIntoAFlexedArcBringItBackToTheFullAdjustment) {
  constexpr int kFrames = 60;
  const std::vector<Eigen::Matrix3d> truth = testing_support::CirclePath(kFrames, 450);
  Noise noise(3);
  LinkGraph graph = EmptyGraph(kFrames, false);
  const double angle = 0.01, scale = 1.003;
  Eigen::Matrix3d centre, bias;
  centre << 1, 0, -0.5 * (kWidth - 1), 0, 1, -0.5 * (kHeight - 1), 0, 0, 1;
  bias << scale * std::cos(angle), -scale * std::sin(angle), 0, scale * std::sin(angle),
      scale * std::cos(angle), 0, 0, 0, 1;
  bias = centre.inverse() * bias * centre;
  for (int k = 0; k + 1 < kFrames; ++k) {
    Link link = MeasureLink(truth, k, k + 1, CornerCovariance(0.5, noise), &noise);
    link.to_from_from = testing_support::Normalised(bias * link.to_from_from);
    graph.links.push_back(link);
  }
  graph.links.push_back(MeasureLink(truth, kFrames - 1, 0, CornerCovariance(1.0, noise), &noise));
  graph.links.push_back(MeasureLink(truth, 31, 29, CornerCovariance(1.0, noise), &noise));
  ChainStart(&graph, truth[0]);

  AdjustmentOptions adjustment;
  adjustment.max_iterations = 200;
  LinkGraph full = graph;
  ASSERT_TRUE(Adjust(&full, adjustment).ok());
  DecompositionOptions options;
  options.max_arc_links = 1000;
  options.max_rounds = 0;  // no linearity check
  LinkGraph unchecked = graph;
  StatusOr<DecomposedSummary> without = AdjustDecomposed(&unchecked, adjustment, options);
  ASSERT_TRUE(without.ok());
  options.max_rounds = 3;
  LinkGraph checked = graph;
  StatusOr<DecomposedSummary> with = AdjustDecomposed(&checked, adjustment, options);
  ASSERT_TRUE(with.ok());
  const double before = MaxDifference(full, unchecked), after = MaxDifference(full, checked);
  std::printf(
      "%s\n%s\nlargest difference from the full adjustment: %.1f m without the check, "
      "%.1f m with it\n",
      without->ToString().c_str(), with->ToString().c_str(), before, after);
  EXPECT_EQ(without->nodes, 4);  // 0, 29, 31, 59
  EXPECT_GT(without->max_flex, options.max_flex);
  EXPECT_GT(with->inserted_nodes, 0);
  EXPECT_EQ(with->rounds, 4);
  EXPECT_LT(after, 0.25 * before);
}

TEST(DecompositionTest, EveryCrossLinkKeptMatchesTheFullAdjustmentClosely) {
  // A circle with two cross-links: 4 nodes; short of the arcs' first-order chaining, the reduced
  // problem is the full one with the arcs' key frames eliminated.
  std::vector<Eigen::Matrix3d> truth;
  const LinkGraph graph = CircleGraph(40, 380, 5, {{20, 18}}, &truth);
  AdjustmentOptions adjustment;
  LinkGraph full = graph, decomposed = graph;
  ASSERT_TRUE(Adjust(&full, adjustment).ok());
  StatusOr<DecomposedSummary> summary =
      AdjustDecomposed(&decomposed, adjustment, DecompositionOptions{});
  ASSERT_TRUE(summary.ok()) << summary.status().ToString();
  EXPECT_EQ(summary->nodes, 4);  // 0, 18, 20, 39
  const double full_error = RmsCornerError(full, truth);
  const double difference = MaxDifference(full, decomposed);
  std::printf("full %.3f m RMS, largest difference %.4f m\n", full_error, difference);
  EXPECT_LT(difference, 0.25 * full_error);
}

TEST(DecompositionTest, CovariancesCoverEveryKeyFrame) {
  constexpr int kFrames = 30;
  std::vector<Eigen::Matrix3d> truth;
  LinkGraph graph = CircleGraph(kFrames, 290, 8, {}, &truth);
  AdjustmentOptions adjustment;
  LinkGraph full = graph;
  ASSERT_TRUE(Adjust(&full, adjustment).ok());
  StatusOr<std::vector<track::HomographyCovariance>> exact = NodeCovariances(full, adjustment);
  ASSERT_TRUE(exact.ok());

  DecompositionOptions options;
  StatusOr<DecomposedSummary> summary = AdjustDecomposed(&graph, adjustment, options);
  ASSERT_TRUE(summary.ok());
  EXPECT_EQ(summary->nodes, 2);
  StatusOr<std::vector<track::HomographyCovariance>> covariances =
      DecomposedCovariances(graph, summary->decomposition, adjustment, options.placement);
  ASSERT_TRUE(covariances.ok()) << covariances.status().ToString();
  ASSERT_EQ(covariances->size(), static_cast<size_t>(kFrames));
  EXPECT_EQ((*covariances)[0].norm(), 0);  // the gauge
  // At the image centre: never below the exact covariance's spread by much (it errs on the safe
  // side), and within a small factor of it.
  const Eigen::Vector2d centre(0.5 * (kWidth - 1), 0.5 * (kHeight - 1));
  for (int k = 1; k < kFrames; ++k) {
    const double approximate =
        track::TransferCovariance(graph.nodes[static_cast<size_t>(k)].map_from_frame,
                                  (*covariances)[static_cast<size_t>(k)], centre)
            .trace();
    const double reference =
        track::TransferCovariance(full.nodes[static_cast<size_t>(k)].map_from_frame,
                                  (*exact)[static_cast<size_t>(k)], centre)
            .trace();
    EXPECT_GT(approximate, 0.8 * reference) << "key frame " << k;
    EXPECT_LT(approximate, 3.0 * reference) << "key frame " << k;
  }
}

TEST(DecompositionTest, RejectsBadOptions) {
  LinkGraph graph = EmptyGraph(3, false);
  graph.links.push_back(IdentityLink(0, 1));
  graph.links.push_back(IdentityLink(1, 2));
  DecompositionOptions options;
  options.max_arc_links = 0;
  EXPECT_FALSE(AdjustDecomposed(&graph, {}, options).ok());
  options = {};
  options.max_flex = 0;
  EXPECT_FALSE(AdjustDecomposed(&graph, {}, options).ok());
  options = {};
  options.cross_link_spacing = -1;
  EXPECT_FALSE(options.Validate().ok());
  EXPECT_EQ(ParseAdjustmentMode("full"), AdjustmentMode::kFull);
  EXPECT_EQ(ParseAdjustmentMode("decomposed"), AdjustmentMode::kDecomposed);
  EXPECT_FALSE(ParseAdjustmentMode("fast").has_value());
  // An invalid graph is an error, not a crash.
  graph.links.push_back(IdentityLink(2, 7));
  EXPECT_FALSE(AdjustDecomposed(&graph, {}, {}).ok());
}

}  // namespace
}  // namespace saker::mosaic
