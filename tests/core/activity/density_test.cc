// The density colour mode's grid, scale, colours and legend on hand-made tracks.

#include "core/activity/density.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace saker::activity {
namespace {

mission::ActivityTrack TrackThrough(const std::vector<Eigen::Vector2d>& points) {
  mission::ActivityTrack track;
  for (const Eigen::Vector2d& p : points) {
    mission::TrackPoint point;
    point.map = p;
    track.points.push_back(point);
  }
  return track;
}

TEST(DensityTest, CountsObservationsPerCellWithAFloorOnTheCell) {
  // 100 m across: 100 / 128 m would be finer than the 4 m floor on a geo-referenced map.
  const mission::ActivityTrack a = TrackThrough({{0, 0}, {1, 1}, {2, 3}, {100, 50}});
  const mission::ActivityTrack b = TrackThrough({{1.5, 0.5}, {50, 20}});
  const DensityGrid grid = CountObservations({&a, &b}, /*geo_referenced=*/true);
  EXPECT_DOUBLE_EQ(grid.cell, 4);
  EXPECT_EQ(grid.origin, Eigen::Vector2d(-2, -2));  // half a cell of margin
  EXPECT_EQ(grid.cols, 26);                         // floor(100 / 4 + 0.5) + 1
  EXPECT_EQ(grid.rows, 14);                         // floor(50 / 4 + 0.5) + 1
  EXPECT_EQ(grid.At(0, 0), 3u);                     // (0,0), (1,1), (1.5,0.5)
  EXPECT_EQ(grid.At(1, 1), 1u);                     // (2,3)
  EXPECT_EQ(grid.At(13, 5), 1u);                    // (50,20)
  EXPECT_EQ(grid.At(25, 13), 1u);                   // the far corner
  EXPECT_EQ(grid.max, 3u);
  uint64_t total = 0;
  for (const uint32_t n : grid.counts) total += n;
  EXPECT_EQ(total, 6u);
  // In map pixels the floor is 8; over 12 800 px the cell is 100.
  const mission::ActivityTrack wide = TrackThrough({{0, 0}, {12800, 10}});
  EXPECT_DOUBLE_EQ(CountObservations({&wide}, false).cell, 100);
  EXPECT_DOUBLE_EQ(CountObservations({&a}, false).cell, 8);
  // Nothing to count: no cells.
  EXPECT_EQ(CountObservations({}, true).cols, 0);
  const mission::ActivityTrack empty;
  EXPECT_EQ(CountObservations({&empty}, true).counts.size(), 0u);
}

TEST(DensityTest, ScaleIsLogarithmicAndEmptyCellsAreTransparent) {
  EXPECT_EQ(DensityPosition(0, 100), 0);
  EXPECT_EQ(DensityAlpha(0), 0);
  EXPECT_GT(DensityPosition(1, 100), 0);  // one observation shows
  EXPECT_GT(DensityAlpha(DensityPosition(1, 100)), 100);
  EXPECT_NEAR(DensityPosition(10, 100), 0.5, 1e-12);
  EXPECT_EQ(DensityPosition(100, 100), 1);
  EXPECT_EQ(DensityPosition(1, 1), 1);
  double last = 0;
  for (uint32_t n = 1; n <= 100; ++n) {
    const double p = DensityPosition(n, 100);
    EXPECT_GE(p, last);
    last = p;
  }
  // Warm colours, darker as the density grows.
  const Rgb low = DensityRamp(0.01), high = DensityRamp(1);
  EXPECT_GT(low.r, 200);
  EXPECT_GT(low.g, high.g);
  EXPECT_GT(low.r + low.g + low.b, high.r + high.g + high.b);
}

TEST(DensityTest, LegendNamesTheCellAndRunsFromOneToTheLargestCount) {
  const mission::ActivityTrack a = TrackThrough(std::vector<Eigen::Vector2d>(81, {5, 5}));
  const mission::ActivityTrack b = TrackThrough({{300, 200}});
  const DensityGrid grid = CountObservations({&a, &b}, true);
  const Legend legend = DensityLegend(grid, true);
  EXPECT_EQ(legend.title, "Observations per 4.0 m cell");
  EXPECT_TRUE(legend.continuous);
  ASSERT_EQ(legend.entries.size(), 5u);
  EXPECT_EQ(legend.entries.front().label, "1");
  EXPECT_EQ(legend.entries[2].label, "9");  // 81^0.5
  EXPECT_EQ(legend.entries.back().label, "81");
  EXPECT_EQ(DensityLegend(CountObservations({&a, &b}, false), false).title,
            "Observations per 8 px cell");
}

}  // namespace
}  // namespace saker::activity
