#pragma once

// INTERNAL to saker_video: includes FFmpeg. Never include from a public header.
//
// A DecodeSession is one opened container plus one opened video decoder: the building block of
// VideoReader, which keeps one session for the sequential pass and a second one for random
// access. FrameConverter turns decoded pictures into cv::Mat.

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <libavutil/frame.h>
#include <libswscale/swscale.h>
}

#include "core/util/status.h"
#include "core/video/video_reader.h"

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace saker::video::internal {

// av_strerror text, never empty.
std::string AvErrorText(int error);

struct FormatCloser {
  void operator()(AVFormatContext* context) const { avformat_close_input(&context); }
};
struct CodecContextFreer {
  void operator()(AVCodecContext* context) const { avcodec_free_context(&context); }
};
struct PacketFreer {
  void operator()(AVPacket* packet) const { av_packet_free(&packet); }
};
struct FrameFreer {
  void operator()(AVFrame* frame) const { av_frame_free(&frame); }
};

struct IoContextFreer {
  void operator()(AVIOContext* context) const {
    if (context != nullptr) av_freep(&context->buffer);
    avio_context_free(&context);
  }
};

// The read position in an in-memory input, for the AVIOContext callbacks.
struct MemoryCursor {
  std::shared_ptr<const std::vector<uint8_t>> bytes;
  int64_t position = 0;
};

struct SessionConfig {
  // When set, the container is read from these bytes (VideoReader::OpenMemory) through a custom
  // AVIOContext, and the session's path is only the name used in messages.
  std::shared_ptr<const std::vector<uint8_t>> memory;
  bool keep_klv = true;        // demux KLV streams and hand them out (sequential pass only)
  bool probe_klv_sync = true;  // read the MPEG-TS PMT to tell synchronous KLV streams
  int decoder_threads = 0;     // AVCodecContext::thread_count
  int64_t max_pixels = 0;      // refuse larger pictures
  // Sequential pass: when the video's timestamps jump back (a spliced or restarted recording),
  // shift every later packet so the pictures carry on and the KLV stays beside them.
  bool join_discontinuities = false;
};

class DecodeSession {
 public:
  static StatusOr<std::unique_ptr<DecodeSession>> Open(const std::string& path,
                                                       const SessionConfig& config);
  ~DecodeSession();
  DecodeSession(const DecodeSession&) = delete;
  DecodeSession& operator=(const DecodeSession&) = delete;

  const VideoInfo& info() const { return info_; }
  AVRational video_time_base() const { return video_->time_base; }
  // The origin of Frame::time_s, in the video time base.
  int64_t start_pts() const { return start_pts_; }
  // Nominal frame interval in the video time base (>= 1), for extrapolating missing timestamps.
  int64_t frame_step() const { return frame_step_; }
  double SecondsFromStart(int64_t pts) const;

  // Decodes the next frame in output (presentation) order into frame(). KLV packets met on the
  // way are appended to *data when non-null. Counts into *stats when non-null. False at the end.
  StatusOr<bool> DecodeNext(std::vector<DataPacket>* data, ReadStats* stats);
  const AVFrame& frame() const { return *frame_; }
  // The frame's own timestamp: pts, else best effort; AV_NOPTS_VALUE when it has neither.
  int64_t RawTimestamp() const;

  // av_seek_frame(AVSEEK_FLAG_BACKWARD) on the video stream, then flushes the decoder; video
  // packets before the next key packet are dropped (they would only decode to garbage).
  Status SeekBackward(int64_t pts);

 private:
  DecodeSession() = default;
  Status OpenImpl(const std::string& path, const SessionConfig& config);
  // The steps of OpenImpl, in order. The container opened and its stream layout probed (within
  // max_pixels), what it declares in info_.
  Status OpenContainer();
  // The video stream to decode and its decoder (`codec`): refused when there is none, it is a
  // still picture or its picture size is invalid or beyond max_pixels; its size, rate, frame count
  // and time origin in info_.
  Status FindVideoStream(const AVCodec** codec);
  // Every stream in info_.streams, KLV streams marked and told synchronous or not; the demuxer
  // discards all but the video and (keep_klv) the KLV streams.
  void DescribeStreams();
  Status OpenDecoder(const AVCodec* codec);
  // avformat_open_input on the file or URL, or on config_.memory.
  int OpenInput(AVFormatContext** format);

  // `offset` (video time base) is added to the packet's timestamp.
  void AppendDataPacket(const AVPacket& packet, int64_t offset,
                        std::vector<DataPacket>* data) const;
  // A packet's pts (else dts) in the video time base, AV_NOPTS_VALUE when it has neither.
  int64_t VideoTicks(const AVPacket& packet) const;
  // Timestamp discontinuities (config_.join_discontinuities): KLV packets wait for the next
  // video packet, which tells whether the timestamps jumped back; then each gets the offset of
  // the recording it is nearest to in raw time.
  void HoldDataPacket(const AVPacket& packet);
  void ReleaseHeldData(int64_t old_offset, int64_t new_offset, int64_t old_last_raw,
                       int64_t new_first_raw, std::vector<DataPacket>* data, ReadStats* stats);
  // Detects a jump back of the video packet's timestamp, updates offset_, releases the held KLV
  // and shifts the packet's pts and dts by offset_.
  void JoinDiscontinuity(AVPacket* packet, std::vector<DataPacket>* data, ReadStats* stats);

  std::string path_;
  SessionConfig config_;
  VideoInfo info_;
  // Declared before format_ so they outlive it: FFmpeg reads through them until it is closed.
  std::unique_ptr<MemoryCursor> memory_cursor_;
  std::unique_ptr<AVIOContext, IoContextFreer> io_;
  std::unique_ptr<AVFormatContext, FormatCloser> format_;
  std::unique_ptr<AVCodecContext, CodecContextFreer> decoder_;
  std::unique_ptr<AVPacket, PacketFreer> packet_;
  std::unique_ptr<AVPacket, PacketFreer> pending_;  // a packet the decoder could not take yet
  bool has_pending_ = false;
  std::unique_ptr<AVFrame, FrameFreer> frame_;
  AVStream* video_ = nullptr;
  std::vector<bool> is_klv_;  // by stream index
  int64_t start_pts_ = 0;
  int64_t frame_step_ = 1;
  bool demux_finished_ = false;       // flush packet sent to the decoder
  bool awaiting_key_packet_ = false;  // after a seek: drop video packets until a key packet
  Status deferred_error_;             // a fatal read error, reported once the decoder is drained
  // Timestamp discontinuities, all in the video time base.
  struct HeldPacket {
    std::unique_ptr<AVPacket, PacketFreer> packet;
    int64_t raw = 0;  // its timestamp before any offset, AV_NOPTS_VALUE when it has none
  };
  std::vector<HeldPacket> held_;  // KLV packets waiting for the next video packet
  int64_t offset_ = 0;            // added to every packet timestamp since the last jump back
  int64_t max_video_pts_ = AV_NOPTS_VALUE;   // latest video timestamp so far, offset included
  int64_t last_video_raw_ = AV_NOPTS_VALUE;  // raw timestamp of the latest video packet
};

// Converts decoded pictures to BGR and grey cv::Mat, caching the swscale contexts.
class FrameConverter {
 public:
  FrameConverter() = default;
  ~FrameConverter();
  FrameConverter(const FrameConverter&) = delete;
  FrameConverter& operator=(const FrameConverter&) = delete;

  // Fills *bgr / *grey (when non-null) with fresh, continuous matrices, and *chroma (when
  // non-null) with the chroma planes of 8-bit YUV pictures as Frame::chroma says (released for
  // other formats) and *coding with how they code colour.
  Status Convert(const AVFrame& frame, cv::Mat* bgr, cv::Mat* grey, cv::Mat* chroma = nullptr,
                 YuvCoding* coding = nullptr);

 private:
  struct Key {
    int width = 0, height = 0, format = -1, colorspace = -1, full_range = -1, target = -1;
    bool operator==(const Key&) const = default;
  };
  SwsContext* Context(const Key& key, SwsContext** context, Key* cached);

  SwsContext* bgr_context_ = nullptr;
  Key bgr_key_;
  SwsContext* grey_context_ = nullptr;
  Key grey_key_;
};

}  // namespace saker::video::internal
