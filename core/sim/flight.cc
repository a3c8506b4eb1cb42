#include "core/sim/flight.h"

#include "core/util/check.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <random>
#include <sstream>
#include <string>
#include <utility>

namespace saker::sim {
namespace {

constexpr double kPi = 3.14159265358979323846;

double Radians(double degrees) { return degrees * kPi / 180.0; }
double Degrees(double radians) { return radians * 180.0 / kPi; }

// Into [-180, 180).
double WrapSigned(double degrees) {
  return degrees - 360.0 * std::floor((degrees + 180.0) / 360.0);
}
// Into [0, 360).
double WrapPositive(double degrees) {
  const double wrapped = degrees - 360.0 * std::floor(degrees / 360.0);
  return wrapped >= 360.0 ? 0.0 : wrapped;  // -1e-17 wraps to 360 in floating point
}

// Heading of the direction (east, north), clockwise from north.
double HeadingOf(const Eigen::Vector2d& direction) {
  return Degrees(std::atan2(direction.x(), direction.y()));
}

// The road-loop scenario's minimum loop: anything shorter is a roundabout, not a loop of roads.
constexpr double kMinRoadLoopM = 200;

// The lemniscate and the raster turns are sampled finely enough that the polyline's chords are
// within centimetres of the curve and the heading smoothing sees many segments per window.
constexpr int kLemniscateSamples = 4096;
constexpr int kTurnSamples = 64;
constexpr int kOrbitSamples = 1440;

// Sinusoids per wander channel and their frequency band: periods from about 3 s to 50 s.
constexpr int kWanderTerms = 4;
constexpr double kWanderMinHz = 0.02;
constexpr double kWanderMaxHz = 0.3;

std::string Describe(const char* name, double value) {
  std::ostringstream text;
  text << "flight option " << name << " = " << value;
  return text.str();
}

Status CheckRange(const char* name, double value, double low, double high, const char* unit) {
  if (std::isfinite(value) && value >= low && value <= high) return Status::Ok();
  std::ostringstream message;
  message << Describe(name, value) << " is outside [" << low << ", " << high << "] " << unit;
  return InvalidArgumentError(message.str());
}

// A fraction in [0, 1): overlaps of 1 or more would never advance.
Status CheckFraction(const char* name, double value) {
  if (std::isfinite(value) && value >= 0.0 && value < 1.0) return Status::Ok();
  return InvalidArgumentError(Describe(name, value) + " must be in [0, 1)");
}

double PolylineLength(const std::vector<Eigen::Vector2d>& points) {
  double length = 0;
  for (size_t i = 1; i < points.size(); ++i) length += (points[i] - points[i - 1]).norm();
  return length;
}

// Uniform double in [0, 1) from the top 53 bits: unlike std::uniform_real_distribution, the same
// on every standard library, so a seed means the same flight everywhere.
double UnitDouble(std::mt19937_64& random) {
  return static_cast<double>(random() >> 11) * (1.0 / 9007199254740992.0);
}

std::vector<Eigen::Vector2d> RoundaboutLoopPoints(const FlightSite& site, double extension_m) {
  std::vector<Eigen::Vector2d> loop = site.road_loop;
  if ((loop.back() - loop.front()).norm() > 1e-6) loop.push_back(loop.front());
  std::vector<Eigen::Vector2d> points = loop;
  // On past the start along the loop (round again if the extension is longer than the loop).
  double remaining = extension_m;
  for (size_t i = 1; remaining > 0.0; i = i % (loop.size() - 1) + 1) {
    const double step = (loop[i] - points.back()).norm();
    if (step >= remaining) {
      points.push_back(points.back() + (loop[i] - points.back()) * (remaining / step));
      break;
    }
    points.push_back(loop[i]);
    remaining -= step;
  }
  return points;
}

// Lemniscate of Bernoulli x = a cos t / (1 + sin^2 t), y = a sin t cos t / (1 + sin^2 t) for t
// from pi to 3 pi: from the western tip (-a, 0) north-east into the centre, round the eastern lobe
// and back through the centre to the start.
std::vector<Eigen::Vector2d> FigureEightPoints(const Eigen::Vector2d& centre, double length_m) {
  std::vector<Eigen::Vector2d> unit(kLemniscateSamples + 1);
  for (int i = 0; i <= kLemniscateSamples; ++i) {
    const double t = kPi + 2.0 * kPi * i / kLemniscateSamples;
    const double denominator = 1.0 + std::sin(t) * std::sin(t);
    unit[i] = Eigen::Vector2d(std::cos(t), std::sin(t) * std::cos(t)) / denominator;
  }
  unit.back() = unit.front();  // close exactly
  const double scale = length_m / PolylineLength(unit);
  std::vector<Eigen::Vector2d> points;
  points.reserve(unit.size());
  for (const Eigen::Vector2d& p : unit) points.push_back(centre + scale * p);
  return points;
}

std::vector<Eigen::Vector2d> RasterPoints(const Eigen::Vector2d& centre, int rows,
                                          double row_length_m, double spacing_m) {
  std::vector<Eigen::Vector2d> points;
  const double west = centre.x() - 0.5 * row_length_m;
  const double east = centre.x() + 0.5 * row_length_m;
  const double radius = 0.5 * spacing_m;
  for (int row = 0; row < rows; ++row) {
    const double y = centre.y() + (row - 0.5 * (rows - 1)) * spacing_m;
    const bool eastbound = row % 2 == 0;
    points.emplace_back(eastbound ? west : east, y);
    points.emplace_back(eastbound ? east : west, y);
    if (row + 1 == rows) break;
    // Semicircle to the next row to the north: a left turn at the east end, a right turn at the
    // west end, both from angle -90 degrees (south of the turn centre) to +-90.
    const Eigen::Vector2d turn_centre(eastbound ? east : west, y + radius);
    for (int i = 1; i < kTurnSamples; ++i) {
      const double sweep = kPi * i / kTurnSamples;
      const double angle = -0.5 * kPi + (eastbound ? sweep : -sweep);
      points.push_back(turn_centre + radius * Eigen::Vector2d(std::cos(angle), std::sin(angle)));
    }
  }
  return points;
}

}  // namespace

const char* ScenarioName(Scenario scenario) {
  switch (scenario) {
    case Scenario::kRoundaboutLoop:
      return "roundabout-loop";
    case Scenario::kFigureEight:
      return "figure-eight";
    case Scenario::kRaster:
      return "raster";
    case Scenario::kStraight:
      return "straight";
    case Scenario::kOrbit:
      return "orbit";
  }
  return "unknown";
}

std::optional<Scenario> ParseScenario(std::string_view name) {
  for (Scenario scenario : AllScenarios()) {
    if (name == ScenarioName(scenario)) return scenario;
  }
  return std::nullopt;
}

std::vector<Scenario> AllScenarios() {
  return {Scenario::kRoundaboutLoop, Scenario::kFigureEight, Scenario::kRaster, Scenario::kStraight,
          Scenario::kOrbit};
}

const char* ScenarioDescription(Scenario scenario) {
  switch (scenario) {
    case Scenario::kRoundaboutLoop:
      return "once round the road loop from the roundabout, ending over the first frames";
    case Scenario::kFigureEight:
      return "a figure eight from its western tip: crosses itself in the middle, ends at the start";
    case Scenario::kRaster:
      return "east-west survey rows joined by semicircular turns, adjacent rows overlapping";
    case Scenario::kStraight:
      return "a straight line through the centre of the world";
    case Scenario::kOrbit:
      return "circles the centre of the world anticlockwise, the camera staring at it";
  }
  return "unknown scenario";
}

Status FlightOptions::Validate() const {
  SAKER_RETURN_IF_ERROR(CheckRange("altitude_m", altitude_m, 10, 10000, "m"));
  if (!(speed_mps > 0.0 && speed_mps <= 300.0)) {
    return InvalidArgumentError(Describe("speed_mps", speed_mps) + " must be in (0, 300] m/s");
  }
  SAKER_RETURN_IF_ERROR(CheckRange("attitude_jitter_deg", attitude_jitter_deg, 0, 10, "deg"));
  // The wander peaks below 3 sigma (kWanderTerms sinusoids), so this keeps the camera well clear
  // of the ground.
  SAKER_RETURN_IF_ERROR(CheckRange("altitude_jitter_m", altitude_jitter_m, 0, 0.1 * altitude_m,
                                   "m (a tenth of the altitude)"));
  SAKER_RETURN_IF_ERROR(
      CheckRange("figure_eight_key_frames", figure_eight_key_frames, 8, 100000, "frames"));
  SAKER_RETURN_IF_ERROR(CheckFraction("key_frame_overlap", key_frame_overlap));
  SAKER_RETURN_IF_ERROR(CheckRange("raster_rows", raster_rows, 1, 1000, "rows"));
  SAKER_RETURN_IF_ERROR(CheckRange("raster_row_length_m", raster_row_length_m, 1, 1e6, "m"));
  SAKER_RETURN_IF_ERROR(CheckFraction("raster_sidelap", raster_sidelap));
  SAKER_RETURN_IF_ERROR(CheckRange("straight_length_m", straight_length_m, 1, 1e6, "m"));
  SAKER_RETURN_IF_ERROR(CheckRange("straight_heading_deg", straight_heading_deg, -360, 360, "deg"));
  SAKER_RETURN_IF_ERROR(CheckRange("orbit_radius_m", orbit_radius_m, 10, 1e5, "m"));
  SAKER_RETURN_IF_ERROR(CheckRange("gimbal_off_nadir_deg", gimbal_off_nadir_deg, 0, 88, "deg"));
  SAKER_RETURN_IF_ERROR(CheckRange("gimbal_azimuth_deg", gimbal_azimuth_deg, -360, 360, "deg"));
  return Status::Ok();
}

GroundTrack::GroundTrack(std::vector<Eigen::Vector2d> points) {
  for (const Eigen::Vector2d& p : points) {
    SAKER_CHECK(p.allFinite()) << "ground track point is not finite";
    if (points_.empty() || (p - points_.back()).norm() > 0.0) points_.push_back(p);
  }
  SAKER_CHECK(points_.size() >= 2) << "a ground track needs two distinct points";
  cumulative_m_.push_back(0.0);
  heading_integral_.push_back(0.0);
  for (size_t i = 1; i < points_.size(); ++i) {
    const Eigen::Vector2d step = points_[i] - points_[i - 1];
    const double raw = HeadingOf(step);
    const double heading =
        segment_heading_deg_.empty()
            ? raw
            : segment_heading_deg_.back() + WrapSigned(raw - segment_heading_deg_.back());
    segment_heading_deg_.push_back(heading);
    cumulative_m_.push_back(cumulative_m_.back() + step.norm());
    heading_integral_.push_back(heading_integral_.back() + heading * step.norm());
  }
}

size_t GroundTrack::SegmentAt(double s) const {
  const auto after = std::upper_bound(cumulative_m_.begin(), cumulative_m_.end(), s);
  const ptrdiff_t index = (after - cumulative_m_.begin()) - 1;
  return static_cast<size_t>(
      std::clamp<ptrdiff_t>(index, 0, static_cast<ptrdiff_t>(segment_heading_deg_.size()) - 1));
}

Eigen::Vector2d GroundTrack::PointAt(double s) const {
  s = std::clamp(s, 0.0, length_m());
  const size_t i = SegmentAt(s);
  const double segment = cumulative_m_[i + 1] - cumulative_m_[i];
  const double f = std::clamp((s - cumulative_m_[i]) / segment, 0.0, 1.0);
  return points_[i] + f * (points_[i + 1] - points_[i]);
}

double GroundTrack::HeadingIntegral(double s) const {
  if (s <= 0.0) return segment_heading_deg_.front() * s;
  if (s >= length_m()) {
    return heading_integral_.back() + segment_heading_deg_.back() * (s - length_m());
  }
  const size_t i = SegmentAt(s);
  return heading_integral_[i] + segment_heading_deg_[i] * (s - cumulative_m_[i]);
}

double GroundTrack::HeadingAt(double s) const {
  s = std::clamp(s, 0.0, length_m());
  const double mean =
      (HeadingIntegral(s + kHeadingWindowM) - HeadingIntegral(s - kHeadingWindowM)) /
      (2.0 * kHeadingWindowM);
  return WrapPositive(mean);
}

double Flight::Wander::At(double t_s) const {
  double sum = 0;
  for (const Term& term : terms) {
    sum += term.amplitude * std::sin(2.0 * kPi * term.frequency_hz * t_s + term.phase_rad);
  }
  return sum;
}

Flight::Flight(Scenario scenario, const FlightOptions& options, GroundTrack track)
    : scenario_(scenario), options_(options), track_(std::move(track)) {
  std::mt19937_64 random(options.seed);
  // Every channel draws its terms whatever its sigma, so changing one sigma leaves the others'
  // noise unchanged. A sum of n sinusoids of amplitude A has variance n A^2 / 2.
  const double per_term = std::sqrt(2.0 / kWanderTerms);
  const std::array<std::pair<Wander*, double>, 4> channels = {
      {{&heading_, options.attitude_jitter_deg},
       {&pitch_, options.attitude_jitter_deg},
       {&roll_, options.attitude_jitter_deg},
       {&altitude_, options.altitude_jitter_m}}};
  for (const auto& [wander, sigma] : channels) {
    for (int i = 0; i < kWanderTerms; ++i) {
      const double frequency = kWanderMinHz + (kWanderMaxHz - kWanderMinHz) * UnitDouble(random);
      const double phase = 2.0 * kPi * UnitDouble(random);
      wander->terms.push_back({sigma * per_term, frequency, phase});
    }
  }
}

StatusOr<Flight> Flight::Create(Scenario scenario, const FlightOptions& options,
                                const CameraIntrinsics& intrinsics, const FlightSite& site) {
  SAKER_RETURN_IF_ERROR(options.Validate());
  SAKER_RETURN_IF_ERROR(intrinsics.Validate());
  if (!site.centre.allFinite()) return InvalidArgumentError("flight site centre is not finite");
  const double gsd = NadirGsd(intrinsics, options.altitude_m);
  const double along_track_m = intrinsics.height * gsd;
  const double across_track_m = intrinsics.width * gsd;

  std::vector<Eigen::Vector2d> points;
  switch (scenario) {
    case Scenario::kRoundaboutLoop: {
      for (const Eigen::Vector2d& p : site.road_loop) {
        if (!p.allFinite())
          return InvalidArgumentError("roundabout-loop: a road loop point is not finite");
      }
      double length = PolylineLength(site.road_loop);
      if (!site.road_loop.empty()) length += (site.road_loop.back() - site.road_loop[0]).norm();
      if (length < kMinRoadLoopM) {
        std::ostringstream message;
        message << "roundabout-loop: the world's road loop is "
                << (site.road_loop.empty() ? "missing" : "too short") << " (" << length
                << " m, at least " << kMinRoadLoopM << " m needed)";
        return InvalidArgumentError(message.str());
      }
      // Half a footprint past the start: the last frame covers half of the first (loop closure).
      points = RoundaboutLoopPoints(site, 0.5 * along_track_m);
      break;
    }
    case Scenario::kFigureEight: {
      const double advance_m = (1.0 - options.key_frame_overlap) * along_track_m;
      points = FigureEightPoints(site.centre, options.figure_eight_key_frames * advance_m);
      break;
    }
    case Scenario::kRaster:
      points = RasterPoints(site.centre, options.raster_rows, options.raster_row_length_m,
                            (1.0 - options.raster_sidelap) * across_track_m);
      break;
    case Scenario::kStraight: {
      const double heading = Radians(options.straight_heading_deg);
      const Eigen::Vector2d half =
          0.5 * options.straight_length_m * Eigen::Vector2d(std::sin(heading), std::cos(heading));
      points = {site.centre - half, site.centre + half};
      break;
    }
    case Scenario::kOrbit: {
      // Anticlockwise from the south of the centre, heading east, once round.
      const double r = options.orbit_radius_m;
      for (int i = 0; i <= kOrbitSamples; ++i) {
        const double angle = -0.5 * kPi + 2.0 * kPi * i / kOrbitSamples;
        points.push_back(site.centre + r * Eigen::Vector2d(std::cos(angle), std::sin(angle)));
      }
      break;
    }
  }
  Flight flight(scenario, options, GroundTrack(std::move(points)));
  flight.stare_point_ = site.centre;
  return flight;
}

double Flight::duration_s() const { return track_.length_m() / options_.speed_mps; }

CameraPose Flight::PoseAt(double t_s) const {
  const double t = std::clamp(t_s, 0.0, duration_s());
  const double s = t * options_.speed_mps;
  CameraPose pose;
  const Eigen::Vector2d ground = track_.PointAt(s);
  pose.position_m = {ground.x(), ground.y(), options_.altitude_m + altitude_.At(t)};
  const double track_heading = track_.HeadingAt(s);
  pose.heading_deg = WrapPositive(track_heading + heading_.At(t));
  pose.pitch_deg = pitch_.At(t);
  pose.roll_deg = roll_.At(t);
  if (scenario_ == Scenario::kOrbit) {
    // Stare: point the gimbal at the centre from the level platform on its track; the attitude
    // wander then moves the view about it as a real stabilised gimbal's residual motion does.
    const Eigen::Vector2d to_point = stare_point_ - ground;
    const double h = Radians(track_heading);
    const double forward = to_point.y() * std::cos(h) + to_point.x() * std::sin(h);
    const double right = -to_point.y() * std::sin(h) + to_point.x() * std::cos(h);
    pose.gimbal_azimuth_deg = WrapPositive(Degrees(std::atan2(right, forward)));
    pose.gimbal_off_nadir_deg =
        Degrees(std::atan2(std::hypot(forward, right), pose.position_m.z()));
  } else {
    pose.gimbal_azimuth_deg = options_.gimbal_azimuth_deg;
    pose.gimbal_off_nadir_deg = options_.gimbal_off_nadir_deg;
  }
  return pose;
}

}  // namespace saker::sim
