#include "core/tiles/image_decode.h"

#include <opencv2/imgcodecs.hpp>

#include <array>
#include <cstring>
#include <new>
#include <string>

namespace saker::tiles {
namespace {

// The signature, then the first chunk: length (13), type "IHDR", width and height (big-endian).
constexpr std::array<uint8_t, 8> kPngSignature = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
constexpr size_t kIhdrType = 12;
constexpr size_t kIhdrWidth = 16;
constexpr size_t kIhdrEnd = 24;

uint32_t BigEndian32(const uint8_t* p) {
  return (static_cast<uint32_t>(p[0]) << 24) | (static_cast<uint32_t>(p[1]) << 16) |
         (static_cast<uint32_t>(p[2]) << 8) | static_cast<uint32_t>(p[3]);
}

uint32_t BigEndian16(const uint8_t* p) {
  return (static_cast<uint32_t>(p[0]) << 8) | static_cast<uint32_t>(p[1]);
}

std::string SizeText(int64_t width, int64_t height) {
  return std::to_string(width) + "x" + std::to_string(height);
}

// Decodes an image whose header declared `size` (`kind` names its format in messages), once the
// size is within `limits`.
StatusOr<cv::Mat> DecodeChecked(const std::vector<uint8_t>& bytes, int flags,
                                const ImageLimits& limits, cv::Size size, const char* kind) {
  const int64_t pixels = static_cast<int64_t>(size.width) * size.height;
  if (size.width > limits.max_width || size.height > limits.max_height ||
      pixels > limits.max_pixels) {
    return InvalidDataError(
        std::string("the ") + kind + " header declares " + SizeText(size.width, size.height) +
        " pixels, more than the record may hold (" + SizeText(limits.max_width, limits.max_height) +
        ", " + std::to_string(limits.max_pixels) + " pixels at most)");
  }
  const auto out_of_memory = [&] {
    return ResourceExhaustedError("out of memory decoding a " + SizeText(size.width, size.height) +
                                  " " + kind + " image");
  };
  cv::Mat image;
  try {
    image = cv::imdecode(bytes, flags);
  } catch (const std::bad_alloc&) {
    return out_of_memory();
  } catch (const cv::Exception& e) {
    if (e.code == cv::Error::StsNoMem) return out_of_memory();
    return InvalidDataError(std::string("the ") + kind + " image cannot be decoded (" + e.msg +
                            ")");
  }
  if (image.empty())
    return InvalidDataError(std::string("the ") + kind + " image cannot be decoded");
  if (image.cols != size.width || image.rows != size.height) {
    return InvalidDataError(std::string("the ") + kind + " image decodes to " +
                            SizeText(image.cols, image.rows) + ", not the " +
                            SizeText(size.width, size.height) + " of its header");
  }
  return image;
}

}  // namespace

StatusOr<cv::Size> ReadPngSize(const std::vector<uint8_t>& bytes) {
  if (bytes.size() < kIhdrEnd ||
      std::memcmp(bytes.data(), kPngSignature.data(), kPngSignature.size()) != 0 ||
      std::memcmp(bytes.data() + kIhdrType, "IHDR", 4) != 0) {
    return InvalidDataError("not a PNG image (" + std::to_string(bytes.size()) + " bytes)");
  }
  const uint32_t width = BigEndian32(bytes.data() + kIhdrWidth);
  const uint32_t height = BigEndian32(bytes.data() + kIhdrWidth + 4);
  // PNG allows 1 .. 2^31 - 1 per side.
  if (width == 0 || height == 0 || width > 0x7fffffffU || height > 0x7fffffffU) {
    return InvalidDataError("the PNG header declares an impossible size " +
                            SizeText(width, height));
  }
  return cv::Size(static_cast<int>(width), static_cast<int>(height));
}

StatusOr<cv::Size> ReadJpegSize(const std::vector<uint8_t>& bytes) {
  const size_t n = bytes.size();
  const auto not_jpeg = [&] {
    return InvalidDataError("not a JPEG image (" + std::to_string(n) + " bytes)");
  };
  if (!IsJpeg(bytes)) return not_jpeg();
  // Markers after the start of image (FF D8): standalone ones (TEM, RSTn) have no length; every
  // other one a big-endian length that counts itself. The first start of frame holds the size.
  size_t at = 2;
  while (at < n) {
    if (bytes[at] != 0xFF) return not_jpeg();
    while (at < n && bytes[at] == 0xFF) ++at;  // fill bytes
    if (at >= n) break;
    const uint8_t marker = bytes[at++];
    if (marker == 0x01 || (marker >= 0xD0 && marker <= 0xD7)) continue;
    if (marker == 0xD8 || marker == 0xD9 || marker == 0xDA) break;  // no frame before the scan
    if (n - at < 2) break;
    const uint32_t length = BigEndian16(bytes.data() + at);
    if (length < 2 || length > n - at) break;
    const bool start_of_frame =
        marker >= 0xC0 && marker <= 0xCF && marker != 0xC4 && marker != 0xC8 && marker != 0xCC;
    if (start_of_frame) {
      if (length < 7) break;
      const uint32_t height = BigEndian16(bytes.data() + at + 3);
      const uint32_t width = BigEndian16(bytes.data() + at + 5);
      if (width == 0 || height == 0) {
        return InvalidDataError("the JPEG header declares an impossible size " +
                                SizeText(width, height));
      }
      return cv::Size(static_cast<int>(width), static_cast<int>(height));
    }
    at += length;
  }
  return InvalidDataError("the JPEG image has no readable frame header (" + std::to_string(n) +
                          " bytes)");
}

bool IsJpeg(const std::vector<uint8_t>& bytes) {
  return bytes.size() >= 4 && bytes[0] == 0xFF && bytes[1] == 0xD8 && bytes[2] == 0xFF;
}

StatusOr<cv::Mat> DecodeJpeg(const std::vector<uint8_t>& bytes, int flags,
                             const ImageLimits& limits) {
  SAKER_ASSIGN_OR_RETURN(const cv::Size size, ReadJpegSize(bytes));
  return DecodeChecked(bytes, flags, limits, size, "JPEG");
}

StatusOr<cv::Mat> DecodePng(const std::vector<uint8_t>& bytes, int flags,
                            const ImageLimits& limits) {
  SAKER_ASSIGN_OR_RETURN(const cv::Size size, ReadPngSize(bytes));
  return DecodeChecked(bytes, flags, limits, size, "PNG");
}

}  // namespace saker::tiles
