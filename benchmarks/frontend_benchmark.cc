// saker-bench-frontend: the Visual MTI front end's speed against decoding alone, on simulated
// H.264 video at 1280x720 and 1920x1080, measured in the same run, with time per stage and peak
// memory.
//
//   saker-bench-frontend [--seconds S] [--json] [--compare-overlays] [--compare-low-frame-rate]
//                        [--compare-colour] [--compare-noise] [--compare-evidence]
//   saker-bench-frontend --memory-minutes M [--memory-height H] [--memory-repeat R]
//
// --memory-minutes measures memory instead: it simulates M minutes of video once (1280x720, or
// 16:9 at --memory-height; the figure-of-eight scenario, in a temporary directory it removes
// afterwards), runs the front end over it, and prints the resident memory after 1, 2, 5, 10, ...
// minutes of video and the peak, with what the result keeps, so that growth per minute is
// visible. --memory-repeat R joins R copies of the simulated MPEG-TS end to end (M x R minutes;
// the reader makes the time stamps continuous at each join, which the front end takes for a cut),
// so that an hour of 1080p does not take the simulator two hours to render.

#include "core/frontend/front_end.h"
#include "core/sim/simulator.h"
#include "core/util/memory.h"
#include "core/util/timer.h"
#include "core/video/video_reader.h"

#include <CLI/CLI.hpp>
#include <malloc.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <string>
#include <vector>

