#pragma once

// Missions for tests: one with every field set (optionals both set and unset) and an exact
// comparison that names the first difference, for the mission store and anything that
// round-trips a Mission.

#include "core/mission/mission.h"

#include <cmath>
#include <cstdint>
#include <sstream>
#include <string>

namespace saker::mission::testing_support {

// Equal, or both NaN (a NaN must survive a round trip as a NaN).
inline bool SameDouble(double a, double b) { return a == b || (std::isnan(a) && std::isnan(b)); }

template <typename Matrix>
bool SameMatrix(const Matrix& a, const Matrix& b) {
  for (int r = 0; r < a.rows(); ++r) {
    for (int c = 0; c < a.cols(); ++c) {
      if (!SameDouble(a(r, c), b(r, c))) return false;
    }
  }
  return true;
}

inline bool SameWgs84(const geo::Wgs84& a, const geo::Wgs84& b) {
  return SameDouble(a.latitude_deg, b.latitude_deg) &&
         SameDouble(a.longitude_deg, b.longitude_deg) && SameDouble(a.height_m, b.height_m);
}

template <typename T, typename Same>
bool SameOptional(const std::optional<T>& a, const std::optional<T>& b, Same same) {
  if (a.has_value() != b.has_value()) return false;
  return !a || same(*a, *b);
}

// Whether `a` and `b` hold exactly the same values; otherwise `why` names the first difference.
inline bool MissionsEqual(const Mission& a, const Mission& b, std::string* why) {
  std::ostringstream out;
  auto differ = [&](const std::string& what) {
    out << what;
    *why = out.str();
    return false;
  };
  auto same_double = [](double x, double y) { return SameDouble(x, y); };
  auto same_int64 = [](int64_t x, int64_t y) { return x == y; };
  auto same_matrix3 = [](const Eigen::Matrix3d& x, const Eigen::Matrix3d& y) {
    return SameMatrix(x, y);
  };
  auto same_wgs84 = [](const geo::Wgs84& x, const geo::Wgs84& y) { return SameWgs84(x, y); };
  auto same_corners = [](const std::array<Eigen::Vector2d, 4>& x,
                         const std::array<Eigen::Vector2d, 4>& y) {
    for (size_t i = 0; i < 4; ++i) {
      if (!SameMatrix(x[i], y[i])) return false;
    }
    return true;
  };

  if (a.schema_version != b.schema_version) return differ("schema_version");
  if (a.saker_version != b.saker_version) return differ("saker_version");
  if (a.options_json != b.options_json) return differ("options_json");
  const SourceVideo& sa = a.source;
  const SourceVideo& sb = b.source;
  if (sa.path != sb.path || sa.fingerprint != sb.fingerprint || sa.size_bytes != sb.size_bytes ||
      sa.width != sb.width || sa.height != sb.height || !SameDouble(sa.frame_rate, sb.frame_rate) ||
      sa.frame_count != sb.frame_count || !SameDouble(sa.duration_s, sb.duration_s)) {
    return differ("source");
  }
  if (a.map.geo_referenced != b.map.geo_referenced) return differ("map.geo_referenced");
  if (!SameOptional(a.map.origin, b.map.origin, same_wgs84)) return differ("map.origin");

  if (a.frames.size() != b.frames.size()) {
    out << a.frames.size() << " vs " << b.frames.size() << " ";
    return differ("frame count");
  }
  for (size_t i = 0; i < a.frames.size(); ++i) {
    const FrameRecord& fa = a.frames[i];
    const FrameRecord& fb = b.frames[i];
    out << "frame " << i << ": ";
    if (fa.index != fb.index) return differ("index");
    if (!SameDouble(fa.time_s, fb.time_s)) return differ("time_s");
    if (!SameOptional(fa.utc_us, fb.utc_us, same_int64)) return differ("utc_us");
    if (!SameOptional(fa.map_from_frame, fb.map_from_frame, same_matrix3)) {
      return differ("map_from_frame");
    }
    if (!SameOptional(fa.metadata_corners, fb.metadata_corners, same_corners)) {
      return differ("metadata_corners");
    }
    if (!SameOptional(fa.sensor, fb.sensor, same_wgs84)) return differ("sensor");
    if (!SameOptional(fa.pts, fb.pts, same_int64)) return differ("pts");
    if (fa.pts && fa.key_frame != fb.key_frame) return differ("key_frame");
    if (fa.sky_line.has_value() != fb.sky_line.has_value() ||
        (fa.sky_line && (!SameDouble(fa.sky_line->y0, fb.sky_line->y0) ||
                         !SameDouble(fa.sky_line->slope, fb.sky_line->slope)))) {
      return differ("sky_line");
    }
    out.str("");
  }

  if (a.overlays.size() != b.overlays.size()) return differ("overlay mask count");
  for (size_t i = 0; i < a.overlays.size(); ++i) {
    const OverlayRecord& oa = a.overlays[i];
    const OverlayRecord& ob = b.overlays[i];
    out << "overlay mask " << i << ": ";
    if (oa.first_frame != ob.first_frame || oa.last_frame != ob.last_frame) return differ("frames");
    if (oa.cell_px != ob.cell_px) return differ("cell_px");
    if (oa.cols != ob.cols || oa.rows != ob.rows) return differ("grid");
    if (oa.cells != ob.cells) return differ("cells");
    out.str("");
  }

  if (a.key_frames.size() != b.key_frames.size()) return differ("key frame count");
  for (size_t i = 0; i < a.key_frames.size(); ++i) {
    const KeyFrameRecord& ka = a.key_frames[i];
    const KeyFrameRecord& kb = b.key_frames[i];
    out << "key frame " << i << ": ";
    if (ka.id != kb.id) return differ("id");
    if (ka.frame_index != kb.frame_index) return differ("frame_index");
    if (ka.segment != kb.segment) return differ("segment");
    if (!SameMatrix(ka.map_from_frame, kb.map_from_frame)) return differ("map_from_frame");
    if (!SameMatrix(ka.covariance, kb.covariance)) return differ("covariance");
    if (ka.node != kb.node) return differ("node");
    out.str("");
  }

  if (a.links.size() != b.links.size()) return differ("link count");
  for (size_t i = 0; i < a.links.size(); ++i) {
    const LinkRecord& la = a.links[i];
    const LinkRecord& lb = b.links[i];
    out << "link " << i << ": ";
    if (la.from != lb.from || la.to != lb.to) return differ("from/to");
    if (la.kind != lb.kind) return differ("kind");
    if (!SameMatrix(la.to_from_from, lb.to_from_from)) return differ("to_from_from");
    if (!SameMatrix(la.covariance, lb.covariance)) return differ("covariance");
    if (la.correspondences != lb.correspondences) return differ("correspondences");
    out.str("");
  }

  if (a.tracks.size() != b.tracks.size()) return differ("track count");
  for (size_t i = 0; i < a.tracks.size(); ++i) {
    const ActivityTrack& ta = a.tracks[i];
    const ActivityTrack& tb = b.tracks[i];
    out << "track " << i << ": ";
    if (ta.id != tb.id) return differ("id");
    if (!SameDouble(ta.start_s, tb.start_s) || !SameDouble(ta.end_s, tb.end_s)) {
      return differ("start_s/end_s");
    }
    if (!SameDouble(ta.length, tb.length)) return differ("length");
    if (!SameDouble(ta.speed, tb.speed)) return differ("speed");
    if (!SameOptional(ta.speed_mps, tb.speed_mps, same_double)) return differ("speed_mps");
    if (!SameDouble(ta.heading_deg, tb.heading_deg)) return differ("heading_deg");
    if (ta.visit != tb.visit) return differ("visit");
    if (!SameOptional(ta.confidence, tb.confidence, same_double)) return differ("confidence");
    if (ta.points.size() != tb.points.size()) return differ("point count");
    for (size_t j = 0; j < ta.points.size(); ++j) {
      const TrackPoint& pa = ta.points[j];
      const TrackPoint& pb = tb.points[j];
      out << "point " << j << ": ";
      if (pa.frame != pb.frame) return differ("frame");
      if (!SameDouble(pa.time_s, pb.time_s)) return differ("time_s");
      if (!SameMatrix(pa.image, pb.image)) return differ("image");
      if (!SameMatrix(pa.box_min, pb.box_min) || !SameMatrix(pa.box_max, pb.box_max)) {
        return differ("box");
      }
      if (!SameMatrix(pa.map, pb.map)) return differ("map");
      if (pa.interpolated != pb.interpolated) return differ("interpolated");
    }
    out.str("");
  }

  if (a.reviews.size() != b.reviews.size()) return differ("review count");
  for (size_t i = 0; i < a.reviews.size(); ++i) {
    const TrackReview& ra = a.reviews[i];
    const TrackReview& rb = b.reviews[i];
    out << "review " << i << ": ";
    if (ra.track_id != rb.track_id) return differ("track_id");
    if (ra.verdict != rb.verdict) return differ("verdict");
    if (ra.label != rb.label) return differ("label");
    if (ra.note != rb.note) return differ("note");
    out.str("");
  }
  if (a.bookmarks.size() != b.bookmarks.size()) return differ("bookmark count");
  for (size_t i = 0; i < a.bookmarks.size(); ++i) {
    const Bookmark& ka = a.bookmarks[i];
    const Bookmark& kb = b.bookmarks[i];
    out << "bookmark " << i << ": ";
    if (ka.id != kb.id) return differ("id");
    if (!SameDouble(ka.time_s, kb.time_s)) return differ("time_s");
    if (!SameMatrix(ka.map, kb.map)) return differ("map");
    if (ka.note != kb.note) return differ("note");
    out.str("");
  }

  if (a.pyramid.has_value() != b.pyramid.has_value()) return differ("pyramid presence");
  if (a.pyramid) {
    const PyramidInfo& pa = *a.pyramid;
    const PyramidInfo& pb = *b.pyramid;
    if (pa.tile_size != pb.tile_size || pa.levels != pb.levels || pa.width != pb.width ||
        pa.height != pb.height || !SameMatrix(pa.map_origin, pb.map_origin) ||
        !SameDouble(pa.step_x, pb.step_x) || !SameDouble(pa.step_y, pb.step_y)) {
      return differ("pyramid");
    }
  }
  const auto same_klv = [](const KlvSummary& x, const KlvSummary& y) {
    return x.packets == y.packets && x.checksum_failures == y.checksum_failures &&
           x.bad_checksums_used == y.bad_checksums_used;
  };
  if (!SameOptional(a.klv, b.klv, same_klv)) return differ("klv");
  const auto same_findings = [](const FrontEndFindings& x, const FrontEndFindings& y) {
    return x.low_frame_rate == y.low_frame_rate && x.polarity_switches == y.polarity_switches &&
           x.noise_feature_frames == y.noise_feature_frames &&
           x.noise_change_frames == y.noise_change_frames &&
           SameDouble(x.noise_feature_px, y.noise_feature_px) &&
           SameDouble(x.noise_change_grey, y.noise_change_grey) &&
           SameDouble(x.noise_change_registration_px, y.noise_change_registration_px);
  };
  if (!SameOptional(a.findings, b.findings, same_findings)) return differ("findings");
  const Progress& pa = a.progress;
  const Progress& pb = b.progress;
  if (pa.front_end != pb.front_end || pa.mosaic != pb.mosaic || pa.activity != pb.activity ||
      pa.tiles != pb.tiles || pa.cancelled != pb.cancelled) {
    return differ("progress");
  }
  why->clear();
  return true;
}

// A deterministic matrix whose entries all differ (and are not integers), from `seed`.
template <typename Matrix>
Matrix PatternMatrix(double seed) {
  Matrix m;
  for (int r = 0; r < m.rows(); ++r) {
    for (int c = 0; c < m.cols(); ++c) {
      m(r, c) = seed + 0.001 * (r * m.cols() + c) + 1e-9 * seed * (r + 1);
    }
  }
  return m;
}

// A mission with every field set to a value distinct from its default, optionals both set and
// unset, every link kind and tracks with and without points.
inline Mission MakeFullMission() {
  Mission m;
  m.saker_version = "0.1.0-test+g1234567";
  m.source.path = "/data/flight 7/vidéo 'quoted'.ts";
  m.source.fingerprint = "v1:123456789:0123456789abcdef";
  m.source.size_bytes = 123456789012;
  m.source.width = 1280;
  m.source.height = 720;
  m.source.frame_rate = 29.97002997;
  m.source.frame_count = 5400;
  m.source.duration_s = 180.18;
  m.options_json = R"({"key_frame_spacing": 15, "name": "ünïcödé", "nested": {"a": [1, 2]}})";
  m.map.geo_referenced = true;
  m.map.origin = geo::Wgs84{51.501234567, -1.254321, 123.45};
  m.klv = KlvSummary{5400, 3, true};
  m.findings = FrontEndFindings{true, 2, 410, 388, 3.25, 4.5, 0.75};

  const int64_t indices[] = {0, 1, 2, 5, 9, 1000000007};
  for (int i = 0; i < 6; ++i) {
    FrameRecord f;
    f.index = indices[i];
    f.time_s = 0.04 * static_cast<double>(f.index) + 0.001;
    const bool all = i == 0 || i == 5;
    if (all || i == 3) f.utc_us = 1700000000000000 + 40000 * f.index;
    if (all || i == 2) f.map_from_frame = PatternMatrix<Eigen::Matrix3d>(1.5 + i);
    if (all || i == 4) {
      f.metadata_corners = std::array<Eigen::Vector2d, 4>{
          Eigen::Vector2d(-10.5 - i, 20.25), Eigen::Vector2d(30.125, 20.5 + i),
          Eigen::Vector2d(31.75, -5.5), Eigen::Vector2d(-11.0625, -6.5 * i)};
    }
    if (all || i == 4) f.sensor = geo::Wgs84{51.5 + 0.001 * i, -1.25 - 0.002 * i, 1500.5 + i};
    if (all || i == 1) {
      f.pts = 3600 * f.index - 7;  // may be negative
      f.key_frame = i == 0;
    }
    if (all || i == 3) f.sky_line = SkyLine{120.375 + i, -0.0625 * i};
    m.frames.push_back(f);
  }

  // Two overlay masks: a grid whose cell count is not a multiple of 8 (the file packs bits), and
  // one that runs to the last frame.
  for (int i = 0; i < 2; ++i) {
    OverlayRecord o;
    o.first_frame = i == 0 ? 1 : 9;
    o.last_frame = i == 0 ? 5 : 1000000007;
    o.cell_px = 8 + 8 * i;
    o.cols = 13 - 3 * i;
    o.rows = 7 + i;
    for (int c = 0; c < o.cols * o.rows; ++c) o.cells.push_back((c * 7 + i) % 5 == 0 ? 1 : 0);
    m.overlays.push_back(std::move(o));
  }

  for (int i = 0; i < 3; ++i) {
    KeyFrameRecord k;
    k.id = 10 + i;
    k.frame_index = indices[2 * i];
    k.segment = i / 2;
    k.map_from_frame = PatternMatrix<Eigen::Matrix3d>(-2.25 * (i + 1));
    k.covariance = PatternMatrix<Covariance8>(1e-3 * (i + 1));
    k.node = i != 1;
    m.key_frames.push_back(k);
  }
  const LinkKind kinds[] = {LinkKind::kSequential, LinkKind::kGeometric, LinkKind::kAppearance,
                            LinkKind::kSequential};
  for (int i = 0; i < 4; ++i) {
    LinkRecord l;
    l.from = 10 + i % 3;
    l.to = 10 + (i + 1) % 3;
    l.kind = kinds[i];
    l.to_from_from = PatternMatrix<Eigen::Matrix3d>(0.75 + i);
    l.covariance = PatternMatrix<Covariance8>(2e-4 * (i + 3));
    l.correspondences = 40 + 7 * i;
    m.links.push_back(l);
  }

  const int point_counts[] = {5, 0, 3};
  for (int i = 0; i < 3; ++i) {
    ActivityTrack t;
    t.id = 900000000000 + i;
    for (int j = 0; j < point_counts[i]; ++j) {
      TrackPoint p;
      p.frame = 100 + 3 * j;
      p.time_s = 4.0 + 0.12 * j;
      p.image = Eigen::Vector2d(100.5 + j, 200.25 - j);
      p.box_min = Eigen::Vector2d(95.5 + j, 190.75);
      p.box_max = Eigen::Vector2d(105.5 + j, 210.125);
      p.map = Eigen::Vector2d(-345.678 + 2.5 * j, 987.654 - 0.5 * j);
      p.interpolated = j == 2;
      t.points.push_back(p);
    }
    t.start_s = 4.0 + i;
    t.end_s = 4.48 + i;
    t.length = 12.345 * (i + 1);
    t.speed = 25.6 + i;
    if (i != 1) t.speed_mps = 8.5 + 0.25 * i;
    t.heading_deg = 271.5 - 10 * i;
    t.visit = 1 + i;
    if (i != 2) t.confidence = 0.125 + 0.25 * i;  // one of unknown confidence
    m.tracks.push_back(t);
  }

  PyramidInfo pyramid;
  pyramid.tile_size = 512;
  pyramid.levels = 6;
  pyramid.width = 10001;
  pyramid.height = 8003;
  pyramid.map_origin = Eigen::Vector2d(-1200.5, 3400.25);
  pyramid.step_x = 0.3125;
  pyramid.step_y = -0.3125;
  m.pyramid = pyramid;
  m.progress.front_end = true;
  m.progress.mosaic = true;
  m.progress.activity = false;
  m.progress.tiles = true;
  m.progress.cancelled = true;
  return m;
}

}  // namespace saker::mission::testing_support
