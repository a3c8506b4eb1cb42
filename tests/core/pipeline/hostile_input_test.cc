// Hostile and degraded video inputs, end to end: every one gets either a clear error that names
// the file and the problem, or the graceful outcome the engine promises (the frames before the
// damage, frames without metadata, a chain break, processing that goes on). Videos are tiny
// (320x180, 2-4 s) so each test runs in seconds. docs/reliability.md, "Hostile inputs".

#include "core/export/export.h"
#include "core/frontend/front_end.h"
#include "core/geo/local_tangent_plane.h"
#include "core/ingest/video_scan.h"
#include "core/mission/mission_store.h"
#include "core/pipeline/process.h"
#include "core/sim/simulator.h"
#include "core/sim/truth.h"
#include "core/video/ts_writer.h"
#include "core/video/video_reader.h"
#include "tests/testing/test_data.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sys/resource.h>
#include <sys/stat.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <future>
#include <iostream>
#include <iterator>
#include <memory>
#include <optional>
#include <random>
#include <string>
#include <vector>

namespace saker::pipeline {
namespace {

namespace fs = std::filesystem;
using Bytes = std::vector<uint8_t>;

constexpr size_t kTsPacket = 188;
constexpr int kVideoPid = 0x100;  // TsWriter's PIDs
constexpr int kKlvPid = 0x101;

// 320x180 at 100 m (0.2 m per pixel, like the demo), 25 fps, over the town's streets.
sim::SimulationOptions TinyOptions(const fs::path& output, double seconds, uint64_t seed = 1) {
  sim::SimulationOptions options;
  options.output = output;
  options.seed = seed;
  options.camera.width = 320;
  options.camera.height = 180;
  options.flight.altitude_m = 100;
  options.duration_s = seconds;
  options.targets.cars = 40;
  return options;
}

Bytes ReadBytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return Bytes(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

void WriteBytes(const fs::path& path, const uint8_t* data, size_t size) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  ASSERT_TRUE(out.good()) << "cannot write " << path;
}

void WriteBytes(const fs::path& path, const Bytes& bytes) {
  WriteBytes(path, bytes.data(), bytes.size());
}

int PidOf(const Bytes& ts, size_t offset) {
  return ((ts[offset + 1] & 0x1f) << 8) | ts[offset + 2];
}

// The error a person gets: not OK, names the file, and says what is wrong in its own words.
void ExpectClearError(const Status& status, const fs::path& file, const std::string& problem) {
  ASSERT_FALSE(status.ok()) << file;
  EXPECT_NE(status.message().find(file.string()), std::string::npos)
      << "the error does not name the file: " << status.ToString();
  EXPECT_NE(status.message().find(problem), std::string::npos)
      << "the error does not say '" << problem << "': " << status.ToString();
}

// The mission must not exist after a failed ProcessVideo on a file that is not a video.
void ExpectProcessRefuses(const fs::path& video, const fs::path& dir, const std::string& problem) {
  const fs::path mission = dir / (video.stem().string() + ".saker");
  ProcessOptions options;
  options.render_tiles = false;
  const StatusOr<ProcessSummary> summary = ProcessVideo(video.string(), mission.string(), options);
  ExpectClearError(summary.status(), video, problem);
  EXPECT_FALSE(fs::exists(mission)) << "a refused video left a mission behind";
}

// Peak resident memory of this process so far, in MiB.
double PeakRssMiB() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<double>(usage.ru_maxrss) / 1024.0;
}

// --- H.264 elementary stream and SPS rewriting -------------------------------------------------

// The video PID's payload of a TsWriter file with its PES headers removed: the H.264 Annex B
// byte stream as the encoder wrote it.
Bytes ExtractVideoElementaryStream(const Bytes& ts) {
  Bytes es;
  for (size_t at = 0; at + kTsPacket <= ts.size(); at += kTsPacket) {
    if (ts[at] != 0x47 || PidOf(ts, at) != kVideoPid) continue;
    const bool unit_start = (ts[at + 1] & 0x40) != 0;
    const int adaptation = (ts[at + 3] >> 4) & 0x3;
    size_t payload = at + 4;
    if (adaptation == 2) continue;  // adaptation field only
    if (adaptation == 3) payload += 1 + ts[at + 4];
    if (payload >= at + kTsPacket) continue;
    if (unit_start) payload += 9 + ts[payload + 8];  // PES header and its optional fields
    es.insert(es.end(), ts.begin() + static_cast<std::ptrdiff_t>(payload),
              ts.begin() + static_cast<std::ptrdiff_t>(at + kTsPacket));
  }
  return es;
}

class BitReader {
 public:
  explicit BitReader(const Bytes& bytes) : bytes_(bytes) {}
  bool Bit() {
    if (position_ >= bytes_.size() * 8) {
      overrun_ = true;
      return false;
    }
    const bool bit = (bytes_[position_ / 8] >> (7 - position_ % 8)) & 1;
    ++position_;
    return bit;
  }
  uint32_t Bits(int n) {
    uint32_t value = 0;
    for (int i = 0; i < n; ++i) value = (value << 1) | Bit();
    return value;
  }
  uint32_t Ue() {  // Exp-Golomb
    int zeros = 0;
    while (!Bit() && !overrun_ && zeros < 32) ++zeros;
    return (uint32_t{1} << zeros) - 1 + Bits(zeros);
  }
  size_t position() const { return position_; }
  size_t size_bits() const { return bytes_.size() * 8; }
  bool overrun() const { return overrun_; }

 private:
  const Bytes& bytes_;
  size_t position_ = 0;
  bool overrun_ = false;
};

class BitWriter {
 public:
  void Bit(bool bit) {
    if (count_ % 8 == 0) bytes_.push_back(0);
    if (bit) bytes_.back() |= static_cast<uint8_t>(0x80 >> (count_ % 8));
    ++count_;
  }
  void Bits(uint32_t value, int n) {
    for (int i = n - 1; i >= 0; --i) Bit((value >> i) & 1);
  }
  void Ue(uint32_t value) {
    const uint64_t coded = uint64_t{value} + 1;
    int length = 0;
    while ((coded >> length) > 1) ++length;
    Bits(0, length);
    for (int i = length; i >= 0; --i) Bit((coded >> i) & 1);
  }
  const Bytes& bytes() const { return bytes_; }

