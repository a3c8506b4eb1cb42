// libFuzzer harness for video + KLV ingest on an in-memory file (core/video, core/ingest): the
// input is a whole video file (seeded with MPEG-TS) that goes through ScanVideoMemory, i.e.
// FFmpeg demux and decode behind VideoReader::OpenMemory, the PMT reader, KLV framing and
// decoding of every data packet, the frame/metadata alignment and the probe and KLV dump
// reports; then random access (VideoReader::ReadFrame) on a second reader of the same bytes.
//
// Work per input is bounded: at most kMaxFrames frames are scanned, pictures larger than
// kMaxPixels are refused, and the decoder runs on one thread.

#include "core/ingest/report.h"
#include "core/ingest/video_scan.h"
#include "core/video/video_reader.h"

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <vector>

namespace {

using namespace saker;

constexpr int64_t kMaxFrames = 48;
constexpr int64_t kMaxPixels = 1280 * 720;
constexpr size_t kDumpPackets = 6;

[[noreturn]] void Fail(const char* what) {
  std::fprintf(stderr, "fuzz_ingest: broken promise: %s\n", what);
  std::abort();
}

video::ReaderOptions FuzzReaderOptions(bool pixels) {
  video::ReaderOptions options;
  options.want_bgr = pixels;
  options.want_grey = pixels;
  options.decoder_threads = 1;
  options.max_pixels = kMaxPixels;
  return options;
}

void CheckScan(const ingest::VideoScan& scan) {
  if (static_cast<int64_t>(scan.frames.size()) > kMaxFrames) Fail("max_frames not honoured");
  for (size_t i = 0; i < scan.frames.size(); ++i) {
    const ingest::FrameRecord& frame = scan.frames[i];
    if (frame.index != static_cast<video::FrameIndex>(i)) Fail("frame indices not 0..n-1");
    if (!std::isfinite(frame.time_s)) Fail("frame time not finite");
    if (i > 0 && !(frame.time_s > scan.frames[i - 1].time_s)) Fail("frame times not increasing");
    if (frame.metadata.packet && *frame.metadata.packet >= scan.packets.size()) {
      Fail("frame tied to a packet that does not exist");
    }
    (void)scan.MetadataOf(i);
  }
  (void)scan.FramesWithMetadata();
  (void)scan.FramesWithCorners();
  (void)scan.UtcSpan();
  // The reports must not throw (invalid UTF-8 in KLV text, odd numbers). The KLV dump of a long
  // scan (every tag of every packet) cost most of the time per input while each packet goes
  // through the same code, so it is made of the first kDumpPackets packets: a consistent
  // smaller scan, the frames tied to later packets left without metadata.
  (void)ingest::ProbeToJson(scan).dump();
  (void)ingest::ProbeToText(scan);
  if (scan.packets.size() <= kDumpPackets) {
    (void)ingest::KlvDumpToJson(scan).dump();
    (void)ingest::KlvDumpToText(scan);
  } else {
    ingest::VideoScan prefix = scan;
    prefix.packets.resize(kDumpPackets);
    for (ingest::FrameRecord& frame : prefix.frames) {
      if (frame.metadata.packet && *frame.metadata.packet >= kDumpPackets) {
        frame.metadata = ingest::FrameMatch{};
      }
    }
    (void)ingest::KlvDumpToJson(prefix).dump();
    (void)ingest::KlvDumpToText(prefix);
  }
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  video::SetFfmpegLogVerbose(false);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::vector<uint8_t> bytes(data, data + size);

  ingest::ScanOptions options;
  options.reader = FuzzReaderOptions(/*pixels=*/true);
  options.max_frames = kMaxFrames;
  int64_t frames_seen = 0;
  auto scan =
      ingest::ScanVideoMemory(bytes, "fuzz.ts", options, nullptr, [&](const video::Frame& frame) {
        ++frames_seen;
        if (frame.bgr.empty() || frame.grey.empty()) {
          Fail("a frame came without its pixels");
        }
      });
  if (!scan.ok()) {
    if (scan.status().message().empty()) Fail("error without a message");
    return 0;
  }
  CheckScan(*scan);
  if (frames_seen != static_cast<int64_t>(scan->frames.size())) Fail("callback count differs");

  // Random access on its own reader: indexes the file (no pixels), seeks, decodes one frame.
  if (scan->frames.size() >= 2) {
    auto reader = video::VideoReader::OpenMemory(bytes, "fuzz.ts", FuzzReaderOptions(false));
    if (reader.ok()) {
      const auto target = static_cast<video::FrameIndex>(scan->frames.size() / 2);
      auto frame = (*reader)->ReadFrame(target);
      if (frame.ok() && frame->index != target) Fail("ReadFrame returned another frame");
      (void)(*reader)->ReadFrame(-1);
    }
  }
  return 0;
}
