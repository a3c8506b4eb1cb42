#pragma once

// ProceduralGround: imagery of a generated World, rendered on demand in tiles.
//
// A tile is painted from the vector world in layers (fields and hedges, grass, footpaths, roads
// and markings, car parks, shadows, roofs, tree canopies, parked vehicles) and textured with value
// noise evaluated in ground coordinates at four scales, so tiles join seamlessly and the texture
// is there for corner tracking and SIFT at any zoom. Tiles are cached (least recently used), so a
// flight over a large world keeps only the area around the camera in memory.

#include "core/sim/ground.h"
#include "core/sim/world.h"

#include <cstdint>
#include <list>
#include <memory>
#include <mutex>
#include <unordered_map>

namespace saker::sim {

class ProceduralGround final : public GroundSource {
 public:
  // `cache_megabytes` bounds the tile cache (a 256x256 tile is 192 KiB).
  ProceduralGround(std::shared_ptr<const World> world, double gsd_m, int cache_megabytes = 256);

  double gsd_m() const override { return gsd_m_; }
  cv::Rect2d extent_m() const override { return world_->extent_m; }
  void Render(const cv::Rect& region, cv::Mat* bgr, cv::Mat* valid) const override;

  const World& world() const { return *world_; }
  static constexpr int kTileSize = 256;

 private:
  struct TileKey {
    int64_t col;
    int64_t row;
    bool operator==(const TileKey&) const = default;
  };
  struct TileKeyHash {
    size_t operator()(const TileKey& key) const;
  };
  struct CachedTile {
    std::shared_ptr<const cv::Mat> bgr;
    std::list<TileKey>::iterator lru;
  };

  std::shared_ptr<const cv::Mat> Tile(const TileKey& key) const;
  cv::Mat PaintTile(const TileKey& key) const;

  std::shared_ptr<const World> world_;
  double gsd_m_;
  size_t max_tiles_;

  mutable std::mutex mutex_;
  mutable std::list<TileKey> lru_;  // most recent first
  mutable std::unordered_map<TileKey, CachedTile, TileKeyHash> cache_;
};

// The ground offset of the shadow of a point one metre above the ground.
Eigen::Vector2d ShadowPerMetre(const World& world);

// Fills a polygon given in image coordinates (double precision, anti-aliased) by blending
// `bgr` over `image` with opacity `alpha`; only the polygon's bounding box is touched.
void BlendPolygon(const std::vector<Eigen::Vector2d>& polygon, const cv::Scalar& bgr, double alpha,
                  cv::Mat* image);

// Draws a vehicle seen from above (body, windows, roof) with its shadow.
// `image_from_ground` maps ground metres to the image; heading is clockwise from north.
void DrawVehicle(const Eigen::Matrix3d& image_from_ground, const Eigen::Vector2d& position,
                 double heading_deg, const VehicleLook& look, const Eigen::Vector2d& shadow_per_m,
                 cv::Mat* image);

// Draws a person seen from above (shoulders and head) with a long shadow.
void DrawPerson(const Eigen::Matrix3d& image_from_ground, const Eigen::Vector2d& position,
                double heading_deg, const cv::Scalar& clothes_bgr,
                const Eigen::Vector2d& shadow_per_m, cv::Mat* image);

}  // namespace saker::sim
