#include "core/mission/schema.h"

#include "core/mission/mission_store.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <initializer_list>
#include <limits>
#include <map>
#include <set>
#include <utility>

namespace saker::mission::schema {
namespace {

// Blob sizes: little-endian float64, row-major.
constexpr int kMatrix3Values = 9;
constexpr int kCovarianceValues = 64;
constexpr int kCornerValues = 8;  // four (x, y) pairs

// Largest pyramid the file may describe (a level l is downsampled by 2^l).
constexpr int kMaxPyramidLevels = 32;
constexpr int kMaxTileSize = 1 << 16;

// Schema v6 (docs/mission-file.md): the tables of version 2 here with the tracks' confidence (new
// in version 4) and the frames' sky lines (new in version 6), the checkpoint table (new in
// version 3) and the overlay masks (new in version 5) below. REAL columns are nullable on
// purpose: SQLite stores NaN as NULL.
constexpr const char* kSchemaSql = R"sql(
CREATE TABLE meta (
  key TEXT PRIMARY KEY NOT NULL,
  value
);
CREATE TABLE source (
  id INTEGER PRIMARY KEY CHECK (id = 1),
  path TEXT NOT NULL,
  fingerprint TEXT NOT NULL,
  size_bytes INTEGER NOT NULL,
  width INTEGER NOT NULL,
  height INTEGER NOT NULL,
  frame_rate REAL,
  frame_count INTEGER NOT NULL,
  duration_s REAL
);
CREATE TABLE frames (
  frame_index INTEGER PRIMARY KEY,
  time_s REAL,
  utc_us INTEGER,
  map_from_frame BLOB,
  metadata_corners BLOB,
  sensor_latitude_deg REAL,
  sensor_longitude_deg REAL,
  sensor_height_m REAL,
  pts INTEGER,
  key_frame INTEGER,
  sky_y0 REAL,
  sky_slope REAL
);
CREATE TABLE key_frames (
  ordinal INTEGER PRIMARY KEY,
  id INTEGER NOT NULL,
  frame_index INTEGER NOT NULL,
  segment INTEGER NOT NULL,
  map_from_frame BLOB NOT NULL,
  covariance BLOB NOT NULL,
  node INTEGER NOT NULL CHECK (node IN (0, 1))
);
CREATE TABLE links (
  ordinal INTEGER PRIMARY KEY,
  from_id INTEGER NOT NULL,
  to_id INTEGER NOT NULL,
  kind TEXT NOT NULL CHECK (kind IN ('sequential', 'geometric', 'appearance')),
  to_from_from BLOB NOT NULL,
  covariance BLOB NOT NULL,
  correspondences INTEGER NOT NULL
);
CREATE TABLE tracks (
  ordinal INTEGER PRIMARY KEY,
  id INTEGER NOT NULL,
  start_s REAL,
  end_s REAL,
  length REAL,
  speed REAL,
  speed_mps REAL,
  heading_deg REAL,
  visit INTEGER NOT NULL,
  point_count INTEGER NOT NULL,
  confidence REAL CHECK (confidence IS NULL OR (confidence >= 0 AND confidence <= 1))
);
CREATE TABLE track_points (
  track_ordinal INTEGER NOT NULL REFERENCES tracks (ordinal),
  ordinal INTEGER NOT NULL,
  frame INTEGER NOT NULL,
  time_s REAL,
  image_x REAL,
  image_y REAL,
  box_min_x REAL,
  box_min_y REAL,
  box_max_x REAL,
  box_max_y REAL,
  map_x REAL,
  map_y REAL,
  interpolated INTEGER NOT NULL DEFAULT 0 CHECK (interpolated IN (0, 1)),
  PRIMARY KEY (track_ordinal, ordinal)
) WITHOUT ROWID;
CREATE TABLE tiles (
  level INTEGER NOT NULL,
  x INTEGER NOT NULL,
  y INTEGER NOT NULL,
  data BLOB NOT NULL,
  PRIMARY KEY (level, x, y)
);
)sql";

// The processing checkpoints of an unfinished job: opaque records that pipeline/checkpoint.h
// gives a meaning to. Added in schema version 3.
constexpr const char* kCheckpointSql = R"sql(
CREATE TABLE checkpoint (
  kind TEXT NOT NULL,
  key INTEGER NOT NULL,
  data BLOB NOT NULL,
  PRIMARY KEY (kind, key)
) WITHOUT ROWID;
)sql";

// The screen-fixed overlay masks (mission.h OverlayRecord): `cells` holds cols * rows bits,
// row-major, least significant bit first, 1 on the overlay. Added in schema version 5.
constexpr const char* kOverlaysSql = R"sql(
CREATE TABLE overlays (
  ordinal INTEGER PRIMARY KEY,
  first_frame INTEGER NOT NULL,
  last_frame INTEGER NOT NULL,
  cell_px INTEGER NOT NULL,
  cols INTEGER NOT NULL,
  rows INTEGER NOT NULL,
  cells BLOB NOT NULL
);
)sql";

// The analyst's reviews of tracks and bookmarks (mission.h TrackReview, Bookmark): verdict 0 none,
// 1 confirmed, 2 false; label 0 none, 1 vehicle, 2 person, 3 other. Added in schema version 7.
constexpr const char* kReviewsSql = R"sql(
CREATE TABLE track_reviews (
  track_id INTEGER PRIMARY KEY,
  verdict INTEGER NOT NULL CHECK (verdict BETWEEN 0 AND 2),
  label INTEGER NOT NULL CHECK (label BETWEEN 0 AND 3),
  note TEXT NOT NULL
);
CREATE TABLE bookmarks (
  id INTEGER PRIMARY KEY CHECK (id >= 1),
  time_s REAL NOT NULL,
  map_x REAL NOT NULL,
  map_y REAL NOT NULL,
  note TEXT NOT NULL
);
)sql";

constexpr const char* kTables[] = {"meta",  "source", "frames",       "key_frames",
                                   "links", "tracks", "track_points", "tiles"};

// Meta keys.
constexpr const char* kKeySchemaVersion = "schema_version";
constexpr const char* kKeySakerVersion = "saker_version";
constexpr const char* kKeyOptionsJson = "options_json";
constexpr const char* kKeyGeoReferenced = "map_geo_referenced";
constexpr const char* kKeyOriginLatitude = "map_origin_latitude_deg";
constexpr const char* kKeyOriginLongitude = "map_origin_longitude_deg";
constexpr const char* kKeyOriginHeight = "map_origin_height_m";
constexpr const char* kKeyTileSize = "pyramid_tile_size";
constexpr const char* kKeyLevels = "pyramid_levels";
constexpr const char* kKeyWidth = "pyramid_width";
constexpr const char* kKeyHeight = "pyramid_height";
constexpr const char* kKeyMapOriginX = "pyramid_map_origin_x";
constexpr const char* kKeyMapOriginY = "pyramid_map_origin_y";
constexpr const char* kKeyStepX = "pyramid_step_x";
constexpr const char* kKeyStepY = "pyramid_step_y";
constexpr const char* kKeyFrontEnd = "progress_front_end";
constexpr const char* kKeyMosaic = "progress_mosaic";
constexpr const char* kKeyActivity = "progress_activity";
constexpr const char* kKeyTiles = "progress_tiles";
constexpr const char* kKeyCancelled = "progress_cancelled";
// Optional (absent in files written before they were counted); readers of older versions ignore
// them, so the schema version is unchanged.
constexpr const char* kKeyKlvPackets = "klv_packets";
constexpr const char* kKeyKlvChecksumFailures = "klv_checksum_failures";
constexpr const char* kKeyKlvBadChecksumsUsed = "klv_bad_checksums_used";

