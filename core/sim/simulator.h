#pragma once

// The world simulator: flies a camera over a procedural town (or a user's orthophoto) and writes
// an MPEG-TS with H.264 video and MISB ST 0601 KLV, plus a truth file (docs/simulator.md).

#include "core/geo/local_tangent_plane.h"
#include "core/sim/camera.h"
#include "core/sim/flight.h"
#include "core/sim/frame_renderer.h"
#include "core/sim/ground_paths.h"
#include "core/sim/overlay.h"
#include "core/sim/targets.h"
#include "core/sim/world.h"
#include "core/util/job_context.h"
#include "core/util/status.h"

#include <nlohmann/json.hpp>
#include <opencv2/core/matx.hpp>

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace saker::sim {

// Version of what the simulator draws: raise it whenever the same options and seed would give a
// different world, traffic or video, so truth files and the cached demo say what made them.
// Version 2: oblique views no longer draw the targets behind the camera (mirrored ghosts, and a
// vehicle across its principal plane filling the frame).
// Version 3: views reaching the horizon (sky, haze, ground drawn out to 8 heights); targets
// behind the camera or in the haze are neither drawn nor counted visible in the truth.
inline constexpr int kSimulatorVersion = 3;

// Which frames carry a KLV packet, and how accurate it is. The paper studies metadata that is
// only moderately accurate and not on every frame.
struct MetadataOptions {
  int every_n_frames = 1;            // a packet every N frames; 0 = no KLV at all
  std::vector<int64_t> only_frames;  // when not empty: packets on exactly these frames
  double position_noise_m = 0;  // 1 sigma, east and north, each corner / position independently
  double bias_east_m = 0;       // constant error added to every ground position
  double bias_north_m = 0;
  double dropout_probability = 0;  // chance that a due packet is not sent
  Status Validate() const;
  bool Due(int64_t frame_index) const;  // before dropouts
};

// How the encoder samples the camera's frames. Real encoders drop frames (a gap in the time
// stamps), repeat them (the same picture again with a new time) and run at irregular rates.
struct SamplingOptions {
  double drop_probability = 0;    // each camera frame after the first is lost with this chance
  double repeat_probability = 0;  // ... or replaced by the previous picture with this chance
  // Frame intervals of 3/4, 4/4 or 5/4 of the nominal one at random (mean: the nominal rate);
  // the stream's time base is then a quarter of a frame interval.
  bool variable_rate = false;
  Status Validate() const;
};

// A splice (an edited or switched feed): from video time `at_s` on, the video shows the flight
// and its traffic `jump_s` seconds later, another place on the flight path. Nothing relates the
// frames either side of it.
struct CutOptions {
  double at_s = -1;  // < 0: no cut
  double jump_s = 30;
  bool enabled() const { return at_s >= 0; }
  Status Validate() const;
};

struct SimulationOptions {
  Scenario scenario = Scenario::kRoundaboutLoop;
  std::filesystem::path output;  // the .ts file
  std::filesystem::path truth;   // empty: beside the output, <stem>.truth.json
  uint64_t seed = 1;
  double fps = 25;        // integer rates, or NTSC rates such as 29.97
  double duration_s = 0;  // 0: the whole flight path of the scenario
  CameraIntrinsics camera;
  ZoomOptions zoom;      // a change of field of view during the flight
  FlightOptions flight;  // flight.seed is replaced by `seed`
  WorldOptions world;    // world.seed is replaced by `seed`
  TargetOptions targets;
  ImagingOptions imaging;
  OverlayOptions overlay;  // burned-in HUD text, reticle, logo
  SamplingOptions sampling;
  CutOptions cut;
  MetadataOptions metadata;
  std::filesystem::path ground_image;  // a PNG/JPEG/GeoTIFF orthophoto instead of the town
  double ground_gsd_m = 0;             // its metres per pixel (0: from the GeoTIFF)
  // A flat fill colour (BGR) that marks "no data" where it touches the image edge: orthomosaics
  // often pad with opaque white or black instead of transparency.
  std::optional<cv::Vec3b> ground_nodata_bgr;
  // Moving targets over the orthophoto: along the lines of a GeoJSON file, or generated paths.
  GroundPathOptions ground_paths;
  geo::Wgs84 origin{51.1520, -1.7470, 100.0};  // ground origin (the roundabout); Salisbury Plain
  uint64_t start_utc_us = 1790000000000000;    // time stamp of frame 0 (2026-09-21 14:13:20 UTC)
  int crf = 23;                                // H.264 quality (lower is better, bigger)
  std::string x264_preset = "veryfast";

  Status Validate() const;
  std::filesystem::path TruthPath() const;
  nlohmann::json ToJson() const;  // kSimulatorVersion and every option, recorded in the truth file
};

// Sets the options named in `overrides`, an object laid out as SimulationOptions::ToJson (nested
// groups such as {"flight": {"altitude_m": 600}}); options it does not name keep their values.
// "simulator_version" is ignored. Output paths are not options here. InvalidArgument naming the
// key for an unknown key or a value of the wrong type, so a typo in a corpus manifest is caught.
Status ApplyOptionsJson(const nlohmann::json& overrides, SimulationOptions* options);

struct SimulationSummary {
  int64_t frames = 0;  // frames in the video
  int64_t dropped_frames = 0, repeated_frames = 0;
  int64_t klv_packets = 0;
  double duration_s = 0;
  double track_length_m = 0;
  double nominal_gsd_m = 0;
  int targets = 0;
  std::filesystem::path video;
  std::filesystem::path truth;
};

// Everything a simulation is made of before frames are rendered: the flight, the world or
// orthophoto ground, the moving targets at time 0. Tests and evaluations use it to rebuild the
// exact ground a video was made from.
class SimulationSetup {
 public:
  static StatusOr<SimulationSetup> Create(const SimulationOptions& options);

  const SimulationOptions& options() const { return options_; }  // seeds filled in
  const Flight& flight() const { return *flight_; }
  const GroundSource& ground() const { return *ground_; }
  const World* world() const { return world_.get(); }  // null with an orthophoto ground
  // The procedural ground at 2, 4, 8 and 16 times its metres per pixel, for the far rows of
  // oblique frames (FrameRenderer::SetCoarserLevels); empty for nadir views and orthophotos.
  std::vector<const GroundSource*> coarser_ground() const;
  int fps_num() const { return fps_num_; }
  int fps_den() const { return fps_den_; }
  double frame_interval_s() const { return static_cast<double>(fps_den_) / fps_num_; }
  int64_t frame_count() const { return frame_count_; }
  double nominal_gsd_m() const;
  // The moment of the flight that video time `video_s` shows (later than it after a cut).
  double CameraTimeAt(double video_s) const;
  // The camera at `time_s`: the options' camera with the zoom's field of view.
  CameraIntrinsics CameraAt(double time_s) const;
  // A fresh target simulation at time 0 (null with an orthophoto ground without paths).
  std::unique_ptr<TargetSimulation> MakeTargets() const;

 private:
  SimulationSetup() = default;
  SimulationOptions options_;
  std::shared_ptr<const Flight> flight_;
  std::shared_ptr<const World> world_;
  std::shared_ptr<const World> path_world_;  // orthophoto ground: the targets' paths
  std::shared_ptr<const GroundSource> ground_;
  std::vector<std::shared_ptr<const GroundSource>> coarser_ground_;
  int fps_num_ = 25, fps_den_ = 1;
  int64_t frame_count_ = 0;
};

// Runs the simulation. Outputs are written under temporary names and renamed when complete, so a
// failure or a cancel (through `job`) never leaves a partial file behind under the final name.
StatusOr<SimulationSummary> Simulate(const SimulationOptions& options, JobContext* job = nullptr);

// The KLV packet of one frame: MISB ST 0601.17 with time stamp, platform position and attitude,
// fields of view, slant range, frame centre, offset (26-33) and full (82-89) corners, version and
// checksum. `corners_m` are the ground footprint (MISB order) already carrying any noise. A view
// that reaches the horizon has no centre (21-25, 78) or no corners (22, 26-33, 82-89) on the
// ground: those are left out.
StatusOr<std::vector<uint8_t>> EncodeFrameKlv(
    const geo::LocalTangentPlane& plane, uint64_t time_us, const CameraIntrinsics& camera,
    const CameraPose& pose, const Eigen::Vector3d& sensor_m,
    const std::optional<Eigen::Vector2d>& centre_m,
    const std::optional<std::array<Eigen::Vector2d, 4>>& corners_m, const std::string& mission);

}  // namespace saker::sim
