#include "core/video/ts_writer.h"

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <libavutil/dict.h>
#include <libavutil/frame.h>
#include <libavutil/log.h>
#include <libswscale/swscale.h>
}

#include "core/video/decode_session.h"

#include <algorithm>
#include <array>
#include <cstring>
#include <deque>
#include <limits>
#include <string_view>
#include <system_error>
#include <utility>
#include <vector>

namespace saker::video {
namespace {

using internal::AvErrorText;
using internal::CodecContextFreer;
using internal::FrameFreer;
using internal::PacketFreer;

constexpr std::array<std::string_view, 10> kX264Presets = {
    "ultrafast", "superfast", "veryfast", "faster",   "fast",
    "medium",    "slow",      "slower",   "veryslow", "placebo"};

// An output context: closes the file (if open) and frees the muxer.
struct OutputFreer {
  void operator()(AVFormatContext* context) const {
    if (context->pb != nullptr) avio_closep(&context->pb);
    avformat_free_context(context);
  }
};
struct SwsFreer {
  void operator()(SwsContext* context) const { sws_freeContext(context); }
};

// The ffmpeg command line's mux delay (-muxdelay 0.7): the first PCR is 0.7 s, the first decode
// time 1.4 s, so decoders get 0.7 s to buffer, as in files that tool makes.
constexpr int64_t kMaxDelayUs = 700000;

// MISB ST 1402 metadata access unit cell header: metadata service id, sequence number, flags
// (cell_fragment_indication 11 = complete cell, decoder_config_flag 0, random_access_indicator
// 1, 4 reserved bits), 16-bit cell data length.
constexpr uint8_t kAuCellFlags = 0xDF;
constexpr size_t kAuCellHeaderBytes = 5;

// FFmpeg's MPEG-TS probe needs more than 10 packets' worth of bytes to recognise a stream; a
// file of a frame or two of flat picture can be shorter. Such files are padded with null
// packets (PID 0x1FFF, ignored by every demuxer) up to this many packets.
constexpr int64_t kTsPacketBytes = 188;
constexpr int64_t kMinFilePackets = 16;

// Bound on KLV frame indices, far beyond any video (35 years at 1000 fps), so that timestamp
// arithmetic cannot overflow.
constexpr int64_t kMaxFrameIndex = int64_t{1} << 40;

std::string Size(int width, int height) {
  return std::to_string(width) + "x" + std::to_string(height);
}

}  // namespace

const char* VideoCodecName(VideoCodec codec) {
  switch (codec) {
    case VideoCodec::kH264:
      return "h264";
    case VideoCodec::kMpeg2:
      return "mpeg2video";
  }
  return "unknown";
}

Status TsWriterOptions::Validate() const {
  auto bad = [](const std::string& message) {
    return InvalidArgumentError("TsWriterOptions." + message);
  };
  if (width < 16 || height < 16 || width > 8192 || height > 8192) {
    return bad("width and height must be in [16, 8192], got " + Size(width, height));
  }
  if (codec == VideoCodec::kH264 && (width % 2 != 0 || height % 2 != 0)) {
    return bad("width and height must be even for H.264 (4:2:0 chroma), got " +
               Size(width, height));
  }
  if (fps_num < 1 || fps_den < 1 || fps_num > 1000LL * fps_den) {
    return bad("fps_num / fps_den must be a positive frame rate of at most 1000, got " +
               std::to_string(fps_num) + "/" + std::to_string(fps_den));
  }
  if (gop_size < 1 || gop_size > 100000) {
    return bad("gop_size must be in [1, 100000], got " + std::to_string(gop_size));
  }
  if (b_frames < 0 || b_frames > 16) {
    return bad("b_frames must be in [0, 16], got " + std::to_string(b_frames));
  }
  if (crf < 0 || crf > 51) return bad("crf must be in [0, 51], got " + std::to_string(crf));
  if (codec == VideoCodec::kH264 &&
      std::find(kX264Presets.begin(), kX264Presets.end(), x264_preset) == kX264Presets.end()) {
    return bad("x264_preset '" + x264_preset +
               "' is not a libx264 preset (ultrafast, superfast, veryfast, faster, fast, medium, "
               "slow, slower, veryslow, placebo)");
  }
  if (mpeg2_qscale < 1 || mpeg2_qscale > 31) {
    return bad("mpeg2_qscale must be in [1, 31], got " + std::to_string(mpeg2_qscale));
  }
  if (threads < 0 || threads > 64) {
    return bad("threads must be in [0, 64] (0 = automatic), got " + std::to_string(threads));
  }
  return Status::Ok();
}

struct TsWriter::Impl {
  std::string path;  // as given, for messages
  TsWriterOptions options;

