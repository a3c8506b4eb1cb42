#include "core/sim/targets.h"

#include "core/sim/random.h"
#include "core/sim/world_raster.h"
#include "core/util/check.h"

#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <limits>

namespace saker::sim {
namespace {

using Eigen::Vector2d;

constexpr double kRadToDeg = 180.0 / M_PI;

double HeadingOf(const Vector2d& direction) {
  return std::atan2(direction.x(), direction.y()) * kRadToDeg;
}

// A path made of points, followed by arc length; vehicles extend theirs as they drive.
class Path {
 public:
  void Append(const Vector2d& p) {
    if (!points_.empty()) {
      const double step = (p - points_.back()).norm();
      if (step < 0.05) return;
      cumulative_.push_back(cumulative_.back() + step);
    } else {
      cumulative_.push_back(0);
    }
    points_.push_back(p);
  }
  double length() const { return cumulative_.empty() ? 0 : cumulative_.back(); }
  size_t size() const { return points_.size(); }
  const Vector2d& point(size_t i) const { return points_[i]; }
  double distance(size_t i) const { return cumulative_[i]; }

  // The segment index containing arc length s (s clamped to the path).
  size_t SegmentAt(double s) const {
    const auto it = std::upper_bound(cumulative_.begin(), cumulative_.end(), s);
    const size_t i =
        it == cumulative_.begin() ? 0 : static_cast<size_t>(it - cumulative_.begin()) - 1;
    return std::min(i, points_.size() - 2);
  }
  Vector2d PointAt(double s) const {
    const size_t i = SegmentAt(s);
    const double seg = cumulative_[i + 1] - cumulative_[i];
    const double t = seg > 0 ? std::clamp((s - cumulative_[i]) / seg, 0.0, 1.0) : 0.0;
    return points_[i] + t * (points_[i + 1] - points_[i]);
  }
  Vector2d DirectionAt(double s) const {
    const size_t i = SegmentAt(s);
    return (points_[i + 1] - points_[i]).normalized();
  }
  // Turning at vertex i (radians), for the speed a bend allows.
  double TurnAt(size_t i) const {
    if (i == 0 || i + 1 >= points_.size()) return 0;
    const Vector2d a = (points_[i] - points_[i - 1]).normalized();
    const Vector2d b = (points_[i + 1] - points_[i]).normalized();
    return std::acos(std::clamp(a.dot(b), -1.0, 1.0));
  }
  // Drops the points more than `keep` metres behind arc length `s`; returns the arc length
  // removed, so callers can shift their own positions.
  double TrimBefore(double s, double keep) {
    size_t drop = 0;
    while (drop + 2 < points_.size() && cumulative_[drop + 1] < s - keep) ++drop;
    if (drop == 0) return 0;
    const double removed = cumulative_[drop];
    points_.erase(points_.begin(), points_.begin() + static_cast<long>(drop));
    cumulative_.erase(cumulative_.begin(), cumulative_.begin() + static_cast<long>(drop));
    for (double& c : cumulative_) c -= removed;
    return removed;
  }

