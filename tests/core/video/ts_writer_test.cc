// TsWriter: MPEG-TS files written at test time and read back with VideoReader (frames, times,
// pixels, KLV bytes and times), byte-identical output for identical input, and every error the
// caller can provoke. Small frames and few of them: the whole suite runs in a few seconds.

#include "core/video/ts_writer.h"

#include "core/track/picture.h"
#include "core/video/mpegts_pmt.h"
#include "core/video/video_reader.h"
#include "tests/core/video/read_all.h"
#include "tests/testing/test_data.h"

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <string>
#include <vector>

namespace saker::video {
namespace {

namespace fs = std::filesystem;

constexpr double kTimeTolerance = 1e-9;
constexpr int kStreamTypeH264 = 0x1B;

// FFmpeg's own messages (an encoder refusing a frame rate, ...) stay out of the test log: the
// Status says it all.
[[maybe_unused]] const bool kFfmpegQuiet = [] {
  SetFfmpegLogVerbose(false);
  return true;
}();

// A textured, moving BGR picture: fine detail in all channels, colour varying slowly (4:2:0
// chroma cannot keep fine colour detail, so that would only measure the subsampling).
cv::Mat TexturedFrame(int index, int width, int height) {
  cv::Mat image(height, width, CV_8UC3);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const double u = x + 2.0 * index;
      const double v = y + 1.0 * index;
      const double detail =
          45 * std::sin(u * 0.21) * std::cos(v * 0.17) + 30 * std::sin((u + v) * 0.11);
      image.at<cv::Vec3b>(y, x) =
          cv::Vec3b(cv::saturate_cast<uint8_t>(110 + detail + 40.0 * x / width),
                    cv::saturate_cast<uint8_t>(120 + detail),
                    cv::saturate_cast<uint8_t>(100 + detail + 40.0 * y / height));
    }
  }
  // A dark block crossing the picture: sharp edges.
  const cv::Rect block(4 + 3 * index, height / 3, width / 5, height / 4);
  image(block & cv::Rect(0, 0, width, height)).setTo(cv::Scalar(20, 30, 40));
  return image;
}

// A KLV-like packet of `size` bytes whose content depends on `seed`.
std::vector<uint8_t> Packet(int seed, size_t size) {
  std::vector<uint8_t> bytes(size);
  for (size_t i = 0; i < size; ++i) bytes[i] = static_cast<uint8_t>(seed * 31 + i * 7);
  return bytes;
}

TsWriterOptions SmallH264() {
  TsWriterOptions options;
  options.width = 128;
  options.height = 96;
  options.gop_size = 4;
  return options;
}

fs::path TempFile(const std::string& name) {
  return saker::testing::MakeTempDir("saker-tswriter") / name;
}

std::unique_ptr<TsWriter> OpenOrDie(const fs::path& path, const TsWriterOptions& options) {
  auto writer = TsWriter::Open(path, options);
  EXPECT_TRUE(writer.ok()) << writer.status().ToString();
  return writer.ok() ? std::move(writer).value() : nullptr;
}

// Writes `frames` textured frames, with the KLV packets of `klv` (frame -> packets) before each
// frame; packets for frames past the end go in before Close.
Status WriteClip(const fs::path& path, const TsWriterOptions& options, int frames,
                 const std::multimap<int, std::vector<uint8_t>>& klv = {}) {
  auto opened = TsWriter::Open(path, options);
  if (!opened.ok()) return opened.status();
  TsWriter& writer = **opened;
  auto next_klv = klv.begin();
  for (int i = 0; i < frames; ++i) {
    for (; next_klv != klv.end() && next_klv->first <= i; ++next_klv) {
      SAKER_RETURN_IF_ERROR(writer.WriteKlv(next_klv->second, next_klv->first));
    }
    SAKER_RETURN_IF_ERROR(writer.WriteFrame(TexturedFrame(i, options.width, options.height)));
  }
  for (; next_klv != klv.end(); ++next_klv) {
    SAKER_RETURN_IF_ERROR(writer.WriteKlv(next_klv->second, next_klv->first));
  }
  EXPECT_EQ(writer.frames_written(), frames);
  return writer.Close();
}

Pass ReadBack(const fs::path& path, const ReaderOptions& options = {}) {
  Pass pass;
  auto reader = VideoReader::Open(path.string(), options);
  EXPECT_TRUE(reader.ok()) << reader.status().ToString();
  if (!reader.ok()) return pass;
  const Status status = ReadAll(reader->get(), &pass);
  EXPECT_TRUE(status.ok()) << status.ToString();
  return pass;
}

// --- Options -----------------------------------------------------------------------------------