  std::unique_ptr<AVFormatContext, OutputFreer> format;
  std::unique_ptr<AVCodecContext, CodecContextFreer> encoder;
  std::unique_ptr<AVFrame, FrameFreer> frame;
  std::unique_ptr<AVPacket, PacketFreer> packet;      // encoder output
  std::unique_ptr<AVPacket, PacketFreer> klv_packet;  // KLV going to the muxer
  std::unique_ptr<SwsContext, SwsFreer> bgr_to_yuv;   // made at the first BGR frame
  AVStream* video = nullptr;
  AVStream* klv = nullptr;
  bool created_file = false;  // the file did not exist before Open

  // KLV waits here until the video packet it must precede comes out of the encoder.
  struct PendingKlv {
    int64_t frame = 0;
    std::vector<uint8_t> bytes;
  };
  std::deque<PendingKlv> klv_queue;
  int64_t last_klv_frame = -1;   // frame index of the latest WriteKlv
  int64_t muxed_klv_frame = -1;  // frame index of the latest KLV PES in the file
  int sync_sequence = 0;         // ST 1402 cell sequence number

  // Added to every timestamp (in frames) so that none is negative: the encoder's first decode
  // time stamp lies before 0 when frames are reordered. Fixed at the first video packet.
  bool offset_known = false;
  int64_t offset = 0;

  int64_t frames_written = 0;
  int64_t next_pts = 0;  // time slot of the next frame, in frame intervals (SkipFrames adds gaps)
  Status failure;        // the error that stopped the writer
  bool closed = false;
  Status close_status;

  AVRational frame_time_base() const { return AVRational{options.fps_den, options.fps_num}; }

  Status Fail(Status status) {
    if (failure.ok()) failure = status;
    return status;
  }

  Status FfmpegError(const std::string& what, int error) const {
    return IoError(path + ": " + what + " (FFmpeg: " + AvErrorText(error) + ")");
  }

  // OK when calls may go on.
  Status Usable(const char* call) const {
    if (closed) return InvalidArgumentError(path + ": " + call + " after Close()");
    return failure;
  }

  Status CheckPath() {
    namespace fs = std::filesystem;
    if (path.empty()) return InvalidArgumentError("TsWriter: empty output path");
    const fs::path file(path);
    std::error_code error;
    const fs::file_status status = fs::status(file, error);
    if (fs::is_directory(status)) {
      return InvalidArgumentError(path + ": is a directory, not a file name");
    }
    created_file = !fs::exists(status);
    fs::path parent = file.parent_path();
    if (parent.empty()) parent = ".";
    const fs::file_status parent_status = fs::status(parent, error);
    if (!fs::exists(parent_status)) {
      return NotFoundError(path + ": cannot create the file: directory " + parent.string() +
                           " does not exist");
    }
    if (!fs::is_directory(parent_status)) {
      return NotFoundError(path + ": cannot create the file: " + parent.string() +
                           " is not a directory");
    }
    return Status::Ok();
  }