 private:
  std::vector<Vector2d> points_;
  std::vector<double> cumulative_;
};

// The road polyline in the direction of travel, moved to the left-hand lane.
Polyline LaneOf(const Road& road, bool forward) {
  Polyline line = road.centreline;
  if (!forward) std::reverse(line.begin(), line.end());
  const double offset = road.width_m / 4;
  Polyline lane;
  for (size_t i = 0; i < line.size(); ++i) {
    const Vector2d before = line[i] - line[i == 0 ? 0 : i - 1];
    const Vector2d after = line[std::min(i + 1, line.size() - 1)] - line[i];
    Vector2d d = (before.normalized() + after.normalized());
    if (before.norm() < 1e-9) d = after.normalized();
    if (after.norm() < 1e-9) d = before.normalized();
    d.normalize();
    lane.push_back(line[i] + Vector2d(-d.y(), d.x()) * offset);
  }
  return lane;
}

}  // namespace

const char* TargetClassName(TargetClass target_class) {
  switch (target_class) {
    case TargetClass::kCar:
      return "car";
    case TargetClass::kVan:
      return "van";
    case TargetClass::kPerson:
      return "person";
  }
  return "unknown";
}

Status TargetOptions::Validate() const {
  const auto check = [](int n, const char* what) -> Status {
    if (n < 0 || n > 2000) {
      return InvalidArgumentError(std::string("targets: the number of ") + what +
                                  " must be between 0 and 2000, got " + std::to_string(n));
    }
    return Status::Ok();
  };
  SAKER_RETURN_IF_ERROR(check(cars, "cars"));
  SAKER_RETURN_IF_ERROR(check(vans, "vans"));
  if (!(slow_walker_fraction >= 0 && slow_walker_fraction <= 1)) {
    return InvalidArgumentError("targets: the fraction of slow walkers must be in [0, 1]");
  }
  if (group_size < 1 || group_size > 10) {
    return InvalidArgumentError("targets: groups of walkers must have 1 to 10 people");
  }
  return check(people, "people");
}

double Target::length_m() const {
  return target_class == TargetClass::kPerson ? 0.35 : look.length_m;
}
double Target::width_m() const {
  return target_class == TargetClass::kPerson ? 0.55 : look.width_m;
}

struct TargetSimulation::Impl {
  struct Mover {
    Path path;
    double s = 0;      // arc length along path
    double speed = 0;  // m/s
    double cruise = 10;
    // Where the route continues: the road being driven and the node it arrives at.
    int road = -1;
    int arrival_node = -1;
    bool follows_loop = false;
    // People: walking back and forth on a footpath.
    int footpath = -1;
    int direction = 1;
    double lateral = 0;
    // Stop-and-start.
    double next_stop_s = 0;  // time of the next stop
    double stopped_until_s = -1;
    Random random{0};
  };

  std::shared_ptr<const World> world;
  std::vector<Target> targets;
  std::vector<Mover> movers;
  double time_s = 0;
  bool stop_and_go = false;  // TargetOptions::stop_and_go

  // Chooses the road to take at `node` after arriving on `from_road`.
  int NextRoad(Mover& m, int node, int from_road) {
    const RoadNode& n = world->nodes[node];
    if (m.follows_loop) {
      // The road that carries on along the loop, in its direction of travel.
      int best = -1;
      double best_score = -1e18;
      for (int r : n.roads) {
        if (r == from_road) continue;
        const Road& road = world->roads[r];
        const Vector2d mid = road.centreline[road.centreline.size() / 2];
        if (DistanceToPolyline(mid, world->road_loop) > 2.0) continue;
        const Polyline lane = LaneOf(road, road.from == node);
        const Vector2d out = (lane[std::min<size_t>(3, lane.size() - 1)] - lane[0]).normalized();
        const Polyline& loop = world->road_loop;
        size_t nearest = 0;
        for (size_t i = 0; i < loop.size(); ++i) {
          if ((loop[i] - n.position).squaredNorm() < (loop[nearest] - n.position).squaredNorm())
            nearest = i;
        }
        const size_t ahead = std::min(nearest + 1, loop.size() - 1);
        const Vector2d tangent = (loop[ahead] - loop[ahead - 1]).normalized();
        const double score = out.dot(tangent);
        if (score > best_score) best_score = score, best = r;
      }
      if (best >= 0) return best;
    }
    std::vector<int> options;
    std::vector<double> weights;
    for (int r : n.roads) {
      if (r == from_road && n.roads.size() > 1) continue;
      options.push_back(r);
      weights.push_back(world->roads[r].road_class == RoadClass::kCountry ? 0.25 : 1.0);
    }
    double total = 0;
    for (double w : weights) total += w;
    double pick = m.random.Uniform(0, total);
    for (size_t i = 0; i < options.size(); ++i) {
      pick -= weights[i];
      if (pick <= 0) return options[i];
    }
    return options.back();
  }

