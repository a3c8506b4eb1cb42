#pragma once
// The link graph of the mosaic (paper: "bundle adjustment of absolute homographies"): key frames
// are nodes, each with its absolute homography map_from_frame; sequential links and cross-links
// (loop closures) are edges carrying a measured pairwise homography, its 8x8 covariance and the
// correspondences that support it.
//
// The map frame is east-north-up metres around the mission origin when the video carries
// metadata corners (geo_referenced), otherwise the first key frame's pixel frame. Image points
// are full-resolution pixels, integer = pixel centre. Homography parameters and covariances use
// the order of core/track/types.h (h00 h01 h02 h10 h11 h12 h20 h21).
#include "core/mission/mission.h"
#include "core/track/types.h"
#include "core/util/status.h"

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace saker::mosaic {

using track::KeyFrameId;

struct Node {
  KeyFrameId id{};          // == its index in LinkGraph::nodes
  int64_t frame_index = 0;  // in the video
  double time_s = 0;        // from the start of the video
  int segment = 0;          // chain segment (a break starts the next)
  Eigen::Matrix3d map_from_frame = Eigen::Matrix3d::Identity();  // current solution, H(2,2) = 1
  // The metadata's ground coordinates of the image corners (ImageCorners order) in map metres,
  // when the frame had them and the graph is geo-referenced.
  std::optional<std::array<Eigen::Vector2d, 4>> metadata_corners;
};

using mission::LinkKind;
using mission::LinkKindName;

struct Link {
  KeyFrameId from{};
  KeyFrameId to{};
  LinkKind kind = LinkKind::kSequential;
  Eigen::Matrix3d to_from_from = Eigen::Matrix3d::Identity();  // `from` px -> `to` px, H(2,2) = 1
  track::HomographyCovariance covariance = track::HomographyCovariance::Zero();
  std::vector<track::Correspondence> correspondences;  // source in `from`, target in `to`
};

struct LinkGraph {
  int image_width = 0;  // full-resolution pixels of every key frame
  int image_height = 0;
  bool geo_referenced = false;  // map frame: ENU metres (true) or first key frame pixels
  std::vector<Node> nodes;
  std::vector<Link> links;

  // Structural checks: ids equal indices, links name existing distinct nodes, finite
  // homographies with H(2,2) = 1, symmetric covariances, positive image size. InvalidData
  // naming the first problem.
  Status Validate() const;
  // Connected components over the links: component index per node, numbered from 0 in node
  // order.
  std::vector<int> Components() const;
  // Whether a link joins a and b (either direction).
  bool Linked(KeyFrameId a, KeyFrameId b) const;
};

}  // namespace saker::mosaic