namespace {

using saker::Stopwatch;

namespace fs = std::filesystem;

double ResidentMb() { return static_cast<double>(saker::ResidentMemoryBytes()) / 1e6; }
double PeakMb() { return static_cast<double>(saker::PeakResidentMemoryBytes()) / 1e6; }

// Memory on a long video: see the file comment.
int MeasureMemory(double clip_minutes, int height, int repeat) {
  const double minutes = clip_minutes * repeat;
  const int width = height * 16 / 9;
  std::string pattern = (fs::temp_directory_path() / "saker-bench-memory-XXXXXX").string();
  if (mkdtemp(pattern.data()) == nullptr) {
    std::cerr << "cannot make a temporary directory\n";
    return 1;
  }
  const fs::path dir = pattern;
  struct Remover {
    fs::path dir;
    ~Remover() {
      std::error_code ignored;
      fs::remove_all(dir, ignored);
    }
  } remover{dir};

  saker::sim::SimulationOptions sim;
  sim.output = dir / "long.ts";
  sim.camera.width = width;
  sim.camera.height = height;
  sim.duration_s = clip_minutes * 60;
  // The paper's figure of eight over the town (504 s with its 75 key frames), sized to last a
  // little longer than asked for.
  sim.scenario = saker::sim::Scenario::kFigureEight;
  sim.flight.figure_eight_key_frames =
      std::max(8, static_cast<int>(std::ceil(75 * sim.duration_s / 504 * 1.05)));
  std::printf("simulating %g minutes of %dx%d video (figure of eight)...\n", clip_minutes, width,
              height);
  std::fflush(stdout);
  Stopwatch start;
  if (auto simulated = saker::sim::Simulate(sim); !simulated.ok()) {
    std::cerr << simulated.status().message() << "\n";
    return 1;
  }
  std::printf("  done in %.0f s, %.0f MB\n", start.ElapsedSeconds(),
              static_cast<double>(fs::file_size(sim.output)) / 1e6);
  std::string video = sim.output.string();
  if (repeat > 1) {
    const fs::path joined = dir / "joined.ts";
    {
      std::ofstream out(joined, std::ios::binary);
      for (int i = 0; i < repeat && out; ++i) {
        std::ifstream in(sim.output, std::ios::binary);
        out << in.rdbuf();
      }
      if (!out) {
        std::cerr << "cannot write " << joined << "\n";
        return 1;
      }
    }
    fs::remove(sim.output);
    video = joined.string();
    std::printf("  joined %d copies: %g minutes, %.0f MB\n", repeat, minutes,
                static_cast<double>(fs::file_size(joined)) / 1e6);
  }
  // What the simulator freed goes back to the system, and the peak starts again from here
  // ("5" resets VmHWM, Linux 4.0 and later), so the figures below are the front end's.
  malloc_trim(0);
  std::ofstream clear_refs("/proc/self/clear_refs");
  clear_refs << "5" << std::flush;
  const bool peak_reset = clear_refs.good();
  const double rss_start = ResidentMb();
  std::printf("before the front end: RSS %.0f MB%s\n", rss_start,
              peak_reset ? "" : " (the peak could not be reset: it includes the simulation)");

  std::vector<double> checkpoints;
  for (double m : {1.0, 2.0, 5.0, 10.0, 20.0, 30.0, 60.0, 120.0}) {
    if (m < minutes) checkpoints.push_back(m);
  }
  checkpoints.push_back(minutes);
  // Progress comes once per frame (counted: the fraction it carries is of the duration the
  // container declares, which a joined video understates).
  size_t next = 0;
  double previous_minutes = 0, previous_rss = rss_start;
  int64_t frames_done = 0;
  start.Restart();
  saker::JobContext job([&](const std::string&, double) {
    const double minutes_done = static_cast<double>(++frames_done) / (sim.fps * 60);
    while (next < checkpoints.size() && minutes_done >= checkpoints[next] - 1e-9) {
      const double rss = ResidentMb();
      std::printf(
          "  after %3g min of video (%4.0f s): RSS %4.0f MB (+%3.0f MB; %+5.1f MB per minute "
          "since the last checkpoint), peak %4.0f MB\n",
          checkpoints[next], start.ElapsedSeconds(), rss, rss - rss_start,
          (rss - previous_rss) / (checkpoints[next] - previous_minutes), PeakMb());
      std::fflush(stdout);
      previous_minutes = checkpoints[next], previous_rss = rss;
      ++next;
    }
  });
  auto result = saker::frontend::RunFrontEnd(video, {}, &job);
  if (!result.ok()) {
    std::cerr << result.status().message() << "\n";
    return 1;
  }
  const double rss_end = ResidentMb(), peak = PeakMb();
  std::printf(
      "front end done: %lld frames in %.0f s (%.1f fps); with its result: RSS %.0f MB (+%.0f MB), "
      "peak %.0f MB (+%.0f MB)\n",
      static_cast<long long>(result->timing.frames), result->timing.wall_s,
      static_cast<double>(result->timing.frames) / result->timing.wall_s, rss_end,
      rss_end - rss_start, peak, peak - rss_start);

  // What the result keeps, by design (frames are not kept).
  const auto mb = [](double bytes) { return bytes / 1e6; };
  double key_image_bytes = 0, key_point_bytes = 0, link_bytes = 0, observation_bytes = 0;
  for (const auto& k : result->key_frame_images)
    key_image_bytes += static_cast<double>(k.grey.total());
  for (const auto& k : result->key_frames) {
    key_point_bytes += static_cast<double>(k.points.size() * sizeof(k.points[0]));
  }
  for (const auto& l : result->links) {
    link_bytes +=
        static_cast<double>(sizeof(l) + l.correspondences.size() * sizeof(l.correspondences[0]));
  }
  int64_t observations = 0;
  for (const auto& t : result->targets) {
    for (const auto& o : t.observations) {
      ++observations;
      observation_bytes +=
          static_cast<double>(sizeof(o) + o.features.size() * sizeof(o.features[0]));
    }
  }
  std::printf(
      "kept: %zu per-frame results (%.1f MB), %zu scan frame records (%.1f MB) and %zu KLV "
      "packets (%.1f MB before their decoded items), %zu key frames (grey images %.1f MB, "
      "points %.1f MB), %zu links (%.1f MB), %zu target tracks with %lld observations (%.1f MB)\n",
      result->frames.size(),
      mb(static_cast<double>(result->frames.size() * sizeof(result->frames[0]))),
      result->scan.frames.size(),
      mb(static_cast<double>(result->scan.frames.size() * sizeof(result->scan.frames[0]))),
      result->scan.packets.size(),
      mb(static_cast<double>(result->scan.packets.size() * sizeof(result->scan.packets[0]))),
      result->key_frames.size(), mb(key_image_bytes), mb(key_point_bytes), result->links.size(),
      mb(link_bytes), result->targets.size(), static_cast<long long>(observations),
      mb(observation_bytes));
  // What each part really occupies (heap included): the memory returned by freeing it, once what
  // the finished threads freed has gone back to the system.
  malloc_trim(0);
  std::printf("  RSS once the front end's threads and buffers are gone: %.0f MB\n", ResidentMb());
  const auto released = [&](const char* what, auto&& free_it) {
    const double before = ResidentMb();
    free_it();
    malloc_trim(0);
    std::printf("  freeing %s returns %.1f MB\n", what, before - ResidentMb());
  };
  released("the KLV packets (decoded sets and items)",
           [&] { decltype(result->scan.packets)().swap(result->scan.packets); });
  released("the key frame images",
           [&] { decltype(result->key_frame_images)().swap(result->key_frame_images); });
  released("the per-frame results", [&] { decltype(result->frames)().swap(result->frames); });
  released("everything else in the result", [&] { *result = saker::frontend::FrontEndResult(); });
  return 0;
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
  const Stopwatch start;
  while (true) {
    auto more = (*reader)->ReadNext(&frame, &data);
    if (!more.ok() || !*more) break;
    ++frames;
  }
  return static_cast<double>(frames) / start.ElapsedSeconds();
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"saker-bench-frontend: front end speed against decoding alone"};
  double seconds = 20;
  bool json = false;
  double memory_minutes = 0;
  app.add_option("--seconds", seconds, "Seconds of simulated video per resolution")
      ->capture_default_str();
  app.add_flag("--json", json, "Print JSON");
  app.add_option("--memory-minutes", memory_minutes,
                 "Instead: memory of the front end on a video this many minutes long, at "
                 "checkpoints")
      ->check(CLI::NonNegativeNumber);
  int memory_height = 720;
  app.add_option("--memory-height", memory_height,
                 "--memory-minutes: the video's height (16:9), e.g. 1080 for 1920x1080")
      ->capture_default_str()
      ->check(CLI::Range(144, 2160));
  int memory_repeat = 1;
  app.add_option("--memory-repeat", memory_repeat,
                 "--memory-minutes: join this many copies of the simulated video end to end")
      ->capture_default_str()
      ->check(CLI::Range(1, 1000));
  bool compare_overlays = false;
  app.add_flag("--compare-overlays", compare_overlays,
               "Also run the front end without overlay detection (FrontEndOptions::overlays) on "
               "the same video, first, for the cost of the overlay mask in the same run");
  bool compare_low_frame_rate = false;
  app.add_flag("--compare-low-frame-rate", compare_low_frame_rate,
               "Also simulate the flight at 2 frames a second and run the front end on it with "
               "the low-frame-rate mode off and on (FrontEndOptions::low_frame_rate), for its "
               "cost per frame against feature targets on the same frames");
  bool compare_colour = false;
  app.add_flag("--compare-colour", compare_colour,
               "Also run the front end with grey key frames (FrontEndOptions::key_frame_colour "
               "off: no chroma decoded) and with colour ones on the same video, for the cost of "
               "the colour mosaic in the same run");
  bool compare_noise = false;
  app.add_flag("--compare-noise", compare_noise,
               "Also run the front end with the fixed motion thresholds alone "
               "(FrontEndOptions::UseFixedThresholds) and with those that follow the measured "
               "noise on the same video, for the cost of measuring it in the same run");
  bool compare_evidence = false;
  app.add_flag("--compare-evidence", compare_evidence,
               "Also run the front end without the change detector's evidence pair "
               "(ChangeOptions::evidence_baseline_s 0) and with it on the same video, for its "
               "cost in the same run");
  CLI11_PARSE(app, argc, argv);
  if (memory_minutes > 0) return MeasureMemory(memory_minutes, memory_height, memory_repeat);

