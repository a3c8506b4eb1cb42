#include "core/ingest/metadata_alignment.h"

#include <gtest/gtest.h>

#include <cmath>

namespace saker::ingest {
namespace {

std::vector<double> FrameTimes(int n, double fps) {
  std::vector<double> t;
  for (int i = 0; i < n; ++i) t.push_back(i / fps);
  return t;
}

TEST(MetadataAlignmentTest, SynchronousPacketsMatchTheirOwnFrame) {
  const auto frames = FrameTimes(10, 30.0);
  std::vector<AlignablePacket> packets;
  for (int i = 0; i < 10; i += 2) packets.push_back({1, frames[i], true, true});
  const auto timing = ClassifyStreams(frames, packets, {}, {});
  ASSERT_EQ(timing.size(), 1u);
  EXPECT_TRUE(timing[0].synchronous);
  const auto matches = AlignFrames(frames, packets, timing, {});
  for (int i = 0; i < 10; ++i) {
    if (i % 2 == 0) {
      EXPECT_EQ(matches[i].kind, MatchKind::kSynchronous) << "frame " << i;
      EXPECT_EQ(*matches[i].packet, static_cast<size_t>(i / 2));
    } else {
      // A synchronous stream does not lend a packet to the frame next door.
      EXPECT_EQ(matches[i].kind, MatchKind::kNone) << "frame " << i;
    }
  }
}

TEST(MetadataAlignmentTest, AsynchronousPacketsMatchNearestWithinTolerance) {
  const auto frames = FrameTimes(60, 30.0);  // 0 .. 1.967 s
  // 2 Hz metadata, offset from the frame clock, stopping at 1.0 s.
  std::vector<AlignablePacket> packets = {
      {1, 0.013, true, true}, {1, 0.513, true, true}, {1, 1.013, true, true}};
  AlignmentOptions options;
  options.async_tolerance_s = 0.3;
  const auto timing = ClassifyStreams(frames, packets, {}, options);
  ASSERT_FALSE(timing[0].synchronous);
  const auto matches = AlignFrames(frames, packets, timing, options);
  EXPECT_EQ(*matches[0].packet, 0u);
  EXPECT_NEAR(matches[0].offset_s, 0.013, 1e-12);
  EXPECT_EQ(*matches[15].packet, 1u);                // 0.5 s
  EXPECT_EQ(*matches[7].packet, 0u);                 // 0.233 s: closer to 0.013 than to 0.513
  EXPECT_EQ(*matches[8].packet, 1u);                 // 0.267 s: closer to 0.513
  EXPECT_EQ(matches[39].kind, MatchKind::kNearest);  // 1.3 s, 0.287 from the last packet
  EXPECT_EQ(matches[40].kind, MatchKind::kNone);     // 1.333 s: metadata stopped mid-flight
  EXPECT_FALSE(matches[59].packet.has_value());
}

TEST(MetadataAlignmentTest, DeclaredSynchronousWinsOverTiming) {
  const auto frames = FrameTimes(4, 25.0);
  std::vector<AlignablePacket> packets = {{2, 0.021, true, true}};
  const auto timing = ClassifyStreams(frames, packets, {{2, true}}, {});
  EXPECT_TRUE(timing[0].synchronous);
  const auto matches = AlignFrames(frames, packets, timing, {});
  // 21 ms off every frame: a synchronous stream refuses it.
  for (const auto& m : matches) EXPECT_EQ(m.kind, MatchKind::kNone);
}

TEST(MetadataAlignmentTest, InferredTimesAreNoEvidenceOfSynchronousTiming) {
  const auto frames = FrameTimes(3, 30.0);
  // Placed on frame times by their position in the file, not by timestamp.
  std::vector<AlignablePacket> packets = {{1, frames[0], true, true, true},
                                          {1, frames[1], true, true, true}};
  const auto timing = ClassifyStreams(frames, packets, {}, {});
  ASSERT_EQ(timing.size(), 1u);
  EXPECT_FALSE(timing[0].synchronous);
  const auto matches = AlignFrames(frames, packets, timing, {});
  EXPECT_EQ(matches[1].kind, MatchKind::kNearest);
  EXPECT_EQ(*matches[1].packet, 1u);
}

TEST(MetadataAlignmentTest, PrefersCornersThenNearestAcrossStreams) {
  const auto frames = FrameTimes(3, 10.0);
  std::vector<AlignablePacket> packets = {
      {1, 0.10, false, true},  // exact time, no corners
      {2, 0.12, true, true},   // corners, 20 ms off
      {3, 0.11, true, true},   // corners, 10 ms off: best
  };
  const auto matches = AlignFrames(frames, packets, {}, {});
  ASSERT_TRUE(matches[1].packet.has_value());
  EXPECT_EQ(*matches[1].packet, 2u);
}

TEST(MetadataAlignmentTest, IgnoresUnusableUntimedAndHandlesDisorder) {
  const auto frames = FrameTimes(5, 10.0);
  std::vector<AlignablePacket> packets = {
      {1, 0.3, true, true},  {1, 0.1, true, true},
      {1, 0.1, true, true},   // out of order, duplicated
      {1, NAN, true, true},   // no timestamp
      {1, 0.2, true, false},  // failed to decode
  };
  const auto matches = AlignFrames(frames, packets, {}, {});
  EXPECT_EQ(*matches[1].packet, 1u);  // first of the duplicated pair
  EXPECT_EQ(*matches[3].packet, 0u);
  // Frame 2 (0.2 s): the undecodable packet is skipped; 0.1 and 0.3 are tied,
  // and the earlier-sorted one is kept.
  ASSERT_TRUE(matches[2].packet.has_value());
  EXPECT_NE(*matches[2].packet, 4u);
  EXPECT_NE(*matches[2].packet, 3u);
}

TEST(MetadataAlignmentTest, ValidateNamesTheField) {
  AlignmentOptions options;
  EXPECT_TRUE(options.Validate().ok());
  options.async_tolerance_s = -1;
  const Status status = options.Validate();
  EXPECT_FALSE(status.ok());
  EXPECT_NE(status.message().find("async_tolerance_s"), std::string::npos);
}

}  // namespace
}  // namespace saker::ingest
