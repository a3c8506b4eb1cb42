#include "core/sim/world_raster.h"

#include "core/sim/random.h"
#include "core/util/check.h"

#include <Eigen/Geometry>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>

namespace saker::sim {
namespace {

using Eigen::Vector2d;

constexpr double kDegToRad = M_PI / 180.0;
constexpr int kShift = 4;  // sub-pixel bits for OpenCV drawing
constexpr double kOne = 1 << kShift;

// ---------------------------------------------------------------------------------------------
// Value noise in ground coordinates: smooth, seeded, in [-1, 1], continuous across tiles.

double LatticeValue(uint64_t seed, int64_t ix, int64_t iy) {
  const uint64_t h = HashCombine(
      seed, HashCombine(static_cast<uint64_t>(ix), static_cast<uint64_t>(iy) * 0x9E3779B1u));
  return static_cast<double>(h >> 11) * 0x1.0p-52 - 1.0;
}

double ValueNoise(uint64_t seed, double x, double y) {
  const double fx = std::floor(x), fy = std::floor(y);
  const int64_t ix = static_cast<int64_t>(fx), iy = static_cast<int64_t>(fy);
  double tx = x - fx, ty = y - fy;
  tx = tx * tx * (3 - 2 * tx);
  ty = ty * ty * (3 - 2 * ty);
  const double v00 = LatticeValue(seed, ix, iy), v10 = LatticeValue(seed, ix + 1, iy);
  const double v01 = LatticeValue(seed, ix, iy + 1), v11 = LatticeValue(seed, ix + 1, iy + 1);
  return (v00 + (v10 - v00) * tx) + ((v01 + (v11 - v01) * tx) - (v00 + (v10 - v00) * tx)) * ty;
}

// How a surface looks: a colour, how strongly noise of each scale modulates its brightness, and
// optional stripes (drill lines, furrows, roof tiles).
struct Material {
  cv::Vec3f bgr;
  float fine = 0, mid = 0, coarse = 0, large = 0;
  float stripe_amplitude = 0;
  float stripe_spacing_m = 1;
  Vector2d stripe_normal{1, 0};
};

Material MakeMaterial(const cv::Scalar& bgr, float fine, float mid, float coarse, float large) {
  Material m;
  m.bgr =
      cv::Vec3f(static_cast<float>(bgr[0]), static_cast<float>(bgr[1]), static_cast<float>(bgr[2]));
  m.fine = fine, m.mid = mid, m.coarse = coarse, m.large = large;
  return m;
}

// Painting context for one tile: ground -> tile pixels, and the material maps.
class TilePainter {
 public:
  TilePainter(const World& world, double gsd, int64_t col0, int64_t row0, int size)
      : world_(world), gsd_(gsd), col0_(col0), row0_(row0), size_(size) {
    ground_.create(size, size, CV_16U);
    top_.create(size, size, CV_16U);
    ground_.setTo(0);
    top_.setTo(0);
    palette_.push_back(MakeMaterial({70, 135, 95}, 0.10f, 0.08f, 0.08f, 0.10f));  // rough grass
    palette_.push_back({});  // 1 = "nothing on top" placeholder
    const double half = 0.5 * gsd;
    bounds_ = cv::Rect2d(col0 * gsd - half, -(row0 + size) * gsd + half, size * gsd, size * gsd);
  }

  // True when a primitive with these ground bounds (plus `margin` metres) may touch the tile.
  bool Touches(const cv::Rect2d& bounds, double margin) const {
    const cv::Rect2d grown(bounds.x - margin, bounds.y - margin, bounds.width + 2 * margin,
                           bounds.height + 2 * margin);
    return (grown & bounds_).area() > 0 || (bounds.width == 0 && bounds.height == 0);
  }
  static cv::Rect2d Bounds(const Polyline& points) {
    double x0 = 1e18, y0 = 1e18, x1 = -1e18, y1 = -1e18;
    for (const Vector2d& p : points) {
      x0 = std::min(x0, p.x()), x1 = std::max(x1, p.x());
      y0 = std::min(y0, p.y()), y1 = std::max(y1, p.y());
    }
    return {x0, y0, std::max(x1 - x0, 1e-3), std::max(y1 - y0, 1e-3)};
  }

