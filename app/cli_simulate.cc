#include "app/cli_simulate.h"

#include "app/cli_common.h"
#include "app/cli_interrupt.h"
#include "core/sim/simulator.h"
#include "core/util/job_context.h"
#include "core/util/timer.h"

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>
#include <sstream>

namespace saker::app {
namespace {

// A one-line progress bar on stderr when it is a terminal; silent otherwise.
class ProgressBar {
 public:
  ProgressBar() : enabled_(isatty(STDERR_FILENO) != 0) {}
  void Update(double fraction) {
    if (!enabled_) return;
    if (fraction < 1.0 && drawn_ && since_last_.ElapsedMs() < 200) return;
    drawn_ = true;
    since_last_.Restart();
    const double elapsed = start_.ElapsedSeconds();
    const int width = 30;
    const int filled = static_cast<int>(fraction * width);
    std::fprintf(stderr, "\rsimulate [%s%s] %3d%%  %.0f s  ",
                 std::string(static_cast<size_t>(filled), '#').c_str(),
                 std::string(static_cast<size_t>(width - filled), ' ').c_str(),
                 static_cast<int>(fraction * 100), elapsed);
    if (fraction > 0 && fraction < 1)
      std::fprintf(stderr, "eta %.0f s ", elapsed * (1 - fraction) / fraction);
    if (fraction >= 1.0) std::fprintf(stderr, "\n");
    std::fflush(stderr);
  }

