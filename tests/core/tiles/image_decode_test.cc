#include "core/tiles/image_decode.h"

#include "core/tiles/pyramid.h"
#include "tests/testing/png_bomb.h"

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

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

}  // namespace
}  // namespace saker::tiles