  cv::Point ToPixel(const Vector2d& p) const {
    return {static_cast<int>(std::lround((p.x() / gsd_ - col0_) * kOne)),
            static_cast<int>(std::lround((-p.y() / gsd_ - row0_) * kOne))};
  }
  std::vector<cv::Point> ToPixels(const Polyline& line) const {
    std::vector<cv::Point> out;
    out.reserve(line.size());
    for (const Vector2d& p : line) out.push_back(ToPixel(p));
    return out;
  }
  int Thickness(double metres) const {
    return std::max(1, static_cast<int>(std::lround(metres / gsd_)));
  }
  Eigen::Matrix3d TileFromGround() const {
    Eigen::Matrix3d t = RasterFromGround(gsd_);
    t(0, 2) -= static_cast<double>(col0_);
    t(1, 2) -= static_cast<double>(row0_);
    return t;
  }

  uint16_t AddMaterial(const Material& m) {
    palette_.push_back(m);
    return static_cast<uint16_t>(palette_.size() - 1);
  }
  void FillPolygon(cv::Mat& layer, const Polyline& polygon, uint16_t id) {
    if (!Touches(Bounds(polygon), 0)) return;
    cv::fillPoly(layer, std::vector<std::vector<cv::Point>>{ToPixels(polygon)}, cv::Scalar(id),
                 cv::LINE_8, kShift);
  }
  void StrokePolyline(cv::Mat& layer, const Polyline& line, double width_m, uint16_t id) {
    if (!Touches(Bounds(line), width_m)) return;
    cv::polylines(layer, std::vector<std::vector<cv::Point>>{ToPixels(line)}, false, cv::Scalar(id),
                  Thickness(width_m), cv::LINE_8, kShift);
  }
  void FillCircle(cv::Mat& layer, const Vector2d& centre, double radius_m, uint16_t id) {
    if (!Touches({centre.x() - radius_m, centre.y() - radius_m, 2 * radius_m, 2 * radius_m}, 0))
      return;
    cv::circle(layer, ToPixel(centre), static_cast<int>(std::lround(radius_m / gsd_ * kOne)),
               cv::Scalar(id), cv::FILLED, cv::LINE_8, kShift);
  }

  cv::Mat& ground() { return ground_; }
  cv::Mat& top() { return top_; }

  // Turns a material map into colour, with noise at four scales in ground coordinates.
  void Shade(const cv::Mat& layer, cv::Mat* bgr, bool skip_zero) const {
    const uint64_t seed = world_.seed;
    const double fine = std::max(0.45, 2.5 * gsd_), mid = std::max(2.0, 6 * gsd_);
    for (int r = 0; r < size_; ++r) {
      const uint16_t* ids = layer.ptr<uint16_t>(r);
      cv::Vec3b* out = bgr->ptr<cv::Vec3b>(r);
      const double y = -(row0_ + r) * gsd_;
      for (int c = 0; c < size_; ++c) {
        if (skip_zero && ids[c] == 0) continue;
        const Material& m = palette_[ids[c]];
        const double x = (col0_ + c) * gsd_;
        double f = 1.0;
        if (m.fine != 0) f += m.fine * ValueNoise(seed ^ 0x11, x / fine, y / fine);
        if (m.mid != 0) f += m.mid * ValueNoise(seed ^ 0x22, x / mid, y / mid);
        if (m.coarse != 0) f += m.coarse * ValueNoise(seed ^ 0x33, x / 9.0, y / 9.0);
        if (m.large != 0) f += m.large * ValueNoise(seed ^ 0x44, x / 40.0, y / 40.0);
        if (m.stripe_amplitude != 0) {
          const double s = (x * m.stripe_normal.x() + y * m.stripe_normal.y()) / m.stripe_spacing_m;
          f += m.stripe_amplitude * std::sin(2 * M_PI * s);
        }
        out[c] = cv::Vec3b(cv::saturate_cast<uint8_t>(m.bgr[0] * f),
                           cv::saturate_cast<uint8_t>(m.bgr[1] * f),
                           cv::saturate_cast<uint8_t>(m.bgr[2] * f));
      }
    }
  }

  double gsd() const { return gsd_; }

