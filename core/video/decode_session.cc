#include "core/video/decode_session.h"

extern "C" {
#include <libavutil/pixdesc.h>
}

#include "core/video/mpegts_pmt.h"

#include <opencv2/core.hpp>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <limits>
#include <map>
#include <system_error>

namespace saker::video::internal {
namespace {

// Reads or decodes in a row that make no progress before a session gives up.
constexpr int kMaxConsecutiveFailures = 10000;

// Size of the AVIOContext buffer for in-memory input (FFmpeg's own default for files).
constexpr int kMemoryIoBufferSize = 32768;

// Calls of DecodeSession::Open, for InputsOpened().
std::atomic<int64_t> inputs_opened{0};

// "file:x.ts" -> "x.ts"; empty for URLs of other protocols.
std::string LocalPath(const std::string& path) {
  if (path.rfind("file:", 0) == 0) return path.substr(5);
  if (path.find("://") != std::string::npos) return {};
  return path;
}

// SessionConfig::max_pixels as FFmpeg's AVCodecContext::max_pixels (an int option).
int64_t DecoderMaxPixels(int64_t max_pixels) {
  return max_pixels > 0 ? std::min<int64_t>(max_pixels, std::numeric_limits<int>::max())
                        : std::numeric_limits<int>::max();
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
  // FFmpeg would wait for ever on a FIFO with no writer (and a device or socket is no recording):
  // a live stream is given by its URL.
  if (!fs::is_regular_file(status)) {
    const char* kind = fs::is_fifo(status)             ? "a FIFO (named pipe)"
                       : fs::is_socket(status)         ? "a socket"
                       : fs::is_character_file(status) ? "a character device"
                       : fs::is_block_file(status)     ? "a block device"
                                                       : "a special file";
    return InvalidArgumentError(path + ": is " + kind +
                                ", not a video file; Saker reads recorded files (a live stream by "
                                "its URL, e.g. udp://...)");
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

// The elementary stream_type of each PID, from the program map tables at the start of a
// transport stream with KLV (SessionConfig::probe_klv_sync: FFmpeg 5.1 does not tell synchronous
// KLV from asynchronous); empty for other inputs and for URLs.
std::map<int, int> PmtStreamTypes(const AVFormatContext& format, bool is_mpegts,
                                  const std::string& path, const SessionConfig& config) {
  bool klv_present = false;
  for (unsigned i = 0; i < format.nb_streams; ++i) {
    klv_present |= format.streams[i]->codecpar->codec_id == AV_CODEC_ID_SMPTE_KLV;
  }
  if (!config.probe_klv_sync || !is_mpegts || !klv_present) return {};
  if (config.memory) {
    // As ScanPmtStreamTypesInFile does for a file: the PMTs are at the start.
    return ScanPmtStreamTypes(config.memory->data(),
                              std::min<size_t>(config.memory->size(), 4 << 20));
  }
  const std::string local = LocalPath(path);
  if (local.empty()) return {};
  StatusOr<std::map<int, int>> types = ScanPmtStreamTypesInFile(local);
  return types.ok() ? std::move(types).value() : std::map<int, int>();
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

// The chroma planes of an 8-bit YUV picture (planar, or semi-planar as NV12 / NV21), Cb and Cr
// interleaved; empty for any other layout.
cv::Mat CopyChroma(const AVPixFmtDescriptor& desc, const AVFrame& frame) {
  constexpr uint64_t kNotYuv =
      AV_PIX_FMT_FLAG_RGB | AV_PIX_FMT_FLAG_PAL | AV_PIX_FMT_FLAG_BAYER | AV_PIX_FMT_FLAG_HWACCEL;
  if ((desc.flags & kNotYuv) != 0 || desc.nb_components < 3) return {};
  const AVComponentDescriptor& cb = desc.comp[1];
  const AVComponentDescriptor& cr = desc.comp[2];
  if (cb.depth != 8 || cr.depth != 8 || cb.shift != 0 || cr.shift != 0) return {};
  const int width = AV_CEIL_RSHIFT(frame.width, desc.log2_chroma_w);
  const int height = AV_CEIL_RSHIFT(frame.height, desc.log2_chroma_h);
  const auto plane = [&](int index, int type) {
    const uint8_t* data = frame.data[index];
    const int stride = frame.linesize[index];
    const int bytes_per_pixel = CV_ELEM_SIZE(type);
    if (data == nullptr || stride < width * bytes_per_pixel) return cv::Mat();
    return cv::Mat(height, width, type, const_cast<uint8_t*>(data), static_cast<size_t>(stride));
  };
  cv::Mat out;
  if (cb.plane != cr.plane && cb.step == 1 && cr.step == 1 && cb.offset == 0 && cr.offset == 0) {
    const cv::Mat u = plane(cb.plane, CV_8UC1);
    const cv::Mat v = plane(cr.plane, CV_8UC1);
    if (u.empty() || v.empty()) return {};
    cv::merge(std::vector<cv::Mat>{u, v}, out);
  } else if (cb.plane == cr.plane && cb.step == 2 && cr.step == 2 &&
             ((cb.offset == 0 && cr.offset == 1) || (cb.offset == 1 && cr.offset == 0))) {
    const cv::Mat uv = plane(cb.plane, CV_8UC2);
    if (uv.empty()) return {};
    if (cb.offset == 0) {
      out = uv.clone();
    } else {
      const int swap[] = {0, 1, 1, 0};
      out.create(uv.size(), CV_8UC2);
      cv::mixChannels(&uv, 1, &out, 1, swap, 2);
    }
  }
  return out;
}

YuvMatrix MatrixOf(int sws_colorspace) {
  switch (sws_colorspace) {
    case SWS_CS_ITU709:
      return YuvMatrix::kBt709;
    case SWS_CS_BT2020:
      return YuvMatrix::kBt2020;
    default:
      return YuvMatrix::kBt601;
  }
}

}  // namespace

std::string AvErrorText(int error) {
  char buffer[AV_ERROR_MAX_STRING_SIZE] = {};
  if (av_strerror(error, buffer, sizeof(buffer)) < 0 || buffer[0] == '\0') {
    return "error " + std::to_string(error);
  }
  return buffer;
}

namespace {

// AVIOContext callbacks over MemoryCursor: a plain read-only file in memory.
int ReadMemory(void* opaque, uint8_t* buffer, int buffer_size) {
  auto* cursor = static_cast<MemoryCursor*>(opaque);
  const auto size = static_cast<int64_t>(cursor->bytes->size());
  if (buffer_size <= 0) return 0;
  if (cursor->position >= size) return AVERROR_EOF;
  const int64_t count = std::min<int64_t>(buffer_size, size - cursor->position);
  std::memcpy(buffer, cursor->bytes->data() + cursor->position, static_cast<size_t>(count));
  cursor->position += count;
  return static_cast<int>(count);
}

int64_t SeekMemory(void* opaque, int64_t offset, int whence) {
  auto* cursor = static_cast<MemoryCursor*>(opaque);
  const auto size = static_cast<int64_t>(cursor->bytes->size());
  whence &= ~AVSEEK_FORCE;
  if (whence == AVSEEK_SIZE) return size;
  int64_t base = 0;
  switch (whence) {
    case SEEK_SET:
      base = 0;
      break;
    case SEEK_CUR:
      base = cursor->position;
      break;
    case SEEK_END:
      base = size;
      break;
    default:
      return AVERROR(EINVAL);
  }
  // Only positions inside [0, size]; written so that no hostile offset can overflow.
  if (offset < 0 ? offset < -base : offset > size - base) return AVERROR(EINVAL);
  cursor->position = base + offset;
  return cursor->position;
}

}  // namespace

StatusOr<std::unique_ptr<DecodeSession>> DecodeSession::Open(const std::string& path,
                                                             const SessionConfig& config) {
  inputs_opened.fetch_add(1, std::memory_order_relaxed);
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
  if (config.memory) {
    if (config.memory->empty()) return InvalidDataError(path + ": empty (0 bytes), not a video");
  } else {
    SAKER_RETURN_IF_ERROR(CheckLocalFile(path));
  }
  SAKER_RETURN_IF_ERROR(OpenContainer());
  const AVCodec* codec = nullptr;
  SAKER_RETURN_IF_ERROR(FindVideoStream(&codec));
  DescribeStreams();
  return OpenDecoder(codec);
}

Status DecodeSession::OpenContainer() {
  AVFormatContext* raw_format = nullptr;
  int ret = OpenInput(&raw_format);
  if (ret < 0) return OpenError(path_, ret);
  format_.reset(raw_format);
  // Probing decodes a few pictures: FFmpeg's own limit keeps a stream that declares an absurd
  // size from allocating it before FindVideoStream can refuse it.
  std::vector<AVDictionary*> probe_options(format_->nb_streams, nullptr);
  const std::string max_pixels = std::to_string(DecoderMaxPixels(config_.max_pixels));
  for (AVDictionary*& options : probe_options) {
    av_dict_set(&options, "max_pixels", max_pixels.c_str(), 0);
  }
  ret = avformat_find_stream_info(format_.get(),
                                  probe_options.empty() ? nullptr : probe_options.data());
  for (AVDictionary*& options : probe_options) av_dict_free(&options);
  if (ret < 0) {
    return InvalidDataError(path_ + ": cannot read the stream layout (FFmpeg: " + AvErrorText(ret) +
                            ")");
  }
  const AVFormatContext& format = *format_;
  info_.container = format.iformat->name ? format.iformat->name : "";
  info_.container_long = format.iformat->long_name ? format.iformat->long_name : "";
  info_.duration_s =
      format.duration != AV_NOPTS_VALUE ? static_cast<double>(format.duration) / AV_TIME_BASE : 0;
  return Status::Ok();
}

Status DecodeSession::FindVideoStream(const AVCodec** codec) {
  const AVFormatContext& format = *format_;
  const int ret = av_find_best_stream(format_.get(), AVMEDIA_TYPE_VIDEO, -1, -1, codec, 0);
  if (ret == AVERROR_DECODER_NOT_FOUND) {
    // Name the codec of the first video stream: that is the one the user expected.
    std::string name = "unknown";
    for (unsigned i = 0; i < format.nb_streams; ++i) {
      if (format.streams[i]->codecpar->codec_type == AVMEDIA_TYPE_VIDEO) {
        name = avcodec_get_name(format.streams[i]->codecpar->codec_id);
        break;
      }
    }
    return UnsupportedError(path_ + ": no decoder for video codec '" + name +
                            "' in this FFmpeg build");
  }
  if (ret < 0) {
    return InvalidDataError(path_ + " has no video stream (container " + info_.container + ", " +
                            std::to_string(format.nb_streams) + " streams)");
  }
  video_ = format.streams[ret];
  const AVCodecParameters& parameters = *video_->codecpar;
  info_.video_stream = video_->index;
  info_.video_codec = avcodec_get_name(parameters.codec_id);
  info_.width = parameters.width;
  info_.height = parameters.height;
  // FFmpeg opens a single picture (PNG, JPEG, ... through its image demuxers) as a video of one
  // frame. No recording is one picture: refuse it plainly rather than make an empty mission.
  if (info_.container == "image2" || info_.container.ends_with("_pipe")) {
    return InvalidDataError(path_ + ": is a still picture (" + info_.video_codec +
                            "), not a video");
  }
  if (info_.width <= 0 || info_.height <= 0) {
    // FFmpeg also leaves the size unset when the header declares one it refuses (beyond its own
    // limits or max_pixels), so say both.
    return InvalidDataError(path_ + " has no video stream that can be decoded: its " +
                            info_.video_codec +
                            " stream has no valid picture size (no picture header, a damaged "
                            "one, or a declared picture size beyond max_pixels = " +
                            std::to_string(config_.max_pixels) + ")");
  }
  const int64_t pixels = static_cast<int64_t>(info_.width) * info_.height;
  if (pixels > config_.max_pixels) {
    return InvalidDataError(path_ + ": declared picture size " + std::to_string(info_.width) + "x" +
                            std::to_string(info_.height) + " exceeds max_pixels (" +
                            std::to_string(config_.max_pixels) + ")");
  }
  info_.fps = FrameRate(*video_);
  info_.declared_frame_count = video_->nb_frames > 0 ? video_->nb_frames : 0;
  start_pts_ = video_->start_time != AV_NOPTS_VALUE ? video_->start_time : 0;
  info_.start_time_s = static_cast<double>(start_pts_) * av_q2d(video_->time_base);
  const double fps = info_.fps > 0 ? info_.fps : 25.0;
  frame_step_ = std::max<int64_t>(1, std::llround(1.0 / (fps * av_q2d(video_->time_base))));
  return Status::Ok();
}

void DecodeSession::DescribeStreams() {
  AVFormatContext* format = format_.get();
  // PIDs are only meaningful for transport streams.
  const bool is_mpegts = info_.container == "mpegts";
  const std::map<int, int> pmt_stream_types = PmtStreamTypes(*format, is_mpegts, path_, config_);
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
    const bool keep = stream == video_ || (config_.keep_klv && is_klv_[i]);
    stream->discard = keep ? AVDISCARD_DEFAULT : AVDISCARD_ALL;
    info_.streams.push_back(std::move(stream_info));
  }
}

Status DecodeSession::OpenDecoder(const AVCodec* codec) {
  decoder_.reset(avcodec_alloc_context3(codec));
  packet_.reset(av_packet_alloc());
  pending_.reset(av_packet_alloc());
  frame_.reset(av_frame_alloc());
  if (!decoder_ || !packet_ || !pending_ || !frame_) {
    return IoError(path_ + ": out of memory opening the decoder");
  }
  int ret = avcodec_parameters_to_context(decoder_.get(), video_->codecpar);
  if (ret < 0) {
    return InvalidDataError(path_ + ": bad " + info_.video_codec +
                            " stream parameters (FFmpeg: " + AvErrorText(ret) + ")");
  }
  decoder_->pkt_timebase = video_->time_base;
  decoder_->thread_count = config_.decoder_threads;
  decoder_->max_pixels = DecoderMaxPixels(config_.max_pixels);  // a size change mid-stream too
  ret = avcodec_open2(decoder_.get(), codec, nullptr);
  if (ret < 0) {
    return UnsupportedError(path_ + ": cannot open the " + info_.video_codec +
                            " decoder (FFmpeg: " + AvErrorText(ret) + ")");
  }
  return Status::Ok();
}

int DecodeSession::OpenInput(AVFormatContext** format) {
  if (!config_.memory) return avformat_open_input(format, path_.c_str(), nullptr, nullptr);
  memory_cursor_ = std::make_unique<MemoryCursor>();
  memory_cursor_->bytes = config_.memory;
  auto* buffer = static_cast<uint8_t*>(av_malloc(kMemoryIoBufferSize));
  if (buffer == nullptr) return AVERROR(ENOMEM);
  io_.reset(avio_alloc_context(buffer, kMemoryIoBufferSize, /*write_flag=*/0, memory_cursor_.get(),
                               &ReadMemory, nullptr, &SeekMemory));
  if (!io_) {
    av_free(buffer);
    return AVERROR(ENOMEM);
  }
  *format = avformat_alloc_context();
  if (*format == nullptr) return AVERROR(ENOMEM);
  // A caller-owned pb: avformat_close_input leaves it to io_ (AVFMT_FLAG_CUSTOM_IO), and on
  // failure avformat_open_input frees the format context itself.
  (*format)->pb = io_.get();
  (*format)->flags |= AVFMT_FLAG_CUSTOM_IO;
  return avformat_open_input(format, path_.c_str(), nullptr, nullptr);
}

double DecodeSession::SecondsFromStart(int64_t pts) const {
  const AVRational time_base = video_->time_base;
  return static_cast<double>(pts - start_pts_) * time_base.num / time_base.den;
}

int64_t DecodeSession::RawTimestamp() const {
  return frame_->pts != AV_NOPTS_VALUE ? frame_->pts : frame_->best_effort_timestamp;
}

void DecodeSession::AppendDataPacket(const AVPacket& packet, int64_t offset,
                                     std::vector<DataPacket>* data) const {
  DataPacket out;
  out.stream_index = packet.stream_index;
  out.pts = packet.pts;  // AV_NOPTS_VALUE is INT64_MIN
  out.byte_pos = packet.pos;
  if (packet.pts == AV_NOPTS_VALUE) {
    out.time_s = std::numeric_limits<double>::quiet_NaN();
  } else {
    const AVStream* stream = format_->streams[packet.stream_index];
    if (offset != 0) out.pts += av_rescale_q(offset, video_->time_base, stream->time_base);
    out.time_s =
        SecondsFromStart(av_rescale_q(packet.pts, stream->time_base, video_->time_base) + offset);
  }
  out.bytes.assign(packet.data, packet.data + packet.size);
  data->push_back(std::move(out));
}

int64_t DecodeSession::VideoTicks(const AVPacket& packet) const {
  const int64_t pts = packet.pts != AV_NOPTS_VALUE ? packet.pts : packet.dts;
  if (pts == AV_NOPTS_VALUE) return AV_NOPTS_VALUE;
  return av_rescale_q(pts, format_->streams[packet.stream_index]->time_base, video_->time_base);
}

void DecodeSession::HoldDataPacket(const AVPacket& packet) {
  HeldPacket held;
  held.packet.reset(av_packet_clone(&packet));
  if (!held.packet) return;  // out of memory: lose this metadata packet, not the video
  held.raw = VideoTicks(packet);
  held_.push_back(std::move(held));
}

void DecodeSession::ReleaseHeldData(int64_t old_offset, int64_t new_offset, int64_t old_last_raw,
                                    int64_t new_first_raw, std::vector<DataPacket>* data,
                                    ReadStats* stats) {
  for (const HeldPacket& held : held_) {
    // A packet that arrived just before the jump belongs with the pictures nearest in raw time:
    // encoders send metadata just before its picture, so the new recording's first packets
    // precede its first picture.
    int64_t offset = new_offset;
    if (old_offset != new_offset && held.raw != AV_NOPTS_VALUE) {
      const bool nearer_new =
          std::llabs(held.raw - new_first_raw) < std::llabs(held.raw - old_last_raw);
      offset = nearer_new ? new_offset : old_offset;
    }
    if (data != nullptr) {
      AppendDataPacket(*held.packet, offset, data);
      if (stats != nullptr) ++stats->data_packets;
    }
  }
  held_.clear();
}

void DecodeSession::JoinDiscontinuity(AVPacket* packet, std::vector<DataPacket>* data,
                                      ReadStats* stats) {
  const int64_t raw = VideoTicks(*packet);
  const int64_t old_offset = offset_;
  const int64_t old_last_raw = last_video_raw_;
  if (raw != AV_NOPTS_VALUE) {
    // Further back than pictures are ever reordered (H.264 allows 16 frames; at very slow rates
    // that is many seconds) and than one second: the timestamps restarted. Carry on one frame
    // after the latest picture.
    const int64_t one_second = std::max<int64_t>(1, std::llround(1.0 / av_q2d(video_->time_base)));
    const int64_t reordering = std::max(one_second, 16 * std::max<int64_t>(frame_step_, 1));
    if (max_video_pts_ != AV_NOPTS_VALUE && raw + offset_ < max_video_pts_ - reordering) {
      offset_ = max_video_pts_ + frame_step_ - raw;
      if (stats != nullptr) ++stats->timestamp_discontinuities;
    }
    max_video_pts_ =
        max_video_pts_ == AV_NOPTS_VALUE ? raw + offset_ : std::max(max_video_pts_, raw + offset_);
    last_video_raw_ = raw;
  }
  ReleaseHeldData(old_offset, offset_, old_last_raw, raw, data, stats);
  if (offset_ != 0) {  // the packet is the video stream's: offset_ is in its time base
    if (packet->pts != AV_NOPTS_VALUE) packet->pts += offset_;
    if (packet->dts != AV_NOPTS_VALUE) packet->dts += offset_;
  }
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
      ReleaseHeldData(offset_, offset_, 0, 0, data, stats);
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
        if (config_.join_discontinuities) JoinDiscontinuity(packet, data, stats);
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
      } else if (config_.join_discontinuities) {
        HoldDataPacket(*packet);
      } else {
        AppendDataPacket(*packet, 0, data);
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

Status FrameConverter::Convert(const AVFrame& frame, cv::Mat* bgr, cv::Mat* grey, cv::Mat* chroma,
                               YuvCoding* coding) {
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
  if (chroma != nullptr) {
    // Only with the luma plane as coded: the two must code colour together.
    *chroma = HasPlainLumaPlane(*desc, frame) ? CopyChroma(*desc, frame) : cv::Mat();
  }
  if (coding != nullptr) *coding = {MatrixOf(base.colorspace), full_range};
  return Status::Ok();
}

}  // namespace saker::video::internal

namespace saker::video {

void SetFfmpegLogVerbose(bool verbose) {
  av_log_set_level(verbose ? AV_LOG_WARNING : AV_LOG_QUIET);
}

int64_t InputsOpened() { return internal::inputs_opened.load(std::memory_order_relaxed); }

}  // namespace saker::video