  Status OpenEncoder() {
    const bool h264 = options.codec == VideoCodec::kH264;
    const AVCodec* codec = h264 ? avcodec_find_encoder_by_name("libx264")
                                : avcodec_find_encoder(AV_CODEC_ID_MPEG2VIDEO);
    if (codec == nullptr) {
      return UnsupportedError(path + ": this FFmpeg build has no " +
                              (h264 ? "libx264 H.264" : "MPEG-2 video") + " encoder");
    }
    encoder.reset(avcodec_alloc_context3(codec));
    if (!encoder) return IoError(path + ": out of memory opening the encoder");
    AVCodecContext* context = encoder.get();
    context->width = options.width;
    context->height = options.height;
    context->time_base = frame_time_base();
    context->framerate = AVRational{options.fps_num, options.fps_den};
    context->sample_aspect_ratio = AVRational{1, 1};
    context->pix_fmt = AV_PIX_FMT_YUV420P;
    context->gop_size = options.gop_size;
    context->max_b_frames = options.b_frames;
    context->thread_count = options.threads;
    // What the BGR conversion produces, declared in the stream so decoders invert it exactly.
    const bool hd = options.height >= 720;
    context->color_range = AVCOL_RANGE_MPEG;
    context->colorspace = hd ? AVCOL_SPC_BT709 : AVCOL_SPC_SMPTE170M;
    context->color_primaries = hd ? AVCOL_PRI_BT709 : AVCOL_PRI_SMPTE170M;
    context->color_trc = hd ? AVCOL_TRC_BT709 : AVCOL_TRC_SMPTE170M;
    if ((format->oformat->flags & AVFMT_GLOBALHEADER) != 0) {
      context->flags |= AV_CODEC_FLAG_GLOBAL_HEADER;
    }

    AVDictionary* settings = nullptr;
    if (h264) {
      av_dict_set(&settings, "preset", options.x264_preset.c_str(), 0);
      av_dict_set(&settings, "crf", std::to_string(options.crf).c_str(), 0);
      // Key frames exactly every gop_size frames. libx264's informational lines (CPU, profile,
      // statistics at close) stay off unless FFmpeg logging is verbose or more; its warnings
      // and errors go through av_log (SetFfmpegLogVerbose decides whether they show).
      const int x264_log_level = av_log_get_level() >= AV_LOG_VERBOSE ? 2 : 1;
      const std::string params = "scenecut=0:log=" + std::to_string(x264_log_level);
      av_dict_set(&settings, "x264-params", params.c_str(), 0);
    } else {
      // Constant quantiser; bit-exact DCT so the bytes do not depend on the CPU.
      context->flags |= AV_CODEC_FLAG_QSCALE | AV_CODEC_FLAG_BITEXACT;
      context->global_quality = FF_QP2LAMBDA * options.mpeg2_qscale;
    }
    const int ret = avcodec_open2(context, codec, &settings);
    av_dict_free(&settings);
    if (ret < 0) {
      const std::string hint =
          h264 ? ""
               : "; MPEG-2 has fixed frame rates: 24000/1001, 24, 25, 30000/1001, 30, 50, "
                 "60000/1001, 60";
      return UnsupportedError(path + ": the " + std::string(codec->name) + " encoder refuses " +
                              Size(options.width, options.height) + " at " +
                              std::to_string(options.fps_num) + "/" +
                              std::to_string(options.fps_den) + " fps with these options" + hint +
                              " (FFmpeg: " + AvErrorText(ret) + ")");
    }
    return Status::Ok();
  }