 private:
  const World& world_;
  double gsd_;
  int64_t col0_, row0_;
  int size_;
  cv::Rect2d bounds_;
  cv::Mat ground_, top_;
  std::vector<Material> palette_;
};

// Dashes of `dash` metres every `period` metres along a polyline, skipping `skip_ends` metres at
// both ends (junctions).
std::vector<std::pair<Vector2d, Vector2d>> Dashes(const Polyline& line, double dash, double period,
                                                  double skip_ends) {
  std::vector<std::pair<Vector2d, Vector2d>> out;
  const double length = PolylineLength(line);
  double travelled = 0;
  for (size_t i = 0; i + 1 < line.size(); ++i) {
    const double seg = (line[i + 1] - line[i]).norm();
    const Vector2d along = (line[i + 1] - line[i]) / std::max(seg, 1e-9);
    double s = std::ceil(travelled / period) * period;
    for (; s < travelled + seg; s += period) {
      if (s < skip_ends || s + dash > length - skip_ends) continue;
      const double t0 = s - travelled, t1 = std::min(seg, t0 + dash);
      out.emplace_back(line[i] + along * t0, line[i] + along * t1);
    }
    travelled += seg;
  }
  return out;
}

std::vector<Vector2d> ProjectAll(const Eigen::Matrix3d& h, const std::vector<Vector2d>& points) {
  std::vector<Vector2d> out;
  out.reserve(points.size());
  for (const Vector2d& p : points) out.push_back((h * p.homogeneous()).hnormalized());
  return out;
}

// A rectangle in a vehicle's own frame (x forward, y left) from `front` to `back` metres behind
// the nose, `half_width` to each side, mapped to the ground.
Polyline VehicleBand(const Vector2d& position, const Vector2d& forward, double length,
                     double from_front, double to_front, double half_width) {
  const Vector2d left(-forward.y(), forward.x());
  const Vector2d nose = position + forward * (length / 2);
  return {nose - forward * from_front + left * half_width,
          nose - forward * from_front - left * half_width,
          nose - forward * to_front - left * half_width,
          nose - forward * to_front + left * half_width};
}

// The material of a field: its colour, with noise and stripes by crop (stripes no finer than a
// few raster pixels, so they do not alias).
Material FieldMaterial(const Field& field, double gsd) {
  Material m = MakeMaterial(field.bgr, 0.06f, 0.05f, 0.07f, 0.08f);
  const double a = field.stripe_angle_deg * kDegToRad;
  m.stripe_normal = Vector2d(-std::sin(a), std::cos(a));
  switch (field.crop) {
    case Crop::kPasture:
      m.fine = 0.09f, m.mid = 0.09f, m.coarse = 0.1f;
      break;
    case Crop::kStripes:
      m.stripe_amplitude = 0.12f, m.stripe_spacing_m = static_cast<float>(std::max(1.6, 4 * gsd));
      break;
    case Crop::kPloughed:
      m.fine = 0.12f, m.stripe_amplitude = 0.16f,
      m.stripe_spacing_m = static_cast<float>(std::max(1.0, 3.5 * gsd));
      break;
    case Crop::kStubble:
      m.fine = 0.08f, m.stripe_amplitude = 0.06f,
      m.stripe_spacing_m = static_cast<float>(std::max(3.0, 4 * gsd));
      break;
  }
  return m;
}

// The ground layer: fields, then hedges between them; the park, footpaths, car parks, roads
// (pavements along town streets, then the carriageway) and the roundabout on top.
void PaintGroundLayer(const World& w, TilePainter& p) {
  cv::Mat& ground = p.ground();
  for (const Field& field : w.fields) {
    const Material m = FieldMaterial(field, p.gsd());
    if (p.Touches(TilePainter::Bounds(field.polygon), 0))
      p.FillPolygon(ground, field.polygon, p.AddMaterial(m));
  }
  const uint16_t hedge = p.AddMaterial(MakeMaterial({38, 82, 52}, 0.22f, 0.25f, 0.1f, 0.05f));
  for (const Polyline& line : w.hedges) p.StrokePolyline(ground, line, 2.8, hedge);
  // The park and the roundabout's island: mown grass.
  const uint16_t lawn = p.AddMaterial(MakeMaterial({80, 150, 100}, 0.05f, 0.05f, 0.06f, 0.06f));
  if (!w.park_boundary.empty()) p.FillPolygon(ground, w.park_boundary, lawn);
  const uint16_t path = p.AddMaterial(MakeMaterial({140, 170, 185}, 0.12f, 0.06f, 0.04f, 0.0f));
  for (const Polyline& line : w.footpaths) p.StrokePolyline(ground, line, 2.0, path);
  // Car parks.
  const uint16_t tarmac = p.AddMaterial(MakeMaterial({92, 94, 96}, 0.08f, 0.05f, 0.06f, 0.04f));
  for (const OrientedBox& park : w.car_parks) p.FillPolygon(ground, park.Corners(), tarmac);
  // Roads: pavements along town streets, then the carriageway; the roundabout on top.
  const uint16_t pavement = p.AddMaterial(MakeMaterial({165, 168, 170}, 0.06f, 0.04f, 0.03f, 0.0f));
  const uint16_t asphalt = p.AddMaterial(MakeMaterial({78, 80, 82}, 0.09f, 0.05f, 0.05f, 0.05f));
  const uint16_t lane = p.AddMaterial(MakeMaterial({95, 100, 104}, 0.1f, 0.06f, 0.06f, 0.05f));
  for (const Road& road : w.roads) {
    if (road.road_class != RoadClass::kCountry)
      p.StrokePolyline(ground, road.centreline, road.width_m + 3.6, pavement);
  }
  for (const Road& road : w.roads) {
    p.StrokePolyline(ground, road.centreline, road.width_m,
                     road.road_class == RoadClass::kCountry ? lane : asphalt);
  }
  if (w.roundabout_node >= 0) {
    const RoadNode& node = w.nodes[w.roundabout_node];
    p.FillCircle(ground, node.position, node.roundabout_radius_m + 1.8, pavement);
    p.FillCircle(ground, node.position, node.roundabout_radius_m, asphalt);
    p.FillCircle(ground, node.position, node.roundabout_radius_m * 0.5 + 0.6, pavement);
    p.FillCircle(ground, node.position, node.roundabout_radius_m * 0.5, lawn);
  }
}

// A white painted stripe from `a` to `b` (ground metres) `width` metres wide.
void PaintStripe(const Eigen::Matrix3d& tile_from_ground, const Vector2d& a, const Vector2d& b,
                 double width, double alpha, cv::Mat* image) {
  const Vector2d along = (b - a).normalized();
  const Vector2d n(-along.y() * width / 2, along.x() * width / 2);
  BlendPolygon(ProjectAll(tile_from_ground, {a + n, b + n, b - n, a - n}),
               cv::Scalar(225, 228, 230), alpha, image);
}

// Road markings: dashed centre lines on streets and main roads; bays in car parks.
void DrawRoadMarkings(const World& w, const TilePainter& p, cv::Mat* image) {
  const Eigen::Matrix3d tile_from_ground = p.TileFromGround();
  for (const Road& road : w.roads) {
    if (road.road_class == RoadClass::kCountry) continue;
    if (!p.Touches(TilePainter::Bounds(road.centreline), 2)) continue;
    const double skip = 12.0;
    for (const auto& [a, b] : Dashes(road.centreline, 3.0, 9.0, skip)) {
      if (w.roundabout_node >= 0 && (a - w.nodes[w.roundabout_node].position).norm() < 24) continue;
      PaintStripe(tile_from_ground, a, b, 0.15, 0.85, image);
    }
  }
  for (const OrientedBox& park : w.car_parks) {
    if (!p.Touches(TilePainter::Bounds(park.Corners()), 1)) continue;
    const double a = park.angle_deg * kDegToRad;
    const Vector2d ax(std::cos(a), std::sin(a)), ay(-std::sin(a), std::cos(a));
    const int bays = static_cast<int>((park.size.x() - 2.0) / 2.5);
    for (int row : {-1, 1}) {
      for (int k = 0; k <= bays; ++k) {
        const Vector2d base = park.centre + ax * (-park.size.x() / 2 + 1.0 + k * 2.5) +
                              ay * (row * (park.size.y() / 2 - 0.4));
        PaintStripe(tile_from_ground, base, base - ay * (row * 5.0), 0.12, 0.8, image);
      }
    }
  }
}

// Marks on `shadow` (the tile's 8-bit shadow mask) the shadow that `outline` casts when raised
// `height` metres: the convex hull of the outline and its image on the ground.
void CastShadow(const TilePainter& p, const Polyline& outline, double height,
                const Vector2d& shadow_per_m, cv::Mat* shadow) {
  std::vector<cv::Point2f> all, hull;
  for (const Vector2d& q : outline) {
    all.emplace_back(static_cast<float>(q.x()), static_cast<float>(q.y()));
    all.emplace_back(static_cast<float>(q.x() + shadow_per_m.x() * height),
                     static_cast<float>(q.y() + shadow_per_m.y() * height));
  }
  cv::convexHull(all, hull);
  Polyline polygon;
  for (const cv::Point2f& q : hull) polygon.emplace_back(q.x, q.y);
  if (!p.Touches(TilePainter::Bounds(polygon), 0)) return;
  cv::fillPoly(*shadow, std::vector<std::vector<cv::Point>>{p.ToPixels(polygon)}, cv::Scalar(255),
               cv::LINE_AA, kShift);
}

// Shadows of buildings and trees, cast away from the sun, darken the ground.
void DarkenShadows(const World& w, const TilePainter& p, cv::Mat* image) {
  const Vector2d shadow_per_m = ShadowPerMetre(w);
  cv::Mat shadow = cv::Mat::zeros(image->size(), CV_8U);
  for (const Building& b : w.buildings) {
    CastShadow(p, b.footprint.Corners(), b.height_m, shadow_per_m, &shadow);
  }
  for (const Tree& t : w.trees) {
    if (!p.Touches({t.centre.x() - 20, t.centre.y() - 20, 40, 40}, 0)) continue;
    Polyline disc;
    for (int k = 0; k < 12; ++k) {
      const double a = 2 * M_PI * k / 12;
      disc.push_back(t.centre + shadow_per_m * (1.6 * t.radius_m) +
                     t.radius_m * Vector2d(std::cos(a), std::sin(a)));
    }
    CastShadow(p, disc, 0.8 * t.radius_m, shadow_per_m, &shadow);
  }
  for (int r = 0; r < image->rows; ++r) {
    const uint8_t* s = shadow.ptr<uint8_t>(r);
    cv::Vec3b* px = image->ptr<cv::Vec3b>(r);
    for (int c = 0; c < image->cols; ++c) {
      if (s[c] == 0) continue;
      const double f = 1.0 - 0.5 * s[c] / 255.0;
      px[c] =
          cv::Vec3b(static_cast<uint8_t>(px[c][0] * f), static_cast<uint8_t>(px[c][1] * f * 0.98),
                    static_cast<uint8_t>(px[c][2] * f * 0.95));
    }
  }
}

// A building's roof on the top layer: a flat roof, or two planes either side of the ridge.
void FillRoof(const World& w, const Building& b, const Polyline& corners, TilePainter& p) {
  Material roof = MakeMaterial(b.roof_bgr, 0.05f, 0.03f, 0.02f, 0.0f);
  const double a = b.footprint.angle_deg * kDegToRad;
  roof.stripe_normal = Vector2d(-std::sin(a), std::cos(a));
  if (b.gabled) {
    // Two roof planes either side of the ridge; the one facing the sun is brighter. Tile
    // courses run along the ridge.
    roof.stripe_amplitude = p.gsd() < 0.15 ? 0.06f : 0.0f;
    roof.stripe_spacing_m = 0.5f;
    const Vector2d mid_a = (corners[0] + corners[3]) / 2, mid_b = (corners[1] + corners[2]) / 2;
    const double facing = roof.stripe_normal.dot(w.sun_direction);
    Material lit = roof, dark = roof;
    lit.bgr *= static_cast<float>(1.0 + 0.18 * std::abs(facing));
    dark.bgr *= static_cast<float>(1.0 - 0.22 * std::abs(facing));
    const Polyline half0{corners[0], corners[1], mid_b, mid_a};
    const Polyline half1{mid_a, mid_b, corners[2], corners[3]};
    const bool half1_lit = facing > 0;
    p.FillPolygon(p.top(), half0, p.AddMaterial(half1_lit ? dark : lit));
    p.FillPolygon(p.top(), half1, p.AddMaterial(half1_lit ? lit : dark));
  } else {
    roof.fine = 0.04f, roof.mid = 0.04f;
    p.FillPolygon(p.top(), corners, p.AddMaterial(roof));
  }
}

// Roofs and tree canopies, shaded on their own layer and laid over the ground.
void LayRoofsAndCanopies(const World& w, TilePainter& p, cv::Mat* image) {
  for (const Building& b : w.buildings) {
    const Polyline corners = b.footprint.Corners();
    if (!p.Touches(TilePainter::Bounds(corners), 0)) continue;
    FillRoof(w, b, corners, p);
  }
  for (const Tree& t : w.trees) {
    Random r(HashCombine(w.seed, static_cast<uint64_t>(std::llround(t.centre.x() * 10)) * 31 +
                                     static_cast<uint64_t>(std::llround(t.centre.y() * 10))));
    Material canopy =
        MakeMaterial(cv::Scalar(35, 95, 55) * r.Uniform(0.8, 1.2), 0.18f, 0.22f, 0.0f, 0.0f);
    p.FillCircle(p.top(), t.centre, t.radius_m, p.AddMaterial(canopy));
  }
  cv::Mat top_image(image->size(), CV_8UC3);  // only the pixels under the mask are shaded and used
  p.Shade(p.top(), &top_image, true);
  cv::Mat top_mask = p.top() != 0;
  top_image.copyTo(*image, top_mask);
}

// Air-conditioning plant on the roof of a shop, with its shadows.
void DrawRoofPlant(const World& w, const Building& b, const Eigen::Matrix3d& tile_from_ground,
                   const Vector2d& shadow_per_m, cv::Mat* image) {
  Random r(HashCombine(w.seed, static_cast<uint64_t>(std::llround(b.footprint.centre.x() * 7))));
  const double a = b.footprint.angle_deg * kDegToRad;
  const Vector2d ax(std::cos(a), std::sin(a)), ay(-std::sin(a), std::cos(a));
  for (int k = 0; k < 4; ++k) {
    const Vector2d at = b.footprint.centre + ax * r.Uniform(-0.35, 0.35) * b.footprint.size.x() +
                        ay * r.Uniform(-0.3, 0.3) * b.footprint.size.y();
    const OrientedBox unit{at, {r.Uniform(1.5, 3.5), r.Uniform(1.2, 2.5)}, b.footprint.angle_deg};
    Polyline unit_shadow = unit.Corners();
    for (Vector2d& q : unit_shadow) q += shadow_per_m * 1.2;
    BlendPolygon(ProjectAll(tile_from_ground, unit_shadow), cv::Scalar(0, 0, 0), 0.4, image);
    BlendPolygon(ProjectAll(tile_from_ground, unit.Corners()), cv::Scalar(200, 202, 205), 1.0,
                 image);
  }
}

// Roof edges and ridges, roof plant on the shops, and the parked vehicles.
void DrawRoofDetailsAndParkedVehicles(const World& w, const TilePainter& p, cv::Mat* image) {
  const Eigen::Matrix3d tile_from_ground = p.TileFromGround();
  const Vector2d shadow_per_m = ShadowPerMetre(w);
  for (const Building& b : w.buildings) {
    const Polyline corners = b.footprint.Corners();
    if (!p.Touches(TilePainter::Bounds(corners), 1)) continue;
    if (b.gabled) {
      const Vector2d mid_a = (corners[0] + corners[3]) / 2, mid_b = (corners[1] + corners[2]) / 2;
      cv::line(*image, p.ToPixel(mid_a), p.ToPixel(mid_b), b.roof_bgr * 0.7, 1, cv::LINE_AA,
               kShift);
    } else if (b.footprint.size.x() * b.footprint.size.y() > 200) {
      DrawRoofPlant(w, b, tile_from_ground, shadow_per_m, image);
    }
    std::vector<cv::Point> outline = p.ToPixels(corners);
    cv::polylines(*image, std::vector<std::vector<cv::Point>>{outline}, true, b.roof_bgr * 0.6, 1,
                  cv::LINE_AA, kShift);
  }
  for (const ParkedVehicle& v : w.parked) {
    if (!p.Touches({v.position.x() - 4, v.position.y() - 4, 8, 8}, 0)) continue;
    DrawVehicle(tile_from_ground, v.position, v.heading_deg, v.look, shadow_per_m, image);
  }
}

}  // namespace

Eigen::Vector2d ShadowPerMetre(const World& world) {
  return -world.sun_direction * world.shadow_length_per_m;
}

void BlendPolygon(const std::vector<Vector2d>& polygon, const cv::Scalar& bgr, double alpha,
                  cv::Mat* image) {
  SAKER_CHECK(image->type() == CV_8UC3);
  double x0 = 1e18, y0 = 1e18, x1 = -1e18, y1 = -1e18;
  for (const Vector2d& p : polygon) {
    if (!std::isfinite(p.x()) || !std::isfinite(p.y())) return;
    x0 = std::min(x0, p.x()), x1 = std::max(x1, p.x());
    y0 = std::min(y0, p.y()), y1 = std::max(y1, p.y());
  }
  const cv::Rect box =
      cv::Rect(static_cast<int>(std::floor(x0)) - 1, static_cast<int>(std::floor(y0)) - 1,
               static_cast<int>(std::ceil(x1 - x0)) + 3, static_cast<int>(std::ceil(y1 - y0)) + 3) &
      cv::Rect(0, 0, image->cols, image->rows);
  if (box.empty()) return;
  cv::Mat coverage = cv::Mat::zeros(box.size(), CV_8U);
  std::vector<cv::Point> points;
  for (const Vector2d& p : polygon) {
    points.emplace_back(static_cast<int>(std::lround((p.x() - box.x) * kOne)),
                        static_cast<int>(std::lround((p.y() - box.y) * kOne)));
  }
  cv::fillPoly(coverage, std::vector<std::vector<cv::Point>>{points}, cv::Scalar(255), cv::LINE_AA,
               kShift);
  cv::Mat roi = (*image)(box);
  for (int r = 0; r < box.height; ++r) {
    const uint8_t* cov = coverage.ptr<uint8_t>(r);
    cv::Vec3b* px = roi.ptr<cv::Vec3b>(r);
    for (int c = 0; c < box.width; ++c) {
      if (cov[c] == 0) continue;
      const double a = alpha * cov[c] / 255.0;
      for (int k = 0; k < 3; ++k)
        px[c][k] = cv::saturate_cast<uint8_t>(px[c][k] * (1 - a) + bgr[k] * a);
    }
  }
}

void DrawVehicle(const Eigen::Matrix3d& image_from_ground, const Vector2d& position,
                 double heading_deg, const VehicleLook& look, const Vector2d& shadow_per_m,
                 cv::Mat* image) {
  const double heading = heading_deg * kDegToRad;
  const Vector2d forward(std::sin(heading), std::cos(heading));
  const double l = look.length_m, hw = look.width_m / 2;
  const double height = look.van ? 2.1 : 1.45;
  // Body outline with chamfered corners, and its shadow on the ground.
  const Vector2d left(-forward.y(), forward.x());
  const Vector2d c = position;
  const double cut = 0.3;
  const Polyline body{
      c + forward * (l / 2) + left * (hw - cut), c + forward * (l / 2 - cut) + left * hw,
      c - forward * (l / 2 - cut) + left * hw,   c - forward * (l / 2) + left * (hw - cut),
      c - forward * (l / 2) - left * (hw - cut), c - forward * (l / 2 - cut) - left * hw,
      c + forward * (l / 2 - cut) - left * hw,   c + forward * (l / 2) - left * (hw - cut)};
  Polyline shadow = body;
  for (Vector2d& p : shadow) p += shadow_per_m * height;
  std::vector<Vector2d> hull = body;
  hull.insert(hull.end(), shadow.begin(), shadow.end());
  std::vector<cv::Point2f> hull_points, hull_out;
  for (const Vector2d& p : hull)
    hull_points.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()));
  cv::convexHull(hull_points, hull_out);
  Polyline shadow_hull;
  for (const cv::Point2f& p : hull_out) shadow_hull.emplace_back(p.x, p.y);
  BlendPolygon(ProjectAll(image_from_ground, shadow_hull), cv::Scalar(0, 0, 0), 0.45, image);
  BlendPolygon(ProjectAll(image_from_ground, body), look.body_bgr, 1.0, image);
  const cv::Scalar glass(38, 34, 32);
  const cv::Scalar roof = look.body_bgr * 1.08;
  if (look.van) {
    BlendPolygon(ProjectAll(image_from_ground, VehicleBand(c, forward, l, 0.35, 0.75, hw - 0.15)),
                 glass, 1.0, image);
    BlendPolygon(ProjectAll(image_from_ground, VehicleBand(c, forward, l, 0.9, l - 0.15, hw - 0.1)),
                 roof, 1.0, image);
  } else {
    BlendPolygon(
        ProjectAll(image_from_ground, VehicleBand(c, forward, l, 0.27 * l, 0.42 * l, hw - 0.12)),
        glass, 1.0, image);
    BlendPolygon(
        ProjectAll(image_from_ground, VehicleBand(c, forward, l, 0.42 * l, 0.74 * l, hw - 0.18)),
        roof, 1.0, image);
    BlendPolygon(
        ProjectAll(image_from_ground, VehicleBand(c, forward, l, 0.74 * l, 0.86 * l, hw - 0.15)),
        glass, 1.0, image);
  }
}

