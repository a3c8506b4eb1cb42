#include "tests/core/video/synthetic_ts.h"

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <libavutil/frame.h>
}

#include <algorithm>
#include <random>
#include <string>
#include <system_error>

namespace saker::testing {
namespace {

std::string AvText(int error) {
  char buffer[AV_ERROR_MAX_STRING_SIZE] = {};
  av_strerror(error, buffer, sizeof(buffer));
  return buffer;
}

Status AvError(const std::string& what, int error) {
  return IoError("synthetic MPEG-TS: " + what + ": " + AvText(error));
}

// Everything the writer allocates, freed in one place.
struct Muxer {
  AVFormatContext* format = nullptr;
  AVCodecContext* encoder = nullptr;
  AVFrame* frame = nullptr;
  AVPacket* packet = nullptr;
  AVStream* video = nullptr;
  AVStream* klv = nullptr;

  ~Muxer() {
    av_packet_free(&packet);
    av_frame_free(&frame);
    avcodec_free_context(&encoder);
    if (format != nullptr) {
      if (format->pb != nullptr) avio_closep(&format->pb);
      avformat_free_context(format);
    }
  }

  // Moves every packet the encoder has ready into the file.
  Status Drain() {
    while (true) {
      int ret = avcodec_receive_packet(encoder, packet);
      if (ret == AVERROR(EAGAIN) || ret == AVERROR_EOF) return Status::Ok();
      if (ret < 0) return AvError("encode", ret);
      av_packet_rescale_ts(packet, encoder->time_base, video->time_base);
      packet->stream_index = video->index;
      ret = av_interleaved_write_frame(format, packet);
      if (ret < 0) return AvError("write video packet", ret);
    }
  }
};

void FillFrame(int index, const SyntheticTsOptions& options, AVFrame* frame) {
  const cv::Rect square = SyntheticSquare(index, options);
  const int background = SyntheticBackgroundLuma(index);
  for (int y = 0; y < options.height; ++y) {
    uint8_t* row = frame->data[0] + static_cast<ptrdiff_t>(y) * frame->linesize[0];
    for (int x = 0; x < options.width; ++x) {
      row[x] = static_cast<uint8_t>(square.contains({x, y}) ? kSyntheticSquareLuma : background);
    }
  }
  for (int plane = 1; plane <= 2; ++plane) {
    for (int y = 0; y < (options.height + 1) / 2; ++y) {
      std::fill_n(frame->data[plane] + static_cast<ptrdiff_t>(y) * frame->linesize[plane],
                  (options.width + 1) / 2, uint8_t{128});
    }
  }
}

}  // namespace

Status SyntheticTsOptions::Validate() const {
  if (width < 16 || height < 16 || width > 4096 || height > 4096) {
    return InvalidArgumentError("SyntheticTsOptions: width and height must be in [16, 4096]");
  }
  if (frames < 1 || fps < 1 || gop_size < 1 || b_frames < 0) {
    return InvalidArgumentError("SyntheticTsOptions: frames, fps, gop_size must be positive");
  }
  return Status::Ok();
}

int SyntheticBackgroundLuma(int index) { return 40 + (8 * index) % 160; }

cv::Rect SyntheticSquare(int index, const SyntheticTsOptions& options) {
  const int span = std::max(1, options.width - 16);
  return {4 + (2 * index) % span, options.height / 2 - 4, 8, 8};
}

uint64_t SyntheticKlvTimestampUs(int index) {
  return 1'700'000'000'000'000ULL + static_cast<uint64_t>(index) * 40'000ULL;
}

std::vector<uint8_t> SyntheticKlvPacket(int index) {
  std::vector<uint8_t> bytes = {0x06, 0x0E, 0x2B, 0x34, 0x02, 0x0B, 0x01, 0x01,
                                0x0E, 0x01, 0x03, 0x01, 0x01, 0x00, 0x00, 0x00};
  bytes.push_back(17);  // BER short-form length of the value below
  bytes.push_back(2);   // tag 2: precision time stamp, 8 bytes big-endian
  bytes.push_back(8);
  const uint64_t time_us = SyntheticKlvTimestampUs(index);
  for (int shift = 56; shift >= 0; shift -= 8) bytes.push_back((time_us >> shift) & 0xFF);
  bytes.insert(bytes.end(), {65, 1, 17});  // tag 65: UAS LS version 17
  bytes.insert(bytes.end(), {1, 2});       // tag 1: checksum over everything up to here
  uint16_t sum = 0;
  for (size_t i = 0; i < bytes.size(); ++i) {
    sum = static_cast<uint16_t>(sum + (bytes[i] << (8 * ((i + 1) % 2))));
  }
  bytes.push_back(static_cast<uint8_t>(sum >> 8));
  bytes.push_back(static_cast<uint8_t>(sum & 0xFF));
  return bytes;
}

Status WriteSyntheticTs(const std::filesystem::path& path, const SyntheticTsOptions& options) {
  SAKER_RETURN_IF_ERROR(options.Validate());
  Muxer m;
  const std::string name = path.string();
  int ret = avformat_alloc_output_context2(&m.format, nullptr, "mpegts", name.c_str());
  if (ret < 0) return AvError("mpegts muxer", ret);

  const AVCodec* codec = avcodec_find_encoder(AV_CODEC_ID_MPEG2VIDEO);
  if (codec == nullptr) return UnsupportedError("synthetic MPEG-TS: no MPEG-2 video encoder");
  m.encoder = avcodec_alloc_context3(codec);
  m.encoder->width = options.width;
  m.encoder->height = options.height;
  m.encoder->time_base = AVRational{1, options.fps};
  m.encoder->framerate = AVRational{options.fps, 1};
  m.encoder->pix_fmt = AV_PIX_FMT_YUV420P;
  m.encoder->gop_size = options.gop_size;
  m.encoder->max_b_frames = options.b_frames;
  m.encoder->flags |= AV_CODEC_FLAG_QSCALE;  // constant fine quantiser: near-lossless flat frames
  m.encoder->global_quality = FF_QP2LAMBDA * 2;
  if ((m.format->oformat->flags & AVFMT_GLOBALHEADER) != 0) {
    m.encoder->flags |= AV_CODEC_FLAG_GLOBAL_HEADER;
  }
  ret = avcodec_open2(m.encoder, codec, nullptr);
  if (ret < 0) return AvError("open MPEG-2 encoder", ret);

  m.video = avformat_new_stream(m.format, nullptr);
  ret = avcodec_parameters_from_context(m.video->codecpar, m.encoder);
  if (ret < 0) return AvError("video parameters", ret);
  m.video->time_base = m.encoder->time_base;
  m.video->avg_frame_rate = m.encoder->framerate;

  if (options.with_klv) {
    m.klv = avformat_new_stream(m.format, nullptr);
    m.klv->codecpar->codec_type = AVMEDIA_TYPE_DATA;
    m.klv->codecpar->codec_id = AV_CODEC_ID_SMPTE_KLV;
    m.klv->codecpar->profile =
        options.klv_synchronous ? FF_PROFILE_KLVA_SYNC : FF_PROFILE_KLVA_ASYNC;
    m.klv->time_base = AVRational{1, 90000};
  }

  ret = avio_open(&m.format->pb, name.c_str(), AVIO_FLAG_WRITE);
  if (ret < 0) return AvError("create " + name, ret);
  ret = avformat_write_header(m.format, nullptr);
  if (ret < 0) return AvError("write header", ret);

  m.frame = av_frame_alloc();
  m.packet = av_packet_alloc();
  m.frame->format = AV_PIX_FMT_YUV420P;
  m.frame->width = options.width;
  m.frame->height = options.height;
  ret = av_frame_get_buffer(m.frame, 0);
  if (ret < 0) return AvError("frame buffer", ret);

  for (int i = 0; i < options.frames; ++i) {
    ret = av_frame_make_writable(m.frame);
    if (ret < 0) return AvError("frame buffer", ret);
    FillFrame(i, options, m.frame);
    m.frame->pts = i;
    m.frame->quality = m.encoder->global_quality;
    ret = avcodec_send_frame(m.encoder, m.frame);
    if (ret < 0) return AvError("encode", ret);
    SAKER_RETURN_IF_ERROR(m.Drain());

    if (m.klv != nullptr) {
      std::vector<uint8_t> payload = SyntheticKlvPacket(i);
      if (options.klv_synchronous) {
        // ST 1402 metadata AU cell: service id, sequence number, flags (complete cell, random
        // access), 16-bit cell length.
        const auto length = static_cast<uint16_t>(payload.size());
        const uint8_t header[5] = {0x00, static_cast<uint8_t>(i & 0xFF), 0xDF,
                                   static_cast<uint8_t>(length >> 8),
                                   static_cast<uint8_t>(length & 0xFF)};
        payload.insert(payload.begin(), header, header + 5);
      }
      AVPacket* klv = av_packet_alloc();
      ret = av_new_packet(klv, static_cast<int>(payload.size()));
      if (ret < 0) {
        av_packet_free(&klv);
        return AvError("KLV packet", ret);
      }
      std::copy(payload.begin(), payload.end(), klv->data);
      klv->stream_index = m.klv->index;
      klv->pts = klv->dts = av_rescale_q(i, m.encoder->time_base, m.klv->time_base);
      klv->flags |= AV_PKT_FLAG_KEY;
      ret = av_interleaved_write_frame(m.format, klv);
      av_packet_free(&klv);
      if (ret < 0) return AvError("write KLV packet", ret);
    }
  }
  ret = avcodec_send_frame(m.encoder, nullptr);
  if (ret < 0) return AvError("flush encoder", ret);
  SAKER_RETURN_IF_ERROR(m.Drain());
  ret = av_write_trailer(m.format);
  if (ret < 0) return AvError("write trailer", ret);
  return Status::Ok();
}

}  // namespace saker::testing
