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

namespace saker::mosaic {

struct CornerErrors {
  double rms_px = 0;  // in the key frames' own pixels
  double rms_m = 0;   // on the ground
  double max_m = 0;
};

struct MosaicAccuracy {
  int key_frames = 0;
  bool geo_referenced = false;
  // After removing the gauge: the estimated map is first mapped onto the truth ground by the one
  // homography that fits all key frame corners best (least squares), since without metadata the
  // map frame is arbitrary (the first key frame's pixels).
  CornerErrors before, after;
  // Geo-referenced maps only: the same without removing anything, what the map's coordinates are
  // worth to a user.
  std::optional<CornerErrors> before_absolute, after_absolute;
  std::vector<LoopClosure> closures;
};

// InvalidArgument when the truth does not describe the video (key frame indices out of range or
// another image size).
StatusOr<MosaicAccuracy> EvaluateMosaic(const MosaicResult& mosaic, const sim::Truth& truth);

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
StatusOr<MetadataExperiment> RunMetadataExperiment(const MosaicResult& mosaic,
                                                   const sim::Truth& truth,
                                                   const MetadataExperimentOptions& options = {});
std::string MetadataExperimentToText(const MetadataExperiment& experiment);

nlohmann::json MosaicAccuracyToJson(const MosaicAccuracy& accuracy);
std::string MosaicAccuracyToText(const MosaicAccuracy& accuracy);

}  // namespace saker::mosaic
