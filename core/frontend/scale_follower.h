#pragma once

// The ground's scale of each frame as a video is read, from its KLV metadata's corners, for the
// front end's speed limits (issue 24, item 1; docs/front-end.md, "Ground scale").

#include "core/ingest/video_scan.h"
#include "core/track/image_geometry.h"

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <array>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <optional>

namespace saker::frontend {

// The scale of a frame is that of the corners of the latest trusted KLV packet carried before
// the frame in the file (encoders send metadata just before the frame it describes; the decoder
// gives pictures out a few packets late, so packets are tied by position, not by arrival).
// Corners older than stale_s of frames are dropped: metadata that stops must not steer the gates
// for the rest of the video. Packets whose corners make no ground (GroundScale::FromCorners) are
// passed over.
class ScaleFollower {
 public:
  explicit ScaleFollower(double fps, double stale_s = 2);

  // Every KLV packet, in the order of the file (ingest::ScanOptions::on_packet).
  void AddPacket(const ingest::MetadataPacket& packet);
  // The scale of the next frame, `width` x `height`, carried at `byte_pos` (-1: unknown; then
  // every packet so far counts). Frames in the order they are decoded.
  std::optional<track::GroundScale> ForFrame(int64_t byte_pos, int width, int height);
  // Packets waiting for the frame after them (at most 1024).
  size_t waiting() const { return pending_.size(); }

 private:
  struct Pending {
    int64_t byte_pos = -1;
    std::array<Eigen::Vector2d, 4> ground;  // the corners, metres (GroundScale::FromCorners)
  };
  // The oldest packet waiting becomes the scale (for pictures of `size`) when its corners make
  // ground.
  void TakeOldest(const cv::Size& size);

  int64_t stale_frames_;
  std::deque<Pending> pending_;
  std::optional<track::GroundScale> current_;  // from ground_ at size_
  std::array<Eigen::Vector2d, 4> ground_;
  cv::Size size_;
  int64_t frames_since_ = 0;
};

}  // namespace saker::frontend
