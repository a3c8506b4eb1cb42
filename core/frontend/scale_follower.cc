#include "core/frontend/scale_follower.h"

#include "core/geo/local_tangent_plane.h"

#include <algorithm>
#include <cmath>
#include <utility>

namespace saker::frontend {

ScaleFollower::ScaleFollower(double fps, double stale_s)
    : stale_frames_(std::max<int64_t>(
          1, std::llround(std::clamp(stale_s, 0.0, 3600.0) * std::clamp(fps, 1.0, 1000.0)))) {}

void ScaleFollower::AddPacket(const ingest::MetadataPacket& packet) {
  if (!packet.trusted || !packet.decoded.metadata || !packet.decoded.metadata->corners) return;
  // On the tangent plane at the first corner (the mosaic's map frame is one too): through
  // Earth-centred coordinates, so a footprint across the antimeridian is whole.
  const std::array<klv::LatLon, 4>& corners = *packet.decoded.metadata->corners;
  const StatusOr<geo::LocalTangentPlane> plane =
      geo::LocalTangentPlane::Create({corners[0].latitude_deg, corners[0].longitude_deg, 0});
  if (!plane.ok()) return;
  Pending p;
  p.byte_pos = packet.byte_pos;
  for (size_t i = 0; i < 4; ++i) {
    p.ground[i] = plane->MapFromLatLon(corners[i].latitude_deg, corners[i].longitude_deg);
  }
  pending_.push_back(p);
  // A stream of metadata with no picture after it (a damaged file) must not hold it all: beyond
  // this many, the oldest is taken as if a frame had come.
  constexpr size_t kMaxPending = 1024;
  if (pending_.size() > kMaxPending) TakeOldest(size_);
}

void ScaleFollower::TakeOldest(const cv::Size& size) {
  std::optional<track::GroundScale> scale =
      track::GroundScale::FromCorners(pending_.front().ground, size.width, size.height);
  if (scale) {
    current_ = std::move(scale);
    ground_ = pending_.front().ground;
    size_ = size;
    frames_since_ = 0;
  }
  pending_.pop_front();
}

std::optional<track::GroundScale> ScaleFollower::ForFrame(int64_t byte_pos, int width, int height) {
  const cv::Size size(width, height);
  while (!pending_.empty() &&
         (byte_pos < 0 || pending_.front().byte_pos < 0 || pending_.front().byte_pos < byte_pos)) {
    TakeOldest(size);
  }
  if (current_ && size != size_) {  // the picture size changed: the same corners, new pixels
    current_ = track::GroundScale::FromCorners(ground_, width, height);
    size_ = size;
  }
  if (current_ && ++frames_since_ > stale_frames_) current_.reset();
  return current_;
}

}  // namespace saker::frontend
