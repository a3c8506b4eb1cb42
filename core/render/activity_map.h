#pragma once

// The activity map picture an operator exports: the mosaic (from the mission's tile pyramid) with
// every moving target's track drawn over it, coloured by speed, direction, visit or time, with a
// legend, and a scale bar and north arrow when the mission is geo-referenced.

#include "core/activity/colours.h"
#include "core/mission/mission.h"
#include "core/util/status.h"

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include <functional>
#include <optional>
#include <string>

namespace saker::render {

// The tile (level, x, y) of the mission's pyramid as CV_8UC4 BGRA, or an empty Mat when absent.
using TileReader = std::function<StatusOr<cv::Mat>(int level, int x, int y)>;

struct ActivityMapOptions {
  activity::ColourMode colour_by = activity::ColourMode::kSpeed;
  int max_side_px = 4096;  // the mosaic part's longer side at most (a coarser level is used)
  double line_width = 2;   // track lines, pixels
  bool legend = true;
  // Only tracks seen within [start_s, end_s] (seconds in the video) when set.
  std::optional<double> start_s, end_s;
  Status Validate() const;
};

struct ActivityMap {
  cv::Mat bgr;                                                   // CV_8UC3
  Eigen::Matrix3d image_from_map = Eigen::Matrix3d::Identity();  // picture pixels from map
  int level = 0;   // pyramid level the mosaic came from
  int tracks = 0;  // tracks drawn
};

// Renders the activity map. Without a tile pyramid (a mission processed without tiles) the
// tracks are drawn on a plain background over their own extent. InvalidData when there is
// nothing to draw (no pyramid and no track).
StatusOr<ActivityMap> RenderActivityMap(const mission::Mission& mission, const TileReader& tiles,
                                        const ActivityMapOptions& options);

// Writes a picture (.png, .jpg or .tif) through a temporary file renamed into place; the error
// names the file.
Status WritePicture(const cv::Mat& bgr, const std::string& path);

}  // namespace saker::render
