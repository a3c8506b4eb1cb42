#include "core/pipeline/checkpoint.h"

#include "core/tiles/image_decode.h"
#include "core/track/picture.h"
#include "core/util/byte_io.h"
#include "core/video/video_reader.h"

#include <opencv2/imgcodecs.hpp>

#include <cmath>
#include <map>
#include <string>
#include <vector>

namespace saker::pipeline {
namespace {

// Record kinds (docs/mission-file.md).
constexpr const char* kState = "state";
constexpr const char* kFrame = "frame";
constexpr const char* kKeyFrame = "key_frame";
constexpr const char* kImage = "key_frame_image";
constexpr const char* kLink = "link";
constexpr const char* kBreak = "break";
constexpr const char* kTarget = "target";
constexpr const char* kChangeTarget = "change_target";
constexpr const char* kOpenTarget = "open_target";
constexpr const char* kOpenChangeTarget = "open_change_target";
constexpr const char* kTrackerState = "tracker_state";
constexpr uint32_t kStateVersion = 1;

std::vector<uint8_t> EncodeFrame(const frontend::FrameResult& f) {
  ByteWriter w;
  w.Put<int64_t>(f.index);
  w.Put<double>(f.time_s);
  w.Put<int64_t>(f.pts);
  w.Put<uint8_t>(static_cast<uint8_t>(f.key_frame) | static_cast<uint8_t>(f.homography_ok) << 1);
  w.PutMatrix(f.current_from_previous);
  w.PutMatrix(f.covariance);
  w.Put<int32_t>(f.tracked);
  w.Put<int32_t>(f.inliers);
  w.Put<int32_t>(f.moving);
  // Added after the first layout: a record that ends before it has no sky line.
  w.Put<uint8_t>(f.sky_line ? 1 : 0);
  if (f.sky_line) {
    w.Put<double>(f.sky_line->YAt(0));
    w.Put<double>(f.sky_line->slope);
  }
  return w.Take();
}

bool DecodeFrame(ByteReader& r, frontend::FrameResult* f) {
  uint8_t flags = 0;
  if (!r.Get(&f->index) || !r.Get(&f->time_s) || !r.Get(&f->pts) || !r.Get(&flags) ||
      !r.GetMatrix(&f->current_from_previous) || !r.GetMatrix(&f->covariance) ||
      !r.Get(&f->tracked) || !r.Get(&f->inliers) || !r.Get(&f->moving)) {
    return false;
  }
  f->key_frame = flags & 1;
  f->homography_ok = flags & 2;
  if (r.AtEnd()) return true;  // written before frames had sky lines
  uint8_t has_sky = 0;
  if (!r.Get(&has_sky) || has_sky > 1) return false;
  if (has_sky == 1) {
    track::HorizonLine line;
    if (!r.Get(&line.y_at_centre) || !r.Get(&line.slope) || !std::isfinite(line.y_at_centre) ||
        !std::isfinite(line.slope)) {
      return false;
    }
    f->sky_line = line;  // centre_x 0: y_at_centre is the line's y at x = 0
  }
  return true;
}

std::vector<uint8_t> EncodeKeyFrame(const track::KeyFrame& k) {
  ByteWriter w;
  w.Put<int32_t>(static_cast<int32_t>(k.id));
  w.Put<int64_t>(k.frame_index);
  w.Put<int32_t>(k.segment);
  w.Put<uint64_t>(k.points.size());
  for (const track::StationaryPoint& p : k.points) {
    w.Put<int64_t>(static_cast<int64_t>(p.first));
    w.PutMatrix(p.second);
  }
  return w.Take();
}

bool DecodeKeyFrame(ByteReader& r, track::KeyFrame* k) {
  int32_t id = 0;
  size_t n = 0;
  if (!r.Get(&id) || !r.Get(&k->frame_index) || !r.Get(&k->segment) || !r.GetCount(24, &n)) {
    return false;
  }
  k->id = static_cast<track::KeyFrameId>(id);
  k->points.resize(n);
  for (track::StationaryPoint& p : k->points) {
    int64_t point_id = 0;
    if (!r.Get(&point_id) || !r.GetMatrix(&p.second)) return false;
    p.first = static_cast<track::FeatureTrackId>(point_id);
  }
  return true;
}

StatusOr<std::vector<uint8_t>> EncodeImage(const frontend::KeyFramePreview& p) {
  ByteWriter w;
  w.Put<int32_t>(static_cast<int32_t>(p.image.id));
  w.Put<int64_t>(p.image.frame_index);
  w.Put<double>(p.image.scale);
  w.PutMatrix(p.preview_from_frame);
  std::vector<uint8_t> png;
  // Lossless, so that a resumed job matches and renders the same pixels; fast compression.
  if (!p.image.grey.empty() &&
      !cv::imencode(".png", p.image.grey, png, {cv::IMWRITE_PNG_COMPRESSION, 1})) {
    return InvalidArgumentError("cannot encode the image of key frame " +
                                std::to_string(static_cast<int>(p.image.id)));
  }
  w.PutBytes(png.data(), png.size());
  if (track::IsColour(p.image)) {
    // The chroma after the grey (a record without it, of an older Saker, is a grey picture): the
    // coding, then Cb and Cr side by side in one grey PNG twice as wide.
    std::vector<uint8_t> chroma;
    if (!cv::imencode(".png", p.image.chroma.reshape(1), chroma,
                      {cv::IMWRITE_PNG_COMPRESSION, 1})) {
      return InvalidArgumentError("cannot encode the colour of key frame " +
                                  std::to_string(static_cast<int>(p.image.id)));
    }
    w.Put<uint8_t>(static_cast<uint8_t>(p.image.coding.matrix));
    w.Put<uint8_t>(p.image.coding.full_range ? 1 : 0);
    w.PutBytes(chroma.data(), chroma.size());
  }
  return w.Take();
}

// `where` names the record. A key frame image is a downscaled copy of a video frame, so its PNG
// may declare no more pixels than the largest picture the video reader accepts; the header is
// checked before anything is decoded (a decompression bomb is refused, not allocated).
StatusOr<bool> DecodeImage(ByteReader& r, const std::string& where, frontend::KeyFramePreview* p) {
  int32_t id = 0;
  std::vector<uint8_t> png;
  if (!r.Get(&id) || !r.Get(&p->image.frame_index) || !r.Get(&p->image.scale) ||
      !r.GetMatrix(&p->preview_from_frame) || !r.GetBytes(&png)) {
    return false;
  }
  p->image.id = static_cast<track::KeyFrameId>(id);
  if (!(p->image.scale >= 1 && p->image.scale < 1e4)) return false;
  if (!png.empty()) {
    const int64_t max_pixels = video::ReaderOptions().max_pixels;
    const tiles::ImageLimits limits{int64_t{1} << 16, int64_t{1} << 16, max_pixels};
    StatusOr<cv::Mat> grey = tiles::DecodePng(png, cv::IMREAD_GRAYSCALE, limits);
    if (!grey.ok()) return Status(grey.status().code(), where + ": " + grey.status().message());
    p->image.grey = std::move(grey).value();
  }
  if (r.AtEnd()) return true;  // a grey picture
  uint8_t matrix = 0, full_range = 0;
  std::vector<uint8_t> chroma_png;
  if (!r.Get(&matrix) || !r.Get(&full_range) || !r.GetBytes(&chroma_png) ||
      matrix > static_cast<uint8_t>(YuvMatrix::kBt2020) || full_range > 1 ||
      p->image.grey.empty()) {
    return false;
  }
  // Cb and Cr side by side: exactly twice half the grey's width, half its height (rounded up).
  const int width = (p->image.grey.cols + 1) / 2;
  const int height = (p->image.grey.rows + 1) / 2;
  const tiles::ImageLimits limits{2 * width, height, int64_t{2} * width * height};
  StatusOr<cv::Mat> chroma = tiles::DecodePng(chroma_png, cv::IMREAD_GRAYSCALE, limits);
  if (!chroma.ok()) return Status(chroma.status().code(), where + ": " + chroma.status().message());
  if (chroma->cols != 2 * width || chroma->rows != height) {
    return InvalidDataError(where + ": the key frame's colour is " + std::to_string(chroma->cols) +
                            " x " + std::to_string(chroma->rows) + " pixels, not " +
                            std::to_string(2 * width) + " x " + std::to_string(height));
  }
  p->image.chroma = chroma->reshape(2);
  p->image.coding = {static_cast<YuvMatrix>(matrix), full_range == 1};
  return true;
}

std::vector<uint8_t> EncodeLink(const track::SequentialLink& l) {
  ByteWriter w;
  w.Put<int32_t>(static_cast<int32_t>(l.from));
  w.Put<int32_t>(static_cast<int32_t>(l.to));
  w.Put<uint8_t>(l.chained);
  w.PutMatrix(l.to_from_from);
  w.PutMatrix(l.covariance);
  w.Put<uint64_t>(l.correspondences.size());
  for (const track::Correspondence& c : l.correspondences) {
    w.Put<int64_t>(static_cast<int64_t>(c.id));
    w.PutMatrix(c.source);
    w.PutMatrix(c.target);
  }
  return w.Take();
}

bool DecodeLink(ByteReader& r, track::SequentialLink* l) {
  int32_t from = 0, to = 0;
  uint8_t chained = 0;
  size_t n = 0;
  if (!r.Get(&from) || !r.Get(&to) || !r.Get(&chained) || !r.GetMatrix(&l->to_from_from) ||
      !r.GetMatrix(&l->covariance) || !r.GetCount(40, &n)) {
    return false;
  }
  l->from = static_cast<track::KeyFrameId>(from);
  l->to = static_cast<track::KeyFrameId>(to);
  l->chained = chained != 0;
  l->correspondences.resize(n);
  for (track::Correspondence& c : l->correspondences) {
    int64_t id = 0;
    if (!r.Get(&id) || !r.GetMatrix(&c.source) || !r.GetMatrix(&c.target)) return false;
    c.id = static_cast<track::FeatureTrackId>(id);
  }
  return true;
}

std::vector<uint8_t> EncodeBreak(const track::ChainBreak& b) {
  ByteWriter w;
  w.Put<int64_t>(b.frame_index);
  w.PutString(b.reason);
  return w.Take();
}

bool DecodeBreak(ByteReader& r, track::ChainBreak* b) {
  return r.Get(&b->frame_index) && r.GetString(&b->reason);
}

std::vector<uint8_t> EncodeTarget(const track::TargetTrack& t) {
  ByteWriter w;
  w.Put<int64_t>(static_cast<int64_t>(t.id));
  w.Put<uint8_t>(t.confirmed);
  w.Put<uint64_t>(t.max_features);
  w.PutMatrix(t.image_velocity);
  w.Put<uint64_t>(t.observations.size());
  for (const track::TargetObservation& o : t.observations) {
    w.Put<int64_t>(o.frame);
    w.PutMatrix(o.position);
    w.PutMatrix(o.box_min);
    w.PutMatrix(o.box_max);
    w.PutMatrix(o.velocity);
    w.Put<uint8_t>(static_cast<uint8_t>(o.change));
    w.Put<uint64_t>(o.features.size());
    for (const track::FeatureTrackId id : o.features) w.Put<int64_t>(static_cast<int64_t>(id));
  }
  return w.Take();
}

bool DecodeTarget(ByteReader& r, track::TargetTrack* t) {
  int64_t id = 0;
  uint8_t confirmed = 0;
  uint64_t max_features = 0;
  size_t n = 0;
  if (!r.Get(&id) || !r.Get(&confirmed) || !r.Get(&max_features) ||
      !r.GetMatrix(&t->image_velocity) || !r.GetCount(81, &n)) {
    return false;
  }
  t->id = static_cast<track::TargetTrackId>(id);
  t->confirmed = confirmed != 0;
  t->max_features = static_cast<size_t>(max_features);
  t->observations.resize(n);
  for (track::TargetObservation& o : t->observations) {
    uint8_t change = 0;
    size_t features = 0;
    if (!r.Get(&o.frame) || !r.GetMatrix(&o.position) || !r.GetMatrix(&o.box_min) ||
        !r.GetMatrix(&o.box_max) || !r.GetMatrix(&o.velocity) || !r.Get(&change) ||
        change > static_cast<uint8_t>(track::ChangeEvidence::kChanged) ||
        !r.GetCount(8, &features)) {
      return false;
    }
    o.change = static_cast<track::ChangeEvidence>(change);
    o.features.resize(features);
    for (track::FeatureTrackId& f : o.features) {
      int64_t feature = 0;
      if (!r.Get(&feature)) return false;
      f = static_cast<track::FeatureTrackId>(feature);
    }
  }
  return true;
}

// The state record: Unsupported for another version of the layout, false when malformed.
StatusOr<bool> DecodeState(ByteReader& r, const std::string& where,
                           frontend::FrontEndCheckpoint* c) {
  uint32_t version = 0;
  uint8_t complete = 0;
  if (r.Get(&version) && version != kStateVersion) {
    return UnsupportedError(where + ": written by another Saker (checkpoint version " +
                            std::to_string(version) + "); process the video again");
  }
  const bool ok = r.Get(&c->through_frame) && r.Get(&complete) && r.Get(&c->change_through_frame);
  c->complete = complete != 0;
  return ok;
}

}  // namespace

CheckpointWriter::CheckpointWriter(mission::MissionStore* store,
                                   const frontend::FrontEndCheckpoint* resumed)
    : store_(store) {
  if (resumed != nullptr) {
    links_ = static_cast<int64_t>(resumed->links.size());
    breaks_ = static_cast<int64_t>(resumed->breaks.size());
    targets_ = static_cast<int64_t>(resumed->targets.size());
    change_targets_ = static_cast<int64_t>(resumed->change_targets.size());
  }
}

Status CheckpointWriter::Write(const frontend::FrontEndCheckpoint& c) {
  std::vector<mission::CheckpointRecord> records;
  std::vector<std::string> replace = {kOpenTarget, kOpenChangeTarget, kTrackerState};
  {
    ByteWriter w;
    w.Put<uint32_t>(kStateVersion);
    w.Put<int64_t>(c.through_frame);
    w.Put<uint8_t>(c.complete);
    w.Put<int64_t>(c.change_through_frame);
    records.push_back({kState, 0, w.Take()});
  }
  for (const frontend::FrameResult& f : c.frames)
    records.push_back({kFrame, f.index, EncodeFrame(f)});
  for (const track::KeyFrame& k : c.key_frames) {
    records.push_back({kKeyFrame, static_cast<int64_t>(k.id), EncodeKeyFrame(k)});
  }
  for (const frontend::KeyFramePreview& p : c.key_frame_images) {
    SAKER_ASSIGN_OR_RETURN(std::vector<uint8_t> bytes, EncodeImage(p));
    records.push_back({kImage, static_cast<int64_t>(p.image.id), std::move(bytes)});
  }
  for (const track::SequentialLink& l : c.links)
    records.push_back({kLink, links_++, EncodeLink(l)});
  for (const track::ChainBreak& b : c.breaks)
    records.push_back({kBreak, breaks_++, EncodeBreak(b)});
  if (c.complete) {
    // The final targets replace everything found along the way.
    replace.insert(replace.end(), {kTarget, kChangeTarget});
    targets_ = change_targets_ = 0;
  }
  for (const track::TargetTrack& t : c.targets) {
    records.push_back({kTarget, targets_++, EncodeTarget(t)});
  }
  for (const track::TargetTrack& t : c.change_targets) {
    records.push_back({kChangeTarget, change_targets_++, EncodeTarget(t)});
  }
  int64_t open = 0;
  for (const track::TargetTrack& t : c.open_targets) {
    records.push_back({kOpenTarget, open++, EncodeTarget(t)});
  }
  open = 0;
  for (const track::TargetTrack& t : c.open_change_targets) {
    records.push_back({kOpenChangeTarget, open++, EncodeTarget(t)});
  }
  if (!c.state.empty()) records.push_back({kTrackerState, 0, c.state});
  return store_->WriteCheckpoint(records, replace);
}

StatusOr<std::optional<frontend::FrontEndCheckpoint>> ReadCheckpoint(
    const mission::MissionStore& store) {
  SAKER_ASSIGN_OR_RETURN(const std::vector<mission::CheckpointRecord> records,
                         store.ReadCheckpoint());
  if (records.empty()) return std::optional<frontend::FrontEndCheckpoint>();
  frontend::FrontEndCheckpoint c;
  bool has_state = false;
  const std::string where = store.path() + ": checkpoint";
  // Records come sorted by kind and key: each kind in the order it was written.
  for (const mission::CheckpointRecord& record : records) {
    if (record.kind == kTrackerState) {
      c.state = record.bytes;  // the front end reads it (it says when it is malformed)
      continue;
    }
    ByteReader r(record.bytes);
    bool ok = false;
    const std::string& kind = record.kind;
    if (kind == kState) {
      SAKER_ASSIGN_OR_RETURN(ok, DecodeState(r, where, &c));
      has_state = true;
    } else if (kind == kFrame) {
      ok = DecodeFrame(r, &c.frames.emplace_back());
    } else if (kind == kKeyFrame) {
      ok = DecodeKeyFrame(r, &c.key_frames.emplace_back());
    } else if (kind == kImage) {
      const std::string record_name = where + " record " + kind + " " + std::to_string(record.key);
      SAKER_ASSIGN_OR_RETURN(ok, DecodeImage(r, record_name, &c.key_frame_images.emplace_back()));
    } else if (kind == kLink) {
      ok = DecodeLink(r, &c.links.emplace_back());
    } else if (kind == kBreak) {
      ok = DecodeBreak(r, &c.breaks.emplace_back());
    } else if (kind == kTarget) {
      ok = DecodeTarget(r, &c.targets.emplace_back());
    } else if (kind == kChangeTarget) {
      ok = DecodeTarget(r, &c.change_targets.emplace_back());
    } else if (kind == kOpenTarget) {
      ok = DecodeTarget(r, &c.open_targets.emplace_back());
    } else if (kind == kOpenChangeTarget) {
      ok = DecodeTarget(r, &c.open_change_targets.emplace_back());

    } else {
      return InvalidDataError(where + ": unknown record kind '" + kind + "'");
    }
    if (!ok || !r.AtEnd()) {
      return InvalidDataError(where + ": record " + kind + " " + std::to_string(record.key) +
                              " is truncated or malformed (" + std::to_string(record.bytes.size()) +
                              " bytes)");
    }
  }
  if (!has_state) return InvalidDataError(where + ": no state record");
  const Status valid = c.Validate();
  if (!valid.ok()) return InvalidDataError(where + ": " + valid.message());
  return std::optional<frontend::FrontEndCheckpoint>(std::move(c));
}

StatusOr<std::optional<CheckpointState>> ReadCheckpointState(const mission::MissionStore& store) {
  SAKER_ASSIGN_OR_RETURN(const std::vector<mission::CheckpointRecord> records,
                         store.ReadCheckpoint());
  std::optional<CheckpointState> state;
  const std::string where = store.path() + ": checkpoint";
  int64_t key_frames = 0;
  for (const mission::CheckpointRecord& record : records) {
    key_frames += record.kind == kKeyFrame;
    if (record.kind != kState) continue;
    ByteReader r(record.bytes);
    frontend::FrontEndCheckpoint c;
    SAKER_ASSIGN_OR_RETURN(const bool ok, DecodeState(r, where, &c));
    if (!ok || !r.AtEnd()) return InvalidDataError(where + ": the state record is malformed");
    state = CheckpointState{c.through_frame, c.complete, 0};
  }
  if (!records.empty() && !state) return InvalidDataError(where + ": no state record");
  if (state) state->key_frames = key_frames;
  return state;
}

}  // namespace saker::pipeline
