#pragma once

// The pictures of key frames (KeyFrameImage): a downscaled copy of the video's luma, always, and
// of its chroma when the video is colour, kept apart so that describing (loop closure) reads the
// grey as it is and a colour key frame costs half a grey one more, not three times. The colour
// picture is made where it is drawn (mosaic tiles, the mosaic picture, the GUI's preview).

#include "core/track/key_frames.h"
#include "core/util/yuv_coding.h"

#include <opencv2/core/mat.hpp>

namespace saker::track {

// Whether every chroma sample (CV_8UC2) lies within `tolerance` of neutral (128): a grey video
// coded as YUV, as infrared and many monochrome cameras are. True for an empty matrix.
bool NeutralChroma(const cv::Mat& chroma, int tolerance = 4);

// Full-range BGR (CV_8UC3, the luma's size) from a luma plane (CV_8UC1) and its chroma (CV_8UC2,
// Cb and Cr, any size: resized to the luma's; empty: neutral, a grey picture) as `coding` codes
// them. Values beyond the coded range (super-whites, out-of-gamut colours) are clipped.
cv::Mat YuvToBgr(const cv::Mat& luma, const cv::Mat& chroma, const YuvCoding& coding);

// A key frame's picture from a video frame: `grey` (the luma as coded) downscaled to at most
// `width` pixels wide (INTER_AREA; never enlarged) into image->grey and image->scale, and when
// `chroma` is given and not neutral, the chroma to half that size (rounded up) into
// image->chroma with image->coding. `width` must be positive.
void MakeKeyFramePicture(const cv::Mat& grey, const cv::Mat& chroma, const YuvCoding& coding,
                         int width, KeyFrameImage* image);

// Whether the key frame's picture is in colour.
inline bool IsColour(const KeyFrameImage& image) { return !image.chroma.empty(); }

// The key frame's picture as BGR (YuvToBgr of its grey and chroma; grey pictures give grey BGR,
// expanded to full range as colour ones are, so that the two blend alike).
cv::Mat KeyFrameBgr(const KeyFrameImage& image);

}  // namespace saker::track
