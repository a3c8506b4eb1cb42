#include "core/pipeline/mosaic_input.h"

#include <string>
#include <utility>
#include <vector>

namespace saker::pipeline {

StatusOr<std::optional<geo::Wgs84>> MapOrigin(const frontend::FrontEndResult& front) {
  Status refused;
  for (const track::KeyFrame& kf : front.key_frames) {
    const klv::FrameMetadata* m = front.scan.MetadataOf(static_cast<size_t>(kf.frame_index));
    if (m == nullptr || !m->corners) continue;
    std::vector<geo::Wgs84> corners;
    for (const klv::LatLon& c : *m->corners) corners.push_back({c.latitude_deg, c.longitude_deg});
    // Longitudes unwrapped around the first corner: a footprint across the antimeridian has its
    // centre there, not at 0.
    geo::Wgs84 origin = geo::CentreOf(corners);
    origin.height_m = m->frame_center_elevation_m.value_or(0.0);
    const Status status = geo::LocalTangentPlane::Create(origin).status();
    if (status.ok()) return std::optional<geo::Wgs84>(origin);
    if (refused.ok()) refused = status;  // off the Earth or at a pole: try the next key frame
  }
  if (!refused.ok()) return refused;
  return std::optional<geo::Wgs84>();
}

mosaic::MosaicInput MosaicInputOf(const frontend::FrontEndResult& front,
                                  std::vector<std::string>* warnings) {
  mosaic::MosaicInput input;
  input.image_width = front.video.width;
  input.image_height = front.video.height;
  input.frames.reserve(front.frames.size());
  for (const frontend::FrameResult& f : front.frames) {
    input.frames.push_back({f.time_s, f.homography_ok, f.current_from_previous, f.covariance});
  }
  input.key_frames = front.key_frames;
  input.key_frame_images = front.key_frame_images;  // shares the pixels
  input.links = front.links;
  StatusOr<std::optional<geo::Wgs84>> origin = MapOrigin(front);
  if (!origin.ok()) {
    if (warnings != nullptr) {
      warnings->push_back(front.video.path + ": the metadata cannot geo-reference the map (" +
                          origin.status().message() +
                          "); the map is in the first key frame's pixels");
    }
    return input;
  }
  input.origin = *origin;
  if (!input.origin) return input;
  StatusOr<geo::LocalTangentPlane> plane = geo::LocalTangentPlane::Create(*input.origin);
  if (!plane.ok()) {  // MapOrigin checked it
    input.origin.reset();
    return input;
  }
  input.metadata_corners.resize(front.frames.size());
  for (size_t i = 0; i < front.frames.size(); ++i) {
    const klv::FrameMetadata* m = front.scan.MetadataOf(i);
    if (m == nullptr || !m->corners) continue;
    mosaic::MapCorners corners;
    bool finite = true;
    for (size_t c = 0; c < 4; ++c) {
      corners[c] =
          plane->MapFromLatLon((*m->corners)[c].latitude_deg, (*m->corners)[c].longitude_deg);
      finite = finite && corners[c].allFinite();
    }
    if (finite) input.metadata_corners[i] = corners;
  }
  return input;
}

}  // namespace saker::pipeline
