// Key frame pictures: the YUV to BGR conversion against the standard matrices and ranges, grey
// video recognised by its neutral chroma, and the sizes and sharing of a key frame's planes.

#include "core/track/picture.h"

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include <string>
#include <tuple>
#include <vector>

namespace saker::track {
namespace {

cv::Vec3b ConvertOne(uint8_t y, uint8_t cb, uint8_t cr, const YuvCoding& coding) {
  const cv::Mat luma(1, 1, CV_8UC1, cv::Scalar(y));
  const cv::Mat chroma(1, 1, CV_8UC2, cv::Scalar(cb, cr));
  return YuvToBgr(luma, chroma, coding).at<cv::Vec3b>(0, 0);
}

void ExpectBgr(const cv::Vec3b& got, int b, int g, int r, const std::string& what) {
  EXPECT_NEAR(got[0], b, 3) << what << " blue";
  EXPECT_NEAR(got[1], g, 3) << what << " green";
  EXPECT_NEAR(got[2], r, 3) << what << " red";
}

TEST(YuvToBgrTest, LimitedRangeBlackWhiteAndPrimariesInEachMatrix) {
  // The coded values of 75 %-free primaries (full intensity), from the matrices' definitions:
  // BT.601 red is Y 81, Cb 90, Cr 240; BT.709 red is Y 63, Cb 102, Cr 240.
  const YuvCoding bt601{YuvMatrix::kBt601, false};
  const YuvCoding bt709{YuvMatrix::kBt709, false};
  ExpectBgr(ConvertOne(16, 128, 128, bt601), 0, 0, 0, "black");
  ExpectBgr(ConvertOne(235, 128, 128, bt601), 255, 255, 255, "white");
  ExpectBgr(ConvertOne(126, 128, 128, bt709), 128, 128, 128, "mid grey");
  ExpectBgr(ConvertOne(81, 90, 240, bt601), 0, 0, 255, "601 red");
  ExpectBgr(ConvertOne(145, 54, 34, bt601), 0, 255, 0, "601 green");
  ExpectBgr(ConvertOne(41, 240, 110, bt601), 255, 0, 0, "601 blue");
  ExpectBgr(ConvertOne(63, 102, 240, bt709), 0, 0, 255, "709 red");
  ExpectBgr(ConvertOne(173, 42, 26, bt709), 0, 255, 0, "709 green");
  ExpectBgr(ConvertOne(32, 240, 118, bt709), 255, 0, 0, "709 blue");
  // The wrong matrix gives a visibly different red: the coding matters.
  const cv::Vec3b wrong = ConvertOne(63, 102, 240, bt601);
  EXPECT_GT(std::abs(wrong[1] - 0) + std::abs(wrong[2] - 255), 20);
}

TEST(YuvToBgrTest, FullRangeAndClipping) {
  const YuvCoding full{YuvMatrix::kBt601, true};
  ExpectBgr(ConvertOne(0, 128, 128, full), 0, 0, 0, "black");
  ExpectBgr(ConvertOne(255, 128, 128, full), 255, 255, 255, "white");
  ExpectBgr(ConvertOne(76, 85, 255, full), 0, 0, 255, "red");  // JPEG's 0.299 R
  // Beyond the coded range (super-white, impossible chroma): clipped, never wrapped.
  const YuvCoding limited{YuvMatrix::kBt709, false};
  ExpectBgr(ConvertOne(255, 128, 128, limited), 255, 255, 255, "super-white");
  ExpectBgr(ConvertOne(0, 128, 128, limited), 0, 0, 0, "below black");
  const cv::Vec3b extreme = ConvertOne(235, 255, 255, limited);
  EXPECT_EQ(extreme[0], 255);
  EXPECT_EQ(extreme[2], 255);
}

TEST(YuvToBgrTest, SubsampledChromaIsResizedAndNoChromaIsGrey) {
  cv::Mat luma(6, 8, CV_8UC1, cv::Scalar(126));
  cv::Mat chroma(3, 4, CV_8UC2, cv::Scalar(102, 240));  // red everywhere, 4:2:0
  const cv::Mat bgr = YuvToBgr(luma, chroma, {YuvMatrix::kBt709, false});
  ASSERT_EQ(bgr.size(), luma.size());
  ASSERT_EQ(bgr.type(), CV_8UC3);
  for (int v = 0; v < bgr.rows; ++v) {
    for (int u = 0; u < bgr.cols; ++u) {
      const cv::Vec3b p = bgr.at<cv::Vec3b>(v, u);
      EXPECT_GT(p[2], p[1] + 100) << u << "," << v;  // red stays red at every pixel
    }
  }
  const cv::Mat grey = YuvToBgr(luma, cv::Mat(), {YuvMatrix::kBt709, false});
  ExpectBgr(grey.at<cv::Vec3b>(2, 3), 128, 128, 128, "no chroma");
}

TEST(NeutralChromaTest, ToleranceAroundHalf) {
  EXPECT_TRUE(NeutralChroma(cv::Mat()));
  cv::Mat chroma(10, 10, CV_8UC2, cv::Scalar(128, 128));
  EXPECT_TRUE(NeutralChroma(chroma));
  chroma.at<cv::Vec2b>(3, 4) = cv::Vec2b(131, 125);
  EXPECT_TRUE(NeutralChroma(chroma));  // coding noise of a grey video
  chroma.at<cv::Vec2b>(7, 1) = cv::Vec2b(128, 140);
  EXPECT_FALSE(NeutralChroma(chroma));  // one red pixel is colour
  EXPECT_TRUE(NeutralChroma(chroma, 12));
}

TEST(MakeKeyFramePictureTest, ColourKeepsHalfSizeChromaAndGreyKeepsNone) {
  cv::Mat grey(720, 1280, CV_8UC1);
  cv::randu(grey, 100, 140);
  cv::Mat chroma(360, 640, CV_8UC2, cv::Scalar(128, 128));
  chroma(cv::Rect(100, 100, 40, 20)).setTo(cv::Scalar(90, 200));  // a coloured car
  const YuvCoding coding{YuvMatrix::kBt709, false};

  KeyFrameImage colour;
  MakeKeyFramePicture(grey, chroma, coding, 640, &colour);
  EXPECT_DOUBLE_EQ(colour.scale, 2);
  EXPECT_EQ(colour.grey.size(), cv::Size(640, 360));
  ASSERT_TRUE(IsColour(colour));
  EXPECT_EQ(colour.chroma.size(), cv::Size(320, 180));
  EXPECT_EQ(colour.coding, coding);
  const cv::Mat bgr = KeyFrameBgr(colour);
  EXPECT_EQ(bgr.size(), colour.grey.size());
  const cv::Vec3b car = bgr.at<cv::Vec3b>(110, 120);  // inside the car, in key frame pixels
  EXPECT_GT(car[2], car[0] + 60);

  KeyFrameImage grey_picture;
  MakeKeyFramePicture(grey, cv::Mat(360, 640, CV_8UC2, cv::Scalar(129, 127)), coding, 640,
                      &grey_picture);
  EXPECT_FALSE(IsColour(grey_picture));
  KeyFrameImage no_chroma;
  MakeKeyFramePicture(grey, cv::Mat(), coding, 640, &no_chroma);
  EXPECT_FALSE(IsColour(no_chroma));

  // Odd sizes round the chroma up; a narrow video is never enlarged.
  KeyFrameImage odd;
  MakeKeyFramePicture(cv::Mat(45, 71, CV_8UC1, cv::Scalar(100)),
                      cv::Mat(23, 36, CV_8UC2, cv::Scalar(60, 200)), coding, 640, &odd);
  EXPECT_DOUBLE_EQ(odd.scale, 1);
  EXPECT_EQ(odd.grey.size(), cv::Size(71, 45));
  EXPECT_EQ(odd.chroma.size(), cv::Size(36, 23));
}

}  // namespace
}  // namespace saker::track
