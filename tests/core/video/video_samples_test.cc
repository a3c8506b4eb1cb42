// VideoReader on the real third-party samples (kwiver/*.ts in the shared data folder; each test
// skips when its file is absent). Expected values were checked against ffprobe (FFmpeg 5.1) when
// the tests were written; ffprobe is never run at test time.

#include "core/video/video_reader.h"
#include "tests/core/video/read_all.h"
#include "tests/testing/test_data.h"

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include <algorithm>
#include <climits>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <numeric>
#include <ostream>
#include <random>

namespace saker::video {
namespace {

namespace fs = std::filesystem;

// Presentation times of every decoded frame, in seconds on the container clock, from
//   ffprobe -select_streams v -show_frames -show_entries frame=best_effort_timestamp_time
//           -of csv=p=0 kwiver/<file>
const std::vector<double> kAphillTimes = {
    1.433367, 1.466733, 1.500100, 1.533467, 1.566833, 1.600200, 1.633567, 1.666933,
    1.700300, 1.733667, 1.767033, 1.800400, 1.833767, 1.867133, 1.900500, 1.933867,
    1.967233, 2.000600, 2.033967, 2.067333, 2.100700, 2.134067, 2.167433, 2.200800,
    2.234167, 2.267533, 2.300900, 2.334267, 2.367633, 2.401000, 2.434367, 2.467733,
    2.501100, 2.534467, 2.567833, 2.601200, 2.634567, 2.667933, 2.701300, 2.734667,
    2.768033, 2.801400, 2.834767, 2.868133, 2.901500, 2.934867, 2.968233, 3.001600};
// Identical for h264_klv.ts, h265_klv.ts and h265_tricky_klv.ts (each checked separately).
const std::vector<double> kKwiverSyntheticTimes = {
    0.000011, 0.033344, 0.066678, 0.100011, 0.133344, 0.166678, 0.200011, 0.233344,
    0.266678, 0.300011, 0.333344, 0.366678, 0.400011, 0.433344, 0.466678, 0.500011,
    0.533344, 0.566678, 0.600011, 0.633344, 0.666678, 0.700011, 0.733344, 0.766678,
    0.800011, 0.833344, 0.866678, 0.900011, 0.933344, 0.966678};
const std::vector<double> kH264NoKlvTimes = {
    0.066667, 0.100000, 0.133333, 0.166667, 0.200000, 0.233333, 0.266667, 0.300000,
    0.333333, 0.366667, 0.400000, 0.433333, 0.466667, 0.500000, 0.533333, 0.566667,
    0.600000, 0.633333, 0.666667, 0.700000, 0.733333, 0.766667, 0.800000, 0.833333,
    0.866667, 0.900000, 0.933333, 0.966667, 1.000000, 1.033333};
const std::vector<double> kMpeg2Times = {
    0.033344, 0.066678, 0.100011, 0.133344, 0.166678, 0.200011, 0.233344, 0.266678,
    0.300011, 0.333344, 0.366678, 0.400011, 0.433344, 0.466678, 0.500011, 0.533344,
    0.566678, 0.600011, 0.633344, 0.666678, 0.700011, 0.733344, 0.766678, 0.800011,
    0.833344, 0.866678, 0.900011, 0.933344, 0.966678, 1.000011};

struct Sample {
  std::string file;
  std::string codec;
  int width;
  int height;
  const std::vector<double>* times;    // ffprobe best_effort_timestamp_time per frame
  std::vector<FrameIndex> key_frames;  // ffprobe -show_entries frame=key_frame
  // KLV packets per PID, from ffprobe -show_entries packet=stream_index; PID from stream=id.
  std::map<int, int> klv_packets_by_pid;
  std::map<int, bool> klv_synchronous_by_pid;  // PMT stream_type 0x15 vs 0x06
};

// Test names and failure messages show the file, not the bytes of the struct.
void PrintTo(const Sample& sample, std::ostream* out) { *out << sample.file; }

const std::vector<Sample>& Samples() {
  static const std::vector<Sample> samples = {
      {"kwiver/h264_klv.ts",
       "h264",
       160,
       120,
       &kKwiverSyntheticTimes,
       {0},
       {{0x101, 30}},
       {{0x101, false}}},
      {"kwiver/mpeg2_klv.ts",
       "mpeg2video",
       160,
       120,
       &kMpeg2Times,
       {0, 12, 24},
       {{0x101, 30}},
       {{0x101, false}}},
      {"kwiver/h265_klv.ts",
       "hevc",
       160,
       120,
       &kKwiverSyntheticTimes,
       {0},
       {{0x101, 30}},
       {{0x101, false}}},
      {"kwiver/h265_tricky_klv.ts",
       "hevc",
       160,
       120,
       &kKwiverSyntheticTimes,
       {0},
       {{0x101, 30}, {0x102, 60}, {0x103, 0}},
       {{0x101, true}, {0x102, false}, {0x103, false}}},
      {"kwiver/h264_no_klv.ts", "h264", 160, 120, &kH264NoKlvTimes, {0}, {}, {}},
      {"kwiver/aphill_short.ts",
       "h264",
       720,
       480,
       &kAphillTimes,
       {0, 16, 32},
       {{0x101, 48}},
       {{0x101, false}}},
  };
  return samples;
}

class SampleTest : public ::testing::TestWithParam<Sample> {};

TEST_P(SampleTest, FramesTimestampsAndKlvMatchFfprobe) {
  const Sample& sample = GetParam();
  SAKER_REQUIRE_TEST_DATA(path, sample.file);
  auto reader = VideoReader::Open(path.string(), ReaderOptions{false, true});
  ASSERT_TRUE(reader.ok()) << reader.status().ToString();
  const VideoInfo& info = (*reader)->info();
  EXPECT_EQ(info.container, "mpegts");
  EXPECT_EQ(info.video_codec, sample.codec);
  EXPECT_EQ(info.width, sample.width);
  EXPECT_EQ(info.height, sample.height);
  EXPECT_EQ(info.KlvStreams().size(), sample.klv_packets_by_pid.size());

  Pass pass;
  const Status status = ReadAll(reader->get(), &pass);
  ASSERT_TRUE(status.ok()) << status.ToString();

  const std::vector<double>& times = *sample.times;
  ASSERT_EQ(pass.frames.size(), times.size());
  std::vector<FrameIndex> keys;
  for (size_t i = 0; i < times.size(); ++i) {
    const Frame& frame = pass.frames[i];
    EXPECT_EQ(frame.index, static_cast<FrameIndex>(i));
    // ffprobe prints 6 decimals.
    EXPECT_NEAR(info.start_time_s + frame.time_s, times[i], 1e-6) << "frame " << i;
    if (i > 0) {
      EXPECT_GT(frame.time_s, pass.frames[i - 1].time_s) << "frame " << i;
    }
    EXPECT_EQ(frame.grey.size(), cv::Size(sample.width, sample.height));
    if (frame.key_frame) keys.push_back(frame.index);
  }
  EXPECT_NEAR(pass.frames.front().time_s, 0.0, 1e-9);  // the video starts the clock
  EXPECT_EQ(keys, sample.key_frames);

  std::map<int, int> packets_by_pid;
  std::map<int, bool> synchronous_by_pid;
  for (int stream : info.KlvStreams()) {
    packets_by_pid[info.streams[stream].pid] = 0;
    synchronous_by_pid[info.streams[stream].pid] = info.streams[stream].klv_synchronous;
  }
  for (const DataPacket& packet : pass.data) {
    ASSERT_GE(packet.stream_index, 0);
    ++packets_by_pid[info.streams[packet.stream_index].pid];
    // Every sample's KLV is a universal-key set: the payload starts with the SMPTE UL prefix.
    ASSERT_GE(packet.bytes.size(), 16u);
    EXPECT_EQ(std::vector<uint8_t>(packet.bytes.begin(), packet.bytes.begin() + 4),
              (std::vector<uint8_t>{0x06, 0x0E, 0x2B, 0x34}));
  }
  EXPECT_EQ(packets_by_pid, sample.klv_packets_by_pid);
  EXPECT_EQ(synchronous_by_pid, sample.klv_synchronous_by_pid);
  EXPECT_EQ((*reader)->stats().data_packets, static_cast<int64_t>(pass.data.size()));
  EXPECT_EQ((*reader)->stats().corrupt_packets, 0);
}

TEST_P(SampleTest, EveryFrameByRandomAccessEqualsTheSequentialFrame) {
  const Sample& sample = GetParam();
  SAKER_REQUIRE_TEST_DATA(path, sample.file);
  auto reader = VideoReader::Open(path.string());
  ASSERT_TRUE(reader.ok()) << reader.status().ToString();
  Pass pass;
  ASSERT_TRUE(ReadAll(reader->get(), &pass).ok());
  ASSERT_EQ(pass.frames.size(), sample.times->size());

  std::vector<FrameIndex> order(pass.frames.size());
  std::iota(order.begin(), order.end(), 0);
  std::shuffle(order.begin(), order.end(), std::mt19937(2024));
  for (FrameIndex n : order) {
    auto frame = (*reader)->ReadFrame(n);
    ASSERT_TRUE(frame.ok()) << "frame " << n << ": " << frame.status().ToString();
    EXPECT_EQ(frame->pts, pass.frames[n].pts) << "frame " << n;
    EXPECT_EQ(frame->byte_pos, pass.frames[n].byte_pos) << "frame " << n;
    EXPECT_EQ(cv::norm(frame->bgr, pass.frames[n].bgr, cv::NORM_INF), 0) << "frame " << n;
  }
}

INSTANTIATE_TEST_SUITE_P(Kwiver, SampleTest, ::testing::ValuesIn(Samples()),
                         [](const ::testing::TestParamInfo<Sample>& param_info) {
                           std::string name = fs::path(param_info.param.file).stem().string();
                           std::replace(name.begin(), name.end(), '-', '_');
                           return name;
                         });

TEST(SampleKlvTest, SynchronousStreamPayloadIsTheSameAsTheAsynchronousOne) {
  // h265_tricky_klv.ts carries on PID 0x101 (stream_type 0x15, with ST 1402 access-unit headers)
  // the same packets as h264_klv.ts on PID 0x101 (0x06): FFmpeg must strip exactly the 5-byte
  // header (`ffmpeg -i X -map 0:d:0 -c copy -f data out.klv` extracts identical files).
  SAKER_REQUIRE_TEST_DATA(tricky_path, "kwiver/h265_tricky_klv.ts");
  SAKER_REQUIRE_TEST_DATA(plain_path, "kwiver/h264_klv.ts");
  auto packets_on_pid = [](const fs::path& path, int pid) {
    std::vector<std::vector<uint8_t>> out;
    auto reader = VideoReader::Open(path.string(), ReaderOptions{false, false});
    EXPECT_TRUE(reader.ok()) << reader.status().ToString();
    if (!reader.ok()) return out;
    Pass pass;
    EXPECT_TRUE(ReadAll(reader->get(), &pass).ok());
    for (const DataPacket& packet : pass.data) {
      if ((*reader)->info().streams[packet.stream_index].pid == pid) out.push_back(packet.bytes);
    }
    return out;
  };
  const auto tricky = packets_on_pid(tricky_path, 0x101);
  const auto plain = packets_on_pid(plain_path, 0x101);
  ASSERT_EQ(tricky.size(), 30u);
  ASSERT_EQ(plain.size(), 30u);
  for (size_t i = 0; i < tricky.size(); ++i) {
    // ffprobe -select_streams d:0 -show_entries packet=size: 16 packets of 2422 bytes, then 14
    // of 2274, in both files.
    EXPECT_EQ(tricky[i].size(), i < 16 ? 2422u : 2274u) << "packet " << i;
    EXPECT_EQ(tricky[i], plain[i]) << "packet " << i;
  }
}

TEST(SampleKlvTest, KlvTimesAreOnTheFrameClock) {
  // In aphill_short.ts the KLV PES packets carry a PTS: same clock as the frames.
  SAKER_REQUIRE_TEST_DATA(path, "kwiver/aphill_short.ts");
  auto reader = VideoReader::Open(path.string(), ReaderOptions{false, false});
  ASSERT_TRUE(reader.ok());
  Pass pass;
  ASSERT_TRUE(ReadAll(reader->get(), &pass).ok());
  ASSERT_EQ(pass.data.size(), 48u);
  // ffprobe -select_streams d -show_entries packet=pts: 126000 first, then every 3003.
  EXPECT_EQ(pass.data[0].pts, 126000);
  EXPECT_NEAR(pass.data[0].time_s, (126000 - 129003) / 90000.0, 1e-9);
  EXPECT_NEAR(pass.data[47].time_s, (126000 + 47 * 3003 - 129003) / 90000.0, 1e-9);
  // h264_klv.ts: asynchronous packets without a timestamp.
  SAKER_REQUIRE_TEST_DATA(async_path, "kwiver/h264_klv.ts");
  auto async_reader = VideoReader::Open(async_path.string(), ReaderOptions{false, false});
  ASSERT_TRUE(async_reader.ok());
  Pass async_pass;
  ASSERT_TRUE(ReadAll(async_reader->get(), &async_pass).ok());
  ASSERT_FALSE(async_pass.data.empty());
  EXPECT_TRUE(std::isnan(async_pass.data[0].time_s));
  EXPECT_EQ(async_pass.data[0].pts, INT64_MIN);
}

TEST(SampleRandomAccessTest, OpenWithIndexAndReadFrameAtTimeOnRealVideo) {
  SAKER_REQUIRE_TEST_DATA(path, "kwiver/aphill_short.ts");
  auto first = VideoReader::Open(path.string());
  ASSERT_TRUE(first.ok());
  Pass pass;
  ASSERT_TRUE(ReadAll(first->get(), &pass).ok());
  ASSERT_EQ(pass.frames.size(), 48u);

  auto second = OpenWithIndex(path.string(), (*first)->frame_index());
  ASSERT_TRUE(second.ok()) << second.status().ToString();
  for (FrameIndex n : {47, 16, 15, 31, 0, 33}) {
    auto frame = (*second)->ReadFrame(n);
    ASSERT_TRUE(frame.ok()) << frame.status().ToString();
    EXPECT_EQ(cv::norm(frame->bgr, pass.frames[n].bgr, cv::NORM_INF), 0) << "frame " << n;
  }
  // 29.97 fps: 1.0 s lies between frames 29 (0.967633 s) and 30 (1.001 s), nearer 30.
  auto at_time = (*second)->ReadFrameAtTime(1.0);
  ASSERT_TRUE(at_time.ok()) << at_time.status().ToString();
  EXPECT_EQ(at_time->index, 30);
  EXPECT_EQ(cv::norm(at_time->bgr, pass.frames[30].bgr, cv::NORM_INF), 0);
  auto out_of_range = (*second)->ReadFrame(48);
  EXPECT_EQ(out_of_range.status().code(), StatusCode::kOutOfRange);
  EXPECT_NE(out_of_range.status().message().find("0..47"), std::string::npos);
}

// --- Damaged copies of h264_klv.ts, made in a temp dir at test time ------------------------

fs::path WriteCopy(const std::vector<unsigned char>& bytes, size_t size, const std::string& name) {
  const fs::path path = saker::testing::MakeTempDir("saker-video") / name;
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(size));
  return path;
}

void ExpectReadsPartially(const fs::path& path, size_t min_frames, size_t max_frames) {
  auto reader = VideoReader::Open(path.string());
  ASSERT_TRUE(reader.ok()) << reader.status().ToString();
  Pass pass;
  const Status status = ReadAll(reader->get(), &pass);
  EXPECT_TRUE(status.ok()) << status.ToString();
  EXPECT_GE(pass.frames.size(), min_frames);
  EXPECT_LE(pass.frames.size(), max_frames);
  for (size_t i = 1; i < pass.frames.size(); ++i) {
    EXPECT_GT(pass.frames[i].time_s, pass.frames[i - 1].time_s);
  }
  // What was read stays reachable by random access.
  for (size_t i = 0; i < pass.frames.size(); i += 3) {
    auto frame = (*reader)->ReadFrame(static_cast<FrameIndex>(i));
    ASSERT_TRUE(frame.ok()) << frame.status().ToString();
    EXPECT_EQ(cv::norm(frame->bgr, pass.frames[i].bgr, cv::NORM_INF), 0) << "frame " << i;
  }
}

TEST(DamagedSampleTest, TruncatedAtSixtyPercent) {
  SAKER_REQUIRE_TEST_DATA(source, "kwiver/h264_klv.ts");
  const auto bytes = saker::testing::ReadFileBytes(source);
  ExpectReadsPartially(WriteCopy(bytes, bytes.size() * 60 / 100, "cut60.ts"), 10, 20);
}

TEST(DamagedSampleTest, TruncatedMidPacketAtAnOddByteCount) {
  SAKER_REQUIRE_TEST_DATA(source, "kwiver/h264_klv.ts");
  const auto bytes = saker::testing::ReadFileBytes(source);
  const size_t cut = (bytes.size() / 2) | 1;  // odd, so inside a 188-byte packet
  ASSERT_NE(cut % 188, 0u);
  ExpectReadsPartially(WriteCopy(bytes, cut, "cut_odd.ts"), 8, 17);
}

TEST(DamagedSampleTest, CorruptedMiddleIsCountedAndReadingContinues) {
  SAKER_REQUIRE_TEST_DATA(source, "kwiver/h264_klv.ts");
  auto bytes = saker::testing::ReadFileBytes(source);
  std::mt19937 random(7);
  for (size_t i = bytes.size() / 2; i < bytes.size() / 2 + 3000; ++i) {
    bytes[i] = static_cast<unsigned char>(random() & 0xFF);
  }
  const fs::path path = WriteCopy(bytes, bytes.size(), "corrupt.ts");
  auto reader = VideoReader::Open(path.string());
  ASSERT_TRUE(reader.ok()) << reader.status().ToString();
  Pass pass;
  const Status status = ReadAll(reader->get(), &pass);
  ASSERT_TRUE(status.ok()) << status.ToString();
  const ReadStats& stats = (*reader)->stats();
  EXPECT_GE(stats.corrupt_packets + stats.decode_errors, 1);
  // Frames after the damage still come out, up to the end of the file.
  EXPECT_GE(pass.frames.size(), 25u);
  EXPECT_LE(pass.frames.size(), 30u);
  EXPECT_GT(pass.frames.back().time_s, 0.9);
  for (size_t i = 1; i < pass.frames.size(); ++i) {
    EXPECT_GT(pass.frames[i].time_s, pass.frames[i - 1].time_s);
  }
}

}  // namespace
}  // namespace saker::video
