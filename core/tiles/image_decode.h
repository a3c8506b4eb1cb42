#pragma once

// Bounded decoding of the PNG and JPEG images Saker stores in a mission (mosaic tiles, checkpoint
// key frame images). cv::imdecode allocates whatever a header declares: a 100-byte PNG that claims
// 40000 x 40000 pixels asks for gigabytes and throws, or exhausts memory. The size is read from
// the header first and checked against what the record must hold; only then is it decoded, and
// any exception of the decoder becomes an error (docs/reliability.md, "Hostile inputs").

#include "core/util/status.h"

#include <opencv2/core/mat.hpp>

#include <cstdint>
#include <vector>

namespace saker::tiles {

// The largest picture a stored image may declare. Each limit must be positive.
struct ImageLimits {
  int64_t max_width = 0;   // pixels
  int64_t max_height = 0;  // pixels
  int64_t max_pixels = 0;  // width x height, at most
};

// The width and height a PNG declares in its header (the IHDR chunk), read without decoding.
// InvalidData when the bytes do not start like a PNG.
StatusOr<cv::Size> ReadPngSize(const std::vector<uint8_t>& bytes);

// Decodes a PNG (`flags` as for cv::imdecode) whose declared size is within `limits`. InvalidData
// for other bytes, a larger declared size, or a decoder failure; ResourceExhausted when memory
// runs out while decoding. Messages say what is wrong; callers prefix the file and the record.
StatusOr<cv::Mat> DecodePng(const std::vector<uint8_t>& bytes, int flags,
                            const ImageLimits& limits);

// Whether the bytes start like a JPEG image (FF D8 FF).
bool IsJpeg(const std::vector<uint8_t>& bytes);

// The width and height a JPEG declares in its first frame header (SOFn), read by walking the
// markers before it, every length checked against the bytes. InvalidData when the bytes do not
// start like a JPEG or end (or reach a scan) before a frame header.
StatusOr<cv::Size> ReadJpegSize(const std::vector<uint8_t>& bytes);

// Decodes a JPEG as DecodePng decodes a PNG.
StatusOr<cv::Mat> DecodeJpeg(const std::vector<uint8_t>& bytes, int flags,
                             const ImageLimits& limits);

}  // namespace saker::tiles
