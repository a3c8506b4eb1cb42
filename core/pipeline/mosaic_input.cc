#include "core/pipeline/mosaic_input.h"

#include <utility>

namespace saker::pipeline {

std::optional<geo::Wgs84> MapOrigin(const frontend::FrontEndResult& front) {
  for (const track::KeyFrame& kf : front.key_frames) {
    const klv::FrameMetadata* m = front.scan.MetadataOf(static_cast<size_t>(kf.frame_index));
    if (m == nullptr || !m->corners) continue;
    geo::Wgs84 origin;
    for (const klv::LatLon& c : *m->corners) {
      origin.latitude_deg += c.latitude_deg / 4;
      origin.longitude_deg += c.longitude_deg / 4;
    }
    origin.height_m = m->frame_center_elevation_m.value_or(0.0);
    if (!geo::LocalTangentPlane::Create(origin).ok()) continue;  // off the Earth: no metadata
    return origin;
  }
  return std::nullopt;
}

mosaic::MosaicInput MosaicInputOf(const frontend::FrontEndResult& front) {
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
  input.origin = MapOrigin(front);
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