constexpr const char* kKeyLowFrameRate = "findings_low_frame_rate";
constexpr const char* kKeyPolaritySwitches = "findings_polarity_switches";
constexpr const char* kKeyNoiseFeatureFrames = "findings_noise_feature_frames";
constexpr const char* kKeyNoiseChangeFrames = "findings_noise_change_frames";
constexpr const char* kKeyNoiseFeaturePx = "findings_noise_feature_px";
constexpr const char* kKeyNoiseChangeGrey = "findings_noise_change_grey";
constexpr const char* kKeyNoiseChangeRegistration = "findings_noise_change_registration_px";
constexpr std::initializer_list<const char*> kFindingsKeys = {
    kKeyLowFrameRate,   kKeyPolaritySwitches, kKeyNoiseFeatureFrames,     kKeyNoiseChangeFrames,
    kKeyNoiseFeaturePx, kKeyNoiseChangeGrey,  kKeyNoiseChangeRegistration};
constexpr std::initializer_list<const char*> kOriginKeys = {kKeyOriginLatitude, kKeyOriginLongitude,
                                                            kKeyOriginHeight};
constexpr std::initializer_list<const char*> kKlvKeys = {kKeyKlvPackets, kKeyKlvChecksumFailures,
                                                         kKeyKlvBadChecksumsUsed};
constexpr std::initializer_list<const char*> kPyramidKeys = {
    kKeyTileSize,   kKeyLevels,     kKeyWidth, kKeyHeight,
    kKeyMapOriginX, kKeyMapOriginY, kKeyStepX, kKeyStepY};

// One value of the meta table.
struct MetaValue {
  int type = SQLITE_NULL;
  int64_t integer = 0;
  double real = 0;
  std::string text;
};

// Typed access to the meta table's values, remembering the first problem like RowReader.
class MetaReader {
 public:
  MetaReader(const std::map<std::string, MetaValue>& values, const std::string& path)
      : values_(values), path_(path) {}

  const Status& status() const { return status_; }

  bool Has(const char* key) const { return values_.count(key) > 0; }
  // How many of `keys` are present; `group` (all or none) fails otherwise.
  bool HasGroup(std::initializer_list<const char*> keys, const char* group) {
    size_t present = 0;
    for (const char* key : keys) present += Has(key) ? 1 : 0;
    if (present != 0 && present != keys.size()) {
      Fail(std::string("the ") + group + " is incomplete (" + std::to_string(present) + " of " +
           std::to_string(keys.size()) + " keys)");
    }
    return present == keys.size();
  }
  int64_t Int(const char* key, int64_t lo, int64_t hi) {
    const MetaValue* v = Find(key);
    if (v == nullptr) return 0;
    if (v->type != SQLITE_INTEGER) {
      Fail(std::string("key '") + key + "': expected an integer, found " +
           sqlite::TypeName(v->type));
      return 0;
    }
    if (v->integer < lo || v->integer > hi) {
      Fail(std::string("key '") + key + "': " + std::to_string(v->integer) + " is outside [" +
           std::to_string(lo) + ", " + std::to_string(hi) + "]");
      return 0;
    }
    return v->integer;
  }
  int Int32(const char* key) {
    return static_cast<int>(
        Int(key, std::numeric_limits<int32_t>::min(), std::numeric_limits<int32_t>::max()));
  }
  bool Bool(const char* key) { return Int(key, 0, 1) == 1; }
  double Real(const char* key) {
    const MetaValue* v = Find(key);
    if (v == nullptr) return 0;
    if (v->type == SQLITE_NULL) return std::numeric_limits<double>::quiet_NaN();
    if (v->type == SQLITE_INTEGER) return static_cast<double>(v->integer);
    if (v->type != SQLITE_FLOAT) {
      Fail(std::string("key '") + key + "': expected a real number, found " +
           sqlite::TypeName(v->type));
      return 0;
    }
    return v->real;
  }
  std::string Text(const char* key) {
    const MetaValue* v = Find(key);
    if (v == nullptr) return {};
    if (v->type != SQLITE_TEXT) {
      Fail(std::string("key '") + key + "': expected text, found " + sqlite::TypeName(v->type));
      return {};
    }
    return v->text;
  }

  void Fail(const std::string& problem) {
    if (status_.ok()) status_ = InvalidDataError(path_ + ": table meta: " + problem);
  }

 private:
  const MetaValue* Find(const char* key) {
    const auto it = values_.find(key);
    if (it == values_.end()) {
      Fail(std::string("key '") + key + "' is missing");
      return nullptr;
    }
    return &it->second;
  }

  const std::map<std::string, MetaValue>& values_;
  const std::string& path_;
  Status status_;
};

bool ValidLinkKind(LinkKind kind) { return LinkKindFromName(LinkKindName(kind)).has_value(); }

// Reads the first `n` bytes of `path`: fewer when the file is shorter.
StatusOr<std::string> ReadPrefix(const std::string& path, size_t n) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    const int err = errno;
    if (err == ENOENT) return NotFoundError(path + ": no such file");
    return IoError(path + ": cannot open: " + std::strerror(err));
  }
  std::string bytes(n, '\0');
  size_t got = 0;
  while (got < n) {
    const ssize_t r = ::pread(fd, bytes.data() + got, n - got, static_cast<off_t>(got));
    if (r < 0 && errno == EINTR) continue;
    if (r < 0) {
      const int err = errno;
      ::close(fd);
      return IoError(path + ": cannot read: " + std::strerror(err));
    }
    if (r == 0) break;
    got += static_cast<size_t>(r);
  }
  ::close(fd);
  bytes.resize(got);
  return bytes;
}

uint32_t BigEndian32(const std::string& bytes, size_t offset) {
  return static_cast<uint32_t>(static_cast<uint8_t>(bytes[offset])) << 24 |
         static_cast<uint32_t>(static_cast<uint8_t>(bytes[offset + 1])) << 16 |
         static_cast<uint32_t>(static_cast<uint8_t>(bytes[offset + 2])) << 8 |
         static_cast<uint32_t>(static_cast<uint8_t>(bytes[offset + 3]));
}

std::string Hex32(uint32_t v) {
  char buffer[16];
  std::snprintf(buffer, sizeof(buffer), "0x%08" PRIX32, v);
  return buffer;
}

StatusOr<int> ReadSchemaVersion(const sqlite::Database& db) {
  SAKER_ASSIGN_OR_RETURN(sqlite::Statement stmt,
                         db.Prepare("SELECT value FROM meta WHERE key = 'schema_version'",
                                    "reading the schema version"));
  sqlite::ResetOnExit reset(stmt.get());
  const int rc = sqlite3_step(stmt.get());
  if (rc == SQLITE_DONE) {
    return InvalidDataError(db.path() + ": not a Saker mission (table meta has no schema_version)");
  }
  if (rc != SQLITE_ROW) return db.Error(rc, "reading the schema version");
  if (sqlite3_column_type(stmt.get(), 0) != SQLITE_INTEGER) {
    return InvalidDataError(db.path() + ": table meta: schema_version is not an integer");
  }
  const int64_t version = sqlite3_column_int64(stmt.get(), 0);
  if (version < 1 || version > std::numeric_limits<int32_t>::max()) {
    return InvalidDataError(db.path() + ": table meta: schema_version " + std::to_string(version) +
                            " is not a valid version");
  }
  return static_cast<int>(version);
}

// ---------------------------------------------------------------------------------------------
// Save.

