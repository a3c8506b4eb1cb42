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

struct SessionConfig {
  bool keep_klv = true;        // demux KLV streams and hand them out (sequential pass only)
  bool probe_klv_sync = true;  // read the MPEG-TS PMT to tell synchronous KLV streams
  int decoder_threads = 0;     // AVCodecContext::thread_count
  int64_t max_pixels = 0;      // refuse larger pictures
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
  void AppendDataPacket(const AVPacket& packet, std::vector<DataPacket>* data) const;

  std::string path_;
  SessionConfig config_;
  VideoInfo info_;
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
};

// Converts decoded pictures to BGR and grey cv::Mat, caching the swscale contexts.
class FrameConverter {
 public:
  FrameConverter() = default;
  ~FrameConverter();
  FrameConverter(const FrameConverter&) = delete;
  FrameConverter& operator=(const FrameConverter&) = delete;

  // Fills *bgr / *grey (when non-null) with fresh, continuous matrices.
  Status Convert(const AVFrame& frame, cv::Mat* bgr, cv::Mat* grey);

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
