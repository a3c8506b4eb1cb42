// saker-bench-sim: how fast the world simulator makes video, against the video's own frame rate
// (it must beat real time) and against encoding alone, measured in the same run.
//
//   saker-bench-sim [--seconds S] [--json]
//
// For 1280x720 and 1920x1080 (roundabout-loop scenario, default options): the simulator's frames
// per second including rendering, targets, noise and H.264 + KLV encoding; the same number of
// already-rendered frames through the encoder alone (the baseline); and the time per frame of each
// rendering step on its own.

#include "core/sim/simulator.h"
#include "core/sim/world_raster.h"
#include "core/util/timer.h"
#include "core/video/ts_writer.h"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>

namespace {

using saker::Stopwatch;

namespace fs = std::filesystem;

struct Figures {
  int width = 0, height = 0;
  int64_t frames = 0;
  double video_fps = 0;
  double simulate_fps = 0;
  double encode_only_fps = 0;
  double ground_ms = 0, targets_ms = 0, effects_ms = 0;
};

Figures Measure(int width, int height, double seconds, const fs::path& dir) {
  using namespace saker;
  sim::SimulationOptions options;
  options.output = dir / ("bench_" + std::to_string(width) + ".ts");
  options.camera.width = width;
  options.camera.height = height;
  options.duration_s = seconds;
  std::error_code ignored;
  fs::remove(options.output, ignored);
  fs::remove(options.TruthPath(), ignored);

  Figures f;
  f.width = width, f.height = height, f.video_fps = options.fps;
  const Stopwatch start;
  StatusOr<sim::SimulationSummary> summary = sim::Simulate(options);
  const double elapsed = start.ElapsedSeconds();
  if (!summary.ok()) {
    std::cerr << "saker-bench-sim: " << summary.status().message() << "\n";
    std::exit(1);
  }
  f.frames = summary->frames;
  f.simulate_fps = static_cast<double>(f.frames) / elapsed;

  // The steps on their own, on the same frames.
  StatusOr<sim::SimulationSetup> setup = sim::SimulationSetup::Create(options);
  const std::unique_ptr<sim::TargetSimulation> targets = setup->MakeTargets();
  sim::ImagingOptions no_effects;
  no_effects.noise_sigma = 0;
  const sim::FrameRenderer plain(setup->ground(), options.camera, no_effects, options.seed);
  const sim::FrameRenderer full(setup->ground(), options.camera, options.imaging, options.seed);
  std::vector<cv::Mat> rendered;
  double ground_s = 0, targets_s = 0, effects_s = 0;
  for (int64_t i = 0; i < f.frames; ++i) {
    const double t = static_cast<double>(i) * setup->frame_interval_s();
    const Eigen::Matrix3d h = sim::FrameFromGround(options.camera, setup->flight().PoseAt(t));
    if (i > 0) targets->Step(setup->frame_interval_s());
    Stopwatch step;
    cv::Mat frame = plain.RenderGround(h);
    ground_s += step.ElapsedSeconds();
    step.Restart();
    targets->Draw(h, &frame);
    targets_s += step.ElapsedSeconds();
    step.Restart();
    cv::Mat with_effects = full.Render(h, {}, Eigen::Vector2d::Zero(), i, t);
    effects_s += step.ElapsedSeconds();
    if (i % 5 == 0) rendered.push_back(with_effects);
  }
  f.ground_ms = 1000 * ground_s / static_cast<double>(f.frames);
  f.targets_ms = 1000 * targets_s / static_cast<double>(f.frames);
  // Render() without targets = ground + effects: the difference is the effects. The baseline
  // encodes frames with their noise, which costs the encoder as much as in the simulation.
  f.effects_ms = std::max(0.0, 1000 * effects_s / static_cast<double>(f.frames) - f.ground_ms);

  // Baseline: encoding alone, the same frame count, frames prepared beforehand.
  video::TsWriterOptions writer_options;
  writer_options.width = width;
  writer_options.height = height;
  writer_options.fps_num = 25;
  writer_options.gop_size = 25;
  const Stopwatch encode_start;
  auto writer = video::TsWriter::Open(dir / "encode_only.ts", writer_options);
  for (int64_t i = 0; i < f.frames; ++i) {
    if (!(*writer)->WriteFrame(rendered[static_cast<size_t>(i / 5) % rendered.size()]).ok())
      std::exit(1);
  }
  if (!(*writer)->Close().ok()) std::exit(1);
  f.encode_only_fps = static_cast<double>(f.frames) / encode_start.ElapsedSeconds();
  return f;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"saker-bench-sim: simulator speed against real time and against encoding alone"};
  double seconds = 20;
  bool json = false;
  app.add_option("--seconds", seconds, "Seconds of video per resolution")->capture_default_str();
  app.add_flag("--json", json, "Print JSON");
  CLI11_PARSE(app, argc, argv);

  const fs::path dir = fs::temp_directory_path() / "saker-bench-sim";
  fs::create_directories(dir);
  nlohmann::json out = nlohmann::json::array();
  for (const auto& [w, h] : {std::pair{1280, 720}, std::pair{1920, 1080}}) {
    const Figures f = Measure(w, h, seconds, dir);
    if (json) {
      out.push_back({{"width", f.width},
                     {"height", f.height},
                     {"frames", f.frames},
                     {"video_fps", f.video_fps},
                     {"simulate_fps", f.simulate_fps},
                     {"encode_only_fps", f.encode_only_fps},
                     {"ground_ms", f.ground_ms},
                     {"targets_ms", f.targets_ms},
                     {"effects_ms", f.effects_ms}});
    } else {
      std::printf(
          "%dx%d, %lld frames: simulate %.1f fps = %.2fx real time (%g fps video); encode alone "
          "%.1f fps, simulate/encode %.2f; per frame: ground %.1f ms, targets %.1f ms, effects "
          "%.1f ms\n",
          f.width, f.height, static_cast<long long>(f.frames), f.simulate_fps,
          f.simulate_fps / f.video_fps, f.video_fps, f.encode_only_fps,
          f.simulate_fps / f.encode_only_fps, f.ground_ms, f.targets_ms, f.effects_ms);
    }
  }
  if (json) std::cout << out.dump(2) << "\n";
  std::error_code ignored;
  fs::remove_all(dir, ignored);
  return 0;
}