TEST(TsWriterOptionsTest, DefaultsAreValidAndCodecsHaveFfmpegNames) {
  EXPECT_TRUE(TsWriterOptions{}.Validate().ok());
  EXPECT_STREQ(VideoCodecName(VideoCodec::kH264), "h264");
  EXPECT_STREQ(VideoCodecName(VideoCodec::kMpeg2), "mpeg2video");
}

TEST(TsWriterOptionsTest, ValidateNamesTheBadField) {
  const std::vector<std::pair<std::string, void (*)(TsWriterOptions*)>> cases = {
      {"width", [](TsWriterOptions* o) { o->width = 8; }},
      {"height", [](TsWriterOptions* o) { o->height = 9000; }},
      {"even", [](TsWriterOptions* o) { o->width = 641; }},
      {"fps_num", [](TsWriterOptions* o) { o->fps_num = 0; }},
      {"fps_num", [](TsWriterOptions* o) { o->fps_den = -1; }},
      {"fps_num", [](TsWriterOptions* o) { o->fps_num = 5000; }},
      {"gop_size", [](TsWriterOptions* o) { o->gop_size = 0; }},
      {"b_frames", [](TsWriterOptions* o) { o->b_frames = 17; }},
      {"crf", [](TsWriterOptions* o) { o->crf = 52; }},
      {"x264_preset", [](TsWriterOptions* o) { o->x264_preset = "quick"; }},
      {"mpeg2_qscale", [](TsWriterOptions* o) { o->mpeg2_qscale = 0; }},
      {"threads", [](TsWriterOptions* o) { o->threads = -1; }},
  };
  for (const auto& [field, spoil] : cases) {
    TsWriterOptions options;
    spoil(&options);
    const Status status = options.Validate();
    EXPECT_EQ(status.code(), StatusCode::kInvalidArgument) << field;
    EXPECT_NE(status.message().find(field), std::string::npos) << status.message();
  }
  // Odd sizes are fine for MPEG-2; the preset only matters for H.264.
  TsWriterOptions mpeg2;
  mpeg2.codec = VideoCodec::kMpeg2;
  mpeg2.width = 71;
  mpeg2.height = 45;
  mpeg2.x264_preset = "";
  EXPECT_TRUE(mpeg2.Validate().ok());
}

// --- Round trips -------------------------------------------------------------------------------

TEST(TsWriterTest, H264RoundTripGivesFramesTimesKeyFramesAndPixels) {
  TsWriterOptions options = SmallH264();
  options.with_klv = false;
  const fs::path path = TempFile("h264.ts");
  ASSERT_TRUE(WriteClip(path, options, 10).ok());

  auto reader = VideoReader::Open(path.string());
  ASSERT_TRUE(reader.ok()) << reader.status().ToString();
  const VideoInfo& info = (*reader)->info();
  EXPECT_EQ(info.container, "mpegts");
  EXPECT_EQ(info.video_codec, "h264");
  EXPECT_EQ(info.width, 128);
  EXPECT_EQ(info.height, 96);
  EXPECT_DOUBLE_EQ(info.fps, 25);
  EXPECT_EQ(info.streams.size(), 1u);
  EXPECT_TRUE(info.KlvStreams().empty());

  Pass pass;
  ASSERT_TRUE(ReadAll(reader->get(), &pass).ok());
  ASSERT_EQ(pass.frames.size(), 10u);
  EXPECT_TRUE(pass.data.empty());
  for (int i = 0; i < 10; ++i) {
    const Frame& frame = pass.frames[i];
    SCOPED_TRACE("frame " + std::to_string(i));
    EXPECT_NEAR(frame.time_s, i / 25.0, kTimeTolerance);
    EXPECT_EQ(frame.key_frame, i % 4 == 0);  // exactly every gop_size frames
    ASSERT_EQ(frame.bgr.size(), cv::Size(128, 96));
    EXPECT_TRUE(frame.grey.empty() && frame.chroma.empty());  // not asked for
    const double psnr = cv::PSNR(frame.bgr, TexturedFrame(i, 128, 96));
    EXPECT_GT(psnr, 33) << "PSNR " << psnr << " dB";  // 38-40 dB measured at crf 23
  }
  EXPECT_EQ((*reader)->stats().decode_errors, 0);
}

TEST(TsWriterTest, Mpeg2RoundTripAcceptsOddSizes) {
  TsWriterOptions options;
  options.codec = VideoCodec::kMpeg2;
  options.width = 71;
  options.height = 45;
  options.gop_size = 3;
  options.b_frames = 1;
  options.with_klv = false;
  const fs::path path = TempFile("mpeg2.ts");
  ASSERT_TRUE(WriteClip(path, options, 6).ok());
  auto reader = VideoReader::Open(path.string());
  ASSERT_TRUE(reader.ok()) << reader.status().ToString();
  EXPECT_EQ((*reader)->info().video_codec, "mpeg2video");
  Pass pass;
  ASSERT_TRUE(ReadAll(reader->get(), &pass).ok());
  ASSERT_EQ(pass.frames.size(), 6u);
  for (int i = 0; i < 6; ++i) {
    EXPECT_NEAR(pass.frames[i].time_s, i / 25.0, kTimeTolerance);
    ASSERT_EQ(pass.frames[i].bgr.size(), cv::Size(71, 45));
    EXPECT_GT(cv::PSNR(pass.frames[i].bgr, TexturedFrame(i, 71, 45)), 30) << "frame " << i;
  }
}