Status WriteHeader(const sqlite::Database& db, const Mission& m) {
  SAKER_RETURN_IF_ERROR(db.Exec("DELETE FROM meta", "saving table meta"));
  SAKER_ASSIGN_OR_RETURN(
      sqlite::Statement stmt,
      db.Prepare("INSERT INTO meta (key, value) VALUES (?1, ?2)", "saving table meta"));
  auto put_int = [&](const char* key, int64_t value) {
    sqlite::Binder b(stmt.get());
    b.Text(1, key);
    b.Int64(2, value);
    return db.Run(stmt.get(), b, "saving table meta");
  };
  auto put_real = [&](const char* key, double value) {
    sqlite::Binder b(stmt.get());
    b.Text(1, key);
    b.Double(2, value);
    return db.Run(stmt.get(), b, "saving table meta");
  };
  auto put_text = [&](const char* key, const std::string& value) {
    sqlite::Binder b(stmt.get());
    b.Text(1, key);
    b.Text(2, value);
    return db.Run(stmt.get(), b, "saving table meta");
  };
  SAKER_RETURN_IF_ERROR(put_int(kKeySchemaVersion, kSchemaVersion));
  SAKER_RETURN_IF_ERROR(put_text(kKeySakerVersion, m.saker_version));
  SAKER_RETURN_IF_ERROR(put_text(kKeyOptionsJson, m.options_json));
  SAKER_RETURN_IF_ERROR(put_int(kKeyGeoReferenced, m.map.geo_referenced ? 1 : 0));
  if (m.map.origin) {
    SAKER_RETURN_IF_ERROR(put_real(kKeyOriginLatitude, m.map.origin->latitude_deg));
    SAKER_RETURN_IF_ERROR(put_real(kKeyOriginLongitude, m.map.origin->longitude_deg));
    SAKER_RETURN_IF_ERROR(put_real(kKeyOriginHeight, m.map.origin->height_m));
  }
  if (m.pyramid) {
    const PyramidInfo& p = *m.pyramid;
    SAKER_RETURN_IF_ERROR(put_int(kKeyTileSize, p.tile_size));
    SAKER_RETURN_IF_ERROR(put_int(kKeyLevels, p.levels));
    SAKER_RETURN_IF_ERROR(put_int(kKeyWidth, p.width));
    SAKER_RETURN_IF_ERROR(put_int(kKeyHeight, p.height));
    SAKER_RETURN_IF_ERROR(put_real(kKeyMapOriginX, p.map_origin.x()));
    SAKER_RETURN_IF_ERROR(put_real(kKeyMapOriginY, p.map_origin.y()));
    SAKER_RETURN_IF_ERROR(put_real(kKeyStepX, p.step_x));
    SAKER_RETURN_IF_ERROR(put_real(kKeyStepY, p.step_y));
  }
  if (m.klv) {
    SAKER_RETURN_IF_ERROR(put_int(kKeyKlvPackets, m.klv->packets));
    SAKER_RETURN_IF_ERROR(put_int(kKeyKlvChecksumFailures, m.klv->checksum_failures));
    SAKER_RETURN_IF_ERROR(put_int(kKeyKlvBadChecksumsUsed, m.klv->bad_checksums_used ? 1 : 0));
  }
  if (const std::optional<FrontEndFindings>& f = m.findings) {
    SAKER_RETURN_IF_ERROR(put_int(kKeyLowFrameRate, f->low_frame_rate ? 1 : 0));
    SAKER_RETURN_IF_ERROR(put_int(kKeyPolaritySwitches, f->polarity_switches));
    SAKER_RETURN_IF_ERROR(put_int(kKeyNoiseFeatureFrames, f->noise_feature_frames));
    SAKER_RETURN_IF_ERROR(put_int(kKeyNoiseChangeFrames, f->noise_change_frames));
    SAKER_RETURN_IF_ERROR(put_real(kKeyNoiseFeaturePx, f->noise_feature_px));
    SAKER_RETURN_IF_ERROR(put_real(kKeyNoiseChangeGrey, f->noise_change_grey));
    SAKER_RETURN_IF_ERROR(put_real(kKeyNoiseChangeRegistration, f->noise_change_registration_px));
  }
  SAKER_RETURN_IF_ERROR(put_int(kKeyFrontEnd, m.progress.front_end));
  SAKER_RETURN_IF_ERROR(put_int(kKeyMosaic, m.progress.mosaic));
  SAKER_RETURN_IF_ERROR(put_int(kKeyActivity, m.progress.activity));
  SAKER_RETURN_IF_ERROR(put_int(kKeyTiles, m.progress.tiles));
  SAKER_RETURN_IF_ERROR(put_int(kKeyCancelled, m.progress.cancelled));

  SAKER_RETURN_IF_ERROR(db.Exec("DELETE FROM source", "saving table source"));
  SAKER_ASSIGN_OR_RETURN(
      sqlite::Statement source,
      db.Prepare(
          "INSERT INTO source (id, path, fingerprint, size_bytes, width, height, frame_rate, "
          "frame_count, duration_s) VALUES (1, ?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8)",
          "saving table source"));
  const SourceVideo& s = m.source;
  sqlite::Binder b(source.get());
  b.Text(1, s.path);
  b.Text(2, s.fingerprint);
  b.Int64(3, s.size_bytes);
  b.Int64(4, s.width);
  b.Int64(5, s.height);
  b.Double(6, s.frame_rate);
  b.Int64(7, s.frame_count);
  b.Double(8, s.duration_s);
  return db.Run(source.get(), b, "saving table source");
}

Status WriteFrames(const sqlite::Database& db, const std::vector<FrameRecord>& frames) {
  SAKER_RETURN_IF_ERROR(db.Exec("DELETE FROM frames", "saving table frames"));
  SAKER_ASSIGN_OR_RETURN(
      sqlite::Statement stmt,
      db.Prepare(
          "INSERT INTO frames (frame_index, time_s, utc_us, map_from_frame, metadata_corners, "
          "sensor_latitude_deg, sensor_longitude_deg, sensor_height_m, pts, key_frame, sky_y0, "
          "sky_slope) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12)",
          "saving table frames"));
  uint8_t matrix[kMatrix3Values * 8];
  uint8_t corners[kCornerValues * 8];
  for (const FrameRecord& f : frames) {
    sqlite::Binder b(stmt.get());
    b.Int64(1, f.index);
    b.Double(2, f.time_s);
    b.OptionalInt64(3, f.utc_us);
    if (f.map_from_frame) {
      sqlite::EncodeRowMajor(*f.map_from_frame, matrix);
      b.Blob(4, matrix, sizeof(matrix));
    } else {
      b.Null(4);
    }
    if (f.metadata_corners) {
      double values[kCornerValues];
      for (int i = 0; i < 4; ++i) {
        values[2 * i] = (*f.metadata_corners)[static_cast<size_t>(i)].x();
        values[2 * i + 1] = (*f.metadata_corners)[static_cast<size_t>(i)].y();
      }
      sqlite::EncodeDoubles(values, kCornerValues, corners);
      b.Blob(5, corners, sizeof(corners));
    } else {
      b.Null(5);
    }
    if (f.sensor) {
      b.Double(6, f.sensor->latitude_deg);
      b.Double(7, f.sensor->longitude_deg);
      b.Double(8, f.sensor->height_m);
    } else {
      b.Null(6);
      b.Null(7);
      b.Null(8);
    }
    b.OptionalInt64(9, f.pts);
    if (f.pts) {
      b.Int64(10, f.key_frame ? 1 : 0);
    } else {
      b.Null(10);
    }
    if (f.sky_line) {
      b.Double(11, f.sky_line->y0);
      b.Double(12, f.sky_line->slope);
    } else {
      b.Null(11);
      b.Null(12);
    }
    SAKER_RETURN_IF_ERROR(db.Run(stmt.get(), b, "saving table frames"));
  }
  return Status::Ok();
}

// Bits of an overlay mask's cells, row-major, least significant bit first.
std::vector<uint8_t> PackCells(const std::vector<uint8_t>& cells) {
  std::vector<uint8_t> bits((cells.size() + 7) / 8, 0);
  for (size_t i = 0; i < cells.size(); ++i) {
    if (cells[i] != 0) bits[i / 8] = static_cast<uint8_t>(bits[i / 8] | (1u << (i % 8)));
  }
  return bits;
}

Status WriteOverlays(const sqlite::Database& db, const std::vector<OverlayRecord>& overlays) {
  SAKER_RETURN_IF_ERROR(db.Exec("DELETE FROM overlays", "saving table overlays"));
  SAKER_ASSIGN_OR_RETURN(
      sqlite::Statement stmt,
      db.Prepare("INSERT INTO overlays (ordinal, first_frame, last_frame, cell_px, cols, rows, "
                 "cells) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7)",
                 "saving table overlays"));
  for (size_t i = 0; i < overlays.size(); ++i) {
    const OverlayRecord& o = overlays[i];
    const std::vector<uint8_t> bits = PackCells(o.cells);
    sqlite::Binder b(stmt.get());
    b.Int64(1, static_cast<int64_t>(i));
    b.Int64(2, o.first_frame);
    b.Int64(3, o.last_frame);
    b.Int64(4, o.cell_px);
    b.Int64(5, o.cols);
    b.Int64(6, o.rows);
    b.Blob(7, bits.data(), bits.size());
    SAKER_RETURN_IF_ERROR(db.Run(stmt.get(), b, "saving table overlays"));
  }
  return Status::Ok();
}

