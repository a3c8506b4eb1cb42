#pragma once
// A mosaic picture for people: the key frames warped into the map with their adjusted
// homographies and blended (each pixel weighted by its distance to its frame's border, so seams
// fade), optionally with the key frames' outlines, the links between them and their uncertainty
// ellipses drawn on top.
//
// The picture's pixels relate to the map by `image_from_map`: north up for a geo-referenced map
// (east right), the first key frame's orientation otherwise.
#include "core/mosaic/link_graph.h"
#include "core/track/key_frames.h"
#include "core/util/status.h"

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include <vector>

namespace saker::mosaic {

struct RenderOptions {
  int max_side_px = 4096;       // the longer side of the picture at most
  double map_units_per_px = 0;  // 0: the key frames' own resolution (capped by max_side_px)
  bool outlines = false;        // key frame outlines, coloured by chain segment
  bool links = false;           // lines between linked key frames' centres (cross-links in red)
  // Uncertainty ellipses of the key frames' corners at this confidence (0: none), from
  // `covariances` (one per node, as MosaicResult::covariances).
  double ellipse_confidence = 0;
  Status Validate() const;
};

struct MosaicImage {
  cv::Mat bgr;                                                   // CV_8UC3
  Eigen::Matrix3d image_from_map = Eigen::Matrix3d::Identity();  // picture pixels from map
  double map_units_per_px = 1;
};

// `images` are the front end's key frame images (matched to nodes by id; nodes without one are
// skipped). InvalidData when no key frame can be drawn or the map extent is not finite.
StatusOr<MosaicImage> RenderMosaic(
    const LinkGraph& graph, const std::vector<track::KeyFrameImage>& images,
    const RenderOptions& options, const std::vector<track::HomographyCovariance>& covariances = {});

}  // namespace saker::mosaic
