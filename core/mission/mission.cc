#include "core/mission/mission.h"

#include <Eigen/Geometry>
#include <Eigen/LU>

#include <algorithm>
#include <cmath>

namespace saker::mission {

const char* LinkKindName(LinkKind kind) {
  switch (kind) {
    case LinkKind::kSequential:
      return "sequential";
    case LinkKind::kGeometric:
      return "geometric";
    case LinkKind::kAppearance:
      return "appearance";
  }
  return "unknown";
}

std::optional<LinkKind> LinkKindFromName(const std::string& name) {
  for (LinkKind kind : {LinkKind::kSequential, LinkKind::kGeometric, LinkKind::kAppearance}) {
    if (name == LinkKindName(kind)) return kind;
  }
  return std::nullopt;
}

const char* VerdictName(Verdict verdict) {
  switch (verdict) {
    case Verdict::kNone:
      return "";
    case Verdict::kConfirmed:
      return "confirmed";
    case Verdict::kFalse:
      return "false";
  }
  return "";
}

const char* TargetLabelName(TargetLabel label) {
  switch (label) {
    case TargetLabel::kNone:
      return "";
    case TargetLabel::kVehicle:
      return "vehicle";
    case TargetLabel::kPerson:
      return "person";
    case TargetLabel::kOther:
      return "other";
  }
  return "";
}

const FrameRecord* FrameRecordOf(const Mission& mission, int64_t index) {
  const auto it =
      std::lower_bound(mission.frames.begin(), mission.frames.end(), index,
                       [](const FrameRecord& r, int64_t value) { return r.index < value; });
  return it != mission.frames.end() && it->index == index ? &*it : nullptr;
}

const TrackReview* FindReview(const std::vector<TrackReview>& reviews, int64_t track_id) {
  const auto it =
      std::lower_bound(reviews.begin(), reviews.end(), track_id,
                       [](const TrackReview& r, int64_t id) { return r.track_id < id; });
  return it != reviews.end() && it->track_id == track_id ? &*it : nullptr;
}

const TrackReview* ReviewOf(const Mission& mission, int64_t track_id) {
  return FindReview(mission.reviews, track_id);
}

std::vector<size_t> FramesSeeing(const Mission& mission, const Eigen::Vector2d& map_point,
                                 size_t max) {
  std::vector<size_t> seen;
  if (!map_point.allFinite()) return seen;
  const double width = mission.source.width, height = mission.source.height;
  for (size_t i = 0; i < mission.frames.size(); ++i) {
    const std::optional<Eigen::Matrix3d>& h = mission.frames[i].map_from_frame;
    if (!h) continue;
    Eigen::Matrix3d frame_from_map;
    bool invertible = false;
    h->computeInverseWithCheck(frame_from_map, invertible);
    if (!invertible) continue;
    const Eigen::Vector3d p = frame_from_map * map_point.homogeneous();
    // In front of the camera: the map point maps back with the sign the frame's pixels have.
    const Eigen::Vector3d centre = *h * Eigen::Vector3d(width / 2, height / 2, 1);
    if (!(p.z() * centre.z() > 0)) continue;
    const Eigen::Vector2d q = p.hnormalized();
    if (q.x() >= -0.5 && q.y() >= -0.5 && q.x() < width - 0.5 && q.y() < height - 0.5) {
      seen.push_back(i);
      if (max > 0 && seen.size() >= max) break;
    }
  }
  return seen;
}

bool IsMarkedFalse(const Mission& mission, int64_t track_id) {
  const TrackReview* review = ReviewOf(mission, track_id);
  return review != nullptr && review->verdict == Verdict::kFalse;
}

bool OverlayRecord::Contains(const Eigen::Vector2d& p) const {
  if (cell_px <= 0 || !std::isfinite(p.x()) || !std::isfinite(p.y())) return false;
  // Pixel centres are at integer coordinates: pixel i covers [i - 0.5, i + 0.5).
  const double x = std::floor((p.x() + 0.5) / cell_px);
  const double y = std::floor((p.y() + 0.5) / cell_px);
  if (x < 0 || y < 0 || x >= cols || y >= rows) return false;
  const size_t i = static_cast<size_t>(y) * static_cast<size_t>(cols) + static_cast<size_t>(x);
  return i < cells.size() && cells[i] != 0;
}

double OverlayRecord::Coverage() const {
  if (cells.empty()) return 0;
  const auto on = std::count_if(cells.begin(), cells.end(), [](uint8_t c) { return c != 0; });
  return static_cast<double>(on) / static_cast<double>(cells.size());
}

std::vector<Eigen::Vector2d> ClipToHalfPlane(const std::vector<Eigen::Vector2d>& polygon,
                                             const Eigen::Vector2d& normal, double offset) {
  // Sutherland-Hodgman, one edge.
  std::vector<Eigen::Vector2d> kept;
  const size_t n = polygon.size();
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector2d& a = polygon[i];
    const Eigen::Vector2d& b = polygon[(i + 1) % n];
    const double da = normal.dot(a) + offset, db = normal.dot(b) + offset;
    if (da >= 0) kept.push_back(a);
    if ((da >= 0) != (db >= 0)) kept.push_back(a + (b - a) * (da / (da - db)));
  }
  return kept;
}

