#include "core/tiles/image_decode.h"

#include "core/tiles/pyramid.h"
#include "tests/testing/png_bomb.h"

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <array>
#include <string>
#include <vector>

namespace saker::tiles {
namespace {

std::vector<uint8_t> EncodeBgra(int width, int height) {
  std::vector<uint8_t> png;
  EXPECT_TRUE(cv::imencode(".png", cv::Mat(height, width, CV_8UC4, cv::Scalar(1, 2, 3, 255)), png));
  return png;
}

TEST(ImageDecodeTest, ReadsTheSizeFromThePngHeader) {
  const auto size = ReadPngSize(EncodeBgra(37, 11));
  ASSERT_TRUE(size.ok()) << size.status().ToString();
  EXPECT_EQ(size->width, 37);
  EXPECT_EQ(size->height, 11);
  const auto bomb = ReadPngSize(testing::PngBomb(40000, 40000));
  ASSERT_TRUE(bomb.ok());
  EXPECT_EQ(bomb->width, 40000);
  EXPECT_FALSE(ReadPngSize({1, 2, 3}).ok());
  std::vector<uint8_t> jpeg;
  ASSERT_TRUE(cv::imencode(".jpg", cv::Mat(8, 8, CV_8UC3, cv::Scalar::all(9)), jpeg));
  EXPECT_EQ(ReadPngSize(jpeg).status().code(), StatusCode::kInvalidData);
}

// A 100-byte tile whose header claims 40000 x 40000 pixels: refused from its header, before
// anything is allocated (cv::imdecode threw cv::Exception out of the export and the GUI).
TEST(ImageDecodeTest, DecompressionBombTileIsRefusedNotDecoded) {
  const std::vector<uint8_t> bomb = testing::PngBomb(40000, 40000);
  EXPECT_LT(bomb.size(), 120u);
  const auto tile = DecodeTile(bomb, 256);
  ASSERT_FALSE(tile.ok());
  EXPECT_EQ(tile.status().code(), StatusCode::kInvalidData);
  EXPECT_NE(tile.status().message().find("40000x40000"), std::string::npos)
      << tile.status().message();
  // A bomb within OpenCV's own pixel limit (which would allocate 3.6 GB) is refused the same way.
  EXPECT_EQ(DecodeTile(testing::PngBomb(30000, 30000), 256).status().code(),
            StatusCode::kInvalidData);
  // So is a tile of another size than the pyramid's (a 16384^2 one made the GUI run out of
  // memory), and a pyramid whose tile size is itself absurd.
  EXPECT_EQ(DecodeTile(EncodeBgra(512, 512), 256).status().code(), StatusCode::kInvalidData);
  EXPECT_EQ(DecodeTile(testing::PngBomb(65536, 65536), 65536).status().code(),
            StatusCode::kInvalidData);
  // A bomb the limits admit fails as bad data too: the decoder's exception is caught.
  const auto truncated = DecodePng(testing::PngBomb(64, 64), -1, {64, 64, 64 * 64});
  EXPECT_EQ(truncated.status().code(), StatusCode::kInvalidData);
}

TEST(ImageDecodeTest, DecodesWithinTheLimits) {
  const auto tile = DecodeTile(EncodeBgra(256, 256), 256);
  ASSERT_TRUE(tile.ok()) << tile.status().ToString();
  EXPECT_EQ(tile->type(), CV_8UC4);
  EXPECT_EQ(tile->at<cv::Vec4b>(3, 4), cv::Vec4b(1, 2, 3, 255));
  const auto grey = DecodePng(EncodeBgra(40, 30), cv::IMREAD_GRAYSCALE, {40, 30, 1200});
  ASSERT_TRUE(grey.ok());
  EXPECT_EQ(grey->type(), CV_8UC1);
  EXPECT_EQ(DecodePng(EncodeBgra(40, 30), cv::IMREAD_GRAYSCALE, {40, 30, 1199}).status().code(),
            StatusCode::kInvalidData);
}

std::vector<uint8_t> EncodeJpeg(int width, int height) {
  std::vector<uint8_t> jpeg;
  EXPECT_TRUE(cv::imencode(".jpg", cv::Mat(height, width, CV_8UC3, cv::Scalar(40, 90, 200)), jpeg));
  return jpeg;
}

// A JPEG's size comes from its frame header, found by walking its markers; a hostile one is
// refused from there, before anything is decoded.
TEST(ImageDecodeTest, ReadsTheSizeFromTheJpegFrameHeader) {
  const std::vector<uint8_t> jpeg = EncodeJpeg(37, 11);
  EXPECT_TRUE(IsJpeg(jpeg));
  EXPECT_FALSE(IsJpeg(EncodeBgra(37, 11)));
  const auto size = ReadJpegSize(jpeg);
  ASSERT_TRUE(size.ok()) << size.status().ToString();
  EXPECT_EQ(size->width, 37);
  EXPECT_EQ(size->height, 11);
  EXPECT_EQ(ReadJpegSize(EncodeBgra(8, 8)).status().code(), StatusCode::kInvalidData);
  // Cut anywhere before the frame header, or with a segment length running past the end: an
  // error, never a read beyond the bytes.
  constexpr std::array<uint8_t, 2> kBaselineFrame = {0xFF, 0xC0};
  const auto sof =
      std::search(jpeg.begin(), jpeg.end(), kBaselineFrame.begin(), kBaselineFrame.end());
  ASSERT_NE(sof, jpeg.end());
  const auto header_end = static_cast<size_t>(sof - jpeg.begin()) + 9;
  for (size_t n = 0; n < header_end; ++n) {
    const std::vector<uint8_t> cut(jpeg.begin(), jpeg.begin() + static_cast<std::ptrdiff_t>(n));
    EXPECT_FALSE(ReadJpegSize(cut).ok()) << n << " bytes";
  }
  std::vector<uint8_t> long_segment = jpeg;
  long_segment[4] = 0xFF;  // the first segment's length: beyond the file
  EXPECT_FALSE(ReadJpegSize(long_segment).ok());
  // A header claiming 60000 x 60000 pixels in a few hundred bytes: refused from its header.
  std::vector<uint8_t> bomb = jpeg;
  const auto at = static_cast<size_t>(sof - jpeg.begin());
  bomb[at + 5] = bomb[at + 6] = bomb[at + 7] = bomb[at + 8] = 0xEA;
  const auto tile = DecodeTile(bomb, 256);
  ASSERT_FALSE(tile.ok());
  EXPECT_EQ(tile.status().code(), StatusCode::kInvalidData);
  EXPECT_NE(tile.status().message().find("60138x60138"), std::string::npos)
      << tile.status().message();
}

TEST(ImageDecodeTest, JpegTilesDecodeOpaque) {
  const auto tile = DecodeTile(EncodeJpeg(256, 256), 256);
  ASSERT_TRUE(tile.ok()) << tile.status().ToString();
  EXPECT_EQ(tile->type(), CV_8UC4);
  const cv::Vec4b p = tile->at<cv::Vec4b>(100, 100);
  EXPECT_NEAR(p[0], 40, 3);
  EXPECT_NEAR(p[1], 90, 3);
  EXPECT_NEAR(p[2], 200, 3);
  EXPECT_EQ(p[3], 255);
  EXPECT_EQ(DecodeTile(EncodeJpeg(128, 256), 256).status().code(), StatusCode::kInvalidData);
  std::vector<uint8_t> truncated = EncodeJpeg(256, 256);
  truncated.resize(truncated.size() / 3);
  // libjpeg fills in what is missing or fails: either a whole tile or bad data, never a crash.
  const auto damaged = DecodeTile(truncated, 256);
  if (damaged.ok()) {
    EXPECT_EQ(damaged->size(), cv::Size(256, 256));
  } else {
    EXPECT_EQ(damaged.status().code(), StatusCode::kInvalidData);
  }
}

}  // namespace
}  // namespace saker::tiles
