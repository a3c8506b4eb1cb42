#pragma once

// The procedural world of the simulator: a small town around a roundabout, in open country.
//
// The world is a vector description (roads, buildings, car parks, trees, fields...) in the ground
// frame of ground.h, generated deterministically from a seed. ProceduralGround (world_raster.h)
// turns it into imagery; targets.h drives vehicles and people over its roads and footpaths.
//
// Layout, so that the paper's real-data case can be flown: a roundabout at the ground origin,
// and a closed road loop of about 1 km that leaves the roundabout and comes back to it
// (World::road_loop). Streets cross the loop's interior and run out of it with houses along them;
// a park with footpaths, shops with flat roofs and car parks sit inside; main roads leave the
// roundabout for the countryside, which is fields with hedges and trees up to the world's extent.

#include "core/util/status.h"

#include <Eigen/Core>
#include <opencv2/core/types.hpp>

#include <cstdint>
#include <vector>

namespace saker::sim {

using Polyline = std::vector<Eigen::Vector2d>;

enum class RoadClass { kMain, kStreet, kCountry };

struct Road {
  Polyline centreline;  // from node `from` to node `to`
  double width_m = 7;
  RoadClass road_class = RoadClass::kStreet;
  int from = -1;  // RoadNode indices
  int to = -1;
};

struct RoadNode {
  Eigen::Vector2d position{0, 0};
  double roundabout_radius_m = 0;  // > 0: a roundabout (outer kerb radius); 0: plain junction
  std::vector<int> roads;          // indices of the roads that start or end here
};

// A rectangle on the ground: centre, size along its own x (length) and y (width) axes, and the
// direction of its x axis in degrees anticlockwise from east.
struct OrientedBox {
  Eigen::Vector2d centre{0, 0};
  Eigen::Vector2d size{1, 1};
  double angle_deg = 0;
  std::vector<Eigen::Vector2d> Corners() const;  // 4 corners, counter-clockwise
};

struct Building {
  OrientedBox footprint;
  double height_m = 7;
  cv::Scalar roof_bgr;
  bool gabled = true;  // ridge along the footprint's x axis; false: flat roof
};

// A vehicle's shape and paint (parked cars and moving targets share it).
struct VehicleLook {
  double length_m = 4.5;
  double width_m = 1.8;
  cv::Scalar body_bgr{200, 200, 200};
  bool van = false;
};

class Random;  // random.h

// A car's or van's size and paint, drawn from the simulator's palette (parked and moving
// vehicles alike).
VehicleLook RandomVehicleLook(Random& random, bool van);

struct ParkedVehicle {
  Eigen::Vector2d position{0, 0};
  double heading_deg = 0;  // clockwise from north
  VehicleLook look;
};

struct Tree {
  Eigen::Vector2d centre{0, 0};
  double radius_m = 3;
};

enum class Crop { kPasture, kStripes, kPloughed, kStubble };

struct Field {
  Polyline polygon;  // convex quadrilateral
  Crop crop = Crop::kPasture;
  cv::Scalar bgr;
  double stripe_angle_deg = 0;  // drill lines of kStripes / furrows of kPloughed
};

struct WorldOptions {
  uint64_t seed = 1;
  double loop_length_m = 1000;  // length of the road loop through the roundabout
  Status Validate() const;
};

struct World {
  uint64_t seed = 0;
  cv::Rect2d extent_m;                  // ground area the world covers (x, y = west, south corner)
  Eigen::Vector2d sun_direction{0, 1};  // unit vector on the ground pointing towards the sun
  double shadow_length_per_m = 0.8;     // shadow length per metre of object height

  std::vector<RoadNode> nodes;
  std::vector<Road> roads;
  int roundabout_node = -1;
  Polyline road_loop;  // closed: starts and ends at the roundabout centre
  Eigen::Vector2d town_centre{0, 0};

  std::vector<Polyline> footpaths;  // 2 m wide paths in the park and between streets
  std::vector<Building> buildings;
  std::vector<OrientedBox> car_parks;
  std::vector<ParkedVehicle> parked;
  std::vector<Tree> trees;
  std::vector<Field> fields;
  std::vector<Polyline> hedges;
  std::vector<Eigen::Vector2d> park_boundary;  // polygon of the town park (grass)
};

// Generates the world covering `extent_m` (the town sits around the ground origin; pass an extent
// that covers the flight). Deterministic: the same options and extent give the same world.
StatusOr<World> GenerateWorld(const WorldOptions& options, const cv::Rect2d& extent_m);

// Length of a polyline, and the distance from a point to it.
double PolylineLength(const Polyline& line);
double DistanceToPolyline(const Eigen::Vector2d& point, const Polyline& line);

}  // namespace saker::sim