// Why `overlays` break a rule of the file: a record's own (OverlayRecord::Problem), or the order
// (increasing and disjoint frame ranges). Empty when they do not.
std::string OverlaysProblem(const std::vector<OverlayRecord>& overlays) {
  for (size_t i = 0; i < overlays.size(); ++i) {
    const std::string problem = overlays[i].Problem();
    if (!problem.empty()) return "overlay mask " + std::to_string(i) + ": " + problem;
    if (i > 0 && overlays[i].first_frame <= overlays[i - 1].last_frame) {
      return "overlay mask " + std::to_string(i) + " starts at frame " +
             std::to_string(overlays[i].first_frame) + ", within the previous one (to frame " +
             std::to_string(overlays[i - 1].last_frame) + ")";
    }
  }
  return {};
}

Status WriteGraph(const sqlite::Database& db, const Mission& m) {
  SAKER_RETURN_IF_ERROR(db.Exec("DELETE FROM links", "saving table links"));
  SAKER_RETURN_IF_ERROR(db.Exec("DELETE FROM key_frames", "saving table key_frames"));
  uint8_t matrix[kMatrix3Values * 8];
  uint8_t covariance[kCovarianceValues * 8];
  {
    SAKER_ASSIGN_OR_RETURN(
        sqlite::Statement stmt,
        db.Prepare("INSERT INTO key_frames (ordinal, id, frame_index, segment, map_from_frame, "
                   "covariance, node) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7)",
                   "saving table key_frames"));
    for (size_t i = 0; i < m.key_frames.size(); ++i) {
      const KeyFrameRecord& k = m.key_frames[i];
      sqlite::EncodeRowMajor(k.map_from_frame, matrix);
      sqlite::EncodeRowMajor(k.covariance, covariance);
      sqlite::Binder b(stmt.get());
      b.Int64(1, static_cast<int64_t>(i));
      b.Int64(2, k.id);
      b.Int64(3, k.frame_index);
      b.Int64(4, k.segment);
      b.Blob(5, matrix, sizeof(matrix));
      b.Blob(6, covariance, sizeof(covariance));
      b.Int64(7, k.node ? 1 : 0);
      SAKER_RETURN_IF_ERROR(db.Run(stmt.get(), b, "saving table key_frames"));
    }
  }
  SAKER_ASSIGN_OR_RETURN(
      sqlite::Statement stmt,
      db.Prepare("INSERT INTO links (ordinal, from_id, to_id, kind, to_from_from, covariance, "
                 "correspondences) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7)",
                 "saving table links"));
  for (size_t i = 0; i < m.links.size(); ++i) {
    const LinkRecord& l = m.links[i];
    sqlite::EncodeRowMajor(l.to_from_from, matrix);
    sqlite::EncodeRowMajor(l.covariance, covariance);
    sqlite::Binder b(stmt.get());
    b.Int64(1, static_cast<int64_t>(i));
    b.Int64(2, l.from);
    b.Int64(3, l.to);
    b.Text(4, LinkKindName(l.kind));
    b.Blob(5, matrix, sizeof(matrix));
    b.Blob(6, covariance, sizeof(covariance));
    b.Int64(7, l.correspondences);
    SAKER_RETURN_IF_ERROR(db.Run(stmt.get(), b, "saving table links"));
  }
  return Status::Ok();
}

Status WriteTracks(const sqlite::Database& db, const std::vector<ActivityTrack>& tracks) {
  // Points first: they refer to their track.
  SAKER_RETURN_IF_ERROR(db.Exec("DELETE FROM track_points", "saving table track_points"));
  SAKER_RETURN_IF_ERROR(db.Exec("DELETE FROM tracks", "saving table tracks"));
  SAKER_ASSIGN_OR_RETURN(
      sqlite::Statement track_stmt,
      db.Prepare("INSERT INTO tracks (ordinal, id, start_s, end_s, length, speed, speed_mps, "
                 "heading_deg, visit, point_count, confidence) "
                 "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11)",
                 "saving table tracks"));
  SAKER_ASSIGN_OR_RETURN(
      sqlite::Statement point_stmt,
      db.Prepare(
          "INSERT INTO track_points (track_ordinal, ordinal, frame, time_s, image_x, image_y, "
          "box_min_x, box_min_y, box_max_x, box_max_y, map_x, map_y, interpolated) "
          "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13)",
          "saving table track_points"));
  for (size_t i = 0; i < tracks.size(); ++i) {
    const ActivityTrack& t = tracks[i];
    sqlite::Binder b(track_stmt.get());
    b.Int64(1, static_cast<int64_t>(i));
    b.Int64(2, t.id);
    b.Double(3, t.start_s);
    b.Double(4, t.end_s);
    b.Double(5, t.length);
    b.Double(6, t.speed);
    b.OptionalDouble(7, t.speed_mps);
    b.Double(8, t.heading_deg);
    b.Int64(9, t.visit);
    b.Int64(10, static_cast<int64_t>(t.points.size()));
    b.OptionalDouble(11, t.confidence);
    SAKER_RETURN_IF_ERROR(db.Run(track_stmt.get(), b, "saving table tracks"));
    for (size_t j = 0; j < t.points.size(); ++j) {
      const TrackPoint& p = t.points[j];
      sqlite::Binder pb(point_stmt.get());
      pb.Int64(1, static_cast<int64_t>(i));
      pb.Int64(2, static_cast<int64_t>(j));
      pb.Int64(3, p.frame);
      pb.Double(4, p.time_s);
      pb.Double(5, p.image.x());
      pb.Double(6, p.image.y());
      pb.Double(7, p.box_min.x());
      pb.Double(8, p.box_min.y());
      pb.Double(9, p.box_max.x());
      pb.Double(10, p.box_max.y());
      pb.Double(11, p.map.x());
      pb.Double(12, p.map.y());
      pb.Int64(13, p.interpolated ? 1 : 0);
      SAKER_RETURN_IF_ERROR(db.Run(point_stmt.get(), pb, "saving table track_points"));
    }
  }
  return Status::Ok();
}

Status WriteReviews(const sqlite::Database& db, const Mission& m) {
  SAKER_RETURN_IF_ERROR(db.Exec("DELETE FROM track_reviews", "saving table track_reviews"));
  SAKER_RETURN_IF_ERROR(db.Exec("DELETE FROM bookmarks", "saving table bookmarks"));
  SAKER_ASSIGN_OR_RETURN(sqlite::Statement review,
                         db.Prepare("INSERT INTO track_reviews (track_id, verdict, label, note) "
                                    "VALUES (?1, ?2, ?3, ?4)",
                                    "saving table track_reviews"));
  for (const TrackReview& r : m.reviews) {
    sqlite::Binder b(review.get());
    b.Int64(1, r.track_id);
    b.Int64(2, static_cast<int64_t>(r.verdict));
    b.Int64(3, static_cast<int64_t>(r.label));
    b.Text(4, r.note);
    SAKER_RETURN_IF_ERROR(db.Run(review.get(), b, "saving table track_reviews"));
  }
  SAKER_ASSIGN_OR_RETURN(sqlite::Statement bookmark,
                         db.Prepare("INSERT INTO bookmarks (id, time_s, map_x, map_y, note) "
                                    "VALUES (?1, ?2, ?3, ?4, ?5)",
                                    "saving table bookmarks"));
  for (const Bookmark& k : m.bookmarks) {
    sqlite::Binder b(bookmark.get());
    b.Int64(1, k.id);
    b.Double(2, k.time_s);
    b.Double(3, k.map.x());
    b.Double(4, k.map.y());
    b.Text(5, k.note);
    SAKER_RETURN_IF_ERROR(db.Run(bookmark.get(), b, "saving table bookmarks"));
  }
  return Status::Ok();
}

// ---------------------------------------------------------------------------------------------
// Load. Each table is read in order, every value checked (sqlite::RowReader); a row that breaks a
// rule of the file stops the load with InvalidData naming the table, the row and the column.

