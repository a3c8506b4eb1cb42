#include "core/sim/world.h"

#include "core/sim/random.h"
#include "core/util/check.h"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <optional>

namespace saker::sim {
namespace {

using Eigen::Vector2d;

constexpr double kDegToRad = M_PI / 180.0;

// ---------------------------------------------------------------------------------------------
// Geometry helpers

double Cross(const Vector2d& a, const Vector2d& b) { return a.x() * b.y() - a.y() * b.x(); }

double DistanceToSegment(const Vector2d& p, const Vector2d& a, const Vector2d& b) {
  const Vector2d ab = b - a;
  const double len2 = ab.squaredNorm();
  const double t = len2 > 0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
  return (a + t * ab - p).norm();
}

// Where segments p0-p1 and q0-q1 cross (strictly inside both), as parameters along each.
std::optional<std::pair<double, double>> SegmentCrossing(const Vector2d& p0, const Vector2d& p1,
                                                         const Vector2d& q0, const Vector2d& q1) {
  const Vector2d r = p1 - p0;
  const Vector2d s = q1 - q0;
  const double denominator = Cross(r, s);
  if (std::abs(denominator) < 1e-12) return std::nullopt;
  const double t = Cross(q0 - p0, s) / denominator;
  const double u = Cross(q0 - p0, r) / denominator;
  if (t <= 1e-9 || t >= 1 - 1e-9 || u <= 1e-9 || u >= 1 - 1e-9) return std::nullopt;
  return std::make_pair(t, u);
}

// Resamples a polyline so that no segment is longer than `step` (keeps the original vertices).
Polyline Densify(const Polyline& line, double step) {
  Polyline out;
  for (size_t i = 0; i + 1 < line.size(); ++i) {
    const int n = std::max(1, static_cast<int>(std::ceil((line[i + 1] - line[i]).norm() / step)));
    for (int k = 0; k < n; ++k)
      out.push_back(line[i] + (line[i + 1] - line[i]) * (static_cast<double>(k) / n));
  }
  out.push_back(line.back());
  return out;
}

// A polyline from `start` heading along `direction` until it leaves `extent` (plus a margin).
Polyline RayToEdge(const Vector2d& start, const Vector2d& direction, const cv::Rect2d& extent) {
  const Vector2d d = direction.normalized();
  Polyline line{start};
  Vector2d p = start;
  const cv::Rect2d outer(extent.x - 100, extent.y - 100, extent.width + 200, extent.height + 200);
  while (outer.contains(cv::Point2d(p.x(), p.y()))) {
    p += 50.0 * d;
    line.push_back(p);
  }
  return line;
}

bool PointInPolygon(const Vector2d& p, const Polyline& polygon) {
  bool inside = false;
  for (size_t i = 0, j = polygon.size() - 1; i < polygon.size(); j = i++) {
    const Vector2d& a = polygon[i];
    const Vector2d& b = polygon[j];
    if ((a.y() > p.y()) != (b.y() > p.y()) &&
        p.x() < (b.x() - a.x()) * (p.y() - a.y()) / (b.y() - a.y()) + a.x()) {
      inside = !inside;
    }
  }
  return inside;
}

// ---------------------------------------------------------------------------------------------
// Occupancy of the town at 1 m, so houses keep off roads, parks and each other.

class Occupancy {
 public:
  explicit Occupancy(const cv::Rect2d& area)
      : area_(area),
        grid_(cv::Mat::zeros(static_cast<int>(area.height) + 1, static_cast<int>(area.width) + 1,
                             CV_8U)) {}