 private:
  Bytes bytes_;
  size_t count_ = 0;
};

Bytes RemoveEmulationPrevention(const uint8_t* data, size_t size) {
  Bytes rbsp;
  int zeros = 0;
  for (size_t i = 0; i < size; ++i) {
    if (zeros >= 2 && data[i] == 0x03) {
      zeros = 0;
      continue;
    }
    zeros = data[i] == 0 ? zeros + 1 : 0;
    rbsp.push_back(data[i]);
  }
  return rbsp;
}

Bytes AddEmulationPrevention(const Bytes& rbsp) {
  Bytes nal;
  int zeros = 0;
  for (uint8_t b : rbsp) {
    if (zeros >= 2 && b <= 0x03) {
      nal.push_back(0x03);
      zeros = 0;
    }
    zeros = b == 0 ? zeros + 1 : 0;
    nal.push_back(b);
  }
  return nal;
}

// Rewrites the picture size of an H.264 sequence parameter set (RBSP after the NAL header byte)
// to width_mbs x height_mbs macroblocks, every other field kept bit for bit. Nullopt for SPS
// layouts this small rewriter does not handle (scaling matrices, picture order count type 1).
std::optional<Bytes> RewriteSpsSize(const Bytes& rbsp, uint32_t width_mbs, uint32_t height_mbs) {
  BitReader in(rbsp);
  BitWriter out;
  const uint32_t profile = in.Bits(8);
  out.Bits(profile, 8);
  out.Bits(in.Bits(16), 16);  // constraint flags, level
  out.Ue(in.Ue());            // seq_parameter_set_id
  static const uint32_t kHighProfiles[] = {100, 110, 122, 244, 44, 83, 86, 118, 128, 138, 139, 134};
  if (std::find(std::begin(kHighProfiles), std::end(kHighProfiles), profile) !=
      std::end(kHighProfiles)) {
    const uint32_t chroma_format = in.Ue();
    out.Ue(chroma_format);
    if (chroma_format == 3) out.Bit(in.Bit());
    out.Ue(in.Ue());    // bit depth luma
    out.Ue(in.Ue());    // bit depth chroma
    out.Bit(in.Bit());  // qpprime_y_zero_transform_bypass
    const bool scaling_matrix = in.Bit();
    if (scaling_matrix) return std::nullopt;
    out.Bit(false);
  }
  out.Ue(in.Ue());  // log2_max_frame_num_minus4
  const uint32_t poc_type = in.Ue();
  out.Ue(poc_type);
  if (poc_type == 0) out.Ue(in.Ue());
  if (poc_type == 1) return std::nullopt;
  out.Ue(in.Ue());    // max_num_ref_frames
  out.Bit(in.Bit());  // gaps_in_frame_num_allowed
  in.Ue();            // pic_width_in_mbs_minus1
  in.Ue();            // pic_height_in_map_units_minus1
  out.Ue(width_mbs - 1);
  out.Ue(height_mbs - 1);
  while (in.position() < in.size_bits()) out.Bit(in.Bit());  // the rest, trailing bits included
  if (in.overrun()) return std::nullopt;
  return out.bytes();
}

// The Annex B stream with every SPS claiming width_mbs x height_mbs macroblocks.
std::optional<Bytes> WithDeclaredSize(const Bytes& es, uint32_t width_mbs, uint32_t height_mbs) {
  // NAL unit starts (after each 00 00 01).
  std::vector<size_t> starts;
  for (size_t i = 0; i + 3 <= es.size(); ++i) {
    if (es[i] == 0 && es[i + 1] == 0 && es[i + 2] == 1) starts.push_back(i + 3);
  }
  Bytes out;
  int rewritten = 0;
  for (size_t k = 0; k < starts.size(); ++k) {
    size_t end = k + 1 < starts.size() ? starts[k + 1] - 3 : es.size();
    while (end > starts[k] && es[end - 1] == 0) --end;  // zero_byte of a 4-byte start code
    const size_t begin = starts[k];
    out.insert(out.end(), {0, 0, 0, 1});
    if (begin < end && (es[begin] & 0x1f) == 7) {
      const Bytes rbsp = RemoveEmulationPrevention(&es[begin + 1], end - begin - 1);
      const std::optional<Bytes> sps = RewriteSpsSize(rbsp, width_mbs, height_mbs);
      if (!sps) return std::nullopt;
      out.push_back(es[begin]);
      const Bytes nal = AddEmulationPrevention(*sps);
      out.insert(out.end(), nal.begin(), nal.end());
      ++rewritten;
    } else {
      out.insert(out.end(), es.begin() + static_cast<std::ptrdiff_t>(begin),
                 es.begin() + static_cast<std::ptrdiff_t>(end));
    }
  }
  if (rewritten == 0) return std::nullopt;
  return out;
}

// --- The shared clip -----------------------------------------------------------------------------

class HostileInputTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new fs::path(saker::testing::MakeTempDir("saker-hostile"));
    const sim::SimulationOptions options = TinyOptions(*dir_ / "clip.ts", 3);
    const StatusOr<sim::SimulationSummary> summary = sim::Simulate(options);
    ASSERT_TRUE(summary.ok()) << summary.status().ToString();
    clip_frames_ = summary->frames;
  }
  static void TearDownTestSuite() {
    delete dir_;
    dir_ = nullptr;
  }
  void SetUp() override { ASSERT_NE(dir_, nullptr); }

  static fs::path Clip() { return *dir_ / "clip.ts"; }

  static fs::path* dir_;
  static int64_t clip_frames_;
};
fs::path* HostileInputTest::dir_ = nullptr;
int64_t HostileInputTest::clip_frames_ = 0;

// --- Files that are not video --------------------------------------------------------------------

TEST_F(HostileInputTest, ZeroByteFileIsRefusedByEveryEntryPoint) {
  const fs::path empty = *dir_ / "empty.ts";
  WriteBytes(empty, Bytes{});
  ASSERT_TRUE(fs::exists(empty));
  ExpectClearError(ingest::ScanVideo(empty.string(), {}).status(), empty, "empty (0 bytes)");
  const auto front = frontend::RunFrontEnd(empty.string(), {});
  ExpectClearError(front.status(), empty, "empty (0 bytes)");
  EXPECT_EQ(front.status().code(), StatusCode::kInvalidData);
  ExpectProcessRefuses(empty, *dir_, "empty (0 bytes)");
}

