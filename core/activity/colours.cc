#include "core/activity/colours.h"

#include "core/activity/density.h"
#include "core/util/statistics.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>

namespace saker::activity {
namespace {

constexpr Rgb kNeutralTrack{235, 235, 235};  // a track in the density mode

// Hue in degrees, saturation and value in [0, 1].
Rgb FromHsv(double hue, double saturation, double value) {
  hue = std::fmod(std::fmod(hue, 360.0) + 360.0, 360.0);
  const double c = value * saturation;
  const double x = c * (1 - std::abs(std::fmod(hue / 60.0, 2.0) - 1));
  const double m = value - c;
  double r = 0, g = 0, b = 0;
  switch (static_cast<int>(hue / 60.0)) {
    case 0:
      r = c, g = x;
      break;
    case 1:
      r = x, g = c;
      break;
    case 2:
      g = c, b = x;
      break;
    case 3:
      g = x, b = c;
      break;
    case 4:
      r = x, b = c;
      break;
    default:
      r = c, b = x;
      break;
  }
  const auto byte = [](double v) {
    return static_cast<uint8_t>(std::lround(std::clamp(v, 0.0, 1.0) * 255));
  };
  return {byte(r + m), byte(g + m), byte(b + m)};
}

// A perceptually ordered dark-blue to yellow ramp (control points of the viridis map).
Rgb Sequential(double t) {
  static constexpr std::array<std::array<double, 3>, 5> kStops = {
      {{68, 1, 84}, {59, 82, 139}, {33, 145, 140}, {94, 201, 98}, {253, 231, 37}}};
  t = std::clamp(t, 0.0, 1.0) * static_cast<double>(kStops.size() - 1);
  const size_t i = std::min(static_cast<size_t>(t), kStops.size() - 2);
  const double f = t - static_cast<double>(i);
  Rgb out;
  uint8_t* channels[3] = {&out.r, &out.g, &out.b};
  for (size_t c = 0; c < 3; ++c) {
    *channels[c] = static_cast<uint8_t>(std::lround(kStops[i][c] * (1 - f) + kStops[i + 1][c] * f));
  }
  return out;
}

Rgb VisitColour(int visit) {
  static constexpr std::array<Rgb, 6> kVisits = {
      {{220, 40, 40}, {40, 90, 220}, {40, 170, 60}, {240, 150, 20}, {150, 60, 190}, {140, 90, 50}}};
  return kVisits[static_cast<size_t>(std::max(visit, 1) - 1) % kVisits.size()];
}

std::string Ordinal(int n) {
  const char* suffix = "th";
  if (n % 100 < 11 || n % 100 > 13) {
    if (n % 10 == 1) suffix = "st";
    if (n % 10 == 2) suffix = "nd";
    if (n % 10 == 3) suffix = "rd";
  }
  return std::to_string(n) + suffix;
}

std::string Clock(double seconds) {
  char text[32];
  const long total = std::lround(std::max(seconds, 0.0));
  std::snprintf(text, sizeof(text), "%ld:%02ld", total / 60, total % 60);
  return text;
}

}  // namespace

const char* ColourModeName(ColourMode mode) {
  switch (mode) {
    case ColourMode::kSpeed:
      return "speed";
    case ColourMode::kDirection:
      return "direction";
    case ColourMode::kVisit:
      return "visit";
    case ColourMode::kTime:
      return "time";
    case ColourMode::kDensity:
      return "density";
  }
  return "speed";
}

std::optional<ColourMode> ParseColourMode(std::string_view name) {
  for (const ColourMode mode : {ColourMode::kSpeed, ColourMode::kDirection, ColourMode::kVisit,
                                ColourMode::kTime, ColourMode::kDensity}) {
    if (name == ColourModeName(mode)) return mode;
  }
  return std::nullopt;
}

TrackColouring::TrackColouring(ColourMode mode, const std::vector<mission::ActivityTrack>& tracks,
                               bool geo_referenced)
    : mode_(mode) {
  switch (mode) {
    case ColourMode::kSpeed: {
      std::vector<double> speeds;
      for (const mission::ActivityTrack& t : tracks) speeds.push_back(t.speed);
      low_ = Quantile(speeds, 0.05);
      high_ = Quantile(speeds, 0.95);
      if (!(high_ > low_)) high_ = low_ + 1;
      legend_.title = geo_referenced ? "Average speed (m/s)" : "Average speed (pixels/s)";
      legend_.continuous = true;
      for (int i = 0; i <= 4; ++i) {
        const double p = i / 4.0;
        char label[32];
        std::snprintf(label, sizeof(label), "%.1f", low_ + p * (high_ - low_));
        legend_.entries.push_back({label, RampColour(p), p});
      }
      break;
    }
    case ColourMode::kDirection: {
      // A map in pixels has no north: its directions are those of its picture (heading 0 is up).
      static constexpr const char* kCompass[] = {"N", "E", "S", "W", "N"};
      static constexpr const char* kPicture[] = {"up", "right", "down", "left", "up"};
      legend_.title = geo_referenced ? "Direction of travel" : "Direction of travel (on the map)";
      legend_.continuous = true;
      for (int i = 0; i < 5; ++i) {
        const double p = i / 4.0;
        legend_.entries.push_back({geo_referenced ? kCompass[i] : kPicture[i], RampColour(p), p});
      }
      break;
    }
    case ColourMode::kVisit: {
      int visits = 1;
      for (const mission::ActivityTrack& t : tracks) visits = std::max(visits, t.visit);
      legend_.title = "Visit";
      for (int v = 1; v <= std::min(visits, 12); ++v) {
        legend_.entries.push_back({Ordinal(v) + " visit", VisitColour(v), 0});
      }
      break;
    }
    case ColourMode::kTime: {
      low_ = tracks.empty() ? 0 : tracks.front().start_s;
      high_ = low_;
      for (const mission::ActivityTrack& t : tracks) {
        low_ = std::min(low_, t.start_s);
        high_ = std::max(high_, t.end_s);
      }
      if (!(high_ > low_)) high_ = low_ + 1;
      legend_.title = "Time in the video (m:ss)";
      legend_.continuous = true;
      for (int i = 0; i <= 4; ++i) {
        const double p = i / 4.0;
        legend_.entries.push_back({Clock(low_ + p * (high_ - low_)), RampColour(p), p});
      }
      break;
    }
    case ColourMode::kDensity: {
      std::vector<const mission::ActivityTrack*> all;
      for (const mission::ActivityTrack& t : tracks) all.push_back(&t);
      legend_ = DensityLegend(CountObservations(all, geo_referenced), geo_referenced);
      break;
    }
  }
}

Rgb TrackColouring::RampColour(double position) const {
  position = std::clamp(position, 0.0, 1.0);
  switch (mode_) {
    case ColourMode::kSpeed:
      return FromHsv(240 * position, 0.9, 0.95);
    case ColourMode::kDirection:
      return FromHsv(360 * position, 0.85, 0.95);
    case ColourMode::kVisit:
      return VisitColour(1 + static_cast<int>(position * 5));
    case ColourMode::kTime:
      return Sequential(position);
    case ColourMode::kDensity:
      return DensityRamp(position);
  }
  return {};
}

Rgb TrackColouring::ColourOf(const mission::ActivityTrack& track) const {
  switch (mode_) {
    case ColourMode::kSpeed:
      return RampColour((track.speed - low_) / (high_ - low_));
    case ColourMode::kDirection:
      return RampColour(track.heading_deg / 360.0);
    case ColourMode::kVisit:
      return VisitColour(track.visit);
    case ColourMode::kTime:
      return RampColour((0.5 * (track.start_s + track.end_s) - low_) / (high_ - low_));
    case ColourMode::kDensity:
      return kNeutralTrack;
  }
  return {};
}

}  // namespace saker::activity
