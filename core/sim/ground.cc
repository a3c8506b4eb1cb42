#include "core/sim/ground.h"

#include "core/util/check.h"

namespace saker::sim {

Eigen::Matrix3d RasterFromGround(double gsd_m) {
  SAKER_CHECK(gsd_m > 0.0);
  Eigen::Matrix3d raster_from_ground;
  raster_from_ground << 1.0 / gsd_m, 0.0, 0.0,  //
      0.0, -1.0 / gsd_m, 0.0,                   //
      0.0, 0.0, 1.0;
  return raster_from_ground;
}

}  // namespace saker::sim