// An `ordinal` column that must count the rows read so far: a gap means a row is missing.
void CheckOrdinal(sqlite::RowReader& row, int col, int64_t ordinal, size_t expected) {
  if (ordinal != static_cast<int64_t>(expected)) {
    row.Fail(col, "ordinal " + std::to_string(ordinal) + " where " + std::to_string(expected) +
                      " was expected (a row is missing)");
  }
}

// Appends a T to `out` for each row of `sql` (from `table`): `read(row, &t)` fills it, leaving
// any problem in the reader, which stops the load before `t` is kept.
template <typename T, typename Read>
Status LoadRows(const sqlite::Database& db, const char* sql, const char* table, std::vector<T>* out,
                Read read) {
  return db.ForEachRow(sql, std::string("loading table ") + table, table,
                       [&](sqlite::RowReader& row) -> Status {
                         T value;
                         read(row, &value);
                         SAKER_RETURN_IF_ERROR(row.status());
                         out->push_back(std::move(value));
                         return Status::Ok();
                       });
}

Status LoadMeta(const sqlite::Database& db, Mission* m) {
  std::map<std::string, MetaValue> values;
  const auto read_meta = [&](sqlite::RowReader& row) -> Status {
    std::string key = row.Text(0);
    SAKER_RETURN_IF_ERROR(row.status());
    MetaValue v;
    v.type = row.Type(1);
    if (v.type == SQLITE_INTEGER) v.integer = row.Int64(1);
    if (v.type == SQLITE_FLOAT) v.real = row.Real(1);
    if (v.type == SQLITE_TEXT) v.text = row.Text(1);
    SAKER_RETURN_IF_ERROR(row.status());
    if (!values.emplace(key, std::move(v)).second) {
      return InvalidDataError(db.path() + ": table meta: key '" + key + "' appears twice");
    }
    return Status::Ok();
  };
  SAKER_RETURN_IF_ERROR(
      db.ForEachRow("SELECT key, value FROM meta", "loading table meta", "meta", read_meta));
  MetaReader meta(values, db.path());
  const int64_t version = meta.Int(kKeySchemaVersion, 1, std::numeric_limits<int32_t>::max());
  SAKER_RETURN_IF_ERROR(meta.status());
  if (version > kSchemaVersion) {
    return UnsupportedError(db.path() + ": written by a newer Saker: schema " +
                            std::to_string(version) + ", this version reads up to " +
                            std::to_string(kSchemaVersion));
  }
  m->schema_version = static_cast<int>(version);
  m->saker_version = meta.Text(kKeySakerVersion);
  m->options_json = meta.Text(kKeyOptionsJson);
  m->map.geo_referenced = meta.Bool(kKeyGeoReferenced);
  if (meta.HasGroup(kOriginKeys, "map origin")) {
    geo::Wgs84 origin;
    origin.latitude_deg = meta.Real(kKeyOriginLatitude);
    origin.longitude_deg = meta.Real(kKeyOriginLongitude);
    origin.height_m = meta.Real(kKeyOriginHeight);
    m->map.origin = origin;
  }
  if (meta.HasGroup(kPyramidKeys, "pyramid")) {
    PyramidInfo p;
    p.tile_size = meta.Int32(kKeyTileSize);
    p.levels = meta.Int32(kKeyLevels);
    p.width = meta.Int32(kKeyWidth);
    p.height = meta.Int32(kKeyHeight);
    p.map_origin = Eigen::Vector2d(meta.Real(kKeyMapOriginX), meta.Real(kKeyMapOriginY));
    p.step_x = meta.Real(kKeyStepX);
    p.step_y = meta.Real(kKeyStepY);
    m->pyramid = p;
  }
  if (meta.HasGroup(kKlvKeys, "KLV summary")) {
    KlvSummary klv;
    klv.packets = meta.Int(kKeyKlvPackets, 0, std::numeric_limits<int64_t>::max());
    klv.checksum_failures = meta.Int(kKeyKlvChecksumFailures, 0, klv.packets);
    klv.bad_checksums_used = meta.Bool(kKeyKlvBadChecksumsUsed);
    m->klv = klv;
  }
  if (meta.HasGroup(kFindingsKeys, "front end findings")) {
    constexpr int64_t kMaxCount = std::numeric_limits<int64_t>::max();
    FrontEndFindings f;
    f.low_frame_rate = meta.Bool(kKeyLowFrameRate);
    f.polarity_switches = meta.Int(kKeyPolaritySwitches, 0, kMaxCount);
    f.noise_feature_frames = meta.Int(kKeyNoiseFeatureFrames, 0, kMaxCount);
    f.noise_change_frames = meta.Int(kKeyNoiseChangeFrames, 0, kMaxCount);
    f.noise_feature_px = meta.Real(kKeyNoiseFeaturePx);
    f.noise_change_grey = meta.Real(kKeyNoiseChangeGrey);
    f.noise_change_registration_px = meta.Real(kKeyNoiseChangeRegistration);
    m->findings = f;
  }
  m->progress.front_end = meta.Bool(kKeyFrontEnd);
  m->progress.mosaic = meta.Bool(kKeyMosaic);
  m->progress.activity = meta.Bool(kKeyActivity);
  m->progress.tiles = meta.Bool(kKeyTiles);
  m->progress.cancelled = meta.Bool(kKeyCancelled);
  SAKER_RETURN_IF_ERROR(meta.status());
  const std::string problem = HeaderProblem(*m);
  if (!problem.empty()) return InvalidDataError(db.path() + ": table meta: " + problem);
  return Status::Ok();
}

Status LoadSource(const sqlite::Database& db, SourceVideo* s) {
  int64_t rows = 0;
  const auto read_source = [&](sqlite::RowReader& row) -> Status {
    rows = row.row();
    if (rows > 1) return InvalidDataError(db.path() + ": table source: more than one row");
    row.Int(0, 1, 1);
    s->path = row.Text(1);
    s->fingerprint = row.Text(2);
    s->size_bytes = row.Int64(3);
    s->width = row.Int32(4);
    s->height = row.Int32(5);
    s->frame_rate = row.Real(6);
    s->frame_count = row.Int64(7);
    s->duration_s = row.Real(8);
    return row.status();
  };
  SAKER_RETURN_IF_ERROR(db.ForEachRow(
      "SELECT id, path, fingerprint, size_bytes, width, height, frame_rate, frame_count, "
      "duration_s FROM source",
      "loading table source", "source", read_source));
  if (rows == 0) return InvalidDataError(db.path() + ": table source: no row");
  return Status::Ok();
}

Status LoadFrames(const sqlite::Database& db, int schema, std::vector<FrameRecord>* frames) {
  // Columns a version did not have yet read as NULL.
  const std::string sql =
      std::string(
          "SELECT frame_index, time_s, utc_us, map_from_frame, metadata_corners, "
          "sensor_latitude_deg, sensor_longitude_deg, sensor_height_m, ") +
      (schema >= 2 ? "pts, key_frame, " : "NULL, NULL, ") +
      (schema >= 6 ? "sky_y0, sky_slope " : "NULL, NULL ") + "FROM frames ORDER BY frame_index";
  return LoadRows(db, sql.c_str(), "frames", frames, [&](sqlite::RowReader& row, FrameRecord* f) {
    f->index = row.Int64(0);
    if (!frames->empty() && f->index <= frames->back().index) {
      row.Fail(0, "frame index " + std::to_string(f->index) + " appears twice");
    }
    f->time_s = row.Real(1);
    f->utc_us = row.OptionalInt64(2);
    if (!row.IsNull(3)) f->map_from_frame = row.RowMajor<Eigen::Matrix3d>(3);
    if (!row.IsNull(4)) {
      double values[kCornerValues];
      row.Doubles(4, kCornerValues, values);
      std::array<Eigen::Vector2d, 4> corners;
      for (int i = 0; i < 4; ++i) {
        corners[static_cast<size_t>(i)] = Eigen::Vector2d(values[2 * i], values[2 * i + 1]);
      }
      f->metadata_corners = corners;
    }
    // The sensor is absent when all three columns are NULL; a single NULL is a NaN.
    if (!row.IsNull(5) || !row.IsNull(6) || !row.IsNull(7)) {
      f->sensor = geo::Wgs84{row.Real(5), row.Real(6), row.Real(7)};
    }
    f->pts = row.OptionalInt64(8);
    if (f->pts) f->key_frame = row.Bool(9);
    if (!row.IsNull(10) || !row.IsNull(11)) {
      const SkyLine line{row.Real(10), row.Real(11)};
      const std::string problem = line.Problem();
      if (!problem.empty()) {
        row.Fail(10, problem);
        return;
      }
      f->sky_line = line;
    }
  });
}