void DrawPerson(const Eigen::Matrix3d& image_from_ground, const Vector2d& position,
                double heading_deg, const cv::Scalar& clothes_bgr, const Vector2d& shadow_per_m,
                cv::Mat* image) {
  const double heading = heading_deg * kDegToRad;
  const Vector2d forward(std::sin(heading), std::cos(heading));
  const Vector2d left(-forward.y(), forward.x());
  const auto ellipse = [&](const Vector2d& centre, const Vector2d& axis_a, const Vector2d& axis_b) {
    Polyline points;
    for (int k = 0; k < 12; ++k) {
      const double t = 2 * M_PI * k / 12;
      points.push_back(centre + axis_a * std::cos(t) + axis_b * std::sin(t));
    }
    return points;
  };
  // The shadow of a 1.7 m standing figure: a long thin ellipse from the feet away from the sun.
  const Vector2d tip = shadow_per_m * 1.7;
  const Vector2d dir = tip.norm() > 1e-6 ? static_cast<Vector2d>(tip.normalized()) : forward;
  BlendPolygon(ProjectAll(image_from_ground,
                          ellipse(position + tip / 2, tip / 2, Vector2d(-dir.y(), dir.x()) * 0.22)),
               cv::Scalar(0, 0, 0), 0.45, image);
  BlendPolygon(ProjectAll(image_from_ground, ellipse(position, forward * 0.16, left * 0.26)),
               clothes_bgr, 1.0, image);
  BlendPolygon(ProjectAll(image_from_ground, ellipse(position, forward * 0.11, left * 0.1)),
               cv::Scalar(40, 50, 70), 1.0, image);
}

