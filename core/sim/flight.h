#pragma once

// Flights for the simulator: named scenarios laid out over the world, flown at constant speed and
// altitude along a ground track, with smooth deterministic attitude and altitude wander.
//
// The camera looks straight down with image up along the direction of travel (camera.h), so a
// frame's along-track footprint is image height x GSD and its across-track footprint is
// image width x GSD (nadir, at the nominal altitude). Scenarios are sized from those footprints:
//
//   roundabout-loop  from the roundabout once round the world's road loop, then on along the start
//                    of the loop for one along-track footprint, so the last frames overlap the
//                    first (one loop closure on the roads).
//   figure-eight     a lemniscate of Bernoulli around the site centre, long axis east-west,
//   starting
//                    at its western tip and flown once round: it crosses itself in the middle and
//                    closes at the start (two loop closures). Its length is figure_eight_key_frames
//                    key-frame advances, advance = (1 - key_frame_overlap) x along-track footprint.
//   raster           raster_rows east-west rows centred on the site centre, the first (southern)
//   row
//                    flown east, joined by semicircular turns; row spacing =
//                    (1 - raster_sidelap) x across-track footprint.
//   straight         a straight line through the site centre at straight_heading_deg.
//   orbit            a circle of orbit_radius_m round the site centre, flown anticlockwise (the
//                    centre on the left), the camera staring at the centre: the most common
//                    pattern of real full-motion video. One turn; --duration cuts it short.
//
// The gimbal is assumed to hold the camera level: turns do not bank it; only the jitter tilts it.
// It points the camera gimbal_off_nadir_deg off nadir towards gimbal_azimuth_deg (0 forward, 90
// to the right), except in the orbit, where it stares at the centre (off nadir by
// atan(radius / altitude)).

#include "core/sim/camera.h"
#include "core/util/status.h"

#include <Eigen/Core>

#include <cstdint>
#include <optional>
#include <string_view>
#include <vector>

namespace saker::sim {

enum class Scenario { kRoundaboutLoop, kFigureEight, kRaster, kStraight, kOrbit };

// "roundabout-loop", "figure-eight", "raster", "straight".
const char* ScenarioName(Scenario scenario);
// Inverse of ScenarioName (exact, lower case); nullopt for anything else.
std::optional<Scenario> ParseScenario(std::string_view name);
std::vector<Scenario> AllScenarios();
// One line for --help and the docs.
const char* ScenarioDescription(Scenario scenario);

struct FlightOptions {
  double altitude_m = 400;  // above the ground plane
  double speed_mps = 15;    // ground speed along the track
  // 1 sigma of the pitch, roll and heading wander, in degrees; smooth, with periods of seconds.
  double attitude_jitter_deg = 0.3;
  double altitude_jitter_m = 2;  // 1 sigma, smooth
  uint64_t seed = 1;             // the same seed gives bit-identical poses

  // Figure-eight size: about this many key frames at this overlap along the path.
  int figure_eight_key_frames = 75;
  double key_frame_overlap = 0.3;
  // Raster: rows, their length, and the overlap of adjacent rows' footprints.
  int raster_rows = 4;
  double raster_row_length_m = 800;
  double raster_sidelap = 0.3;
  // Straight line through the site centre.
  double straight_length_m = 1000;
  double straight_heading_deg = 90;  // clockwise from north
  // Orbit: radius of the circle round the site centre.
  double orbit_radius_m = 400;
  // Oblique views (every scenario but the orbit): the camera's angle off nadir (0 .. 88 degrees;
  // from about 70 a default lens sees the horizon and the sky) and the direction it leans,
  // clockwise from the nose (0 forward, 90 right, 270 left).
  double gimbal_off_nadir_deg = 0;
  double gimbal_azimuth_deg = 0;

  Status Validate() const;
};

// Where the world puts things. The flight is laid out around `centre`; the roundabout loop follows
// `road_loop`, a closed polyline along the roads (first point = last point = the roundabout
// centre) of about 1 km. An open road_loop is closed with a straight segment back to its start.
struct FlightSite {
  Eigen::Vector2d centre{0, 0};
  std::vector<Eigen::Vector2d> road_loop;
};

// A ground track (east-north metres) parameterised by arc length s.
class GroundTrack {
 public:
  // Needs at least two distinct points (SAKER_CHECK); repeated consecutive points are dropped.
  explicit GroundTrack(std::vector<Eigen::Vector2d> points);

  double length_m() const { return cumulative_m_.back(); }
  // The point at arc length s, clamped to [0, length].
  Eigen::Vector2d PointAt(double s) const;
  // Direction of travel in degrees clockwise from north, in [0, 360), smoothed over
  // +-kHeadingWindowM of track: the average of the (unwrapped) segment headings over that window.
  // Averaging angles rather than positions makes corners turn gradually and keeps a hairpin (even
  // a 180-degree reversal on the spot) from flipping the heading in one step.
  double HeadingAt(double s) const;
  const std::vector<Eigen::Vector2d>& points() const { return points_; }

  static constexpr double kHeadingWindowM = 20;

 private:
  // Integral of the unwrapped heading (degrees x metres) from 0 to s; s may lie outside the
  // track, where the heading of the first or last segment continues.
  double HeadingIntegral(double s) const;
  // Index of the segment containing s in [0, length].
  size_t SegmentAt(double s) const;

  std::vector<Eigen::Vector2d> points_;
  std::vector<double> cumulative_m_;         // arc length at each point
  std::vector<double> segment_heading_deg_;  // unwrapped: consecutive values differ by <= 180
  std::vector<double> heading_integral_;     // HeadingIntegral at each point
};

class Flight {
 public:
  // Lays out `scenario` over `site`. Fails on invalid options or intrinsics, or when the site
  // lacks what the scenario needs (roundabout-loop: a road loop of at least 200 m).
  static StatusOr<Flight> Create(Scenario scenario, const FlightOptions& options,
                                 const CameraIntrinsics& intrinsics, const FlightSite& site);

  Scenario scenario() const { return scenario_; }
  const FlightOptions& options() const { return options_; }
  const GroundTrack& track() const { return track_; }
  double duration_s() const;  // track length / speed
  // Deterministic function of (scenario, options, intrinsics, site, t); t is clamped to
  // [0, duration].
  CameraPose PoseAt(double t_s) const;

 private:
  // Smooth zero-mean noise: a sum of sinusoids with seeded frequencies and phases.
  struct Wander {
    struct Term {
      double amplitude;
      double frequency_hz;
      double phase_rad;
    };
    std::vector<Term> terms;
    double At(double t_s) const;
  };

  Flight(Scenario scenario, const FlightOptions& options, GroundTrack track);

  Scenario scenario_;
  FlightOptions options_;
  GroundTrack track_;
  Eigen::Vector2d stare_point_{0, 0};  // orbit: the point the camera stares at
  Wander heading_, pitch_, roll_, altitude_;
};

}  // namespace saker::sim
