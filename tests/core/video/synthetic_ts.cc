#include "tests/core/video/synthetic_ts.h"

#include "core/klv/st0601_encode.h"
#include "core/util/check.h"
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
  StatusOr<std::vector<uint8_t>> bytes = klv::St0601Encoder()
                                             .AddUnsigned(2, SyntheticKlvTimestampUs(index))
                                             .AddUnsigned(65, 17)
                                             .Finish();
  SAKER_CHECK(bytes.ok()) << bytes.status().ToString();
  return *bytes;
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
