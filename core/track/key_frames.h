#pragma once

// Key frame selection and the sequential chain of the mosaic (paper: "Key frames are chosen with
// 30 % overlap of stationary points"). Streaming: one call per frame, in order; it keeps only
// the key frames' stationary points, the links, the breaks and the running frame-to-frame
// product since the last key frame. Rules and formulas: docs/homography-covariance.md.

#include "core/track/homography.h"
#include "core/track/types.h"
#include "core/util/status.h"
#include "core/util/yuv_coding.h"

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace saker::track {

struct KeyFrameOptions {
  // A frame becomes a key frame when the stationary tracks it shares with the last key frame
  // are at most this fraction of the last key frame's.
  double min_shared_fraction = 0.3;
  // A link is estimated directly from the shared tracks when there are at least this many (and
  // the estimate succeeds); otherwise it is chained through the frame-to-frame homographies. Also
  // the number of stationary points a frame needs to start a segment.
  int min_points = 20;
  // For the direct link estimates.
  HomographyOptions homography;

  Status Validate() const;
};

using StationaryPoint = std::pair<FeatureTrackId, Eigen::Vector2d>;

// A downscaled copy of a key frame's picture, for describing it (loop closure) and drawing the
// mosaic: its luma, and its chroma when the video is colour (core/track/picture.h makes them and
// the colour picture). Its pixels are shared, never modified once made.
struct KeyFrameImage {
  KeyFrameId id{};
  int64_t frame_index = 0;
  cv::Mat grey;      // downscaled luma as coded (CV_8UC1)
  double scale = 1;  // full-resolution pixels per pixel of `grey`
  // Cb and Cr (CV_8UC2) at half the size of `grey` (rounded up); empty for a grey picture.
  cv::Mat chroma;
  YuvCoding coding;  // how `grey` and `chroma` code colour
};

struct KeyFrame {
  KeyFrameId id{};  // == its index in KeyFrameChain::key_frames()
  int64_t frame_index = 0;
  int segment = 0;  // segments count from 0; a chain break starts the next one
  // The stationary points seen in the key frame, sorted by id (the caller keeps images and
  // descriptors).
  std::vector<StationaryPoint> points;
};

// The homography between consecutive key frames of a segment.
struct SequentialLink {
  KeyFrameId from{};
  KeyFrameId to{};
  Eigen::Matrix3d to_from_from = Eigen::Matrix3d::Identity();  // key frame `from` px -> `to` px
  HomographyCovariance covariance = HomographyCovariance::Zero();
  // Direct: the inliers of the estimate (source in `from`, target in `to`). Chained: all the
  // tracks the two key frames share (fewer than min_points, often none).
  std::vector<Correspondence> correspondences;
  // False: estimated from tracks seen in both key frames. True: the product of the
  // frame-to-frame homographies in between, covariance propagated assuming they are independent.
  bool chained = false;
};

struct ChainBreak {
  int64_t frame_index = 0;  // the first frame that could not be joined to the chain
  std::string reason;
};

// What one frame did to the chain. A frame can both break the chain and start the next segment
// (a scene cut: no frame-to-frame estimate, but plenty of points).
struct FrameOutcome {
  bool chain_break = false;             // breaks().back() was added for this frame
  std::optional<KeyFrameId> key_frame;  // this frame became key_frames()[*key_frame]
  std::optional<size_t> link;           // and was linked: links()[*link]
  // Shared fraction with the last key frame of the running segment (none outside a segment).
  std::optional<double> shared_fraction;
};

class KeyFrameChain {
 public:
  // The options must be valid (SAKER_CHECK); check them with Validate() first.
  explicit KeyFrameChain(const KeyFrameOptions& options);

  // Per frame, in increasing frame_index (SAKER_CHECK): the stationary tracked points in this
  // frame (id, position; ids unique) and the estimate of this frame from the previous frame
  // (target = this frame, source = the previous one), or nullopt when that failed (blank or
  // featureless frame, cut). A frame outside a segment starts one (as its first key frame) when
  // it has at least min_points stationary points. Inside a segment, nullopt ends the segment
  // with a ChainBreak; otherwise the frame becomes a key frame when its shared fraction drops to
  // min_shared_fraction or below.
  FrameOutcome AddFrame(int64_t frame_index, const std::vector<StationaryPoint>& stationary,
                        const std::optional<HomographyEstimate>& from_previous);

  // A chain that goes on from `last`, the latest key frame of a run that stopped there (a resumed
  // run, docs/reliability.md "Resume"): it becomes this chain's key frame 0, in segment 0, as if
  // the frames before had been added. Only on a new chain.
  void ContinueFrom(KeyFrame last);

  const std::vector<KeyFrame>& key_frames() const { return key_frames_; }
  const std::vector<SequentialLink>& links() const { return links_; }
  const std::vector<ChainBreak>& breaks() const { return breaks_; }
  // Whether a segment is running (its last key frame is key_frames().back()).
  bool in_segment() const { return in_segment_; }

 private:
  // Appends a key frame and returns its id.
  KeyFrameId AddKeyFrame(int64_t frame_index, std::vector<StationaryPoint> sorted_points);
  void Break(int64_t frame_index, std::string reason, FrameOutcome* outcome);

  KeyFrameOptions options_;
  std::vector<KeyFrame> key_frames_;
  std::vector<SequentialLink> links_;
  std::vector<ChainBreak> breaks_;
  bool in_segment_ = false;
  int segment_ = -1;
  std::optional<int64_t> last_frame_index_;
  // current frame from last key frame: the product of frame-to-frame estimates since then.
  HomographyWithCovariance since_key_frame_;
};

}  // namespace saker::track
