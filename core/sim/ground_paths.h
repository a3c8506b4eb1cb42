#pragma once

// Roads and footpaths for moving targets over a ground that has no road network of its own (a
// user's orthophoto), so that real textures carry movers too.
//
// Two sources: a GeoJSON file of LineStrings (WGS84 longitude, latitude) that vehicles drive
// (features whose property "kind" is "footpath" are walked by people instead), or paths generated
// from the seed: straight and curved roads right across the ground and short footpaths near its
// centre. Either way the result is a World holding only roads, nodes, footpaths and a sun (for
// the targets' shadows); targets.h drives it as it drives the town. A road's ends are dead ends
// where vehicles turn round; ends within a metre of each other are one junction.

#include "core/geo/local_tangent_plane.h"
#include "core/sim/world.h"
#include "core/util/status.h"

#include <opencv2/core/types.hpp>

#include <cstdint>
#include <filesystem>

namespace saker::sim {

struct GroundPathOptions {
  std::filesystem::path geojson;  // LineStrings / MultiLineStrings to use as roads and footpaths
  bool generated = false;         // else: generate straight and curved paths from the seed

  bool enabled() const { return generated || !geojson.empty(); }
};

// The paths over `extent_m` (the ground's extent, metres). Errors name the file and the feature:
// NotFound, InvalidData (not GeoJSON, a line with fewer than two positions, coordinates out of
// range or more than 50 km from the origin), InvalidArgument (no usable line at all).
StatusOr<World> MakePathWorld(const GroundPathOptions& options, const cv::Rect2d& extent_m,
                              const geo::LocalTangentPlane& plane, uint64_t seed);

}  // namespace saker::sim
