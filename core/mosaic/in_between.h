#pragma once
// The absolute homography of every video frame, not only of the key frames (paper: "we compute
// the homographies of in-between frames by performing local bundle adjustment with the end-frames
// fixed at the key frames ... and takes linear time"). Moving targets are seen on every frame; this
// is what places them on the map.
//
// The frames are cut into runs joined by frame-to-frame homographies (a chain break ends a run).
// Within a run:
// - key frames keep their adjusted map_from_frame;
// - the frames between two consecutive key frames are solved by the chain solver (chain_solver.h)
//   over the measured frame-to-frame homographies and their covariances, both key frames fixed,
//   so the adjustment's correction is spread along the chain as the measurements allow;
// - frames before the run's first key frame or after its last are chained from it (one end only);
// - a run without a key frame is not placed.
// Time and memory are linear in the number of frames.
#include "core/mosaic/chain_solver.h"
#include "core/mosaic/link_graph.h"
#include "core/mosaic/mosaic_input.h"
#include "core/util/job_context.h"
#include "core/util/status.h"

#include <Eigen/Core>

#include <optional>
#include <string>
#include <vector>

namespace saker::mosaic {

struct InBetweenFrames {
  // Per video frame (the front end's frame index), H(2,2) = 1; nullopt when not placed.
  std::vector<std::optional<Eigen::Matrix3d>> map_from_frame;
  int key_frames = 0;  // frames that are key frames
  int solved = 0;      // frames solved between two key frames
  int chained = 0;     // frames chained from one key frame (before the first, after the last)
  int unplaced = 0;    // frames in a run without any key frame
  double time_s = 0;
  std::string ToString() const;  // one line
};

// `frames` is every video frame (index == position), `graph` the adjusted key
// frames (their frame_index within `frames`). InvalidArgument when a key frame's frame index is
// outside `frames` or two key frames share a frame; InvalidData from the chain solver (a
// degenerate frame homography, named); Cancelled through `job` (checked between key frames).
// Progress: job->ReportProgress("in-between frames", f).
StatusOr<InBetweenFrames> PlaceInBetweenFrames(const std::vector<MosaicFrame>& frames,
                                               const LinkGraph& graph,
                                               const ChainOptions& options = {},
                                               JobContext* job = nullptr);

}  // namespace saker::mosaic
