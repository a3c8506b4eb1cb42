// One-pass scan of the real sample clips: frames tied to their KLV metadata.

#include "core/ingest/video_scan.h"

#include "core/ingest/report.h"
#include "tests/testing/test_data.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace saker::ingest {
namespace {

// The same KLV bytes muxed with three codecs. The packets carry no
// timestamp: each is placed by the next video frame in the multiplex, which
// reproduces KWIVER's gold frame numbers (packet k belongs to frame k).
class VideoScanCodecTest : public ::testing::TestWithParam<const char*> {};

TEST_P(VideoScanCodecTest, EveryFrameHasItsOwnCornerMetadata) {
  SAKER_REQUIRE_TEST_DATA(path, GetParam());
  auto scan = ScanVideo(path.string(), {});
  ASSERT_TRUE(scan.ok()) << scan.status().ToString();
  ASSERT_EQ(scan->frames.size(), 30u);
  ASSERT_EQ(scan->klv_streams.size(), 1u);
  EXPECT_EQ(scan->klv_streams[0].klv_packets, 30);
  EXPECT_EQ(scan->klv_streams[0].st0601_packets, 30);
  EXPECT_EQ(scan->klv_streams[0].checksum_failures, 0);
  EXPECT_EQ(scan->FramesWithMetadata(), 30);
  EXPECT_EQ(scan->FramesWithCorners(), 30);
  // Each frame gets its own packet, in order.
  for (size_t i = 0; i < scan->frames.size(); ++i) {
    ASSERT_TRUE(scan->frames[i].metadata.packet.has_value()) << "frame " << i;
    EXPECT_EQ(*scan->frames[i].metadata.packet, i) << "frame " << i;
  }
  const klv::FrameMetadata* first = scan->MetadataOf(0);
  ASSERT_NE(first, nullptr);
  ASSERT_TRUE(first->corners.has_value());
  EXPECT_NEAR((*first->corners)[0].latitude_deg, -10.5287284, 1e-6);
  EXPECT_NEAR((*first->corners)[0].longitude_deg, 29.1615504, 1e-6);
  ASSERT_TRUE(first->unix_time_us.has_value());
  EXPECT_EQ(FormatUtcMicros(*first->unix_time_us), "2008-10-24T00:13:29.913000Z");
  for (const auto& p : scan->packets) EXPECT_TRUE(p.time_inferred);
}

INSTANTIATE_TEST_SUITE_P(SampleClips, VideoScanCodecTest,
                         ::testing::Values("kwiver/h264_klv.ts", "kwiver/mpeg2_klv.ts",
                                           "kwiver/h265_klv.ts"));

TEST(VideoScanTest, TrickyFileHasThreeKlvStreamsOneEmpty) {
  SAKER_REQUIRE_TEST_DATA(path, "kwiver/h265_tricky_klv.ts");
  auto scan = ScanVideo(path.string(), {});
  ASSERT_TRUE(scan.ok()) << scan.status().ToString();
  ASSERT_EQ(scan->klv_streams.size(), 3u);
  EXPECT_EQ(scan->klv_streams[0].pid, 0x101);
  EXPECT_EQ(scan->klv_streams[0].klv_packets, 30);
  EXPECT_TRUE(scan->klv_streams[0].synchronous);
  EXPECT_EQ(scan->klv_streams[1].pid, 0x102);
  EXPECT_EQ(scan->klv_streams[1].klv_packets, 60);
  EXPECT_EQ(scan->klv_streams[2].pid, 0x103);
  EXPECT_EQ(scan->klv_streams[2].klv_packets, 0);
  for (const auto& s : scan->klv_streams) EXPECT_EQ(s.checksum_failures, 0);
  // The exhaustive packets (with corners) on 0x101 win over the short ones.
  EXPECT_EQ(scan->FramesWithCorners(), static_cast<int64_t>(scan->frames.size()));
  for (size_t i = 0; i < scan->frames.size(); ++i) {
    EXPECT_EQ(scan->packets[*scan->frames[i].metadata.packet].stream_index,
              scan->klv_streams[0].stream_index);
  }
}

TEST(VideoScanTest, Eg0104RealClipHasCornersOnEveryFrame) {
  SAKER_REQUIRE_TEST_DATA(path, "kwiver/aphill_short.ts");
  auto scan = ScanVideo(path.string(), {});
  ASSERT_TRUE(scan.ok()) << scan.status().ToString();
  EXPECT_EQ(scan->frames.size(), 48u);
  ASSERT_EQ(scan->klv_streams.size(), 1u);
  EXPECT_EQ(scan->klv_streams[0].eg0104_packets, 48);
  EXPECT_EQ(scan->FramesWithCorners(), 48);
  // The clip's first KLV packet (pts 1.400 s) comes one frame before the
  // first picture (pts 1.433 s); frame 0 takes the packet with its own time.
  const auto& first_packet = scan->packets.front().decoded.metadata;
  ASSERT_TRUE(first_packet.has_value());
  EXPECT_EQ(first_packet->standard, klv::MetadataStandard::kEg0104);
  EXPECT_NEAR((*first_packet->corners)[0].latitude_deg, 38.2456129, 1e-6);
  EXPECT_NEAR((*first_packet->corners)[0].longitude_deg, -77.3535250, 1e-6);
  EXPECT_NEAR(scan->packets.front().time_s, -1.001 / 30.0, 1e-4);
  const FrameMatch& frame0 = scan->frames[0].metadata;
  EXPECT_EQ(frame0.kind, MatchKind::kNearest);
  EXPECT_EQ(*frame0.packet, 1u);
  EXPECT_NEAR(frame0.offset_s, 0.0, 1e-6);
}

TEST(VideoScanTest, VideoWithoutKlvReportsNoMetadataNotAnError) {
  SAKER_REQUIRE_TEST_DATA(path, "kwiver/h264_no_klv.ts");
  auto scan = ScanVideo(path.string(), {});
  ASSERT_TRUE(scan.ok()) << scan.status().ToString();
  EXPECT_EQ(scan->frames.size(), 30u);
  EXPECT_TRUE(scan->klv_streams.empty());
  EXPECT_EQ(scan->FramesWithMetadata(), 0);
  EXPECT_EQ(scan->MetadataOf(0), nullptr);
  EXPECT_NE(ProbeToText(*scan).find("Metadata:   none"), std::string::npos);
}

TEST(VideoScanTest, ProbeJsonHasTheSummaryFields) {
  SAKER_REQUIRE_TEST_DATA(path, "kwiver/h264_klv.ts");
  auto scan = ScanVideo(path.string(), {});
  ASSERT_TRUE(scan.ok());
  const auto j = ProbeToJson(*scan);
  EXPECT_EQ(j["container"], "mpegts");
  EXPECT_EQ(j["video"]["width"], 160);
  EXPECT_EQ(j["video"]["height"], 120);
  EXPECT_EQ(j["video"]["frames"], 30);
  EXPECT_NEAR(j["video"]["fps"].get<double>(), 30.0, 1e-6);
  EXPECT_EQ(j["klv_streams"][0]["klv_packets"], 30);
  EXPECT_EQ(j["metadata"]["checksum_failures"], 0);
  EXPECT_EQ(j["metadata"]["frames_with_corners"], 30);
  EXPECT_EQ(j["metadata"]["first_utc"], "2008-10-24T00:13:29.913000Z");
  EXPECT_EQ(j["metadata"]["last_utc"], "2008-10-24T00:13:30.879666Z");
  EXPECT_NEAR(j["metadata"]["span_s"].get<double>(), 0.966666, 1e-6);
  const auto dump = KlvDumpToJson(*scan);
  ASSERT_EQ(dump["packets"].size(), 30u);
  EXPECT_EQ(dump["packets"][0]["frames"][0], 0);
}

TEST(VideoScanTest, MissingAndNonVideoFilesGiveClearErrors) {
  auto missing = ScanVideo("/nonexistent/flight.ts", {});
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.status().message().find("/nonexistent/flight.ts"), std::string::npos)
      << missing.status().message();

