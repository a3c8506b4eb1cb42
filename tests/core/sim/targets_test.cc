#include "core/sim/targets.h"

#include "core/sim/camera.h"

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include <map>

namespace saker::sim {
namespace {

std::shared_ptr<const World> TestWorld() {
  static const std::shared_ptr<const World> world = [] {
    StatusOr<World> w = GenerateWorld({}, cv::Rect2d(-1500, -1000, 3000, 2000));
    return std::make_shared<const World>(std::move(w).value());
  }();
  return world;
}

// Distance from a point to the nearest carriageway edge (negative inside a road or roundabout).
double OffRoad(const World& world, const Eigen::Vector2d& p) {
  double best = 1e9;
  for (const Road& road : world.roads)
    best = std::min(best, DistanceToPolyline(p, road.centreline) - road.width_m / 2);
  const RoadNode& r = world.nodes[world.roundabout_node];
  best = std::min(best, (p - r.position).norm() - r.roundabout_radius_m);
  return best;
}

// An oblique camera sees only the targets in front of it: one behind it (the ground homography's
// third coordinate of the other sign) would be drawn mirrored into the frame, and one straddling
// its principal plane as a polygon across the whole frame. Neither is drawn; one in view is.
TEST(TargetsTest, AnObliqueCameraDrawsNoTargetBehindIt) {
  CameraIntrinsics lens;
  lens.width = 640, lens.height = 360;
  CameraPose pose;
  pose.position_m = {0, 0, 200};
  pose.gimbal_off_nadir_deg = 45;  // looking north, 45 degrees down
  const Eigen::Matrix3d image_from_ground = FrameFromGround(lens, pose);
  const auto ahead = GroundCentre(lens, pose);
  ASSERT_TRUE(ahead.has_value());
  const auto image_of = [&](const Eigen::Vector2d& ground, const Eigen::Matrix3d& h) {
    cv::Mat image(lens.height, lens.width, CV_8UC3, cv::Scalar(90, 120, 90));
    Target car;
    car.position = ground;
    car.look.body_bgr = cv::Scalar(250, 250, 250);
    DrawTargets({car}, Eigen::Vector2d(0.3, 0.2), h, &image);
    return cv::norm(image, cv::Mat(image.size(), CV_8UC3, cv::Scalar(90, 120, 90)), cv::NORM_L1);
  };
  EXPECT_GT(image_of(*ahead, image_from_ground), 0) << "the car in view is drawn";
  // Behind the camera (the principal plane meets the ground 200 m south of it) and just on it.
  for (const Eigen::Vector2d& behind :
       {Eigen::Vector2d(10, -400), Eigen::Vector2d(-30, -250), Eigen::Vector2d(0, -200.5)}) {
    EXPECT_EQ(image_of(behind, image_from_ground), 0) << behind.transpose();
    // Whatever the homography's scale and sign.
    EXPECT_EQ(image_of(behind, -2.0 * image_from_ground), 0) << behind.transpose();
  }
  EXPECT_GT(image_of(*ahead, -2.0 * image_from_ground), 0);
}

TEST(TargetsTest, VehiclesStayOnRoadsAtRealisticSpeedsAndStopAndStart) {
  const auto world = TestWorld();
  TargetSimulation sim(world, {}, 5);
  std::map<int, int> stopped_steps, moving_steps;
  double max_vehicle_speed = 0, max_person_speed = 0;
  for (int step = 0; step < 25 * 90; ++step) {
    sim.Step(0.04);
    for (const Target& t : sim.targets()) {
      const double speed = t.velocity.norm();
      if (t.target_class == TargetClass::kPerson) {
        max_person_speed = std::max(max_person_speed, speed);
        continue;
      }
      max_vehicle_speed = std::max(max_vehicle_speed, speed);
      ASSERT_LT(OffRoad(*world, t.position), 0.5)
          << "vehicle " << static_cast<int>(t.id) << " left the road at " << t.position.transpose();
      (speed < 0.05 ? stopped_steps : moving_steps)[static_cast<int>(t.id)]++;
    }
  }
  EXPECT_LT(max_vehicle_speed, 14.5);
  EXPECT_GT(max_vehicle_speed, 8.0);
  EXPECT_LT(max_person_speed, 1.8);
  int stop_and_go = 0;
  for (const auto& [id, n] : stopped_steps) stop_and_go += n > 25 && moving_steps[id] > 25;
  EXPECT_GE(stop_and_go, 5) << "vehicles should stop for a while and drive on";
}

TEST(TargetsTest, TrafficGoesClockwiseRoundTheRoundabout) {
  const auto world = TestWorld();
  TargetSimulation sim(world, {}, 2);
  const Eigen::Vector2d centre = world->nodes[world->roundabout_node].position;
  int on_ring = 0, clockwise = 0;
  for (int step = 0; step < 25 * 120; ++step) {
    sim.Step(0.04);
    for (const Target& t : sim.targets()) {
      const Eigen::Vector2d r = t.position - centre;
      if (t.target_class == TargetClass::kPerson || r.norm() > 15 || t.velocity.norm() < 1)
        continue;
      ++on_ring;
      clockwise += r.x() * t.velocity.y() - r.y() * t.velocity.x() < 0;
    }
  }
  EXPECT_GT(on_ring, 50);
  EXPECT_GT(clockwise, 0.95 * on_ring);
}

TEST(TargetsTest, Deterministic) {
  TargetSimulation a(TestWorld(), {}, 9), b(TestWorld(), {}, 9), c(TestWorld(), {}, 10);
  for (int step = 0; step < 500; ++step) a.Step(0.04), b.Step(0.04), c.Step(0.04);
  ASSERT_EQ(a.targets().size(), b.targets().size());
  bool any_different = false;
  for (size_t k = 0; k < a.targets().size(); ++k) {
    EXPECT_EQ(a.targets()[k].position, b.targets()[k].position);
    any_different |= a.targets()[k].position != c.targets()[k].position;
  }
  EXPECT_TRUE(any_different);
}

TEST(TargetsTest, CountsAndClasses) {
  TargetOptions options;
  options.cars = 3, options.vans = 2, options.people = 4;
  TargetSimulation sim(TestWorld(), options, 1);
  std::map<TargetClass, int> count;
  for (const Target& t : sim.targets()) count[t.target_class]++;
  EXPECT_EQ(count[TargetClass::kCar], 3);
  EXPECT_EQ(count[TargetClass::kVan], 2);
  EXPECT_EQ(count[TargetClass::kPerson], 4);
  options.cars = -1;
  EXPECT_FALSE(options.Validate().ok());
}

}  // namespace
}  // namespace saker::sim

