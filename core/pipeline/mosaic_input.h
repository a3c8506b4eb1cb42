#pragma once
// The mosaic's input from a front-end run: the map frame chosen and every frame's metadata
// corners put on it, once, for the mosaic and the mission's frame records alike.

#include "core/frontend/front_end.h"
#include "core/geo/local_tangent_plane.h"
#include "core/mosaic/mosaic_input.h"

#include <optional>
#include <string>
#include <vector>

namespace saker::pipeline {

// The map origin of a run: the centre of the first key frame's metadata footprint (its four
// ground corners, longitudes unwrapped across the antimeridian: geo::CentreOf) at the frame
// centre's elevation, skipping footprints where no tangent plane can be made; nullopt when no
// key frame has metadata corners. InvalidArgument, saying why (off the Earth, too near a pole:
// geo::LocalTangentPlane::Create), when key frames have corners but none gives a usable origin.
StatusOr<std::optional<geo::Wgs84>> MapOrigin(const frontend::FrontEndResult& front);

// The run's frames, key frames (with their images) and links, its map origin (MapOrigin) and the
// metadata corners of every frame in east-north-up metres around it (nullopt for a frame without
// metadata corners, or whose corners do not project). When MapOrigin fails the input has no
// origin (the map is the first key frame's pixels) and `warnings`, if given, says why.
mosaic::MosaicInput MosaicInputOf(const frontend::FrontEndResult& front,
                                  std::vector<std::string>* warnings = nullptr);

}  // namespace saker::pipeline
