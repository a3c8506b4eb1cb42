#pragma once

// Writes an MPEG transport stream: one video stream (H.264 through libx264, or MPEG-2) and,
// optionally, one KLV data stream (MISB ST 1402, asynchronous or synchronous). The files read
// back with VideoReader: frame n at time n * fps_den / fps_num from the video start, every KLV
// packet byte for byte at the time of the frame it was given for. FFmpeg stays behind a pimpl:
// nothing here includes it.
//
// Threads: a TsWriter is used by one thread at a time. Separate writers may run concurrently.
//
// Determinism: the same options and the same calls give byte-identical files with the same
// FFmpeg build. With H.264 that holds for a given `threads` value (libx264 is deterministic
// with frame threads, but its output depends on the thread count): threads = 0 (automatic)
// depends on the number of cores, so set threads explicitly for files that must match across
// machines.

#include "core/util/status.h"

#include <opencv2/core/mat.hpp>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <span>
#include <string>

namespace saker::video {

enum class VideoCodec { kH264, kMpeg2 };
// FFmpeg's codec name, as VideoInfo::video_codec reports it when reading: "h264", "mpeg2video".
const char* VideoCodecName(VideoCodec codec);

// Largest KLV payload per frame: the packets given for one frame share one PES packet.
inline constexpr size_t kMaxKlvBytesPerFrame = 65000;

struct TsWriterOptions {
  int width = 1280;  // pixels, 16..8192; even for H.264 (4:2:0 chroma)
  int height = 720;  // pixels, 16..8192; even for H.264
  int fps_num = 25;  // frame rate fps_num / fps_den (at most 1000 fps); frame n has the
  int fps_den = 1;   // time n * fps_den / fps_num seconds
  VideoCodec codec = VideoCodec::kH264;
  int gop_size = 25;  // key frame interval in frames (1 = intra only). H.264: an IDR frame
                      // exactly every gop_size frames (scene-cut detection is off)
  int b_frames = 0;   // B-frames between reference frames, 0..16 (frames are reordered, dts < pts)
  int crf = 23;       // H.264 quality: libx264 constant rate factor, 0 (lossless) .. 51 (worst)
  std::string x264_preset = "veryfast";  // H.264 speed: ultrafast .. placebo (libx264 presets)
  int mpeg2_qscale = 2;  // MPEG-2 quality: constant quantiser, 1 (best) .. 31 (worst)
  int threads = 0;       // encoder threads, 0 = automatic (see Determinism above), at most 64
  bool with_klv = true;  // add a KLV data stream (PID 0x101; video is PID 0x100)
  // PMT stream_type 0x15 (synchronous, metadata access units) instead of 0x06 (asynchronous,
  // registration "KLVA"). Synchronous packets get the 5-byte MISB ST 1402 metadata access unit
  // cell header in front, which FFmpeg 5.1's demuxer strips but its muxer does not add.
  bool klv_synchronous = false;
  // Error naming the first bad field (InvalidArgument), OK otherwise.
  Status Validate() const;
};

class TsWriter {
 public:
  // Creates (or truncates) the file and writes the stream headers. Errors name the file:
  // InvalidArgument (bad options, path is a directory), NotFound (the directory does not exist),
  // IoError (cannot create the file), Unsupported (no such encoder in this FFmpeg build).
  static StatusOr<std::unique_ptr<TsWriter>> Open(const std::filesystem::path& path,
                                                  const TsWriterOptions& options);
  // Finishes the file like Close() when it was not closed, ignoring errors (never throws).
  ~TsWriter();
  TsWriter(const TsWriter&) = delete;
  TsWriter& operator=(const TsWriter&) = delete;

  // Queues one KLV packet (the full key + length + value bytes; 1..kMaxKlvBytesPerFrame bytes)
  // stamped with the time of video frame `frame_index`: its PES carries that frame's PTS on the
  // 90 kHz clock. It goes into the file just before the first video packet (in decode order)
  // of a frame at or after `frame_index`; with b_frames = 0 that is right before the frame
  // itself. Call it before WriteFrame(frame_index) (a later call still works: the packet goes
  // out before the next video packet). Frame indices must not decrease from call to call;
  // several packets for the same frame are joined into one PES, which VideoReader returns as one
  // DataPacket holding them back to back (klv::SplitKlvPackets separates them). Errors:
  // InvalidArgument (no KLV stream, empty or too large, index negative, above 2^40 or
  // decreasing, the frame's KLV already in the file, writer closed), or the error that stopped
  // the writer.
  Status WriteKlv(std::span<const uint8_t> packet, int64_t frame_index);

  // Leaves `count` frame times without a picture, as an encoder that drops frames does: the next
  // frame's time stamp is that many frame intervals later. Frame indices of WriteKlv count frame
  // times, skipped ones included. InvalidArgument for a negative count or beyond 2^40.
  Status SkipFrames(int64_t count);

  // Encodes the next frame: without SkipFrames, frame n is the n-th call (time n * fps_den /
  // fps_num); each skipped frame time delays the frames after it by one interval. `image` is
  // exactly width x height, either CV_8UC3 BGR (converted to limited-range YUV 4:2:0 with the
  // BT.709 matrix from 720 lines up, else BT.601, and tagged so) or CV_8UC1, taken as the luma
  // plane as coded with neutral chroma (the convention of Frame::grey: VideoReader gives it back
  // as Frame::grey; values are video range, 16 black .. 235 white). Any row stride is fine.
  // A wrong size or type is InvalidArgument and leaves the writer usable; an encoder or write
  // failure (e.g. disk full) is IoError and stops the writer (later calls return it again).
  Status WriteFrame(const cv::Mat& image);

  // Flushes the encoder and the queued KLV packets, writes the trailer and closes the file.
  // Idempotent: later calls return the first call's result. After a failure the file is closed
  // as it stands (incomplete).
  Status Close();

  // Frames accepted by WriteFrame so far.
  int64_t frames_written() const;
  const TsWriterOptions& options() const;

 private:
  struct Impl;
  explicit TsWriter(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace saker::video
