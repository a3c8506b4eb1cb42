#include "core/sim/world.h"

#include "core/sim/world_raster.h"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <queue>

namespace saker::sim {
namespace {

const cv::Rect2d kExtent(-1500, -1000, 3000, 2000);

World MakeWorld(uint64_t seed) {
  WorldOptions options;
  options.seed = seed;
  StatusOr<World> world = GenerateWorld(options, kExtent);
  EXPECT_TRUE(world.ok()) << world.status().ToString();
  return std::move(world).value();
}

int CornerCount(const cv::Mat& bgr) {
  cv::Mat grey;
  cv::cvtColor(bgr, grey, cv::COLOR_BGR2GRAY);
  std::vector<cv::Point2f> corners;
  cv::goodFeaturesToTrack(grey, corners, 5000, 0.002, 5, cv::noArray(), 3, true);
  return static_cast<int>(corners.size());
}

TEST(WorldTest, SameSeedSameWorldOtherSeedOtherWorld) {
  const World a = MakeWorld(7), b = MakeWorld(7), c = MakeWorld(8);
  ASSERT_EQ(a.buildings.size(), b.buildings.size());
  for (size_t i = 0; i < a.buildings.size(); ++i) {
    EXPECT_EQ(a.buildings[i].footprint.centre, b.buildings[i].footprint.centre);
  }
  ASSERT_EQ(a.road_loop.size(), b.road_loop.size());
  EXPECT_EQ(a.road_loop[40], b.road_loop[40]);
  EXPECT_NE(a.road_loop[40], c.road_loop[40]);
}

TEST(WorldTest, RoadLoopOfOneKilometreThroughTheRoundabout) {
  const World world = MakeWorld(1);
  EXPECT_NEAR(PolylineLength(world.road_loop), 1000.0, 10.0);
  EXPECT_LT(world.road_loop.front().norm(), 1e-9);
  EXPECT_LT(world.road_loop.back().norm(), 1e-9);
  ASSERT_GE(world.roundabout_node, 0);
  const RoadNode& roundabout = world.nodes[world.roundabout_node];
  EXPECT_GT(roundabout.roundabout_radius_m, 10);
  EXPECT_GE(roundabout.roads.size(), 5u);  // two loop ends and three roads out of town
  // The loop is drivable: every point of it lies on a road of the network.
  for (const Eigen::Vector2d& p : world.road_loop) {
    double nearest = 1e9;
    for (const Road& road : world.roads)
      nearest = std::min(nearest, DistanceToPolyline(p, road.centreline));
    ASSERT_LT(nearest, 0.5) << "loop point " << p.transpose() << " is off the roads";
  }
}

TEST(WorldTest, RoadNetworkIsConnected) {
  const World world = MakeWorld(3);
  std::vector<bool> seen(world.nodes.size(), false);
  std::queue<int> queue;
  queue.push(world.roundabout_node);
  seen[world.roundabout_node] = true;
  while (!queue.empty()) {
    const int node = queue.front();
    queue.pop();
    for (int r : world.nodes[node].roads) {
      for (int next : {world.roads[r].from, world.roads[r].to}) {
        if (!seen[next]) seen[next] = true, queue.push(next);
      }
    }
  }
  for (size_t i = 0; i < seen.size(); ++i) {
    if (!world.nodes[i].roads.empty()) {
      EXPECT_TRUE(seen[i]) << "node " << i << " unreachable";
    }
  }
}

TEST(WorldTest, TownHasItsParts) {
  const World world = MakeWorld(1);
  EXPECT_GT(world.buildings.size(), 120u);
  EXPECT_GE(world.car_parks.size(), 1u);
  EXPECT_GT(world.parked.size(), 30u);
  EXPECT_GT(world.trees.size(), 200u);
  EXPECT_GT(world.fields.size(), 50u);
  EXPECT_GE(world.footpaths.size(), 3u);
  // No building stands on a road.
  for (const Building& b : world.buildings) {
    for (const Eigen::Vector2d& corner : b.footprint.Corners()) {
      for (const Road& road : world.roads) {
        ASSERT_GT(DistanceToPolyline(corner, road.centreline), road.width_m / 2)
            << "building at " << b.footprint.centre.transpose() << " on a road";
      }
    }
  }
}

TEST(WorldTest, GroundHasTextureInTownAndCountry) {
  auto world = std::make_shared<const World>(MakeWorld(1));
  const ProceduralGround ground(world, 0.2);
  cv::Mat bgr, valid;
  // 100 m x 100 m in town (north of the roundabout, inside the loop) and in the fields.
  const Eigen::Vector2d town = world->town_centre + Eigen::Vector2d(-60, 40);
  ground.Render(cv::Rect(static_cast<int>(town.x() / 0.2) - 250,
                         static_cast<int>(-town.y() / 0.2) - 250, 500, 500),
                &bgr, &valid);
  EXPECT_EQ(cv::countNonZero(valid), 500 * 500);
  const int town_corners = CornerCount(bgr);
  ground.Render(cv::Rect(static_cast<int>(1100 / 0.2), static_cast<int>(600 / 0.2), 500, 500), &bgr,
                &valid);
  const int field_corners = CornerCount(bgr);
  EXPECT_GT(town_corners, 150);
  EXPECT_GT(field_corners, 100);
  // Flat colour has none: the measure can fail.
  EXPECT_LT(CornerCount(cv::Mat(500, 500, CV_8UC3, cv::Scalar(80, 140, 90))), 5);
}

TEST(WorldTest, TilesJoinSeamlesslyAndCacheEvictionChangesNothing) {
  auto world = std::make_shared<const World>(MakeWorld(1));
  const ProceduralGround small_cache(world, 0.25, /*cache_megabytes=*/1);
  const cv::Rect region(-300, -200, 700, 500);  // spans several tiles, negative indices too
  cv::Mat first, valid;
  small_cache.Render(region, &first, &valid);
  cv::Mat elsewhere;
  small_cache.Render(cv::Rect(8000, 4000, 1500, 1500), &elsewhere,
                     &valid);  // evicts the first tiles
  cv::Mat again;
  small_cache.Render(region, &again, &valid);
  EXPECT_EQ(cv::norm(first, again, cv::NORM_INF), 0);
  // A sub-region rendered alone equals the same pixels of the larger render.
  cv::Mat part;
  small_cache.Render(cv::Rect(-45, -70, 300, 200), &part, &valid);
  EXPECT_EQ(cv::norm(part, first(cv::Rect(255, 130, 300, 200)), cv::NORM_INF), 0);
}

TEST(WorldTest, OutsideTheExtentIsNoData) {
  auto world = std::make_shared<const World>(MakeWorld(1));
  const ProceduralGround ground(world, 1.0);
  cv::Mat bgr, valid;
  const cv::Rect2d e = world->extent_m;
  ground.Render(cv::Rect(static_cast<int>(e.x + e.width) + 10, 0, 50, 50), &bgr, &valid);
  EXPECT_EQ(cv::countNonZero(valid), 0);
}

TEST(WorldTest, RejectsBadOptions) {
  WorldOptions options;
  options.loop_length_m = 50;
  EXPECT_FALSE(GenerateWorld(options, kExtent).ok());
  EXPECT_FALSE(GenerateWorld({}, cv::Rect2d(0, 0, -5, 10)).ok());
}

}  // namespace
}  // namespace saker::sim
