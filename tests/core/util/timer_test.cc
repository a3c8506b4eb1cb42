#include "core/util/timer.h"

#include <gtest/gtest.h>

#include <chrono>
#include <thread>

namespace saker {
namespace {

// Only lower bounds: a loaded machine may take any time longer.
TEST(StopwatchTest, MeasuresAtLeastTheTimeSlept) {
  Stopwatch watch;
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  const double seconds = watch.ElapsedSeconds();
  EXPECT_GE(seconds, 0.020);
  EXPECT_GE(watch.ElapsedMs(), 20.0);
  EXPECT_GE(watch.ElapsedUs(), 20000.0);
  EXPECT_GE(watch.ElapsedMs(), seconds * 1e3);  // later reads never go back
}

TEST(StopwatchTest, RestartAndLapsStartAgain) {
  Stopwatch watch;
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  const Stopwatch total;
  const double lap = watch.LapSeconds();
  EXPECT_GE(lap, 0.020);
  // The lap started `watch` again after `total` started; reading `watch` first keeps the
  // comparison true whatever the scheduler does between the two reads.
  const double since_lap = watch.ElapsedSeconds();
  EXPECT_LE(since_lap, total.ElapsedSeconds());
  std::this_thread::sleep_for(std::chrono::milliseconds(5));
  watch.Restart();
  const double since_restart = watch.ElapsedSeconds();
  EXPECT_LE(since_restart, total.ElapsedSeconds());
  EXPECT_LE(since_restart, total.ElapsedSeconds() - 0.005);  // the 5 ms sleep is not in it
}

}  // namespace
}  // namespace saker