TEST(TsWriterTest, SaturatedColoursSurviveInSdAndHd) {
  // Flat patches of strong colour: their insides come back within a few levels, so the matrix
  // (BT.601 below 720 lines, BT.709 from 720) and the range match what the stream declares.
  const std::vector<cv::Scalar> colours = {{200, 60, 30},  {40, 190, 70},   {50, 40, 210},
                                           {230, 230, 40}, {128, 128, 128}, {15, 20, 25}};
  for (const int height : {96, 720}) {
    SCOPED_TRACE("height " + std::to_string(height));
    cv::Mat image(height, 192, CV_8UC3);
    std::vector<cv::Rect> insides;
    for (size_t k = 0; k < colours.size(); ++k) {
      const cv::Rect patch(static_cast<int>(k) * 32, 0, 32, height);
      image(patch).setTo(colours[k]);
      insides.emplace_back(patch.x + 8, 8, 16, height - 16);
    }
    TsWriterOptions options = SmallH264();
    options.width = 192;
    options.height = height;
    options.with_klv = false;
    const fs::path path = TempFile("colours.ts");
    {
      auto writer = OpenOrDie(path, options);
      ASSERT_NE(writer, nullptr);
      ASSERT_TRUE(writer->WriteFrame(image).ok());
      ASSERT_TRUE(writer->WriteFrame(image).ok());
      ASSERT_TRUE(writer->Close().ok());
    }
    const Pass pass = ReadBack(path);
    ASSERT_EQ(pass.frames.size(), 2u);
    // The same colours from the luma and chroma as coded (what the key frames keep), turned into
    // BGR with the coding the reader reports.
    ReaderOptions planes;
    planes.want_bgr = false;
    planes.want_grey = true;
    planes.want_chroma = true;
    const Pass coded = ReadBack(path, planes);
    ASSERT_EQ(coded.frames.size(), 2u);
    const Frame& frame = coded.frames[1];
    ASSERT_EQ(frame.chroma.type(), CV_8UC2);
    ASSERT_EQ(frame.chroma.size(), cv::Size(96, height / 2));  // 4:2:0
    EXPECT_EQ(frame.coding.matrix, height >= 720 ? YuvMatrix::kBt709 : YuvMatrix::kBt601);
    EXPECT_FALSE(frame.coding.full_range);
    const cv::Mat from_planes = track::YuvToBgr(frame.grey, frame.chroma, frame.coding);
    for (size_t k = 0; k < colours.size(); ++k) {
      const cv::Scalar mean = cv::mean(pass.frames[1].bgr(insides[k]));
      const cv::Scalar planes_mean = cv::mean(from_planes(insides[k]));
      for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(mean[c], colours[k][c], 4) << "colour " << k << " channel " << c;
        EXPECT_NEAR(planes_mean[c], colours[k][c], 4) << "colour " << k << " channel " << c;
      }
    }
  }
}

TEST(TsWriterTest, GreyImagesAreTheCodedLuma) {
  TsWriterOptions options = SmallH264();
  options.with_klv = false;
  const fs::path path = TempFile("grey.ts");
  std::vector<cv::Mat> written;
  {
    auto writer = OpenOrDie(path, options);
    ASSERT_NE(writer, nullptr);
    for (int i = 0; i < 3; ++i) {
      cv::Mat luma;
      cv::extractChannel(TexturedFrame(i, 128, 96), luma, 1);
      luma = luma * (219.0 / 255.0) + 16;  // video range
      written.push_back(luma);
      ASSERT_TRUE(writer->WriteFrame(luma).ok());
    }
    ASSERT_TRUE(writer->Close().ok());
  }
  ReaderOptions grey;
  grey.want_grey = true;
  grey.want_chroma = true;
  const Pass pass = ReadBack(path, grey);
  ASSERT_EQ(pass.frames.size(), 3u);
  for (int i = 0; i < 3; ++i) {
    EXPECT_GT(cv::PSNR(pass.frames[i].grey, written[i]), 35) << "frame " << i;
    // Grey video: the chroma as coded is neutral (a key frame of it keeps no colour).
    EXPECT_EQ(pass.frames[i].chroma.size(), cv::Size(64, 48)) << "frame " << i;
    EXPECT_TRUE(track::NeutralChroma(pass.frames[i].chroma)) << "frame " << i;
    // Neutral chroma: the BGR picture is grey.
    std::vector<cv::Mat> channels;
    cv::split(pass.frames[i].bgr, channels);
    EXPECT_LE(cv::norm(channels[0], channels[2], cv::NORM_INF), 3) << "frame " << i;
  }
}

