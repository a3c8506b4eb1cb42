#include "core/sim/simulator.h"

#include "core/klv/st0601_encode.h"
#include "core/sim/ground_image.h"
#include "core/sim/random.h"
#include "core/sim/truth.h"
#include "core/sim/world_raster.h"
#include "core/video/ts_writer.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <future>
#include <system_error>
#include <tuple>

namespace saker::sim {
namespace {

using Eigen::Vector2d;

// The frame rate as a fraction: integer rates exactly, others over 1001 (29.97 = 30000/1001).
std::pair<int, int> FrameRateFraction(double fps) {
  if (std::abs(fps - std::round(fps)) < 1e-6) return {int(std::lround(fps)), 1};
  return {int(std::lround(fps * 1001)), 1001};
}

// Removes a file if present, ignoring errors (cleanup after a failure).
void RemoveQuietly(const std::filesystem::path& path) {
  std::error_code ignored;
  std::filesystem::remove(path, ignored);
}

std::filesystem::path PartPath(const std::filesystem::path& path) {
  std::filesystem::path part = path;
  part += ".part";
  return part;
}

}  // namespace

Status MetadataOptions::Validate() const {
  if (every_n_frames < 0) return InvalidArgumentError("metadata: --klv-every must be >= 0");
  for (int64_t frame : only_frames) {
    if (frame < 0)
      return InvalidArgumentError("metadata: --klv-frames holds a negative frame number");
  }
  if (!(position_noise_m >= 0 && position_noise_m <= 10000)) {
    return InvalidArgumentError("metadata: position noise must be between 0 and 10000 m");
  }
  if (!std::isfinite(bias_east_m) || !std::isfinite(bias_north_m) ||
      std::abs(bias_east_m) > 10000 || std::abs(bias_north_m) > 10000) {
    return InvalidArgumentError("metadata: bias must be finite and at most 10000 m");
  }
  if (!(dropout_probability >= 0 && dropout_probability <= 1)) {
    return InvalidArgumentError("metadata: dropout probability must be in [0, 1]");
  }
  return Status::Ok();
}

bool MetadataOptions::Due(int64_t frame_index) const {
  if (!only_frames.empty()) {
    return std::find(only_frames.begin(), only_frames.end(), frame_index) != only_frames.end();
  }
  return every_n_frames > 0 && frame_index % every_n_frames == 0;
}

Status SimulationOptions::Validate() const {
  if (output.empty()) return InvalidArgumentError("simulate: no output file given (-o FILE.ts)");
  if (!(fps >= 1 && fps <= 240))
    return InvalidArgumentError("simulate: fps must be between 1 and 240");
  if (!(duration_s >= 0 && duration_s <= 24 * 3600)) {
    return InvalidArgumentError("simulate: duration must be between 0 (whole flight) and 24 h");
  }
  SAKER_RETURN_IF_ERROR(camera.Validate());
  if (camera.width % 2 != 0 || camera.height % 2 != 0) {
    return InvalidArgumentError("simulate: H.264 needs an even width and height, got " +
                                std::to_string(camera.width) + "x" + std::to_string(camera.height));
  }
  SAKER_RETURN_IF_ERROR(flight.Validate());
  SAKER_RETURN_IF_ERROR(world.Validate());
  SAKER_RETURN_IF_ERROR(targets.Validate());
  SAKER_RETURN_IF_ERROR(imaging.Validate());
  SAKER_RETURN_IF_ERROR(metadata.Validate());
  if (!(crf >= 0 && crf <= 51))
    return InvalidArgumentError("simulate: --crf must be between 0 and 51");
  if (ground_image.empty() && ground_gsd_m != 0) {
    return InvalidArgumentError("simulate: --gsd applies to --ground only");
  }
  if (!ground_image.empty() && scenario == Scenario::kRoundaboutLoop) {
    return InvalidArgumentError(
        "simulate: the roundabout-loop scenario follows the procedural town's roads; with --ground "
        "choose figure-eight, raster or straight");
  }
  SAKER_RETURN_IF_ERROR(geo::LocalTangentPlane::Create(origin).status());
  // KLV heights (tags 15, 25, 75, 78) reach -900 to 19000 m.
  if (!(origin.height_m >= -900 &&
        origin.height_m + flight.altitude_m + 4 * flight.altitude_jitter_m <= 19000)) {
    return InvalidArgumentError(
        "simulate: ground height and flying height must keep the sensor between -900 and 19000 m "
        "(the KLV altitude range)");
  }
  return Status::Ok();
}

std::filesystem::path SimulationOptions::TruthPath() const {
  if (!truth.empty()) return truth;
  std::filesystem::path path = output;
  path.replace_extension(".truth.json");
  return path;
}

nlohmann::json SimulationOptions::ToJson() const {
  nlohmann::json only = nlohmann::json::array();
  for (int64_t f : metadata.only_frames) only.push_back(f);
  return {
      {"simulator_version", kSimulatorVersion},
      {"scenario", ScenarioName(scenario)},
      {"seed", seed},
      {"fps", fps},
      {"duration_s", duration_s},
      {"camera",
       {{"width", camera.width}, {"height", camera.height}, {"hfov_deg", camera.hfov_deg}}},
      {"flight",
       {{"altitude_m", flight.altitude_m},
        {"speed_mps", flight.speed_mps},
        {"attitude_jitter_deg", flight.attitude_jitter_deg},
        {"altitude_jitter_m", flight.altitude_jitter_m},
        {"figure_eight_key_frames", flight.figure_eight_key_frames},
        {"key_frame_overlap", flight.key_frame_overlap},
        {"raster_rows", flight.raster_rows},
        {"raster_row_length_m", flight.raster_row_length_m},
        {"raster_sidelap", flight.raster_sidelap},
        {"straight_length_m", flight.straight_length_m},
        {"straight_heading_deg", flight.straight_heading_deg}}},
      {"world", {{"loop_length_m", world.loop_length_m}}},
      {"targets", {{"cars", targets.cars}, {"vans", targets.vans}, {"people", targets.people}}},
      {"imaging",
       {{"noise_sigma", imaging.noise_sigma},
        {"blur_sigma_px", imaging.blur_sigma_px},
        {"gain_drift", imaging.gain_drift},
        {"gain_period_s", imaging.gain_period_s},
        {"blank_start_s", imaging.blank_start_s},
        {"blank_duration_s", imaging.blank_duration_s}}},
      {"metadata",
       {{"every_n_frames", metadata.every_n_frames},
        {"only_frames", only},
        {"position_noise_m", metadata.position_noise_m},
        {"bias_east_m", metadata.bias_east_m},
        {"bias_north_m", metadata.bias_north_m},
        {"dropout_probability", metadata.dropout_probability}}},
      {"ground_image", ground_image.string()},
      {"ground_gsd_m", ground_gsd_m},
      {"ground_nodata_bgr",
       ground_nodata_bgr ? nlohmann::json::array({(*ground_nodata_bgr)[0], (*ground_nodata_bgr)[1],
                                                  (*ground_nodata_bgr)[2]})
                         : nlohmann::json()},
      {"crf", crf},
      {"x264_preset", x264_preset},
  };
}

StatusOr<std::vector<uint8_t>> EncodeFrameKlv(
    const geo::LocalTangentPlane& plane, uint64_t time_us, const CameraIntrinsics& camera,
    const CameraPose& pose, const Eigen::Vector3d& sensor_m, const Vector2d& centre_m,
    const std::array<Vector2d, 4>& corners_m, const std::string& mission) {
  // Heights: 75 and 78 are above the ellipsoid, as the simulator's world is. 15 and 25 are
  // defined above mean sea level; with no geoid model available offline the simulator takes the
  // geoid as the ellipsoid there (docs/simulator.md).
  const double ground_height = plane.origin().height_m;
  const geo::Wgs84 sensor = plane.Wgs84FromEnu(sensor_m);
  const geo::Wgs84 centre = plane.LatLonFromMap(centre_m);
  const double heading = std::fmod(std::fmod(pose.heading_deg, 360.0) + 360.0, 360.0);
  klv::St0601Encoder e;
  e.AddUnsigned(2, time_us)
      .AddString(3, mission)
      .Add(5, heading)
      .Add(6, pose.pitch_deg)
      .Add(7, pose.roll_deg)
      .AddString(10, "Saker simulator")
      .AddString(11, "EO nadir")
      .AddString(12, "Geodetic WGS84")
      .Add(13, sensor.latitude_deg)
      .Add(14, sensor.longitude_deg)
      .Add(15, sensor.height_m)
      .Add(16, camera.hfov_deg)
      .Add(17, camera.vfov_deg())
      .Add(18, 0.0)
      .Add(19, -90.0)
      .Add(20, 0.0)
      .Add(21, (Eigen::Vector3d(centre_m.x(), centre_m.y(), 0) - pose.position_m).norm())
      .Add(23, centre.latitude_deg)
      .Add(24, centre.longitude_deg)
      .Add(25, ground_height)
      .Add(75, sensor.height_m)
      .Add(78, ground_height);
  // Target width (22) only reaches 10 km; very wide footprints leave it out.
  const double target_width = (corners_m[2] - corners_m[3]).norm();
  if (target_width <= 10000) e.Add(22, target_width);
  std::array<geo::Wgs84, 4> corners;
  bool offsets_fit = true;
  for (int k = 0; k < 4; ++k) {
    corners[k] = plane.LatLonFromMap(corners_m[k]);
    offsets_fit &= std::abs(corners[k].latitude_deg - centre.latitude_deg) <= 0.075 &&
                   std::abs(corners[k].longitude_deg - centre.longitude_deg) <= 0.075;
  }
  // Offset corners (26-33) only reach 0.075 degrees from the centre; wider footprints carry only
  // the full corners.
  if (offsets_fit) {
    for (int k = 0; k < 4; ++k) {
      e.Add(26 + 2 * k, corners[k].latitude_deg - centre.latitude_deg)
          .Add(27 + 2 * k, corners[k].longitude_deg - centre.longitude_deg);
    }
  }
  for (int k = 0; k < 4; ++k) {
    e.Add(82 + 2 * k, corners[k].latitude_deg).Add(83 + 2 * k, corners[k].longitude_deg);
  }
  e.AddUnsigned(65, 17);
  return e.Finish();
}

double SimulationSetup::nominal_gsd_m() const {
  return NadirGsd(options_.camera, options_.flight.altitude_m);
}

std::unique_ptr<TargetSimulation> SimulationSetup::MakeTargets() const {
  if (!world_) return nullptr;
  return std::make_unique<TargetSimulation>(world_, options_.targets, options_.seed);
}

StatusOr<SimulationSetup> SimulationSetup::Create(const SimulationOptions& options_in) {
  SAKER_RETURN_IF_ERROR(options_in.Validate());
  SimulationSetup setup;
  SimulationOptions& options = setup.options_;
  options = options_in;
  options.flight.seed = options.seed;
  options.world.seed = options.seed;
  std::tie(setup.fps_num_, setup.fps_den_) = FrameRateFraction(options.fps);
  const double frame_interval = setup.frame_interval_s();
  const CameraIntrinsics& camera = options.camera;

  // The flight is laid out over the town (its centre and road loop depend only on the seed), so
  // generate the town first, then again over the whole area the camera will see.
  FlightSite site;
  if (options.ground_image.empty()) {
    SAKER_ASSIGN_OR_RETURN(const World town,
                           GenerateWorld(options.world, cv::Rect2d(-10, -10, 20, 20)));
    site.centre = town.town_centre;
    site.road_loop = town.road_loop;
  }
  SAKER_ASSIGN_OR_RETURN(Flight flight,
                         Flight::Create(options.scenario, options.flight, camera, site));
  setup.flight_ = std::make_shared<const Flight>(std::move(flight));
  double duration = setup.flight_->duration_s();
  if (options.duration_s > 0) {
    if (options.duration_s > duration + 1e-9) {
      return InvalidArgumentError("simulate: the " + std::string(ScenarioName(options.scenario)) +
                                  " flight lasts " + std::to_string(duration) +
                                  " s at this speed; ask for at most that (or 0 for all of it)");
    }
    duration = options.duration_s;
  }
  setup.frame_count_ = std::max<int64_t>(1, int64_t(std::floor(duration / frame_interval + 1e-9)));

  // Everything the camera sees, to size the world; every frame, so that a pose looking above the
  // horizon is an error here rather than a failed check in the renderer.
  double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300;
  for (int64_t i = 0; i < setup.frame_count_; ++i) {
    const double t = double(i) * frame_interval;
    const auto footprint = GroundFootprint(camera, setup.flight_->PoseAt(t));
    if (!footprint) {
      return InvalidArgumentError(
          "simulate: at " + std::to_string(t) +
          " s the camera sees above the horizon; reduce the attitude jitter");
    }
    for (const Vector2d& p : *footprint) {
      x0 = std::min(x0, p.x()), x1 = std::max(x1, p.x());
      y0 = std::min(y0, p.y()), y1 = std::max(y1, p.y());
    }
  }
  const cv::Rect2d seen(x0 - 300, y0 - 300, x1 - x0 + 600, y1 - y0 + 600);
  if (options.ground_image.empty()) {
    SAKER_ASSIGN_OR_RETURN(World generated, GenerateWorld(options.world, seen));
    setup.world_ = std::make_shared<const World>(std::move(generated));
    // A little finer than the frames, so the warp resamples rather than magnifies.
    setup.ground_ = std::make_shared<ProceduralGround>(
        setup.world_, std::clamp(0.8 * setup.nominal_gsd_m(), 0.02, 5.0));
  } else {
    GroundImageOptions image_options;
    image_options.path = options.ground_image;
    image_options.gsd_m = options.ground_gsd_m;
    image_options.nodata_fill_bgr = options.ground_nodata_bgr;
    SAKER_ASSIGN_OR_RETURN(std::unique_ptr<GroundImage> image, GroundImage::Load(image_options));
    setup.ground_ = std::move(image);
  }
  return setup;
}

StatusOr<SimulationSummary> Simulate(const SimulationOptions& options_in, JobContext* job) {
  SAKER_ASSIGN_OR_RETURN(const SimulationSetup setup, SimulationSetup::Create(options_in));
  const SimulationOptions& options = setup.options();
  const CameraIntrinsics& camera = options.camera;
  const Flight& flight = setup.flight();
  const double frame_interval = setup.frame_interval_s();
  const int64_t frame_count = setup.frame_count();
  const double nominal_gsd = setup.nominal_gsd_m();
  const std::unique_ptr<TargetSimulation> targets = setup.MakeTargets();
  const FrameRenderer renderer(setup.ground(), camera, options.imaging, options.seed);
  SAKER_ASSIGN_OR_RETURN(const geo::LocalTangentPlane plane,
                         geo::LocalTangentPlane::Create(options.origin));

  video::TsWriterOptions writer_options;
  writer_options.width = camera.width;
  writer_options.height = camera.height;
  writer_options.fps_num = setup.fps_num();
  writer_options.fps_den = setup.fps_den();
  writer_options.gop_size = std::max(1, int(std::lround(options.fps)));
  writer_options.crf = options.crf;
  writer_options.x264_preset = options.x264_preset;
  // libx264's output depends on its thread count: fix it so a seed gives the same file on any
  // machine (4 threads keep two cores busy and cost little on more).
  writer_options.threads = 4;
  writer_options.with_klv =
      options.metadata.every_n_frames > 0 || !options.metadata.only_frames.empty();
  const std::filesystem::path video_part = PartPath(options.output);
  SAKER_ASSIGN_OR_RETURN(std::unique_ptr<video::TsWriter> writer,
                         video::TsWriter::Open(video_part, writer_options));
  const auto fail = [&](Status status) {
    writer.reset();
    RemoveQuietly(video_part);
    return status;
  };

  Truth truth;
  truth.generator = options.ToJson();
  truth.origin_latitude_deg = options.origin.latitude_deg;
  truth.origin_longitude_deg = options.origin.longitude_deg;
  truth.origin_height_m = options.origin.height_m;
  truth.width = camera.width, truth.height = camera.height;
  truth.fx = camera.fx(), truth.fy = camera.fy(), truth.cx = camera.cx(), truth.cy = camera.cy();
  truth.fps = double(setup.fps_num()) / setup.fps_den();
  truth.start_utc_us = options.start_utc_us;
  if (targets) {
    for (const Target& t : targets->targets()) {
      truth.targets.push_back(
          {int(t.id), TargetClassName(t.target_class), t.length_m(), t.width_m(), {}});
      truth.targets.back().samples.reserve(size_t(frame_count));
    }
  }

  Random klv_random(HashCombine(options.seed, 0x4B4Cu));
  const std::string mission = std::string("SAKER SIM ") + ScenarioName(options.scenario);
  SimulationSummary summary;
  const Eigen::Vector2d shadow = targets ? targets->shadow_per_m() : Eigen::Vector2d::Zero();
  std::future<cv::Mat> pending;  // the previous frame, being rendered
  for (int64_t i = 0; i < frame_count; ++i) {
    if (job != nullptr && job->IsCancelled()) {
      if (pending.valid()) pending.wait();
      return fail(CancelledError("simulate: cancelled"));
    }
    const double t = double(i) * frame_interval;
    const CameraPose pose = flight.PoseAt(t);
    const Eigen::Matrix3d frame_from_ground = FrameFromGround(camera, pose);
    if (targets && i > 0) targets->Step(frame_interval);

    FrameTruth frame;
    frame.index = i;
    frame.time_s = t;
    frame.frame_from_ground = frame_from_ground;
    frame.position_m = pose.position_m;
    frame.heading_deg = pose.heading_deg, frame.pitch_deg = pose.pitch_deg,
    frame.roll_deg = pose.roll_deg;
    frame.blank = options.imaging.IsBlank(t);
    if (targets) {
      const std::vector<Target>& list = targets->targets();
      for (size_t k = 0; k < list.size(); ++k) {
        TargetSampleTruth s;
        s.ground_m = list[k].position;
        s.velocity_mps = list[k].velocity;
        s.image_px = (frame_from_ground * list[k].position.homogeneous()).hnormalized();
        s.visible = !frame.blank && s.image_px.x() >= -0.5 && s.image_px.y() >= -0.5 &&
                    s.image_px.x() <= camera.width - 0.5 && s.image_px.y() <= camera.height - 0.5;
        truth.targets[k].samples.push_back(s);
      }
    }

    if (options.metadata.Due(i) && !klv_random.Bernoulli(options.metadata.dropout_probability)) {
      const auto footprint = GroundFootprint(camera, pose);
      const auto centre = GroundCentre(camera, pose);
      if (!footprint || !centre)
        return fail(InvalidArgumentError("simulate: the camera looks above the horizon"));
      const Vector2d bias(options.metadata.bias_east_m, options.metadata.bias_north_m);
      const double sigma = options.metadata.position_noise_m;
      const auto noisy = [&](const Vector2d& p) {
        const double e = klv_random.Normal(), n = klv_random.Normal();
        return Vector2d(p + bias + sigma * Vector2d(e, n));
      };
      std::array<Vector2d, 4> corners;
      for (int k = 0; k < 4; ++k) corners[k] = noisy((*footprint)[k]);
      const Vector2d centre_noisy = noisy(*centre);
      const Vector2d sensor_xy = noisy(pose.position_m.head<2>());
      const Eigen::Vector3d sensor(sensor_xy.x(), sensor_xy.y(), pose.position_m.z());
      StatusOr<std::vector<uint8_t>> packet =
          EncodeFrameKlv(plane, options.start_utc_us + uint64_t(std::llround(t * 1e6)), camera,
                         pose, sensor, centre_noisy, corners, mission);
      if (!packet.ok()) return fail(packet.status());
      Status status = writer->WriteKlv(*packet, i);
      if (!status.ok()) return fail(status);
      frame.klv = true;
      ++summary.klv_packets;
    }
    truth.frames.push_back(frame);

    // Render this frame on a worker while the previous one is encoded here (the encoder has its
    // own threads too); targets are copied, so the simulation can step on.
    std::future<cv::Mat> next =
        std::async(std::launch::async,
                   [&renderer, frame_from_ground,
                    snapshot = targets ? targets->targets() : std::vector<Target>(), shadow, i,
                    t] { return renderer.Render(frame_from_ground, snapshot, shadow, i, t); });
    if (pending.valid()) {
      Status status = writer->WriteFrame(pending.get());
      if (!status.ok()) {
        next.wait();
        return fail(status);
      }
      if (job != nullptr) job->ReportProgress("simulate", double(i) / double(frame_count));
    }
    pending = std::move(next);
  }
  if (pending.valid()) {
    Status status = writer->WriteFrame(pending.get());
    if (!status.ok()) return fail(status);
    if (job != nullptr) job->ReportProgress("simulate", 1.0);
  }
  Status status = writer->Close();
  if (!status.ok()) return fail(status);
  writer.reset();

  const std::filesystem::path truth_path = options.TruthPath();
  status = WriteTruth(truth, truth_path);
  if (!status.ok()) return fail(status);
  std::error_code error;
  std::filesystem::rename(video_part, options.output, error);
  if (error) {
    return fail(IoError("cannot rename " + video_part.string() + " to " + options.output.string() +
                        ": " + error.message()));
  }
  summary.frames = frame_count;
  summary.duration_s = double(frame_count) * frame_interval;
  summary.track_length_m = flight.track().length_m();
  summary.nominal_gsd_m = nominal_gsd;
  summary.targets = int(truth.targets.size());
  summary.video = options.output;
  summary.truth = truth_path;
  return summary;
}

}  // namespace saker::sim