  Status Open() {
    SAKER_RETURN_IF_ERROR(CheckPath());
    AVFormatContext* raw_format = nullptr;
    int ret = avformat_alloc_output_context2(&raw_format, nullptr, "mpegts", nullptr);
    if (ret < 0 || raw_format == nullptr) {
      return UnsupportedError(
          path + ": this FFmpeg build has no MPEG-TS muxer (FFmpeg: " + AvErrorText(ret) + ")");
    }
    format.reset(raw_format);
    format->max_delay = kMaxDelayUs;
    format->flags |= AVFMT_FLAG_BITEXACT;
    // Timestamps are made non-negative here (offset), never shifted by the muxer.
    format->avoid_negative_ts = AVFMT_AVOID_NEG_TS_DISABLED;

    SAKER_RETURN_IF_ERROR(OpenEncoder());

    video = avformat_new_stream(format.get(), nullptr);
    if (video == nullptr) return IoError(path + ": out of memory adding the video stream");
    ret = avcodec_parameters_from_context(video->codecpar, encoder.get());
    if (ret < 0) return FfmpegError("cannot describe the video stream", ret);
    video->time_base = encoder->time_base;
    video->avg_frame_rate = encoder->framerate;

    if (options.with_klv) {
      klv = avformat_new_stream(format.get(), nullptr);
      if (klv == nullptr) return IoError(path + ": out of memory adding the KLV stream");
      klv->codecpar->codec_type = AVMEDIA_TYPE_DATA;
      klv->codecpar->codec_id = AV_CODEC_ID_SMPTE_KLV;
      klv->codecpar->profile =
          options.klv_synchronous ? FF_PROFILE_KLVA_SYNC : FF_PROFILE_KLVA_ASYNC;
      klv->time_base = AVRational{1, 90000};
    }

    frame.reset(av_frame_alloc());
    packet.reset(av_packet_alloc());
    klv_packet.reset(av_packet_alloc());
    if (!frame || !packet || !klv_packet) return IoError(path + ": out of memory");
    frame->format = AV_PIX_FMT_YUV420P;
    frame->width = options.width;
    frame->height = options.height;
    ret = av_frame_get_buffer(frame.get(), 0);
    if (ret < 0) return FfmpegError("cannot allocate a picture", ret);

    // The "file:" protocol, so that a colon in the name is never taken for a protocol.
    ret = avio_open(&format->pb, ("file:" + path).c_str(), AVIO_FLAG_WRITE);
    if (ret < 0) {
      const std::string text = " (FFmpeg: " + AvErrorText(ret) + ")";
      if (ret == AVERROR(ENOENT)) {
        return NotFoundError(path + ": cannot create the file: no such directory" + text);
      }
      if (ret == AVERROR(EACCES) || ret == AVERROR(EPERM) || ret == AVERROR(EROFS)) {
        return IoError(path + ": cannot create the file: permission denied" + text);
      }
      return IoError(path + ": cannot create the file" + text);
    }
    ret = avformat_write_header(format.get(), nullptr);
    if (ret < 0) return FfmpegError("cannot write the stream headers", ret);
    return Status::Ok();
  }

  // Hands one packet to the muxer (which leaves it blank).
  Status Mux(AVPacket* out, const char* what) {
    const int ret = av_write_frame(format.get(), out);
    av_packet_unref(out);
    if (ret < 0) return Fail(FfmpegError(std::string("cannot write a ") + what, ret));
    return Status::Ok();
  }

  Status MuxKlv(const PendingKlv& pending) {
    const bool sync = options.klv_synchronous;
    const size_t size = pending.bytes.size() + (sync ? kAuCellHeaderBytes : 0);
    AVPacket* out = klv_packet.get();
    int ret = av_new_packet(out, static_cast<int>(size));
    if (ret < 0) return Fail(FfmpegError("cannot allocate a KLV packet", ret));
    uint8_t* data = out->data;
    if (sync) {
      const auto length = static_cast<uint16_t>(pending.bytes.size());
      const uint8_t header[kAuCellHeaderBytes] = {0x00, static_cast<uint8_t>(sync_sequence & 0xFF),
                                                  kAuCellFlags, static_cast<uint8_t>(length >> 8),
                                                  static_cast<uint8_t>(length & 0xFF)};
      std::memcpy(data, header, kAuCellHeaderBytes);
      data += kAuCellHeaderBytes;
      ++sync_sequence;
    }
    std::memcpy(data, pending.bytes.data(), pending.bytes.size());
    out->stream_index = klv->index;
    out->pts = out->dts = av_rescale_q(pending.frame + offset, frame_time_base(), klv->time_base);
    out->flags |= AV_PKT_FLAG_KEY;
    SAKER_RETURN_IF_ERROR(Mux(out, "KLV packet"));
    muxed_klv_frame = pending.frame;
    return Status::Ok();
  }