// Checks one KLV pass against what was written: bytes, times, and that each packet precedes
// the video packet of its frame in the file.
void ExpectKlv(const Pass& pass, const std::vector<std::pair<int, std::vector<uint8_t>>>& expected,
               double fps) {
  ASSERT_EQ(pass.data.size(), expected.size());
  for (size_t i = 0; i < expected.size(); ++i) {
    const auto& [frame, bytes] = expected[i];
    SCOPED_TRACE("KLV packet " + std::to_string(i) + " of frame " + std::to_string(frame));
    EXPECT_EQ(pass.data[i].bytes, bytes);
    EXPECT_NEAR(pass.data[i].time_s, frame / fps, kTimeTolerance);
    if (static_cast<size_t>(frame) < pass.frames.size()) {
      EXPECT_LT(pass.data[i].byte_pos, pass.frames[frame].byte_pos);
    }
  }
}

// Packets of assorted sizes: none for frame 4, two for frame 6 (joined into one PES), one for
// frame 12, after the last frame (written at Close).
std::multimap<int, std::vector<uint8_t>> KlvPlan() {
  std::multimap<int, std::vector<uint8_t>> plan;
  for (int i = 0; i < 10; ++i) {
    if (i != 4) plan.emplace(i, Packet(i, 20 + 37 * i));
  }
  plan.emplace(6, Packet(60, 5));
  plan.emplace(12, Packet(12, 300));
  return plan;
}

std::vector<std::pair<int, std::vector<uint8_t>>> ExpectedKlv() {
  std::vector<std::pair<int, std::vector<uint8_t>>> expected;
  for (int i = 0; i < 10; ++i) {
    if (i == 4) continue;
    std::vector<uint8_t> bytes = Packet(i, 20 + 37 * i);
    if (i == 6) {
      const std::vector<uint8_t> second = Packet(60, 5);
      bytes.insert(bytes.end(), second.begin(), second.end());
    }
    expected.emplace_back(i, bytes);
  }
  expected.emplace_back(12, Packet(12, 300));
  return expected;
}

TEST(TsWriterTest, AsynchronousKlvKeepsBytesAndTimes) {
  const fs::path path = TempFile("async.ts");
  ASSERT_TRUE(WriteClip(path, SmallH264(), 10, KlvPlan()).ok());
  auto types = ScanPmtStreamTypesInFile(path.string());
  ASSERT_TRUE(types.ok());
  EXPECT_EQ(*types, (std::map<int, int>{{0x100, kStreamTypeH264}, {0x101, kStreamTypePrivatePes}}));

  auto reader = VideoReader::Open(path.string());
  ASSERT_TRUE(reader.ok());
  ASSERT_EQ((*reader)->info().KlvStreams().size(), 1u);
  EXPECT_FALSE((*reader)->info().streams[(*reader)->info().KlvStreams()[0]].klv_synchronous);
  Pass pass;
  ASSERT_TRUE(ReadAll(reader->get(), &pass).ok());
  ASSERT_EQ(pass.frames.size(), 10u);
  ExpectKlv(pass, ExpectedKlv(), 25);
}

TEST(TsWriterTest, SynchronousKlvKeepsBytesAndTimes) {
  TsWriterOptions options = SmallH264();
  options.klv_synchronous = true;
  const fs::path path = TempFile("sync.ts");
  ASSERT_TRUE(WriteClip(path, options, 10, KlvPlan()).ok());
  auto types = ScanPmtStreamTypesInFile(path.string());
  ASSERT_TRUE(types.ok());
  EXPECT_EQ(*types, (std::map<int, int>{{0x100, kStreamTypeH264}, {0x101, kStreamTypeMetadata}}));

  auto reader = VideoReader::Open(path.string());
  ASSERT_TRUE(reader.ok());
  ASSERT_EQ((*reader)->info().KlvStreams().size(), 1u);
  EXPECT_TRUE((*reader)->info().streams[(*reader)->info().KlvStreams()[0]].klv_synchronous);
  Pass pass;
  ASSERT_TRUE(ReadAll(reader->get(), &pass).ok());
  ASSERT_EQ(pass.frames.size(), 10u);
  ExpectKlv(pass, ExpectedKlv(), 25);  // the 5-byte access unit header is gone again
}