size_t ProceduralGround::TileKeyHash::operator()(const TileKey& key) const {
  return static_cast<size_t>(
      HashCombine(static_cast<uint64_t>(key.col), static_cast<uint64_t>(key.row)));
}

ProceduralGround::ProceduralGround(std::shared_ptr<const World> world, double gsd_m,
                                   int cache_megabytes)
    : world_(std::move(world)), gsd_m_(gsd_m) {
  SAKER_CHECK(world_ != nullptr && gsd_m > 0);
  const size_t tile_bytes = static_cast<size_t>(kTileSize) * kTileSize * 3;
  max_tiles_ =
      std::max<size_t>(16, static_cast<size_t>(cache_megabytes) * 1024 * 1024 / tile_bytes);
}

std::shared_ptr<const cv::Mat> ProceduralGround::Tile(const TileKey& key) const {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    auto it = cache_.find(key);
    if (it != cache_.end()) {
      lru_.splice(lru_.begin(), lru_, it->second.lru);
      return it->second.bgr;
    }
  }
  // Painted outside the lock so threads paint different tiles at once; a tile painted twice by a
  // race is identical, so either copy may be kept.
  auto tile = std::make_shared<const cv::Mat>(PaintTile(key));
  std::lock_guard<std::mutex> lock(mutex_);
  auto it = cache_.find(key);
  if (it != cache_.end()) return it->second.bgr;
  lru_.push_front(key);
  cache_.emplace(key, CachedTile{tile, lru_.begin()});
  while (cache_.size() > max_tiles_) {
    cache_.erase(lru_.back());
    lru_.pop_back();
  }
  return tile;
}