  void MarkPolyline(const Polyline& line, double width_m) {
    std::vector<cv::Point> points;
    for (const Vector2d& p : line) points.push_back(ToGrid(p));
    cv::polylines(grid_, points, false, cv::Scalar(255),
                  std::max(1, static_cast<int>(std::ceil(width_m))));
  }
  void MarkPolygon(const Polyline& polygon) {
    std::vector<cv::Point> points;
    for (const Vector2d& p : polygon) points.push_back(ToGrid(p));
    cv::fillPoly(grid_, std::vector<std::vector<cv::Point>>{points}, cv::Scalar(255));
  }
  // True when every metre of the polygon's bounding box that lies inside it is free.
  bool IsFree(const Polyline& polygon) const {
    double x0 = 1e18, y0 = 1e18, x1 = -1e18, y1 = -1e18;
    for (const Vector2d& p : polygon) {
      x0 = std::min(x0, p.x()), x1 = std::max(x1, p.x());
      y0 = std::min(y0, p.y()), y1 = std::max(y1, p.y());
    }
    for (double y = y0; y <= y1; y += 1.0) {
      for (double x = x0; x <= x1; x += 1.0) {
        const Vector2d p(x, y);
        if (!PointInPolygon(p, polygon)) continue;
        const cv::Point g = ToGrid(p);
        if (g.x < 0 || g.y < 0 || g.x >= grid_.cols || g.y >= grid_.rows) return false;
        if (grid_.at<uint8_t>(g)) return false;
      }
    }
    return true;
  }

 private:
  cv::Point ToGrid(const Vector2d& p) const {
    return {static_cast<int>(std::lround(p.x() - area_.x)),
            static_cast<int>(std::lround(area_.y + area_.height - p.y()))};
  }
  cv::Rect2d area_;
  cv::Mat grid_;
};

// The box grown by `margin` on every side.
OrientedBox Grown(const OrientedBox& box, double margin) {
  OrientedBox grown = box;
  grown.size += Vector2d(2 * margin, 2 * margin);
  return grown;
}

// ---------------------------------------------------------------------------------------------
// The road network: raw polylines are split wherever they cross and joined at shared nodes.

struct RawRoad {
  Polyline line;
  double width_m;
  RoadClass road_class;
};

class NetworkBuilder {
 public:
  void Add(Polyline line, double width_m, RoadClass road_class) {
    raw_.push_back({Densify(line, 10.0), width_m, road_class});
  }

  // Splits every road at every crossing, merges end points closer than 1.5 m into one node, and
  // drops the short stubs that street ends pushed a little past the road they meet leave behind.
  void Build(World* world) {
    struct Cut {
      size_t segment;
      double t;
    };
    std::vector<std::vector<Cut>> cuts(raw_.size());
    for (size_t a = 0; a < raw_.size(); ++a) {
      for (size_t b = a + 1; b < raw_.size(); ++b) {
        const Polyline& la = raw_[a].line;
        const Polyline& lb = raw_[b].line;
        for (size_t i = 0; i + 1 < la.size(); ++i) {
          for (size_t j = 0; j + 1 < lb.size(); ++j) {
            if (auto tu = SegmentCrossing(la[i], la[i + 1], lb[j], lb[j + 1])) {
              cuts[a].push_back({i, tu->first});
              cuts[b].push_back({j, tu->second});
            }
          }
        }
      }
    }
    for (size_t r = 0; r < raw_.size(); ++r) {
      std::sort(cuts[r].begin(), cuts[r].end(), [](const Cut& x, const Cut& y) {
        return x.segment != y.segment ? x.segment < y.segment : x.t < y.t;
      });
      const Polyline& line = raw_[r].line;
      Polyline piece{line.front()};
      size_t next_cut = 0;
      for (size_t i = 0; i + 1 < line.size(); ++i) {
        while (next_cut < cuts[r].size() && cuts[r][next_cut].segment == i) {
          const Vector2d p = line[i] + cuts[r][next_cut].t * (line[i + 1] - line[i]);
          piece.push_back(p);
          AddRoad(world, piece, raw_[r]);
          piece = {p};
          ++next_cut;
        }
        piece.push_back(line[i + 1]);
      }
      AddRoad(world, piece, raw_[r]);
    }
    RemoveStubs(world);
  }

 private:
  int NodeAt(World* world, const Vector2d& p) {
    for (size_t i = 0; i < world->nodes.size(); ++i) {
      if ((world->nodes[i].position - p).norm() < 1.5) return static_cast<int>(i);
    }
    world->nodes.push_back({p, 0.0, {}});
    return static_cast<int>(world->nodes.size()) - 1;
  }

  void AddRoad(World* world, const Polyline& piece, const RawRoad& raw) {
    if (piece.size() < 2 || PolylineLength(piece) < 1e-6) return;
    Road road{piece, raw.width_m, raw.road_class, NodeAt(world, piece.front()),
              NodeAt(world, piece.back())};
    road.centreline.front() = world->nodes[road.from].position;
    road.centreline.back() = world->nodes[road.to].position;
    world->roads.push_back(std::move(road));
  }