 private:
  bool enabled_;
  Stopwatch start_;
  Stopwatch since_last_;  // since the last drawing
  bool drawn_ = false;
};

int RunSimulation(const sim::SimulationOptions& options, bool quiet) {
  ProgressBar bar;
  JobContext job([&](const std::string&, double fraction) {
    if (!quiet) bar.Update(fraction);
  });
  StatusOr<sim::SimulationSummary> summary = [&] {
    const ScopedInterrupt interrupt(&job);
    return sim::Simulate(options, &job);
  }();
  if (!summary.ok()) {
    std::cerr << "\nsaker-cli: " << summary.status().message() << "\n";
    return kExitFailed;
  }
  if (!quiet) {
    std::cout << "wrote " << summary->video.string() << ": " << summary->frames << " frames ("
              << summary->duration_s << " s";
    if (summary->dropped_frames > 0 || summary->repeated_frames > 0) {
      std::cout << "; " << summary->dropped_frames << " dropped, " << summary->repeated_frames
                << " repeated";
    }
    std::cout << "), " << summary->klv_packets << " KLV packets, " << summary->targets
              << " moving targets, track " << static_cast<int>(summary->track_length_m) << " m, "
              << summary->nominal_gsd_m << " m/pixel at nadir\n"
              << "wrote " << summary->truth.string() << "\n";
  }
  return kExitOk;
}

std::string ScenarioList() {
  std::ostringstream out;
  for (sim::Scenario s : sim::AllScenarios()) {
    out << "  " << sim::ScenarioName(s) << ": " << sim::ScenarioDescription(s) << "\n";
  }
  return out.str();
}

// The gimbal azimuth of a --look value: a named direction or degrees clockwise from the nose.
std::optional<double> LookAzimuth(const std::string& look) {
  if (look == "forward") return 0.0;
  if (look == "right") return 90.0;
  if (look == "back") return 180.0;
  if (look == "left") return 270.0;
  try {
    size_t used = 0;
    const double degrees = std::stod(look, &used);
    if (used == look.size() && std::isfinite(degrees) && std::abs(degrees) <= 360) return degrees;
  } catch (const std::exception&) {
  }
  return std::nullopt;
}

}  // namespace

struct SimulateCommand::State {
  CLI::App* command = nullptr;
  sim::SimulationOptions options;
  std::string scenario = "roundabout-loop";
  std::vector<double> bias;
  std::string nodata = "none";
  std::string look = "forward";
  std::string logo = "none";
  std::string sensor_look = "eo";
  std::string target_paths;
  bool force = false;
  bool quiet = false;
};

SimulateCommand::SimulateCommand(CLI::App& app) : state_(std::make_unique<State>()) {
  State& s = *state_;
  sim::SimulationOptions& o = s.options;
  CLI::App* c = app.add_subcommand(
      "simulate",
      "Fly a simulated camera over a procedural town (or your orthophoto) and write an MPEG-TS\n"
      "with H.264 video and MISB ST 0601 KLV, plus a truth file (docs/simulator.md).\n"
      "Scenarios:\n" +
          ScenarioList());
  s.command = c;
  c->add_option("--scenario", s.scenario,
                "Flight path: roundabout-loop, figure-eight, raster, straight, orbit")
      ->capture_default_str();
  c->add_option("-o,--output", o.output, "Output MPEG-TS file")->required();
  c->add_option("--truth", o.truth, "Truth file (default: OUTPUT with .truth.json)");
  c->add_option("--seed", o.seed, "Seed of the world, targets, jitter and noise")
      ->capture_default_str();
  c->add_flag("--force", s.force, "Overwrite existing output files");
  c->add_flag("-q,--quiet", s.quiet, "No progress bar and no summary");

  auto* video = "Video";
  c->add_option("--fps", o.fps, "Frame rate (25, 30, 29.97...)")
      ->capture_default_str()
      ->group(video);
  c->add_option("--duration", o.duration_s, "Seconds of video; 0 = the whole flight path")
      ->capture_default_str()
      ->group(video);
  c->add_option("--width", o.camera.width, "Frame width, pixels (even)")
      ->capture_default_str()
      ->group(video);
  c->add_option("--height", o.camera.height, "Frame height, pixels (even)")
      ->capture_default_str()
      ->group(video);
  c->add_option("--hfov", o.camera.hfov_deg, "Horizontal field of view, degrees")
      ->capture_default_str()
      ->group(video);
  c->add_option("--crf", o.crf, "H.264 quality, 0 (lossless) .. 51")
      ->capture_default_str()
      ->group(video);
  c->add_option("--preset", o.x264_preset, "x264 speed preset (ultrafast .. veryslow)")
      ->capture_default_str()
      ->group(video);

  auto* flight = "Flight";
  c->add_option("--altitude", o.flight.altitude_m, "Height above ground, metres")
      ->capture_default_str()
      ->group(flight);
  c->add_option("--speed", o.flight.speed_mps, "Ground speed, m/s")
      ->capture_default_str()
      ->group(flight);
  c->add_option("--jitter", o.flight.attitude_jitter_deg, "Attitude wander, degrees (1 sigma)")
      ->capture_default_str()
      ->group(flight);
  c->add_option("--altitude-jitter", o.flight.altitude_jitter_m, "Height wander, metres (1 sigma)")
      ->capture_default_str()
      ->group(flight);
  c->add_option("--key-frames", o.flight.figure_eight_key_frames,
                "figure-eight: size the path for about this many key frames")
      ->capture_default_str()
      ->group(flight);
  c->add_option("--overlap", o.flight.key_frame_overlap, "figure-eight: key frame overlap (0..1)")
      ->capture_default_str()
      ->group(flight);
  c->add_option("--rows", o.flight.raster_rows, "raster: number of rows")
      ->capture_default_str()
      ->group(flight);
  c->add_option("--row-length", o.flight.raster_row_length_m, "raster: row length, metres")
      ->capture_default_str()
      ->group(flight);
  c->add_option("--sidelap", o.flight.raster_sidelap, "raster: sideways overlap of rows (0..1)")
      ->capture_default_str()
      ->group(flight);
  c->add_option("--length", o.flight.straight_length_m, "straight: length, metres")
      ->capture_default_str()
      ->group(flight);
  c->add_option("--heading", o.flight.straight_heading_deg, "straight: heading, degrees from north")
      ->capture_default_str()
      ->group(flight);
  c->add_option("--orbit-radius", o.flight.orbit_radius_m,
                "orbit: radius of the circle round the point the camera stares at, metres")
      ->capture_default_str()
      ->group(flight);

  auto* pointing = "Pointing";
  c->add_option("--off-nadir", o.flight.gimbal_off_nadir_deg,
                "Oblique view: the camera's angle off nadir, 0 (straight down) .. 88 degrees;\n"
                "from about 70 (with the default lens) the top of the frame shows the horizon\n"
                "and the sky (the orbit scenario sets its own, staring at the centre)")
      ->capture_default_str()
      ->group(pointing);
  c->add_option("--look", s.look,
                "Which way an oblique camera leans: forward, right, left, back, or an azimuth\n"
                "in degrees clockwise from the nose")
      ->capture_default_str()
      ->group(pointing);
  CLI::Option* zoom_start =
      c->add_option("--zoom-start", o.zoom.start_s, "Start of a zoom, seconds (none by default)")
          ->group(pointing);
  c->add_option("--zoom-duration", o.zoom.duration_s, "Length of the zoom, seconds")
      ->capture_default_str()
      ->needs(zoom_start)
      ->group(pointing);
  CLI::Option* zoom_to =
      c->add_option("--zoom-to", o.zoom.to_hfov_deg,
                    "Horizontal field of view at the end of the zoom, degrees (from --hfov)")
          ->group(pointing);
  zoom_start->needs(zoom_to);
  zoom_to->needs(zoom_start);

  auto* world = "World";
  c->add_option("--loop-length", o.world.loop_length_m, "Length of the town's road loop, metres")
      ->capture_default_str()
      ->group(world);
  c->add_option("--cars", o.targets.cars, "Moving cars")->capture_default_str()->group(world);
  c->add_option("--vans", o.targets.vans, "Moving vans")->capture_default_str()->group(world);
  c->add_option("--people", o.targets.people, "Walking people")
      ->capture_default_str()
      ->group(world);
  c->add_option("--slow-walkers", o.targets.slow_walker_fraction,
                "Fraction of people who dawdle at 0.4-0.6 m/s")
      ->capture_default_str()
      ->group(world);
  c->add_option("--groups", o.targets.group_size,
                "People walk in groups of this many, side by side")
      ->capture_default_str()
      ->group(world);
  c->add_flag("--stop-and-go", o.targets.stop_and_go,
              "Vehicles stop every 5-20 s for 2-8 s; queues form behind them")
      ->group(world);
  c->add_option("--ground", o.ground_image,
                "Orthophoto (PNG, JPEG, GeoTIFF) to fly over instead of the town; transparent\n"
                "pixels are no data. Moving targets only with --target-paths.")
      ->check(CLI::ExistingFile)
      ->group(world);
  c->add_option("--gsd", o.ground_gsd_m, "Metres per pixel of --ground (read from a GeoTIFF if 0)")
      ->group(world);
  c->add_option("--ground-nodata", s.nodata,
                "Padding colour of --ground that means no data where it touches the image edge:\n"
                "none, white or black (transparent pixels are always no data)")
      ->check(CLI::IsMember({"none", "white", "black"}))
      ->capture_default_str()
      ->group(world);
  c->add_option("--target-paths", s.target_paths,
                "With --ground: where targets move: 'generated' (straight and curved roads\n"
                "across the image, footpaths near its centre) or a GeoJSON file of LineStrings\n"
                "(WGS84; features with property kind = footpath are walked)")
      ->group(world);
  c->add_option("--lat", o.origin.latitude_deg, "Latitude of the ground origin, degrees")
      ->capture_default_str()
      ->group(world);
  c->add_option("--lon", o.origin.longitude_deg, "Longitude of the ground origin, degrees")
      ->capture_default_str()
      ->group(world);
  c->add_option("--ground-height", o.origin.height_m,
                "Ground height above the WGS84 ellipsoid, metres")
      ->capture_default_str()
      ->group(world);

  auto* imaging = "Imaging";
  c->add_option("--noise", o.imaging.noise_sigma, "Sensor noise, grey levels (1 sigma)")
      ->capture_default_str()
      ->group(imaging);
  c->add_option("--blur", o.imaging.blur_sigma_px, "Extra blur, pixels (Gaussian sigma)")
      ->capture_default_str()
      ->group(imaging);
  c->add_option("--gain-drift", o.imaging.gain_drift, "Slow brightness drift, relative amplitude")
      ->capture_default_str()
      ->group(imaging);
  c->add_option("--sensor", s.sensor_look,
                "Sensor: eo (visible colour), ir-white-hot or ir-black-hot (thermal infrared)")
      ->check(CLI::IsMember({"eo", "ir-white-hot", "ir-black-hot"}))
      ->capture_default_str()
      ->group(imaging);
  c->add_option("--polarity-switch", o.imaging.polarity_switch_s,
                "Infrared: switch white-hot <-> black-hot at this time, seconds")
      ->group(imaging);
  c->add_option("--haze", o.imaging.haze, "Haze: contrast taken by bright airlight, 0 .. 0.8")
      ->capture_default_str()
      ->group(imaging);
  c->add_option("--motion-blur", o.imaging.motion_blur_px,
                "Smear along the image's vertical axis, pixels")
      ->capture_default_str()
      ->group(imaging);
  c->add_option("--lens-k1", o.imaging.lens_k1,
                "Radial lens distortion, -0.3 (barrel) .. 0.3 (pincushion); homographies then\n"
                "hold only approximately")
      ->capture_default_str()
      ->group(imaging);
  c->add_option("--blank-start", o.imaging.blank_start_s,
                "Start of a blank interval (cloud), seconds")
      ->group(imaging);
  c->add_option("--blank-duration", o.imaging.blank_duration_s,
                "Length of the blank interval, seconds")
      ->group(imaging);

  auto* sampling = "Sampling and cuts";
  c->add_option("--drop-frames", o.sampling.drop_probability,
                "Chance that a camera frame is lost (a gap in the time stamps), 0 .. 0.5")
      ->capture_default_str()
      ->group(sampling);
  c->add_option("--repeat-frames", o.sampling.repeat_probability,
                "Chance that a frame repeats the previous picture, 0 .. 0.5")
      ->capture_default_str()
      ->group(sampling);
  c->add_flag("--variable-rate", o.sampling.variable_rate,
              "Frame intervals of 3/4 to 5/4 of the nominal one (a variable frame rate)")
      ->group(sampling);
  CLI::Option* cut_at =
      c->add_option(
           "--cut-at", o.cut.at_s,
           "A splice at this video time, seconds: the video then shows the flight later on")
          ->group(sampling);
  c->add_option("--cut-jump", o.cut.jump_s, "How much later the video resumes after --cut-at, s")
      ->capture_default_str()
      ->needs(cut_at)
      ->group(sampling);

  auto* overlays = "Burned-in overlays";
  c->add_flag("--hud-text", o.overlay.hud_text,
              "Telemetry text (time, frame, position, heading) that changes every frame")
      ->group(overlays);
  c->add_flag("--reticle", o.overlay.reticle, "A cross at the image centre")->group(overlays);
  c->add_option("--logo", s.logo, "A corner logo: none, static, rotating or pulsing")
      ->check(CLI::IsMember({"none", "static", "rotating", "pulsing"}))
      ->capture_default_str()
      ->group(overlays);
  c->add_option("--overlay-opacity", o.overlay.opacity,
                "Opacity of the overlays, (0, 1]; below 1 they are semi-transparent")
      ->capture_default_str()
      ->group(overlays);

  auto* metadata = "Metadata (KLV)";
  c->add_option("--klv-every", o.metadata.every_n_frames, "A KLV packet every N frames; 0 = no KLV")
      ->capture_default_str()
      ->group(metadata);
  c->add_option("--klv-frames", o.metadata.only_frames,
                "KLV only on these frames (comma-separated)")
      ->delimiter(',')
      ->group(metadata);
  c->add_option("--klv-noise", o.metadata.position_noise_m, "Position noise, metres (1 sigma)")
      ->capture_default_str()
      ->group(metadata);
  c->add_option("--klv-bias", s.bias, "Constant position error EAST,NORTH, metres")
      ->delimiter(',')
      ->expected(2)
      ->group(metadata);
  c->add_option("--klv-dropout", o.metadata.dropout_probability, "Chance that a due packet is lost")
      ->capture_default_str()
      ->group(metadata);
}

SimulateCommand::~SimulateCommand() = default;
bool SimulateCommand::parsed() const { return state_->command->parsed(); }

int SimulateCommand::Run() const {
  sim::SimulationOptions options = state_->options;
  const auto scenario = sim::ParseScenario(state_->scenario);
  if (!scenario) {
    std::cerr << "saker-cli: unknown scenario '" << state_->scenario << "'; choose one of:\n"
              << ScenarioList();
    return kExitUsage;
  }
  options.scenario = *scenario;
  if (state_->nodata != "none") {
    const uint8_t v = state_->nodata == "white" ? 255 : 0;
    options.ground_nodata_bgr = cv::Vec3b(v, v, v);
  }
  if (state_->target_paths == "generated") {
    options.ground_paths.generated = true;
  } else if (!state_->target_paths.empty()) {
    options.ground_paths.geojson = state_->target_paths;
  }
  options.imaging.look = sim::ParseSensorLook(state_->sensor_look).value_or(sim::SensorLook::kEo);
  options.overlay.logo = sim::ParseLogoMotion(state_->logo).value_or(sim::LogoMotion::kNone);
  if (const auto azimuth = LookAzimuth(state_->look)) {
    options.flight.gimbal_azimuth_deg = *azimuth;
  } else {
    std::cerr << "saker-cli: --look must be forward, right, left, back or an azimuth in degrees "
                 "(got '"
              << state_->look << "')\n";
    return kExitUsage;
  }
  if (state_->bias.size() == 2) {
    options.metadata.bias_east_m = state_->bias[0];
    options.metadata.bias_north_m = state_->bias[1];
  }
  if (const Status status = options.Validate(); !status.ok()) {
    std::cerr << "saker-cli: " << status.message() << "\n";
    return kExitUsage;
  }
  if (!state_->force) {
    for (const auto& path : {options.output, options.TruthPath()}) {
      if (std::filesystem::exists(path)) {
        std::cerr << "saker-cli: " << path.string() << " exists; use --force to overwrite it\n";
        return kExitFailed;
      }
    }
  }
  return RunSimulation(options, state_->quiet);
}

struct DemoCommand::State {
  CLI::App* command = nullptr;
  std::filesystem::path directory = "demo";
  bool no_gui = false;
};

DemoCommand::DemoCommand(CLI::App& app) : state_(std::make_unique<State>()) {
  state_->command = app.add_subcommand(
      "demo",
      "The built-in demo mission: generates DIR/demo.ts (the roundabout-loop scenario, 71 s of\n"
      "1280x720 video at 25 fps with KLV, and its truth) unless it is already there, then runs\n"
      "the main job on it: processes it into the mission DIR/demo.saker (replacing an earlier\n"
      "one) and writes its activity map, tracks coloured by speed, to DIR/activity.png.\n"
      "When a display is present and the Saker GUI was built, the mission then opens in it.");
  state_->command->add_option("--dir", state_->directory, "Where the demo mission lives")
      ->capture_default_str();
  state_->command->add_flag("--no-gui", state_->no_gui,
                            "Do not open the GUI afterwards, even with a display");
}

DemoCommand::~DemoCommand() = default;
bool DemoCommand::parsed() const { return state_->command->parsed(); }
bool DemoCommand::no_gui() const { return state_->no_gui; }
std::string DemoCommand::VideoPath() const { return (state_->directory / "demo.ts").string(); }

int DemoCommand::Prepare() const {
  sim::SimulationOptions options;
  options.scenario = sim::Scenario::kRoundaboutLoop;
  options.output = VideoPath();
  // A stamp records the simulator version and options the demo was made with; when either
  // changes, the demo is made again.
  const std::filesystem::path stamp = state_->directory / "demo.options.json";
  const std::string wanted = options.ToJson().dump();
  std::string existing;
  if (std::ifstream in(stamp); in) std::getline(in, existing);
  if (existing == wanted && std::filesystem::exists(options.output) &&
      std::filesystem::exists(options.TruthPath())) {
    std::cerr << "demo: using " << options.output.string() << " (delete "
              << state_->directory.string() << " to make it again)\n";
    return kExitOk;
  }
  std::error_code error;
  std::filesystem::create_directories(state_->directory, error);
  if (error) {
    std::cerr << "saker-cli: cannot create " << state_->directory.string() << ": "
              << error.message() << "\n";
    return kExitFailed;
  }
  std::cerr << "demo: generating " << options.output.string() << "\n";
  if (const int code = RunSimulation(options, false); code != kExitOk) return code;
  std::ofstream out(stamp, std::ios::trunc);
  out << wanted << "\n";
  return out ? kExitOk : kExitFailed;
}

}  // namespace saker::app
