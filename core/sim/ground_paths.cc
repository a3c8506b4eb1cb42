#include "core/sim/ground_paths.h"

#include "core/sim/random.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <string>

namespace saker::sim {
namespace {

using Eigen::Vector2d;

constexpr double kPi = 3.14159265358979323846;
constexpr double kMaxDistanceFromOriginM = 50000;
constexpr double kJunctionToleranceM = 1.0;

// Points every `step_m` along the line (targets follow polylines; long straight segments would
// leave their lane offsets and bends coarse).
Polyline Densify(const Polyline& line, double step_m) {
  Polyline out;
  for (size_t i = 0; i + 1 < line.size(); ++i) {
    const Vector2d a = line[i], b = line[i + 1];
    const int n = std::max(1, static_cast<int>(std::ceil((b - a).norm() / step_m)));
    for (int k = 0; k < n; ++k) out.push_back(a + (b - a) * (static_cast<double>(k) / n));
  }
  out.push_back(line.back());
  return out;
}

// The part of the line through `p` in direction `d` inside `box` (Liang-Barsky), or empty.
Polyline ClipLine(const Vector2d& p, const Vector2d& d, const cv::Rect2d& box) {
  double t0 = -1e12, t1 = 1e12;
  const double lo[2] = {box.x, box.y}, hi[2] = {box.x + box.width, box.y + box.height};
  for (int axis = 0; axis < 2; ++axis) {
    if (std::abs(d[axis]) < 1e-12) {
      if (p[axis] < lo[axis] || p[axis] > hi[axis]) return {};
      continue;
    }
    double a = (lo[axis] - p[axis]) / d[axis], b = (hi[axis] - p[axis]) / d[axis];
    if (a > b) std::swap(a, b);
    t0 = std::max(t0, a), t1 = std::min(t1, b);
  }
  if (t1 - t0 < 1.0) return {};
  return {p + t0 * d, p + t1 * d};
}

// Adds `line` as a road between two nodes, reusing a node within kJunctionToleranceM of an end.
void AddRoad(const Polyline& line, World* world) {
  const auto node_at = [&](const Vector2d& p) {
    for (size_t i = 0; i < world->nodes.size(); ++i) {
      if ((world->nodes[i].position - p).norm() < kJunctionToleranceM) return static_cast<int>(i);
    }
    world->nodes.push_back({p, 0, {}});
    return static_cast<int>(world->nodes.size()) - 1;
  };
  Road road;
  road.centreline = Densify(line, 5.0);
  road.width_m = 7;
  road.road_class = RoadClass::kStreet;
  road.from = node_at(line.front());
  road.to = node_at(line.back());
  const int index = static_cast<int>(world->roads.size());
  world->nodes[static_cast<size_t>(road.from)].roads.push_back(index);
  if (road.to != road.from) world->nodes[static_cast<size_t>(road.to)].roads.push_back(index);
  world->roads.push_back(std::move(road));
}

void GeneratePaths(const cv::Rect2d& extent, uint64_t seed, World* world) {
  Random random(HashCombine(seed, 0x50415448u));
  const Vector2d centre(extent.x + extent.width / 2, extent.y + extent.height / 2);
  const cv::Rect2d inner(extent.x + 0.08 * extent.width, extent.y + 0.08 * extent.height,
                         0.84 * extent.width, 0.84 * extent.height);
  // Three straight roads across the ground through points near its middle.
  for (int k = 0; k < 3; ++k) {
    const Vector2d through(centre.x() + random.Uniform(-0.3, 0.3) * extent.width,
                           centre.y() + random.Uniform(-0.3, 0.3) * extent.height);
    const double angle = kPi * (k / 3.0 + random.Uniform(-0.1, 0.1));
    const Polyline line = ClipLine(through, Vector2d(std::cos(angle), std::sin(angle)), inner);
    if (line.size() == 2) AddRoad(line, world);
  }
  // A curved road: two thirds of a circle round the middle.
  const double radius = 0.3 * std::min(extent.width, extent.height);
  const double start = random.Uniform(0, 2 * kPi);
  Polyline arc;
  for (int k = 0; k <= 96; ++k) {
    const double a = start + (4.0 * kPi / 3.0) * k / 96;
    arc.push_back(centre + radius * Vector2d(std::cos(a), std::sin(a)));
  }
  AddRoad(arc, world);
  // Footpaths of 60 to 150 m near the middle.
  for (int k = 0; k < 4; ++k) {
    const Vector2d from(centre.x() + random.Uniform(-0.25, 0.25) * extent.width,
                        centre.y() + random.Uniform(-0.25, 0.25) * extent.height);
    const double angle = random.Uniform(0, 2 * kPi);
    const Vector2d to = from + random.Uniform(60, 150) * Vector2d(std::cos(angle), std::sin(angle));
    world->footpaths.push_back(Densify({from, to}, 5.0));
  }
}

// The lines of one GeoJSON geometry, in map metres.
Status ReadGeometry(const nlohmann::json& geometry, const geo::LocalTangentPlane& plane,
                    const std::string& where, std::vector<Polyline>* lines) {
  const std::string type = geometry.at("type").get<std::string>();
  std::vector<const nlohmann::json*> parts;
  const nlohmann::json& coordinates = geometry.at("coordinates");
  if (type == "LineString") {
    parts.push_back(&coordinates);
  } else if (type == "MultiLineString") {
    for (const nlohmann::json& part : coordinates) parts.push_back(&part);
  } else {
    return Status::Ok();  // points and polygons carry no paths
  }
  for (const nlohmann::json* part : parts) {
    Polyline line;
    for (const nlohmann::json& position : *part) {
      if (!position.is_array() || position.size() < 2 || !position[0].is_number() ||
          !position[1].is_number()) {
        return InvalidDataError(where + ": a position is not [longitude, latitude]");
      }
      const double lon = position[0].get<double>(), lat = position[1].get<double>();
      if (!(std::abs(lat) <= 90 && std::abs(lon) <= 180)) {
        return InvalidDataError(where + ": position [" + std::to_string(lon) + ", " +
                                std::to_string(lat) + "] is not a longitude and latitude");
      }
      const Vector2d p = plane.MapFromLatLon(lat, lon);
      if (!(p.norm() <= kMaxDistanceFromOriginM)) {
        return InvalidDataError(where +
                                ": a position lies more than 50 km from the ground origin "
                                "(--lat, --lon)");
      }
      if (line.empty() || (p - line.back()).norm() > 0.01) line.push_back(p);
    }
    if (line.size() < 2) return InvalidDataError(where + ": a line needs two distinct positions");
    lines->push_back(std::move(line));
  }
  return Status::Ok();
}

Status ReadGeoJson(const std::filesystem::path& path, const geo::LocalTangentPlane& plane,
                   World* world) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return NotFoundError("cannot open the paths file " + path.string());
  try {
    nlohmann::json j;
    in >> j;
    std::vector<std::pair<nlohmann::json, std::string>> features;  // geometry, kind
    const std::string type = j.at("type").get<std::string>();
    if (type == "FeatureCollection") {
      for (const nlohmann::json& f : j.at("features")) {
        const nlohmann::json properties = f.value("properties", nlohmann::json::object());
        features.emplace_back(f.at("geometry"),
                              properties.is_object() ? properties.value("kind", "road") : "road");
      }
    } else if (type == "Feature") {
      features.emplace_back(j.at("geometry"), "road");
    } else {
      features.emplace_back(j, "road");
    }
    for (size_t i = 0; i < features.size(); ++i) {
      if (features[i].first.is_null()) continue;
      std::vector<Polyline> lines;
      SAKER_RETURN_IF_ERROR(ReadGeometry(features[i].first, plane,
                                         path.string() + ": feature " + std::to_string(i), &lines));
      for (const Polyline& line : lines) {
        if (features[i].second == "footpath") {
          world->footpaths.push_back(Densify(line, 5.0));
        } else {
          AddRoad(line, world);
        }
      }
    }
  } catch (const nlohmann::json::exception& e) {
    return InvalidDataError(path.string() + ": not usable GeoJSON: " + e.what());
  }
  if (world->roads.empty() && world->footpaths.empty()) {
    return InvalidArgumentError(path.string() + ": holds no LineString to move targets along");
  }
  return Status::Ok();
}

}  // namespace

StatusOr<World> MakePathWorld(const GroundPathOptions& options, const cv::Rect2d& extent_m,
                              const geo::LocalTangentPlane& plane, uint64_t seed) {
  World world;
  world.seed = seed;
  world.extent_m = extent_m;
  world.town_centre = Vector2d(extent_m.x + extent_m.width / 2, extent_m.y + extent_m.height / 2);
  Random random(HashCombine(seed, 0x53554Eu));
  const double sun = random.Uniform(0, 2 * kPi);
  world.sun_direction = Vector2d(std::cos(sun), std::sin(sun));
  world.shadow_length_per_m = 0.8;
  if (!options.geojson.empty()) {
    SAKER_RETURN_IF_ERROR(ReadGeoJson(options.geojson, plane, &world));
  } else {
    GeneratePaths(extent_m, seed, &world);
  }
  return world;
}

}  // namespace saker::sim
