// VideoReader on synthetic transport streams written at test time (no shared data needed):
// frames, times and KLV bytes against ground truth, random access against the sequential pass,
// and hostile inputs that can be made from nothing.

#include "core/video/video_reader.h"

#include "tests/core/video/read_all.h"
#include "tests/core/video/synthetic_ts.h"
#include "tests/testing/test_data.h"

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <numeric>
#include <random>
#include <thread>

namespace saker::video {
namespace {

namespace fs = std::filesystem;
using saker::testing::SyntheticBackgroundLuma;
using saker::testing::SyntheticKlvPacket;
using saker::testing::SyntheticSquare;
using saker::testing::SyntheticTsOptions;

constexpr double kTimeTolerance = 1e-9;

// Writes a synthetic file once per test into a fresh temp dir.
fs::path WriteSynthetic(const SyntheticTsOptions& options, const std::string& name) {
  const fs::path path = saker::testing::MakeTempDir("saker-video") / name;
  const Status written = saker::testing::WriteSyntheticTs(path, options);
  EXPECT_TRUE(written.ok()) << written.ToString();
  return path;
}

std::unique_ptr<VideoReader> OpenOrDie(const fs::path& path, const ReaderOptions& options = {}) {
  auto reader = VideoReader::Open(path.string(), options);
  EXPECT_TRUE(reader.ok()) << reader.status().ToString();
  return reader.ok() ? std::move(reader).value() : nullptr;
}

ReaderOptions BgrAndGrey() {
  ReaderOptions options;
  options.want_bgr = true;
  options.want_grey = true;
  return options;
}

TEST(ReaderOptionsTest, ValidateNamesTheField) {
  EXPECT_TRUE(ReaderOptions{}.Validate().ok());
  ReaderOptions threads;
  threads.decoder_threads = -1;
  EXPECT_EQ(threads.Validate().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(threads.Validate().message().find("decoder_threads"), std::string::npos);
  ReaderOptions pixels;
  pixels.max_pixels = 0;
  EXPECT_NE(pixels.Validate().message().find("max_pixels"), std::string::npos);
  // Open refuses invalid options before touching the file.
  auto opened = VideoReader::Open("/nonexistent.ts", threads);
  EXPECT_EQ(opened.status().code(), StatusCode::kInvalidArgument);
}

TEST(SyntheticVideoTest, InfoDescribesTheStreams) {
  const SyntheticTsOptions options;
  auto reader = OpenOrDie(WriteSynthetic(options, "clip.ts"));
  ASSERT_NE(reader, nullptr);
  const VideoInfo& info = reader->info();
  EXPECT_EQ(info.container, "mpegts");
  EXPECT_NE(info.container_long.find("MPEG-TS"), std::string::npos);
  EXPECT_EQ(info.video_codec, "mpeg2video");
  EXPECT_EQ(info.width, options.width);
  EXPECT_EQ(info.height, options.height);
  EXPECT_DOUBLE_EQ(info.fps, options.fps);
  ASSERT_EQ(info.streams.size(), 2u);
  EXPECT_EQ(info.streams[info.video_stream].kind, StreamKind::kVideo);
  ASSERT_EQ(info.KlvStreams().size(), 1u);
  const StreamInfo& klv = info.streams[info.KlvStreams()[0]];
  EXPECT_EQ(klv.codec_name, "klv");
  EXPECT_EQ(klv.pid, 0x101);  // libavformat's default PIDs: 0x100 video, 0x101 next
  EXPECT_FALSE(klv.klv_synchronous);
}

TEST(SyntheticVideoTest, FramesTimesAndKlvBytesMatchGroundTruth) {
  const SyntheticTsOptions options;
  auto reader = OpenOrDie(WriteSynthetic(options, "clip.ts"), BgrAndGrey());
  ASSERT_NE(reader, nullptr);
  Pass pass;
  ASSERT_TRUE(ReadAll(reader.get(), &pass).ok());

  ASSERT_EQ(pass.frames.size(), static_cast<size_t>(options.frames));
  for (int i = 0; i < options.frames; ++i) {
    const Frame& frame = pass.frames[i];
    SCOPED_TRACE("frame " + std::to_string(i));
    EXPECT_EQ(frame.index, i);
    EXPECT_NEAR(frame.time_s, i / static_cast<double>(options.fps), kTimeTolerance);
    ASSERT_EQ(frame.grey.type(), CV_8UC1);
    ASSERT_EQ(frame.bgr.type(), CV_8UC3);
    ASSERT_EQ(frame.grey.size(), cv::Size(options.width, options.height));
    ASSERT_EQ(frame.bgr.size(), cv::Size(options.width, options.height));
    EXPECT_TRUE(frame.bgr.isContinuous());
    // Grey is the coded luma: the background value, and the bright square where it was drawn.
    const int background = SyntheticBackgroundLuma(i);
    EXPECT_NEAR(frame.grey.at<uint8_t>(2, options.width - 3), background, 2);
    const cv::Rect square = SyntheticSquare(i, options);
    const cv::Point centre(square.x + square.width / 2, square.y + square.height / 2);
    EXPECT_GE(frame.grey.at<uint8_t>(centre), 220);
    // BGR is full range and neutral grey: (Y - 16) * 255 / 219 in all three channels.
    const cv::Vec3b pixel = frame.bgr.at<cv::Vec3b>(2, options.width - 3);
    const double expected = (background - 16) * 255.0 / 219.0;
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(pixel[c], expected, 4) << "channel " << c;
  }
  EXPECT_TRUE(pass.frames.front().key_frame);

  // One KLV packet per frame, byte for byte, on the frames' clock (libavformat writes a PTS).
  ASSERT_EQ(pass.data.size(), static_cast<size_t>(options.frames));
  for (int i = 0; i < options.frames; ++i) {
    const DataPacket& packet = pass.data[i];
    EXPECT_EQ(packet.stream_index, reader->info().KlvStreams()[0]);
    EXPECT_EQ(packet.bytes, SyntheticKlvPacket(i)) << "packet " << i;
    EXPECT_NEAR(packet.time_s, i / static_cast<double>(options.fps), kTimeTolerance);
  }

  const ReadStats& stats = reader->stats();
  EXPECT_EQ(stats.frames_decoded, options.frames);
  EXPECT_EQ(stats.data_packets, options.frames);
  EXPECT_EQ(stats.corrupt_packets, 0);
  EXPECT_EQ(stats.decode_errors, 0);

  // The index mirrors the pass; the end is sticky.
  ASSERT_TRUE(reader->frame_index_complete());
  ASSERT_EQ(reader->frame_index().size(), pass.frames.size());
  for (size_t i = 0; i < pass.frames.size(); ++i) {
    EXPECT_EQ(reader->frame_index()[i].pts, pass.frames[i].pts);
    EXPECT_EQ(reader->frame_index()[i].key_frame, pass.frames[i].key_frame);
  }
  Frame extra;
  auto more = reader->ReadNext(&extra, nullptr);
  ASSERT_TRUE(more.ok());
  EXPECT_FALSE(*more);
}

TEST(SyntheticVideoTest, SynchronousKlvIsDetectedAndItsPayloadIsIntact) {
  SyntheticTsOptions options;
  options.klv_synchronous = true;
  auto reader = OpenOrDie(WriteSynthetic(options, "sync.ts"), ReaderOptions{false, false});
  ASSERT_NE(reader, nullptr);
  ASSERT_EQ(reader->info().KlvStreams().size(), 1u);
  EXPECT_TRUE(reader->info().streams[reader->info().KlvStreams()[0]].klv_synchronous);
  Pass pass;
  ASSERT_TRUE(ReadAll(reader.get(), &pass).ok());
  ASSERT_EQ(pass.data.size(), static_cast<size_t>(options.frames));
  // The demuxer removed the 5-byte access-unit header the writer put in front.
  for (int i = 0; i < options.frames; ++i) {
    EXPECT_EQ(pass.data[i].bytes, SyntheticKlvPacket(i)) << "packet " << i;
  }
}

TEST(SyntheticVideoTest, OddPictureSizeConvertsWithoutPaddingArtefacts) {
  // 71x45: BGR rows of 213 bytes, chroma planes of 36x23, decoder line sizes padded beyond the
  // width; the images must still be exactly width x height and correct up to the last column.
  SyntheticTsOptions options;
  options.width = 71;
  options.height = 45;
  options.frames = 8;
  auto reader = OpenOrDie(WriteSynthetic(options, "odd.ts"), BgrAndGrey());
  ASSERT_NE(reader, nullptr);
  Pass pass;
  ASSERT_TRUE(ReadAll(reader.get(), &pass).ok());
  ASSERT_EQ(pass.frames.size(), 8u);
  for (const Frame& frame : pass.frames) {
    SCOPED_TRACE("frame " + std::to_string(frame.index));
    ASSERT_EQ(frame.bgr.size(), cv::Size(71, 45));
    ASSERT_EQ(frame.grey.size(), cv::Size(71, 45));
    EXPECT_TRUE(frame.bgr.isContinuous());
    EXPECT_TRUE(frame.grey.isContinuous());
    const int background = SyntheticBackgroundLuma(static_cast<int>(frame.index));
    // Corners, including the last row and column.
    for (const cv::Point corner :
         {cv::Point(0, 0), cv::Point(70, 0), cv::Point(0, 44), cv::Point(70, 44)}) {
      EXPECT_NEAR(frame.grey.at<uint8_t>(corner), background, 3) << corner;
      const double expected = (background - 16) * 255.0 / 219.0;
      EXPECT_NEAR(frame.bgr.at<cv::Vec3b>(corner)[1], expected, 5) << corner;
    }
  }
}

TEST(SyntheticVideoTest, ImagesOnlyWhenRequested) {
  const fs::path path = WriteSynthetic(SyntheticTsOptions{}, "clip.ts");
  ReaderOptions grey_only;
  grey_only.want_bgr = false;
  grey_only.want_grey = true;
  auto reader = OpenOrDie(path, grey_only);
  ASSERT_NE(reader, nullptr);
  Frame frame;
  ASSERT_TRUE(*reader->ReadNext(&frame, nullptr));
  EXPECT_TRUE(frame.bgr.empty());
  EXPECT_EQ(frame.grey.type(), CV_8UC1);

  auto timing_only = OpenOrDie(path, ReaderOptions{false, false});
  ASSERT_NE(timing_only, nullptr);
  ASSERT_TRUE(*timing_only->ReadNext(&frame, nullptr));
  EXPECT_TRUE(frame.bgr.empty());
  EXPECT_TRUE(frame.grey.empty());
}

TEST(SyntheticVideoTest, RandomAccessIsBitIdenticalToTheSequentialPass) {
  SyntheticTsOptions options;
  options.frames = 40;  // several GOPs, with B-frames
  const fs::path path = WriteSynthetic(options, "clip.ts");
  auto sequential = OpenOrDie(path, BgrAndGrey());
  ASSERT_NE(sequential, nullptr);
  Pass pass;
  ASSERT_TRUE(ReadAll(sequential.get(), &pass).ok());
  ASSERT_EQ(pass.frames.size(), 40u);
  EXPECT_GT(std::count_if(pass.frames.begin(), pass.frames.end(),
                          [](const Frame& f) { return f.key_frame; }),
            2);

  // A fresh reader: its first ReadFrame builds the index itself.
  auto random = OpenOrDie(path, BgrAndGrey());
  ASSERT_NE(random, nullptr);
  std::vector<FrameIndex> order(pass.frames.size());
  std::iota(order.begin(), order.end(), 0);
  std::shuffle(order.begin(), order.end(), std::mt19937(7));
  for (FrameIndex n : order) {
    auto frame = random->ReadFrame(n);
    ASSERT_TRUE(frame.ok()) << frame.status().ToString();
    const Frame& expected = pass.frames[n];
    EXPECT_EQ(frame->index, n);
    EXPECT_EQ(frame->pts, expected.pts);
    EXPECT_EQ(frame->time_s, expected.time_s);
    EXPECT_EQ(frame->key_frame, expected.key_frame);
    EXPECT_EQ(frame->byte_pos, expected.byte_pos);
    EXPECT_EQ(cv::norm(frame->bgr, expected.bgr, cv::NORM_INF), 0) << "frame " << n;
    EXPECT_EQ(cv::norm(frame->grey, expected.grey, cv::NORM_INF), 0) << "frame " << n;
  }
  EXPECT_TRUE(random->frame_index_complete());
  // Stepping forward frame by frame (the GUI's "next frame") stays exact too.
  for (FrameIndex n = 10; n < 20; ++n) {
    auto frame = random->ReadFrame(n);
    ASSERT_TRUE(frame.ok());
    EXPECT_EQ(cv::norm(frame->bgr, pass.frames[n].bgr, cv::NORM_INF), 0) << "frame " << n;
  }
}

TEST(SyntheticVideoTest, OutOfRangeNamesTheValidRange) {
  auto reader = OpenOrDie(WriteSynthetic(SyntheticTsOptions{}, "clip.ts"));
  ASSERT_NE(reader, nullptr);
  for (FrameIndex bad : {FrameIndex{-1}, FrameIndex{20}, FrameIndex{1000}}) {
    auto frame = reader->ReadFrame(bad);
    ASSERT_FALSE(frame.ok());
    EXPECT_EQ(frame.status().code(), StatusCode::kOutOfRange);
    EXPECT_NE(frame.status().message().find("0..19"), std::string::npos)
        << frame.status().message();
  }
}

TEST(SyntheticVideoTest, ReadFrameAtTimeTakesTheNearestFrame) {
  auto reader = OpenOrDie(WriteSynthetic(SyntheticTsOptions{}, "clip.ts"));
  ASSERT_NE(reader, nullptr);
  const std::vector<std::pair<double, FrameIndex>> cases = {
      {0.0, 0}, {-0.01, 0}, {0.041, 1}, {0.059, 1}, {0.061, 2}, {0.76, 19}, {0.79, 19}};
  for (const auto& [time, expected] : cases) {
    auto frame = reader->ReadFrameAtTime(time);
    ASSERT_TRUE(frame.ok()) << time << ": " << frame.status().ToString();
    EXPECT_EQ(frame->index, expected) << "time " << time;
  }
  EXPECT_EQ(reader->ReadFrameAtTime(10.0).status().code(), StatusCode::kOutOfRange);
  EXPECT_EQ(reader->ReadFrameAtTime(-1.0).status().code(), StatusCode::kOutOfRange);
  EXPECT_EQ(reader->ReadFrameAtTime(std::nan("")).status().code(), StatusCode::kInvalidArgument);
}

TEST(SyntheticVideoTest, OpenWithIndexReusesTheIndex) {
  const fs::path path = WriteSynthetic(SyntheticTsOptions{}, "clip.ts");
  auto first = OpenOrDie(path);
  ASSERT_NE(first, nullptr);
  Pass pass;
  ASSERT_TRUE(ReadAll(first.get(), &pass).ok());

  auto second = OpenWithIndex(path.string(), first->frame_index());
  ASSERT_TRUE(second.ok()) << second.status().ToString();
  EXPECT_TRUE((*second)->frame_index_complete());
  EXPECT_EQ((*second)->frame_index().size(), 20u);
  for (FrameIndex n : {13, 2, 19}) {
    auto frame = (*second)->ReadFrame(n);
    ASSERT_TRUE(frame.ok()) << frame.status().ToString();
    EXPECT_EQ(cv::norm(frame->bgr, pass.frames[n].bgr, cv::NORM_INF), 0) << "frame " << n;
  }

  EXPECT_EQ(OpenWithIndex(path.string(), {}).status().code(), StatusCode::kInvalidArgument);
  std::vector<FrameIndexEntry> unordered = first->frame_index();
  std::swap(unordered[3].pts, unordered[4].pts);
  EXPECT_EQ(OpenWithIndex(path.string(), unordered).status().code(), StatusCode::kInvalidArgument);
}

TEST(SyntheticVideoTest, RandomAccessLeavesTheSequentialPassAloneAndRewindRestartsIt) {
  const fs::path path = WriteSynthetic(SyntheticTsOptions{}, "clip.ts");
  auto reference = OpenOrDie(path);
  ASSERT_NE(reference, nullptr);
  Pass expected;
  ASSERT_TRUE(ReadAll(reference.get(), &expected).ok());

  auto reader = OpenOrDie(path);
  ASSERT_NE(reader, nullptr);
  Pass pass;
  for (int i = 0; i < 5; ++i) {
    Frame frame;
    ASSERT_TRUE(*reader->ReadNext(&frame, &pass.data));
    pass.frames.push_back(frame);
  }
  ASSERT_TRUE(reader->ReadFrame(15).ok());  // builds the index on the side
  ASSERT_TRUE(ReadAll(reader.get(), &pass).ok());
  ASSERT_EQ(pass.frames.size(), 20u);
  EXPECT_EQ(pass.data.size(), 20u);
  for (size_t i = 0; i < pass.frames.size(); ++i) {
    EXPECT_EQ(pass.frames[i].pts, expected.frames[i].pts);
    EXPECT_EQ(cv::norm(pass.frames[i].bgr, expected.frames[i].bgr, cv::NORM_INF), 0) << i;
  }

  ASSERT_TRUE(reader->Rewind().ok());
  EXPECT_EQ(reader->stats().frames_decoded, 0);
  Pass again;
  ASSERT_TRUE(ReadAll(reader.get(), &again).ok());
  ASSERT_EQ(again.frames.size(), 20u);
  EXPECT_EQ(again.data.size(), 20u);
  EXPECT_EQ(again.frames[0].index, 0);
  EXPECT_EQ(cv::norm(again.frames[7].bgr, expected.frames[7].bgr, cv::NORM_INF), 0);
  EXPECT_EQ(reader->stats().frames_decoded, 20);
}

TEST(SyntheticVideoTest, SeparateReadersOnSeparateThreadsAgree) {
  const fs::path path = WriteSynthetic(SyntheticTsOptions{}, "clip.ts");
  std::vector<double> sums(4, 0.0);
  std::vector<std::thread> threads;
  for (size_t t = 0; t < sums.size(); ++t) {
    threads.emplace_back([&path, &sums, t] {
      auto reader = VideoReader::Open(path.string());
      if (!reader.ok()) return;
      Frame frame;
      while (true) {
        auto more = (*reader)->ReadNext(&frame, nullptr);
        if (!more.ok() || !*more) break;
        sums[t] += cv::sum(frame.bgr)[0] * static_cast<double>(frame.index + 1);
      }
    });
  }
  for (auto& thread : threads) thread.join();
  EXPECT_GT(sums[0], 0);
  for (size_t t = 1; t < sums.size(); ++t) EXPECT_EQ(sums[t], sums[0]) << "thread " << t;
}

TEST(SyntheticVideoTest, TruncatedCopyGivesTheFramesItHas) {
  const fs::path path = WriteSynthetic(SyntheticTsOptions{}, "clip.ts");
  const auto bytes = saker::testing::ReadFileBytes(path);
  const fs::path cut = path.parent_path() / "cut.ts";
  {
    std::ofstream out(cut, std::ios::binary);
    out.write(reinterpret_cast<const char*>(bytes.data()),
              static_cast<std::streamsize>(bytes.size() * 6 / 10 + 1));
  }
  auto reader = OpenOrDie(cut);
  ASSERT_NE(reader, nullptr);
  Pass pass;
  const Status status = ReadAll(reader.get(), &pass);
  EXPECT_TRUE(status.ok()) << status.ToString();
  EXPECT_GT(pass.frames.size(), 5u);
  EXPECT_LT(pass.frames.size(), 20u);
  for (size_t i = 1; i < pass.frames.size(); ++i) {
    EXPECT_GT(pass.frames[i].time_s, pass.frames[i - 1].time_s);
  }
}

// --- Hostile inputs that need no data --------------------------------------------------------

TEST(HostileInputTest, MissingFileIsNotFoundAndNamed) {
  const fs::path path = saker::testing::MakeTempDir("saker-video") / "missing.ts";
  auto reader = VideoReader::Open(path.string());
  ASSERT_FALSE(reader.ok());
  EXPECT_EQ(reader.status().code(), StatusCode::kNotFound);
  EXPECT_NE(reader.status().message().find(path.string()), std::string::npos);
}

TEST(HostileInputTest, ZeroByteFileIsInvalidData) {
  const fs::path path = saker::testing::MakeTempDir("saker-video") / "empty.ts";
  std::ofstream(path).close();
  auto reader = VideoReader::Open(path.string());
  ASSERT_FALSE(reader.ok());
  EXPECT_EQ(reader.status().code(), StatusCode::kInvalidData);
  EXPECT_NE(reader.status().message().find("empty"), std::string::npos);
  EXPECT_NE(reader.status().message().find(path.string()), std::string::npos);
}

TEST(HostileInputTest, DirectoryIsRefused) {
  const fs::path dir = saker::testing::MakeTempDir("saker-video");
  auto reader = VideoReader::Open(dir.string());
  ASSERT_FALSE(reader.ok());
  EXPECT_EQ(reader.status().code(), StatusCode::kInvalidArgument);
}

TEST(HostileInputTest, TextFileNamedTsIsInvalidData) {
  const fs::path path = saker::testing::MakeTempDir("saker-video") / "notes.ts";
  std::ofstream(path) << "Mission notes: flight 12, camera EO, no video here.\n";
  auto reader = VideoReader::Open(path.string());
  ASSERT_FALSE(reader.ok());
  EXPECT_EQ(reader.status().code(), StatusCode::kInvalidData);
  EXPECT_NE(reader.status().message().find(path.string()), std::string::npos);
}

TEST(HostileInputTest, RandomBytesNamedTsAreInvalidData) {
  const fs::path path = saker::testing::MakeTempDir("saker-video") / "noise.ts";
  std::mt19937 random(1234);
  std::string bytes(64 * 1024, '\0');
  for (char& byte : bytes) byte = static_cast<char>(random() & 0xFF);
  std::ofstream(path, std::ios::binary) << bytes;
  auto reader = VideoReader::Open(path.string());
  ASSERT_FALSE(reader.ok());
  EXPECT_EQ(reader.status().code(), StatusCode::kInvalidData) << reader.status().ToString();
  EXPECT_NE(reader.status().message().find(path.string()), std::string::npos);
}

TEST(HostileInputTest, AbsurdSizeIsRefusedByMaxPixels) {
  const fs::path path = WriteSynthetic(SyntheticTsOptions{}, "clip.ts");
  ReaderOptions options;
  options.max_pixels = 64 * 48 - 1;
  auto reader = VideoReader::Open(path.string(), options);
  ASSERT_FALSE(reader.ok());
  EXPECT_EQ(reader.status().code(), StatusCode::kInvalidData);
  // FFmpeg's probe is given the limit too (so that it never allocates an absurd picture), so it
  // refuses the declared size itself and the size is not known: the message names the file and
  // the limit.
  EXPECT_NE(reader.status().message().find(path.string()), std::string::npos);
  EXPECT_NE(reader.status().message().find("max_pixels = 3071"), std::string::npos)
      << reader.status().message();
}

TEST(HostileInputTest, KlvOnlyStreamHasNoVideoStream) {
  // Demux a KLV-only transport stream: the synthetic writer cannot make one, so cut the video
  // out with the sync-byte-level PID filter below.
  const fs::path path = WriteSynthetic(SyntheticTsOptions{}, "clip.ts");
  const auto bytes = saker::testing::ReadFileBytes(path);
  std::string klv_only;
  for (size_t pos = 0; pos + 188 <= bytes.size(); pos += 188) {
    const int pid = ((bytes[pos + 1] & 0x1F) << 8) | bytes[pos + 2];
    if (pid == 0x100) continue;  // the video PID
    klv_only.append(reinterpret_cast<const char*>(&bytes[pos]), 188);
  }
  const fs::path stripped = path.parent_path() / "klv_only.ts";
  std::ofstream(stripped, std::ios::binary) << klv_only;
  auto reader = VideoReader::Open(stripped.string());
  ASSERT_FALSE(reader.ok());
  EXPECT_EQ(reader.status().code(), StatusCode::kInvalidData);
  EXPECT_NE(reader.status().message().find("has no video stream"), std::string::npos)
      << reader.status().message();
}

}  // namespace
}  // namespace saker::video
