// ScanVideoMemory (a whole video in memory) and ScanVideo on an opened reader against ScanVideo on
// the same bytes as a file, and the frame cap (ScanOptions::max_frames) that bounds the work on
// untrusted input.

#include "core/ingest/report.h"
#include "core/ingest/video_scan.h"
#include "tests/core/video/synthetic_ts.h"
#include "tests/testing/test_data.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <utility>
#include <vector>

namespace saker::ingest {
namespace {

namespace fs = std::filesystem;

std::vector<uint8_t> FileBytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::vector<uint8_t>(std::istreambuf_iterator<char>(in), {});
}

fs::path WriteSynthetic(const saker::testing::SyntheticTsOptions& options) {
  const fs::path path = saker::testing::MakeTempDir("saker-scan-memory") / "clip.ts";
  const Status written = saker::testing::WriteSyntheticTs(path, options);
  EXPECT_TRUE(written.ok()) << written.ToString();
  return path;
}

TEST(VideoScanMemoryTest, SameScanAsTheFileFromMemoryOrAnOpenedReader) {
  saker::testing::SyntheticTsOptions options;
  options.frames = 12;
  const fs::path path = WriteSynthetic(options);
  auto from_file = ScanVideo(path.string(), {});
  ASSERT_TRUE(from_file.ok()) << from_file.status().ToString();
  auto from_memory = ScanVideoMemory(FileBytes(path), path.string(), {});
  ASSERT_TRUE(from_memory.ok()) << from_memory.status().ToString();

  ASSERT_EQ(from_memory->frames.size(), 12u);
  EXPECT_EQ(from_memory->FramesWithMetadata(), 12);
  ASSERT_EQ(from_memory->packets.size(), from_file->packets.size());
  ASSERT_EQ(from_memory->frames.size(), from_file->frames.size());
  for (size_t i = 0; i < from_file->frames.size(); ++i) {
    EXPECT_EQ(from_memory->frames[i].time_s, from_file->frames[i].time_s);
    EXPECT_EQ(from_memory->frames[i].byte_pos, from_file->frames[i].byte_pos);
    EXPECT_EQ(from_memory->frames[i].metadata.packet, from_file->frames[i].metadata.packet);
  }
  // Same reports, byte for byte (the name given is the file's path).
  EXPECT_EQ(KlvDumpToJson(*from_memory).dump(), KlvDumpToJson(*from_file).dump());
  EXPECT_EQ(ProbeToJson(*from_memory).dump(), ProbeToJson(*from_file).dump());

  // A reader the caller opened (to look at the video first) scans as the path does, and nothing
  // is opened again.
  auto reader = video::VideoReader::Open(path.string(), ScanOptions().reader);
  ASSERT_TRUE(reader.ok()) << reader.status().ToString();
  const int64_t opened = video::InputsOpened();
  auto from_reader = ScanVideo(std::move(reader).value(), {});
  ASSERT_TRUE(from_reader.ok()) << from_reader.status().ToString();
  EXPECT_EQ(video::InputsOpened(), opened);
  EXPECT_EQ(KlvDumpToJson(*from_reader).dump(), KlvDumpToJson(*from_file).dump());
  EXPECT_EQ(ProbeToJson(*from_reader).dump(), ProbeToJson(*from_file).dump());
}

TEST(VideoScanMemoryTest, MaxFramesStopsTheScanAndSaysSo) {
  saker::testing::SyntheticTsOptions options;
  options.frames = 20;
  const fs::path path = WriteSynthetic(options);
  ScanOptions capped;
  capped.max_frames = 5;
  int callbacks = 0;
  auto scan = ScanVideoMemory(FileBytes(path), "capped clip", capped, nullptr,
                              [&](const video::Frame&) { ++callbacks; });
  ASSERT_TRUE(scan.ok()) << scan.status().ToString();
  EXPECT_EQ(scan->frames.size(), 5u);
  EXPECT_EQ(callbacks, 5);
  EXPECT_EQ(scan->FramesWithMetadata(), 5);
  bool said_so = false;
  for (const auto& warning : scan->warnings) {
    said_so |= warning.find("capped clip") != std::string::npos &&
               warning.find("max_frames") != std::string::npos;
  }
  EXPECT_TRUE(said_so) << "no warning names the input and max_frames";

  // No cap: every frame, no such warning.
  auto whole = ScanVideoMemory(FileBytes(path), "clip", {});
  ASSERT_TRUE(whole.ok());
  EXPECT_EQ(whole->frames.size(), 20u);
  for (const auto& warning : whole->warnings) {
    EXPECT_EQ(warning.find("max_frames"), std::string::npos) << warning;
  }

  ScanOptions negative;
  negative.max_frames = -1;
  EXPECT_EQ(negative.Validate().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(negative.Validate().message().find("max_frames"), std::string::npos);
}

TEST(VideoScanMemoryTest, EmptyAndNonVideoBytesNameTheInput) {
  auto empty = ScanVideoMemory({}, "nothing.ts", {});
  ASSERT_FALSE(empty.ok());
  EXPECT_NE(empty.status().message().find("nothing.ts"), std::string::npos);
  const std::string text = "This is a mission briefing, not a transport stream.\n";
  auto not_video = ScanVideoMemory(std::vector<uint8_t>(text.begin(), text.end()), "notes", {});
  ASSERT_FALSE(not_video.ok());
  EXPECT_NE(not_video.status().message().find("notes"), std::string::npos);
}

}  // namespace
}  // namespace saker::ingest