  const auto dir = testing::MakeTempDir("saker-scan");
  const auto text = dir / "notes.ts";
  std::ofstream(text) << "This is a mission briefing, not a transport stream.\n";
  auto not_video = ScanVideo(text.string(), {});
  ASSERT_FALSE(not_video.ok());
  EXPECT_NE(not_video.status().message().find("notes.ts"), std::string::npos)
      << not_video.status().message();
  std::filesystem::remove_all(dir);
}

// Each packet reaches on_packet as it is demuxed: packet k (carried before frame k) before frame
// k reaches on_frame (five more have come in this clip: the decoder gives pictures out a few
// packets late, so a reader ties them by position in the file), with the decode the scan keeps.
TEST(VideoScanTest, PacketsAreHandedOutAsTheyAreDecoded) {
  SAKER_REQUIRE_TEST_DATA(path, "kwiver/h264_klv.ts");
  ScanOptions options;
  size_t packets = 0;
  options.on_packet = [&](const MetadataPacket& packet) {
    ASSERT_TRUE(packet.decoded.metadata.has_value());
    EXPECT_TRUE(packet.trusted);
    EXPECT_TRUE(packet.decoded.metadata->HasCorners());
    ++packets;
  };
  std::vector<size_t> packets_before;
  auto scan = ScanVideo(path.string(), options, nullptr,
                        [&](const video::Frame&) { packets_before.push_back(packets); });
  ASSERT_TRUE(scan.ok()) << scan.status().ToString();
  EXPECT_EQ(packets, 30u);
  ASSERT_EQ(packets_before.size(), 30u);
  for (size_t k = 0; k < 30; ++k) {
    EXPECT_GE(packets_before[k], k + 1) << "frame " << k;
    EXPECT_LE(packets_before[k], k + 8) << "frame " << k;
  }
}

TEST(VideoScanTest, CancelStopsTheScan) {
  SAKER_REQUIRE_TEST_DATA(path, "kwiver/aphill_short.ts");
  JobContext context;
  int frames = 0;
  auto scan = ScanVideo(path.string(), {}, &context, [&](const video::Frame&) {
    if (++frames == 5) context.RequestCancel();
  });
  ASSERT_FALSE(scan.ok());
  EXPECT_EQ(scan.status().code(), StatusCode::kCancelled);
  EXPECT_EQ(frames, 5);
}

}  // namespace
}  // namespace saker::ingest
