// saker-bench-crash: kill -9 at random moments while a mission is processed or copied (Save As),
// many times, and check after each kill that the mission reopens in its last committed state.
//
//   saker-bench-crash [--runs N] [--seed S] [--keep]
//
// It simulates a small revisiting flight (the roundabout loop at 640x360, in a temporary
// directory), processes it once without interruption as the reference, then repeats:
//   - process: `saker-cli process` into a fresh file, or over the previous run's mission with
//     --replace, killed (SIGKILL) after a random time up to the reference's duration (half of
//     the kills in its last quarter, where the later stages are saved). While the
//     child runs, a read-only reader polls the file and notes the furthest stage it saw committed.
//     Checkpoints are taken at every key frame (--checkpoint-every 0). A killed processing job is
//     then resumed (--resume), half the time killed once more first, and must complete.
//   - copy: `saker-cli copy` of the reference over a copy of the last processing run's mission
//     (often partial) with --replace, killed likewise.
// After each kill a run fails when the file cannot be opened and loaded, fails SQLite's integrity
// check, has a stage marked complete whose data differ from the reference's, has a later stage
// complete without an earlier one, lost a stage the reader had seen committed, or (copy) is
// neither the previous copy nor the complete new one; and when the reference itself changed. A
// resumed job fails when it does not complete, leaves its checkpoint, or differs from the
// reference by more than a resumed job may (Inconsistency).
// It prints the number of runs and failures (the target is zero), where the kills landed, and the
// temporary files that killed jobs left beside their targets.

#include "core/mission/mission_store.h"
#include "core/sim/simulator.h"
#include "core/util/timer.h"
#include "tests/testing/small_loop.h"

#include <CLI/CLI.hpp>
#include <fcntl.h>
#include <sqlite3.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <iostream>
#include <map>
#include <optional>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <utility>
#include <vector>