  // Writes the queued KLV packets of frames up to `frame`.
  Status FlushKlv(int64_t frame_index) {
    while (!klv_queue.empty() && klv_queue.front().frame <= frame_index) {
      SAKER_RETURN_IF_ERROR(MuxKlv(klv_queue.front()));
      klv_queue.pop_front();
    }
    return Status::Ok();
  }

  // Writes the encoder's packet, after the KLV of its frame and every frame before.
  Status MuxVideoPacket() {
    AVPacket* out = packet.get();
    if (!offset_known) {
      const int64_t first = out->dts != AV_NOPTS_VALUE ? out->dts : out->pts;
      offset = first != AV_NOPTS_VALUE && first < 0 ? -first : 0;
      offset_known = true;
    }
    if (out->pts != AV_NOPTS_VALUE) SAKER_RETURN_IF_ERROR(FlushKlv(out->pts));
    if (out->pts != AV_NOPTS_VALUE) out->pts += offset;
    if (out->dts != AV_NOPTS_VALUE) out->dts += offset;
    av_packet_rescale_ts(out, frame_time_base(), video->time_base);
    out->stream_index = video->index;
    return Mux(out, "video packet");
  }

  // Moves every packet the encoder has ready into the file.
  Status Drain() {
    while (true) {
      const int ret = avcodec_receive_packet(encoder.get(), packet.get());
      if (ret == AVERROR(EAGAIN) || ret == AVERROR_EOF) return Status::Ok();
      if (ret < 0) return Fail(FfmpegError("the video encoder failed", ret));
      SAKER_RETURN_IF_ERROR(MuxVideoPacket());
    }
  }

  Status Fill(const cv::Mat& image) {
    AVFrame* picture = frame.get();
    const int width = options.width;
    const int height = options.height;
    if (image.type() == CV_8UC1) {
      for (int y = 0; y < height; ++y) {
        std::memcpy(picture->data[0] + static_cast<ptrdiff_t>(y) * picture->linesize[0],
                    image.ptr<uint8_t>(y), static_cast<size_t>(width));
      }
      for (int plane = 1; plane <= 2; ++plane) {
        for (int y = 0; y < (height + 1) / 2; ++y) {
          std::memset(picture->data[plane] + static_cast<ptrdiff_t>(y) * picture->linesize[plane],
                      128, static_cast<size_t>((width + 1) / 2));
        }
      }
      return Status::Ok();
    }
    if (!bgr_to_yuv) {
      bgr_to_yuv.reset(sws_getContext(width, height, AV_PIX_FMT_BGR24, width, height,
                                      AV_PIX_FMT_YUV420P, SWS_BILINEAR | SWS_ACCURATE_RND, nullptr,
                                      nullptr, nullptr));
      if (!bgr_to_yuv) return UnsupportedError(path + ": cannot convert BGR to YUV 4:2:0");
      // Full-range BGR in, limited-range YUV out, with the matrix the stream declares. Without
      // SWS_ACCURATE_RND the x86 path truncates: flat grey 128 became Y 125, U = V = 127.
      const int matrix = options.height >= 720 ? SWS_CS_ITU709 : SWS_CS_ITU601;
      sws_setColorspaceDetails(bgr_to_yuv.get(), sws_getCoefficients(matrix), 1,
                               sws_getCoefficients(matrix), 0, 0, 1 << 16, 1 << 16);
    }
    const uint8_t* source[4] = {image.data, nullptr, nullptr, nullptr};
    const int stride[4] = {static_cast<int>(image.step[0]), 0, 0, 0};
    const int rows =
        sws_scale(bgr_to_yuv.get(), source, stride, 0, height, picture->data, picture->linesize);
    if (rows != height) return InvalidDataError(path + ": BGR to YUV conversion failed");
    return Status::Ok();
  }

