// saker-bench-mission: processing a video into a mission against the video's duration and
// against decoding it alone, the time to open a mission against reading its file's bytes, and
// the latency of picking a track observation against a brute-force scan, all measured in the
// same run.
//
//   saker-bench-mission [VIDEO] [--opens N] [--picks N] [--keep FILE.saker] [--json]
//
// VIDEO defaults to the demo mission's video, demo/demo.ts beside the source tree (run
// `saker-cli demo` once to make it); without it, the roundabout loop at 1280x720 is simulated into
// a temporary directory. The mission is written to a temporary directory unless --keep names it.

#include "core/activity/activity.h"
#include "core/mission/mission_store.h"
#include "core/pipeline/process.h"
#include "core/sim/simulator.h"
#include "core/util/statistics.h"
#include "core/util/timer.h"
#include "core/video/video_reader.h"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <random>
#include <string>
#include <vector>

namespace {

namespace fs = std::filesystem;
using saker::Median;
using saker::Quantile;
using saker::Stopwatch;

// A temporary directory removed on scope exit.
class TempDir {
 public:
  TempDir() {
    std::string pattern = (fs::temp_directory_path() / "saker-bench-mission-XXXXXX").string();
    if (mkdtemp(pattern.data()) != nullptr) path_ = pattern;
  }
  ~TempDir() {
    std::error_code ignored;
    if (!path_.empty()) fs::remove_all(path_, ignored);
  }
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

// The baseline of processing: one sequential decode of the video to grey frames (what the front
// end's decode thread does), nothing else.
saker::StatusOr<double> DecodeSeconds(const std::string& video) {
  const Stopwatch begin;
  saker::video::ReaderOptions options;
  options.want_bgr = false;
  options.want_grey = true;
  auto reader = saker::video::VideoReader::Open(video, options);
  if (!reader.ok()) return reader.status();
  saker::video::Frame frame;
  while (true) {
    auto more = (*reader)->ReadNext(&frame, nullptr);
    if (!more.ok()) return more.status();
    if (!*more) break;
  }
  return begin.ElapsedSeconds();
}

// The baseline of opening: reading the mission file's bytes (cold caches are not measured: the
// file was just written, as it is when an analyst opens a mission after processing).
double ReadBytesSeconds(const fs::path& path) {
  const Stopwatch begin;
  std::ifstream in(path, std::ios::binary);
  std::vector<char> buffer(1 << 20);
  size_t total = 0;
  while (in.read(buffer.data(), static_cast<std::streamsize>(buffer.size())) || in.gcount() > 0) {
    total += static_cast<size_t>(in.gcount());
  }
  volatile size_t sink = total;
  (void)sink;
  return begin.ElapsedSeconds();
}

// The nearest observation by scanning every one: what picking costs without the index.
double BruteForceNearest(const std::vector<saker::mission::ActivityTrack>& tracks,
                         const Eigen::Vector2d& p, double tolerance) {
  double best = std::numeric_limits<double>::infinity();
  for (const auto& t : tracks) {
    for (const auto& point : t.points) best = std::min(best, (point.map - p).norm());
  }
  return best <= tolerance ? best : -1;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "saker-bench-mission: processing against video duration and decoding alone, mission open "
      "time against reading the file, pick latency against a brute-force scan."};
  std::string video;
  int opens = 20;
  int picks = 20000;
  std::string keep;
  bool json = false;
  app.add_option("video", video,
                 "Video to process (default: demo/demo.ts beside the source tree, else a "
                 "simulated 1280x720 roundabout loop)");
  app.add_option("--opens", opens, "How many times to open the mission")
      ->check(CLI::Range(1, 1000));
  app.add_option("--picks", picks, "How many picks to time")->check(CLI::Range(1, 10000000));
  app.add_option("--keep", keep, "Write the mission here instead of a temporary directory");
  app.add_flag("--json", json, "Print the figures as JSON");
  CLI11_PARSE(app, argc, argv);

