#include "core/mosaic/in_between.h"

#include "core/mosaic/link_graph.h"
#include "core/mosaic/mosaic_input.h"
#include "core/track/homography.h"
#include "core/track/image_geometry.h"
#include "tests/core/mosaic/synthetic_camera.h"
#include "tests/core/mosaic/synthetic_graph.h"
#include "tests/testing/noise.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

namespace saker::mosaic {
namespace {

using saker::testing::Noise;
using testing_support::CornerCovariance;
using testing_support::kHeight;
using testing_support::kWidth;
using testing_support::MeasureLink;
using testing_support::Normalised;

// A video of `n` frames flying a gentle curve, 4 m per frame: the frame-to-frame homographies
// measured with 0.3 px corner noise, key frames every `spacing` frames placed at the truth.
struct Video {
  std::vector<Eigen::Matrix3d> truth;
  std::vector<MosaicFrame> frames;
  LinkGraph graph;
};

Video MakeVideo(int n, int spacing, uint64_t seed) {
  Video v;
  v.truth = testing_support::CurvePath(n, 4);
  Noise noise(seed);
  v.frames.resize(static_cast<size_t>(n));
  for (int f = 0; f < n; ++f) {
    MosaicFrame& fr = v.frames[static_cast<size_t>(f)];
    fr.time_s = f / 25.0;
    if (f == 0) continue;
    const Link link = MeasureLink(v.truth, f - 1, f, CornerCovariance(0.3, noise), &noise);
    fr.homography_ok = true;
    fr.current_from_previous = link.to_from_from;
    fr.covariance = link.covariance;
  }
  v.graph.image_width = kWidth;
  v.graph.image_height = kHeight;
  for (int f = spacing / 2; f < n; f += spacing) {
    Node node;
    node.id = static_cast<KeyFrameId>(v.graph.nodes.size());
    node.frame_index = f;
    node.map_from_frame = v.truth[static_cast<size_t>(f)];
    v.graph.nodes.push_back(node);
  }
  return v;
}

double CornerError(const Eigen::Matrix3d& estimate, const Eigen::Matrix3d& truth) {
  double sum = 0;
  for (const Eigen::Vector2d& c : track::ImageCorners(kWidth, kHeight)) {
    sum += (track::Transfer(estimate, c) - track::Transfer(truth, c)).squaredNorm();
  }
  return std::sqrt(sum / 4);
}

TEST(InBetweenTest, FramesBetweenKeyFramesAreSolvedWithBothEndsFixed) {
  const Video v = MakeVideo(400, 50, 21);
  StatusOr<InBetweenFrames> placed = PlaceInBetweenFrames(v.frames, v.graph);
  ASSERT_TRUE(placed.ok()) << placed.status().ToString();
  std::printf("%s\n", placed->ToString().c_str());
  EXPECT_EQ(placed->key_frames, 8);
  EXPECT_EQ(placed->chained, 25 + 25 - 1);  // before frame 25 and after frame 375
  EXPECT_EQ(placed->solved, 400 - 8 - 49);
  EXPECT_EQ(placed->unplaced, 0);
  ASSERT_EQ(placed->map_from_frame.size(), 400u);

  // Against forward chaining from each key frame (what one fixed end gives): the error of the
  // solved frames is lower, and largest half way between key frames, not at the next key frame.
  double solved = 0, chained = 0;
  int count = 0;
  for (size_t k = 0; k + 1 < v.graph.nodes.size(); ++k) {
    const size_t a = static_cast<size_t>(v.graph.nodes[k].frame_index);
    const size_t b = static_cast<size_t>(v.graph.nodes[k + 1].frame_index);
    Eigen::Matrix3d forward = v.truth[a];
    for (size_t f = a + 1; f < b; ++f) {
      forward = Normalised(forward * v.frames[f].current_from_previous.inverse());
      solved += std::pow(CornerError(*placed->map_from_frame[f], v.truth[f]), 2);
      chained += std::pow(CornerError(forward, v.truth[f]), 2);
      ++count;
    }
    const double near_end = CornerError(*placed->map_from_frame[b - 1], v.truth[b - 1]);
    const double middle = CornerError(*placed->map_from_frame[(a + b) / 2], v.truth[(a + b) / 2]);
    EXPECT_LT(near_end, 2 * middle + 0.01) << "between key frames " << k << " and " << k + 1;
  }
  solved = std::sqrt(solved / count);
  chained = std::sqrt(chained / count);
  std::printf("in-between corner error: solved %.3f m RMS, chained from one end %.3f m RMS\n",
              solved, chained);
  EXPECT_LT(solved, 0.8 * chained);
  // The key frames themselves are kept.
  for (const Node& node : v.graph.nodes) {
    EXPECT_EQ(*placed->map_from_frame[static_cast<size_t>(node.frame_index)], node.map_from_frame);
  }
}

TEST(InBetweenTest, AChainBreakEndsARunAndARunWithoutKeyFramesIsNotPlaced) {
  Video v = MakeVideo(300, 50, 4);  // key frames at 25, 75, ..., 275
  // Frames 140..159 are a run of their own (breaks at 140 and 160), without a key frame.
  v.frames[140].homography_ok = false;
  v.frames[160].homography_ok = false;
  StatusOr<InBetweenFrames> placed = PlaceInBetweenFrames(v.frames, v.graph);
  ASSERT_TRUE(placed.ok()) << placed.status().ToString();
  EXPECT_EQ(placed->unplaced, 20);
  for (int f = 140; f < 160; ++f)
    EXPECT_FALSE(placed->map_from_frame[static_cast<size_t>(f)].has_value());
  // 126..139 chained from key frame 125; 160..174 chained back from key frame 175.
  EXPECT_TRUE(placed->map_from_frame[139].has_value());
  EXPECT_TRUE(placed->map_from_frame[160].has_value());
  EXPECT_LT(CornerError(*placed->map_from_frame[160], v.truth[160]), 5.0);
  int total = placed->key_frames + placed->solved + placed->chained + placed->unplaced;
  EXPECT_EQ(total, 300);
}

TEST(InBetweenTest, BadKeyFramesAreErrorsNotCrashes) {
  Video v = MakeVideo(60, 20, 2);
  LinkGraph graph = v.graph;
  graph.nodes[1].frame_index = 600;
  StatusOr<InBetweenFrames> placed = PlaceInBetweenFrames(v.frames, graph);
  ASSERT_FALSE(placed.ok());
  EXPECT_NE(placed.status().message().find("600"), std::string::npos);
  graph = v.graph;
  graph.nodes[1].frame_index = graph.nodes[0].frame_index;
  EXPECT_FALSE(PlaceInBetweenFrames(v.frames, graph).ok());
  // A degenerate frame homography is reported with the frames it lies between.
  std::vector<MosaicFrame> frames = v.frames;
  frames[15].current_from_previous.setZero();
  frames[15].current_from_previous(2, 2) = 1;
  placed = PlaceInBetweenFrames(frames, v.graph);
  EXPECT_FALSE(placed.ok());
  // No key frame at all: nothing placed, no error.
  graph = v.graph;
  graph.nodes.clear();
  placed = PlaceInBetweenFrames(v.frames, graph);
  ASSERT_TRUE(placed.ok());
  EXPECT_EQ(placed->unplaced, 60);
}

}  // namespace
}  // namespace saker::mosaic