TEST_F(HostileInputTest, FilesThatAreNotVideoAreRefusedNamingThem) {
  // Text, a PNG picture and random bytes, each renamed .ts.
  const fs::path text = *dir_ / "notes.ts";
  std::ofstream(text) << "Sortie 12, camera 2: see attached video.\n";
  const fs::path png = *dir_ / "picture.ts";
  Bytes png_bytes;
  ASSERT_TRUE(cv::imencode(".png", cv::Mat(90, 160, CV_8UC3, cv::Scalar(40, 120, 200)), png_bytes));
  WriteBytes(png, png_bytes);
  const fs::path noise = *dir_ / "noise.ts";
  Bytes random(256 * 1024);
  std::mt19937 generator(20261122);
  for (uint8_t& b : random) b = static_cast<uint8_t>(generator());
  WriteBytes(noise, random);
  // A transport stream whose packets are all padding (sync bytes, no program): it demuxes, but
  // holds no video.
  const fs::path padding = *dir_ / "padding.ts";
  Bytes null_packets(kTsPacket * 2000, 0xff);
  for (size_t at = 0; at < null_packets.size(); at += kTsPacket) {
    null_packets[at] = 0x47;
    null_packets[at + 1] = 0x1f;
    null_packets[at + 2] = 0xff;
    null_packets[at + 3] = 0x10;
  }
  WriteBytes(padding, null_packets);

  for (const fs::path& file : {text, png, noise, padding}) {
    SCOPED_TRACE(file.string());
    const StatusOr<ingest::VideoScan> scan = ingest::ScanVideo(file.string(), {});
    ASSERT_FALSE(scan.ok()) << "read as a video of " << scan->frames.size() << " frames ("
                            << scan->info.container << ")";
    std::cout << file.filename().string() << ": " << scan.status().ToString() << "\n";
    EXPECT_NE(scan.status().message().find(file.string()), std::string::npos)
        << scan.status().ToString();
    EXPECT_EQ(scan.status().code(), StatusCode::kInvalidData) << scan.status().ToString();
    ExpectProcessRefuses(file, *dir_, file.string());
  }
  // FFmpeg reads a picture as a one-frame video; Saker says what it is.
  ExpectClearError(ingest::ScanVideo(png.string(), {}).status(), png,
                   "is a still picture (png), not a video");
}

// Item 11 of issue 29: a FIFO given as the video blocked `probe` and `process` for ever (FFmpeg
// waits for a writer). It is refused at once; a test that would hang unblocks it and fails.
TEST_F(HostileInputTest, AFifoIsRefusedNotWaitedOn) {
  const fs::path fifo = *dir_ / "live.ts";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const fs::path mission = *dir_ / "live.saker";
  auto refused = std::async(std::launch::async, [&] {
    return std::make_pair(ingest::ScanVideo(fifo.string(), {}).status(),
                          ProcessVideo(fifo.string(), mission.string(), {}).status());
  });
  if (refused.wait_for(std::chrono::seconds(10)) != std::future_status::ready) {
    ADD_FAILURE() << "still waiting on the FIFO after 10 s";
    // Unblock it: a writer that closes at once ends the reading.
    for (int i = 0;
         i < 4 && refused.wait_for(std::chrono::milliseconds(200)) != std::future_status::ready;
         ++i) {
      std::ofstream(fifo, std::ios::binary).close();
    }
  }
  const auto [scan, process] = refused.get();
  ExpectClearError(scan, fifo, "is a FIFO (named pipe), not a video file");
  EXPECT_EQ(scan.code(), StatusCode::kInvalidArgument);
  ExpectClearError(process, fifo, "is a FIFO (named pipe), not a video file");
  EXPECT_FALSE(fs::exists(mission));
  fs::remove(fifo);
}

// --- Truncation ----------------------------------------------------------------------------------

TEST_F(HostileInputTest, TruncatedStreamsGiveTheFramesBeforeTheCutOrAClearError) {
  const Bytes whole = ReadBytes(Clip());
  ASSERT_GT(whole.size(), 100 * kTsPacket);
  const size_t quarter = whole.size() / 4 / kTsPacket * kTsPacket;
  // Packet boundaries and mid-packet cuts, from the first bytes to one byte short of the end.
  const std::vector<size_t> cuts = {1,
                                    100,
                                    kTsPacket,
                                    3 * kTsPacket + 50,
                                    20 * kTsPacket,
                                    quarter + 77,
                                    2 * quarter,
                                    2 * quarter + 94,
                                    3 * quarter + 187,
                                    whole.size() - kTsPacket,
                                    whole.size() - 1};
  int64_t previous_frames = 0;
  for (size_t cut : cuts) {
    SCOPED_TRACE("cut at byte " + std::to_string(cut));
    const fs::path file = *dir_ / ("cut-" + std::to_string(cut) + ".ts");
    WriteBytes(file, whole.data(), cut);
    const StatusOr<ingest::VideoScan> scan = ingest::ScanVideo(file.string(), {});
    if (!scan.ok()) {
      std::cout << "cut " << cut << ": " << scan.status().ToString() << "\n";
      // Only a cut before the first complete picture may fail, and then it says which file.
      EXPECT_LT(cut, 2 * quarter) << scan.status().ToString();
      EXPECT_NE(scan.status().message().find(file.string()), std::string::npos)
          << scan.status().ToString();
      EXPECT_EQ(scan.status().code(), StatusCode::kInvalidData) << scan.status().ToString();
      continue;
    }
    const int64_t frames = static_cast<int64_t>(scan->frames.size());
    std::cout << "cut " << cut << ": " << frames << " of " << clip_frames_ << " frames, "
              << scan->FramesWithMetadata() << " with metadata\n";
    EXPECT_LE(frames, clip_frames_);
    EXPECT_GE(frames, previous_frames) << "a longer file gave fewer frames";
    previous_frames = frames;
    for (size_t i = 1; i < scan->frames.size(); ++i) {
      ASSERT_GT(scan->frames[i].time_s, scan->frames[i - 1].time_s);
    }
    // Most of what lies before the cut survives (the last GOP may lose its tail).
    const double kept = static_cast<double>(cut) / static_cast<double>(whole.size());
    if (kept >= 0.5) {
      EXPECT_GE(static_cast<double>(frames), kept * static_cast<double>(clip_frames_) - 26);
      EXPECT_GE(scan->FramesWithMetadata(), frames - 2);
    }
  }
  EXPECT_GE(previous_frames, clip_frames_ - 1);
}