namespace saker::sim {
namespace {

// How many times each vehicle comes to a stop (from moving) in `seconds`.
double StopsPerVehicleMinute(const TargetOptions& options, double seconds) {
  TargetSimulation sim(TestWorld(), options, 7);
  std::map<int, bool> was_stopped;
  int stops = 0, vehicles = 0;
  for (int step = 0; step < static_cast<int>(seconds / 0.04); ++step) {
    sim.Step(0.04);
    for (const Target& t : sim.targets()) {
      if (t.target_class == TargetClass::kPerson) continue;
      const bool stopped = t.velocity.norm() < 0.05;
      if (stopped && was_stopped.count(static_cast<int>(t.id)) &&
          !was_stopped[static_cast<int>(t.id)])
        ++stops;
      was_stopped[static_cast<int>(t.id)] = stopped;
    }
  }
  for (const Target& t : sim.targets()) vehicles += t.target_class != TargetClass::kPerson;
  return stops / static_cast<double>(vehicles) / (seconds / 60);
}

TEST(HarderTrafficTest, StopAndGoStopsMoreOften) {
  TargetOptions normal, stop_and_go;
  stop_and_go.stop_and_go = true;
  const double usual = StopsPerVehicleMinute(normal, 120);
  const double often = StopsPerVehicleMinute(stop_and_go, 120);
  EXPECT_GT(often, 2.0 * usual) << usual << " against " << often;
  EXPECT_GT(often, 2.0);
}

TEST(HarderTrafficTest, SlowWalkersAndGroups) {
  TargetOptions options;
  options.cars = options.vans = 0;
  options.people = 12;
  options.group_size = 3;
  options.slow_walker_fraction = 1.0;
  TargetSimulation sim(TestWorld(), options, 3);
  double fastest = 0, widest_group = 0;
  for (int step = 0; step < 25 * 60; ++step) {
    sim.Step(0.04);
    const std::vector<Target>& people = sim.targets();
    ASSERT_EQ(people.size(), 12u);
    for (size_t k = 0; k < people.size(); ++k) {
      fastest = std::max(fastest, people[k].velocity.norm());
      if (k % 3 != 0) {
        widest_group =
            std::max(widest_group, (people[k].position - people[k - k % 3].position).norm());
      }
    }
  }
  EXPECT_LE(fastest, 0.61) << "every leader dawdles, and the groups keep their pace";
  EXPECT_GT(fastest, 0.35);
  EXPECT_LT(widest_group, 3.5) << "a group walks together";
  TargetOptions bad;
  bad.group_size = 0;
  EXPECT_FALSE(bad.Validate().ok());
  bad = {};
  bad.slow_walker_fraction = 1.5;
  EXPECT_FALSE(bad.Validate().ok());
}

}  // namespace
}  // namespace saker::sim