Status LoadOverlays(const sqlite::Database& db, std::vector<OverlayRecord>* overlays) {
  return LoadRows(
      db,
      "SELECT ordinal, first_frame, last_frame, cell_px, cols, rows, cells FROM overlays "
      "ORDER BY ordinal",
      "overlays", overlays, [&](sqlite::RowReader& row, OverlayRecord* o) {
        CheckOrdinal(row, 0, row.Int64(0), overlays->size());
        o->first_frame = row.Int(1, 0, std::numeric_limits<int64_t>::max());
        o->last_frame = row.Int(2, o->first_frame, std::numeric_limits<int64_t>::max());
        o->cell_px = static_cast<int>(row.Int(3, 1, kMaxOverlayCellPx));
        o->cols = static_cast<int>(row.Int(4, 1, kMaxOverlayCells));
        o->rows = static_cast<int>(row.Int(5, 1, kMaxOverlayCells));
        if (!row.status().ok()) return;
        if (!overlays->empty() && o->first_frame <= overlays->back().last_frame) {
          row.Fail(1, "frame " + std::to_string(o->first_frame) +
                          " is within the previous mask (to frame " +
                          std::to_string(overlays->back().last_frame) + ")");
          return;
        }
        const size_t n = static_cast<size_t>(o->cols) * static_cast<size_t>(o->rows);
        std::vector<uint8_t> bits;
        if (row.Type(6) != SQLITE_BLOB) {
          row.Fail(6, std::string("expected a blob, found ") + sqlite::TypeName(row.Type(6)));
          return;
        }
        if (!row.Bytes(6, &bits)) {
          row.Fail(6, "out of memory reading the cells");
          return;
        }
        if (bits.size() != (n + 7) / 8) {
          row.Fail(6, "blob of " + std::to_string(bits.size()) + " bytes, expected " +
                          std::to_string((n + 7) / 8) + " for " + std::to_string(n) + " cells");
          return;
        }
        o->cells.resize(n);
        for (size_t i = 0; i < n; ++i) o->cells[i] = (bits[i / 8] >> (i % 8)) & 1u;
      });
}

// A note: text of at most kMaxNoteBytes.
std::string ReadNote(sqlite::RowReader& row, int col) {
  std::string note = row.Text(col);
  if (row.status().ok() && note.size() > kMaxNoteBytes) {
    row.Fail(col, "a note of " + std::to_string(note.size()) + " bytes, more than " +
                      std::to_string(kMaxNoteBytes));
  }
  return note;
}

Status LoadReviews(const sqlite::Database& db, std::vector<TrackReview>* reviews) {
  return LoadRows(db, "SELECT track_id, verdict, label, note FROM track_reviews ORDER BY track_id",
                  "track_reviews", reviews, [&](sqlite::RowReader& row, TrackReview* r) {
                    r->track_id = row.Int64(0);
                    r->verdict = static_cast<Verdict>(row.Int(1, 0, 2));
                    r->label = static_cast<TargetLabel>(row.Int(2, 0, 3));
                    r->note = ReadNote(row, 3);
                  });
}

Status LoadBookmarks(const sqlite::Database& db, std::vector<Bookmark>* bookmarks) {
  return LoadRows(db, "SELECT id, time_s, map_x, map_y, note FROM bookmarks ORDER BY id",
                  "bookmarks", bookmarks, [&](sqlite::RowReader& row, Bookmark* k) {
                    k->id = row.Int(0, 1, std::numeric_limits<int64_t>::max());
                    k->time_s = row.Real(1);
                    k->map = {row.Real(2), row.Real(3)};
                    if (row.status().ok() && !(std::isfinite(k->time_s) && k->map.allFinite())) {
                      row.FailRow("the time or the place is not a finite number");
                    }
                    k->note = ReadNote(row, 4);
                  });
}

Status LoadKeyFrames(const sqlite::Database& db, std::vector<KeyFrameRecord>* key_frames) {
  return LoadRows(db,
                  "SELECT ordinal, id, frame_index, segment, map_from_frame, covariance, node "
                  "FROM key_frames ORDER BY ordinal",
                  "key_frames", key_frames, [&](sqlite::RowReader& row, KeyFrameRecord* k) {
                    CheckOrdinal(row, 0, row.Int64(0), key_frames->size());
                    k->id = row.Int32(1);
                    k->frame_index = row.Int64(2);
                    k->segment = row.Int32(3);
                    k->map_from_frame = row.RowMajor<Eigen::Matrix3d>(4);
                    k->covariance = row.RowMajor<Covariance8>(5);
                    k->node = row.Bool(6);
                  });
}

Status LoadLinks(const sqlite::Database& db, std::vector<LinkRecord>* links) {
  return LoadRows(db,
                  "SELECT ordinal, from_id, to_id, kind, to_from_from, covariance, correspondences "
                  "FROM links ORDER BY ordinal",
                  "links", links, [&](sqlite::RowReader& row, LinkRecord* l) {
                    CheckOrdinal(row, 0, row.Int64(0), links->size());
                    l->from = row.Int32(1);
                    l->to = row.Int32(2);
                    const std::string kind = row.Text(3);
                    if (row.status().ok()) {
                      const std::optional<LinkKind> parsed = LinkKindFromName(kind);
                      if (parsed) {
                        l->kind = *parsed;
                      } else {
                        row.Fail(3, "unknown link kind '" + kind + "'");
                      }
                    }
                    l->to_from_from = row.RowMajor<Eigen::Matrix3d>(4);
                    l->covariance = row.RowMajor<Covariance8>(5);
                    l->correspondences = row.Int32(6);
                  });
}

