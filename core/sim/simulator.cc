#include "core/sim/simulator.h"

#include "core/klv/st0601_encode.h"
#include "core/sim/ground_image.h"
#include "core/sim/random.h"
#include "core/sim/truth.h"
#include "core/sim/world_raster.h"
#include "core/util/durable_file.h"
#include "core/video/ts_writer.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <future>
#include <map>
#include <tuple>
#include <type_traits>

namespace saker::sim {
namespace {

using Eigen::Vector2d;

// The frame rate as a fraction: integer rates exactly, others over 1001 (29.97 = 30000/1001).
std::pair<int, int> FrameRateFraction(double fps) {
  if (std::abs(fps - std::round(fps)) < 1e-6) return {static_cast<int>(std::lround(fps)), 1};
  return {static_cast<int>(std::lround(fps * 1001)), 1001};
}

// Coarser renderings of the procedural ground for oblique views: up to 16 times the detail
// ground's metres per pixel, each with a smaller tile cache than the detail level's.
constexpr int kCoarserGroundLevels = 4;
constexpr int kCoarserGroundCacheMegabytes = 64;

// One camera frame as the encoder takes it (FrameClock).
struct FrameSlot {
  int64_t slot = 0;     // the writer's time slot (frame intervals; quarters at a variable rate)
  double video_s = 0;   // its presentation time
  double camera_s = 0;  // the moment of the flight it shows (later than video_s after a cut)
  int64_t target_steps = 0;  // steps of FrameClock::step_s() the traffic moves before it
  bool dropped = false;      // lost: not in the video
  bool repeated = false;     // the previous picture again
  bool cut = false;          // the first frame after a splice
};

// The camera's frames at the nominal rate, as the encoder samples them (SamplingOptions) and an
// edit splices them (CutOptions). Without either, frame k is slot k at k frame intervals.
class FrameClock {
 public:
  FrameClock(const SimulationOptions& options, double frame_interval_s, int64_t frame_count)
      : sampling_(options.sampling),
        cut_(options.cut),
        slots_per_frame_(options.sampling.variable_rate ? kVariableRateSlots : 1),
        step_s_(frame_interval_s / slots_per_frame_),
        end_slot_(frame_count * slots_per_frame_),
        random_(HashCombine(options.seed, 0x53414D50u)) {}

  // The time slots per nominal frame interval (the writer's frame rate is this many times the
  // nominal one).
  int slots_per_frame() const { return slots_per_frame_; }
  double step_s() const { return step_s_; }
  double fraction_done() const {
    return std::min(1.0, static_cast<double>(next_slot_) / static_cast<double>(end_slot_));
  }

  // The next camera frame, or false at the end of the video.
  bool Next(FrameSlot* slot) {
    if (next_slot_ >= end_slot_) return false;
    *slot = FrameSlot();
    slot->slot = next_slot_;
    slot->video_s = static_cast<double>(next_slot_) * step_s_;
    slot->target_steps = next_slot_ - last_slot_;
    last_slot_ = next_slot_;
    const bool sampled = sampling_.drop_probability > 0 || sampling_.repeat_probability > 0;
    if (cut_.enabled() && !cut_done_ && slot->video_s >= cut_.at_s) {
      cut_done_ = true;
      slot->cut = true;
      slot->target_steps += static_cast<int64_t>(std::llround(cut_.jump_s / step_s_));
    } else if (sampled && slot->slot > 0) {
      const double u = random_.Uniform();
      slot->dropped = u < sampling_.drop_probability;
      slot->repeated =
          !slot->dropped && u < sampling_.drop_probability + sampling_.repeat_probability;
    }
    slot->camera_s = cut_done_ ? slot->video_s + cut_.jump_s : slot->video_s;
    next_slot_ +=
        slots_per_frame_ == 1 ? 1 : random_.UniformInt(slots_per_frame_ - 1, slots_per_frame_ + 1);
    return true;
  }

 private:
  // A variable rate's intervals are 3, 4 or 5 quarters of the nominal one.
  static constexpr int kVariableRateSlots = 4;