  static void RemoveStubs(World* world) {
    std::vector<int> degree(world->nodes.size(), 0);
    for (const Road& road : world->roads) ++degree[road.from], ++degree[road.to];
    std::vector<Road> kept;
    for (const Road& road : world->roads) {
      const bool dangling = degree[road.from] == 1 || degree[road.to] == 1;
      if (dangling && PolylineLength(road.centreline) < 3.0) continue;
      kept.push_back(road);
    }
    world->roads = std::move(kept);
    for (RoadNode& node : world->nodes) node.roads.clear();
    for (size_t i = 0; i < world->roads.size(); ++i) {
      world->nodes[world->roads[i].from].roads.push_back(static_cast<int>(i));
      if (world->roads[i].to != world->roads[i].from) {
        world->nodes[world->roads[i].to].roads.push_back(static_cast<int>(i));
      }
    }
  }

  std::vector<RawRoad> raw_;
};

// ---------------------------------------------------------------------------------------------
// Town layout

// The loop: a gently irregular oval whose westernmost point is the roundabout at the origin,
// scaled so that its length is `length_m`.
Polyline MakeLoop(double length_m, Random& random, double* semi_major, double* semi_minor) {
  const double w1 = random.Uniform(0, 2 * M_PI);
  const double w2 = random.Uniform(0, 2 * M_PI);
  const auto shape = [&](double a, double b) {
    Polyline loop;
    const int n = 240;
    for (int k = 0; k <= n; ++k) {
      const double phi = M_PI + 2 * M_PI * k / n;
      // The wobble vanishes at the roundabout (phi = pi) so the loop meets it head-on.
      const double s = std::sin((phi - M_PI) / 2);
      const double wobble =
          1 + s * s * (0.05 * std::sin(2 * phi + w1) + 0.035 * std::sin(3 * phi + w2));
      loop.emplace_back(a + a * std::cos(phi) * wobble, b * std::sin(phi) * wobble);
    }
    loop.back() = loop.front();
    return loop;
  };
  double a = length_m / 5.4, b = a / 1.45;
  for (int iteration = 0; iteration < 4; ++iteration) {
    const double scale = length_m / PolylineLength(shape(a, b));
    a *= scale, b *= scale;
  }
  *semi_major = a, *semi_minor = b;
  return shape(a, b);
}

// Where the vertical line x = `x` crosses the loop: the lowest and highest y.
std::pair<double, double> LoopSpanAt(const Polyline& loop, double x) {
  double lo = 1e18, hi = -1e18;
  for (size_t i = 0; i + 1 < loop.size(); ++i) {
    const Vector2d& p = loop[i];
    const Vector2d& q = loop[i + 1];
    if ((p.x() - x) * (q.x() - x) > 0 || p.x() == q.x()) continue;
    const double y = p.y() + (q.y() - p.y()) * (x - p.x()) / (q.x() - p.x());
    lo = std::min(lo, y), hi = std::max(hi, y);
  }
  return {lo, hi};
}

cv::Scalar RoofColour(Random& random) {
  static const cv::Scalar kRoofs[] = {
      {60, 80, 150},    // terracotta tiles
      {90, 88, 86},     // slate
      {50, 60, 95},     // brown tiles
      {58, 58, 120},    // dark red
      {120, 118, 112},  // grey concrete tiles
  };
  cv::Scalar c = kRoofs[random.UniformInt(0, 4)];
  const double shade = random.Uniform(0.85, 1.15);
  return c * shade;
}

// Houses along both sides of a street, and trees in their back gardens.
void LineStreetWithHouses(const Road& road, Occupancy& occupancy, Random& random, World* world) {
  const Polyline& line = road.centreline;
  for (int side : {-1, 1}) {
    double next = random.Uniform(5, 15);
    double travelled = 0;
    for (size_t i = 0; i + 1 < line.size(); ++i) {
      const Vector2d a = line[i], b = line[i + 1];
      const double length = (b - a).norm();
      const Vector2d along = (b - a) / length;
      const Vector2d normal(-along.y() * side, along.x() * side);
      while (next < travelled + length) {
        const double t = next - travelled;
        const double frontage = random.Uniform(8, 12);
        const double depth = random.Uniform(7, 10);
        const double setback = random.Uniform(7, 10);
        Building house;
        house.footprint.centre = a + t * along + normal * (road.width_m / 2 + setback + depth / 2);
        house.footprint.size = {frontage, depth};
        house.footprint.angle_deg = std::atan2(along.y(), along.x()) / kDegToRad;
        house.height_m = random.Uniform(6, 9);
        house.roof_bgr = RoofColour(random);
        house.gabled = random.Bernoulli(0.8);
        const Polyline plot = Grown(house.footprint, 1.5).Corners();
        if (occupancy.IsFree(plot)) {
          occupancy.MarkPolygon(plot);
          world->buildings.push_back(house);
          // Back garden: a tree or two behind the house, and sometimes a car on the drive.
          const int garden_trees = random.UniformInt(0, 2);
          for (int k = 0; k < garden_trees; ++k) {
            const Vector2d centre = house.footprint.centre +
                                    normal * (depth / 2 + random.Uniform(4, 9)) +
                                    along * random.Uniform(-frontage / 2, frontage / 2);
            world->trees.push_back({centre, random.Uniform(1.8, 3.5)});
          }
          if (random.Bernoulli(0.35)) {
            ParkedVehicle car;
            car.look = RandomVehicleLook(random, /*van=*/false);
            car.position = house.footprint.centre - normal * (depth / 2 + setback / 2) +
                           along * (frontage / 2 + 1.6);
            const Vector2d facing = -normal;
            car.heading_deg = std::atan2(facing.x(), facing.y()) / kDegToRad;
            world->parked.push_back(car);
          }
        }
        next += frontage + random.Uniform(2, 6);
      }
      travelled += length;
    }
  }
}

// A car park with two rows of bays facing a central aisle; about 70 % of bays taken.
void FillCarPark(const OrientedBox& park, Random& random, World* world) {
  const double angle = park.angle_deg * kDegToRad;
  const Vector2d ax(std::cos(angle), std::sin(angle));  // along the rows
  const Vector2d ay(-ax.y(), ax.x());
  const double bay_width = 2.5, bay_depth = 5.0;
  const int bays = static_cast<int>((park.size.x() - 2.0) / bay_width);
  for (int row : {-1, 1}) {
    for (int k = 0; k < bays; ++k) {
      if (!random.Bernoulli(0.7)) continue;
      ParkedVehicle car;
      car.look = RandomVehicleLook(random, random.Bernoulli(0.12));
      const double x = -park.size.x() / 2 + 1.0 + (k + 0.5) * bay_width;
      const double y = row * (park.size.y() / 2 - bay_depth / 2 - 0.4);
      car.position = park.centre + x * ax + y * ay + random.Uniform(-0.15, 0.15) * ax;
      // Nose in or reversed in, along the bay.
      const Vector2d facing = (random.Bernoulli(0.7) ? row : -row) * ay;
      car.heading_deg = std::atan2(facing.x(), facing.y()) / kDegToRad + random.Uniform(-3, 3);
      world->parked.push_back(car);
    }
  }
}

// Countryside: a jittered grid of fields with hedges along their edges.
void MakeCountryside(const cv::Rect2d& extent, const Vector2d& town_centre, double town_a,
                     double town_b, uint64_t seed, World* world) {
  const double cell = 150.0;
  const int i0 = static_cast<int>(std::floor(extent.x / cell)) - 1;
  const int i1 = static_cast<int>(std::ceil((extent.x + extent.width) / cell)) + 1;
  const int j0 = static_cast<int>(std::floor(extent.y / cell)) - 1;
  const int j1 = static_cast<int>(std::ceil((extent.y + extent.height) / cell)) + 1;
  const auto corner = [&](int i, int j) {
    Random r(HashCombine(
        seed, HashCombine(static_cast<uint64_t>(i) * 0x1000193u, static_cast<uint64_t>(j))));
    return Vector2d(i * cell + r.Uniform(-35, 35), j * cell + r.Uniform(-35, 35));
  };
  const auto in_town = [&](const Vector2d& p) {
    const Vector2d d = p - town_centre;
    const double u = d.x() / town_a, v = d.y() / town_b;
    return u * u + v * v < 1.0;
  };
  std::vector<std::vector<bool>> is_field(i1 - i0 + 1, std::vector<bool>(j1 - j0 + 1, false));
  for (int i = i0; i < i1; ++i) {
    for (int j = j0; j < j1; ++j) {
      const Polyline quad{corner(i, j), corner(i + 1, j), corner(i + 1, j + 1), corner(i, j + 1)};
      Vector2d centre(0, 0);
      for (const Vector2d& p : quad) centre += p / 4.0;
      if (in_town(centre)) continue;
      is_field[i - i0][j - j0] = true;
      Random r(HashCombine(seed ^ 0xF1E1Du,
                           HashCombine(static_cast<uint64_t>(i), static_cast<uint64_t>(j) << 20)));
      Field field;
      field.polygon = quad;
      const double pick = r.Uniform();
      if (pick < 0.35) {
        field.crop = Crop::kPasture;
        field.bgr = cv::Scalar(60, 125, 85) * r.Uniform(0.85, 1.1);
      } else if (pick < 0.65) {
        field.crop = Crop::kStripes;
        field.bgr = r.Bernoulli(0.5) ? cv::Scalar(55, 140, 110) * r.Uniform(0.9, 1.1)
                                     : cv::Scalar(80, 160, 170) * r.Uniform(0.9, 1.1);
      } else if (pick < 0.85) {
        field.crop = Crop::kPloughed;
        field.bgr = cv::Scalar(60, 85, 115) * r.Uniform(0.85, 1.1);
      } else {
        field.crop = Crop::kStubble;
        field.bgr = cv::Scalar(120, 175, 195) * r.Uniform(0.9, 1.05);
      }
      const Vector2d edge = quad[1] - quad[0];
      field.stripe_angle_deg =
          std::atan2(edge.y(), edge.x()) / kDegToRad + (r.Bernoulli(0.5) ? 90 : 0);
      world->fields.push_back(field);
    }
  }
  // Hedges on every grid edge next to at least one field, with a tree every so often.
  const auto field_at = [&](int i, int j) {
    return i >= i0 && i < i1 && j >= j0 && j < j1 && is_field[i - i0][j - j0];
  };
  for (int i = i0; i <= i1; ++i) {
    for (int j = j0; j <= j1; ++j) {
      for (int dir = 0; dir < 2; ++dir) {
        const int ni = dir == 0 ? i + 1 : i, nj = dir == 0 ? j : j + 1;
        const bool beside_field =
            dir == 0 ? field_at(i, j) || field_at(i, j - 1) : field_at(i, j) || field_at(i - 1, j);
        if (!beside_field) continue;
        Random r(HashCombine(seed ^ 0x4ED6Eu, HashCombine(static_cast<uint64_t>(i) * 3 + dir,
                                                          static_cast<uint64_t>(j))));
        if (r.Bernoulli(0.15)) continue;  // some field edges are open
        const Polyline hedge{corner(i, j), corner(ni, nj)};
        world->hedges.push_back(hedge);
        const double length = PolylineLength(hedge);
        for (double s = r.Uniform(5, 30); s < length; s += r.Uniform(20, 60)) {
          world->trees.push_back(
              {hedge[0] + (hedge[1] - hedge[0]) * (s / length), r.Uniform(2.5, 5)});
        }
      }
    }
  }
}

}  // namespace

VehicleLook RandomVehicleLook(Random& random, bool van) {
  static const cv::Scalar kPaints[] = {
      {235, 235, 235}, {30, 30, 30},  {160, 160, 165}, {40, 40, 170},   {140, 60, 20},
      {200, 200, 205}, {60, 110, 40}, {30, 60, 110},   {100, 100, 100}, {180, 150, 60},
  };
  VehicleLook look;
  look.van = van;
  look.length_m = van ? random.Uniform(5.0, 5.6) : random.Uniform(4.0, 4.9);
  look.width_m = van ? 2.0 : random.Uniform(1.7, 1.85);
  // Most vans are white.
  look.body_bgr =
      van && random.Bernoulli(0.6) ? cv::Scalar(240, 240, 240) : kPaints[random.UniformInt(0, 9)];
  return look;
}

std::vector<Vector2d> OrientedBox::Corners() const {
  const double a = angle_deg * kDegToRad;
  const Vector2d ax = Vector2d(std::cos(a), std::sin(a)) * (size.x() / 2);
  const Vector2d ay = Vector2d(-std::sin(a), std::cos(a)) * (size.y() / 2);
  return {centre - ax - ay, centre + ax - ay, centre + ax + ay, centre - ax + ay};
}

double PolylineLength(const Polyline& line) {
  double length = 0;
  for (size_t i = 0; i + 1 < line.size(); ++i) length += (line[i + 1] - line[i]).norm();
  return length;
}

double DistanceToPolyline(const Vector2d& point, const Polyline& line) {
  if (line.size() == 1) return (point - line[0]).norm();
  double best = std::numeric_limits<double>::infinity();
  for (size_t i = 0; i + 1 < line.size(); ++i) {
    best = std::min(best, DistanceToSegment(point, line[i], line[i + 1]));
  }
  return best;
}

Status WorldOptions::Validate() const {
  if (!(loop_length_m >= 500 && loop_length_m <= 3000)) {
    return InvalidArgumentError("world: the road loop length must be between 500 and 3000 m, got " +
                                std::to_string(loop_length_m));
  }
  return Status::Ok();
}

namespace {

// The town's shape: the road loop, an oval of semi-axes `a` (east-west) and `b` whose centre is
// `centre`, and where the three streets crossing it north-south run.
struct Town {
  Polyline loop;
  Vector2d centre{0, 0};
  double a = 0, b = 0;
  std::array<double, 3> chord_x{};
};

// A main road west from the roundabout and two country roads north-west and south-west, all out
// to the edge of `extent`.
void AddRoadsFromRoundabout(const cv::Rect2d& extent, NetworkBuilder* network) {
  Polyline west{{0, 0}, {-70, 6}};
  Polyline rest = RayToEdge({-70, 6}, {-1, 0.04}, extent);
  west.insert(west.end(), rest.begin() + 1, rest.end());
  network->Add(west, 8.0, RoadClass::kMain);
  Polyline south_west{{0, 0}, {-35, -45}};
  rest = RayToEdge({-35, -45}, {-0.55, -0.85}, extent);
  south_west.insert(south_west.end(), rest.begin() + 1, rest.end());
  network->Add(south_west, 6.0, RoadClass::kCountry);
  Polyline north_west{{0, 0}, {-30, 55}};
  rest = RayToEdge({-30, 55}, {-0.25, 1}, extent);
  north_west.insert(north_west.end(), rest.begin() + 1, rest.end());
  network->Add(north_west, 6.0, RoadClass::kCountry);
}

// The town's streets across and around the loop.
void AddTownStreets(const Town& town, const cv::Rect2d& extent, NetworkBuilder* network) {
  const Polyline& loop = town.loop;
  const Vector2d& centre = town.centre;
  const double a = town.a, b = town.b;
  const std::array<double, 3>& chord_x = town.chord_x;
  // Streets crossing the loop north-south; the middle one runs on into the country.
  for (int k = 0; k < 3; ++k) {
    const auto [lo, hi] = LoopSpanAt(loop, chord_x[k]);
    if (k == 1) {
      Polyline north = RayToEdge({chord_x[k], hi}, {0.03, 1}, extent);
      Polyline south = RayToEdge({chord_x[k], lo}, {-0.03, -1}, extent);
      Polyline street(south.rbegin(), south.rend());
      street.insert(street.end(), north.begin() + 1, north.end());
      network->Add(street, 7.0, RoadClass::kStreet);
    } else {
      network->Add({{chord_x[k], lo - 130}, {chord_x[k], hi + 130}}, 6.5, RoadClass::kStreet);
    }
  }
  // An east-west street from the first chord through the loop and east into the country.
  {
    const double y = 0.3 * b;
    Polyline east{{chord_x[0] - 1.0, y}, {centre.x() + a + 60, y}};
    Polyline rest = RayToEdge(east.back(), {1, -0.06}, extent);
    east.insert(east.end(), rest.begin() + 1, rest.end());
    network->Add(east, 7.5, RoadClass::kMain);
  }
  // A short street across the loop's south-east quarter, past the shops.
  {
    const double y = -0.5 * b;
    const double x_end =
        LoopSpanAt(loop, centre.x() + 0.8 * a).first < y ? centre.x() + a : centre.x() + 0.8 * a;
    network->Add({{chord_x[1] - 1.0, y}, {x_end + 30, y}}, 6.0, RoadClass::kStreet);
  }
  // Streets outside the loop joining the chord ends: a crescent to the north, a street south.
  Polyline crescent;
  for (int k = 0; k <= 16; ++k) {
    const double x = chord_x[0] - 25 + (chord_x[2] - chord_x[0] + 50) * k / 16.0;
    const double u = (x - centre.x()) / (0.5 * a + 25);
    crescent.emplace_back(x, b + 95 - 25 * u * u);
  }
  network->Add(crescent, 6.0, RoadClass::kStreet);
  network->Add({{chord_x[0] - 25, -b - 80}, {chord_x[2] + 25, -b - 80}}, 6.0, RoadClass::kStreet);
}

// The road network: the loop, the roads from the roundabout and the town's streets, joined at
// their crossings; the node at the origin is the roundabout.
void AddRoads(const Town& town, World* world) {
  NetworkBuilder network;
  network.Add(town.loop, 8.0, RoadClass::kMain);
  AddRoadsFromRoundabout(world->extent_m, &network);
  AddTownStreets(town, world->extent_m, &network);
  network.Build(world);
  for (size_t i = 0; i < world->nodes.size(); ++i) {
    if (world->nodes[i].position.norm() < 1.0) {
      world->roundabout_node = static_cast<int>(i);
      world->nodes[i].roundabout_radius_m = 16.0;
    }
  }
  SAKER_CHECK(world->roundabout_node >= 0);
}

// The park: grass and trees inside the loop's south-west, crossed by footpaths.
void AddPark(const Town& town, Occupancy& occupancy, Random& random, World* world) {
  const double x0 = town.chord_x[0] + 12, x1 = town.chord_x[1] - 12;
  const double y1 = 0.3 * town.b - 12;
  const double y0 = std::max(LoopSpanAt(town.loop, x0).first, LoopSpanAt(town.loop, x1).first) + 14;
  world->park_boundary = {{x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}};
  occupancy.MarkPolygon(world->park_boundary);
  world->footpaths.push_back({{x0, y0}, {x1, y1}});
  world->footpaths.push_back({{x0, y1}, {x1, y0}});
  world->footpaths.push_back(
      {{x0, (y0 + y1) / 2}, {(x0 + x1) / 2, (y0 + y1) / 2 + 8}, {x1, (y0 + y1) / 2}});
  for (int k = 0; k < 28; ++k) {
    const Vector2d p(random.Uniform(x0 + 4, x1 - 4), random.Uniform(y0 + 4, y1 - 4));
    bool on_path = false;
    for (const Polyline& path : world->footpaths) on_path |= DistanceToPolyline(p, path) < 6;
    if (!on_path) world->trees.push_back({p, random.Uniform(2.5, 5.5)});
  }
}

// Shops with car parks in front, where they fit.
void AddShops(const Town& town, Occupancy& occupancy, Random& random, World* world) {
  const Vector2d& centre = town.centre;
  const double a = town.a, b = town.b;
  const struct {
    Vector2d at;
    double angle;
  } kCommercialSites[] = {
      {{centre.x() + 0.26 * a, 0.0 * b}, 0},
      {{centre.x() - 0.24 * a, 0.62 * b}, 0},
      {{centre.x() + 0.76 * a, -0.05 * b}, 90},
      {{centre.x() + a + 90, 0.3 * b - 45}, 0},
  };
  for (const auto& site : kCommercialSites) {
    const OrientedBox car_park{site.at, {44, 17}, site.angle};
    const double angle = site.angle * kDegToRad;
    const Vector2d behind = Vector2d(-std::sin(angle), std::cos(angle)) * -(17 / 2.0 + 3 + 11);
    const OrientedBox shop{site.at + behind, {random.Uniform(30, 40), 20}, site.angle};
    const Polyline car_park_plot = Grown(car_park, 1).Corners();
    const Polyline shop_plot = Grown(shop, 1).Corners();
    if (!occupancy.IsFree(car_park_plot) || !occupancy.IsFree(shop_plot)) continue;
    occupancy.MarkPolygon(car_park_plot);
    occupancy.MarkPolygon(shop_plot);
    world->car_parks.push_back(car_park);
    FillCarPark(car_park, random, world);
    world->buildings.push_back({shop, random.Uniform(7, 10),
                                cv::Scalar(170, 172, 168) * random.Uniform(0.9, 1.05), false});
  }
}

// Trees along the main and country roads outside the town.
void AddRoadsideTrees(const Town& town, Random& random, World* world) {
  for (const Road& road : world->roads) {
    if (road.road_class == RoadClass::kStreet) continue;
    const Polyline& line = road.centreline;
    for (size_t i = 0; i + 1 < line.size(); ++i) {
      const Vector2d along = (line[i + 1] - line[i]).normalized();
      const Vector2d normal(-along.y(), along.x());
      for (int side : {-1, 1}) {
        if (!random.Bernoulli(0.35)) continue;
        const Vector2d p = line[i] + normal * side * (road.width_m / 2 + random.Uniform(4, 7));
        const Vector2d d = p - town.centre;
        if (std::pow(d.x() / (town.a + 200), 2) + std::pow(d.y() / (town.b + 200), 2) < 1) continue;
        world->trees.push_back({p, random.Uniform(2.5, 4.5)});
      }
    }
  }
}

}  // namespace

StatusOr<World> GenerateWorld(const WorldOptions& options, const cv::Rect2d& extent_m) {
  SAKER_RETURN_IF_ERROR(options.Validate());
  if (!(extent_m.width > 0 && extent_m.height > 0) || extent_m.width > 50000 ||
      extent_m.height > 50000) {
    return InvalidArgumentError("world: the extent must be between 0 and 50 km on a side");
  }
  World world;
  world.seed = options.seed;
  Random random(HashCombine(options.seed, 0x7041u));

  // The town must fit in the extent whatever the flight: grow the extent around it.
  Town town;
  town.loop = MakeLoop(options.loop_length_m, random, &town.a, &town.b);
  const double a = town.a, b = town.b;
  const Vector2d centre(a, 0);
  town.centre = centre;
  town.chord_x = {centre.x() - 0.5 * a, centre.x() + 0.02 * a, centre.x() + 0.5 * a};
  const cv::Rect2d town_box(centre.x() - a - 450, centre.y() - b - 450, 2 * a + 900, 2 * b + 900);
  world.extent_m = extent_m | town_box;
  world.town_centre = centre;
  world.road_loop = town.loop;
  const double sun_azimuth = random.Uniform(135, 165) * kDegToRad;
  world.sun_direction = Vector2d(std::sin(sun_azimuth), std::cos(sun_azimuth));
  world.shadow_length_per_m = 1.0 / std::tan(random.Uniform(42, 55) * kDegToRad);
  AddRoads(town, &world);

  // Reserve the roads, then the park, shops and car parks, then houses along the streets.
  Occupancy occupancy(town_box);
  for (const Road& road : world.roads) occupancy.MarkPolyline(road.centreline, road.width_m + 5);
  occupancy.MarkPolygon(OrientedBox{{0, 0}, {40, 40}, 0}.Corners());  // the roundabout
  AddPark(town, occupancy, random, &world);
  AddShops(town, occupancy, random, &world);
  for (const Road& road : world.roads) {
    const Vector2d mid = road.centreline[road.centreline.size() / 2];
    const Vector2d d = mid - centre;
    const bool in_town = std::pow(d.x() / (a + 160), 2) + std::pow(d.y() / (b + 160), 2) < 1;
    if (in_town) LineStreetWithHouses(road, occupancy, random, &world);
  }
  // Footpaths between the crescent and the loop, past the houses.
  const double chord_x1 = town.chord_x[1];
  world.footpaths.push_back(
      {{chord_x1 + 30, LoopSpanAt(town.loop, chord_x1 + 30).second + 6}, {chord_x1 + 34, b + 70}});

  AddRoadsideTrees(town, random, &world);
  MakeCountryside(world.extent_m, centre, a + 170, b + 170, HashCombine(options.seed, 0xC0u),
                  &world);
  return world;
}

}  // namespace saker::sim