  // The lane without its points inside a roundabout at either end (the ring replaces them).
  Polyline TrimmedLane(const Polyline& lane, int start_node, int end_node) const {
    Polyline kept;
    for (const Vector2d& p : lane) {
      bool inside = false;
      for (int node : {start_node, end_node}) {
        const RoadNode& n = world->nodes[node];
        inside |= n.roundabout_radius_m > 0 && (p - n.position).norm() < n.roundabout_radius_m + 2;
      }
      if (!inside) kept.push_back(p);
    }
    return kept;
  }

  // Appends the next road of the route, and the way round the roundabout before it, if any.
  void ExtendRoute(Mover& m) {
    const int node = m.arrival_node;
    const RoadNode& n = world->nodes[node];
    const int next = NextRoad(m, node, m.road);
    const Road& road = world->roads[next];
    const bool forward = road.from == node;
    const int far = forward ? road.to : road.from;
    const Polyline lane = TrimmedLane(LaneOf(road, forward), node, far);
    if (n.roundabout_radius_m > 0 && !lane.empty()) {
      // Circulate clockwise on the ring from where the car arrives to where it leaves.
      const double ring = n.roundabout_radius_m - 2.5;
      const Vector2d entry = m.path.point(m.path.size() - 1) - n.position;
      const Vector2d exit = lane.front() - n.position;
      const double a_in = std::atan2(entry.y(), entry.x());
      const double a_out = std::atan2(exit.y(), exit.x());
      double sweep = a_in - a_out;
      while (sweep <= 0.2) sweep += 2 * M_PI;
      while (sweep > 2 * M_PI + 0.2) sweep -= 2 * M_PI;
      const int steps = std::max(4, static_cast<int>(sweep * ring / 2.0));
      for (int k = 0; k <= steps; ++k) {
        const double a = a_in - sweep * k / steps;
        m.path.Append(n.position + ring * Vector2d(std::cos(a), std::sin(a)));
      }
    }
    for (const Vector2d& p : lane) m.path.Append(p);
    m.road = next;
    m.arrival_node = far;
  }

