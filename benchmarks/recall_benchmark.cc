// saker-bench-recall: what an analyst feels recalling frames in the workstation, with the
// decode of one frame by random access (the baseline) measured in the same run:
// - recall: a click on an observation to its frame on screen, over random observations;
// - scrubbing: the time line's slider dragged across the mission (a mouse event every 16 ms, the
//   frame panel asked for each new frame, latest wins): the latency of every frame that reaches
//   the screen and how many of those asked for did.
//
//   saker-bench-recall [--mission M.saker --video V.ts] [--hd] [--drag-seconds S] [--json]
//
// Without --mission it uses the demo mission (demo/demo.saker) when it is there. --hd also
// simulates and processes a 20 s 1920x1080 clip (saker-cli) and measures it the same way.

#include "core/mission/mission_store.h"
#include "core/util/statistics.h"
#include "ui/frame_panel.h"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <QApplication>
#include <QElapsedTimer>
#include <QEventLoop>
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <memory>
#include <random>
#include <string>
#include <vector>

namespace {

namespace fs = std::filesystem;

// Runs the event loop for `ms` milliseconds.
void Pump(int ms) {
  QElapsedTimer clock;
  clock.start();
  while (clock.elapsed() < ms) {
    QCoreApplication::processEvents(QEventLoop::AllEvents,
                                    static_cast<int>(std::max<qint64>(1, ms - clock.elapsed())));
  }
}

// Runs the event loop until `done` or `ms` milliseconds passed; whether `done` came.
template <typename Done>
bool PumpUntil(Done done, int ms) {
  QElapsedTimer clock;
  clock.start();
  while (!done() && clock.elapsed() < ms) QCoreApplication::processEvents(QEventLoop::AllEvents, 5);
  return done();
}

double Percentile(std::vector<double> values, double q) {
  if (values.empty()) return std::nan("");
  return saker::Quantile(std::move(values), q);
}

nlohmann::json Measure(const std::string& label, const fs::path& mission_path,
                       const fs::path& video_path, double drag_seconds) {
  auto store = saker::mission::MissionStore::Open(mission_path.string());
  if (!store.ok()) {
    std::cerr << store.status().message() << "\n";
    return nullptr;
  }
  auto loaded = (*store)->Load();
  if (!loaded.ok() || loaded->tracks.empty() || loaded->frames.empty()) {
    std::cerr << mission_path << ": no mission with tracks to recall\n";
    return nullptr;
  }
  const auto mission = std::make_shared<const saker::mission::Mission>(std::move(loaded).value());
  saker::ui::FramePanel panel;
  panel.resize(800, 620);
  panel.show();
  panel.setMission(mission, QString::fromStdString(video_path.string()));
  std::vector<double> recall_ms, decode_ms;
  std::vector<std::pair<int64_t, double>> shown;  // frame, latency
  QObject::connect(&panel, &saker::ui::FramePanel::frameShown,
                   [&](int64_t frame, double ms) { shown.emplace_back(frame, ms); });
  // Warm: the first recall indexes the video when the mission does not know its frames.
  panel.showObservation(0, 0);
  PumpUntil([&] { return !shown.empty(); }, 120000);

  // Clicks on random observations.
  std::mt19937 random(7);
  for (int i = 0; i < 30; ++i) {
    const size_t t = random() % mission->tracks.size();
    const size_t p = random() % mission->tracks[t].points.size();
    shown.clear();
    panel.showObservation(t, p);
    if (!PumpUntil([&] { return !shown.empty(); }, 10000)) continue;
    recall_ms.push_back(panel.lastRecallMs());
    decode_ms.push_back(panel.lastDecodeMs());
    Pump(50);
  }

  // A drag across the whole mission in `drag_seconds`: a mouse event every 16 ms.
  panel.clear();
  Pump(100);
  shown.clear();
  const size_t frames = mission->frames.size();
  const int events = std::max(1, static_cast<int>(drag_seconds * 1000 / 16));
  int64_t asked = 0, last = -1;
  QElapsedTimer clock;
  clock.start();
  for (int e = 0; e <= events; ++e) {
    const size_t position = std::min(frames - 1, frames * static_cast<size_t>(e) / events);
    const int64_t frame = mission->frames[position].index;
    if (frame != last) {
      panel.showFrame(frame);
      ++asked;
      last = frame;
    }
    const qint64 due = static_cast<qint64>(16) * (e + 1);
    if (clock.elapsed() < due) Pump(static_cast<int>(due - clock.elapsed()));
  }
  PumpUntil([&] { return !shown.empty() && shown.back().first == last; }, 5000);
  std::vector<double> scrub_ms;
  for (const auto& [frame, ms] : shown) {
    if (std::isfinite(ms)) scrub_ms.push_back(ms);
  }
  const nlohmann::json row = {
      {"mission", label},
      {"width", mission->source.width},
      {"height", mission->source.height},
      {"recall_median_ms", Percentile(recall_ms, 0.5)},
      {"recall_p95_ms", Percentile(recall_ms, 0.95)},
      {"decode_median_ms", Percentile(decode_ms, 0.5)},
      {"scrub_frames_asked", asked},
      {"scrub_frames_shown", scrub_ms.size()},
      {"scrub_median_ms", Percentile(scrub_ms, 0.5)},
      {"scrub_p95_ms", Percentile(scrub_ms, 0.95)},
  };
  std::printf(
      "%s (%dx%d): recall median %.0f ms, p95 %.0f ms over %zu clicks; decode alone (random "
      "access) median %.0f ms, so recall = %.1fx decode. Scrubbing %zu frames in %.0f s: %zu "
      "shown (%.0f %%), latency median %.0f ms, p95 %.0f ms (targets 50 and 150)\n",
      label.c_str(), mission->source.width, mission->source.height, Percentile(recall_ms, 0.5),
      Percentile(recall_ms, 0.95), recall_ms.size(), Percentile(decode_ms, 0.5),
      Percentile(recall_ms, 0.5) / Percentile(decode_ms, 0.5), static_cast<size_t>(asked),
      drag_seconds, scrub_ms.size(),
      100.0 * static_cast<double>(scrub_ms.size()) /
          static_cast<double>(std::max<int64_t>(1, asked)),
      Percentile(scrub_ms, 0.5), Percentile(scrub_ms, 0.95));
  return row;
}

}  // namespace