  TempDir temp;
  if (temp.path().empty()) {
    std::cerr << "saker-bench-mission: cannot make a temporary directory\n";
    return 1;
  }
  if (video.empty()) {
    const fs::path demo = fs::path(SAKER_SOURCE_DIR) / "demo" / "demo.ts";
    if (fs::exists(demo)) {
      video = demo.string();
    } else {
      std::cerr << "no " << demo.string()
                << " (run `saker-cli demo` to make it): simulating the roundabout loop\n";
      saker::sim::SimulationOptions sim;
      sim.output = temp.path() / "loop.ts";
      const auto simulated = saker::sim::Simulate(sim);
      if (!simulated.ok()) {
        std::cerr << simulated.status().ToString() << "\n";
        return 1;
      }
      video = sim.output.string();
    }
  }
  const fs::path mission_path = keep.empty() ? temp.path() / "bench.saker" : fs::path(keep);

  // Baseline first, so the video is in the page cache for both.
  const auto decode_s = DecodeSeconds(video);
  if (!decode_s.ok()) {
    std::cerr << decode_s.status().ToString() << "\n";
    return 1;
  }
  saker::pipeline::ProcessOptions options;
  options.replace = true;
  options.saker_version = SAKER_VERSION;
  const auto summary = saker::pipeline::ProcessVideo(video, mission_path.string(), options);
  if (!summary.ok()) {
    std::cerr << summary.status().ToString() << "\n";
    return 1;
  }

  // Opening: what the GUI does before it can draw (open, check, load everything but the tiles).
  std::vector<double> open_ms, read_ms;
  saker::mission::Mission mission;
  for (int i = 0; i < opens; ++i) {
    read_ms.push_back(ReadBytesSeconds(mission_path) * 1e3);
    const Stopwatch begin;
    auto store = saker::mission::MissionStore::Open(mission_path.string());
    if (!store.ok()) {
      std::cerr << store.status().ToString() << "\n";
      return 1;
    }
    auto loaded = (*store)->Load();
    if (!loaded.ok()) {
      std::cerr << loaded.status().ToString() << "\n";
      return 1;
    }
    open_ms.push_back(begin.ElapsedSeconds() * 1e3);
    mission = std::move(loaded).value();
  }
  const double file_mb = static_cast<double>(fs::file_size(mission_path)) / (1 << 20);

  // Picking: half the points near an observation (a click on a track), half anywhere on the map.
  const Stopwatch index_begin;
  const saker::activity::TrackIndex index(&mission.tracks);
  const double index_ms = index_begin.ElapsedSeconds() * 1e3;
  std::vector<double> pick_us, brute_us;
  size_t hits = 0, agree = 0;
  if (index.size() > 0) {
    Eigen::Vector2d low(std::numeric_limits<double>::max(), std::numeric_limits<double>::max());
    Eigen::Vector2d high = -low;
    std::vector<Eigen::Vector2d> all;
    for (const auto& t : mission.tracks) {
      for (const auto& p : t.points) {
        low = low.cwiseMin(p.map), high = high.cwiseMax(p.map);
        all.push_back(p.map);
      }
    }
    // Tolerance: 8 screen pixels at the mosaic's full resolution (one map unit per pixel when
    // there is no pyramid).
    const double tolerance = 8 * (mission.pyramid ? std::abs(mission.pyramid->step_x) : 1.0);
    std::mt19937 random(7);
    std::uniform_real_distribution<double> unit(0, 1);
    std::normal_distribution<double> jitter(0, tolerance / 2);
    std::uniform_int_distribution<size_t> any(0, all.size() - 1);
    const int brute_every = std::max(1, picks / 500);  // the scan is slow: time a sample of it
    for (int i = 0; i < picks; ++i) {
      Eigen::Vector2d p =
          i % 2 == 0
              ? Eigen::Vector2d(all[any(random)] + Eigen::Vector2d(jitter(random), jitter(random)))
              : Eigen::Vector2d(
                    low + (high - low).cwiseProduct(Eigen::Vector2d(unit(random), unit(random))));
      Stopwatch begin;
      const auto pick = index.Nearest(p, tolerance);
      pick_us.push_back(begin.ElapsedSeconds() * 1e6);
      hits += pick.has_value();
      if (i % brute_every == 0) {
        begin.Restart();
        const double brute = BruteForceNearest(mission.tracks, p, tolerance);
        brute_us.push_back(begin.ElapsedSeconds() * 1e6);
        agree +=
            (brute < 0) == !pick.has_value() && (!pick || std::abs(pick->distance - brute) < 1e-9);
      }
    }
  }