  Impl(std::shared_ptr<const World> w, const TargetOptions& options, uint64_t seed)
      : world(std::move(w)), stop_and_go(options.stop_and_go) {
    Random random(HashCombine(seed, 0x7A56u));
    int next_id = 1;
    // Vehicles start on town roads, spread by length.
    std::vector<int> town_roads;
    std::vector<double> cumulative;
    double total = 0;
    for (size_t r = 0; r < world->roads.size(); ++r) {
      if (world->roads[r].road_class == RoadClass::kCountry) continue;
      total += PolylineLength(world->roads[r].centreline);
      town_roads.push_back(static_cast<int>(r));
      cumulative.push_back(total);
    }
    const int vehicles = options.cars + options.vans;
    for (int k = 0; k < vehicles && !town_roads.empty(); ++k) {
      Target t;
      t.id = TargetId{next_id++};
      t.target_class = k < options.cars ? TargetClass::kCar : TargetClass::kVan;
      Mover m;
      m.random = Random(HashCombine(seed, static_cast<uint64_t>(k) + 1000));
      t.look = RandomVehicleLook(m.random, t.target_class == TargetClass::kVan);
      m.cruise = t.look.van ? m.random.Uniform(8, 12) : m.random.Uniform(9, 14);
      m.follows_loop = k % 4 == 0 && !world->road_loop.empty();
      int road = town_roads[0];
      double along = 0;
      if (m.follows_loop) {
        // Start somewhere on the loop.
        std::vector<int> loop_roads;
        for (int r : town_roads) {
          const Polyline& line = world->roads[r].centreline;
          if (DistanceToPolyline(line[line.size() / 2], world->road_loop) < 2.0)
            loop_roads.push_back(r);
        }
        if (!loop_roads.empty())
          road = loop_roads[m.random.UniformInt(0, static_cast<int>(loop_roads.size()) - 1)];
      } else {
        const double pick = random.Uniform(0, total);
        road = town_roads[std::lower_bound(cumulative.begin(), cumulative.end(), pick) -
                          cumulative.begin()];
      }
      const Road& r = world->roads[road];
      bool forward = m.random.Bernoulli(0.5);
      if (m.follows_loop) {
        // Drive the loop in its own direction: from the roundabout round and back.
        const Polyline& loop = world->road_loop;
        size_t nearest = 0;
        for (size_t i = 0; i < loop.size(); ++i) {
          if ((loop[i] - r.centreline.front()).squaredNorm() <
              (loop[nearest] - r.centreline.front()).squaredNorm()) {
            nearest = i;
          }
        }
        const size_t ahead = std::min(nearest + 1, loop.size() - 1);
        const Vector2d tangent = loop[ahead] - loop[ahead - 1];
        forward = (r.centreline[1] - r.centreline[0]).dot(tangent) > 0;
      }
      for (const Vector2d& p : TrimmedLane(LaneOf(r, forward), r.from, r.to)) m.path.Append(p);
      m.road = road;
      m.arrival_node = forward ? r.to : r.from;
      along = m.random.Uniform(0, m.path.length() * 0.8);
      m.s = along;
      m.speed = m.cruise * m.random.Uniform(0.5, 1.0);
      m.next_stop_s = options.stop_and_go ? m.random.Uniform(2, 20) : m.random.Uniform(5, 60);
      targets.push_back(t);
      movers.push_back(std::move(m));
      while (movers.back().path.length() < movers.back().s + 150) ExtendRoute(movers.back());
    }
    // People on footpaths.
    for (int k = 0; k < options.people && !world->footpaths.empty(); ++k) {
      Target t;
      t.id = TargetId{next_id++};
      t.target_class = TargetClass::kPerson;
      Mover m;
      m.random = Random(HashCombine(seed, static_cast<uint64_t>(k) + 500000));
      static const cv::Scalar kClothes[] = {{40, 40, 160},   {150, 60, 30},  {30, 30, 30},
                                            {200, 200, 200}, {40, 140, 200}, {120, 40, 120}};
      t.clothes_bgr = kClothes[m.random.UniformInt(0, 5)];
      m.footpath = m.random.UniformInt(0, static_cast<int>(world->footpaths.size()) - 1);
      for (const Vector2d& p : world->footpaths[m.footpath]) m.path.Append(p);
      m.s = m.random.Uniform(0, m.path.length());
      m.direction = m.random.Bernoulli(0.5) ? 1 : -1;
      m.cruise = m.random.Uniform(1.1, 1.6);
      m.speed = m.cruise;
      m.lateral = m.random.Uniform(-0.6, 0.6);
      m.next_stop_s = m.random.Uniform(5, 40);
      const int place = k % options.group_size;
      if (place > 0) {
        // A member of the group of the person `place` before: the same path, pace and pauses
        // (the same random state), a little behind and beside.
        const Mover& leader = movers[movers.size() - static_cast<size_t>(place)];
        m.random = leader.random;
        m.footpath = leader.footpath;
        m.path = leader.path;
        m.direction = leader.direction;
        m.cruise = m.speed = leader.cruise;
        m.next_stop_s = leader.next_stop_s;
        m.s = std::clamp(leader.s - 0.8 * m.direction * place, 0.0, m.path.length());
        m.lateral = leader.lateral + (place % 2 == 1 ? 0.7 : -0.7) * ((place + 1) / 2);
      } else if (options.slow_walker_fraction > 0 &&
                 Random(HashCombine(seed, static_cast<uint64_t>(k) + 900000))
                     .Bernoulli(options.slow_walker_fraction)) {
        m.cruise = m.speed = m.random.Uniform(0.4, 0.6);
      }
      targets.push_back(t);
      movers.push_back(std::move(m));
    }
    UpdateTargets(0);
  }