int main(int argc, char** argv) {
  if (qEnvironmentVariableIsEmpty("QT_QPA_PLATFORM")) qputenv("QT_QPA_PLATFORM", "offscreen");
  CLI::App app("saker-bench-recall: frame recall and time-line scrubbing latency");
  std::string mission, video;
  bool hd = false, json = false;
  double drag_seconds = 5;
  app.add_option("--mission", mission, "Mission file (default: demo/demo.saker)");
  app.add_option("--video", video, "Its video (default: beside it, demo.ts for the demo)");
  app.add_flag("--hd", hd, "Also simulate, process and measure a 20 s 1920x1080 clip");
  app.add_option("--drag-seconds", drag_seconds, "How long the drag across the mission takes")
      ->capture_default_str()
      ->check(CLI::Range(0.5, 120.0));
  app.add_flag("--json", json, "Print JSON");
  CLI11_PARSE(app, argc, argv);
  QApplication application(argc, argv);
  nlohmann::json rows = nlohmann::json::array();
  if (mission.empty()) {
    const fs::path demo = fs::path(SAKER_SOURCE_DIR) / "demo";
    mission = (demo / "demo.saker").string();
    if (video.empty()) video = (demo / "demo.ts").string();
  }
  if (video.empty()) video = (fs::path(mission).parent_path() / "demo.ts").string();
  if (fs::exists(mission) && fs::exists(video)) {
    rows.push_back(Measure(fs::path(mission).filename().string(), mission, video, drag_seconds));
  } else {
    std::cerr << "saker-bench-recall: " << mission << " or " << video
              << " not found (run saker-cli demo first, or give --mission and --video)\n";
  }
  if (hd) {
    const fs::path dir = fs::temp_directory_path() / "saker-bench-recall";
    fs::create_directories(dir);
    const std::string ts = (dir / "hd.ts").string(), saker = (dir / "hd.saker").string();
    const std::string cli = SAKER_CLI_PATH;
    const std::string simulate =
        "'" + cli + "' simulate -q --width 1920 --height 1080 --duration 20 -o '" + ts + "'";
    const std::string process =
        "'" + cli + "' process -q --replace --no-tiles '" + ts + "' -o '" + saker + "'";
    if (std::system(simulate.c_str()) != 0 || std::system(process.c_str()) != 0) {
      std::cerr << "saker-bench-recall: making the 1080p mission failed\n";
      return 1;
    }
    rows.push_back(Measure("1920x1080 simulated", saker, ts, drag_seconds));
    fs::remove_all(dir);
  }
  if (json) std::cout << rows.dump(2) << "\n";
  return rows.empty() ? 1 : 0;
}
