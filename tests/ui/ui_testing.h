#pragma once

// Shared by the GUI tests: a small processed mission (the roundabout loop at 640x360, 12.5
// frames per second, with KLV metadata, cars and people), made once per build tree (in
// tests/ui/small-mission of the build folder) and shared by the test processes, and helpers to
// wait on the event loop. Tests must not modify its files: copy them first.

#include "core/mission/mission.h"
#include "core/sim/truth.h"

#include <filesystem>
#include <functional>
#include <string>

namespace saker::ui::testing {

struct TestMission {
  std::filesystem::path video;    // the simulated MPEG-TS
  std::filesystem::path mission;  // processed from it, with tiles
  std::filesystem::path truth;    // the simulator's truth file
  sim::Truth truth_data;
  mission::Mission loaded;  // the mission as the file holds it
};

// Simulates and processes the mission the first time in a build tree (about ten seconds), then
// returns the same files. Fails the calling test (ADD_FAILURE) and returns null when either step
// fails.
const TestMission* SmallMission();

// How long a test waits for the window to process the small mission from start to end: two
// minutes, three times that under a sanitizer (ThreadSanitizer runs the engine's own code several
// times slower, and the suite runs two such tests side by side on two cores).
int ProcessingWaitMs();

// Runs the event loop until `done()` or `timeout_ms` passes; returns done().
bool WaitUntil(const std::function<bool()>& done, int timeout_ms = 30000);

}  // namespace saker::ui::testing