TEST_F(HostileInputTest, StreamEndingInsideAKlvPacketIsProcessedToTheEnd) {
  const Bytes whole = ReadBytes(Clip());
  // Cut in the middle of the last transport packet of the KLV stream: the last metadata packet,
  // and the video after it, end mid-packet.
  size_t last_klv = 0;
  for (size_t at = 0; at + kTsPacket <= whole.size(); at += kTsPacket) {
    if (PidOf(whole, at) == kKlvPid) last_klv = at;
  }
  ASSERT_GT(last_klv, whole.size() / 2);
  const fs::path file = *dir_ / "ends-mid-klv.ts";
  WriteBytes(file, whole.data(), last_klv + 100);

  const StatusOr<ingest::VideoScan> scan = ingest::ScanVideo(file.string(), {});
  ASSERT_TRUE(scan.ok()) << scan.status().ToString();
  EXPECT_GE(static_cast<int64_t>(scan->frames.size()), clip_frames_ - 3);
  EXPECT_GE(scan->FramesWithMetadata(), static_cast<int64_t>(scan->frames.size()) - 1);
  for (const std::string& w : scan->warnings) std::cout << "warning: " << w << "\n";

  ProcessOptions options;
  options.render_tiles = false;
  const fs::path mission_path = *dir_ / "ends-mid-klv.saker";
  const StatusOr<ProcessSummary> summary =
      ProcessVideo(file.string(), mission_path.string(), options);
  ASSERT_TRUE(summary.ok()) << summary.status().ToString();
  EXPECT_EQ(summary->frames, static_cast<int64_t>(scan->frames.size()));
  EXPECT_TRUE(summary->progress.mosaic);
  EXPECT_TRUE(summary->geo_referenced);
}

// --- Absurd picture sizes ------------------------------------------------------------------------

TEST_F(HostileInputTest, AbsurdDeclaredSizesAreRefusedBeforeDecoding) {
  // A tiny honest H.264 stream, then the same stream with its sequence parameter sets claiming
  // a huge picture (the slices still code 320x180).
  const fs::path ts = *dir_ / "plain.ts";
  {
    video::TsWriterOptions writer_options;
    writer_options.width = 320;
    writer_options.height = 180;
    writer_options.with_klv = false;
    writer_options.threads = 1;
    auto writer = video::TsWriter::Open(ts, writer_options);
    ASSERT_TRUE(writer.ok()) << writer.status().ToString();
    cv::Mat image(180, 320, CV_8UC3);
    for (int i = 0; i < 10; ++i) {
      cv::randu(image, cv::Scalar::all(0), cv::Scalar::all(255));
      ASSERT_TRUE((*writer)->WriteFrame(image).ok());
    }
    ASSERT_TRUE((*writer)->Close().ok());
  }
  const Bytes es = ExtractVideoElementaryStream(ReadBytes(ts));
  ASSERT_GT(es.size(), 1000u);

  // The unmodified elementary stream reads: the rewrite below is what makes the difference.
  const fs::path plain = *dir_ / "plain.h264";
  WriteBytes(plain, es);
  {
    const StatusOr<ingest::VideoScan> scan = ingest::ScanVideo(plain.string(), {});
    ASSERT_TRUE(scan.ok()) << scan.status().ToString();
    EXPECT_EQ(scan->info.width, 320);
    EXPECT_EQ(scan->info.height, 180);
    EXPECT_EQ(scan->frames.size(), 10u);
    // The same stream with the size rewritten to its own size still reads (the rewriter is
    // faithful).
    const std::optional<Bytes> same = WithDeclaredSize(es, 20, 12);
    ASSERT_TRUE(same.has_value());
    const fs::path rewritten = *dir_ / "same-size.h264";
    WriteBytes(rewritten, *same);
    const StatusOr<ingest::VideoScan> again = ingest::ScanVideo(rewritten.string(), {});
    ASSERT_TRUE(again.ok()) << again.status().ToString();
    EXPECT_EQ(again->info.width, 320);
    EXPECT_EQ(again->frames.size(), 10u);
  }

  const double rss_before = PeakRssMiB();
  // 60000x60000: beyond what FFmpeg accepts at all. 16000x16000: FFmpeg accepts it (and would
  // allocate about 400 MB per picture) but it is beyond Saker's max_pixels.
  struct Case {
    uint32_t mbs_wide, mbs_high;
    const char* name;
  };
  for (const Case& c :
       {Case{3750, 3750, "60000x60000.h264"}, Case{1000, 1000, "16000x16000.h264"}}) {
    SCOPED_TRACE(c.name);
    const std::optional<Bytes> huge = WithDeclaredSize(es, c.mbs_wide, c.mbs_high);
    ASSERT_TRUE(huge.has_value());
    const fs::path file = *dir_ / c.name;
    WriteBytes(file, *huge);
    const StatusOr<ingest::VideoScan> scan = ingest::ScanVideo(file.string(), {});
    ASSERT_FALSE(scan.ok()) << "a " << c.name << " stream was accepted: " << scan->info.width << "x"
                            << scan->info.height;
    std::cout << c.name << ": " << scan.status().ToString() << "\n";
    ExpectClearError(scan.status(), file, "picture size");
    EXPECT_EQ(scan.status().code(), StatusCode::kInvalidData);
    ExpectClearError(frontend::RunFrontEnd(file.string(), {}).status(), file, "picture size");
    ExpectProcessRefuses(file, *dir_, "picture size");
  }
  // Nothing near a huge picture was ever allocated (one 16000x16000 YUV picture is 366 MiB).
  // Under AddressSanitizer freed memory stays resident in its quarantine, so the peak says
  // nothing there.
#if !defined(__SANITIZE_ADDRESS__)
  EXPECT_LT(PeakRssMiB() - rss_before, 150.0);
#else
  (void)rss_before;
#endif

  // The limit is an option: a 320x180 video is refused below 57600 pixels.
  ingest::ScanOptions small;
  small.reader.max_pixels = 320 * 180 - 1;
  ExpectClearError(ingest::ScanVideo(Clip().string(), small).status(), Clip(), "max_pixels");
  small.reader.max_pixels = 320 * 180;
  EXPECT_TRUE(ingest::ScanVideo(Clip().string(), small).ok());
}