Status LoadTracks(const sqlite::Database& db, int schema, std::vector<ActivityTrack>* tracks) {
  std::vector<int64_t> point_counts;
  // Each track's point count, read with it (kept only when the whole row is good).
  SAKER_RETURN_IF_ERROR(LoadRows(
      db,
      schema >= 4 ? "SELECT ordinal, id, start_s, end_s, length, speed, speed_mps, "
                    "heading_deg, visit, point_count, confidence FROM tracks ORDER BY "
                    "ordinal"
                  : "SELECT ordinal, id, start_s, end_s, length, speed, speed_mps, "
                    "heading_deg, visit, point_count, NULL FROM tracks ORDER BY ordinal",
      "tracks", tracks, [&](sqlite::RowReader& row, ActivityTrack* t) {
        CheckOrdinal(row, 0, row.Int64(0), tracks->size());
        t->id = row.Int64(1);
        t->start_s = row.Real(2);
        t->end_s = row.Real(3);
        t->length = row.Real(4);
        t->speed = row.Real(5);
        t->speed_mps = row.OptionalReal(6);
        t->heading_deg = row.Real(7);
        t->visit = row.Int32(8);
        const int64_t count = row.Int(9, 0, std::numeric_limits<int64_t>::max());
        t->confidence = row.OptionalReal(10);
        if (t->confidence && !(*t->confidence >= 0 && *t->confidence <= 1)) {
          row.Fail(10, "confidence " + std::to_string(*t->confidence) + " is not in [0, 1]");
        }
        if (row.status().ok()) point_counts.push_back(count);
      }));
  const auto read_point = [&](sqlite::RowReader& row) -> Status {
    const int64_t track = row.Int64(0);
    const int64_t ordinal = row.Int64(1);
    SAKER_RETURN_IF_ERROR(row.status());
    if (track < 0 || track >= static_cast<int64_t>(tracks->size())) {
      row.Fail(0, "track_ordinal " + std::to_string(track) + " names no track");
      return row.status();
    }
    std::vector<TrackPoint>& points = (*tracks)[static_cast<size_t>(track)].points;
    CheckOrdinal(row, 1, ordinal, points.size());
    if (static_cast<int64_t>(points.size()) >= point_counts[static_cast<size_t>(track)]) {
      row.FailRow("more points than the track's point_count " +
                  std::to_string(point_counts[static_cast<size_t>(track)]));
    }
    TrackPoint p;
    p.frame = row.Int64(2);
    p.time_s = row.Real(3);
    p.image = Eigen::Vector2d(row.Real(4), row.Real(5));
    p.box_min = Eigen::Vector2d(row.Real(6), row.Real(7));
    p.box_max = Eigen::Vector2d(row.Real(8), row.Real(9));
    p.map = Eigen::Vector2d(row.Real(10), row.Real(11));
    p.interpolated = row.Bool(12);
    SAKER_RETURN_IF_ERROR(row.status());
    points.push_back(p);
    return Status::Ok();
  };
  // Points written before schema 8 were all seen.
  const std::string sql = std::string(
                              "SELECT track_ordinal, ordinal, frame, time_s, image_x, image_y, "
                              "box_min_x, box_min_y, box_max_x, box_max_y, map_x, map_y, ") +
                          (schema >= 8 ? "interpolated " : "0 ") +
                          "FROM track_points ORDER BY track_ordinal, ordinal";
  SAKER_RETURN_IF_ERROR(
      db.ForEachRow(sql.c_str(), "loading table track_points", "track_points", read_point));
  for (size_t i = 0; i < tracks->size(); ++i) {
    if (static_cast<int64_t>((*tracks)[i].points.size()) != point_counts[i]) {
      return InvalidDataError(db.path() + ": table track_points: track " + std::to_string(i) +
                              " has " + std::to_string((*tracks)[i].points.size()) +
                              " points, table tracks says " + std::to_string(point_counts[i]));
    }
  }
  return Status::Ok();
}

}  // namespace

std::string ReviewsProblem(const Mission& mission) {
  for (size_t i = 0; i < mission.reviews.size(); ++i) {
    const TrackReview& r = mission.reviews[i];
    const std::string which = "the review of track " + std::to_string(r.track_id);
    if (i > 0 && mission.reviews[i - 1].track_id >= r.track_id) {
      return which + " is out of order or repeated";
    }
    if (static_cast<int>(r.verdict) > 2 || static_cast<int>(r.label) > 3) {
      return which + " has an unknown verdict or label";
    }
    if (r.note.size() > kMaxNoteBytes) {
      return which + " has a note of " + std::to_string(r.note.size()) + " bytes, more than " +
             std::to_string(kMaxNoteBytes);
    }
  }
  for (size_t i = 0; i < mission.bookmarks.size(); ++i) {
    const Bookmark& k = mission.bookmarks[i];
    const std::string which = "bookmark " + std::to_string(k.id);
    if (k.id < 1 || (i > 0 && mission.bookmarks[i - 1].id >= k.id)) {
      return which + " is out of order, repeated or not positive";
    }
    if (!std::isfinite(k.time_s) || !k.map.allFinite()) {
      return which + " has a time or a place that is not a finite number";
    }
    if (k.note.size() > kMaxNoteBytes) {
      return which + " has a note of " + std::to_string(k.note.size()) + " bytes, more than " +
             std::to_string(kMaxNoteBytes);
    }
  }
  return {};
}

std::string HeaderProblem(const Mission& mission) {
  if (mission.map.geo_referenced != mission.map.origin.has_value()) {
    return mission.map.geo_referenced ? "the map is geo-referenced but has no origin"
                                      : "the map has an origin but is not geo-referenced";
  }
  if (mission.pyramid) {
    const PyramidInfo& p = *mission.pyramid;
    if (p.tile_size < 1 || p.tile_size > kMaxTileSize) {
      return "pyramid tile size " + std::to_string(p.tile_size) + " is outside [1, " +
             std::to_string(kMaxTileSize) + "]";
    }
    if (p.levels < 0 || p.levels > kMaxPyramidLevels) {
      return "pyramid levels " + std::to_string(p.levels) + " is outside [0, " +
             std::to_string(kMaxPyramidLevels) + "]";
    }
    if (p.width < 0 || p.height < 0) return "the pyramid size is negative";
  }
  if (const std::optional<FrontEndFindings>& f = mission.findings) {
    for (const double v :
         {f->noise_feature_px, f->noise_change_grey, f->noise_change_registration_px}) {
      if (!(std::isfinite(v) && v >= 0)) return "a noise threshold of the findings is not >= 0";
    }
  }
  return {};
}

std::string PartsProblem(const Mission& mission, unsigned parts) {
  if (parts & kSaveFrames) {
    const std::vector<FrameRecord>& frames = mission.frames;
    bool increasing = true;
    for (size_t i = 1; i < frames.size() && increasing; ++i) {
      increasing = frames[i - 1].index < frames[i].index;
    }
    if (!increasing) {
      std::vector<int64_t> indices;
      indices.reserve(frames.size());
      for (const FrameRecord& f : frames) indices.push_back(f.index);
      std::sort(indices.begin(), indices.end());
      const auto dup = std::adjacent_find(indices.begin(), indices.end());
      if (dup != indices.end()) return "frame index " + std::to_string(*dup) + " appears twice";
    }
  }
  if (parts & kSaveFrames) {
    for (const FrameRecord& f : mission.frames) {
      const std::string problem = f.sky_line ? f.sky_line->Problem() : "";
      if (!problem.empty()) return "frame " + std::to_string(f.index) + ": " + problem;
    }
    const std::string problem = OverlaysProblem(mission.overlays);
    if (!problem.empty()) return problem;
  }
  if (parts & kSaveReviews) {
    const std::string problem = ReviewsProblem(mission);
    if (!problem.empty()) return problem;
  }
  if (parts & kSaveGraph) {
    for (size_t i = 0; i < mission.links.size(); ++i) {
      if (!ValidLinkKind(mission.links[i].kind)) {
        return "link " + std::to_string(i) + " has an unknown kind " +
               std::to_string(static_cast<int>(mission.links[i].kind));
      }
    }
  }
  return {};
}

// The application_id is set when the file is built and checkpointed into the main file before it
// appears under its name, so it is always there.
Status CheckFileHeader(const std::string& path) {
  struct stat st;
  if (::stat(path.c_str(), &st) != 0) {
    const int err = errno;
    if (err == ENOENT || err == ENOTDIR) return NotFoundError(path + ": no such file");
    return IoError(path + ": " + std::strerror(err));
  }
  if (!S_ISREG(st.st_mode)) return InvalidDataError(path + ": not a regular file");
  if (st.st_size == 0) return InvalidDataError(path + ": empty file, not a Saker mission");
  SAKER_ASSIGN_OR_RETURN(const std::string header, ReadPrefix(path, 100));
  static const char kMagic[] = "SQLite format 3";  // with its terminating zero: 16 bytes
  if (header.size() < 100 || std::memcmp(header.data(), kMagic, sizeof(kMagic)) != 0) {
    return InvalidDataError(path + ": not a Saker mission (not an SQLite database)");
  }
  const uint32_t application_id = BigEndian32(header, 68);
  if (application_id != static_cast<uint32_t>(kMissionApplicationId)) {
    return InvalidDataError(path + ": an SQLite database but not a Saker mission (application_id " +
                            Hex32(application_id) + ")");
  }
  return Status::Ok();
}

