#pragma once

// A synthetic MPEG transport stream with ground truth, written with video::TsWriter, so the video
// tests mean something without the shared data folder: MPEG-2 video of flat frames with a
// moving bright square, plus one KLV data stream carrying a known ST 0601 packet per frame.
// No GoogleTest here: the benchmark uses it too.

#include "core/util/status.h"

#include <opencv2/core/types.hpp>

#include <cstdint>
#include <filesystem>
#include <vector>

namespace saker::testing {

struct SyntheticTsOptions {
  int width = 64;                // pixels, 16..4096 (odd sizes allowed)
  int height = 48;               // pixels, 16..4096
  int frames = 20;               // number of video frames
  int fps = 25;                  // frame rate; timestamps are exact multiples of 1/fps
  int gop_size = 6;              // key frame every gop_size frames
  int b_frames = 2;              // B-frames between references (reordering: dts != pts)
  bool with_klv = true;          // add the KLV stream
  bool klv_synchronous = false;  // PMT stream_type 0x15 instead of the asynchronous 0x06
  Status Validate() const;
};

// Luma of the flat background of frame `index` (video range, distinct per frame).
int SyntheticBackgroundLuma(int index);
// Luma of the moving square.
inline constexpr int kSyntheticSquareLuma = 235;
// Where the 8x8 square of frame `index` is.
cv::Rect SyntheticSquare(int index, const SyntheticTsOptions& options);

// The KLV packet carried with frame `index`: a MISB ST 0601 local set with a precision time
// stamp (tag 2), LS version 17 (tag 65) and a valid checksum (tag 1).
std::vector<uint8_t> SyntheticKlvPacket(int index);
// Microseconds since 1970 in tag 2 of SyntheticKlvPacket(index): 40 ms steps whatever the
// stream's frame rate (the payload is only compared as bytes).
uint64_t SyntheticKlvTimestampUs(int index);

// Writes the stream. Synchronous KLV gets the 5-byte metadata access-unit cell header of MISB
// ST 1402 in front of each packet, which FFmpeg 5.1's demuxer strips (its muxer does not add it).
Status WriteSyntheticTs(const std::filesystem::path& path, const SyntheticTsOptions& options);

}  // namespace saker::testing