// --- Metadata ------------------------------------------------------------------------------------

// Rewrites the clip with the same pictures and its own KLV packets, but with time stamps that
// repeat and go backwards: frame 10 repeats frame 9's packet (the same UTC time twice), frame 30
// carries two packets (its own and frame 29's: two packets with one PES time), frames 50 and 51
// have each other's packets (UTC goes backwards).
TEST_F(HostileInputTest, DuplicatedAndOutOfOrderKlvTimestampsAreAccepted) {
  auto reader = video::VideoReader::Open(Clip().string());
  ASSERT_TRUE(reader.ok()) << reader.status().ToString();
  std::vector<cv::Mat> frames;
  std::vector<Bytes> klv;  // per frame, the clip's packet for it
  std::vector<double> times;
  std::vector<video::DataPacket> data;
  std::vector<video::DataPacket> all_data;
  video::Frame frame;
  while (true) {
    data.clear();
    auto more = (*reader)->ReadNext(&frame, &data);
    ASSERT_TRUE(more.ok()) << more.status().ToString();
    all_data.insert(all_data.end(), data.begin(), data.end());
    if (!*more) break;
    frames.push_back(frame.bgr.clone());
    times.push_back(frame.time_s);
  }
  ASSERT_EQ(static_cast<int64_t>(frames.size()), clip_frames_);
  klv.resize(frames.size());
  for (const video::DataPacket& p : all_data) {
    const auto at = std::lower_bound(times.begin(), times.end(), p.time_s - 1e-3);
    ASSERT_NE(at, times.end());
    klv[static_cast<size_t>(at - times.begin())] = p.bytes;
  }
  for (size_t i = 0; i < klv.size(); ++i) ASSERT_FALSE(klv[i].empty()) << "frame " << i;

  const fs::path file = *dir_ / "klv-times.ts";
  {
    video::TsWriterOptions options;
    options.width = 320;
    options.height = 180;
    options.threads = 1;
    auto writer = video::TsWriter::Open(file, options);
    ASSERT_TRUE(writer.ok()) << writer.status().ToString();
    for (size_t i = 0; i < frames.size(); ++i) {
      std::vector<size_t> sources = {i};
      if (i == 10) sources = {9};
      if (i == 30) sources = {30, 29};
      if (i == 50) sources = {51};
      if (i == 51) sources = {50};
      for (size_t s : sources) {
        ASSERT_TRUE((*writer)->WriteKlv(klv[s], static_cast<int64_t>(i)).ok());
      }
      ASSERT_TRUE((*writer)->WriteFrame(frames[i]).ok());
    }
    ASSERT_TRUE((*writer)->Close().ok());
  }

  const StatusOr<ingest::VideoScan> original = ingest::ScanVideo(Clip().string(), {});
  ASSERT_TRUE(original.ok());
  const StatusOr<ingest::VideoScan> scan = ingest::ScanVideo(file.string(), {});
  ASSERT_TRUE(scan.ok()) << scan.status().ToString();
  EXPECT_EQ(scan->frames.size(), frames.size());
  EXPECT_EQ(scan->packets.size(), frames.size() + 1);
  EXPECT_EQ(scan->FramesWithMetadata(), static_cast<int64_t>(frames.size()));
  for (const ingest::KlvStreamSummary& s : scan->klv_streams) {
    EXPECT_EQ(s.decode_errors, 0);
    EXPECT_EQ(s.checksum_failures, 0);
  }
  ASSERT_TRUE(scan->UtcSpan().has_value());
  EXPECT_EQ(scan->UtcSpan()->first_us, original->UtcSpan()->first_us);
  EXPECT_EQ(scan->UtcSpan()->last_us, original->UtcSpan()->last_us);
  // Each frame carries the packet it was given (one of two for frame 30).
  const auto utc_of = [](const ingest::VideoScan& s, size_t f) {
    const klv::FrameMetadata* m = s.MetadataOf(f);
    return m != nullptr && m->unix_time_us ? *m->unix_time_us : 0;
  };
  EXPECT_EQ(utc_of(*scan, 10), utc_of(*original, 9));
  EXPECT_EQ(utc_of(*scan, 50), utc_of(*original, 51));
  EXPECT_EQ(utc_of(*scan, 51), utc_of(*original, 50));
  EXPECT_GT(utc_of(*scan, 50), utc_of(*scan, 51));

  ProcessOptions options;
  options.render_tiles = false;
  const fs::path mission_path = *dir_ / "klv-times.saker";
  const StatusOr<ProcessSummary> summary =
      ProcessVideo(file.string(), mission_path.string(), options);
  ASSERT_TRUE(summary.ok()) << summary.status().ToString();
  EXPECT_EQ(summary->frames, static_cast<int64_t>(frames.size()));
  EXPECT_TRUE(summary->geo_referenced);
  EXPECT_TRUE(summary->progress.mosaic);
}

TEST_F(HostileInputTest, MetadataThatStopsMidFlightLeavesTheRestWithout) {
  sim::SimulationOptions sim_options = TinyOptions(*dir_ / "metadata-stops.ts", 3);
  for (int64_t f = 0; f < 25; ++f) sim_options.metadata.only_frames.push_back(f);  // 1 s of 3
  ASSERT_TRUE(sim::Simulate(sim_options).ok());
  const std::string file = sim_options.output.string();

  const StatusOr<ingest::VideoScan> scan = ingest::ScanVideo(file, {});
  ASSERT_TRUE(scan.ok()) << scan.status().ToString();
  ASSERT_EQ(static_cast<int64_t>(scan->frames.size()), clip_frames_);
  // The first second has metadata; frames more than the 0.5 s tolerance after the last packet
  // have none, and say so (no packet borrowed from far away).
  for (size_t f = 0; f < 25; ++f) EXPECT_NE(scan->MetadataOf(f), nullptr) << "frame " << f;
  for (size_t f = 25 + 13; f < scan->frames.size(); ++f) {
    EXPECT_EQ(scan->MetadataOf(f), nullptr) << "frame " << f;
    EXPECT_EQ(scan->frames[f].metadata.kind, ingest::MatchKind::kNone);
  }

  ProcessOptions options;
  options.render_tiles = false;
  const fs::path mission_path = *dir_ / "metadata-stops.saker";
  const StatusOr<ProcessSummary> summary = ProcessVideo(file, mission_path.string(), options);
  ASSERT_TRUE(summary.ok()) << summary.status().ToString();
  EXPECT_EQ(summary->frames, clip_frames_);
  EXPECT_TRUE(summary->progress.mosaic);
  auto store = mission::MissionStore::Open(mission_path.string());
  ASSERT_TRUE(store.ok()) << store.status().ToString();
  const StatusOr<mission::Mission> mission = (*store)->Load();
  ASSERT_TRUE(mission.ok()) << mission.status().ToString();
  ASSERT_EQ(static_cast<int64_t>(mission->frames.size()), clip_frames_);
  EXPECT_TRUE(mission->frames.front().utc_us.has_value());
  EXPECT_FALSE(mission->frames.back().utc_us.has_value());
  EXPECT_FALSE(mission->frames.back().metadata_corners.has_value());
  // The frames without metadata are still placed on the map through the video.
  EXPECT_TRUE(mission->frames.back().map_from_frame.has_value());
}

