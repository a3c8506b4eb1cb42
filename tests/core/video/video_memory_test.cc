// VideoReader::OpenMemory: a video held in memory reads exactly like the same bytes as a file
// (frames, pixels, times, byte positions, KLV bytes and their synchronous flag, random access),
// and hostile memory inputs get the same clear errors.

#include "core/video/video_reader.h"
#include "tests/core/video/read_all.h"
#include "tests/core/video/synthetic_ts.h"
#include "tests/testing/test_data.h"

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

namespace saker::video {
namespace {

namespace fs = std::filesystem;
using saker::testing::SyntheticTsOptions;

fs::path WriteSynthetic(const SyntheticTsOptions& options, const std::string& name) {
  const fs::path path = saker::testing::MakeTempDir("saker-video-memory") / name;
  const Status written = saker::testing::WriteSyntheticTs(path, options);
  EXPECT_TRUE(written.ok()) << written.ToString();
  return path;
}

std::vector<uint8_t> FileBytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::vector<uint8_t>(std::istreambuf_iterator<char>(in), {});
}

ReaderOptions BgrAndGrey() {
  ReaderOptions options;
  options.want_bgr = true;
  options.want_grey = true;
  return options;
}

bool SameImage(const cv::Mat& a, const cv::Mat& b) {
  return a.size() == b.size() && a.type() == b.type() && cv::norm(a, b, cv::NORM_INF) == 0;
}

void ExpectSamePass(const Pass& file, const Pass& memory) {
  ASSERT_EQ(file.frames.size(), memory.frames.size());
  for (size_t i = 0; i < file.frames.size(); ++i) {
    SCOPED_TRACE("frame " + std::to_string(i));
    EXPECT_EQ(file.frames[i].index, memory.frames[i].index);
    EXPECT_EQ(file.frames[i].pts, memory.frames[i].pts);
    EXPECT_EQ(file.frames[i].time_s, memory.frames[i].time_s);
    EXPECT_EQ(file.frames[i].key_frame, memory.frames[i].key_frame);
    EXPECT_EQ(file.frames[i].byte_pos, memory.frames[i].byte_pos);
    EXPECT_TRUE(SameImage(file.frames[i].bgr, memory.frames[i].bgr));
    EXPECT_TRUE(SameImage(file.frames[i].grey, memory.frames[i].grey));
  }
  ASSERT_EQ(file.data.size(), memory.data.size());
  for (size_t i = 0; i < file.data.size(); ++i) {
    SCOPED_TRACE("data packet " + std::to_string(i));
    EXPECT_EQ(file.data[i].stream_index, memory.data[i].stream_index);
    EXPECT_EQ(file.data[i].pts, memory.data[i].pts);
    EXPECT_EQ(file.data[i].byte_pos, memory.data[i].byte_pos);
    EXPECT_EQ(file.data[i].bytes, memory.data[i].bytes);
  }
}

TEST(VideoMemoryTest, ReadsLikeTheFile) {
  SyntheticTsOptions options;
  options.klv_synchronous = true;  // the PMT is read from memory too
  const fs::path path = WriteSynthetic(options, "clip.ts");
  auto from_file = VideoReader::Open(path.string(), BgrAndGrey());
  ASSERT_TRUE(from_file.ok()) << from_file.status().ToString();
  auto from_memory = VideoReader::OpenMemory(FileBytes(path), "in-memory clip", BgrAndGrey());
  ASSERT_TRUE(from_memory.ok()) << from_memory.status().ToString();

  const VideoInfo& info = (*from_memory)->info();
  EXPECT_EQ(info.path, "in-memory clip");
  EXPECT_EQ(info.container, "mpegts");
  EXPECT_EQ(info.width, options.width);
  EXPECT_EQ(info.height, options.height);
  ASSERT_EQ(info.KlvStreams().size(), 1u);
  const StreamInfo& klv = info.streams[info.KlvStreams()[0]];
  EXPECT_EQ(klv.pid, (*from_file)->info().streams[klv.index].pid);
  EXPECT_TRUE(klv.klv_synchronous) << "stream_type 0x15 must be found in the in-memory PMT";

  Pass file_pass, memory_pass;
  ASSERT_TRUE(ReadAll(from_file->get(), &file_pass).ok());
  ASSERT_TRUE(ReadAll(from_memory->get(), &memory_pass).ok());
  ASSERT_EQ(memory_pass.frames.size(), static_cast<size_t>(options.frames));
  ExpectSamePass(file_pass, memory_pass);
  EXPECT_EQ((*from_memory)->stats().frames_decoded, options.frames);
  EXPECT_EQ((*from_memory)->stats().corrupt_packets, 0);
}

TEST(VideoMemoryTest, RandomAccessAndRewind) {
  const SyntheticTsOptions options;
  const fs::path path = WriteSynthetic(options, "clip.ts");
  auto reader = VideoReader::OpenMemory(FileBytes(path), "clip", BgrAndGrey());
  ASSERT_TRUE(reader.ok()) << reader.status().ToString();
  Pass pass;
  ASSERT_TRUE(ReadAll(reader->get(), &pass).ok());
  ASSERT_EQ(pass.frames.size(), static_cast<size_t>(options.frames));

  // Backwards, so every recall seeks in the in-memory input.
  for (FrameIndex i = options.frames - 1; i >= 0; i -= 3) {
    auto frame = (*reader)->ReadFrame(i);
    ASSERT_TRUE(frame.ok()) << frame.status().ToString();
    EXPECT_EQ(frame->index, i);
    EXPECT_TRUE(SameImage(frame->grey, pass.frames[i].grey)) << "frame " << i;
  }
  auto out_of_range = (*reader)->ReadFrame(options.frames);
  EXPECT_EQ(out_of_range.status().code(), StatusCode::kOutOfRange);
  EXPECT_NE(out_of_range.status().message().find("clip"), std::string::npos);

  ASSERT_TRUE((*reader)->Rewind().ok());
  Pass again;
  ASSERT_TRUE(ReadAll(reader->get(), &again).ok());
  ExpectSamePass(pass, again);
}

TEST(VideoMemoryTest, HostileBytesGetClearErrors) {
  auto empty = VideoReader::OpenMemory({}, "empty input");
  EXPECT_EQ(empty.status().code(), StatusCode::kInvalidData);
  EXPECT_NE(empty.status().message().find("empty input"), std::string::npos);
  EXPECT_NE(empty.status().message().find("empty"), std::string::npos);

  std::vector<uint8_t> garbage(20000);
  for (size_t i = 0; i < garbage.size(); ++i) garbage[i] = static_cast<uint8_t>(i * 7919 >> 3);
  auto unrecognised = VideoReader::OpenMemory(garbage, "garbage");
  EXPECT_FALSE(unrecognised.ok());
  EXPECT_NE(unrecognised.status().message().find("garbage"), std::string::npos);

  // A file cut short in the middle: opens, reads what is there, and ends without a crash.
  const fs::path path = WriteSynthetic(SyntheticTsOptions{}, "clip.ts");
  std::vector<uint8_t> bytes = FileBytes(path);
  bytes.resize(bytes.size() / 2 + 101);
  auto cut = VideoReader::OpenMemory(bytes, "cut");
  ASSERT_TRUE(cut.ok()) << cut.status().ToString();
  Pass pass;
  ASSERT_TRUE(ReadAll(cut->get(), &pass).ok());
  EXPECT_GT(pass.frames.size(), 0u);
  EXPECT_LT(pass.frames.size(), static_cast<size_t>(SyntheticTsOptions{}.frames));

  // Invalid options are refused before anything is read, as for files.
  ReaderOptions bad;
  bad.decoder_threads = -1;
  EXPECT_EQ(VideoReader::OpenMemory(bytes, "cut", bad).status().code(),
            StatusCode::kInvalidArgument);
}

TEST(VideoMemoryTest, RealSampleMatchesTheFile) {
  SAKER_REQUIRE_TEST_DATA(path, "kwiver/h265_tricky_klv.ts");
  auto from_file = VideoReader::Open(path.string(), BgrAndGrey());
  ASSERT_TRUE(from_file.ok()) << from_file.status().ToString();
  auto from_memory = VideoReader::OpenMemory(FileBytes(path), path.string(), BgrAndGrey());
  ASSERT_TRUE(from_memory.ok()) << from_memory.status().ToString();
  const VideoInfo& file_info = (*from_file)->info();
  const VideoInfo& memory_info = (*from_memory)->info();
  ASSERT_EQ(file_info.streams.size(), memory_info.streams.size());
  for (size_t i = 0; i < file_info.streams.size(); ++i) {
    EXPECT_EQ(file_info.streams[i].pid, memory_info.streams[i].pid);
    EXPECT_EQ(file_info.streams[i].klv_synchronous, memory_info.streams[i].klv_synchronous);
  }
  Pass file_pass, memory_pass;
  ASSERT_TRUE(ReadAll(from_file->get(), &file_pass).ok());
  ASSERT_TRUE(ReadAll(from_memory->get(), &memory_pass).ok());
  ExpectSamePass(file_pass, memory_pass);
}

}  // namespace
}  // namespace saker::video
