#include "tests/ui/ui_testing.h"

#include "core/mission/mission_store.h"
#include "core/pipeline/process.h"
#include "core/sim/simulator.h"
#include "tests/testing/sanitizers.h"
#include "tests/testing/small_loop.h"
#include "tests/testing/test_data.h"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/file.h>
#include <unistd.h>

#include <QApplication>
#include <QElapsedTimer>
#include <QTest>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>

namespace saker::ui::testing {

namespace {

// CTest runs every test in a process of its own; the mission is made once per build, in a folder
// of the build tree, under a lock so that parallel tests wait for the first one. A stamp written
// last marks it complete (with the options, the build of this file and the modification times of
// the engine libraries, so it is remade when any of them changes: this file is not compiled
// again when only the engine is).
std::string EngineStamp() {
  std::string stamp;
  std::stringstream libraries(SAKER_UI_TEST_ENGINE);
  for (std::string library; std::getline(libraries, library, ':');) {
    std::error_code error;
    const auto time = std::filesystem::last_write_time(library, error);
    stamp += " " + (error ? std::string("?") : std::to_string(time.time_since_epoch().count()));
  }
  return stamp;
}

class CacheLock {
 public:
  explicit CacheLock(const std::filesystem::path& path)
      : fd_(open(path.c_str(), O_RDWR | O_CREAT, 0644)) {
    if (fd_ >= 0) flock(fd_, LOCK_EX);
  }
  ~CacheLock() {
    if (fd_ >= 0) close(fd_);  // releases the lock
  }

 private:
  int fd_;
};

std::unique_ptr<TestMission> MakeSmallMission() {
  auto made = std::make_unique<TestMission>();
  const std::filesystem::path dir = SAKER_UI_TEST_CACHE;
  std::error_code error;
  std::filesystem::create_directories(dir, error);
  if (error) {
    ADD_FAILURE() << dir << ": " << error.message();
    return nullptr;
  }
  const CacheLock lock(dir / "lock");
  made->video = dir / "loop.ts";
  made->mission = dir / "loop.saker";

  const sim::SimulationOptions options = saker::testing::SmallLoopOptions(made->video);
  made->truth = options.TruthPath();
  const std::string stamp_text =
      options.ToJson().dump() + " " + __DATE__ + " " + __TIME__ + EngineStamp();
  const std::filesystem::path stamp = dir / "stamp";
  std::string existing;
  if (std::ifstream in(stamp); in) std::getline(in, existing);
  const bool cached = existing == stamp_text;
  if (!cached) std::filesystem::remove(stamp, error);
  const auto simulated =
      cached ? StatusOr<sim::SimulationSummary>(sim::SimulationSummary{}) : sim::Simulate(options);
  if (!simulated.ok()) {
    ADD_FAILURE() << simulated.status().ToString();
    return nullptr;
  }
  auto truth = sim::ReadTruth(made->truth);
  if (!truth.ok()) {
    ADD_FAILURE() << truth.status().ToString();
    return nullptr;
  }
  made->truth_data = std::move(truth).value();

  if (!cached) {
    pipeline::ProcessOptions process;
    process.saker_version = "test";
    process.replace = true;
    const auto processed =
        pipeline::ProcessVideo(made->video.string(), made->mission.string(), process);
    if (!processed.ok()) {
      ADD_FAILURE() << processed.status().ToString();
      return nullptr;
    }
    std::ofstream(stamp) << stamp_text << "\n";
  }
  auto store = mission::MissionStore::Open(made->mission.string());
  if (!store.ok()) {
    ADD_FAILURE() << store.status().ToString();
    return nullptr;
  }
  auto loaded = (*store)->Load();
  if (!loaded.ok()) {
    ADD_FAILURE() << loaded.status().ToString();
    return nullptr;
  }
  made->loaded = std::move(loaded).value();
  return made;
}

}  // namespace

const TestMission* SmallMission() {
  static std::unique_ptr<TestMission> mission = MakeSmallMission();
  if (mission == nullptr) ADD_FAILURE() << "the small test mission could not be made";
  return mission.get();
}

int ProcessingWaitMs() {
  constexpr int kWaitMs = 120000;
  return saker::testing::kUnderThreadSanitizer || saker::testing::kUnderAddressSanitizer
             ? 3 * kWaitMs
             : kWaitMs;
}

bool WaitUntil(const std::function<bool()>& done, int timeout_ms) {
  QElapsedTimer timer;
  timer.start();
  while (!done()) {
    if (timer.elapsed() > timeout_ms) return false;
    QTest::qWait(10);
  }
  return true;
}

}  // namespace saker::ui::testing