  Status WriteFrame(const cv::Mat& image) {
    SAKER_RETURN_IF_ERROR(Usable("WriteFrame"));
    // Only built for error messages.
    const auto which = [&] { return "frame " + std::to_string(frames_written); };
    if (image.empty()) return InvalidArgumentError(path + ": " + which() + " is an empty image");
    if (image.type() != CV_8UC3 && image.type() != CV_8UC1) {
      return InvalidArgumentError(
          path + ": " + which() + " must be CV_8UC3 (BGR) or CV_8UC1 (luma), got type " +
          std::to_string(image.type()) + " with " + std::to_string(image.channels()) + " channels");
    }
    if (image.dims != 2 || image.cols != options.width || image.rows != options.height) {
      return InvalidArgumentError(path + ": " + which() + " is " + Size(image.cols, image.rows) +
                                  ", the stream is " + Size(options.width, options.height));
    }
    // The encoder may still hold the previous picture (reordering): write into a fresh buffer.
    int ret = av_frame_make_writable(frame.get());
    if (ret < 0) return Fail(FfmpegError("cannot allocate a picture", ret));
    SAKER_RETURN_IF_ERROR(Fill(image));
    frame->pts = next_pts;
    frame->pict_type = AV_PICTURE_TYPE_NONE;
    if (options.codec == VideoCodec::kMpeg2) frame->quality = encoder->global_quality;
    ret = avcodec_send_frame(encoder.get(), frame.get());
    if (ret < 0) return Fail(FfmpegError("cannot encode " + which(), ret));
    ++frames_written;
    ++next_pts;
    return Drain();
  }

  Status WriteKlv(std::span<const uint8_t> bytes, int64_t frame_index) {
    SAKER_RETURN_IF_ERROR(Usable("WriteKlv"));
    const auto which = [&] { return "KLV for frame " + std::to_string(frame_index); };
    if (klv == nullptr) {
      return InvalidArgumentError(path + ": " + which() +
                                  ": the writer has no KLV stream (opened with with_klv = false)");
    }
    if (bytes.empty()) return InvalidArgumentError(path + ": " + which() + ": empty packet");
    if (frame_index < 0 || frame_index > kMaxFrameIndex) {
      return InvalidArgumentError(path + ": " + which() + ": frame index out of range [0, " +
                                  std::to_string(kMaxFrameIndex) + "]");
    }
    if (frame_index < last_klv_frame) {
      return InvalidArgumentError(path + ": " + which() + " comes after KLV for frame " +
                                  std::to_string(last_klv_frame) +
                                  "; frame indices must not decrease");
    }
    if (frame_index <= muxed_klv_frame) {
      return InvalidArgumentError(path + ": " + which() +
                                  ": that frame's KLV is already in the file; write all packets "
                                  "of a frame before WriteFrame of that frame");
    }
    const bool join = !klv_queue.empty() && klv_queue.back().frame == frame_index;
    const size_t total = bytes.size() + (join ? klv_queue.back().bytes.size() : 0);
    if (total > kMaxKlvBytesPerFrame) {
      return InvalidArgumentError(path + ": " + which() + ": " + std::to_string(total) +
                                  " bytes of KLV for one frame, at most " +
                                  std::to_string(kMaxKlvBytesPerFrame));
    }
    if (join) {
      std::vector<uint8_t>& queued = klv_queue.back().bytes;
      queued.insert(queued.end(), bytes.begin(), bytes.end());
    } else {
      klv_queue.push_back({frame_index, std::vector<uint8_t>(bytes.begin(), bytes.end())});
    }
    last_klv_frame = frame_index;
    return Status::Ok();
  }