// PTS and DTS (DTS = PTS when absent) of every video PES (PID 0x100), in file order, read from
// the transport stream bytes: the raw 33-bit values, as any demuxer sees them.
std::vector<std::pair<int64_t, int64_t>> VideoPesTimestamps(const fs::path& path) {
  const std::vector<unsigned char> ts = saker::testing::ReadFileBytes(path);
  auto stamp = [](const unsigned char* b) {
    return (static_cast<int64_t>(b[0] & 0x0E) << 29) | (static_cast<int64_t>(b[1]) << 22) |
           (static_cast<int64_t>(b[2] & 0xFE) << 14) | (static_cast<int64_t>(b[3]) << 7) |
           (b[4] >> 1);
  };
  std::vector<std::pair<int64_t, int64_t>> times;
  for (size_t pos = 0; pos + 188 <= ts.size(); pos += 188) {
    const unsigned char* packet = &ts[pos];
    const int pid = ((packet[1] & 0x1F) << 8) | packet[2];
    if (packet[0] != 0x47 || pid != 0x100 || (packet[1] & 0x40) == 0) continue;  // PES start
    size_t offset = 4;
    if ((packet[3] & 0x20) != 0) offset += 1 + packet[4];  // adaptation field
    if (offset + 19 > 188) continue;
    const unsigned char* pes = packet + offset;
    if (pes[0] != 0 || pes[1] != 0 || pes[2] != 1 || (pes[7] & 0x80) == 0) continue;
    const int64_t pts = stamp(pes + 9);
    times.emplace_back(pts, (pes[7] & 0x40) != 0 ? stamp(pes + 14) : pts);
  }
  return times;
}

TEST(TsWriterTest, ReorderedFramesKeepExactTimesAtNtscAndSlowRates) {
  // B-frames: decode order differs from presentation order and the encoder's first decode time
  // is negative (two frames before 0). At 0.5 fps that is 4 s, more than the muxer's 1.4 s
  // delay: only the writer's own offset keeps the file's timestamps from wrapping.
  for (const auto& [num, den] : {std::pair{30000, 1001}, std::pair{1, 2}}) {
    SCOPED_TRACE(std::to_string(num) + "/" + std::to_string(den) + " fps");
    TsWriterOptions options = SmallH264();
    options.b_frames = 2;
    options.gop_size = 6;
    options.fps_num = num;
    options.fps_den = den;
    const fs::path path = TempFile("reordered.ts");
    ASSERT_TRUE(WriteClip(path, options, 10, KlvPlan()).ok());
    const Pass pass = ReadBack(path);
    ASSERT_EQ(pass.frames.size(), 10u);
    const double fps = static_cast<double>(num) / den;
    for (int i = 0; i < 10; ++i) {
      EXPECT_NEAR(pass.frames[i].time_s, i / fps, kTimeTolerance) << "frame " << i;
      EXPECT_EQ(pass.frames[i].key_frame, i % 6 == 0) << "frame " << i;
      EXPECT_GT(cv::PSNR(pass.frames[i].bgr, TexturedFrame(i, 128, 96)), 33) << "frame " << i;
    }
    ExpectKlv(pass, ExpectedKlv(), fps);

    // In the file itself no timestamp wraps: DTS <= PTS, DTS increasing, all far below 2^33.
    const auto stamps = VideoPesTimestamps(path);
    ASSERT_EQ(stamps.size(), 10u);
    for (size_t i = 0; i < stamps.size(); ++i) {
      EXPECT_LE(stamps[i].second, stamps[i].first) << "PES " << i;
      EXPECT_LT(stamps[i].first, int64_t{1} << 32) << "PES " << i;
      if (i > 0) {
        EXPECT_GT(stamps[i].second, stamps[i - 1].second) << "PES " << i;
      }
    }
  }
}