TEST_F(HostileInputTest, MetadataDropoutsAndSparsePacketsKeepEveryFrame) {
  sim::SimulationOptions sim_options = TinyOptions(*dir_ / "dropouts.ts", 3);
  sim_options.metadata.every_n_frames = 5;
  sim_options.metadata.dropout_probability = 0.5;
  ASSERT_TRUE(sim::Simulate(sim_options).ok());
  const StatusOr<ingest::VideoScan> scan = ingest::ScanVideo(sim_options.output.string(), {});
  ASSERT_TRUE(scan.ok()) << scan.status().ToString();
  ASSERT_EQ(static_cast<int64_t>(scan->frames.size()), clip_frames_);
  EXPECT_LT(scan->packets.size(), static_cast<size_t>(clip_frames_ / 5 + 1));
  EXPECT_GT(scan->packets.size(), 0u);
  ProcessOptions options;
  options.render_tiles = false;
  const StatusOr<ProcessSummary> summary =
      ProcessVideo(sim_options.output.string(), (*dir_ / "dropouts.saker").string(), options);
  ASSERT_TRUE(summary.ok()) << summary.status().ToString();
  EXPECT_EQ(summary->frames, clip_frames_);
}

// --- Pictures
// --------------------------------------------------------------------------------------

TEST_F(HostileInputTest, BlankFramesBreakTheChainAndProcessingGoesOn) {
  sim::SimulationOptions sim_options = TinyOptions(*dir_ / "blank.ts", 4);
  sim_options.imaging.blank_start_s = 1.5;  // uniform grey, no texture at all, for 1 s
  sim_options.imaging.blank_duration_s = 1;
  ASSERT_TRUE(sim::Simulate(sim_options).ok());
  const std::string file = sim_options.output.string();

  const StatusOr<frontend::FrontEndResult> front = frontend::RunFrontEnd(file, {});
  ASSERT_TRUE(front.ok()) << front.status().ToString();
  EXPECT_EQ(front->frames.size(), 100u);
  ASSERT_GE(front->breaks.size(), 1u);
  EXPECT_NEAR(static_cast<double>(front->breaks.front().frame_index), 37.5, 3);
  bool estimated_after = false;  // the chain recovers after the blank
  for (size_t f = 70; f < front->frames.size(); ++f)
    estimated_after |= front->frames[f].homography_ok;
  EXPECT_TRUE(estimated_after);

  ProcessOptions options;
  options.render_tiles = false;
  const StatusOr<ProcessSummary> summary =
      ProcessVideo(file, (*dir_ / "blank.saker").string(), options);
  ASSERT_TRUE(summary.ok()) << summary.status().ToString();
  EXPECT_EQ(summary->frames, 100);
  EXPECT_TRUE(summary->progress.mosaic);
  EXPECT_LT(summary->frames_placed, summary->frames + 1);
}

// Two different recordings joined byte for byte (a recorder restarted, a file spliced): the
// second one's timestamps start again from its own beginning.
TEST_F(HostileInputTest, AbruptCutBetweenTwoClipsKeepsEachFramesOwnMetadata) {
  sim::SimulationOptions second = TinyOptions(*dir_ / "second.ts", 2, 7);
  second.scenario = sim::Scenario::kStraight;
  second.start_utc_us += 3600LL * 1000000;  // an hour later
  const StatusOr<sim::SimulationSummary> made = sim::Simulate(second);
  ASSERT_TRUE(made.ok()) << made.status().ToString();
  Bytes joined = ReadBytes(Clip());
  const Bytes tail = ReadBytes(second.output);
  joined.insert(joined.end(), tail.begin(), tail.end());
  const fs::path file = *dir_ / "spliced.ts";
  WriteBytes(file, joined);
  const int64_t first_frames = clip_frames_;
  const int64_t total = first_frames + made->frames;

  const StatusOr<ingest::VideoScan> scan = ingest::ScanVideo(file.string(), {});
  ASSERT_TRUE(scan.ok()) << scan.status().ToString();
  for (const std::string& w : scan->warnings) std::cout << "warning: " << w << "\n";
  EXPECT_EQ(scan->stats.timestamp_discontinuities, 1);
  EXPECT_TRUE(std::any_of(scan->warnings.begin(), scan->warnings.end(), [&](const std::string& w) {
    return w.find(file.string()) != std::string::npos &&
           w.find("jump back 1 time") != std::string::npos;
  })) << "no warning about the splice";
  EXPECT_GE(static_cast<int64_t>(scan->frames.size()), total - 2);
  EXPECT_LE(static_cast<int64_t>(scan->frames.size()), total);
  for (size_t i = 1; i < scan->frames.size(); ++i) {
    ASSERT_GT(scan->frames[i].time_s, scan->frames[i - 1].time_s) << "frame " << i;
  }
  // Every frame's metadata comes from its own recording: UTC times before the splice belong to
  // the first clip, after it to the second (an hour later).
  const uint64_t second_start = second.start_utc_us;
  int64_t wrong = 0, without = 0;
  for (size_t f = 0; f < scan->frames.size(); ++f) {
    const klv::FrameMetadata* m = scan->MetadataOf(f);
    if (m == nullptr || !m->unix_time_us) {
      ++without;
      continue;
    }
    const bool from_second = *m->unix_time_us >= second_start;
    wrong += from_second != (static_cast<int64_t>(f) >= first_frames);
  }
  EXPECT_EQ(wrong, 0) << "frames tied to the other recording's metadata";
  EXPECT_LE(without, 2);

  const StatusOr<frontend::FrontEndResult> front = frontend::RunFrontEnd(file.string(), {});
  ASSERT_TRUE(front.ok()) << front.status().ToString();
  bool break_at_cut = false;
  for (const track::ChainBreak& b : front->breaks) {
    break_at_cut |= std::abs(b.frame_index - first_frames) <= 2;
  }
  EXPECT_TRUE(break_at_cut) << "no chain break at the splice (frame " << first_frames << ")";

  ProcessOptions options;
  options.render_tiles = false;
  const StatusOr<ProcessSummary> summary =
      ProcessVideo(file.string(), (*dir_ / "spliced.saker").string(), options);
  ASSERT_TRUE(summary.ok()) << summary.status().ToString();
  EXPECT_EQ(summary->frames, static_cast<int64_t>(scan->frames.size()));
  EXPECT_TRUE(summary->progress.mosaic);
}