  // Flushes everything and writes the trailer.
  Status Finish() {
    int ret = avcodec_send_frame(encoder.get(), nullptr);
    if (ret < 0) return Fail(FfmpegError("cannot flush the video encoder", ret));
    SAKER_RETURN_IF_ERROR(Drain());
    SAKER_RETURN_IF_ERROR(FlushKlv(std::numeric_limits<int64_t>::max()));
    ret = av_write_trailer(format.get());
    if (ret < 0) return Fail(FfmpegError("cannot finish the file", ret));
    for (int64_t size = avio_tell(format->pb); size >= 0 && size < kMinFilePackets * kTsPacketBytes;
         size += kTsPacketBytes) {
      uint8_t null_packet[kTsPacketBytes];
      std::memset(null_packet, 0xFF, sizeof(null_packet));
      null_packet[0] = 0x47;  // sync byte
      null_packet[1] = 0x1F;  // PID 0x1FFF
      null_packet[3] = 0x10;  // payload only
      avio_write(format->pb, null_packet, static_cast<int>(sizeof(null_packet)));
    }
    avio_flush(format->pb);
    if (format->pb->error < 0) return Fail(FfmpegError("cannot write the file", format->pb->error));
    return Status::Ok();
  }

  Status Close() {
    if (closed) return close_status;
    Status result = failure;
    if (result.ok() && format && encoder) result = Finish();
    closed = true;
    klv_queue.clear();
    bgr_to_yuv.reset();
    encoder.reset();
    frame.reset();
    packet.reset();
    klv_packet.reset();
    if (format && format->pb != nullptr) {
      const int ret = avio_closep(&format->pb);
      if (ret < 0 && result.ok()) result = FfmpegError("cannot close the file", ret);
    }
    format.reset();
    close_status = result;
    return result;
  }

  // After a failed Open: releases FFmpeg and removes the file if Open created it.
  void Abandon() {
    const bool file_opened = format && format->pb != nullptr;
    closed = true;
    close_status = InvalidArgumentError(path + ": not open");
    encoder.reset();
    format.reset();
    if (file_opened && created_file) {
      std::error_code ignored;
      std::filesystem::remove(path, ignored);
    }
  }
};

TsWriter::TsWriter(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

TsWriter::~TsWriter() {
  if (impl_) static_cast<void>(impl_->Close());
}

StatusOr<std::unique_ptr<TsWriter>> TsWriter::Open(const std::filesystem::path& path,
                                                   const TsWriterOptions& options) {
  const std::string name = path.string();
  const Status valid = options.Validate();
  if (!valid.ok()) {
    return InvalidArgumentError((name.empty() ? "TsWriter" : name) + ": " + valid.message());
  }
  auto impl = std::make_unique<Impl>();
  impl->path = name;
  impl->options = options;
  const Status opened = impl->Open();
  if (!opened.ok()) {
    impl->Abandon();
    return opened;
  }
  return std::unique_ptr<TsWriter>(new TsWriter(std::move(impl)));
}

Status TsWriter::WriteKlv(std::span<const uint8_t> packet, int64_t frame_index) {
  return impl_->WriteKlv(packet, frame_index);
}

Status TsWriter::WriteFrame(const cv::Mat& image) { return impl_->WriteFrame(image); }

Status TsWriter::Close() { return impl_->Close(); }

int64_t TsWriter::frames_written() const { return impl_->frames_written; }

Status TsWriter::SkipFrames(int64_t count) {
  SAKER_RETURN_IF_ERROR(impl_->Usable("SkipFrames"));
  if (count < 0 || impl_->next_pts + count > kMaxFrameIndex) {
    return InvalidArgumentError(impl_->path + ": cannot skip " + std::to_string(count) +
                                " frame times (at most up to frame time " +
                                std::to_string(kMaxFrameIndex) + ")");
  }
  impl_->next_pts += count;
  return Status::Ok();
}

const TsWriterOptions& TsWriter::options() const { return impl_->options; }

}  // namespace saker::video
