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

std::string SizeText(int64_t width, int64_t height) {
  return std::to_string(width) + "x" + std::to_string(height);
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

StatusOr<cv::Mat> DecodePng(const std::vector<uint8_t>& bytes, int flags,
                            const ImageLimits& limits) {
  SAKER_ASSIGN_OR_RETURN(const cv::Size size, ReadPngSize(bytes));
  const int64_t pixels = static_cast<int64_t>(size.width) * size.height;
  if (size.width > limits.max_width || size.height > limits.max_height ||
      pixels > limits.max_pixels) {
    return InvalidDataError("the PNG header declares " + SizeText(size.width, size.height) +
                            " pixels, more than the record may hold (" +
                            SizeText(limits.max_width, limits.max_height) + ", " +
                            std::to_string(limits.max_pixels) + " pixels at most)");
  }
  const auto out_of_memory = [&] {
    return ResourceExhaustedError("out of memory decoding a " + SizeText(size.width, size.height) +
                                  " PNG image");
  };
  cv::Mat image;
  try {
    image = cv::imdecode(bytes, flags);
  } catch (const std::bad_alloc&) {
    return out_of_memory();
  } catch (const cv::Exception& e) {
    if (e.code == cv::Error::StsNoMem) return out_of_memory();
    return InvalidDataError("the PNG image cannot be decoded (" + e.msg + ")");
  }
  if (image.empty()) return InvalidDataError("the PNG image cannot be decoded");
  if (image.cols != size.width || image.rows != size.height) {
    return InvalidDataError("the PNG image decodes to " + SizeText(image.cols, image.rows) +
                            ", not the " + SizeText(size.width, size.height) + " of its header");
  }
  return image;
}

}  // namespace saker::tiles
