// saker-bench-ingest: how fast VideoReader ingests a video compared with a bare FFmpeg decode
// loop, and how long a random-access recall takes.
//
//   saker-bench-ingest [FILE] [--repeat N] [--recalls N] [--threads N] [--synthetic] [--json]
//
// FILE defaults to $SAKER_TEST_DATA/kwiver/aphill_short.ts (or the shared data folder beside the
// source tree), else a synthetic 640x480 MPEG-2 stream written to a temp dir. Throughput figures
// are the median over --repeat runs of a full pass (open included); the ratio is ours / baseline.

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
}

#include "core/util/statistics.h"
#include "core/util/timer.h"
#include "core/video/video_reader.h"
#include "tests/core/video/synthetic_ts.h"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <random>
#include <string>
#include <vector>

namespace {

namespace fs = std::filesystem;
using saker::Median;
using saker::Quantile;
using saker::Status;
using saker::StatusOr;
using saker::Stopwatch;

struct Throughput {
  int64_t frames = 0;
  double seconds = 0;
  double fps() const { return seconds > 0 ? static_cast<double>(frames) / seconds : 0; }
};

// The baseline: demux + avcodec decode of the video stream, nothing else (no pixel conversion,
// no KLV, no timestamps bookkeeping).
StatusOr<Throughput> PlainFfmpegDecode(const std::string& path, int threads) {
  const Stopwatch start;
  AVFormatContext* format = nullptr;
  if (avformat_open_input(&format, path.c_str(), nullptr, nullptr) < 0) {
    return saker::IoError(path + ": FFmpeg cannot open it");
  }
  Throughput result;
  AVCodecContext* decoder = nullptr;
  AVPacket* packet = av_packet_alloc();
  AVFrame* frame = av_frame_alloc();
  const AVCodec* codec = nullptr;
  int video = -1;
  if (avformat_find_stream_info(format, nullptr) >= 0) {
    video = av_find_best_stream(format, AVMEDIA_TYPE_VIDEO, -1, -1, &codec, 0);
  }
  if (video >= 0) {
    decoder = avcodec_alloc_context3(codec);
    avcodec_parameters_to_context(decoder, format->streams[video]->codecpar);
    decoder->thread_count = threads;
    if (avcodec_open2(decoder, codec, nullptr) < 0) video = -1;
  }
  if (video >= 0) {
    auto drain = [&] {
      while (avcodec_receive_frame(decoder, frame) >= 0) ++result.frames;
    };
    while (av_read_frame(format, packet) >= 0) {
      if (packet->stream_index == video) {
        avcodec_send_packet(decoder, packet);
        drain();
      }
      av_packet_unref(packet);
    }
    avcodec_send_packet(decoder, nullptr);
    drain();
  }
  av_frame_free(&frame);
  av_packet_free(&packet);
  avcodec_free_context(&decoder);
  avformat_close_input(&format);
  if (video < 0) return saker::InvalidDataError(path + ": no decodable video stream");
  result.seconds = start.ElapsedSeconds();
  return result;
}

// Our sequential pass with KLV collection, as the ingest stage runs it.
StatusOr<Throughput> ReaderPass(const std::string& path,
                                const saker::video::ReaderOptions& options) {
  const Stopwatch start;
  auto reader = saker::video::VideoReader::Open(path, options);
  if (!reader.ok()) return reader.status();
  Throughput result;
  saker::video::Frame frame;
  std::vector<saker::video::DataPacket> data;
  while (true) {
    data.clear();
    auto more = (*reader)->ReadNext(&frame, &data);
    if (!more.ok()) return more.status();
    if (!*more) break;
    ++result.frames;
  }
  result.seconds = start.ElapsedSeconds();
  return result;
}

struct Series {
  std::string name;
  std::vector<double> fps;
  int64_t frames = 0;
};

template <typename Run>
Status RunOnce(Series* series, Run run) {
  auto result = run();
  if (!result.ok()) return result.status();
  series->fps.push_back(result->fps());
  series->frames = result->frames;
  return Status::Ok();
}

std::string DefaultFile() {
  std::vector<fs::path> candidates;
  if (const char* env = std::getenv("SAKER_TEST_DATA"); env != nullptr && *env != '\0') {
    candidates.push_back(fs::path(env) / "kwiver/aphill_short.ts");
  }
  candidates.push_back(fs::path(SAKER_DEFAULT_TEST_DATA_DIR) / "kwiver/aphill_short.ts");
  for (const fs::path& candidate : candidates) {
    if (fs::is_regular_file(candidate)) return candidate.string();
  }
  return {};
}

// Removes the synthetic file's folder when main returns.
struct TempDir {
  fs::path path;
  ~TempDir() {
    std::error_code ignored;
    if (!path.empty()) fs::remove_all(path, ignored);
  }
};

StatusOr<std::string> WriteSyntheticFile(TempDir* dir_guard) {
  const fs::path dir = fs::temp_directory_path() / ("saker-bench-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  dir_guard->path = dir;
  const fs::path path = dir / "synthetic_640x480.ts";
  saker::testing::SyntheticTsOptions options;
  options.width = 640;
  options.height = 480;
  options.frames = 300;
  options.gop_size = 30;
  SAKER_RETURN_IF_ERROR(saker::testing::WriteSyntheticTs(path, options));
  return path.string();
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Ingest benchmark: VideoReader against a bare FFmpeg decode loop"};
  std::string file;
  int repeat = 5;
  int recalls = 200;
  int threads = 0;
  bool json = false;
  app.add_option("file", file, "video file (default: kwiver/aphill_short.ts, else synthetic)");
  app.add_option("--repeat", repeat, "full passes per figure; the median is reported")
      ->check(CLI::Range(1, 1000));
  app.add_option("--recalls", recalls, "random-access recalls to time")
      ->check(CLI::Range(1, 100000));
  app.add_option("--threads", threads, "decoder threads for both (0 = FFmpeg chooses)")
      ->check(CLI::Range(0, 64));
  bool force_synthetic = false;
  app.add_flag("--json", json, "print one JSON object instead of text");
  app.add_flag("--synthetic", force_synthetic,
               "use the synthetic 640x480 stream even if data exists");
  CLI11_PARSE(app, argc, argv);

  av_log_set_level(AV_LOG_ERROR);  // keep FFmpeg's chatter out of the figures
  bool synthetic = false;
  TempDir synthetic_dir;
  if (file.empty() && !force_synthetic) file = DefaultFile();
  if (file.empty()) {
    auto written = WriteSyntheticFile(&synthetic_dir);
    if (!written.ok()) {
      std::cerr << written.status().ToString() << "\n";
      return 1;
    }
    file = *written;
    synthetic = true;
  }

  saker::video::ReaderOptions probe_options;
  probe_options.want_bgr = false;
  auto probe = saker::video::VideoReader::Open(file, probe_options);
  if (!probe.ok()) {
    std::cerr << probe.status().ToString() << "\n";
    return 1;
  }
  const saker::video::VideoInfo info = (*probe)->info();
  probe->reset();

  // (1)-(3) Throughput.
  saker::video::ReaderOptions bgr;
  bgr.decoder_threads = threads;
  saker::video::ReaderOptions grey;
  grey.want_bgr = false;
  grey.want_grey = true;
  grey.decoder_threads = threads;
  saker::video::ReaderOptions none;
  none.want_bgr = false;
  none.decoder_threads = threads;
  Series baseline{"ffmpeg decode only (baseline)", {}, 0};
  Series ours_bgr{"VideoReader BGR", {}, 0};
  Series ours_grey{"VideoReader grey only", {}, 0};
  Series ours_none{"VideoReader no conversion", {}, 0};
  // Rounds interleave the four passes, so a busy machine slows them alike.
  Status status;
  for (int round = 0; round < repeat && status.ok(); ++round) {
    status = RunOnce(&baseline, [&] { return PlainFfmpegDecode(file, threads); });
    if (status.ok()) status = RunOnce(&ours_bgr, [&] { return ReaderPass(file, bgr); });
    if (status.ok()) status = RunOnce(&ours_grey, [&] { return ReaderPass(file, grey); });
    if (status.ok()) status = RunOnce(&ours_none, [&] { return ReaderPass(file, none); });
  }
  if (!status.ok()) {
    std::cerr << status.ToString() << "\n";
    return 1;
  }

  // (4) Random-access recall: index build on a fresh reader, then timed recalls.
  auto reader = saker::video::VideoReader::Open(file, bgr);
  if (!reader.ok()) {
    std::cerr << reader.status().ToString() << "\n";
    return 1;
  }
  const Stopwatch index_start;
  auto first = (*reader)->ReadFrame(0);  // builds the index (decode-only pass)
  const double index_ms = index_start.ElapsedSeconds() * 1e3;
  if (!first.ok()) {
    std::cerr << first.status().ToString() << "\n";
    return 1;
  }
  const auto frame_count = static_cast<int64_t>((*reader)->frame_index().size());
  std::mt19937_64 random(20240611);
  std::uniform_int_distribution<int64_t> pick(0, frame_count - 1);
  std::vector<double> latencies_ms;
  for (int i = 0; i < recalls; ++i) {
    const int64_t n = pick(random);
    const Stopwatch start;
    auto frame = (*reader)->ReadFrame(n);
    latencies_ms.push_back(start.ElapsedSeconds() * 1e3);
    if (!frame.ok()) {
      std::cerr << frame.status().ToString() << "\n";
      return 1;
    }
  }

  const double base_fps = Median(baseline.fps);
  auto ratio = [&](const Series& s) { return base_fps > 0 ? Median(s.fps) / base_fps : 0; };
  if (json) {
    nlohmann::json out;
    out["file"] = file;
    out["synthetic"] = synthetic;
    out["video"] = {{"codec", info.video_codec},
                    {"width", info.width},
                    {"height", info.height},
                    {"frames", baseline.frames}};
    out["repeat"] = repeat;
    out["decoder_threads"] = threads;
    for (const Series* s : {&baseline, &ours_bgr, &ours_grey, &ours_none}) {
      out["throughput"].push_back({{"name", s->name},
                                   {"frames", s->frames},
                                   {"median_fps", Median(s->fps)},
                                   {"runs_fps", s->fps},
                                   {"ratio_to_baseline", ratio(*s)}});
    }
    out["random_access"] = {
        {"recalls", recalls},
        {"index_build_ms", index_ms},
        {"median_ms", Median(latencies_ms)},
        {"p95_ms", Quantile(latencies_ms, 0.95)},
        {"worst_ms", *std::max_element(latencies_ms.begin(), latencies_ms.end())}};
    std::cout << out.dump(2) << "\n";
    return 0;
  }

  std::printf("file     %s%s\n", file.c_str(), synthetic ? " (synthetic)" : "");
  std::printf("video    %s %dx%d, %lld frames; decoder threads %s; median of %d runs\n\n",
              info.video_codec.c_str(), info.width, info.height,
              static_cast<long long>(baseline.frames),
              threads == 0 ? "auto" : std::to_string(threads).c_str(), repeat);
  std::printf("%-32s %12s %10s\n", "sequential pass", "frames/s", "vs base");
  for (const Series* s : {&baseline, &ours_bgr, &ours_grey, &ours_none}) {
    std::printf("%-32s %12.1f %9.2fx\n", s->name.c_str(), Median(s->fps), ratio(*s));
  }
  std::printf("\nrandom access (ReadFrame, BGR) over %d random frames of %lld:\n", recalls,
              static_cast<long long>(frame_count));
  std::printf("  index build on first call  %8.2f ms\n", index_ms);
  std::printf("  median                     %8.2f ms\n", Median(latencies_ms));
  std::printf("  95th percentile            %8.2f ms\n", Quantile(latencies_ms, 0.95));
  std::printf("  worst                      %8.2f ms\n",
              *std::max_element(latencies_ms.begin(), latencies_ms.end()));
  return 0;
}
