#include "core/activity/density.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>

namespace saker::activity {

DensityGrid CountObservations(const std::vector<const mission::ActivityTrack*>& tracks,
                              bool geo_referenced) {
  DensityGrid grid;
  Eigen::Vector2d lo = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector2d hi = -lo;
  for (const mission::ActivityTrack* track : tracks) {
    for (const mission::TrackPoint& p : track->points) {
      if (!p.map.allFinite()) continue;
      lo = lo.cwiseMin(p.map);
      hi = hi.cwiseMax(p.map);
    }
  }
  if (!lo.allFinite()) return grid;
  constexpr int kCellsAcross = 128;
  grid.cell = std::max((hi - lo).maxCoeff() / kCellsAcross, geo_referenced ? 4.0 : 8.0);
  // Half a cell of margin: the extreme observations lie mid-cell, so that a picture interpolated
  // between cell centres shows them at full strength, not half.
  grid.origin = lo - Eigen::Vector2d::Constant(grid.cell / 2);
  grid.cols = static_cast<int>(std::floor((hi.x() - lo.x()) / grid.cell + 0.5)) + 1;
  grid.rows = static_cast<int>(std::floor((hi.y() - lo.y()) / grid.cell + 0.5)) + 1;
  grid.counts.assign(static_cast<size_t>(grid.cols) * static_cast<size_t>(grid.rows), 0);
  for (const mission::ActivityTrack* track : tracks) {
    for (const mission::TrackPoint& p : track->points) {
      if (!p.map.allFinite()) continue;
      const Eigen::Vector2d at = (p.map - grid.origin) / grid.cell;
      const int c = std::min(grid.cols - 1, static_cast<int>(at.x()));
      const int r = std::min(grid.rows - 1, static_cast<int>(at.y()));
      uint32_t& n = grid.counts[static_cast<size_t>(r) * static_cast<size_t>(grid.cols) +
                                static_cast<size_t>(c)];
      ++n;
      grid.max = std::max(grid.max, n);
    }
  }
  return grid;
}

double DensityPosition(uint32_t count, uint32_t max) {
  if (count == 0 || max == 0) return 0;
  if (max == 1) return 1;
  // A single observation sits at the scale's start, not at 0 (which is nothing, transparent).
  return std::clamp(std::log(static_cast<double>(count)) / std::log(static_cast<double>(max)), 1e-3,
                    1.0);
}

Rgb DensityRamp(double position) {
  // Pale yellow, orange, red, dark red: warm and unlike any ground colour or track ramp.
  static constexpr std::array<std::array<double, 3>, 4> kStops = {
      {{255, 240, 120}, {253, 141, 60}, {220, 30, 30}, {110, 0, 20}}};
  const double t = std::clamp(position, 0.0, 1.0) * static_cast<double>(kStops.size() - 1);
  const size_t i = std::min(static_cast<size_t>(t), kStops.size() - 2);
  const double f = t - static_cast<double>(i);
  const auto mix = [&](size_t c) {
    return static_cast<uint8_t>(std::lround(kStops[i][c] * (1 - f) + kStops[i + 1][c] * f));
  };
  return {mix(0), mix(1), mix(2)};
}

uint8_t DensityAlpha(double position) {
  if (!(position > 0)) return 0;
  return static_cast<uint8_t>(std::lround(255 * (0.45 + 0.4 * std::clamp(position, 0.0, 1.0))));
}

Legend DensityLegend(const DensityGrid& grid, bool geo_referenced) {
  Legend legend;
  char title[80];
  if (geo_referenced) {
    std::snprintf(title, sizeof(title), "Observations per %.*f m cell", grid.cell < 10 ? 1 : 0,
                  grid.cell);
  } else {
    std::snprintf(title, sizeof(title), "Observations per %.0f px cell", grid.cell);
  }
  legend.title = title;
  legend.continuous = true;
  const uint32_t max = std::max<uint32_t>(grid.max, 1);
  for (int i = 0; i <= 4; ++i) {
    const double p = i / 4.0;
    // The count at position p: the inverse of DensityPosition.
    const double count = std::pow(static_cast<double>(max), p);
    char label[32];
    std::snprintf(label, sizeof(label), "%.0f", std::round(count));
    legend.entries.push_back({label, DensityRamp(std::max(p, 1e-3)), p});
  }
  return legend;
}

}  // namespace saker::activity
