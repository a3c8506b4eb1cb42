#pragma once

// The mosaic as a tiled, multi-resolution pyramid (for the GUI's view and the GeoTIFF export):
// key frame images warped into the map and blended, rendered one full-resolution tile at a time
// so a long flight never needs the whole mosaic in memory, the coarser levels built from the
// finer ones. Tiles are BGRA (alpha 0 where no key frame covers the map), stored as PNG, or as
// JPEG where a colour tile is covered throughout; their placement is a mission::PyramidInfo.
// docs/missions.md ("Tile pyramid").

#include "core/mission/mission.h"
#include "core/mission/mission_store.h"
#include "core/util/job_context.h"
#include "core/util/status.h"
#include "core/util/yuv_coding.h"

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include <functional>
#include <optional>
#include <vector>

namespace saker::tiles {

// A key frame to draw: its picture (a downscaled copy of the video frame, as
// track::KeyFrameImage keeps it) and where it lies.
struct KeyFrameView {
  const cv::Mat* grey = nullptr;  // CV_8UC1, the luma as coded, not owned
  double scale = 1;               // full-resolution video pixels per pixel of `grey`
  Eigen::Matrix3d map_from_frame = Eigen::Matrix3d::Identity();  // full-resolution pixels
  // The overlay mask of its frame (burned-in text, logos; not owned, may be null): not ground, so
  // never drawn as it is. Another key frame's picture fills the place where one sees it; where
  // none does, a smooth fill from the pixels around it.
  const mission::OverlayRecord* overlay = nullptr;
  // A low oblique view's sky mask (mission::SkyLine): the picture above the line is not drawn.
  std::optional<mission::SkyLine> sky_line;
  // Its chroma (CV_8UC2 at half the size of `grey`, not owned; null or empty: a grey picture) and
  // how the two code colour. When any frame has chroma the tiles are in colour, grey pictures
  // drawn as grey in them; otherwise grey, the luma as coded.
  const cv::Mat* chroma = nullptr;
  YuvCoding coding;
};

// The part of a key frame's picture (full-resolution pixels, pixel centres at integers) that is
// drawn: the frame's rectangle below its sky line, where the ground is seen at most
// mission::kMaxScaleSpread times coarser than the frame's nearest ground; a convex polygon, empty
// when the rectangle below the sky line reaches behind the map's plane (beyond its horizon).
std::vector<Eigen::Vector2d> DrawnPart(const KeyFrameView& frame, int width, int height);

// The largest tile side PyramidOptions admits (a 64 MiB BGRA tile); a stored tile never exceeds it.
inline constexpr int kMaxTileSize = 4096;

struct PyramidOptions {
  int tile_size = 256;          // pixels per tile side, 16..kMaxTileSize
  double map_units_per_px = 0;  // level 0 resolution; 0: the key frames' median resolution
  int max_side_px = 32768;      // level 0's longer side at most (coarsens the resolution)
  int png_compression = 1;      // 0-9: fast by default (tiles are written often)
  // Colour tiles covered throughout are stored as JPEG of this quality (1-100; 0: PNG always).
  int jpeg_quality = 90;
  Status Validate() const;
};

// The pyramid covering the key frames' footprints (video frames of `width` x `height`): north up
// on a geo-referenced map, the first key frame's orientation otherwise. InvalidData when no
// footprint is finite.
StatusOr<mission::PyramidInfo> PlanPyramid(const std::vector<KeyFrameView>& frames, int width,
                                           int height, bool geo_referenced,
                                           const PyramidOptions& options);

// Writes a batch of encoded tiles (one transaction in a mission store).
using TileSink = std::function<Status(const std::vector<mission::EncodedTile>&)>;

struct RenderSummary {
  int64_t tiles_written = 0;  // every level
  int64_t empty_tiles = 0;    // not written: no key frame covers them
  double time_s = 0;
};

// Renders every tile of `info` and hands them to `write` in batches. Tiles no key frame covers
// are not written. The pyramid is walked depth first from its single top tile, so only four
// tiles per level are held at a time. Cancelled through `job` (between tiles; what was written
// stays).
StatusOr<RenderSummary> RenderPyramid(const std::vector<KeyFrameView>& frames, int width,
                                      int height, const mission::PyramidInfo& info,
                                      const PyramidOptions& options, const TileSink& write,
                                      JobContext* job = nullptr);

// Decodes a tile written by RenderPyramid for a pyramid of `tile_size` (PyramidInfo::tile_size):
// CV_8UC4 BGRA, tile_size x tile_size (a JPEG tile opaque throughout). InvalidData when the bytes
// are not an image of that kind, before anything is decoded when the header declares another size
// or the tile size is beyond kMaxTileSize (a decompression bomb); ResourceExhausted when memory
// runs out.
StatusOr<cv::Mat> DecodeTile(const std::vector<uint8_t>& bytes, int tile_size);

}  // namespace saker::tiles