  // The speed a vehicle may have now: its cruise speed, the bends ahead, the vehicle ahead.
  double DesiredSpeed(size_t k) const {
    const Mover& m = movers[k];
    if (time_s < m.stopped_until_s) return 0;
    double desired = m.cruise;
    const double braking = 2.5, lateral = 2.0;
    for (size_t i = m.path.SegmentAt(m.s) + 1; i + 1 < m.path.size(); ++i) {
      const double distance = m.path.distance(i) - m.s;
      if (distance > 60) break;
      const double turn = m.path.TurnAt(i);
      if (turn < 1e-3) continue;
      const double seg = 0.5 * (m.path.distance(i + 1) - m.path.distance(i - 1));
      const double radius = seg / turn;
      const double limit = std::sqrt(lateral * radius);
      desired = std::min(desired, std::sqrt(limit * limit + 2 * braking * std::max(0.0, distance)));
    }
    // Keep a gap to the vehicle ahead in the same direction.
    const Target& self = targets[k];
    const Vector2d forward = m.path.DirectionAt(m.s);
    for (size_t j = 0; j < targets.size(); ++j) {
      if (j == k || targets[j].target_class == TargetClass::kPerson) continue;
      const Vector2d d = targets[j].position - self.position;
      const double ahead = d.dot(forward);
      const double across = std::abs(d.x() * forward.y() - d.y() * forward.x());
      if (ahead <= 0 || ahead > 30 || across > 1.6) continue;
      const double gap = ahead - 0.5 * (self.length_m() + targets[j].length_m()) - 2.5;
      desired = std::min(desired, std::max(0.0, targets[j].velocity.norm() + 0.6 * gap));
      if (gap < 0.5) desired = 0;
    }
    return desired;
  }

  void Step(double dt) {
    time_s += dt;
    std::vector<double> desired(movers.size());
    for (size_t k = 0; k < movers.size(); ++k) {
      desired[k] = targets[k].target_class == TargetClass::kPerson
                       ? (time_s < movers[k].stopped_until_s ? 0 : movers[k].cruise)
                       : DesiredSpeed(k);
    }
    for (size_t k = 0; k < movers.size(); ++k) {
      Mover& m = movers[k];
      if (time_s >= m.next_stop_s && m.stopped_until_s < m.next_stop_s) {
        const bool person = targets[k].target_class == TargetClass::kPerson;
        if (!person && stop_and_go) {
          m.stopped_until_s = time_s + m.random.Uniform(2, 8);
          m.next_stop_s = m.stopped_until_s + m.random.Uniform(5, 20);
        } else {
          m.stopped_until_s = time_s + (person ? m.random.Uniform(2, 8) : m.random.Uniform(2, 10));
          m.next_stop_s =
              m.stopped_until_s + (person ? m.random.Uniform(10, 50) : m.random.Uniform(20, 70));
        }
      }
      const double accel = targets[k].target_class == TargetClass::kPerson ? 1.0 : 1.6;
      const double decel = targets[k].target_class == TargetClass::kPerson ? 2.0 : 3.0;
      m.speed = std::clamp(desired[k], m.speed - decel * dt, m.speed + accel * dt);
      m.speed = std::max(0.0, m.speed);
      if (targets[k].target_class == TargetClass::kPerson) {
        m.s += m.direction * m.speed * dt;
        if (m.s > m.path.length()) m.s = 2 * m.path.length() - m.s, m.direction = -1;
        if (m.s < 0) m.s = -m.s, m.direction = 1;
      } else {
        m.s += m.speed * dt;
        while (m.path.length() < m.s + 150) ExtendRoute(m);
        m.s -= m.path.TrimBefore(m.s, 50);
      }
    }
    UpdateTargets(dt);
  }

