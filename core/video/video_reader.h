#pragma once

// Video ingest: demuxes and decodes any FFmpeg-readable file or URL (MPEG-TS, MPG, MP4; H.264,
// H.265, MPEG-2, ...) into frames in presentation order, and hands out the KLV data packets met
// on the way in the same pass. FFmpeg stays behind a pimpl: nothing here includes it.
//
// Threads: a VideoReader is used by one thread at a time (it holds demuxer and decoder state and
// its calls are not synchronised). Separate readers, even on the same file, may run on separate
// threads concurrently; use OpenWithIndex() to give a second thread its own reader cheaply.

#include "core/util/status.h"
#include "core/util/yuv_coding.h"

#include <opencv2/core/mat.hpp>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace saker::video {

using FrameIndex = int64_t;  // 0-based, in presentation order

enum class StreamKind { kVideo, kAudio, kKlv, kOtherData, kOther };
// "video", "audio", "klv", "data", "other".
const char* StreamKindName(StreamKind kind);

// One elementary stream of the container, as FFmpeg sees it.
struct StreamInfo {
  int index = -1;  // FFmpeg stream index
  StreamKind kind = StreamKind::kOther;
  std::string codec_name;  // "h264", "hevc", "mpeg2video", "klv", ...
  int pid = -1;            // MPEG-TS PID when known (AVStream::id), else -1
  // True for a synchronous KLV stream (MISB ST 1402: PMT stream_type 0x15, metadata access
  // units). FFmpeg 5.1 leaves the KLV profile at FF_PROFILE_UNKNOWN when reading, so besides the
  // profile (FF_PROFILE_KLVA_SYNC, honoured when a future FFmpeg sets it) the reader looks up the
  // stream_type of the PID in the transport stream's program map table (local MPEG-TS files).
  bool klv_synchronous = false;
};

// What the container declares, read once at Open().
struct VideoInfo {
  std::string path;                     // as given
  std::string container;                // format short name, e.g. "mpegts"
  std::string container_long;           // e.g. "MPEG-TS (MPEG-2 Transport Stream)"
  int video_stream = -1;                // FFmpeg index of the decoded video stream
  std::string video_codec;              // "h264", "hevc", "mpeg2video", ...
  int width = 0, height = 0;            // coded picture size in pixels
  double fps = 0;                       // average frame rate (avg_frame_rate, else r_frame_rate)
  double duration_s = 0;                // container duration, 0 when unknown
  int64_t declared_frame_count = 0;     // nb_frames, 0 when unknown
  double start_time_s = 0;              // video stream start time; frame times are relative to it
  std::vector<StreamInfo> streams;      // every stream of the container, by FFmpeg index
  std::vector<int> KlvStreams() const;  // indices of KLV streams
};

// One decoded picture.
struct Frame {
  FrameIndex index = 0;
  double time_s = 0;  // presentation time in seconds from the video stream start (first frame = 0
                      // for typical files); strictly increasing over the pass
  int64_t pts = 0;    // in the video stream time base: the frame's pts, else FFmpeg's best
                      // effort timestamp; a missing or non-increasing one is extrapolated by 1/fps
                      // so the sequence is strictly increasing
  bool key_frame = false;
  int64_t byte_pos = -1;  // byte offset in the file of the packet that carried this frame, -1 when
                          // unknown; used to place KLV packets that have no timestamp
  cv::Mat bgr;            // CV_8UC3, continuous, empty when not requested
  cv::Mat grey;  // CV_8UC1, continuous, empty when not requested. For 8-bit YUV video this is the
                 // luma plane as coded (usually limited range 16-235), not a BGR->grey conversion
  // With ReaderOptions::want_chroma, for 8-bit YUV video: its two chroma planes as coded, Cb and
  // Cr interleaved (CV_8UC2, continuous) at the chroma's own resolution (half the width and
  // height for 4:2:0), and how they code colour with `grey`. Empty for other pixel formats (RGB,
  // palette, more than 8 bits) and when not requested.
  cv::Mat chroma;
  YuvCoding coding;
};

// A demuxed packet of a KLV (data) stream, bytes exactly as the demuxer gives them.
struct DataPacket {
  int stream_index = -1;
  double time_s = 0;      // same clock as Frame::time_s (relative to the video start); NaN when the
                          // packet has no timestamp (asynchronous KLV often has none)
  int64_t pts = 0;        // in that stream's time base (AV_NOPTS_VALUE mapped to INT64_MIN)
  int64_t byte_pos = -1;  // byte offset of the packet in the file, -1 when unknown
  std::vector<uint8_t> bytes;
};

struct ReaderOptions {
  bool want_bgr = true;      // convert decoded frames to BGR (Frame::bgr)
  bool want_grey = false;    // also (or only) give an 8-bit grey image (Frame::grey); with neither,
                             // frames carry only index and time (fast scans)
  bool want_chroma = false;  // with want_grey: also the chroma planes (Frame::chroma), a copy of
                             // half the luma's bytes for 4:2:0 video, no conversion
  int decoder_threads = 0;   // 0 = FFmpeg chooses (one per core); at most 64
  // Largest picture (width x height) accepted, declared or decoded: a larger one is refused
  // with an error naming the file before any picture of that size is allocated (FFmpeg's
  // decoder checks it too). 8192 x 8192 admits 8K video; a hostile header can otherwise make
  // FFmpeg allocate about 400 MB per picture (docs/reliability.md, "Hostile inputs").
  int64_t max_pixels = 8192LL * 8192;
  Status Validate() const;
};