StatusOr<int> CheckIdentity(const sqlite::Database& db) {
  SAKER_ASSIGN_OR_RETURN(const int64_t application_id,
                         db.QueryInt("PRAGMA application_id", "not a readable Saker mission"));
  if (application_id != kMissionApplicationId) {
    return InvalidDataError(db.path() +
                            ": an SQLite database but not a Saker mission (application_id " +
                            Hex32(static_cast<uint32_t>(application_id)) + ")");
  }
  SAKER_ASSIGN_OR_RETURN(const int64_t user_version,
                         db.QueryInt("PRAGMA user_version", "not a readable Saker mission"));

  std::set<std::string> tables;
  SAKER_RETURN_IF_ERROR(db.ForEachRow("SELECT name FROM sqlite_master WHERE type = 'table'",
                                      "reading the schema", "sqlite_master",
                                      [&](sqlite::RowReader& row) {
                                        if (row.Type(0) == SQLITE_TEXT) tables.insert(row.Text(0));
                                        return Status::Ok();
                                      }));
  if (tables.count("meta") == 0) {
    return InvalidDataError(db.path() + ": not a Saker mission (no table meta)");
  }
  SAKER_ASSIGN_OR_RETURN(const int schema, ReadSchemaVersion(db));
  const int64_t newest = std::max<int64_t>(schema, user_version);
  if (newest > kSchemaVersion) {
    return UnsupportedError(db.path() + ": written by a newer Saker: schema " +
                            std::to_string(newest) + ", this version reads up to " +
                            std::to_string(kSchemaVersion));
  }
  if (user_version != schema) {
    return InvalidDataError(db.path() + ": inconsistent schema version (user_version " +
                            std::to_string(user_version) + ", meta " + std::to_string(schema) +
                            ")");
  }
  for (const char* table : kTables) {
    if (tables.count(table) == 0) {
      return InvalidDataError(db.path() + ": not a Saker mission (no table " + table + ")");
    }
  }
  if (schema >= 3 && tables.count("checkpoint") == 0) {
    return InvalidDataError(db.path() + ": not a Saker mission (no table checkpoint)");
  }
  if (schema >= 5 && tables.count("overlays") == 0) {
    return InvalidDataError(db.path() + ": not a Saker mission (no table overlays)");
  }
  for (const char* table : {"track_reviews", "bookmarks"}) {
    if (schema >= 7 && tables.count(table) == 0) {
      return InvalidDataError(db.path() + ": not a Saker mission (no table " + table + ")");
    }
  }
  return schema;
}

Status Create(const sqlite::Database& db) {
  const std::string pragmas = "PRAGMA application_id = " + std::to_string(kMissionApplicationId) +
                              "; PRAGMA user_version = " + std::to_string(kSchemaVersion);
  sqlite::Transaction transaction(db);
  SAKER_RETURN_IF_ERROR(transaction.Begin(/*write=*/true));
  SAKER_RETURN_IF_ERROR(db.Exec(pragmas.c_str(), "setting the file identity"));
  SAKER_RETURN_IF_ERROR(db.Exec(kSchemaSql, "creating the schema"));
  SAKER_RETURN_IF_ERROR(db.Exec(kCheckpointSql, "creating the schema"));
  SAKER_RETURN_IF_ERROR(db.Exec(kOverlaysSql, "creating the schema"));
  SAKER_RETURN_IF_ERROR(db.Exec(kReviewsSql, "creating the schema"));
  return transaction.Commit();
}

// Version 1 -> 2: the frames' stream positions (NULL: unknown, as for any frame without them).
// Version 2 -> 3: the checkpoint table.
// Version 3 -> 4: the tracks' confidence. NULL (unknown): it needs the front end's evidence
// (features and change per observation), which older files did not keep.
// Version 4 -> 5: the overlay masks' table, empty (older files did not keep them).
// Version 5 -> 6: the frames' sky lines, NULL (no sky masked: older files did not keep them).
// Version 6 -> 7: the analyst's track reviews and bookmarks, empty.
// Version 7 -> 8: the track points' interpolated flag, 0 (every point of an older file was seen).
Status Upgrade(const sqlite::Database& db, int schema) {
  sqlite::Transaction transaction(db);
  SAKER_RETURN_IF_ERROR(transaction.Begin(/*write=*/true));
  if (schema < 2) {
    SAKER_RETURN_IF_ERROR(
        db.Exec("ALTER TABLE frames ADD COLUMN pts INTEGER; "
                "ALTER TABLE frames ADD COLUMN key_frame INTEGER",
                "upgrading the mission to schema 2"));
  }
  if (schema < 3) {
    SAKER_RETURN_IF_ERROR(db.Exec(kCheckpointSql, "upgrading the mission to schema 3"));
  }
  if (schema < 4) {
    SAKER_RETURN_IF_ERROR(
        db.Exec("ALTER TABLE tracks ADD COLUMN confidence REAL "
                "CHECK (confidence IS NULL OR (confidence >= 0 AND confidence <= 1))",
                "upgrading the mission to schema 4"));
  }
  if (schema < 5) {
    SAKER_RETURN_IF_ERROR(db.Exec(kOverlaysSql, "upgrading the mission to schema 5"));
  }
  if (schema < 6) {
    SAKER_RETURN_IF_ERROR(
        db.Exec("ALTER TABLE frames ADD COLUMN sky_y0 REAL; "
                "ALTER TABLE frames ADD COLUMN sky_slope REAL",
                "upgrading the mission to schema 6"));
  }
  if (schema < 7) {
    SAKER_RETURN_IF_ERROR(db.Exec(kReviewsSql, "upgrading the mission to schema 7"));
  }
  if (schema < 8) {
    SAKER_RETURN_IF_ERROR(
        db.Exec("ALTER TABLE track_points ADD COLUMN interpolated INTEGER NOT NULL DEFAULT 0 "
                "CHECK (interpolated IN (0, 1))",
                "upgrading the mission to schema 8"));
  }
  const std::string version = std::to_string(kSchemaVersion);
  const std::string sql = "UPDATE meta SET value = " + version + " WHERE key = '" +
                          kKeySchemaVersion + "'; PRAGMA user_version = " + version;
  SAKER_RETURN_IF_ERROR(db.Exec(sql.c_str(), "upgrading the mission's schema version"));
  return transaction.Commit();
}

Status Save(const sqlite::Database& db, const Mission& mission, unsigned parts) {
  sqlite::Transaction transaction(db);
  SAKER_RETURN_IF_ERROR(transaction.Begin(/*write=*/true));
  SAKER_RETURN_IF_ERROR(WriteHeader(db, mission));
  if (parts & kSaveFrames) {
    SAKER_RETURN_IF_ERROR(WriteFrames(db, mission.frames));
    SAKER_RETURN_IF_ERROR(WriteOverlays(db, mission.overlays));
  }
  if (parts & kSaveGraph) SAKER_RETURN_IF_ERROR(WriteGraph(db, mission));
  if (parts & kSaveTracks) SAKER_RETURN_IF_ERROR(WriteTracks(db, mission.tracks));
  if (parts & kSaveReviews) SAKER_RETURN_IF_ERROR(WriteReviews(db, mission));
  return transaction.Commit();
}

Status SaveReviews(const sqlite::Database& db, const Mission& mission) {
  sqlite::Transaction transaction(db);
  SAKER_RETURN_IF_ERROR(transaction.Begin(/*write=*/true));
  SAKER_RETURN_IF_ERROR(WriteReviews(db, mission));
  return transaction.Commit();
}

Status Load(const sqlite::Database& db, int schema, Mission* m) {
  // One read transaction: a concurrent Save is seen entirely or not at all.
  sqlite::Transaction transaction(db);
  SAKER_RETURN_IF_ERROR(transaction.Begin(/*write=*/false));
  SAKER_RETURN_IF_ERROR(LoadMeta(db, m));
  SAKER_RETURN_IF_ERROR(LoadSource(db, &m->source));
  SAKER_RETURN_IF_ERROR(LoadFrames(db, schema, &m->frames));
  if (schema >= 5) SAKER_RETURN_IF_ERROR(LoadOverlays(db, &m->overlays));
  SAKER_RETURN_IF_ERROR(LoadKeyFrames(db, &m->key_frames));
  SAKER_RETURN_IF_ERROR(LoadLinks(db, &m->links));
  SAKER_RETURN_IF_ERROR(LoadTracks(db, schema, &m->tracks));
  if (schema >= 7) {
    SAKER_RETURN_IF_ERROR(LoadReviews(db, &m->reviews));
    SAKER_RETURN_IF_ERROR(LoadBookmarks(db, &m->bookmarks));
  }
  return transaction.Commit();
}

}  // namespace saker::mission::schema
