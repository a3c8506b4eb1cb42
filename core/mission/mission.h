#pragma once

// A processed mission as plain data: what the mission file (`.saker`, an SQLite database)
// stores, what the exports write and what the GUI shows. Nothing here refers to a running engine
// stage; the pipeline (`core/pipeline/stages.h`) fills it from one, `mission_store.h` saves and
// loads it.
//
// Conventions (docs/architecture.md): homographies are `target_from_source`, H(2,2) = 1, with
// 8x8 covariances in the order of track/types.h; the map frame is east-north-up metres around
// `MapFrame::origin` when the mission is geo-referenced, otherwise the first key frame's pixel
// frame (x right, y down). Times are seconds from the start of the video.

#include "core/geo/local_tangent_plane.h"

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace saker::mission {

// Version of the mission file's schema. A file with a newer version is refused, never written.
// Version 2 added the frames' presentation time stamps and key-frame flags, version 3 the table of
// processing checkpoints, version 4 the tracks' confidence, version 5 the screen-fixed overlay
// masks, version 6 the frames' sky lines, version 7 the analyst's track reviews and bookmarks; an
// older file is read as it is and upgraded in place when it is opened for writing.
inline constexpr int kSchemaVersion = 8;

using Covariance8 = Eigen::Matrix<double, 8, 8>;

struct SourceVideo {
  std::string path;         // absolute path at processing time (the video may move later)
  std::string fingerprint;  // FingerprintFile(path): recognises the same video elsewhere
  int64_t size_bytes = 0;
  int width = 0;
  int height = 0;
  double frame_rate = 0;  // frames per second
  int64_t frame_count = 0;
  double duration_s = 0;
};

struct MapFrame {
  bool geo_referenced = false;       // true: ENU metres around `origin`; false: key frame pixels
  std::optional<geo::Wgs84> origin;  // set exactly when geo_referenced
};

// The lower edge of a low oblique view's sky mask (docs/front-end.md, "Oblique views"): the
// pixels above the line y = y0 + slope * x (full-resolution frame pixels, y down) are sky or
// ground too distant to map, left out of the mosaic's tiles.
struct SkyLine {
  double y0 = 0;
  double slope = 0;
  bool Masks(const Eigen::Vector2d& p) const { return p.y() < y0 + slope * p.x(); }
  // Why the line cannot be stored ("" when it can): values not finite, or steeper than
  // kMaxSkySlope (the front end finds lines within 25 degrees of level).
  std::string Problem() const;
};
inline constexpr double kMaxSkySlope = 10;

// What of a frame is mapped (the mosaic's tiles, the tracks' map positions): the ground below its
// sky line, and of that only the ground seen at most kMaxScaleSpread times coarser (map units per
// pixel, the square root of the area scale) than the frame's nearest ground: towards the horizon
// of a low oblique view a pixel spans ever more ground, and the map would show smears. The map's
// scale at a pixel p goes as w^(-3/2), w = the third row of map_from_frame . (p, 1) (the area
// scale is det(H) / w^3), so the limit is a least w, kMaxScaleSpread^(-2/3) times the largest.
inline constexpr double kMaxScaleSpread = 8;

// The part of convex `polygon` where normal . p + offset >= 0.
std::vector<Eigen::Vector2d> ClipToHalfPlane(const std::vector<Eigen::Vector2d>& polygon,
                                             const Eigen::Vector2d& normal, double offset);
// A frame's rectangle (full-resolution pixel centres at integers, corners clockwise from the top
// left) below its sky line: a convex polygon, empty when the line passes below the frame.
std::vector<Eigen::Vector2d> BelowSkyLine(const std::optional<SkyLine>& sky_line, int width,
                                          int height);
// The least w (above) of the ground mapped within `part` of a frame: the largest w over its
// vertices (the nearest ground) times kMaxScaleSpread^(-2/3); nullopt when no vertex lies in
// front of the map's plane.
std::optional<double> FarthestMappedW(const Eigen::Matrix3d& map_from_frame,
                                      const std::vector<Eigen::Vector2d>& part);

struct FrameRecord {
  int64_t index = 0;
  double time_s = 0;
  std::optional<int64_t> utc_us;                  // KLV time stamp, when the frame has metadata
  std::optional<Eigen::Matrix3d> map_from_frame;  // absent: the frame could not be placed
  // The four image corners (top-left, top-right, bottom-right, bottom-left) on the map according
  // to the frame's metadata, when it has them.
  std::optional<std::array<Eigen::Vector2d, 4>> metadata_corners;
  std::optional<geo::Wgs84> sensor;  // sensor position from the metadata
  // Where the frame is in the video stream (video::FrameIndexEntry: pts in the stream's time base
  // and whether it is a key frame), so frame recall can seek without indexing the video again.
  // Absent in missions of schema version 1.
  std::optional<int64_t> pts;
  bool key_frame = false;
  // The sky mask's edge, when the front end found the horizon in this frame (schema version 6).
  std::optional<SkyLine> sky_line;
};

struct KeyFrameRecord {
  int32_t id = 0;  // KeyFrameId
  int64_t frame_index = 0;
  int32_t segment = 0;  // chain segment (a chain break starts a new one)
  Eigen::Matrix3d map_from_frame = Eigen::Matrix3d::Identity();
  Covariance8 covariance = Covariance8::Zero();
  bool node = false;  // a node of the node/arc decomposition
};

// How two key frames came to be linked; the one definition, shared with the mosaic engine.
enum class LinkKind {
  kSequential,  // consecutive key frames of a segment (front end)
  kGeometric,   // loop closure: features matched inside their predicted uncertainty ellipses
  kAppearance,  // loop closure: SIFT matched without geometry, verified by RANSAC
};

struct LinkRecord {
  int32_t from = 0;  // KeyFrameId
  int32_t to = 0;
  LinkKind kind = LinkKind::kSequential;
  Eigen::Matrix3d to_from_from = Eigen::Matrix3d::Identity();
  Covariance8 covariance = Covariance8::Zero();
  int32_t correspondences = 0;  // inlier point pairs that measured it
};

// One observation of a moving target.
struct TrackPoint {
  int64_t frame = 0;
  double time_s = 0;
  Eigen::Vector2d image{0, 0};  // pixels in the original video frame
  Eigen::Vector2d box_min{0, 0};
  Eigen::Vector2d box_max{0, 0};
  Eigen::Vector2d map{0, 0};  // map frame
  // Not seen in this frame: placed between the observations on either side of a short gap
  // (track::FillGaps). Schema 8; false in older files.
  bool interpolated = false;
};

// A moving target's track with its activity attributes (docs/activity.md).
struct ActivityTrack {
  int64_t id = 0;                  // TargetTrackId
  std::vector<TrackPoint> points;  // increasing frame
  double start_s = 0;
  double end_s = 0;
  double length = 0;                // path length, map units
  double speed = 0;                 // average speed, map units per second
  std::optional<double> speed_mps;  // metres per second, when geo-referenced
  double heading_deg = 0;           // direction of travel, degrees clockwise from map north (+y
                                    // when geo-referenced, -y, up the image, otherwise)
  int visit = 1;                    // which pass of the aircraft over the place, from 1
  // How much the evidence says this is a real moving target, 0 to 1 (activity/confidence.h,
  // docs/activity.md "Confidence"). Absent: unknown (missions written before schema version 4,
  // whose evidence was not kept).
  std::optional<double> confidence;
};

// Limits of an overlay mask's grid (a cell's side in pixels, cells a side).
inline constexpr int kMaxOverlayCellPx = 1024;
inline constexpr int kMaxOverlayCells = 8192;

// A screen-fixed overlay mask (burned-in text, reticles, logos; track/overlay_mask.h) that the
// front end found and left out of the ground motion and the targets, and the frames it applies
// to (within one chain segment). The image is cut into square cells of `cell_px` pixels of the
// original video frame; cell (x, y) covers pixels [x, x+1) * cell_px. Absent in missions written
// before schema version 5.
struct OverlayRecord {
  int64_t first_frame = 0;
  int64_t last_frame = 0;  // inclusive
  int cell_px = 8;
  int cols = 0;
  int rows = 0;
  std::vector<uint8_t> cells;  // cols * rows, row-major: 1 on the overlay, 0 elsewhere

  // Whether the point `p` of the original frame lies on the overlay (pixel centres at integer
  // coordinates: pixel i covers [i - 0.5, i + 0.5)).
  bool Contains(const Eigen::Vector2d& p) const;
  // The fraction of the cells on the overlay.
  double Coverage() const;
  // Why the record breaks a rule of the file (empty when it does not): sizes, the cells' count
  // and values, the frame range.
  std::string Problem() const;
};

// The overlay mask that applies to `frame`, or null: `overlays` in frame order, disjoint.
const OverlayRecord* OverlayAt(const std::vector<OverlayRecord>& overlays, int64_t frame);

// The frames the masks cover, and the mean fraction of the image they mask there (0 and 0 for
// none).
struct OverlayExtent {
  int64_t frames = 0;
  double coverage = 0;
};
OverlayExtent ExtentOf(const std::vector<OverlayRecord>& overlays);

// Where the mosaic's tile pyramid lies on the map. Level 0 is full resolution; level l is
// downsampled by 2^l; tile (x, y) of level l covers pixels [x, x+1) * tile_size of that level.
struct PyramidInfo {
  int tile_size = 256;
  int levels = 0;
  int width = 0;  // level 0 size in pixels
  int height = 0;
  // Map coordinates of level 0 pixel centres: map = origin + (col * step_x, row * step_y).
  Eigen::Vector2d map_origin{0, 0};
  double step_x = 1;  // map units per pixel along columns
  double step_y = 1;  // along rows (negative when the map's y axis points north)
};

// What the video's KLV held, counted when the front end scanned it (absent in missions written
// before Saker counted it). Packets that failed their checksum are never used for a frame's time,
// position or footprint unless the job accepted them.
struct KlvSummary {
  int64_t packets = 0;              // KLV packets found
  int64_t checksum_failures = 0;    // of them, ST 0601 packets whose checksum failed
  bool bad_checksums_used = false;  // the job was told to use them (--accept-bad-checksums)
};

// What the front end found about the video itself (FrontEndResult), kept so that whoever opens
// the mission later learns it too (saker-cli info, the GUI's mission facts); missions written
// before 2026-11-29 have none.
struct FrontEndFindings {
  bool low_frame_rate = false;    // targets came from change detection alone (the video's rate)
  int64_t polarity_switches = 0;  // a thermal camera's white-hot / black-hot switches
  // How far the video's own noise raised the motion thresholds (frontend::VideoNoise): the frames
  // whose feature thresholds and the change answers whose allowances were raised, and the largest
  // thresholds used (pixels, grey levels, pixels of misregistration).
  int64_t noise_feature_frames = 0, noise_change_frames = 0;
  double noise_feature_px = 0, noise_change_grey = 0, noise_change_registration_px = 0;
};

// Which processing stages have completed (and been saved).
struct Progress {
  bool front_end = false;
  bool mosaic = false;
  bool activity = false;
  bool tiles = false;
  bool cancelled = false;  // the job was cancelled: what is here is what had completed
};

// The analyst's judgement of a track (kept apart from the track, which processing writes).
enum class Verdict : uint8_t {
  kNone = 0,       // not judged
  kConfirmed = 1,  // a real moving target
  kFalse = 2,      // not one: hidden from the map and the exports unless asked for
};
// What the analyst says the target is.
enum class TargetLabel : uint8_t { kNone = 0, kVehicle = 1, kPerson = 2, kOther = 3 };

const char* VerdictName(Verdict verdict);        // "", "confirmed", "false"
const char* TargetLabelName(TargetLabel label);  // "", "vehicle", "person", "other"

// The longest note the file keeps (characters of UTF-8; a longer one is refused on saving).
inline constexpr size_t kMaxNoteBytes = 10000;

// The analyst's review of one track (by ActivityTrack::id). Absent for a track never judged.
struct TrackReview {
  int64_t track_id = 0;
  Verdict verdict = Verdict::kNone;
  TargetLabel label = TargetLabel::kNone;
  std::string note;
  bool empty() const {
    return verdict == Verdict::kNone && label == TargetLabel::kNone && note.empty();
  }
};

// A time and place the analyst marked, with a note.
struct Bookmark {
  int64_t id = 0;  // unique in the mission, from 1
  double time_s = 0;
  Eigen::Vector2d map{0, 0};
  std::string note;
};

struct Mission {
  int schema_version = kSchemaVersion;
  std::string saker_version;
  SourceVideo source;
  std::string options_json;  // the processing options, as JSON
  MapFrame map;
  std::vector<FrameRecord> frames;
  std::vector<OverlayRecord> overlays;  // in frame order, disjoint; saved with the frames
  std::vector<KeyFrameRecord> key_frames;
  std::vector<LinkRecord> links;
  std::vector<ActivityTrack> tracks;
  std::optional<PyramidInfo> pyramid;
  std::optional<KlvSummary> klv;             // set by the front end stage
  std::optional<FrontEndFindings> findings;  // set by the front end stage
  Progress progress;
  // The analyst's: reviews sorted by track id (none empty), bookmarks by id. Processing never
  // writes them (MissionStore::SaveReviews does).
  std::vector<TrackReview> reviews;
  std::vector<Bookmark> bookmarks;
};

// The frames (indices into Mission::frames, in order) whose picture saw the map point: placed on
// the map, the point in front of the camera and inside the frame's width x height pixels (of
// Mission::source). At most `max` of them (0: all).
std::vector<size_t> FramesSeeing(const Mission& mission, const Eigen::Vector2d& map_point,
                                 size_t max = 0);

// The record of frame `index` in Mission::frames (sorted by index), or null when it has none.
const FrameRecord* FrameRecordOf(const Mission& mission, int64_t index);

// The review of track `track_id` in reviews sorted by track id (Mission::reviews), or null.
const TrackReview* FindReview(const std::vector<TrackReview>& reviews, int64_t track_id);
// The review of track `track_id`, or null when it has none.
const TrackReview* ReviewOf(const Mission& mission, int64_t track_id);
// Whether the analyst marked the track false.
bool IsMarkedFalse(const Mission& mission, int64_t track_id);

const char* LinkKindName(LinkKind kind);  // "sequential", "geometric", "appearance"; "unknown"
std::optional<LinkKind> LinkKindFromName(const std::string& name);  // LinkKindName's inverse

}  // namespace saker::mission
