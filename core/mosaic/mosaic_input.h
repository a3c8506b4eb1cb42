#pragma once
// What the mosaic is built from: the geometry of one video as plain data. The mosaic does not
// know where it came from; the pipeline makes it from a front-end run (pipeline::MosaicInputOf),
// and anything holding the same facts (a saved front-end checkpoint, a test) can make one too.

#include "core/geo/local_tangent_plane.h"
#include "core/track/homography.h"
#include "core/track/key_frames.h"
#include "core/track/types.h"
#include "core/util/status.h"

#include <Eigen/Core>

#include <array>
#include <optional>
#include <vector>

namespace saker::mosaic {

// One video frame, as the frames between key frames need it (in_between.h).
struct MosaicFrame {
  double time_s = 0;
  bool homography_ok = false;  // current_from_previous is valid (never for a segment's first frame)
  Eigen::Matrix3d current_from_previous = Eigen::Matrix3d::Identity();
  track::HomographyCovariance covariance = track::HomographyCovariance::Zero();
};

// The four image corners (upper left, upper right, lower right, lower left) on the map.
using MapCorners = std::array<Eigen::Vector2d, 4>;

struct MosaicInput {
  int image_width = 0;
  int image_height = 0;
  std::vector<MosaicFrame> frames;  // every video frame, index == position
  std::vector<track::KeyFrame> key_frames;
  // Grey copies of the key frames (any subset, in key frame order) for loop closure by matching.
  std::vector<track::KeyFrameImage> key_frame_images;
  std::vector<track::SequentialLink> links;
  // The map frame when the metadata gives one: east-north-up metres around `origin`, and each
  // frame's metadata corners in it (nullopt for a frame without; empty without an origin).
  // Without an origin the map is the first key frame's pixels.
  std::optional<geo::Wgs84> origin;
  std::vector<std::optional<MapCorners>> metadata_corners;

  // InvalidArgument unless the parts fit: a positive image size, key frame ids 0, 1, ... on
  // frames that exist, links between known key frames, metadata corners per frame (or none) and
  // only with an origin.
  Status Validate() const;
};

}  // namespace saker::mosaic
