#include "tests/core/video/synthetic_ts.h"

#include "core/video/ts_writer.h"

#include <opencv2/core.hpp>

#include <algorithm>
#include <memory>

namespace saker::testing {

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
  video::TsWriterOptions writer_options;
  writer_options.codec = video::VideoCodec::kMpeg2;
  writer_options.width = options.width;
  writer_options.height = options.height;
  writer_options.fps_num = options.fps;
  writer_options.fps_den = 1;
  writer_options.gop_size = options.gop_size;
  writer_options.b_frames = options.b_frames;
  writer_options.mpeg2_qscale = 2;  // fine constant quantiser: near-lossless flat frames
  writer_options.threads = 1;
  writer_options.with_klv = options.with_klv;
  writer_options.klv_synchronous = options.klv_synchronous;
  auto opened = video::TsWriter::Open(path, writer_options);
  if (!opened.ok()) return opened.status();
  std::unique_ptr<video::TsWriter> writer = std::move(opened).value();

  // Luma as coded (TsWriter writes a CV_8UC1 image as the luma plane, chroma neutral).
  cv::Mat luma(options.height, options.width, CV_8UC1);
  const cv::Rect image(0, 0, options.width, options.height);
  for (int i = 0; i < options.frames; ++i) {
    if (options.with_klv) SAKER_RETURN_IF_ERROR(writer->WriteKlv(SyntheticKlvPacket(i), i));
    luma.setTo(SyntheticBackgroundLuma(i));
    luma(SyntheticSquare(i, options) & image).setTo(kSyntheticSquareLuma);
    SAKER_RETURN_IF_ERROR(writer->WriteFrame(luma));
  }
  return writer->Close();
}

}  // namespace saker::testing