  const fs::path dir = fs::temp_directory_path() / "saker-bench-frontend";
  fs::create_directories(dir);
  nlohmann::json out = nlohmann::json::array();
  // Runs the front end on `video` with `options` and prints a row; false when it failed.
  const auto run = [&](const saker::sim::SimulationOptions& sim, double decode_fps,
                       const saker::frontend::FrontEndOptions& options, const std::string& label) {
    const double rss_before = PeakMb();
    auto result = saker::frontend::RunFrontEnd(sim.output.string(), options);
    if (!result.ok()) {
      std::cerr << result.status().message() << "\n";
      return false;
    }
    const auto& t = result->timing;
    const double front_fps = static_cast<double>(t.frames) / t.wall_s;
    const int w = sim.camera.width, h = sim.camera.height;
    if (json) {
      out.push_back({{"width", w},
                     {"height", h},
                     {"video_fps", sim.fps},
                     {"overlays", options.overlays.enabled},
                     {"key_frame_colour", options.key_frame_colour},
                     {"low_frame_rate", result->low_frame_rate},
                     {"frames", t.frames},
                     {"decode_only_fps", decode_fps},
                     {"front_end_fps", front_fps},
                     {"cost_vs_decode", decode_fps / front_fps},
                     {"decode_ms", t.decode_ms},
                     {"track_ms", t.track_ms},
                     {"homography_ms", t.homography_ms},
                     {"segment_ms", t.segment_ms},
                     {"change_ms", t.change_ms},
                     {"change_tracks_ms", t.change_tracks_ms},
                     {"change_wait_ms", t.change_wait_ms},
                     {"key_frames_ms", t.key_frames_ms},
                     {"peak_rss_mb", PeakMb()},
                     {"peak_rss_before_mb", rss_before}});
    } else {
      std::printf(
          "%dx%d at %g fps, %s, %lld frames: front end %.1f fps, decode alone %.1f fps, front end "
          "time = %.2fx decode time; per frame: decode %.1f ms (own thread), track %.1f, "
          "homography %.1f, segment %.1f, change %.1f (own thread), blob tracks %.2f, waiting for "
          "change %.2f, key frames %.2f ms; peak RSS %.0f MB\n",
          w, h, sim.fps, label.c_str(), static_cast<long long>(t.frames), front_fps, decode_fps,
          decode_fps / front_fps, t.decode_ms, t.track_ms, t.homography_ms, t.segment_ms,
          t.change_ms, t.change_tracks_ms, t.change_wait_ms, t.key_frames_ms, PeakMb());
    }
    return true;
  };
  // Simulates `sim` afresh; false when it failed.
  const auto simulate = [](const saker::sim::SimulationOptions& sim) {
    std::error_code ignored;
    fs::remove(sim.output, ignored);
    fs::remove(sim.TruthPath(), ignored);
    const auto summary = saker::sim::Simulate(sim);
    if (!summary.ok()) std::cerr << "saker-bench-frontend: " << summary.status().message() << "\n";
    return summary.ok();
  };
  for (const auto& [w, h] : {std::pair{1280, 720}, std::pair{1920, 1080}}) {
    saker::sim::SimulationOptions sim;
    sim.output = dir / ("bench_" + std::to_string(w) + ".ts");
    sim.camera.width = w;
    sim.camera.height = h;
    sim.duration_s = seconds;
    if (!simulate(sim)) return 1;
    const double decode_fps = DecodeOnlyFps(sim.output.string());
    for (const bool overlays :
         compare_overlays ? std::vector{false, true}
                          : std::vector{saker::frontend::FrontEndOptions{}.overlays.enabled}) {
      saker::frontend::FrontEndOptions options;
      options.overlays.enabled = overlays;
      if (!run(sim, decode_fps, options, overlays ? "overlays on" : "overlays off")) return 1;
    }
    // The A/B comparisons asked for: the option off, then on, on the same video.
    struct Comparison {
      bool asked;
      const char* off;
      const char* on;
      std::function<void(bool, saker::frontend::FrontEndOptions*)> set;
    };
    const std::vector<Comparison> comparisons = {
        {compare_colour, "grey key frames", "colour key frames",
         [](bool on, auto* o) { o->key_frame_colour = on; }},
        {compare_noise, "fixed thresholds", "measured noise",
         [](bool on, auto* o) {
           if (!on) o->UseFixedThresholds();
         }},
        {compare_evidence, "no evidence pair", "evidence pair",
         [](bool on, auto* o) {
           if (!on) o->change.evidence_baseline_s = 0;
         }},
    };
    for (const Comparison& c : comparisons) {
      for (const bool on : c.asked ? std::vector{false, true} : std::vector<bool>{}) {
        saker::frontend::FrontEndOptions options;
        c.set(on, &options);
        if (!run(sim, decode_fps, options, on ? c.on : c.off)) return 1;
      }
    }
    if (!compare_low_frame_rate) continue;
    // The whole flight (71 s) at 2 frames a second.
    sim.output = dir / ("bench_" + std::to_string(w) + "_2fps.ts");
    sim.fps = 2;
    sim.duration_s = 0;
    if (!simulate(sim)) return 1;
    const double low_decode_fps = DecodeOnlyFps(sim.output.string());
    using Mode = saker::frontend::LowFrameRateOptions::Mode;
    for (const Mode mode : {Mode::kOff, Mode::kOn}) {
      saker::frontend::FrontEndOptions options;
      options.low_frame_rate.mode = mode;
      if (!run(sim, low_decode_fps, options,
               std::string("low-frame-rate mode ") + saker::frontend::LowFrameRateModeName(mode))) {
        return 1;
      }
    }
  }
  if (json) std::cout << out.dump(2) << "\n";
  std::error_code ignored;
  fs::remove_all(dir, ignored);
  return 0;
}
