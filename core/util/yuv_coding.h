#pragma once

// How a video codes its colour: the matrix from R'G'B' to luma and chroma, and the range of the
// values. Carried from the decoder to whatever turns a luma plane and its chroma back into a
// colour picture (the key frames' pictures of the mosaic).

#include <cstdint>

namespace saker {

enum class YuvMatrix : uint8_t {
  kBt601 = 0,   // SD video, and the usual reading of an unspecified SD stream
  kBt709 = 1,   // HD video, and the usual reading of an unspecified HD stream
  kBt2020 = 2,  // UHD (non-constant luminance)
};

struct YuvCoding {
  YuvMatrix matrix = YuvMatrix::kBt601;
  // False: limited ("video") range, luma 16-235 and chroma 16-240; true: 0-255 for both.
  bool full_range = false;
  bool operator==(const YuvCoding&) const = default;
};

}  // namespace saker
