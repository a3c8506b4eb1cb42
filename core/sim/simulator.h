#pragma once

// The world simulator: flies a camera over a procedural town (or a user's orthophoto) and writes
// an MPEG-TS with H.264 video and MISB ST 0601 KLV, plus a truth file (docs/simulator.md).

#include "core/geo/local_tangent_plane.h"
#include "core/sim/camera.h"
#include "core/sim/flight.h"
#include "core/sim/frame_renderer.h"
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
inline constexpr int kSimulatorVersion = 1;

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

struct SimulationOptions {
  Scenario scenario = Scenario::kRoundaboutLoop;
  std::filesystem::path output;  // the .ts file
  std::filesystem::path truth;   // empty: beside the output, <stem>.truth.json
  uint64_t seed = 1;
  double fps = 25;        // integer rates, or NTSC rates such as 29.97
  double duration_s = 0;  // 0: the whole flight path of the scenario
  CameraIntrinsics camera;
  FlightOptions flight;  // flight.seed is replaced by `seed`
  WorldOptions world;    // world.seed is replaced by `seed`
  TargetOptions targets;
  ImagingOptions imaging;
  MetadataOptions metadata;
  std::filesystem::path ground_image;  // a PNG/JPEG/GeoTIFF orthophoto instead of the town
  double ground_gsd_m = 0;             // its metres per pixel (0: from the GeoTIFF)
  // A flat fill colour (BGR) that marks "no data" where it touches the image edge: orthomosaics
  // often pad with opaque white or black instead of transparency.
  std::optional<cv::Vec3b> ground_nodata_bgr;
  geo::Wgs84 origin{51.1520, -1.7470, 100.0};  // ground origin (the roundabout); Salisbury Plain
  uint64_t start_utc_us = 1790000000000000;    // time stamp of frame 0 (2026-09-21 14:13:20 UTC)
  int crf = 23;                                // H.264 quality (lower is better, bigger)
  std::string x264_preset = "veryfast";

  Status Validate() const;
  std::filesystem::path TruthPath() const;
  nlohmann::json ToJson() const;  // kSimulatorVersion and every option, recorded in the truth file
};

struct SimulationSummary {
  int64_t frames = 0;
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
  int fps_num() const { return fps_num_; }
  int fps_den() const { return fps_den_; }
  double frame_interval_s() const { return double(fps_den_) / fps_num_; }
  int64_t frame_count() const { return frame_count_; }
  double nominal_gsd_m() const;
  // A fresh target simulation at time 0 (null with an orthophoto ground).
  std::unique_ptr<TargetSimulation> MakeTargets() const;

 private:
  SimulationSetup() = default;
  SimulationOptions options_;
  std::shared_ptr<const Flight> flight_;
  std::shared_ptr<const World> world_;
  std::shared_ptr<const GroundSource> ground_;
  int fps_num_ = 25, fps_den_ = 1;
  int64_t frame_count_ = 0;
};

// Runs the simulation. Outputs are written under temporary names and renamed when complete, so a
// failure or a cancel (through `job`) never leaves a partial file behind under the final name.
StatusOr<SimulationSummary> Simulate(const SimulationOptions& options, JobContext* job = nullptr);

// The KLV packet of one frame: MISB ST 0601.17 with time stamp, platform position and attitude,
// fields of view, slant range, frame centre, offset (26-33) and full (82-89) corners, version and
// checksum. `corners_m` are the ground footprint (MISB order) already carrying any noise.
StatusOr<std::vector<uint8_t>> EncodeFrameKlv(
    const geo::LocalTangentPlane& plane, uint64_t time_us, const CameraIntrinsics& camera,
    const CameraPose& pose, const Eigen::Vector3d& sensor_m, const Eigen::Vector2d& centre_m,
    const std::array<Eigen::Vector2d, 4>& corners_m, const std::string& mission);

}  // namespace saker::sim
