#pragma once

// The small revisiting flight that the pipeline and GUI tests process: the roundabout loop at
// 640x360, 12.5 frames per second, a 500 m loop, with KLV metadata, six cars and four people.
// Header only: include it from tests that link saker_sim.

#include "core/sim/simulator.h"

#include <filesystem>

namespace saker::testing {

inline sim::SimulationOptions SmallLoopOptions(const std::filesystem::path& output) {
  sim::SimulationOptions options;
  options.output = output;
  options.scenario = sim::Scenario::kRoundaboutLoop;
  options.camera.width = 640;
  options.camera.height = 360;
  options.flight.altitude_m = 200;
  options.fps = 12.5;
  options.world.loop_length_m = 500;
  options.targets.cars = 6;
  options.targets.vans = 0;
  options.targets.people = 4;
  return options;
}

}  // namespace saker::testing
