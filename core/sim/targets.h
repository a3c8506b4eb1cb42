#pragma once

// Moving targets of the simulated world: cars and vans driving the road network, people walking
// the footpaths.
//
// Vehicles keep to the left (the default world is placed in England) and go clockwise round the
// roundabout. Each has a cruising speed, slows for bends and for the vehicle ahead, and now and
// then stops for a few seconds and starts again (a junction, a drop-off). A quarter of them keep
// driving round the road loop, as the traffic of the paper's real-data case; the others choose a
// random road at each junction, preferring the town's streets. People walk back and forth along
// footpaths and pause now and then. Everything is deterministic from the seed and the time step.

#include "core/sim/world.h"
#include "core/util/status.h"

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include <cstdint>
#include <memory>
#include <vector>

namespace saker::sim {

enum class TargetId : int32_t {};

enum class TargetClass { kCar, kVan, kPerson };
const char* TargetClassName(TargetClass target_class);  // "car", "van", "person"

struct TargetOptions {
  int cars = 24;
  int vans = 4;
  int people = 16;
  // Harder traffic. Slow walkers: this fraction of people dawdle at 0.4-0.6 m/s.
  double slow_walker_fraction = 0;
  // People walk in groups of this many, side by side and in step (1: alone).
  int group_size = 1;
  // Vehicles stop every 5-20 s for 2-8 s (instead of every 20-70 s): stop-and-go traffic, with
  // queues forming behind each stop.
  bool stop_and_go = false;
  Status Validate() const;
};

struct Target {
  TargetId id{};
  TargetClass target_class = TargetClass::kCar;
  VehicleLook look;                // vehicles: size and paint
  cv::Scalar clothes_bgr;          // people
  Eigen::Vector2d position{0, 0};  // ground frame, metres (centre of the vehicle or person)
  Eigen::Vector2d velocity{0, 0};  // metres per second
  double heading_deg = 0;          // clockwise from north
  // Footprint on the ground: length along the heading and width across it, metres.
  double length_m() const;
  double width_m() const;
};

// Draws targets (and their shadows) into `image` through `image_from_ground`; `shadow_per_m` is
// ShadowPerMetre of the world. A free function so a copy of the targets can be drawn on another
// thread while the simulation steps on.
void DrawTargets(const std::vector<Target>& targets, const Eigen::Vector2d& shadow_per_m,
                 const Eigen::Matrix3d& image_from_ground, cv::Mat* image);

class TargetSimulation {
 public:
  TargetSimulation(std::shared_ptr<const World> world, const TargetOptions& options, uint64_t seed);
  ~TargetSimulation();
  TargetSimulation(TargetSimulation&&) noexcept;
  TargetSimulation& operator=(TargetSimulation&&) noexcept;

  // Advances every target by `dt_s` seconds.
  void Step(double dt_s);
  double time_s() const;

  const std::vector<Target>& targets() const;

  // The ground offset of the shadow of a point 1 m up (see DrawTargets).
  Eigen::Vector2d shadow_per_m() const;

  // Draws every target (and its shadow) into `image` through `image_from_ground`.
  void Draw(const Eigen::Matrix3d& image_from_ground, cv::Mat* image) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace saker::sim