// --- KLV that failed its checksum ------------------------------------------------------------

// Flips bits in the time stamp (tag 2) and the sensor latitude (tag 13) of the ST 0601 packets
// that start in the KLV transport packets numbered `ordinals` (counting those that start a PES
// packet), leaving the checksum as it was: the packets still decode, but fail their checksum.
// Returns how many packets were damaged.
int DamageKlvPackets(Bytes* ts, const std::vector<int>& ordinals) {
  int ordinal = -1, damaged = 0;
  for (size_t at = 0; at + kTsPacket <= ts->size(); at += kTsPacket) {
    Bytes& b = *ts;
    if (b[at] != 0x47 || PidOf(b, at) != kKlvPid || (b[at + 1] & 0x40) == 0) continue;
    ++ordinal;
    if (std::find(ordinals.begin(), ordinals.end(), ordinal) == ordinals.end()) continue;
    const size_t end = at + kTsPacket;
    size_t p = at + 4;
    if (((b[at + 3] >> 4) & 0x3) == 3) p += 1 + b[at + 4];
    p += 9 + b[p + 8];  // the PES header
    if (p + 18 > end || b[p] != 0x06 || b[p + 1] != 0x0e || b[p + 2] != 0x2b) continue;
    p += 16;                                     // the ST 0601 key
    p += (b[p] & 0x80) ? 1 + (b[p] & 0x7f) : 1;  // its BER length
    bool time = false, latitude = false;
    while (p + 2 <= end && !(time && latitude)) {
      const int tag = b[p], length = b[p + 1];
      if (p + 2 + static_cast<size_t>(length) > end || (length & 0x80) != 0) break;
      if (tag == 2 && length == 8) {
        b[p + 4] ^= 0x04;  // 2^42 us: 51 days
        time = true;
      }
      if (tag == 13 && length == 4) {
        b[p + 2] ^= 0x10;  // 11 degrees of latitude
        latitude = true;
      }
      p += 2 + static_cast<size_t>(length);
    }
    damaged += time && latitude;
  }
  return damaged;
}

// Processes `video` (no tiles) into `mission_path` and reads the mission back.
StatusOr<mission::Mission> ProcessAndLoad(const fs::path& video, const fs::path& mission_path) {
  ProcessOptions options;
  options.render_tiles = false;
  SAKER_RETURN_IF_ERROR(ProcessVideo(video.string(), mission_path.string(), options).status());
  SAKER_ASSIGN_OR_RETURN(const std::unique_ptr<mission::MissionStore> store,
                         mission::MissionStore::Open(mission_path.string()));
  return store->Load();
}

// Flipped bits in a few packets mid-clip: their checksum fails, so they time and place nothing
// (the UTC span and the sensor positions are the clean clip's), they are counted (probe, the
// mission for `info`), and --accept-bad-checksums lets them in again.
TEST_F(HostileInputTest, KlvPacketsFailingTheirChecksumNeverTimeOrPlaceFrames) {
  Bytes ts = ReadBytes(Clip());
  const int damaged = DamageKlvPackets(&ts, {10, 20, 30, 40, 50});
  ASSERT_EQ(damaged, 5) << "the clip's KLV packets are not laid out as expected";
  const fs::path file = *dir_ / "bad-checksums.ts";
  WriteBytes(file, ts);

  const StatusOr<ingest::VideoScan> original = ingest::ScanVideo(Clip().string(), {});
  ASSERT_TRUE(original.ok()) << original.status().ToString();
  ASSERT_TRUE(original->UtcSpan().has_value());
  const StatusOr<ingest::VideoScan> scan = ingest::ScanVideo(file.string(), {});
  ASSERT_TRUE(scan.ok()) << scan.status().ToString();
  EXPECT_EQ(scan->ChecksumFailures(), damaged);
  ASSERT_TRUE(scan->UtcSpan().has_value());
  EXPECT_EQ(scan->UtcSpan()->first_us, original->UtcSpan()->first_us);
  EXPECT_EQ(scan->UtcSpan()->last_us, original->UtcSpan()->last_us);
  EXPECT_NEAR(scan->UtcSpan()->SpanSeconds(), original->UtcSpan()->SpanSeconds(), 1e-9);
  ASSERT_EQ(scan->frames.size(), original->frames.size());
  EXPECT_GE(scan->FramesWithMetadata(), original->FramesWithMetadata() - damaged);
  for (size_t f = 0; f < scan->frames.size(); ++f) {
    const klv::FrameMetadata* m = scan->MetadataOf(f);
    if (m == nullptr) continue;
    EXPECT_TRUE(m->checksum_ok) << "frame " << f << " took a packet that failed its checksum";
    ASSERT_TRUE(m->sensor_latitude_deg && m->unix_time_us) << "frame " << f;
    ASSERT_NE(original->MetadataOf(f), nullptr) << "frame " << f;
    EXPECT_NEAR(*m->sensor_latitude_deg, *original->MetadataOf(f)->sensor_latitude_deg, 1e-3)
        << "frame " << f;
    EXPECT_NEAR(static_cast<double>(*m->unix_time_us),
                static_cast<double>(*original->MetadataOf(f)->unix_time_us), 0.5e6)
        << "frame " << f;
  }
  bool warned = false;
  for (const std::string& w : scan->warnings) warned |= w.find("failed the checksum") != w.npos;
  EXPECT_TRUE(warned) << "no warning about the packets that failed their checksum";

  // Asked for, the damaged packets are used: 51 days of "flight" in 3 s of video.
  ingest::ScanOptions accept;
  accept.alignment.accept_bad_checksums = true;
  const StatusOr<ingest::VideoScan> accepted = ingest::ScanVideo(file.string(), accept);
  ASSERT_TRUE(accepted.ok()) << accepted.status().ToString();
  ASSERT_TRUE(accepted->UtcSpan().has_value());
  EXPECT_GT(accepted->UtcSpan()->SpanSeconds(), 86400.0);

  // The mission: every frame's time and sensor position from good packets, the failures counted.
  const StatusOr<mission::Mission> m = ProcessAndLoad(file, *dir_ / "bad-checksums.saker");
  ASSERT_TRUE(m.ok()) << m.status().ToString();
  ASSERT_TRUE(m->klv.has_value());
  EXPECT_EQ(m->klv->checksum_failures, damaged);
  EXPECT_EQ(m->klv->packets, static_cast<int64_t>(scan->packets.size()));
  EXPECT_FALSE(m->klv->bad_checksums_used);
  for (const mission::FrameRecord& f : m->frames) {
    if (f.utc_us) {
      EXPECT_GE(static_cast<uint64_t>(*f.utc_us), original->UtcSpan()->first_us) << f.index;
      EXPECT_LE(static_cast<uint64_t>(*f.utc_us), original->UtcSpan()->last_us) << f.index;
    }
    if (f.sensor) {
      EXPECT_NEAR(f.sensor->latitude_deg, 51.152, 0.01) << f.index;
    }
  }
}