std::vector<Eigen::Vector2d> BelowSkyLine(const std::optional<SkyLine>& sky_line, int width,
                                          int height) {
  std::vector<Eigen::Vector2d> part = {Eigen::Vector2d(0, 0), Eigen::Vector2d(width - 1, 0),
                                       Eigen::Vector2d(width - 1, height - 1),
                                       Eigen::Vector2d(0, height - 1)};
  if (sky_line) {  // keep y >= y0 + slope x
    part = ClipToHalfPlane(part, Eigen::Vector2d(-sky_line->slope, 1), -sky_line->y0);
  }
  if (part.size() < 3) part.clear();
  return part;
}

std::optional<double> FarthestMappedW(const Eigen::Matrix3d& map_from_frame,
                                      const std::vector<Eigen::Vector2d>& part) {
  const Eigen::Vector3d row = map_from_frame.row(2).transpose();
  double nearest = 0;
  for (const Eigen::Vector2d& p : part) {
    const double w = row.dot(p.homogeneous());
    if (std::isfinite(w)) nearest = std::max(nearest, w);
  }
  if (!(nearest > 0)) return std::nullopt;
  return nearest * std::pow(kMaxScaleSpread, -2.0 / 3.0);
}

std::string SkyLine::Problem() const {
  if (!std::isfinite(y0) || !std::isfinite(slope) || std::abs(y0) > 1e7) {
    return "sky line y = " + std::to_string(y0) + " + " + std::to_string(slope) +
           " x is not a finite line across the frame";
  }
  if (std::abs(slope) > kMaxSkySlope) {
    return "sky line slope " + std::to_string(slope) + " is steeper than " +
           std::to_string(kMaxSkySlope);
  }
  return {};
}

std::string OverlayRecord::Problem() const {
  if (first_frame < 0 || last_frame < first_frame) {
    return "frames " + std::to_string(first_frame) + " to " + std::to_string(last_frame) +
           " are not a range of frames";
  }
  if (cell_px < 1 || cell_px > kMaxOverlayCellPx) {
    return "cell size " + std::to_string(cell_px) + " px is outside [1, " +
           std::to_string(kMaxOverlayCellPx) + "]";
  }
  if (cols < 1 || rows < 1 || cols > kMaxOverlayCells || rows > kMaxOverlayCells) {
    return "grid of " + std::to_string(cols) + "x" + std::to_string(rows) +
           " cells is outside [1, " + std::to_string(kMaxOverlayCells) + "] a side";
  }
  if (cells.size() != static_cast<size_t>(cols) * static_cast<size_t>(rows)) {
    return std::to_string(cells.size()) + " cells for a grid of " + std::to_string(cols) + "x" +
           std::to_string(rows);
  }
  if (std::any_of(cells.begin(), cells.end(), [](uint8_t c) { return c > 1; })) {
    return "a cell is neither 0 nor 1";
  }
  return {};
}

OverlayExtent ExtentOf(const std::vector<OverlayRecord>& overlays) {
  OverlayExtent extent;
  double masked = 0;
  for (const OverlayRecord& o : overlays) {
    const int64_t n = o.last_frame - o.first_frame + 1;
    extent.frames += n;
    masked += static_cast<double>(n) * o.Coverage();
  }
  if (extent.frames > 0) extent.coverage = masked / static_cast<double>(extent.frames);
  return extent;
}

const OverlayRecord* OverlayAt(const std::vector<OverlayRecord>& overlays, int64_t frame) {
  // The first mask ending at or after `frame`; it applies when it starts at or before it.
  const auto it =
      std::lower_bound(overlays.begin(), overlays.end(), frame,
                       [](const OverlayRecord& o, int64_t f) { return o.last_frame < f; });
  if (it == overlays.end() || it->first_frame > frame) return nullptr;
  return &*it;
}

}  // namespace saker::mission