namespace {

using saker::Stopwatch;

namespace fs = std::filesystem;
using saker::mission::Mission;
using saker::mission::MissionStore;

// What a mission file holds, as far as the check needs it.
struct Snapshot {
  bool exists = false;
  std::string error;  // why it could not be opened or loaded; empty when it could
  std::string integrity;
  saker::mission::Progress progress;
  Mission mission;
  int64_t tiles = 0;
  int stages() const {  // completed stages in order, counting the "source" commit as 1
    const saker::mission::Progress& p = progress;
    return 1 + static_cast<int>(p.front_end) + static_cast<int>(p.mosaic) +
           static_cast<int>(p.activity) + static_cast<int>(p.tiles);
  }
};

std::string IntegrityCheck(const std::string& path) {
  sqlite3* db = nullptr;
  std::string answer = "cannot open";
  if (sqlite3_open_v2(path.c_str(), &db, SQLITE_OPEN_READONLY, nullptr) == SQLITE_OK) {
    sqlite3_stmt* statement = nullptr;
    if (sqlite3_prepare_v2(db, "PRAGMA integrity_check", -1, &statement, nullptr) == SQLITE_OK) {
      answer.clear();
      while (sqlite3_step(statement) == SQLITE_ROW) {
        if (!answer.empty()) answer += "; ";
        answer += reinterpret_cast<const char*>(sqlite3_column_text(statement, 0));
      }
    }
    sqlite3_finalize(statement);
  }
  sqlite3_close(db);
  return answer;
}

// `full`: also count the tiles and run SQLite's integrity check (the polling reader does not).
Snapshot Take(const std::string& path, bool full) {
  Snapshot s;
  std::error_code ignored;
  s.exists = fs::exists(path, ignored);
  if (!s.exists) return s;
  auto store = MissionStore::Open(path);
  if (!store.ok()) {
    s.error = store.status().message();
    return s;
  }
  auto mission = (*store)->Load();
  if (!mission.ok()) {
    s.error = mission.status().message();
    return s;
  }
  s.mission = std::move(mission).value();
  s.progress = s.mission.progress;
  if (full && s.mission.pyramid) {
    const saker::mission::PyramidInfo& p = *s.mission.pyramid;
    for (int level = 0; level < p.levels; ++level) {
      const int size = p.tile_size << level;
      for (int y = 0; y * size < p.height; ++y) {
        for (int x = 0; x * size < p.width; ++x) {
          auto tile = (*store)->ReadTile(level, x, y);
          if (!tile.ok()) {
            s.error = tile.status().message();
            return s;
          }
          s.tiles += tile->has_value();
        }
      }
    }
  }
  if (full) s.integrity = IntegrityCheck(path);
  return s;
}

// Why `s` is not a state the processing job can have committed (empty: it is one). A resumed
// job's mosaic and tracks are those of one run only up to the seam where it resumed, so for it
// (`exact` false) they must only be close to the reference's: key frames within 15 %, the same
// frames placed, tracks within 3.
std::string Inconsistency(const Snapshot& s, const Snapshot& reference, bool exact = true) {
  if (!s.error.empty()) return "does not reopen: " + s.error;
  if (s.integrity != "ok") return "integrity check: " + s.integrity;
  const saker::mission::Progress& p = s.progress;
  if ((p.mosaic && !p.front_end) || (p.activity && !p.mosaic) || (p.tiles && !p.activity)) {
    return "a stage is complete without the one before it";
  }
  const Mission& m = s.mission;
  const Mission& r = reference.mission;
  if (m.source.path != r.source.path || m.source.width != r.source.width) {
    return "the source differs";
  }
  if (p.front_end) {
    if (m.frames.size() != r.frames.size()) return "front end: frame count differs";
    for (size_t i = 0; i < m.frames.size(); ++i) {
      if (m.frames[i].index != r.frames[i].index || m.frames[i].time_s != r.frames[i].time_s) {
        return "front end: frame " + std::to_string(i) + " differs";
      }
    }
  }
  const auto near = [](size_t a, size_t b, double tolerance) {
    return std::abs(static_cast<double>(a) - static_cast<double>(b)) <= tolerance;
  };
  if (!exact) {
    if (p.mosaic && !near(m.key_frames.size(), r.key_frames.size(),
                          0.15 * static_cast<double>(r.key_frames.size()) + 1)) {
      return "mosaic (resumed): " + std::to_string(m.key_frames.size()) +
             " key frames, not about " + std::to_string(r.key_frames.size());
    }
    if (p.activity && !near(m.tracks.size(), r.tracks.size(), 3)) {
      return "activity (resumed): " + std::to_string(m.tracks.size()) + " tracks, not about " +
             std::to_string(r.tracks.size());
    }
    if (p.tiles && (s.tiles == 0 || !m.pyramid)) return "tiles (resumed): none";
    return {};
  }
  if (p.mosaic) {
    if (m.key_frames.size() != r.key_frames.size() || m.links.size() != r.links.size()) {
      return "mosaic: key frame or link count differs";
    }
    for (size_t i = 0; i < m.key_frames.size(); ++i) {
      if (!m.key_frames[i].map_from_frame.isApprox(r.key_frames[i].map_from_frame, 1e-9)) {
        return "mosaic: key frame " + std::to_string(i) + " placed differently";
      }
    }
    size_t placed = 0, placed_reference = 0;
    for (const auto& f : m.frames) placed += f.map_from_frame.has_value();
    for (const auto& f : r.frames) placed_reference += f.map_from_frame.has_value();
    if (placed != placed_reference) return "mosaic: placed frame count differs";
  }
  if (p.activity) {
    if (m.tracks.size() != r.tracks.size()) return "activity: track count differs";
    for (size_t i = 0; i < m.tracks.size(); ++i) {
      if (m.tracks[i].points.size() != r.tracks[i].points.size()) {
        return "activity: track " + std::to_string(i) + " differs";
      }
    }
  }
  if (p.tiles && (s.tiles != reference.tiles || !m.pyramid)) return "tiles: tile count differs";
  return {};
}

// Runs saker-cli with `arguments` (stdout and stderr to /dev/null); returns the child's pid.
pid_t Spawn(const std::vector<std::string>& arguments) {
  std::vector<char*> argv;
  static const std::string program = SAKER_CLI_PATH;
  argv.push_back(const_cast<char*>(program.c_str()));
  for (const std::string& a : arguments) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  const pid_t child = fork();
  if (child == 0) {
    const int null = ::open("/dev/null", O_WRONLY);
    dup2(null, STDOUT_FILENO);
    dup2(null, STDERR_FILENO);
    execv(argv[0], argv.data());
    _exit(127);
  }
  return child;
}

// Waits until `after` has passed, calling `poll` every 15 ms, then kills `child` with SIGKILL,
// unless it ends by itself first. Returns the seconds it ran and whether it ended by itself.
std::pair<double, bool> KillAfter(pid_t child, std::chrono::duration<double> after,
                                  const std::function<void()>& poll) {
  const Stopwatch spawned;
  bool ended = false;
  while (spawned.ElapsedSeconds() < after.count()) {
    if (waitpid(child, nullptr, WNOHANG) == child) {
      ended = true;
      break;
    }
    if (poll) poll();
    std::this_thread::sleep_for(std::chrono::milliseconds(15));
  }
  if (!ended) {
    kill(child, SIGKILL);
    waitpid(child, nullptr, 0);
  }
  return {spawned.ElapsedSeconds(), ended};
}

// Whether the mission at `path` holds a checkpoint to resume from.
bool HasCheckpoint(const std::string& path) {
  auto store = MissionStore::Open(path);
  if (!store.ok()) return false;
  auto records = (*store)->ReadCheckpoint();
  return records.ok() && !records->empty();
}

// Leftover temporary files of killed jobs beside the targets.
int CountTemporaryFiles(const fs::path& dir) {
  int n = 0;
  for (const auto& entry : fs::directory_iterator(dir)) {
    const std::string name = entry.path().filename().string();
    if (name.find(".new-") != std::string::npos || name.find(".part-") != std::string::npos) ++n;
  }
  return n;
}

const char* kStageNames[] = {"no file", "source",   "front end",
                             "mosaic",  "activity", "tiles (complete)"};

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"saker-bench-crash: kill -9 during processing and Save As, check every reopen"};
  int runs = 100;
  unsigned seed = 1;
  bool keep = false;
  app.add_option("--runs", runs, "Kills")->capture_default_str()->check(CLI::PositiveNumber);
  app.add_option("--seed", seed, "Random seed of the kill times")->capture_default_str();
  app.add_flag("--keep", keep, "Keep the temporary directory (its path is printed)");
  CLI11_PARSE(app, argc, argv);

  std::string pattern = (fs::temp_directory_path() / "saker-bench-crash-XXXXXX").string();
  if (mkdtemp(pattern.data()) == nullptr) {
    std::perror("saker-bench-crash: temporary directory");
    return 1;
  }
  const fs::path dir = pattern;
  struct Remover {
    fs::path dir;
    bool keep;
    ~Remover() {
      std::error_code ignored;
      if (!keep) fs::remove_all(dir, ignored);
    }
  } remover{dir, keep};
  if (keep) std::printf("working in %s\n", dir.c_str());

  // The pipeline and GUI tests' flight (header only, shared with the tests).
  const saker::sim::SimulationOptions sim = saker::testing::SmallLoopOptions(dir / "loop.ts");
  std::printf("simulating the small loop (640x360)...\n");
  std::fflush(stdout);
  if (auto simulated = saker::sim::Simulate(sim); !simulated.ok()) {
    std::cerr << "saker-bench-crash: " << simulated.status().message() << "\n";
    return 1;
  }
  const std::string video = sim.output.string();
  const std::string reference_path = (dir / "reference.saker").string();
  const auto run_to_end = [](const std::vector<std::string>& arguments) {
    int status = 0;
    const Stopwatch start;
    waitpid(Spawn(arguments), &status, 0);
    const double seconds = start.ElapsedSeconds();
    return WIFEXITED(status) && WEXITSTATUS(status) == 0 ? seconds : -1.0;
  };
  // Checkpoints at every key frame, so that the kills land in and between them.
  const std::vector<std::string> checkpoint_every = {"--checkpoint-every", "0"};
  const auto process_arguments = [&](const std::string& output) {
    std::vector<std::string> arguments = {"process", "-q", video, "-o", output};
    arguments.insert(arguments.end(), checkpoint_every.begin(), checkpoint_every.end());
    return arguments;
  };
  double process_s = run_to_end(process_arguments(reference_path));
  double copy_s = run_to_end({"copy", reference_path, (dir / "timing.saker").string()});
  if (process_s < 0 || copy_s < 0) {
    std::cerr << "saker-bench-crash: the uninterrupted reference run failed\n";
    return 1;
  }
  fs::remove(dir / "timing.saker");
  const Snapshot reference = Take(reference_path, true);
  if (Inconsistency(reference, reference) != "" || !reference.progress.tiles) {
    std::cerr << "saker-bench-crash: the reference mission is incomplete\n";
    return 1;
  }
  std::printf(
      "reference: processing %.2f s (%zu frames, %zu key frames, %zu tracks, %lld tiles), "
      "copy %.2f s\n",
      process_s, reference.mission.frames.size(), reference.mission.key_frames.size(),
      reference.mission.tracks.size(), static_cast<long long>(reference.tiles), copy_s);
  std::fflush(stdout);

  std::mt19937 random(seed);
  const std::string processed = (dir / "processed.saker").string();
  const std::string copied = (dir / "copy.saker").string();
  int failures = 0, process_runs = 0, copy_runs = 0, replaced_runs = 0, copies_complete = 0,
      ended_runs = 0;
  // Resuming the killed processing jobs: how many, from a checkpoint, killed again first, and
  // the time to finish.
  int resumed_runs = 0, from_checkpoint = 0, resumes_killed = 0;
  double resume_s = 0;
  bool processed_resumed = false;  // `processed` holds a resumed job's mission
  bool copied_resumed = false;     // and the copy a Save As replaces
  std::map<int, int> landed;       // stages completed when killed -> processing runs
  const Stopwatch start;
  for (int run = 0; run < runs; ++run) {
    const bool copy = std::uniform_int_distribution<int>(0, 2)(random) == 0;
    // Half the kills anywhere, half in the last quarter, where the later stages and the tiles
    // are saved (the front end takes most of the time).
    const double duration_s = copy ? copy_s : process_s;
    const double earliest_s =
        std::uniform_int_distribution<int>(0, 1)(random) == 0 ? 0.0 : 0.75 * duration_s;
    const auto kill_after = std::chrono::duration<double>(
        std::uniform_real_distribution<double>(earliest_s, 1.05 * duration_s)(random));
    std::string failure;
    if (!copy) {
      ++process_runs;
      // Half the runs replace the previous run's mission, half write a new file.
      const bool replace =
          fs::exists(processed) && std::uniform_int_distribution<int>(0, 1)(random);
      if (!replace) fs::remove(processed);
      replaced_runs += replace;
      const Snapshot before = Take(processed, false);
      std::vector<std::string> arguments = process_arguments(processed);
      if (replace) arguments.push_back("--replace");
      const pid_t child = Spawn(arguments);
      // The furthest stage a reader saw committed by this run (on a new file only: while
      // replacing, the reader sees the old file until the new one is renamed over it).
      int seen = 0;
      const auto [ran_s, ended] = KillAfter(child, kill_after, [&] {
        if (replace) return;
        const Snapshot now = Take(processed, false);
        if (now.exists && now.error.empty()) seen = std::max(seen, now.stages());
      });
      // A job that ended before its kill shows the machine is faster now than when the
      // reference ran: later kills aim within this duration.
      if (ended) ++ended_runs, process_s = ran_s;
      const Snapshot after = Take(processed, true);
      if (!after.exists) {
        if (seen > 0 || before.exists) failure = "the mission file vanished";
        landed[0]++;
      } else {
        // Killed before its rename, a replacing job leaves the previous (maybe resumed) mission.
        failure = Inconsistency(after, reference, !(replace && processed_resumed));
        if (failure.empty() && after.stages() < seen) {
          failure = "lost a committed stage (a reader had seen " + std::to_string(seen) +
                    " stages, " + std::to_string(after.stages()) + " reopened)";
        }
        landed[after.stages()]++;
      }
      if (!replace || ended) processed_resumed = false;
      // The killed job resumed (half the time killed once more first), then checked complete.
      if (failure.empty() && !ended && after.exists && after.error.empty()) {
        ++resumed_runs;
        from_checkpoint += HasCheckpoint(processed);
        std::vector<std::string> resume = process_arguments(processed);
        resume.push_back("--resume");
        if (std::uniform_int_distribution<int>(0, 1)(random) == 0) {
          ++resumes_killed;
          KillAfter(Spawn(resume),
                    std::chrono::duration<double>(
                        std::uniform_real_distribution<double>(0, process_s)(random)),
                    nullptr);
          if (std::string why = Inconsistency(Take(processed, true), reference, false);
              !why.empty()) {
            failure = "killed resume: " + why;
          }
        }
        if (failure.empty()) {
          const double seconds = run_to_end(resume);
          const Snapshot done = Take(processed, true);
          if (seconds < 0) {
            failure = "resume: the job failed";
          } else if (std::string why = Inconsistency(done, reference, false); !why.empty()) {
            failure = "resume: " + why;
          } else if (!done.progress.tiles || done.progress.cancelled) {
            failure = "resume: the mission is not complete";
          } else if (HasCheckpoint(processed)) {
            failure = "resume: the completed job left its checkpoint";
          }
          resume_s += std::max(0.0, seconds);
        }
        processed_resumed = true;
      }
    } else {
      ++copy_runs;
      // What Save As replaces: the last processing run's mission (often partial), copied whole.
      fs::remove(copied);
      copied_resumed = false;
      if (Take(processed, false).error.empty() && fs::exists(processed)) {
        run_to_end({"copy", processed, copied});
        copied_resumed = processed_resumed;
      }
      const Snapshot before = Take(copied, true);
      std::vector<std::string> arguments = {"copy", reference_path, copied};
      if (before.exists) arguments.push_back("--replace");
      const auto [ran_s, ended] = KillAfter(Spawn(arguments), kill_after, nullptr);
      if (ended) ++ended_runs, copy_s = ran_s;
      const Snapshot after = Take(copied, true);
      if (!after.exists) {
        if (before.exists) failure = "copy: the previous copy vanished";
      } else if (std::string why = Inconsistency(after, reference, !copied_resumed); !why.empty()) {
        failure = "copy: " + why;
      } else if (after.progress.tiles && after.tiles == reference.tiles) {
        ++copies_complete;
      } else if (!before.exists || after.stages() != before.stages() ||
                 after.tiles != before.tiles) {
        failure = "copy: neither the previous copy nor a complete one";
      }
      const Snapshot source = Take(reference_path, true);
      if (failure.empty() && (!Inconsistency(source, reference).empty() || !source.progress.tiles ||
                              source.tiles != reference.tiles)) {
        failure = "copy: the original changed";
      }
    }
    if (!failure.empty()) {
      ++failures;
      std::printf("run %d (%s, killed after %.2f s): FAILED: %s\n", run, copy ? "copy" : "process",
                  kill_after.count(), failure.c_str());
      std::fflush(stdout);
    }
  }
  const double elapsed = start.ElapsedSeconds();
  std::printf(
      "%d runs in %.0f s (%d processing, %d of them replacing a mission; %d Save As, %d of "
      "which had completed); %d jobs ended before their kill: %d failures\n",
      runs, elapsed, process_runs, replaced_runs, copy_runs, copies_complete, ended_runs, failures);
  std::printf("processing runs by the state they reopened in:");
  for (const auto& [stages, count] : landed) std::printf(" %s %d;", kStageNames[stages], count);
  std::printf("\ntemporary files left by killed jobs: %d\n", CountTemporaryFiles(dir));
  if (resumed_runs > 0) {
    std::printf(
        "resumed %d killed processing jobs (%d from a checkpoint, the rest from the start; %d "
        "killed once more first): finishing took %.2f s on average, %.0f %% of processing from "
        "the start (%.2f s)\n",
        resumed_runs, from_checkpoint, resumes_killed, resume_s / resumed_runs,
        100 * resume_s / resumed_runs / process_s, process_s);
  }
  return failures == 0 ? 0 : 1;
}
