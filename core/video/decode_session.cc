#include "core/video/decode_session.h"

extern "C" {
#include <libavutil/pixdesc.h>
}

#include "core/video/mpegts_pmt.h"

#include <cmath>
#include <filesystem>
#include <limits>
#include <map>
#include <system_error>

namespace saker::video::internal {
namespace {

// Reads or decodes in a row that make no progress before a session gives up.
constexpr int kMaxConsecutiveFailures = 10000;

// "file:x.ts" -> "x.ts"; empty for URLs of other protocols.
std::string LocalPath(const std::string& path) {
  if (path.rfind("file:", 0) == 0) return path.substr(5);
  if (path.find("://") != std::string::npos) return {};
  return path;
}

// Plain-language errors for what the file system can tell before FFmpeg is involved.
Status CheckLocalFile(const std::string& path) {
  const std::string local = LocalPath(path);
  if (local.empty()) return Status::Ok();
  namespace fs = std::filesystem;
  std::error_code error;
  const fs::file_status status = fs::status(local, error);
  if (status.type() == fs::file_type::not_found) return NotFoundError(path + ": no such file");
  if (error) return IoError(path + ": cannot access: " + error.message());
  if (fs::is_directory(status)) {
    return InvalidArgumentError(path + ": is a directory, not a video file");
  }
  if (fs::is_regular_file(status) && fs::file_size(local, error) == 0 && !error) {
    return InvalidDataError(path + ": file is empty (0 bytes), not a video");
  }
  return Status::Ok();
}

Status OpenError(const std::string& path, int error) {
  const std::string text = " (FFmpeg: " + AvErrorText(error) + ")";
  if (error == AVERROR(ENOENT)) return NotFoundError(path + ": no such file" + text);
  if (error == AVERROR(EACCES) || error == AVERROR(EPERM)) {
    return IoError(path + ": permission denied" + text);
  }
  if (error == AVERROR_INVALIDDATA) {
    return InvalidDataError(path + ": not a video file FFmpeg can recognise" + text);
  }
  if (error == AVERROR_PROTOCOL_NOT_FOUND || error == AVERROR_DEMUXER_NOT_FOUND) {
    return UnsupportedError(path + ": this FFmpeg build cannot read it" + text);
  }
  return IoError(path + ": cannot open" + text);
}

StreamKind KindOf(const AVCodecParameters& parameters) {
  if (parameters.codec_id == AV_CODEC_ID_SMPTE_KLV) return StreamKind::kKlv;
  switch (parameters.codec_type) {
    case AVMEDIA_TYPE_VIDEO:
      return StreamKind::kVideo;
    case AVMEDIA_TYPE_AUDIO:
      return StreamKind::kAudio;
    case AVMEDIA_TYPE_DATA:
      return StreamKind::kOtherData;
    default:
      return StreamKind::kOther;
  }
}

double FrameRate(const AVStream& stream) {
  for (AVRational rate : {stream.avg_frame_rate, stream.r_frame_rate}) {
    if (rate.num > 0 && rate.den > 0) return av_q2d(rate);
  }
  return 0;
}

// The YUV matrix swscale should use for this picture.
int SwsColorspace(const AVFrame& frame) {
  switch (frame.colorspace) {
    case AVCOL_SPC_BT709:
      return SWS_CS_ITU709;
    case AVCOL_SPC_FCC:
      return SWS_CS_FCC;
    case AVCOL_SPC_SMPTE240M:
      return SWS_CS_SMPTE240M;
    case AVCOL_SPC_BT2020_NCL:
    case AVCOL_SPC_BT2020_CL:
      return SWS_CS_BT2020;
    case AVCOL_SPC_BT470BG:
    case AVCOL_SPC_SMPTE170M:
      return SWS_CS_ITU601;
    default:  // Unspecified: the usual convention, BT.709 for HD, BT.601 for SD.
      return frame.height >= 720 ? SWS_CS_ITU709 : SWS_CS_ITU601;
  }
}

// The deprecated full-range "J" formats as their plain equivalent plus a full-range flag, which
// is what swscale expects (and it warns otherwise).
AVPixelFormat PlainFormat(AVPixelFormat format, bool* full_range) {
  switch (format) {
    case AV_PIX_FMT_YUVJ420P:
      *full_range = true;
      return AV_PIX_FMT_YUV420P;
    case AV_PIX_FMT_YUVJ422P:
      *full_range = true;
      return AV_PIX_FMT_YUV422P;
    case AV_PIX_FMT_YUVJ444P:
      *full_range = true;
      return AV_PIX_FMT_YUV444P;
    case AV_PIX_FMT_YUVJ440P:
      *full_range = true;
      return AV_PIX_FMT_YUV440P;
    case AV_PIX_FMT_YUVJ411P:
      *full_range = true;
      return AV_PIX_FMT_YUV411P;
    default:
      return format;
  }
}

// True when plane 0 is a plain 8-bit luma (or grey) plane that can be copied as the grey image.
bool HasPlainLumaPlane(const AVPixFmtDescriptor& desc, const AVFrame& frame) {
  constexpr uint64_t kNotPlainYuv =
      AV_PIX_FMT_FLAG_RGB | AV_PIX_FMT_FLAG_PAL | AV_PIX_FMT_FLAG_BAYER | AV_PIX_FMT_FLAG_HWACCEL;
  if ((desc.flags & kNotPlainYuv) != 0 || desc.nb_components < 1) return false;
  const AVComponentDescriptor& luma = desc.comp[0];
  return luma.plane == 0 && luma.depth == 8 && luma.step == 1 && luma.shift == 0 &&
         luma.offset == 0 && frame.data[0] != nullptr && frame.linesize[0] >= frame.width;
}

}  // namespace

std::string AvErrorText(int error) {
  char buffer[AV_ERROR_MAX_STRING_SIZE] = {};
  if (av_strerror(error, buffer, sizeof(buffer)) < 0 || buffer[0] == '\0') {
    return "error " + std::to_string(error);
  }
  return buffer;
}

StatusOr<std::unique_ptr<DecodeSession>> DecodeSession::Open(const std::string& path,
                                                             const SessionConfig& config) {
  std::unique_ptr<DecodeSession> session(new DecodeSession());
  SAKER_RETURN_IF_ERROR(session->OpenImpl(path, config));
  return session;
}

DecodeSession::~DecodeSession() = default;

Status DecodeSession::OpenImpl(const std::string& path, const SessionConfig& config) {
  path_ = path;
  config_ = config;
  info_.path = path;
  if (path.empty()) return InvalidArgumentError("empty video path");
  SAKER_RETURN_IF_ERROR(CheckLocalFile(path));

  AVFormatContext* raw_format = nullptr;
  int ret = avformat_open_input(&raw_format, path.c_str(), nullptr, nullptr);
  if (ret < 0) return OpenError(path, ret);
  format_.reset(raw_format);
  ret = avformat_find_stream_info(format_.get(), nullptr);
  if (ret < 0) {
    return InvalidDataError(path + ": cannot read the stream layout (FFmpeg: " + AvErrorText(ret) +
                            ")");
  }
  AVFormatContext* format = format_.get();
  info_.container = format->iformat->name ? format->iformat->name : "";
  info_.container_long = format->iformat->long_name ? format->iformat->long_name : "";
  info_.duration_s =
      format->duration != AV_NOPTS_VALUE ? static_cast<double>(format->duration) / AV_TIME_BASE : 0;

  const AVCodec* codec = nullptr;
  ret = av_find_best_stream(format, AVMEDIA_TYPE_VIDEO, -1, -1, &codec, 0);
  if (ret == AVERROR_DECODER_NOT_FOUND) {
    // Name the codec of the first video stream: that is the one the user expected.
    std::string name = "unknown";
    for (unsigned i = 0; i < format->nb_streams; ++i) {
      if (format->streams[i]->codecpar->codec_type == AVMEDIA_TYPE_VIDEO) {
        name = avcodec_get_name(format->streams[i]->codecpar->codec_id);
        break;
      }
    }
    return UnsupportedError(path + ": no decoder for video codec '" + name +
                            "' in this FFmpeg build");
  }
  if (ret < 0) {
    return InvalidDataError(path + " has no video stream (container " + info_.container + ", " +
                            std::to_string(format->nb_streams) + " streams)");
  }
  video_ = format->streams[ret];
  const AVCodecParameters& parameters = *video_->codecpar;
  info_.video_stream = video_->index;
  info_.video_codec = avcodec_get_name(parameters.codec_id);
  info_.width = parameters.width;
  info_.height = parameters.height;
  if (info_.width <= 0 || info_.height <= 0) {
    return InvalidDataError(path + " has no video stream that can be decoded: its " +
                            info_.video_codec +
                            " stream has no picture header (declared but empty, or damaged)");
  }
  const int64_t pixels = static_cast<int64_t>(info_.width) * info_.height;
  if (pixels > config.max_pixels) {
    return InvalidDataError(path + ": declared picture size " + std::to_string(info_.width) + "x" +
                            std::to_string(info_.height) + " exceeds max_pixels (" +
                            std::to_string(config.max_pixels) + ")");
  }
  info_.fps = FrameRate(*video_);
  info_.declared_frame_count = video_->nb_frames > 0 ? video_->nb_frames : 0;
  start_pts_ = video_->start_time != AV_NOPTS_VALUE ? video_->start_time : 0;
  info_.start_time_s = static_cast<double>(start_pts_) * av_q2d(video_->time_base);
  const double fps = info_.fps > 0 ? info_.fps : 25.0;
  frame_step_ = std::max<int64_t>(1, std::llround(1.0 / (fps * av_q2d(video_->time_base))));

  // Streams. PIDs are only meaningful for transport streams.
  const bool is_mpegts = info_.container == "mpegts";
  std::map<int, int> pmt_stream_types;
  const std::string local = LocalPath(path);
  bool klv_present = false;
  for (unsigned i = 0; i < format->nb_streams; ++i) {
    klv_present |= format->streams[i]->codecpar->codec_id == AV_CODEC_ID_SMPTE_KLV;
  }
  if (config.probe_klv_sync && is_mpegts && klv_present && !local.empty()) {
    auto types = ScanPmtStreamTypesInFile(local);
    if (types.ok()) pmt_stream_types = std::move(types).value();
  }
  is_klv_.assign(format->nb_streams, false);
  for (unsigned i = 0; i < format->nb_streams; ++i) {
    AVStream* stream = format->streams[i];
    StreamInfo stream_info;
    stream_info.index = static_cast<int>(i);
    stream_info.kind = KindOf(*stream->codecpar);
    stream_info.codec_name = avcodec_get_name(stream->codecpar->codec_id);
    stream_info.pid = is_mpegts ? stream->id : -1;
    if (stream_info.kind == StreamKind::kKlv) {
      is_klv_[i] = true;
      const int profile = stream->codecpar->profile;
      if (profile == FF_PROFILE_KLVA_SYNC) {
        stream_info.klv_synchronous = true;
      } else if (profile != FF_PROFILE_KLVA_ASYNC) {
        auto found = pmt_stream_types.find(stream_info.pid);
        stream_info.klv_synchronous =
            found != pmt_stream_types.end() && found->second == kStreamTypeMetadata;
      }
    }
    const bool keep = stream == video_ || (config.keep_klv && is_klv_[i]);
    stream->discard = keep ? AVDISCARD_DEFAULT : AVDISCARD_ALL;
    info_.streams.push_back(std::move(stream_info));
  }

  // Decoder.
  decoder_.reset(avcodec_alloc_context3(codec));
  packet_.reset(av_packet_alloc());
  pending_.reset(av_packet_alloc());
  frame_.reset(av_frame_alloc());
  if (!decoder_ || !packet_ || !pending_ || !frame_) {
    return IoError(path + ": out of memory opening the decoder");
  }
  ret = avcodec_parameters_to_context(decoder_.get(), video_->codecpar);
  if (ret < 0) {
    return InvalidDataError(path + ": bad " + info_.video_codec +
                            " stream parameters (FFmpeg: " + AvErrorText(ret) + ")");
  }
  decoder_->pkt_timebase = video_->time_base;
  decoder_->thread_count = config.decoder_threads;
  ret = avcodec_open2(decoder_.get(), codec, nullptr);
  if (ret < 0) {
    return UnsupportedError(path + ": cannot open the " + info_.video_codec +
                            " decoder (FFmpeg: " + AvErrorText(ret) + ")");
  }
  return Status::Ok();
}

double DecodeSession::SecondsFromStart(int64_t pts) const {
  const AVRational time_base = video_->time_base;
  return static_cast<double>(pts - start_pts_) * time_base.num / time_base.den;
}

int64_t DecodeSession::RawTimestamp() const {
  return frame_->pts != AV_NOPTS_VALUE ? frame_->pts : frame_->best_effort_timestamp;
}

void DecodeSession::AppendDataPacket(const AVPacket& packet, std::vector<DataPacket>* data) const {
  DataPacket out;
  out.stream_index = packet.stream_index;
  out.pts = packet.pts;  // AV_NOPTS_VALUE is INT64_MIN
  out.byte_pos = packet.pos;
  if (packet.pts == AV_NOPTS_VALUE) {
    out.time_s = std::numeric_limits<double>::quiet_NaN();
  } else {
    const AVStream* stream = format_->streams[packet.stream_index];
    out.time_s = SecondsFromStart(av_rescale_q(packet.pts, stream->time_base, video_->time_base));
  }
  out.bytes.assign(packet.data, packet.data + packet.size);
  data->push_back(std::move(out));
}

StatusOr<bool> DecodeSession::DecodeNext(std::vector<DataPacket>* data, ReadStats* stats) {
  AVCodecContext* decoder = decoder_.get();
  AVPacket* packet = packet_.get();
  int failures = 0;
  while (true) {
    int ret = avcodec_receive_frame(decoder, frame_.get());
    if (ret >= 0) {
      if (stats != nullptr) {
        ++stats->frames_decoded;
        if (frame_->decode_error_flags != 0 || (frame_->flags & AV_FRAME_FLAG_CORRUPT) != 0) {
          ++stats->decode_errors;
        }
      }
      const int64_t pixels = static_cast<int64_t>(frame_->width) * frame_->height;
      if (frame_->width <= 0 || frame_->height <= 0 || pixels > config_.max_pixels) {
        return InvalidDataError(path_ + ": decoded picture size " + std::to_string(frame_->width) +
                                "x" + std::to_string(frame_->height) +
                                " is empty or exceeds max_pixels");
      }
      return true;
    }
    if (ret == AVERROR_EOF || (ret == AVERROR(EAGAIN) && demux_finished_ && !has_pending_)) {
      if (!deferred_error_.ok()) {
        Status error = deferred_error_;
        deferred_error_ = Status::Ok();
        return error;
      }
      return false;
    }
    if (ret != AVERROR(EAGAIN)) {
      // A picture the decoder could not reconstruct: count it and go on.
      if (stats != nullptr) ++stats->decode_errors;
      if (++failures > kMaxConsecutiveFailures) {
        return InvalidDataError(path_ + ": the decoder keeps failing (FFmpeg: " + AvErrorText(ret) +
                                ")");
      }
      continue;
    }

    // The decoder wants input.
    if (has_pending_) {
      ret = avcodec_send_packet(decoder, pending_.get());
      av_packet_unref(pending_.get());
      has_pending_ = false;
      if (ret < 0 && stats != nullptr) ++stats->decode_errors;
      continue;
    }
    ret = av_read_frame(format_.get(), packet);
    if (ret < 0) {
      if (ret == AVERROR(EAGAIN) || ret == AVERROR_INVALIDDATA) {
        // EAGAIN: a live source has nothing yet. INVALIDDATA: the demuxer skipped bytes it
        // could not parse (lost transport stream sync); it resumes after them.
        if (ret == AVERROR_INVALIDDATA && stats != nullptr) ++stats->corrupt_packets;
        if (++failures > kMaxConsecutiveFailures) {
          return InvalidDataError(path_ + ": no readable packet (FFmpeg: " + AvErrorText(ret) +
                                  ")");
        }
        continue;
      }
      if (ret != AVERROR_EOF) {
        deferred_error_ = IoError(path_ + ": read error (FFmpeg: " + AvErrorText(ret) + ")");
      }
      avcodec_send_packet(decoder, nullptr);  // enter draining mode
      demux_finished_ = true;
      continue;
    }
    failures = 0;
    const int stream_index = packet->stream_index;
    if (stream_index == video_->index) {
      if ((packet->flags & AV_PKT_FLAG_CORRUPT) != 0) {
        if (stats != nullptr) ++stats->corrupt_packets;
      } else if (awaiting_key_packet_ && (packet->flags & AV_PKT_FLAG_KEY) == 0) {
        // After a seek, pictures before the first key frame cannot be reconstructed.
      } else {
        awaiting_key_packet_ = false;
        ret = avcodec_send_packet(decoder, packet);
        if (ret == AVERROR(EAGAIN)) {
          av_packet_move_ref(pending_.get(), packet);
          has_pending_ = true;
        } else if (ret < 0 && stats != nullptr) {
          ++stats->decode_errors;
        }
      }
    } else if (data != nullptr && stream_index >= 0 &&
               static_cast<size_t>(stream_index) < is_klv_.size() && is_klv_[stream_index]) {
      if ((packet->flags & AV_PKT_FLAG_CORRUPT) != 0) {
        if (stats != nullptr) ++stats->corrupt_packets;
      } else {
        AppendDataPacket(*packet, data);
        if (stats != nullptr) ++stats->data_packets;
      }
    }
    av_packet_unref(packet);
  }
}

Status DecodeSession::SeekBackward(int64_t pts) {
  const int ret = av_seek_frame(format_.get(), video_->index, pts, AVSEEK_FLAG_BACKWARD);
  if (ret < 0) {
    return IoError(path_ + ": cannot seek to pts " + std::to_string(pts) +
                   " (FFmpeg: " + AvErrorText(ret) + ")");
  }
  avcodec_flush_buffers(decoder_.get());
  av_packet_unref(pending_.get());
  has_pending_ = false;
  demux_finished_ = false;
  deferred_error_ = Status::Ok();
  awaiting_key_packet_ = true;
  return Status::Ok();
}

FrameConverter::~FrameConverter() {
  sws_freeContext(bgr_context_);
  sws_freeContext(grey_context_);
}

SwsContext* FrameConverter::Context(const Key& key, SwsContext** context, Key* cached) {
  if (*context != nullptr && *cached == key) return *context;
  sws_freeContext(*context);
  *cached = Key{};
  const auto source = static_cast<AVPixelFormat>(key.format);
  const auto target = static_cast<AVPixelFormat>(key.target);
  *context = sws_getContext(key.width, key.height, source, key.width, key.height, target,
                            SWS_BILINEAR, nullptr, nullptr, nullptr);
  if (*context == nullptr) return nullptr;
  const AVPixFmtDescriptor* desc = av_pix_fmt_desc_get(source);
  if (desc != nullptr && (desc->flags & AV_PIX_FMT_FLAG_RGB) == 0) {
    // BGR is full range; grey keeps the source range so it matches the luma-plane fast path.
    const int target_full_range = target == AV_PIX_FMT_BGR24 ? 1 : key.full_range;
    sws_setColorspaceDetails(*context, sws_getCoefficients(key.colorspace), key.full_range,
                             sws_getCoefficients(SWS_CS_DEFAULT), target_full_range, 0, 1 << 16,
                             1 << 16);
  }
  *cached = key;
  return *context;
}

Status FrameConverter::Convert(const AVFrame& frame, cv::Mat* bgr, cv::Mat* grey) {
  const int width = frame.width;
  const int height = frame.height;
  bool full_range = frame.color_range == AVCOL_RANGE_JPEG;
  const AVPixelFormat format = PlainFormat(static_cast<AVPixelFormat>(frame.format), &full_range);
  const AVPixFmtDescriptor* desc = av_pix_fmt_desc_get(format);
  if (width <= 0 || height <= 0 || desc == nullptr) {
    return InvalidDataError("decoded picture has no size or no pixel format");
  }
  const Key base{width, height, format, SwsColorspace(frame), full_range ? 1 : 0, -1};

  // One spare row after each image: swscale's SIMD writers may touch a few bytes past a row.
  auto scale = [&](SwsContext* context, int type, cv::Mat* out) -> Status {
    cv::Mat buffer(height + 1, width, type);
    uint8_t* planes[4] = {buffer.data, nullptr, nullptr, nullptr};
    int strides[4] = {static_cast<int>(buffer.step[0]), 0, 0, 0};
    const int rows = sws_scale(context, frame.data, frame.linesize, 0, height, planes, strides);
    if (rows != height) {
      return InvalidDataError("pixel conversion from " + std::string(desc->name) + " failed");
    }
    *out = buffer.rowRange(0, height);
    return Status::Ok();
  };

  if (bgr != nullptr) {
    Key key = base;
    key.target = AV_PIX_FMT_BGR24;
    SwsContext* context = Context(key, &bgr_context_, &bgr_key_);
    if (context == nullptr) {
      return UnsupportedError("cannot convert pixel format " + std::string(desc->name) + " to BGR");
    }
    SAKER_RETURN_IF_ERROR(scale(context, CV_8UC3, bgr));
  }
  if (grey != nullptr) {
    if (HasPlainLumaPlane(*desc, frame)) {
      // Fast path: the luma plane is the grey image; one copy, no conversion.
      cv::Mat(height, width, CV_8UC1, frame.data[0], static_cast<size_t>(frame.linesize[0]))
          .copyTo(*grey);
    } else {
      Key key = base;
      key.target = AV_PIX_FMT_GRAY8;
      SwsContext* context = Context(key, &grey_context_, &grey_key_);
      if (context == nullptr) {
        return UnsupportedError("cannot convert pixel format " + std::string(desc->name) +
                                " to grey");
      }
      SAKER_RETURN_IF_ERROR(scale(context, CV_8UC1, grey));
    }
  }
  return Status::Ok();
}

}  // namespace saker::video::internal

namespace saker::video {

void SetFfmpegLogVerbose(bool verbose) {
  av_log_set_level(verbose ? AV_LOG_WARNING : AV_LOG_QUIET);
}

}  // namespace saker::video