void ProceduralGround::Render(const cv::Rect& region, cv::Mat* bgr, cv::Mat* valid) const {
  bgr->create(region.size(), CV_8UC3);
  valid->create(region.size(), CV_8U);
  const auto floor_div = [](int64_t a, int64_t b) { return a >= 0 ? a / b : -((-a + b - 1) / b); };
  const int64_t c0 = floor_div(region.x, kTileSize),
                c1 = floor_div(region.x + region.width - 1, kTileSize);
  const int64_t r0 = floor_div(region.y, kTileSize),
                r1 = floor_div(region.y + region.height - 1, kTileSize);
  for (int64_t tr = r0; tr <= r1; ++tr) {
    for (int64_t tc = c0; tc <= c1; ++tc) {
      const std::shared_ptr<const cv::Mat> tile = Tile({tc, tr});
      const cv::Rect tile_rect(static_cast<int>(tc * kTileSize), static_cast<int>(tr * kTileSize),
                               kTileSize, kTileSize);
      const cv::Rect overlap = tile_rect & region;
      if (overlap.empty()) continue;
      (*tile)(overlap - tile_rect.tl()).copyTo((*bgr)(overlap - region.tl()));
    }
  }
  // Valid where the pixel centre lies inside the world's extent: a rectangle of raster pixels.
  const cv::Rect2d& e = world_->extent_m;
  const int c_lo = static_cast<int>(std::ceil(e.x / gsd_m_)),
            c_hi = static_cast<int>(std::floor((e.x + e.width) / gsd_m_));
  const int r_lo = static_cast<int>(std::ceil(-(e.y + e.height) / gsd_m_)),
            r_hi = static_cast<int>(std::floor(-e.y / gsd_m_));
  const cv::Rect inside = cv::Rect(c_lo, r_lo, c_hi - c_lo + 1, r_hi - r_lo + 1) & region;
  valid->setTo(0);
  if (!inside.empty()) (*valid)(inside - region.tl()).setTo(255);
  if (inside != region) {
    cv::Mat outside;
    cv::bitwise_not(*valid, outside);
    bgr->setTo(cv::Scalar::all(0), outside);
  }
}

cv::Mat ProceduralGround::PaintTile(const TileKey& key) const {
  const World& w = *world_;
  TilePainter p(w, gsd_m_, key.col * kTileSize, key.row * kTileSize, kTileSize);
  PaintGroundLayer(w, p);
  // The ground layer in colour; everything else is laid over it, each layer over the last.
  cv::Mat image(kTileSize, kTileSize, CV_8UC3);
  p.Shade(p.ground(), &image, false);
  DrawRoadMarkings(w, p, &image);
  DarkenShadows(w, p, &image);
  LayRoofsAndCanopies(w, p, &image);
  DrawRoofDetailsAndParkedVehicles(w, p, &image);
  return image;
}

}  // namespace saker::sim