  SamplingOptions sampling_;
  CutOptions cut_;
  int slots_per_frame_;
  double step_s_;
  int64_t end_slot_;
  Random random_;
  int64_t next_slot_ = 0, last_slot_ = 0;
  bool cut_done_ = false;
};

// The KLV packet of a frame: its footprint, centre and sensor position with the metadata's noise
// and bias (drawn from `random` in a fixed order: the four corners, the centre, the sensor).
StatusOr<std::vector<uint8_t>> FrameKlv(const geo::LocalTangentPlane& plane, uint64_t utc_us,
                                        const CameraIntrinsics& lens, const CameraPose& pose,
                                        const SimulationOptions& options,
                                        const std::string& mission, Random* random) {
  // A view reaching the horizon has no ground under some corners (or the centre): the packet
  // leaves them out, as a real one does. The noise is drawn all the same, to keep the order.
  const auto footprint = GroundFootprint(lens, pose);
  const auto centre = GroundCentre(lens, pose);
  const Vector2d bias(options.metadata.bias_east_m, options.metadata.bias_north_m);
  const double sigma = options.metadata.position_noise_m;
  const auto noisy = [&](const Vector2d& p) {
    const double e = random->Normal(), n = random->Normal();
    return Vector2d(p + bias + sigma * Vector2d(e, n));
  };
  std::optional<std::array<Vector2d, 4>> corners;
  if (footprint) corners.emplace();
  for (int k = 0; k < 4; ++k) {
    const Vector2d p = noisy(footprint ? (*footprint)[k] : Vector2d::Zero());
    if (corners) (*corners)[k] = p;
  }
  const Vector2d centre_drawn = noisy(centre ? *centre : Vector2d::Zero());
  std::optional<Vector2d> centre_noisy;
  if (centre) centre_noisy = centre_drawn;
  const Vector2d sensor_xy = noisy(pose.position_m.head<2>());
  const Eigen::Vector3d sensor(sensor_xy.x(), sensor_xy.y(), pose.position_m.z());
  return EncodeFrameKlv(plane, utc_us, lens, pose, sensor, centre_noisy, corners, mission);
}

}  // namespace

Status SamplingOptions::Validate() const {
  if (!(drop_probability >= 0 && drop_probability <= 0.5) ||
      !(repeat_probability >= 0 && repeat_probability <= 0.5)) {
    return InvalidArgumentError(
        "sampling: the chances of dropped and of repeated frames must each be in [0, 0.5]");
  }
  return Status::Ok();
}

Status CutOptions::Validate() const {
  if (!enabled()) return Status::Ok();
  if (!std::isfinite(at_s) || !(jump_s >= 1 && jump_s <= 24 * 3600)) {
    return InvalidArgumentError("cut: needs a time >= 0 and a jump of 1 s .. 24 h");
  }
  return Status::Ok();
}

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
  SAKER_RETURN_IF_ERROR(zoom.Validate());
  if (camera.width % 2 != 0 || camera.height % 2 != 0) {
    return InvalidArgumentError("simulate: H.264 needs an even width and height, got " +
                                std::to_string(camera.width) + "x" + std::to_string(camera.height));
  }
  SAKER_RETURN_IF_ERROR(flight.Validate());
  SAKER_RETURN_IF_ERROR(world.Validate());
  SAKER_RETURN_IF_ERROR(targets.Validate());
  SAKER_RETURN_IF_ERROR(imaging.Validate());
  SAKER_RETURN_IF_ERROR(overlay.Validate());
  SAKER_RETURN_IF_ERROR(sampling.Validate());
  SAKER_RETURN_IF_ERROR(cut.Validate());
  if (cut.enabled() && duration_s > 0 && cut.at_s >= duration_s) {
    return InvalidArgumentError("cut: --cut-at must fall inside the video's duration");
  }
  SAKER_RETURN_IF_ERROR(metadata.Validate());
  if (!(crf >= 0 && crf <= 51))
    return InvalidArgumentError("simulate: --crf must be between 0 and 51");
  if (ground_image.empty() && ground_gsd_m != 0) {
    return InvalidArgumentError("simulate: --gsd applies to --ground only");
  }
  if (ground_image.empty() && ground_paths.enabled()) {
    return InvalidArgumentError(
        "simulate: --target-paths applies to --ground only (the town has its own roads)");
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

namespace {

// Every option once, for ToJson and ApplyOptionsJson: `visit(group, key, field)` with group ""
// for top-level keys. Output paths are not options.
template <class Options, class Visitor>
void VisitOptions(Options& o, Visitor&& visit) {
  visit("", "scenario", o.scenario);
  visit("", "seed", o.seed);
  visit("", "fps", o.fps);
  visit("", "duration_s", o.duration_s);
  visit("camera", "width", o.camera.width);
  visit("camera", "height", o.camera.height);
  visit("camera", "hfov_deg", o.camera.hfov_deg);
  visit("zoom", "start_s", o.zoom.start_s);
  visit("zoom", "duration_s", o.zoom.duration_s);
  visit("zoom", "to_hfov_deg", o.zoom.to_hfov_deg);
  visit("flight", "altitude_m", o.flight.altitude_m);
  visit("flight", "speed_mps", o.flight.speed_mps);
  visit("flight", "attitude_jitter_deg", o.flight.attitude_jitter_deg);
  visit("flight", "altitude_jitter_m", o.flight.altitude_jitter_m);
  visit("flight", "figure_eight_key_frames", o.flight.figure_eight_key_frames);
  visit("flight", "key_frame_overlap", o.flight.key_frame_overlap);
  visit("flight", "raster_rows", o.flight.raster_rows);
  visit("flight", "raster_row_length_m", o.flight.raster_row_length_m);
  visit("flight", "raster_sidelap", o.flight.raster_sidelap);
  visit("flight", "straight_length_m", o.flight.straight_length_m);
  visit("flight", "straight_heading_deg", o.flight.straight_heading_deg);
  visit("flight", "orbit_radius_m", o.flight.orbit_radius_m);
  visit("flight", "gimbal_off_nadir_deg", o.flight.gimbal_off_nadir_deg);
  visit("flight", "gimbal_azimuth_deg", o.flight.gimbal_azimuth_deg);
  visit("world", "loop_length_m", o.world.loop_length_m);
  visit("targets", "cars", o.targets.cars);
  visit("targets", "vans", o.targets.vans);
  visit("targets", "people", o.targets.people);
  visit("targets", "slow_walker_fraction", o.targets.slow_walker_fraction);
  visit("targets", "group_size", o.targets.group_size);
  visit("targets", "stop_and_go", o.targets.stop_and_go);
  visit("imaging", "look", o.imaging.look);
  visit("imaging", "polarity_switch_s", o.imaging.polarity_switch_s);
  visit("imaging", "haze", o.imaging.haze);
  visit("imaging", "motion_blur_px", o.imaging.motion_blur_px);
  visit("imaging", "lens_k1", o.imaging.lens_k1);
  visit("imaging", "noise_sigma", o.imaging.noise_sigma);
  visit("imaging", "blur_sigma_px", o.imaging.blur_sigma_px);
  visit("imaging", "gain_drift", o.imaging.gain_drift);
  visit("imaging", "gain_period_s", o.imaging.gain_period_s);
  visit("imaging", "blank_start_s", o.imaging.blank_start_s);
  visit("imaging", "blank_duration_s", o.imaging.blank_duration_s);
  visit("sampling", "drop_probability", o.sampling.drop_probability);
  visit("sampling", "repeat_probability", o.sampling.repeat_probability);
  visit("sampling", "variable_rate", o.sampling.variable_rate);
  visit("cut", "at_s", o.cut.at_s);
  visit("cut", "jump_s", o.cut.jump_s);
  visit("overlay", "hud_text", o.overlay.hud_text);
  visit("overlay", "reticle", o.overlay.reticle);
  visit("overlay", "logo", o.overlay.logo);
  visit("overlay", "logo_turn_deg_per_s", o.overlay.logo_turn_deg_per_s);
  visit("overlay", "logo_pulse_hz", o.overlay.logo_pulse_hz);
  visit("overlay", "opacity", o.overlay.opacity);
  visit("metadata", "every_n_frames", o.metadata.every_n_frames);
  visit("metadata", "only_frames", o.metadata.only_frames);
  visit("metadata", "position_noise_m", o.metadata.position_noise_m);
  visit("metadata", "bias_east_m", o.metadata.bias_east_m);
  visit("metadata", "bias_north_m", o.metadata.bias_north_m);
  visit("metadata", "dropout_probability", o.metadata.dropout_probability);
  visit("", "ground_image", o.ground_image);
  visit("", "ground_gsd_m", o.ground_gsd_m);
  visit("", "ground_nodata_bgr", o.ground_nodata_bgr);
  visit("ground_paths", "geojson", o.ground_paths.geojson);
  visit("ground_paths", "generated", o.ground_paths.generated);
  visit("", "crf", o.crf);
  visit("", "x264_preset", o.x264_preset);
}

nlohmann::json OptionToJson(Scenario scenario) { return ScenarioName(scenario); }
nlohmann::json OptionToJson(LogoMotion motion) { return LogoMotionName(motion); }
nlohmann::json OptionToJson(SensorLook look) { return SensorLookName(look); }
nlohmann::json OptionToJson(const std::filesystem::path& path) { return path.string(); }
nlohmann::json OptionToJson(const std::optional<cv::Vec3b>& bgr) {
  if (!bgr) return nlohmann::json();
  return nlohmann::json::array({(*bgr)[0], (*bgr)[1], (*bgr)[2]});
}
template <class T>
nlohmann::json OptionToJson(const T& value) {
  return value;
}

Status OptionFromJson(const nlohmann::json& j, Scenario* scenario) {
  const std::optional<Scenario> parsed =
      j.is_string() ? ParseScenario(j.get<std::string>()) : std::nullopt;
  if (!parsed) return InvalidArgumentError("unknown scenario " + j.dump());
  *scenario = *parsed;
  return Status::Ok();
}
Status OptionFromJson(const nlohmann::json& j, SensorLook* look) {
  const std::optional<SensorLook> parsed =
      j.is_string() ? ParseSensorLook(j.get<std::string>()) : std::nullopt;
  if (!parsed) return InvalidArgumentError("unknown sensor look " + j.dump());
  *look = *parsed;
  return Status::Ok();
}
Status OptionFromJson(const nlohmann::json& j, LogoMotion* motion) {
  const std::optional<LogoMotion> parsed =
      j.is_string() ? ParseLogoMotion(j.get<std::string>()) : std::nullopt;
  if (!parsed) return InvalidArgumentError("unknown logo motion " + j.dump());
  *motion = *parsed;
  return Status::Ok();
}
Status OptionFromJson(const nlohmann::json& j, std::filesystem::path* path) {
  *path = j.get<std::string>();
  return Status::Ok();
}
Status OptionFromJson(const nlohmann::json& j, std::optional<cv::Vec3b>* bgr) {
  if (j.is_null()) {
    bgr->reset();
    return Status::Ok();
  }
  const auto v = j.get<std::array<int, 3>>();
  for (int c : v) {
    if (c < 0 || c > 255) return InvalidArgumentError("colour components must be 0..255");
  }
  *bgr =
      cv::Vec3b(static_cast<uint8_t>(v[0]), static_cast<uint8_t>(v[1]), static_cast<uint8_t>(v[2]));
  return Status::Ok();
}
Status OptionFromJson(const nlohmann::json& j, bool* value) {
  if (!j.is_boolean()) return InvalidArgumentError("expected true or false, got " + j.dump());
  *value = j.get<bool>();
  return Status::Ok();
}
template <class T>
Status OptionFromJson(const nlohmann::json& j, T* value) {
  if constexpr (std::is_arithmetic_v<T>) {
    if (!j.is_number()) return InvalidArgumentError("expected a number, got " + j.dump());
    if constexpr (std::is_integral_v<T>) {
      if (!j.is_number_integer() && !j.is_number_unsigned())
        return InvalidArgumentError("expected a whole number, got " + j.dump());
      if constexpr (std::is_unsigned_v<T>) {
        if (j.is_number_integer() && j.get<int64_t>() < 0)
          return InvalidArgumentError("expected a number >= 0, got " + j.dump());
      }
    }
  }
  *value = j.get<T>();
  return Status::Ok();
}

}  // namespace

nlohmann::json SimulationOptions::ToJson() const {
  nlohmann::json j = {{"simulator_version", kSimulatorVersion}};
  VisitOptions(*this, [&](const char* group, const char* key, const auto& field) {
    if (*group == '\0') {
      j[key] = OptionToJson(field);
    } else {
      j[group][key] = OptionToJson(field);
    }
  });
  return j;
}

Status ApplyOptionsJson(const nlohmann::json& overrides, SimulationOptions* options) {
  if (!overrides.is_object()) return InvalidArgumentError("simulation options must be an object");
  SimulationOptions result = *options;
  // Every key of `overrides` must be visited once; count them off.
  std::map<std::string, bool> seen;
  for (const auto& [key, value] : overrides.items()) {
    if (key == "simulator_version") continue;
    if (value.is_object()) {
      for (const auto& item : value.items()) seen[key + "." + item.key()] = false;
    } else {
      seen[key] = false;
    }
  }
  Status status = Status::Ok();
  VisitOptions(result, [&](const char* group, const char* key, auto& field) {
    const std::string name = *group == '\0' ? std::string(key) : std::string(group) + "." + key;
    const auto found = seen.find(name);
    if (found == seen.end() || !status.ok()) return;
    found->second = true;
    const nlohmann::json& value = *group == '\0' ? overrides.at(key) : overrides.at(group).at(key);
    try {
      Status parsed = OptionFromJson(value, &field);
      if (!parsed.ok()) status = InvalidArgumentError("option " + name + ": " + parsed.message());
    } catch (const nlohmann::json::exception&) {
      status = InvalidArgumentError("option " + name + ": value " + value.dump() +
                                    " has the wrong type");
    }
  });
  SAKER_RETURN_IF_ERROR(status);
  for (const auto& [name, used] : seen) {
    if (!used) return InvalidArgumentError("unknown simulation option '" + name + "'");
  }
  *options = result;
  return Status::Ok();
}

StatusOr<std::vector<uint8_t>> EncodeFrameKlv(
    const geo::LocalTangentPlane& plane, uint64_t time_us, const CameraIntrinsics& camera,
    const CameraPose& pose, const Eigen::Vector3d& sensor_m,
    const std::optional<Vector2d>& centre_m,
    const std::optional<std::array<Vector2d, 4>>& corners_m, const std::string& mission) {
  // Heights: 75 and 78 are above the ellipsoid, as the simulator's world is. 15 and 25 are
  // defined above mean sea level; with no geoid model available offline the simulator takes the
  // geoid as the ellipsoid there (docs/simulator.md).
  const double ground_height = plane.origin().height_m;
  const geo::Wgs84 sensor = plane.Wgs84FromEnu(sensor_m);
  const double heading = std::fmod(std::fmod(pose.heading_deg, 360.0) + 360.0, 360.0);
  klv::St0601Encoder e;
  e.AddUnsigned(2, time_us)
      .AddString(3, mission)
      .Add(5, heading)
      .Add(6, pose.pitch_deg)
      .Add(7, pose.roll_deg)
      .AddString(10, "Saker simulator")
      .AddString(11, pose.gimbal_off_nadir_deg == 0 ? "EO nadir" : "EO gimbal")
      .AddString(12, "Geodetic WGS84")
      .Add(13, sensor.latitude_deg)
      .Add(14, sensor.longitude_deg)
      .Add(15, sensor.height_m)
      .Add(16, camera.hfov_deg)
      .Add(17, camera.vfov_deg())
      .Add(18, std::fmod(std::fmod(pose.gimbal_azimuth_deg, 360.0) + 360.0, 360.0))
      .Add(19, pose.gimbal_off_nadir_deg - 90.0)
      .Add(20, 0.0)
      .Add(75, sensor.height_m);
  if (centre_m) {
    const geo::Wgs84 centre = plane.LatLonFromMap(*centre_m);
    e.Add(21, (Eigen::Vector3d(centre_m->x(), centre_m->y(), 0) - pose.position_m).norm())
        .Add(23, centre.latitude_deg)
        .Add(24, centre.longitude_deg)
        .Add(25, ground_height)
        .Add(78, ground_height);
  }
  if (corners_m) {
    // Target width (22) only reaches 10 km; very wide footprints leave it out.
    const double target_width = ((*corners_m)[2] - (*corners_m)[3]).norm();
    if (target_width <= 10000) e.Add(22, target_width);
    std::array<geo::Wgs84, 4> corners;
    for (int k = 0; k < 4; ++k) corners[k] = plane.LatLonFromMap((*corners_m)[k]);
    // Offset corners (26-33) are relative to the centre and only reach 0.075 degrees from it;
    // wider footprints carry only the full corners.
    if (centre_m) {
      const geo::Wgs84 centre = plane.LatLonFromMap(*centre_m);
      std::array<double, 4> longitude_offsets{};  // across the antimeridian the short way round
      bool offsets_fit = true;
      for (int k = 0; k < 4; ++k) {
        longitude_offsets[k] =
            geo::UnwrapLongitude(corners[k].longitude_deg, centre.longitude_deg) -
            centre.longitude_deg;
        offsets_fit &= std::abs(corners[k].latitude_deg - centre.latitude_deg) <= 0.075 &&
                       std::abs(longitude_offsets[k]) <= 0.075;
      }
      if (offsets_fit) {
        for (int k = 0; k < 4; ++k) {
          e.Add(26 + 2 * k, corners[k].latitude_deg - centre.latitude_deg)
              .Add(27 + 2 * k, longitude_offsets[k]);
        }
      }
    }
    for (int k = 0; k < 4; ++k) {
      e.Add(82 + 2 * k, corners[k].latitude_deg).Add(83 + 2 * k, corners[k].longitude_deg);
    }
  }
  e.AddUnsigned(65, 17);
  return e.Finish();
}

std::vector<const GroundSource*> SimulationSetup::coarser_ground() const {
  std::vector<const GroundSource*> levels;
  for (const auto& level : coarser_ground_) levels.push_back(level.get());
  return levels;
}

double SimulationSetup::CameraTimeAt(double video_s) const {
  const CutOptions& cut = options_.cut;
  return cut.enabled() && video_s >= cut.at_s ? video_s + cut.jump_s : video_s;
}

CameraIntrinsics SimulationSetup::CameraAt(double time_s) const {
  CameraIntrinsics camera = options_.camera;
  camera.hfov_deg = options_.zoom.HfovAt(time_s, camera.hfov_deg);
  return camera;
}

double SimulationSetup::nominal_gsd_m() const {
  return NadirGsd(options_.camera, options_.flight.altitude_m);
}

std::unique_ptr<TargetSimulation> SimulationSetup::MakeTargets() const {
  const std::shared_ptr<const World>& world = world_ ? world_ : path_world_;
  if (!world) return nullptr;
  return std::make_unique<TargetSimulation>(world, options_.targets, options_.seed);
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
  if (options.cut.enabled() && duration + options.cut.jump_s > setup.flight_->duration_s() + 1e-9) {
    return InvalidArgumentError(
        "simulate: a cut jumping " + std::to_string(options.cut.jump_s) + " s ahead needs a " +
        std::to_string(duration + options.cut.jump_s) + " s flight; the " +
        ScenarioName(options.scenario) + " flight lasts " +
        std::to_string(setup.flight_->duration_s()) + " s: shorten --duration or the jump");
  }
  setup.frame_count_ =
      std::max<int64_t>(1, static_cast<int64_t>(std::floor(duration / frame_interval + 1e-9)));

  // Everything the camera sees, to size the world; every frame, so that a pose seeing no ground is
  // an error here rather than a failed check in the renderer.
  double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300;
  for (int64_t i = 0; i < setup.frame_count_; ++i) {
    const double t = setup.CameraTimeAt(static_cast<double>(i) * frame_interval);
    const CameraIntrinsics lens = setup.CameraAt(t);
    const CameraPose pose = setup.flight_->PoseAt(t);
    // A view reaching the horizon sees the ground out to the renderer's draw distance.
    std::vector<Vector2d> seen_points;
    if (const auto footprint = GroundFootprint(lens, pose)) {
      seen_points.assign(footprint->begin(), footprint->end());
    } else {
      seen_points = VisibleGroundOutline(lens, pose, FrameRenderer::kDrawDistanceHeights);
    }
    if (seen_points.empty()) {
      return InvalidArgumentError(
          "simulate: at " + std::to_string(t) + " s the camera sees no ground within " +
          std::to_string(static_cast<int>(FrameRenderer::kDrawDistanceHeights)) +
          " heights along its image border; reduce the angle off nadir "
          "(in an orbit: the radius against the altitude) or the attitude "
          "jitter");
    }
    for (const Vector2d& p : seen_points) {
      x0 = std::min(x0, p.x()), x1 = std::max(x1, p.x());
      y0 = std::min(y0, p.y()), y1 = std::max(y1, p.y());
    }
  }
  const cv::Rect2d seen(x0 - 300, y0 - 300, x1 - x0 + 600, y1 - y0 + 600);
  if (options.ground_image.empty()) {
    SAKER_ASSIGN_OR_RETURN(World generated, GenerateWorld(options.world, seen));
    setup.world_ = std::make_shared<const World>(std::move(generated));
    // A little finer than the frames (at the narrowest field of view of a zoom), so the warp
    // resamples rather than magnifies.
    const double finest_gsd_m =
        options.zoom.enabled()
            ? NadirGsd(setup.CameraAt(options.zoom.start_s + options.zoom.duration_s),
                       options.flight.altitude_m)
            : setup.nominal_gsd_m();
    const double gsd_m = std::clamp(0.8 * std::min(finest_gsd_m, setup.nominal_gsd_m()), 0.02, 5.0);
    setup.ground_ = std::make_shared<ProceduralGround>(setup.world_, gsd_m);
    const bool oblique = options.scenario == Scenario::kOrbit ||
                         options.flight.gimbal_off_nadir_deg > 0 || options.zoom.enabled();
    for (int level = 1; oblique && level <= kCoarserGroundLevels; ++level) {
      setup.coarser_ground_.push_back(std::make_shared<ProceduralGround>(
          setup.world_, gsd_m * static_cast<double>(1 << level), kCoarserGroundCacheMegabytes));
    }
  } else {
    GroundImageOptions image_options;
    image_options.path = options.ground_image;
    image_options.gsd_m = options.ground_gsd_m;
    image_options.nodata_fill_bgr = options.ground_nodata_bgr;
    SAKER_ASSIGN_OR_RETURN(std::unique_ptr<GroundImage> image, GroundImage::Load(image_options));
    setup.ground_ = std::move(image);
    if (options.ground_paths.enabled()) {
      SAKER_ASSIGN_OR_RETURN(const geo::LocalTangentPlane plane,
                             geo::LocalTangentPlane::Create(options.origin));
      SAKER_ASSIGN_OR_RETURN(
          World paths,
          MakePathWorld(options.ground_paths, setup.ground_->extent_m(), plane, options.seed));
      setup.path_world_ = std::make_shared<const World>(std::move(paths));
    }
  }
  return setup;
}

namespace {

// One run of Simulate over a setup: steps the targets frame by frame, records the truth, writes
// the KLV and hands the frames to the encoder. Frames are rendered on a worker one ahead of the
// encoder: while frame k renders, frame k - 1 is encoded here (the encoder has its own threads
// too).
class SimulationRun {
 public:
  SimulationRun(const SimulationSetup& setup, const geo::LocalTangentPlane& plane, JobContext* job)
      : setup_(setup),
        options_(setup.options()),
        camera_(options_.camera),
        plane_(plane),
        job_(job),
        targets_(setup.MakeTargets()),
        renderer_(setup.ground(), camera_, options_.imaging, options_.seed),
        overlay_(options_.overlay, camera_.width, camera_.height),
        clock_(options_, setup.frame_interval_s(), setup.frame_count()),
        klv_random_(HashCombine(options_.seed, 0x4B4Cu)),
        mission_(std::string("SAKER SIM ") + ScenarioName(options_.scenario)),
        shadow_(targets_ ? targets_->shadow_per_m() : Eigen::Vector2d::Zero()) {
    renderer_.SetCoarserLevels(setup.coarser_ground());
    InitTruth();
  }

  // The encoder's settings for this run's video.
  video::TsWriterOptions WriterOptions() const;
  // Renders and writes every frame, its KLV and its truth; `writer` is left open.
  Status WriteFrames(video::TsWriter* writer);

  const Truth& truth() const { return truth_; }
  const SimulationSummary& summary() const { return summary_; }

 private:
  // The truth's header: the generator, origin, camera, overlays and one entry per target.
  void InitTruth();
  // Records the truth and KLV of the camera frame in `slot` (the `k`th camera frame), starts
  // rendering it and writes the frame before it.
  Status AddFrame(const FrameSlot& slot, int64_t k);
  // The truth of a frame showing a new picture, without its KLV flag; appends the targets'
  // samples.
  FrameTruth NewFrameTruth(int64_t index, double time_s, bool cut, const CameraPose& pose,
                           const CameraIntrinsics& lens, const Eigen::Matrix3d& frame_from_ground);
  // The truth of a repeated frame: the previous frame's, with this frame's index and time.
  void RepeatPreviousTruth(int64_t index, double time_s);
  // Writes frame `index`'s KLV packet at writer slot `slot` when it is due and not dropped.
  Status WriteKlvIfDue(int64_t index, int64_t slot, uint64_t utc_us, const CameraIntrinsics& lens,
                       const CameraPose& pose, FrameTruth* frame);
  // Starts rendering a frame on a worker; the targets are copied, so the simulation can step on.
  std::shared_future<cv::Mat> StartRender(const Eigen::Matrix3d& frame_from_ground, int64_t k,
                                          double time_s, const HudTelemetry& telemetry) const;
  // Writes the pending frame at its time slot, leaving the slots before it empty.
  Status WritePending();

  const SimulationSetup& setup_;
  const SimulationOptions& options_;
  const CameraIntrinsics& camera_;
  const geo::LocalTangentPlane& plane_;
  JobContext* job_;
  const std::unique_ptr<TargetSimulation> targets_;
  FrameRenderer renderer_;
  const OverlayPainter overlay_;
  FrameClock clock_;
  Random klv_random_;
  const std::string mission_;
  const Eigen::Vector2d shadow_;
  Truth truth_;
  SimulationSummary summary_;
  video::TsWriter* writer_ = nullptr;    // the encoder, while WriteFrames runs
  std::shared_future<cv::Mat> pending_;  // the previous frame, being rendered
  int64_t pending_slot_ = 0;             // its time slot
  int64_t next_slot_ = 0;                // the writer's next time slot
};

video::TsWriterOptions SimulationRun::WriterOptions() const {
  video::TsWriterOptions writer_options;
  writer_options.width = camera_.width;
  writer_options.height = camera_.height;
  writer_options.fps_num = setup_.fps_num() * clock_.slots_per_frame();
  writer_options.fps_den = setup_.fps_den();
  writer_options.gop_size = std::max(1, static_cast<int>(std::lround(options_.fps)));
  writer_options.crf = options_.crf;
  writer_options.x264_preset = options_.x264_preset;
  // libx264's output depends on its thread count: fix it so a seed gives the same file on any
  // machine (4 threads keep two cores busy and cost little on more).
  writer_options.threads = 4;
  writer_options.with_klv =
      options_.metadata.every_n_frames > 0 || !options_.metadata.only_frames.empty();
  return writer_options;
}

void SimulationRun::InitTruth() {
  truth_.generator = options_.ToJson();
  truth_.origin_latitude_deg = options_.origin.latitude_deg;
  truth_.origin_longitude_deg = options_.origin.longitude_deg;
  truth_.origin_height_m = options_.origin.height_m;
  truth_.width = camera_.width, truth_.height = camera_.height;
  truth_.fx = camera_.fx(), truth_.fy = camera_.fy(), truth_.cx = camera_.cx(),
  truth_.cy = camera_.cy();
  truth_.fps = static_cast<double>(setup_.fps_num()) / setup_.fps_den();
  truth_.start_utc_us = options_.start_utc_us;
  truth_.overlays = overlay_.regions();
  if (targets_) {
    for (const Target& t : targets_->targets()) {
      truth_.targets.push_back(
          {static_cast<int>(t.id), TargetClassName(t.target_class), t.length_m(), t.width_m(), {}});
      truth_.targets.back().samples.reserve(static_cast<size_t>(setup_.frame_count()));
    }
  }
}

Status SimulationRun::WriteFrames(video::TsWriter* writer) {
  writer_ = writer;
  FrameSlot slot;
  for (int64_t k = 0; clock_.Next(&slot); ++k) {
    if (job_ != nullptr && job_->IsCancelled()) {
      if (pending_.valid()) pending_.wait();
      return CancelledError("simulate: cancelled");
    }
    for (int64_t step = 0; targets_ && step < slot.target_steps; ++step) {
      targets_->Step(clock_.step_s());
    }
    if (slot.dropped) {
      ++summary_.dropped_frames;
      continue;
    }
    SAKER_RETURN_IF_ERROR(AddFrame(slot, k));
  }
  if (pending_.valid()) {
    SAKER_RETURN_IF_ERROR(WritePending());
    if (job_ != nullptr) job_->ReportProgress("simulate", 1.0);
  }
  return Status::Ok();
}

Status SimulationRun::AddFrame(const FrameSlot& slot, int64_t k) {
  const int64_t i = static_cast<int64_t>(truth_.frames.size());  // the frame's index in the video
  const double t = slot.video_s;
  const CameraPose pose = setup_.flight().PoseAt(slot.camera_s);
  const CameraIntrinsics lens = setup_.CameraAt(slot.camera_s);
  const Eigen::Matrix3d frame_from_ground = FrameFromGround(lens, pose);
  // UTC of the moment shown (after a cut, later than the video time says).
  const uint64_t utc_us =
      options_.start_utc_us + static_cast<uint64_t>(std::llround(slot.camera_s * 1e6));

  if (slot.repeated) {
    RepeatPreviousTruth(i, t);
  } else {
    FrameTruth frame = NewFrameTruth(i, t, slot.cut, pose, lens, frame_from_ground);
    SAKER_RETURN_IF_ERROR(WriteKlvIfDue(i, slot.slot, utc_us, lens, pose, &frame));
    truth_.frames.push_back(frame);
  }

  // A repeat shares the previous frame's picture.
  std::shared_future<cv::Mat> next;
  if (slot.repeated) {
    next = pending_;
  } else {
    HudTelemetry telemetry;
    telemetry.utc_us = utc_us;
    telemetry.frame_index = i;
    const geo::Wgs84 sensor = plane_.Wgs84FromEnu(pose.position_m);
    telemetry.latitude_deg = sensor.latitude_deg, telemetry.longitude_deg = sensor.longitude_deg;
    telemetry.height_m = sensor.height_m;
    telemetry.heading_deg = pose.heading_deg;
    telemetry.hfov_deg = lens.hfov_deg;
    next = StartRender(frame_from_ground, k, t, telemetry);
  }
  if (pending_.valid()) {
    Status status = WritePending();
    if (!status.ok()) {
      next.wait();
      return status;
    }
    if (job_ != nullptr) job_->ReportProgress("simulate", clock_.fraction_done());
  }
  pending_ = std::move(next);
  pending_slot_ = slot.slot;
  return Status::Ok();
}

FrameTruth SimulationRun::NewFrameTruth(int64_t index, double time_s, bool cut,
                                        const CameraPose& pose, const CameraIntrinsics& lens,
                                        const Eigen::Matrix3d& frame_from_ground) {
  FrameTruth frame;
  frame.index = index;
  frame.time_s = time_s;
  frame.frame_from_ground = frame_from_ground;
  frame.position_m = pose.position_m;
  frame.heading_deg = pose.heading_deg, frame.pitch_deg = pose.pitch_deg,
  frame.roll_deg = pose.roll_deg;
  frame.blank = options_.imaging.IsBlank(time_s);
  frame.cut = cut;
  frame.hfov_deg = lens.hfov_deg;
  frame.gimbal_azimuth_deg = pose.gimbal_azimuth_deg;
  frame.gimbal_off_nadir_deg = pose.gimbal_off_nadir_deg;
  if (targets_) {
    const std::vector<Target>& list = targets_->targets();
    for (size_t n = 0; n < list.size(); ++n) {
      TargetSampleTruth sample;
      sample.ground_m = list[n].position;
      sample.velocity_mps = list[n].velocity;
      sample.image_px =
          LensDistort((frame_from_ground * list[n].position.homogeneous()).hnormalized(),
                      camera_.width, camera_.height, options_.imaging.lens_k1);
      sample.visible = !frame.blank && sample.image_px.x() >= -0.5 && sample.image_px.y() >= -0.5 &&
                       sample.image_px.x() <= camera_.width - 0.5 &&
                       sample.image_px.y() <= camera_.height - 0.5 &&
                       renderer_.Shows(frame_from_ground, list[n].position);
      truth_.targets[n].samples.push_back(sample);
    }
  }
  return frame;
}

void SimulationRun::RepeatPreviousTruth(int64_t index, double time_s) {
  FrameTruth frame = truth_.frames.back();
  frame.index = index;
  frame.time_s = time_s;
  frame.repeated = true;
  frame.klv = false;
  frame.cut = false;
  truth_.frames.push_back(frame);
  for (TargetTruth& target : truth_.targets) target.samples.push_back(target.samples.back());
  ++summary_.repeated_frames;
}

Status SimulationRun::WriteKlvIfDue(int64_t index, int64_t slot, uint64_t utc_us,
                                    const CameraIntrinsics& lens, const CameraPose& pose,
                                    FrameTruth* frame) {
  // The dropout is drawn only for due frames, then the packet's noise.
  if (!options_.metadata.Due(index) ||
      klv_random_.Bernoulli(options_.metadata.dropout_probability)) {
    return Status::Ok();
  }
  SAKER_ASSIGN_OR_RETURN(const std::vector<uint8_t> packet,
                         FrameKlv(plane_, utc_us, lens, pose, options_, mission_, &klv_random_));
  SAKER_RETURN_IF_ERROR(writer_->WriteKlv(packet, slot));
  frame->klv = true;
  ++summary_.klv_packets;
  return Status::Ok();
}

std::shared_future<cv::Mat> SimulationRun::StartRender(const Eigen::Matrix3d& frame_from_ground,
                                                       int64_t k, double time_s,
                                                       const HudTelemetry& telemetry) const {
  const FrameRenderer& renderer = renderer_;
  const OverlayPainter& overlay = overlay_;
  return std::async(std::launch::async,
                    [&renderer, &overlay, frame_from_ground,
                     snapshot = targets_ ? targets_->targets() : std::vector<Target>(),
                     shadow = shadow_, k, t = time_s, telemetry] {
                      cv::Mat picture = renderer.Render(frame_from_ground, snapshot, shadow, k, t);
                      overlay.Paint(telemetry, t, &picture);
                      return picture;
                    })
      .share();
}

Status SimulationRun::WritePending() {
  SAKER_RETURN_IF_ERROR(writer_->SkipFrames(pending_slot_ - next_slot_));
  next_slot_ = pending_slot_ + 1;
  return writer_->WriteFrame(pending_.get());
}

}  // namespace

StatusOr<SimulationSummary> Simulate(const SimulationOptions& options_in, JobContext* job) {
  SAKER_ASSIGN_OR_RETURN(const SimulationSetup setup, SimulationSetup::Create(options_in));
  const SimulationOptions& options = setup.options();
  SAKER_ASSIGN_OR_RETURN(const geo::LocalTangentPlane plane,
                         geo::LocalTangentPlane::Create(options.origin));
  SimulationRun run(setup, plane, job);

  // The video is renamed into place once it and its truth are complete.
  FileReplacement video(options.output.string());
  SAKER_ASSIGN_OR_RETURN(std::unique_ptr<video::TsWriter> writer,
                         video::TsWriter::Open(video.temporary(), run.WriterOptions()));
  const auto fail = [&](Status status) {
    writer.reset();
    video.Discard();
    return status;
  };
  Status status = run.WriteFrames(writer.get());
  if (!status.ok()) return fail(status);
  status = writer->Close();
  if (!status.ok()) return fail(status);
  writer.reset();

  const std::filesystem::path truth_path = options.TruthPath();
  status = WriteTruth(run.truth(), truth_path);
  if (!status.ok()) return fail(status);
  status = video.Commit();
  if (!status.ok()) return status;
  SimulationSummary summary = run.summary();
  summary.frames = static_cast<int64_t>(run.truth().frames.size());
  summary.duration_s = static_cast<double>(setup.frame_count()) * setup.frame_interval_s();
  summary.track_length_m = setup.flight().track().length_m();
  summary.nominal_gsd_m = setup.nominal_gsd_m();
  summary.targets = static_cast<int>(run.truth().targets.size());
  summary.video = options.output;
  summary.truth = truth_path;
  return summary;
}

}  // namespace saker::sim