  void UpdateTargets(double dt) {
    for (size_t k = 0; k < movers.size(); ++k) {
      const Mover& m = movers[k];
      Target& t = targets[k];
      // Direction over a short stretch, so heading and the walkers' sideways offset turn
      // smoothly at path vertices instead of jumping.
      const double reach = t.target_class == TargetClass::kPerson ? 1.0 : 1.5;
      Vector2d direction = m.path.PointAt(m.s + reach) - m.path.PointAt(m.s - reach);
      direction = direction.norm() > 1e-6 ? static_cast<Vector2d>(direction.normalized())
                                          : m.path.DirectionAt(m.s);
      Vector2d position = m.path.PointAt(m.s);
      if (t.target_class == TargetClass::kPerson) {
        position += Vector2d(-direction.y(), direction.x()) * m.lateral;
        direction *= m.direction;
      }
      const Vector2d previous = t.position;
      t.position = position;
      t.velocity = dt > 0 ? Vector2d((position - previous) / dt) : Vector2d(direction * m.speed);
      t.heading_deg = HeadingOf(direction);
    }
  }
};

TargetSimulation::TargetSimulation(std::shared_ptr<const World> world, const TargetOptions& options,
                                   uint64_t seed)
    : impl_(std::make_unique<Impl>(std::move(world), options, seed)) {}
TargetSimulation::~TargetSimulation() = default;
TargetSimulation::TargetSimulation(TargetSimulation&&) noexcept = default;
TargetSimulation& TargetSimulation::operator=(TargetSimulation&&) noexcept = default;

void TargetSimulation::Step(double dt_s) { impl_->Step(dt_s); }
double TargetSimulation::time_s() const { return impl_->time_s; }
const std::vector<Target>& TargetSimulation::targets() const { return impl_->targets; }

Eigen::Vector2d TargetSimulation::shadow_per_m() const { return ShadowPerMetre(*impl_->world); }

void TargetSimulation::Draw(const Eigen::Matrix3d& image_from_ground, cv::Mat* image) const {
  DrawTargets(impl_->targets, shadow_per_m(), image_from_ground, image);
}

void DrawTargets(const std::vector<Target>& targets, const Vector2d& shadow_per_m,
                 const Eigen::Matrix3d& image_from_ground, cv::Mat* image) {
  // The sign of the third coordinate of the ground points in front of the camera: that of the
  // point seen at the image centre (image_from_ground is known up to scale, its sign too).
  const Eigen::Vector3d centre =
      image_from_ground.inverse() * Eigen::Vector3d(0.5 * image->cols, 0.5 * image->rows, 1);
  const double front =
      (image_from_ground * Eigen::Vector3d(centre.x() / centre.z(), centre.y() / centre.z(), 1))
                  .z() >= 0
          ? 1
          : -1;
  for (const Target& t : targets) {
    // Only targets in front of the camera and near the frame: behind it a target would be drawn
    // mirrored, and one straddling the camera's principal plane as a polygon across the frame.
    const Eigen::Vector3d q =
        image_from_ground * Eigen::Vector3d(t.position.x(), t.position.y(), 1);
    if (!(front * q.z() > 0)) continue;
    const double x = q.x() / q.z(), y = q.y() / q.z();
    if (x < -image->cols || x > 2.0 * image->cols || y < -image->rows || y > 2.0 * image->rows) {
      continue;
    }
    if (t.target_class == TargetClass::kPerson) {
      DrawPerson(image_from_ground, t.position, t.heading_deg, t.clothes_bgr, shadow_per_m, image);
    } else {
      DrawVehicle(image_from_ground, t.position, t.heading_deg, t.look, shadow_per_m, image);
    }
  }
}

}  // namespace saker::sim