// --- The antimeridian ------------------------------------------------------------------------

// Where the truth puts image pixel `pixel` of frame `frame` on the ground (map metres).
Eigen::Vector2d GroundOfPixel(const sim::FrameTruth& frame, const Eigen::Vector2d& pixel) {
  const Eigen::Vector3d g = frame.frame_from_ground.inverse() * pixel.homogeneous();
  return g.hnormalized();
}

// A flight over the antimeridian at 51.15 N, its first footprint straddling it: the map origin
// is where the flight is (not at longitude 0, the plain mean of 179.9998 and -179.9998), and the
// exported tracks lie on the simulated targets, longitudes in [-180, 180] and continuous.
TEST_F(HostileInputTest, FlightAcrossTheAntimeridianIsExportedWhereItFlew) {
  sim::SimulationOptions sim_options = TinyOptions(*dir_ / "antimeridian.ts", 4);
  sim_options.origin = {51.15, 179.9999, 100.0};
  ASSERT_TRUE(sim::Simulate(sim_options).ok());
  const StatusOr<sim::Truth> truth = sim::ReadTruth(sim_options.TruthPath());
  ASSERT_TRUE(truth.ok()) << truth.status().ToString();
  const StatusOr<geo::LocalTangentPlane> truth_plane = geo::LocalTangentPlane::Create(
      {truth->origin_latitude_deg, truth->origin_longitude_deg, truth->origin_height_m});
  ASSERT_TRUE(truth_plane.ok());
  // The test is about a footprint across the antimeridian: check that the first one is.
  int east = 0, west = 0;
  for (const Eigen::Vector2d& corner : {Eigen::Vector2d(0, 0), Eigen::Vector2d(319, 0),
                                        Eigen::Vector2d(319, 179), Eigen::Vector2d(0, 179)}) {
    const geo::Wgs84 p = truth_plane->LatLonFromMap(GroundOfPixel(truth->frames[0], corner));
    (p.longitude_deg > 0 ? east : west) += 1;
  }
  ASSERT_TRUE(east > 0 && west > 0) << "the first footprint does not straddle the antimeridian";

  const StatusOr<mission::Mission> m =
      ProcessAndLoad(sim_options.output, *dir_ / "antimeridian.saker");
  ASSERT_TRUE(m.ok()) << m.status().ToString();
  ASSERT_TRUE(m->map.geo_referenced && m->map.origin);
  EXPECT_LE(std::abs(m->map.origin->longitude_deg), 180.0);
  EXPECT_LT(
      truth_plane->MapFromLatLon(m->map.origin->latitude_deg, m->map.origin->longitude_deg).norm(),
      50.0)
      << "map origin " << m->map.origin->latitude_deg << ", " << m->map.origin->longitude_deg;

  const fs::path geojson = *dir_ / "antimeridian.geojson";
  ASSERT_TRUE(exporting::ExportGeoJson(*m, geojson.string()).ok());
  std::ifstream in(geojson);
  const nlohmann::json tracks = nlohmann::json::parse(in);
  ASSERT_FALSE(tracks["features"].empty()) << "no track to check";
  int points = 0;
  for (const nlohmann::json& feature : tracks["features"]) {
    nlohmann::json coordinates = feature["geometry"]["coordinates"];
    if (feature["geometry"]["type"] == "Point") coordinates = nlohmann::json::array({coordinates});
    const nlohmann::json& observed = feature["properties"]["points"];
    ASSERT_EQ(coordinates.size(), observed.size());
    for (size_t i = 0; i < coordinates.size(); ++i) {
      const double lon = coordinates[i][0], lat = coordinates[i][1];
      EXPECT_LE(std::abs(lon), 180.0);
      if (i > 0) {
        const double step = std::remainder(lon - coordinates[i - 1][0].get<double>(), 360.0);
        EXPECT_LT(std::abs(step), 1e-3) << "a jump along track " << feature["id"];
      }
      // On a simulated target (the nearest one in that frame).
      const size_t frame = observed[i]["frame"].get<size_t>();
      const Eigen::Vector2d at = truth_plane->MapFromLatLon(lat, lon);
      double nearest = 1e300;
      for (const sim::TargetTruth& target : truth->targets) {
        nearest = std::min(nearest, (target.samples[frame].ground_m - at).norm());
      }
      EXPECT_LT(nearest, 6.0) << "track " << feature["id"] << " at frame " << frame << ": " << lat
                              << ", " << lon;
      ++points;
    }
  }
  EXPECT_GT(points, 10);
}

}  // namespace
}  // namespace saker::pipeline