TEST(TsWriterTest, SkippedFrameTimesLeaveGapsInTheTimeStamps) {
  const fs::path path = TempFile("skipped.ts");
  auto writer = OpenOrDie(path, SmallH264());  // 25 fps
  ASSERT_NE(writer, nullptr);
  // Frames at slots 0, 1, 4 and 5; KLV for slot 4 goes with the third picture.
  ASSERT_TRUE(writer->WriteFrame(TexturedFrame(0, 128, 96)).ok());
  ASSERT_TRUE(writer->WriteFrame(TexturedFrame(1, 128, 96)).ok());
  ASSERT_TRUE(writer->SkipFrames(2).ok());
  ASSERT_TRUE(writer->WriteKlv(Packet(4, 30), 4).ok());
  ASSERT_TRUE(writer->WriteFrame(TexturedFrame(4, 128, 96)).ok());
  ASSERT_TRUE(writer->SkipFrames(0).ok());
  ASSERT_TRUE(writer->WriteFrame(TexturedFrame(5, 128, 96)).ok());
  const Status negative = writer->SkipFrames(-1);
  EXPECT_EQ(negative.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(negative.message().find(path.string()), std::string::npos) << negative.message();
  ASSERT_TRUE(writer->Close().ok());
  EXPECT_EQ(writer->frames_written(), 4);
  EXPECT_EQ(writer->SkipFrames(1).code(), StatusCode::kInvalidArgument) << "after Close";
  const Pass pass = ReadBack(path);
  ASSERT_EQ(pass.frames.size(), 4u);
  const int slots[] = {0, 1, 4, 5};
  for (size_t i = 0; i < 4; ++i) {
    EXPECT_NEAR(pass.frames[i].time_s, slots[i] / 25.0, kTimeTolerance) << "frame " << i;
  }
  ASSERT_EQ(pass.data.size(), 1u);
  EXPECT_NEAR(pass.data[0].time_s, 4 / 25.0, kTimeTolerance);
}

// --- Determinism -------------------------------------------------------------------------------

TEST(TsWriterTest, SameInputGivesByteIdenticalFiles) {
  TsWriterOptions threaded = SmallH264();
  threaded.b_frames = 2;  // threads = 0: libx264 frame threads (several even on 2 cores)
  TsWriterOptions two_threads = threaded;
  two_threads.threads = 2;
  TsWriterOptions mpeg2 = threaded;
  mpeg2.codec = VideoCodec::kMpeg2;
  mpeg2.klv_synchronous = true;
  for (const TsWriterOptions& options : {threaded, two_threads, mpeg2}) {
    SCOPED_TRACE(std::string(VideoCodecName(options.codec)) + " threads " +
                 std::to_string(options.threads));
    const fs::path first = TempFile("first.ts");
    const fs::path second = TempFile("second.ts");
    ASSERT_TRUE(WriteClip(first, options, 12, KlvPlan()).ok());
    ASSERT_TRUE(WriteClip(second, options, 12, KlvPlan()).ok());
    const auto bytes = saker::testing::ReadFileBytes(first);
    EXPECT_GT(bytes.size(), 10000u);
    EXPECT_TRUE(bytes == saker::testing::ReadFileBytes(second)) << "files differ";
  }
}

TEST(TsWriterTest, ImageStrideDoesNotMatter) {
  // A view into a wider picture (rows not contiguous) gives the same file as a compact copy.
  TsWriterOptions options = SmallH264();
  options.with_klv = false;
  const fs::path compact = TempFile("compact.ts");
  const fs::path view = TempFile("view.ts");
  auto a = OpenOrDie(compact, options);
  auto b = OpenOrDie(view, options);
  ASSERT_TRUE(a && b);
  for (int i = 0; i < 3; ++i) {
    const cv::Mat wide = TexturedFrame(i, 200, 120);
    const cv::Mat roi = wide(cv::Rect(5, 7, 128, 96));
    ASSERT_FALSE(roi.isContinuous());
    ASSERT_TRUE(a->WriteFrame(roi.clone()).ok());
    ASSERT_TRUE(b->WriteFrame(roi).ok());
  }
  ASSERT_TRUE(a->Close().ok());
  ASSERT_TRUE(b->Close().ok());
  EXPECT_TRUE(saker::testing::ReadFileBytes(compact) == saker::testing::ReadFileBytes(view));
}

// --- Errors ------------------------------------------------------------------------------------

TEST(TsWriterErrorsTest, MissingDirectoryIsNotFoundAndNamed) {
  const fs::path path = TempFile("x.ts").parent_path() / "no-such-dir" / "out.ts";
  auto writer = TsWriter::Open(path, SmallH264());
  ASSERT_FALSE(writer.ok());
  EXPECT_EQ(writer.status().code(), StatusCode::kNotFound);
  EXPECT_NE(writer.status().message().find(path.string()), std::string::npos)
      << writer.status().message();
  EXPECT_NE(writer.status().message().find("does not exist"), std::string::npos);
}

TEST(TsWriterErrorsTest, DirectoryAsFileIsRefused) {
  const fs::path dir = saker::testing::MakeTempDir("saker-tswriter");
  auto writer = TsWriter::Open(dir, SmallH264());
  ASSERT_FALSE(writer.ok());
  EXPECT_EQ(writer.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(writer.status().message().find(dir.string()), std::string::npos);
}

TEST(TsWriterErrorsTest, UncreatableFileIsAnIoErrorNamingIt) {
  // The encoder is already open when creating the file fails: nothing may leak (ASan build).
  const fs::path path = TempFile("x.ts").parent_path() / (std::string(300, 'n') + ".ts");
  auto writer = TsWriter::Open(path, SmallH264());
  ASSERT_FALSE(writer.ok());
  EXPECT_EQ(writer.status().code(), StatusCode::kIoError);
  EXPECT_NE(writer.status().message().find(path.string()), std::string::npos);
  EXPECT_NE(writer.status().message().find("cannot create"), std::string::npos);
}

TEST(TsWriterErrorsTest, EncoderRefusalIsUnsupportedAndLeavesNoFile) {
  TsWriterOptions options;
  options.codec = VideoCodec::kMpeg2;
  options.width = 64;
  options.height = 48;
  options.fps_num = 7;  // not an MPEG-2 frame rate
  const fs::path path = TempFile("seven.ts");
  auto writer = TsWriter::Open(path, options);
  ASSERT_FALSE(writer.ok());
  EXPECT_EQ(writer.status().code(), StatusCode::kUnsupported);
  EXPECT_NE(writer.status().message().find(path.string()), std::string::npos);
  EXPECT_NE(writer.status().message().find("frame rates"), std::string::npos);
  EXPECT_FALSE(fs::exists(path));
}

TEST(TsWriterErrorsTest, OddSizeForH264IsRefusedBeforeCreatingTheFile) {
  TsWriterOptions options = SmallH264();
  options.width = 127;
  const fs::path path = TempFile("odd.ts");
  auto writer = TsWriter::Open(path, options);
  ASSERT_FALSE(writer.ok());
  EXPECT_EQ(writer.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(writer.status().message().find(path.string()), std::string::npos);
  EXPECT_NE(writer.status().message().find("even"), std::string::npos);
  EXPECT_FALSE(fs::exists(path));
}

TEST(TsWriterErrorsTest, WrongImagesAreRefusedAndTheWriterGoesOn) {
  TsWriterOptions options = SmallH264();
  options.with_klv = false;
  const fs::path path = TempFile("wrong.ts");
  auto writer = OpenOrDie(path, options);
  ASSERT_NE(writer, nullptr);
  const std::vector<cv::Mat> wrong = {
      cv::Mat(),
      cv::Mat(96, 130, CV_8UC3, cv::Scalar::all(0)),
      cv::Mat(94, 128, CV_8UC1, cv::Scalar::all(0)),
      cv::Mat(96, 128, CV_8UC4, cv::Scalar::all(0)),
      cv::Mat(96, 128, CV_16UC3, cv::Scalar::all(0)),
      cv::Mat(96, 128, CV_32FC1, cv::Scalar::all(0)),
  };
  for (const cv::Mat& image : wrong) {
    const Status status = writer->WriteFrame(image);
    EXPECT_EQ(status.code(), StatusCode::kInvalidArgument) << image.size() << " " << image.type();
    EXPECT_NE(status.message().find(path.string()), std::string::npos) << status.message();
  }
  const Status size = writer->WriteFrame(wrong[1]);
  EXPECT_NE(size.message().find("130x96"), std::string::npos) << size.message();
  EXPECT_NE(size.message().find("128x96"), std::string::npos) << size.message();
  EXPECT_EQ(writer->frames_written(), 0);
  ASSERT_TRUE(writer->WriteFrame(TexturedFrame(0, 128, 96)).ok());
  ASSERT_TRUE(writer->WriteFrame(TexturedFrame(1, 128, 96)).ok());
  ASSERT_TRUE(writer->Close().ok());
  EXPECT_EQ(ReadBack(path).frames.size(), 2u);
}

TEST(TsWriterErrorsTest, CallsAfterCloseAreRefusedAndCloseIsIdempotent) {
  const fs::path path = TempFile("closed.ts");
  auto writer = OpenOrDie(path, SmallH264());
  ASSERT_NE(writer, nullptr);
  ASSERT_TRUE(writer->WriteKlv(Packet(0, 30), 0).ok());
  ASSERT_TRUE(writer->WriteFrame(TexturedFrame(0, 128, 96)).ok());
  ASSERT_TRUE(writer->Close().ok());
  const Status frame = writer->WriteFrame(TexturedFrame(1, 128, 96));
  EXPECT_EQ(frame.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(frame.message().find("after Close"), std::string::npos) << frame.message();
  EXPECT_NE(frame.message().find(path.string()), std::string::npos) << frame.message();
  EXPECT_EQ(writer->WriteKlv(Packet(1, 30), 1).code(), StatusCode::kInvalidArgument);
  EXPECT_TRUE(writer->Close().ok());
  EXPECT_EQ(writer->frames_written(), 1);
  const Pass pass = ReadBack(path);
  EXPECT_EQ(pass.frames.size(), 1u);
  EXPECT_EQ(pass.data.size(), 1u);
}

TEST(TsWriterErrorsTest, KlvMisuseIsRefused) {
  TsWriterOptions no_klv = SmallH264();
  no_klv.with_klv = false;
  auto plain = OpenOrDie(TempFile("plain.ts"), no_klv);
  ASSERT_NE(plain, nullptr);
  const Status none = plain->WriteKlv(Packet(0, 10), 0);
  EXPECT_EQ(none.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(none.message().find("with_klv"), std::string::npos) << none.message();

  auto writer = OpenOrDie(TempFile("klv.ts"), SmallH264());
  ASSERT_NE(writer, nullptr);
  EXPECT_EQ(writer->WriteKlv({}, 0).code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(writer->WriteKlv(Packet(0, 10), -1).code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(writer->WriteKlv(Packet(0, 10), std::numeric_limits<int64_t>::max()).code(),
            StatusCode::kInvalidArgument);
  EXPECT_EQ(writer->WriteKlv(Packet(0, kMaxKlvBytesPerFrame + 1), 0).code(),
            StatusCode::kInvalidArgument);
  ASSERT_TRUE(writer->WriteKlv(Packet(0, kMaxKlvBytesPerFrame - 10), 0).ok());
  EXPECT_EQ(writer->WriteKlv(Packet(0, 11), 0).code(), StatusCode::kInvalidArgument)
      << "the joined packets of a frame are limited too";
  ASSERT_TRUE(writer->WriteKlv(Packet(3, 10), 3).ok());
  const Status backwards = writer->WriteKlv(Packet(2, 10), 2);
  EXPECT_EQ(backwards.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(backwards.message().find("must not decrease"), std::string::npos);
  // Once frame 3 is long encoded, its KLV is in the file: no more packets for it.
  for (int i = 0; i < 40; ++i) ASSERT_TRUE(writer->WriteFrame(TexturedFrame(i, 128, 96)).ok());
  const Status late = writer->WriteKlv(Packet(3, 10), 3);
  EXPECT_EQ(late.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(late.message().find("already in the file"), std::string::npos) << late.message();
  // A late packet for a later frame still goes in, at that frame's time.
  ASSERT_TRUE(writer->WriteKlv(Packet(5, 10), 5).ok());
  ASSERT_TRUE(writer->Close().ok());
}

TEST(TsWriterErrorsTest, DiskFullIsAnIoErrorThatStopsTheWriter) {
  const fs::path full = "/dev/full";
  if (!fs::exists(full)) GTEST_SKIP() << "no /dev/full on this system";
  TsWriterOptions options = SmallH264();
  options.crf = 0;  // large packets fill the output buffer quickly
  auto writer = OpenOrDie(full, options);
  ASSERT_NE(writer, nullptr);
  Status first_error;
  for (int i = 0; i < 60 && first_error.ok(); ++i) {
    first_error = writer->WriteFrame(TexturedFrame(i, 128, 96));
  }
  const Status closed = writer->Close();
  EXPECT_FALSE(closed.ok());
  const Status error = first_error.ok() ? closed : first_error;
  EXPECT_EQ(error.code(), StatusCode::kIoError);
  EXPECT_NE(error.message().find("/dev/full"), std::string::npos) << error.message();
  EXPECT_NE(error.message().find("No space left"), std::string::npos) << error.message();
  EXPECT_EQ(closed.message(), error.message()) << "Close reports the error that stopped it";
}

TEST(TsWriterErrorsTest, AFailedOpenLeavesAnExistingFileAlone) {
  // The encoder is opened before the file, so refusing the settings never touches what is there.
  const fs::path path = TempFile("existing.ts");
  { std::ofstream(path) << "an earlier recording"; }
  TsWriterOptions options;
  options.codec = VideoCodec::kMpeg2;
  options.width = 64;
  options.height = 48;
  options.fps_num = 7;  // not an MPEG-2 frame rate
  ASSERT_FALSE(TsWriter::Open(path, options).ok());
  std::ifstream in(path);
  std::string content;
  std::getline(in, content);
  EXPECT_EQ(content, "an earlier recording");
}

TEST(TsWriterErrorsTest, DestructorFinishesAnUnclosedFile) {
  const fs::path path = TempFile("unclosed.ts");
  {
    auto writer = OpenOrDie(path, SmallH264());
    ASSERT_NE(writer, nullptr);
    for (int i = 0; i < 5; ++i) {
      ASSERT_TRUE(writer->WriteKlv(Packet(i, 40), i).ok());
      ASSERT_TRUE(writer->WriteFrame(TexturedFrame(i, 128, 96)).ok());
    }
  }
  const Pass pass = ReadBack(path);
  EXPECT_EQ(pass.frames.size(), 5u);
  EXPECT_EQ(pass.data.size(), 5u);
}

TEST(TsWriterErrorsTest, InvalidOptionsNameTheFile) {
  TsWriterOptions options = SmallH264();
  options.crf = 99;
  const fs::path path = TempFile("bad.ts");
  auto writer = TsWriter::Open(path, options);
  ASSERT_FALSE(writer.ok());
  EXPECT_EQ(writer.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(writer.status().message().find(path.string()), std::string::npos);
  EXPECT_NE(writer.status().message().find("crf"), std::string::npos);
  EXPECT_FALSE(fs::exists(path));
}

}  // namespace
}  // namespace saker::video
