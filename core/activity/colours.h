#pragma once

// How tracks are coloured on an activity map, shared by the exported pictures and the GUI so
// that a legend always means the same thing (docs/activity.md, "Colours"):
// - speed: relative average speed, red slowest to blue fastest (as in the paper), over the
//   5th to 95th percentile of the tracks' speeds;
// - direction: a colour wheel on the heading (north red, east yellow-green, south cyan, west
//   violet);
// - visit: first visit red, second blue, then green, orange, purple, brown (then repeating);
// - time: a sequential colour map (dark blue early to yellow late) over the mission's time span;
// - density: not the tracks but a heat map of their observations per cell (core/activity/
//   density.h); the tracks themselves are drawn neutral, or not at all.

#include "core/mission/mission.h"

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace saker::activity {

enum class ColourMode { kSpeed, kDirection, kVisit, kTime, kDensity };

// "speed", "direction", "visit", "time", "density"
const char* ColourModeName(ColourMode mode);
std::optional<ColourMode> ParseColourMode(std::string_view name);

struct Rgb {
  uint8_t r = 0, g = 0, b = 0;
  bool operator==(const Rgb& other) const { return r == other.r && g == other.g && b == other.b; }
};

// A legend: discrete entries (visit) or labelled stops along a continuous ramp (speed, time) or
// round a wheel (direction).
struct Legend {
  std::string title;  // e.g. "Average speed (m/s)"
  bool continuous = false;
  struct Entry {
    std::string label;
    Rgb colour;
    double position = 0;  // continuous legends: 0..1 along the ramp
  };
  std::vector<Entry> entries;
};

class TrackColouring {
 public:
  // The scale is fixed from `tracks` (speed percentiles, time span, visits seen);
  // `geo_referenced` chooses the speed unit and the direction words (compass points, or up,
  // right, down, left on a map in pixels).
  TrackColouring(ColourMode mode, const std::vector<mission::ActivityTrack>& tracks,
                 bool geo_referenced);

  ColourMode mode() const { return mode_; }
  Rgb ColourOf(const mission::ActivityTrack& track) const;
  // The colour at a position 0..1 of a continuous scale (speed, time, direction as heading/360).
  Rgb RampColour(double position) const;
  const Legend& legend() const { return legend_; }

 private:
  ColourMode mode_;
  double low_ = 0, high_ = 1;  // the scale's ends (speed or time)
  Legend legend_;
};

}  // namespace saker::activity