// Counters of the current sequential pass (reset by Rewind()); random access does not count.
struct ReadStats {
  int64_t frames_decoded = 0;   // frames output by the decoder
  int64_t corrupt_packets = 0;  // packets the demuxer flagged corrupt (skipped) or could not read
  int64_t decode_errors = 0;    // packets the decoder rejected, frames it flagged as damaged
  int64_t data_packets = 0;     // KLV packets handed out
  // Times the video's timestamps jumped back by more than a second (a spliced or restarted
  // recording). The pass carries on one frame interval after the latest picture, and the KLV
  // packets of the new part are shifted with it, so they stay beside their pictures.
  int64_t timestamp_discontinuities = 0;
};

struct FrameIndexEntry {
  FrameIndex index;
  int64_t pts;  // as Frame::pts
  double time_s;
  bool key_frame;
};

class VideoReader {
 public:
  // Opens the container and the video decoder. Errors name the file: NotFound (missing file),
  // InvalidData (empty, unrecognised, no video stream, absurd size), Unsupported (no decoder).
  static StatusOr<std::unique_ptr<VideoReader>> Open(const std::string& path_or_url,
                                                     const ReaderOptions& options = {});
  // Opens a video file held in memory (the whole file: MPEG-TS, MP4, ...), read through an FFmpeg
  // custom I/O context instead of a file. `name` stands for the path in VideoInfo::path and in
  // every message (and its extension, if any, is a hint for the container format). The reader
  // keeps the bytes for random access and Rewind(). Same errors as Open(); empty bytes are
  // InvalidData. Everything else, byte_pos included (offsets into `bytes`), is as for a file.
  static StatusOr<std::unique_ptr<VideoReader>> OpenMemory(std::vector<uint8_t> bytes,
                                                           const std::string& name,
                                                           const ReaderOptions& options = {});
  ~VideoReader();
  VideoReader(const VideoReader&) = delete;
  VideoReader& operator=(const VideoReader&) = delete;

  const VideoInfo& info() const;
  const ReaderOptions& options() const;  // as opened

  // Sequential pass. Decodes the next frame in presentation order; every KLV data packet the
  // demuxer meets before that frame is output is appended to *data (may be null; same pass, no
  // second read). Returns true when a frame was produced, false at end of stream (after draining
  // the decoder; remaining data packets are still appended). Corrupt packets mid-stream are
  // skipped and counted, not fatal; only an unrecoverable error returns a Status.
  StatusOr<bool> ReadNext(Frame* frame, std::vector<DataPacket>* data);
  const ReadStats& stats() const;

  // The frame index built during the sequential pass (complete once ReadNext returned false, or
  // once random access has built it).
  const std::vector<FrameIndexEntry>& frame_index() const;
  bool frame_index_complete() const;

  // Random access, on a second demuxer/decoder of its own so it never disturbs the sequential
  // pass: seeks to the key frame at or before the target, flushes the decoder and decodes
  // forward (a recall inside the GOP just decoded continues without seeking). Frame N is
  // bit-identical to the N-th frame of the sequential pass. Out of range -> OutOfRange naming the
  // valid range.
  // Cost: if the index is not complete yet, the first call builds it by decoding the whole file
  // once without pixel conversion (about the time of a plain FFmpeg decode of the file).
  StatusOr<Frame> ReadFrame(FrameIndex index);
  // The frame whose time is nearest to time_s (ties go to the earlier frame); OutOfRange when
  // time_s lies more than one frame interval outside the first..last frame times.
  StatusOr<Frame> ReadFrameAtTime(double time_s);

  // Restarts the sequential pass from the beginning (reopens the input; keeps the frame index).
  Status Rewind();

 private:
  friend StatusOr<std::unique_ptr<VideoReader>> OpenWithIndex(const std::string&,
                                                              std::vector<FrameIndexEntry>,
                                                              const ReaderOptions&);
  struct Impl;
  explicit VideoReader(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

// Opens a second reader for random access on the same file, reusing an existing complete index
// (so the GUI's recall does not rescan). The index must be the one a reader produced for this
// file: entries numbered 0..n-1 with strictly increasing pts (InvalidArgument otherwise).
StatusOr<std::unique_ptr<VideoReader>> OpenWithIndex(const std::string& path,
                                                     std::vector<FrameIndexEntry> index,
                                                     const ReaderOptions& options = {});

// FFmpeg prints its own diagnostics to stderr (damaged macroblocks, missing
// start times). Saker counts damage itself and reports it with file names, so
// by default that output is off; `verbose` turns FFmpeg's warnings back on for
// troubleshooting. Process-wide, since FFmpeg's log level is.
void SetFfmpegLogVerbose(bool verbose);

// How many times this process has opened a video input, failed attempts included: the
// sequential pass of every Open, OpenMemory, OpenWithIndex and Rewind, and each reader's
// random-access pass when first used. For tests that check how often a job opens its video.
int64_t InputsOpened();

}  // namespace saker::video
