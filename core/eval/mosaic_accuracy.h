#pragma once
// The mosaic against the simulator's truth: how far the key frames' corners land from where they
// really are, before the adjustment (the sequential chain alone) and after it, and which loop
// closures were found. `saker-cli evaluate` prints these next to the front end's figures.
#include "core/mosaic/mosaic_builder.h"
#include "core/sim/truth.h"
#include "core/util/status.h"

#include <nlohmann/json.hpp>

#include <optional>
#include <string>
#include <vector>

namespace saker::eval {

struct CornerErrors {
  double rms_px = 0;  // in the key frames' own pixels
  double rms_m = 0;   // on the ground
  double max_m = 0;
};

// The in-between frames (every video frame that is not a key frame,
// mosaic::MosaicResult::in_between) against the truth, after the same gauge fit as the key frames'
// `after` figures.
struct InBetweenAccuracy {
  int frames = 0;                 // placed frames that are not key frames
  CornerErrors frames_error;      // theirs
  CornerErrors key_frames_error;  // the key frames' (== MosaicAccuracy::after)
  // Frames solved between two key frames: how far a frame's RMS corner error (its own pixels)
  // exceeds the larger of its two key frames' (0 when it does not), median and largest.
  int between = 0;
  double median_excess_px = 0;
  double max_excess_px = 0;
};

struct MosaicAccuracy {
  int key_frames = 0;
  bool geo_referenced = false;
  // How the key frames were adjusted: "full" or "decomposed", and in the latter case the last
  // adjustment's nodes and arcs; the time of all adjustments (mosaic::MosaicTiming::adjust_s).
  std::string adjust_mode;
  int nodes = 0;
  int arcs = 0;
  double adjust_s = 0;
  // After removing the gauge: the estimated map is first mapped onto the truth ground by the one
  // homography that fits all key frame corners best (least squares), since without metadata the
  // map frame is arbitrary (the first key frame's pixels).
  CornerErrors before, after;
  // Geo-referenced maps only: the same without removing anything, what the map's coordinates are
  // worth to a user.
  std::optional<CornerErrors> before_absolute, after_absolute;
  std::vector<mosaic::LoopClosure> closures;
  std::optional<InBetweenAccuracy> in_between;  // when the mosaic placed them
};

// InvalidArgument when the truth does not describe the video (key frame indices out of range or
// another image size).
StatusOr<MosaicAccuracy> EvaluateMosaic(const mosaic::MosaicResult& mosaic,
                                        const sim::Truth& truth);

// The paper's metadata experiment, on a mosaic's link graph and the truth. The first key frame's
// homography is made wrong by `start_error_fraction` of the image width at its corners (a
// keystone: the top corners moved inwards), the others chained from it; then the graph is
// adjusted
//  - without metadata (the wrong start fixed: the error grows away from the start), and
//  - with metadata corners on `metadata_key_frames` key frames spread along the flight, each
//    corner coordinate off by Gaussian noise of `metadata_sigma_m` (0: the frame's footprint
//    width, "an accuracy of about the image size"), the adjustment told that sigma.
// Errors are key frame corners against the truth ground, nothing removed.
struct MetadataExperimentOptions {
  double start_error_fraction = 0.1;
  int metadata_key_frames = 8;
  double metadata_sigma_m = 0;
  uint64_t seed = 1;
};
struct MetadataExperiment {
  double start_error_m = 0;  // RMS corner error of the wrong start
  double metadata_sigma_m = 0;
  int metadata_key_frames = 0;
  CornerErrors without_metadata, with_metadata;
};
StatusOr<MetadataExperiment> RunMetadataExperiment(const mosaic::MosaicResult& mosaic,
                                                   const sim::Truth& truth,
                                                   const MetadataExperimentOptions& options = {});
std::string MetadataExperimentToText(const MetadataExperiment& experiment);

// The paper's graph decomposition experiment (its figures 9 and 10) on a mosaic's link graph:
// from the sequential chain's start (mosaic::MosaicResult::chained), the full adjustment and the
// decomposed one, timed, compared with each other and with the truth. `decomposition` says how
// few nodes to use (cross_link_spacing keeps one cross-link per loop closure, as the paper did).
struct DecompositionExperiment {
  int key_frames = 0;
  int nodes = 0, arcs = 0, cross_links = 0, left_out_cross_links = 0, inserted_nodes = 0;
  double full_s = 0;         // the full adjustment
  double decomposed_s = 0;   // the node adjustment(s) and the arcs' placement
  double node_adjust_s = 0;  // the node adjustment(s) alone
  // Key frame corners, decomposed against full, in the key frames' own pixels.
  double difference_rms_px = 0, difference_max_px = 0;
  CornerErrors full, decomposed;  // against the truth, gauge removed
};
StatusOr<DecompositionExperiment> RunDecompositionExperiment(
    const mosaic::MosaicResult& mosaic, const sim::Truth& truth,
    const mosaic::DecompositionOptions& decomposition,
    const mosaic::AdjustmentOptions& adjustment = {});
std::string DecompositionExperimentToText(const DecompositionExperiment& experiment);
nlohmann::json DecompositionExperimentToJson(const DecompositionExperiment& experiment);

nlohmann::json MosaicAccuracyToJson(const MosaicAccuracy& accuracy);
std::string MosaicAccuracyToText(const MosaicAccuracy& accuracy);

}  // namespace saker::eval
