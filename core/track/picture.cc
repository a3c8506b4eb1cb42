#include "core/track/picture.h"

#include "core/util/check.h"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>

namespace saker::track {
namespace {

// The luma weights of red and blue; green's is what remains.
struct LumaWeights {
  double red, blue;
};

LumaWeights WeightsOf(YuvMatrix matrix) {
  switch (matrix) {
    case YuvMatrix::kBt709:
      return {0.2126, 0.0722};
    case YuvMatrix::kBt2020:
      return {0.2627, 0.0593};
    case YuvMatrix::kBt601:
      break;
  }
  return {0.299, 0.114};
}

// The contributions of each coded value to the 0-255 outputs, as tables.
struct Tables {
  std::array<float, 256> luma{};      // Y -> the common part of B, G, R
  std::array<float, 256> cr_red{};    // Cr -> R
  std::array<float, 256> cr_green{};  // Cr -> G
  std::array<float, 256> cb_green{};  // Cb -> G
  std::array<float, 256> cb_blue{};   // Cb -> B
};

Tables TablesOf(const YuvCoding& coding) {
  const LumaWeights k = WeightsOf(coding.matrix);
  const double green = 1 - k.red - k.blue;
  const double luma_offset = coding.full_range ? 0 : 16;
  const double luma_span = coding.full_range ? 255 : 219;
  const double chroma_span = coding.full_range ? 255 : 224;
  Tables t;
  for (int v = 0; v < 256; ++v) {
    const auto i = static_cast<size_t>(v);
    t.luma[i] = static_cast<float>((v - luma_offset) / luma_span * 255);
    const double c = (v - 128) / chroma_span * 255;  // -127.5 .. 127.5 in output units
    t.cr_red[i] = static_cast<float>(2 * (1 - k.red) * c);
    t.cb_blue[i] = static_cast<float>(2 * (1 - k.blue) * c);
    t.cr_green[i] = static_cast<float>(-2 * k.red * (1 - k.red) / green * c);
    t.cb_green[i] = static_cast<float>(-2 * k.blue * (1 - k.blue) / green * c);
  }
  return t;
}

uint8_t Clip(float v) { return static_cast<uint8_t>(std::clamp(std::lround(v), 0L, 255L)); }

}  // namespace

bool NeutralChroma(const cv::Mat& chroma, int tolerance) {
  if (chroma.empty()) return true;
  SAKER_CHECK(chroma.type() == CV_8UC2) << "chroma must be CV_8UC2";
  double low = 0, high = 0;
  cv::minMaxLoc(chroma.reshape(1), &low, &high);
  return low >= 128 - tolerance && high <= 128 + tolerance;
}

cv::Mat YuvToBgr(const cv::Mat& luma, const cv::Mat& chroma, const YuvCoding& coding) {
  SAKER_CHECK(luma.type() == CV_8UC1) << "luma must be CV_8UC1";
  SAKER_CHECK(chroma.empty() || chroma.type() == CV_8UC2) << "chroma must be CV_8UC2";
  cv::Mat full;
  if (chroma.empty()) {
    full = cv::Mat(luma.size(), CV_8UC2, cv::Scalar(128, 128));
  } else if (chroma.size() == luma.size()) {
    full = chroma;
  } else {
    cv::resize(chroma, full, luma.size(), 0, 0, cv::INTER_LINEAR);
  }
  const Tables t = TablesOf(coding);
  cv::Mat bgr(luma.size(), CV_8UC3);
  for (int v = 0; v < luma.rows; ++v) {
    const uint8_t* y = luma.ptr<uint8_t>(v);
    const uint8_t* c = full.ptr<uint8_t>(v);
    uint8_t* out = bgr.ptr<uint8_t>(v);
    for (int u = 0; u < luma.cols; ++u, c += 2, out += 3) {
      const float base = t.luma[y[u]];
      out[0] = Clip(base + t.cb_blue[c[0]]);
      out[1] = Clip(base + t.cb_green[c[0]] + t.cr_green[c[1]]);
      out[2] = Clip(base + t.cr_red[c[1]]);
    }
  }
  return bgr;
}

void MakeKeyFramePicture(const cv::Mat& grey, const cv::Mat& chroma, const YuvCoding& coding,
                         int width, KeyFrameImage* image) {
  SAKER_CHECK(width > 0 && !grey.empty()) << "a key frame picture needs a width and a picture";
  image->scale = std::max(1.0, static_cast<double>(grey.cols) / width);
  cv::resize(grey, image->grey, cv::Size(), 1.0 / image->scale, 1.0 / image->scale, cv::INTER_AREA);
  image->chroma.release();
  image->coding = coding;
  if (chroma.empty()) return;
  const cv::Size half((image->grey.cols + 1) / 2, (image->grey.rows + 1) / 2);
  cv::Mat small;
  cv::resize(chroma, small, half, 0, 0,
             chroma.cols > half.width ? cv::INTER_AREA : cv::INTER_LINEAR);
  if (!NeutralChroma(small)) image->chroma = small;
}

cv::Mat KeyFrameBgr(const KeyFrameImage& image) {
  return YuvToBgr(image.grey, image.chroma, image.coding);
}

}  // namespace saker::track
