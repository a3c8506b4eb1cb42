#pragma once

// Activity density (the heat map colour mode): how many track observations fall in each cell of
// a square grid on the map, and the colours that show it. Shared by the exported activity map
// and the GUI so that the two read alike (docs/activity.md, "Density").

#include "core/activity/colours.h"
#include "core/mission/mission.h"

#include <Eigen/Core>

#include <cstdint>
#include <vector>

namespace saker::activity {

struct DensityGrid {
  // The map point at the corner of cell (0, 0), lowest x and y: half a cell before the lowest
  // observation.
  Eigen::Vector2d origin{0, 0};
  double cell = 1;  // side of a cell, map units (metres on a geo-referenced map)
  int cols = 0, rows = 0;
  std::vector<uint32_t> counts;  // row-major; row r spans y in [origin.y + r cell, + cell)
  uint32_t max = 0;              // the largest count
  uint32_t At(int col, int row) const {
    return counts[static_cast<size_t>(row) * static_cast<size_t>(cols) + static_cast<size_t>(col)];
  }
};

// The observations of `tracks` counted per cell. The cell is 1/128 of the observations' extent,
// at least 4 m on a geo-referenced map (a car's length, a lane and its kerb) and 8 map pixels
// otherwise, so that the grid has at most 129 cells a side whatever the mission. Empty (no
// cells) without observations.
DensityGrid CountObservations(const std::vector<const mission::ActivityTrack*>& tracks,
                              bool geo_referenced);

// Where a count lies on the density scale, 0..1: logarithmic (log count / log max), so that
// places passed once still show beside a junction where cars waited; 0 only for an empty cell.
double DensityPosition(uint32_t count, uint32_t max);
// The colour (pale yellow through orange and red to dark red) and opacity (0.45 to 0.85) of a
// position on that scale; position 0 is transparent.
Rgb DensityRamp(double position);
uint8_t DensityAlpha(double position);

// The legend of a grid: observations per cell (its side named), from 1 to the largest count.
Legend DensityLegend(const DensityGrid& grid, bool geo_referenced);

}  // namespace saker::activity
