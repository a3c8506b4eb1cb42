// saker-bench-frontend: the Visual MTI front end's speed against decoding alone, on simulated
// H.264 video at 1280x720 and 1920x1080, measured in the same run, with time per stage and peak
// memory.
//
//   saker-bench-frontend [--seconds S] [--json]

#include "core/frontend/front_end.h"
#include "core/sim/simulator.h"
#include "core/video/video_reader.h"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <sys/resource.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

double PeakRssMb() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return double(usage.ru_maxrss) / 1024.0;
}

double DecodeOnlyFps(const std::string& path) {
  saker::video::ReaderOptions options;
  options.want_bgr = false;
  options.want_grey = true;
  auto reader = saker::video::VideoReader::Open(path, options);
  if (!reader.ok()) std::exit(1);
  saker::video::Frame frame;
  std::vector<saker::video::DataPacket> data;
  int64_t frames = 0;
  const auto start = Clock::now();
  while (true) {
    auto more = (*reader)->ReadNext(&frame, &data);
    if (!more.ok() || !*more) break;
    ++frames;
  }
  return double(frames) / std::chrono::duration<double>(Clock::now() - start).count();
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"saker-bench-frontend: front end speed against decoding alone"};
  double seconds = 20;
  bool json = false;
  app.add_option("--seconds", seconds, "Seconds of simulated video per resolution")
      ->capture_default_str();
  app.add_flag("--json", json, "Print JSON");
  CLI11_PARSE(app, argc, argv);

  const fs::path dir = fs::temp_directory_path() / "saker-bench-frontend";
  fs::create_directories(dir);
  nlohmann::json out = nlohmann::json::array();
  for (const auto& [w, h] : {std::pair{1280, 720}, std::pair{1920, 1080}}) {
    saker::sim::SimulationOptions sim;
    sim.output = dir / ("bench_" + std::to_string(w) + ".ts");
    sim.camera.width = w;
    sim.camera.height = h;
    sim.duration_s = seconds;
    std::error_code ignored;
    fs::remove(sim.output, ignored);
    fs::remove(sim.TruthPath(), ignored);
    if (!saker::sim::Simulate(sim).ok()) return 1;

    const double decode_fps = DecodeOnlyFps(sim.output.string());
    const double rss_before = PeakRssMb();
    auto result = saker::frontend::RunFrontEnd(sim.output.string(), {});
    if (!result.ok()) {
      std::cerr << result.status().message() << "\n";
      return 1;
    }
    const auto& t = result->timing;
    const double front_fps = double(t.frames) / t.wall_s;
    if (json) {
      out.push_back({{"width", w},
                     {"height", h},
                     {"frames", t.frames},
                     {"decode_only_fps", decode_fps},
                     {"front_end_fps", front_fps},
                     {"cost_vs_decode", decode_fps / front_fps},
                     {"decode_ms", t.decode_ms},
                     {"track_ms", t.track_ms},
                     {"homography_ms", t.homography_ms},
                     {"segment_ms", t.segment_ms},
                     {"change_ms", t.change_ms},
                     {"key_frames_ms", t.key_frames_ms},
                     {"peak_rss_mb", PeakRssMb()},
                     {"peak_rss_before_mb", rss_before}});
    } else {
      std::printf(
          "%dx%d, %lld frames: front end %.1f fps, decode alone %.1f fps, front end time = %.2fx "
          "decode "
          "time; per frame: decode %.1f ms (own thread), track %.1f, homography %.1f, segment "
          "%.1f, change %.1f, key frames %.2f ms; peak RSS %.0f MB\n",
          w, h, static_cast<long long>(t.frames), front_fps, decode_fps, decode_fps / front_fps,
          t.decode_ms, t.track_ms, t.homography_ms, t.segment_ms, t.change_ms, t.key_frames_ms,
          PeakRssMb());
    }
  }
  if (json) std::cout << out.dump(2) << "\n";
  std::error_code ignored;
  fs::remove_all(dir, ignored);
  return 0;
}