  const double duration_s = summary->video_duration_s;
  const double pick_median = Median(pick_us), brute_median = Median(brute_us);
  nlohmann::json out = {
      {"video", video},
      {"video_duration_s", duration_s},
      {"frames", summary->frames},
      {"key_frames", summary->key_frames},
      {"tracks", summary->tracks},
      {"tiles", summary->tiles},
      {"decode_s", *decode_s},
      {"process_s", summary->total_s},
      {"front_end_s", summary->front_end_s},
      {"mosaic_s", summary->mosaic_s},
      {"activity_s", summary->activity_s},
      {"tiles_s", summary->tiles_s},
      {"save_s", summary->save_s},
      {"process_per_video_second", summary->total_s / std::max(duration_s, 1e-9)},
      {"process_per_decode", summary->total_s / std::max(*decode_s, 1e-9)},
      {"mission_mb", file_mb},
      {"open_median_ms", Median(open_ms)},
      {"open_max_ms", Quantile(open_ms, 1.0)},
      {"read_bytes_median_ms", Median(read_ms)},
      {"open_per_read_bytes", Median(open_ms) / std::max(Median(read_ms), 1e-9)},
      {"observations", index.size()},
      {"index_build_ms", index_ms},
      {"pick_median_us", pick_median},
      {"pick_p99_us", Quantile(pick_us, 0.99)},
      {"pick_hits", hits},
      {"brute_force_median_us", brute_median},
      {"brute_force_per_pick", brute_median / std::max(pick_median, 1e-9)},
      {"brute_force_agreement",
       brute_us.empty() ? 1.0 : static_cast<double>(agree) / static_cast<double>(brute_us.size())},
  };
  if (json) {
    std::cout << out.dump(2) << "\n";
    return 0;
  }
  std::printf("video            %s\n", video.c_str());
  std::printf(
      "                 %.1f s, %lld frames; mission: %lld key frames, %lld tracks, "
      "%lld tiles, %.1f MiB\n",
      duration_s, static_cast<long long>(summary->frames),
      static_cast<long long>(summary->key_frames), static_cast<long long>(summary->tracks),
      static_cast<long long>(summary->tiles), file_mb);
  std::printf(
      "processing       %.2f s (front end %.2f, mosaic %.2f, activity %.2f, tiles %.2f, "
      "saves %.2f)\n",
      summary->total_s, summary->front_end_s, summary->mosaic_s, summary->activity_s,
      summary->tiles_s, summary->save_s);
  std::printf("  per video s    %.3f s  (%.2fx real time)\n",
              summary->total_s / std::max(duration_s, 1e-9),
              duration_s / std::max(summary->total_s, 1e-9));
  std::printf("  baseline       decoding alone %.2f s: processing costs %.2fx decoding\n",
              *decode_s, summary->total_s / std::max(*decode_s, 1e-9));
  std::printf(
      "open mission     median %.2f ms, max %.2f ms over %d opens (open + load, no tiles)\n",
      Median(open_ms), Quantile(open_ms, 1.0), opens);
  std::printf("  baseline       reading the file's bytes %.2f ms: opening costs %.2fx that\n",
              Median(read_ms), Median(open_ms) / std::max(Median(read_ms), 1e-9));
  std::printf("pick             %zu observations, index built in %.2f ms\n", index.size(),
              index_ms);
  std::printf("  latency        median %.2f us, p99 %.2f us over %d picks (%zu hits)\n",
              pick_median, Quantile(pick_us, 0.99), picks, hits);
  std::printf(
      "  baseline       brute-force scan median %.1f us: the index is %.0fx faster; "
      "same answer in %zu of %zu\n",
      brute_median, brute_median / std::max(pick_median, 1e-9), agree, brute_us.size());
  return 0;
}
