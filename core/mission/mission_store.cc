#include "core/mission/mission_store.h"

#include "core/util/durable_file.h"

#include <fcntl.h>
#include <signal.h>
#include <sqlite3.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <initializer_list>
#include <limits>
#include <map>
#include <new>
#include <set>
#include <utility>

namespace saker::mission {
namespace {

// How long a connection waits for another one's lock (a writer's commit, a checkpoint) before it
// reports "database is locked".
constexpr int kBusyTimeoutMs = 5000;

// Blob sizes: little-endian float64, row-major.
constexpr int kMatrix3Values = 9;
constexpr int kCovarianceValues = 64;
constexpr int kCornerValues = 8;  // four (x, y) pairs

// Largest pyramid the file may describe (a level l is downsampled by 2^l).
constexpr int kMaxPyramidLevels = 32;
constexpr int kMaxTileSize = 1 << 16;

// Schema v3 (docs/mission-file.md): the tables of version 2 here, the checkpoint table (new in
// version 3) below. REAL columns are nullable on purpose: SQLite stores NaN as
// NULL.
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
  key_frame INTEGER
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
  point_count INTEGER NOT NULL
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

constexpr std::initializer_list<const char*> kOriginKeys = {kKeyOriginLatitude, kKeyOriginLongitude,
                                                            kKeyOriginHeight};
constexpr std::initializer_list<const char*> kPyramidKeys = {
    kKeyTileSize,   kKeyLevels,     kKeyWidth, kKeyHeight,
    kKeyMapOriginX, kKeyMapOriginY, kKeyStepX, kKeyStepY};

// ---------------------------------------------------------------------------------------------
// Little-endian float64 blobs.

void EncodeDoubles(const double* values, int n, uint8_t* out) {
  if constexpr (std::endian::native == std::endian::little) {
    std::memcpy(out, values, size_t(n) * 8);
  } else {
    for (int i = 0; i < n; ++i) {
      const uint64_t bits = std::bit_cast<uint64_t>(values[i]);
      for (int b = 0; b < 8; ++b) out[i * 8 + b] = uint8_t(bits >> (8 * b));
    }
  }
}

void DecodeDoubles(const uint8_t* in, int n, double* values) {
  if constexpr (std::endian::native == std::endian::little) {
    std::memcpy(values, in, size_t(n) * 8);
  } else {
    for (int i = 0; i < n; ++i) {
      uint64_t bits = 0;
      for (int b = 0; b < 8; ++b) bits |= uint64_t(in[i * 8 + b]) << (8 * b);
      values[i] = std::bit_cast<double>(bits);
    }
  }
}

template <typename Matrix>
void EncodeRowMajor(const Matrix& m, uint8_t* out) {
  double values[Matrix::RowsAtCompileTime * Matrix::ColsAtCompileTime];
  int k = 0;
  for (int r = 0; r < m.rows(); ++r) {
    for (int c = 0; c < m.cols(); ++c) values[k++] = m(r, c);
  }
  EncodeDoubles(values, k, out);
}

template <typename Matrix>
void DecodeRowMajor(const double* values, Matrix* m) {
  int k = 0;
  for (int r = 0; r < m->rows(); ++r) {
    for (int c = 0; c < m->cols(); ++c) (*m)(r, c) = values[k++];
  }
}

// ---------------------------------------------------------------------------------------------
// SQLite plumbing.

// The Status for a failed SQLite call: content problems are InvalidData, the rest IoError.
Status SqliteStatus(int rc, const std::string& message) {
  switch (rc & 0xff) {
    case SQLITE_CORRUPT:
    case SQLITE_NOTADB:
    case SQLITE_FORMAT:
    case SQLITE_ERROR:  // e.g. "no such table": the file does not have our schema
    case SQLITE_MISMATCH:
    case SQLITE_CONSTRAINT:
    case SQLITE_SCHEMA:
    case SQLITE_RANGE:
      return InvalidDataError(message);
    default:
      return IoError(message);
  }
}

Status SqliteError(sqlite3* db, int rc, const std::string& path, const std::string& what) {
  const char* detail = db != nullptr ? sqlite3_errmsg(db) : sqlite3_errstr(rc);
  std::string message = path + ": " + what + ": " + (detail ? detail : "unknown SQLite error");
  if ((rc & 0xff) == SQLITE_CORRUPT) message += " (the file is damaged or truncated)";
  return SqliteStatus(rc, message);
}

// Runs SQL that returns no rows.
Status ExecSql(sqlite3* db, const std::string& path, const char* sql, const std::string& what) {
  const int rc = sqlite3_exec(db, sql, nullptr, nullptr, nullptr);
  if (rc != SQLITE_OK) return SqliteError(db, rc, path, what);
  return Status::Ok();
}

// A transaction that rolls back unless committed.
class Transaction {
 public:
  Transaction(sqlite3* db, const std::string& path) : db_(db), path_(path) {}
  Transaction(const Transaction&) = delete;
  Transaction& operator=(const Transaction&) = delete;
  ~Transaction() {
    // ROLLBACK only fails when SQLite already rolled the transaction back after an error.
    if (active_) sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
  }

  // `write`: take the write lock now (BEGIN IMMEDIATE), waiting up to the busy timeout, so the
  // transaction never fails half-way for a lock.
  Status Begin(bool write) {
    SAKER_RETURN_IF_ERROR(
        ExecSql(db_, path_, write ? "BEGIN IMMEDIATE" : "BEGIN",
                write ? "starting a write transaction" : "starting a read transaction"));
    active_ = true;
    return Status::Ok();
  }
  Status Commit() {
    SAKER_RETURN_IF_ERROR(ExecSql(db_, path_, "COMMIT", "committing"));
    active_ = false;
    return Status::Ok();
  }

 private:
  sqlite3* db_;
  const std::string& path_;
  bool active_ = false;
};

struct DbCloser {
  // sqlite3_close_v2 defers the close until every statement is finalized; it only fails for a
  // null or already closed handle.
  void operator()(sqlite3* db) const { sqlite3_close_v2(db); }
};
using DbHandle = std::unique_ptr<sqlite3, DbCloser>;

// Owns a prepared statement.
class Statement {
 public:
  Statement() = default;
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;
  Statement(Statement&& other) noexcept : stmt_(std::exchange(other.stmt_, nullptr)) {}
  Statement& operator=(Statement&& other) noexcept {
    std::swap(stmt_, other.stmt_);
    return *this;
  }
  // sqlite3_finalize only repeats the last step's error, which was handled where it happened.
  ~Statement() { sqlite3_finalize(stmt_); }

  sqlite3_stmt* get() const { return stmt_; }
  sqlite3_stmt** out() { return &stmt_; }

 private:
  sqlite3_stmt* stmt_ = nullptr;
};

// Resets a statement when leaving a scope, so it never holds a read snapshot open.
class ResetOnExit {
 public:
  explicit ResetOnExit(sqlite3_stmt* stmt) : stmt_(stmt) {}
  ResetOnExit(const ResetOnExit&) = delete;
  ResetOnExit& operator=(const ResetOnExit&) = delete;
  // The result repeats the last step's, already handled.
  ~ResetOnExit() { sqlite3_reset(stmt_); }

 private:
  sqlite3_stmt* stmt_;
};

// Binds parameters, remembering the first failure so a whole row is bound before one check.
class Binder {
 public:
  explicit Binder(sqlite3_stmt* stmt) : stmt_(stmt) {}

  void Int64(int i, int64_t v) { Check(sqlite3_bind_int64(stmt_, i, v)); }
  void Double(int i, double v) { Check(sqlite3_bind_double(stmt_, i, v)); }  // NaN binds NULL
  void Null(int i) { Check(sqlite3_bind_null(stmt_, i)); }
  // The text is not copied: it must stay valid until the statement has been stepped (so no
  // temporaries; literals and the caller's strings are fine).
  void Text(int i, const std::string& s) {
    Check(sqlite3_bind_text64(stmt_, i, s.data(), s.size(), SQLITE_STATIC, SQLITE_UTF8));
  }
  void Text(int i, const char* s) {
    Check(sqlite3_bind_text64(stmt_, i, s, std::strlen(s), SQLITE_STATIC, SQLITE_UTF8));
  }
  void Text(int i, std::string&&) = delete;
  // `data` must stay valid until the statement has been stepped.
  void Blob(int i, const uint8_t* data, size_t size) {
    static const uint8_t kEmpty = 0;  // a null pointer would bind NULL, not an empty blob
    Check(sqlite3_bind_blob64(stmt_, i, size > 0 ? data : &kEmpty, size, SQLITE_STATIC));
  }
  void OptionalInt64(int i, const std::optional<int64_t>& v) { v ? Int64(i, *v) : Null(i); }
  void OptionalDouble(int i, const std::optional<double>& v) { v ? Double(i, *v) : Null(i); }

  int rc() const { return rc_; }

 private:
  void Check(int rc) {
    if (rc_ == SQLITE_OK) rc_ = rc;
  }

  sqlite3_stmt* stmt_;
  int rc_ = SQLITE_OK;
};

std::string ColumnName(sqlite3_stmt* stmt, int col) {
  const char* name = sqlite3_column_name(stmt, col);
  return name != nullptr ? name : "column " + std::to_string(col);
}

const char* TypeName(int type) {
  switch (type) {
    case SQLITE_INTEGER:
      return "an integer";
    case SQLITE_FLOAT:
      return "a real";
    case SQLITE_TEXT:
      return "text";
    case SQLITE_BLOB:
      return "a blob";
    case SQLITE_NULL:
      return "NULL";
  }
  return "an unknown type";
}

// Reads the columns of one result row with type and size checks, remembering the first problem
// (InvalidData naming the file, the table, the row and the column). Values read after a problem
// are defaults; check status() once per row.
class RowReader {
 public:
  RowReader(sqlite3_stmt* stmt, const std::string& path, const char* table)
      : stmt_(stmt), path_(path), table_(table) {}

  void NextRow() { ++row_; }
  int64_t row() const { return row_; }
  const Status& status() const { return status_; }

  bool IsNull(int col) { return sqlite3_column_type(stmt_, col) == SQLITE_NULL; }

  int64_t Int64(int col) {
    const int type = sqlite3_column_type(stmt_, col);
    if (type != SQLITE_INTEGER) {
      Fail(col, std::string("expected an integer, found ") + TypeName(type));
      return 0;
    }
    return sqlite3_column_int64(stmt_, col);
  }
  int64_t Int(int col, int64_t lo, int64_t hi) {
    const int64_t v = Int64(col);
    if (v < lo || v > hi) {
      Fail(col, std::to_string(v) + " is outside [" + std::to_string(lo) + ", " +
                    std::to_string(hi) + "]");
      return 0;
    }
    return v;
  }
  int32_t Int32(int col) {
    return int32_t(
        Int(col, std::numeric_limits<int32_t>::min(), std::numeric_limits<int32_t>::max()));
  }
  bool Bool(int col) { return Int(col, 0, 1) == 1; }
  std::optional<int64_t> OptionalInt64(int col) {
    if (IsNull(col)) return std::nullopt;
    return Int64(col);
  }
  // REAL (or an INTEGER a tool wrote); NULL is NaN, which SQLite cannot store.
  double Real(int col) {
    const int type = sqlite3_column_type(stmt_, col);
    if (type == SQLITE_NULL) return std::numeric_limits<double>::quiet_NaN();
    if (type != SQLITE_FLOAT && type != SQLITE_INTEGER) {
      Fail(col, std::string("expected a real number, found ") + TypeName(type));
      return 0;
    }
    return sqlite3_column_double(stmt_, col);
  }
  std::optional<double> OptionalReal(int col) {
    if (IsNull(col)) return std::nullopt;
    return Real(col);
  }
  std::string Text(int col) {
    const int type = sqlite3_column_type(stmt_, col);
    if (type != SQLITE_TEXT) {
      Fail(col, std::string("expected text, found ") + TypeName(type));
      return {};
    }
    const auto* text = reinterpret_cast<const char*>(sqlite3_column_text(stmt_, col));
    const int size = sqlite3_column_bytes(stmt_, col);
    if (text == nullptr) {
      Fail(col, "out of memory reading text");
      return {};
    }
    return std::string(text, size_t(size));
  }
  // A BLOB of exactly `n` float64.
  void Doubles(int col, int n, double* out) {
    std::fill(out, out + n, 0.0);
    const int type = sqlite3_column_type(stmt_, col);
    if (type != SQLITE_BLOB) {
      Fail(col, std::string("expected a blob of ") + std::to_string(n * 8) + " bytes, found " +
                    TypeName(type));
      return;
    }
    const void* data = sqlite3_column_blob(stmt_, col);
    const int size = sqlite3_column_bytes(stmt_, col);
    if (size != n * 8 || data == nullptr) {
      Fail(col, "blob of " + std::to_string(size) + " bytes, expected " + std::to_string(n * 8) +
                    " (" + std::to_string(n) + " float64)");
      return;
    }
    DecodeDoubles(static_cast<const uint8_t*>(data), n, out);
  }
  Eigen::Matrix3d Matrix3(int col) {
    double v[kMatrix3Values];
    Doubles(col, kMatrix3Values, v);
    Eigen::Matrix3d m;
    DecodeRowMajor(v, &m);
    return m;
  }
  Covariance8 Covariance(int col) {
    double v[kCovarianceValues];
    Doubles(col, kCovarianceValues, v);
    Covariance8 m;
    DecodeRowMajor(v, &m);
    return m;
  }

  void Fail(int col, const std::string& problem) {
    if (!status_.ok()) return;
    status_ = InvalidDataError(path_ + ": table " + table_ + ", row " + std::to_string(row_) +
                               ", column " + ColumnName(stmt_, col) + ": " + problem);
  }
  void FailRow(const std::string& problem) {
    if (!status_.ok()) return;
    status_ = InvalidDataError(path_ + ": table " + table_ + ", row " + std::to_string(row_) +
                               ": " + problem);
  }

 private:
  sqlite3_stmt* stmt_;
  const std::string& path_;
  const char* table_;
  int64_t row_ = 0;
  Status status_;
};

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
      Fail(std::string("key '") + key + "': expected an integer, found " + TypeName(v->type));
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
    return int(Int(key, std::numeric_limits<int32_t>::min(), std::numeric_limits<int32_t>::max()));
  }
  bool Bool(const char* key) { return Int(key, 0, 1) == 1; }
  double Real(const char* key) {
    const MetaValue* v = Find(key);
    if (v == nullptr) return 0;
    if (v->type == SQLITE_NULL) return std::numeric_limits<double>::quiet_NaN();
    if (v->type == SQLITE_INTEGER) return double(v->integer);
    if (v->type != SQLITE_FLOAT) {
      Fail(std::string("key '") + key + "': expected a real number, found " + TypeName(v->type));
      return 0;
    }
    return v->real;
  }
  std::string Text(const char* key) {
    const MetaValue* v = Find(key);
    if (v == nullptr) return {};
    if (v->type != SQLITE_TEXT) {
      Fail(std::string("key '") + key + "': expected text, found " + TypeName(v->type));
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

std::optional<LinkKind> LinkKindFromName(const std::string& name) {
  for (LinkKind kind : {LinkKind::kSequential, LinkKind::kGeometric, LinkKind::kAppearance}) {
    if (name == LinkKindName(kind)) return kind;
  }
  return std::nullopt;
}

bool ValidLinkKind(LinkKind kind) {
  return kind == LinkKind::kSequential || kind == LinkKind::kGeometric ||
         kind == LinkKind::kAppearance;
}

// Why the header of `mission` breaks a rule of the file (empty when it does not). Save refuses
// such a mission and Load such a file, so the store never writes what it would not read.
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
  return {};
}

// Why the parts of `mission` named by `parts` cannot be saved (empty when they can).
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
  if (parts & kSaveGraph) {
    for (size_t i = 0; i < mission.links.size(); ++i) {
      if (!ValidLinkKind(mission.links[i].kind)) {
        return "link " + std::to_string(i) + " has an unknown kind " +
               std::to_string(int(mission.links[i].kind));
      }
    }
  }
  return {};
}

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
    const ssize_t r = ::pread(fd, bytes.data() + got, n - got, off_t(got));
    if (r < 0 && errno == EINTR) continue;
    if (r < 0) {
      const int err = errno;
      ::close(fd);
      return IoError(path + ": cannot read: " + std::strerror(err));
    }
    if (r == 0) break;
    got += size_t(r);
  }
  ::close(fd);
  bytes.resize(got);
  return bytes;
}

uint32_t BigEndian32(const std::string& bytes, size_t offset) {
  return uint32_t(uint8_t(bytes[offset])) << 24 | uint32_t(uint8_t(bytes[offset + 1])) << 16 |
         uint32_t(uint8_t(bytes[offset + 2])) << 8 | uint32_t(uint8_t(bytes[offset + 3]));
}

std::string Hex32(uint32_t v) {
  char buffer[16];
  std::snprintf(buffer, sizeof(buffer), "0x%08" PRIX32, v);
  return buffer;
}

// Checks the file's first bytes before SQLite touches it, so a foreign file never gets WAL side
// files and the messages say what the file is. The application_id is set when the file is built
// and checkpointed into the main file before it appears under its name, so it is always there.
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
  if (application_id != uint32_t(kMissionApplicationId)) {
    return InvalidDataError(path + ": an SQLite database but not a Saker mission (application_id " +
                            Hex32(application_id) + ")");
  }
  return Status::Ok();
}

// The files SQLite may keep beside a database.
const std::vector<std::string> kDatabaseSideSuffixes = {"-wal", "-shm", "-journal"};

}  // namespace

// ---------------------------------------------------------------------------------------------

struct MissionStore::Impl {
  std::string path;
  OpenMode mode = OpenMode::kReadOnly;
  mutable int schema = kSchemaVersion;  // of the file, once CheckIdentity has read it
  DbHandle db;                          // destroyed last: after the statements below
  Statement read_tile;                  // cached: tiles are read one by one while the map is panned
  Statement count_tiles;

  Status Error(int rc, const std::string& what) const {
    return SqliteError(db.get(), rc, path, what);
  }

  Status Exec(const char* sql, const std::string& what) {
    return ExecSql(db.get(), path, sql, what);
  }

  StatusOr<Statement> Prepare(const char* sql, const std::string& what, unsigned flags = 0) const {
    Statement stmt;
    const int rc = sqlite3_prepare_v3(db.get(), sql, -1, flags, stmt.out(), nullptr);
    if (rc != SQLITE_OK) return Error(rc, what);
    if (stmt.get() == nullptr) return Error(SQLITE_ERROR, what + ": empty statement");
    return stmt;
  }

  // Steps a statement that returns no row, after checking its bindings, and resets it.
  Status Run(sqlite3_stmt* stmt, const Binder& binder, const std::string& what) {
    ResetOnExit reset(stmt);
    if (binder.rc() != SQLITE_OK) return Error(binder.rc(), what);
    const int rc = sqlite3_step(stmt);
    if (rc != SQLITE_DONE && rc != SQLITE_ROW) return Error(rc, what);
    return Status::Ok();
  }

  // A one-row, one-integer query such as a pragma.
  StatusOr<int64_t> QueryInt(const char* sql, const std::string& what) const {
    SAKER_ASSIGN_OR_RETURN(Statement stmt, Prepare(sql, what));
    const int rc = sqlite3_step(stmt.get());
    if (rc != SQLITE_ROW) {
      if (rc == SQLITE_DONE) return InvalidDataError(path + ": " + what + ": no result");
      return Error(rc, what);
    }
    if (sqlite3_column_type(stmt.get(), 0) != SQLITE_INTEGER) {
      return InvalidDataError(path + ": " + what + ": not an integer");
    }
    return int64_t(sqlite3_column_int64(stmt.get(), 0));
  }

  StatusOr<std::string> QueryText(const char* sql, const std::string& what) const {
    SAKER_ASSIGN_OR_RETURN(Statement stmt, Prepare(sql, what));
    const int rc = sqlite3_step(stmt.get());
    if (rc != SQLITE_ROW) {
      if (rc == SQLITE_DONE) return InvalidDataError(path + ": " + what + ": no result");
      return Error(rc, what);
    }
    const auto* text = reinterpret_cast<const char*>(sqlite3_column_text(stmt.get(), 0));
    return std::string(text != nullptr ? text : "");
  }

  Status OpenConnection(int flags);
  Status CheckIdentity() const;
  StatusOr<int> ReadSchemaVersion() const;
  Status SetWriteOptions();
  Status Upgrade();  // to kSchemaVersion, in one transaction
  Status SaveInTransaction(const Mission& mission, unsigned parts);
  Status WriteHeader(const Mission& mission);
  Status WriteFrames(const std::vector<FrameRecord>& frames);
  Status WriteGraph(const Mission& mission);
  Status WriteTracks(const std::vector<ActivityTrack>& tracks);
  Status LoadInTransaction(Mission* mission);
  Status LoadMeta(Mission* mission) const;
  Status LoadSource(SourceVideo* source) const;
  Status LoadFrames(std::vector<FrameRecord>* frames) const;
  Status LoadKeyFrames(std::vector<KeyFrameRecord>* key_frames) const;
  Status LoadLinks(std::vector<LinkRecord>* links) const;
  Status LoadTracks(std::vector<ActivityTrack>* tracks) const;
  Status Checkpoint();
};

Status MissionStore::Impl::OpenConnection(int flags) {
  sqlite3* raw = nullptr;
  const int rc = sqlite3_open_v2(path.c_str(), &raw, flags, nullptr);
  db.reset(raw);  // closed on every path, even when the open failed
  if (rc != SQLITE_OK) {
    return SqliteError(raw, rc, path, "cannot open");
  }
  int status = sqlite3_extended_result_codes(db.get(), 0);
  if (status == SQLITE_OK) status = sqlite3_busy_timeout(db.get(), kBusyTimeoutMs);
  // A hostile file must not reach beyond its own content: no writes to SQLite's internal
  // structures, and no functions with side effects in its views or triggers.
  if (status == SQLITE_OK) {
    status = sqlite3_db_config(db.get(), SQLITE_DBCONFIG_DEFENSIVE, 1, nullptr);
  }
#ifdef SQLITE_DBCONFIG_TRUSTED_SCHEMA
  if (status == SQLITE_OK) {
    status = sqlite3_db_config(db.get(), SQLITE_DBCONFIG_TRUSTED_SCHEMA, 0, nullptr);
  }
#endif
  if (status != SQLITE_OK) return Error(status, "configuring the connection");
  return Exec("PRAGMA cell_size_check = ON", "configuring the connection");
}

StatusOr<int> MissionStore::Impl::ReadSchemaVersion() const {
  SAKER_ASSIGN_OR_RETURN(
      Statement stmt,
      Prepare("SELECT value FROM meta WHERE key = 'schema_version'", "reading the schema version"));
  ResetOnExit reset(stmt.get());
  const int rc = sqlite3_step(stmt.get());
  if (rc == SQLITE_DONE) {
    return InvalidDataError(path + ": not a Saker mission (table meta has no schema_version)");
  }
  if (rc != SQLITE_ROW) return Error(rc, "reading the schema version");
  if (sqlite3_column_type(stmt.get(), 0) != SQLITE_INTEGER) {
    return InvalidDataError(path + ": table meta: schema_version is not an integer");
  }
  const int64_t version = sqlite3_column_int64(stmt.get(), 0);
  if (version < 1 || version > std::numeric_limits<int32_t>::max()) {
    return InvalidDataError(path + ": table meta: schema_version " + std::to_string(version) +
                            " is not a valid version");
  }
  return int(version);
}

// Whether the open database is a Saker mission this build reads. Reads only.
Status MissionStore::Impl::CheckIdentity() const {
  SAKER_ASSIGN_OR_RETURN(const int64_t application_id,
                         QueryInt("PRAGMA application_id", "not a readable Saker mission"));
  if (application_id != kMissionApplicationId) {
    return InvalidDataError(path + ": an SQLite database but not a Saker mission (application_id " +
                            Hex32(uint32_t(application_id)) + ")");
  }
  SAKER_ASSIGN_OR_RETURN(const int64_t user_version,
                         QueryInt("PRAGMA user_version", "not a readable Saker mission"));

  std::set<std::string> tables;
  {
    SAKER_ASSIGN_OR_RETURN(
        Statement stmt,
        Prepare("SELECT name FROM sqlite_master WHERE type = 'table'", "reading the schema"));
    int rc;
    while ((rc = sqlite3_step(stmt.get())) == SQLITE_ROW) {
      const auto* name = reinterpret_cast<const char*>(sqlite3_column_text(stmt.get(), 0));
      if (name != nullptr) tables.insert(name);
    }
    if (rc != SQLITE_DONE) return Error(rc, "reading the schema");
  }
  if (tables.count("meta") == 0) {
    return InvalidDataError(path + ": not a Saker mission (no table meta)");
  }
  SAKER_ASSIGN_OR_RETURN(const int schema_version, ReadSchemaVersion());
  const int64_t newest = std::max<int64_t>(schema_version, user_version);
  if (newest > kSchemaVersion) {
    return UnsupportedError(path + ": written by a newer Saker: schema " + std::to_string(newest) +
                            ", this version reads up to " + std::to_string(kSchemaVersion));
  }
  schema = schema_version;
  if (user_version != schema_version) {
    return InvalidDataError(path + ": inconsistent schema version (user_version " +
                            std::to_string(user_version) + ", meta " +
                            std::to_string(schema_version) + ")");
  }
  for (const char* table : kTables) {
    if (tables.count(table) == 0) {
      return InvalidDataError(path + ": not a Saker mission (no table " + table + ")");
    }
  }
  if (schema >= 3 && tables.count("checkpoint") == 0) {
    return InvalidDataError(path + ": not a Saker mission (no table checkpoint)");
  }
  return Status::Ok();
}

Status MissionStore::Impl::SetWriteOptions() {
  SAKER_ASSIGN_OR_RETURN(const std::string journal,
                         QueryText("PRAGMA journal_mode = WAL", "switching to WAL"));
  if (journal != "wal") {
    return IoError(path + ": cannot use a write-ahead log here (journal mode stays " + journal +
                   "); is the file on a network file system?");
  }
  // In WAL mode NORMAL loses at most the last commits on power loss, never consistency; a killed
  // process loses nothing that was committed.
  SAKER_RETURN_IF_ERROR(Exec("PRAGMA synchronous = NORMAL", "setting synchronous"));
  // The schema declares track_points -> tracks for other tools; Save writes both tables in one
  // transaction and Load checks the relation, so enforcing it per row (a third slower track
  // save) buys nothing here.
  return Exec("PRAGMA foreign_keys = OFF", "configuring foreign keys");
}

// Version 1 -> 2: the frames' stream positions (NULL: unknown, as for any frame without them).
Status MissionStore::Impl::Upgrade() {
  Transaction transaction(db.get(), path);
  SAKER_RETURN_IF_ERROR(transaction.Begin(/*write=*/true));
  if (schema < 2) {
    SAKER_RETURN_IF_ERROR(
        Exec("ALTER TABLE frames ADD COLUMN pts INTEGER; "
             "ALTER TABLE frames ADD COLUMN key_frame INTEGER",
             "upgrading the mission to schema 2"));
  }
  if (schema < 3) SAKER_RETURN_IF_ERROR(Exec(kCheckpointSql, "upgrading the mission to schema 3"));
  const std::string version = std::to_string(kSchemaVersion);
  const std::string sql = "UPDATE meta SET value = " + version + " WHERE key = '" +
                          kKeySchemaVersion + "'; PRAGMA user_version = " + version;
  SAKER_RETURN_IF_ERROR(Exec(sql.c_str(), "upgrading the mission's schema version"));
  SAKER_RETURN_IF_ERROR(transaction.Commit());
  schema = kSchemaVersion;
  return Status::Ok();
}

Status MissionStore::Impl::Checkpoint() {
  SAKER_ASSIGN_OR_RETURN(Statement stmt,
                         Prepare("PRAGMA wal_checkpoint(TRUNCATE)", "checkpointing"));
  const int rc = sqlite3_step(stmt.get());
  if (rc != SQLITE_ROW) return Error(rc, "checkpointing");
  if (sqlite3_column_int(stmt.get(), 0) != 0) {
    return IoError(path + ": the mission is in use by another program (checkpoint blocked)");
  }
  return Status::Ok();
}

// ---------------------------------------------------------------------------------------------
// Save.

Status MissionStore::Impl::WriteHeader(const Mission& m) {
  SAKER_RETURN_IF_ERROR(Exec("DELETE FROM meta", "saving table meta"));
  SAKER_ASSIGN_OR_RETURN(Statement stmt, Prepare("INSERT INTO meta (key, value) VALUES (?1, ?2)",
                                                 "saving table meta"));
  auto put_int = [&](const char* key, int64_t value) {
    Binder b(stmt.get());
    b.Text(1, key);
    b.Int64(2, value);
    return Run(stmt.get(), b, "saving table meta");
  };
  auto put_real = [&](const char* key, double value) {
    Binder b(stmt.get());
    b.Text(1, key);
    b.Double(2, value);
    return Run(stmt.get(), b, "saving table meta");
  };
  auto put_text = [&](const char* key, const std::string& value) {
    Binder b(stmt.get());
    b.Text(1, key);
    b.Text(2, value);
    return Run(stmt.get(), b, "saving table meta");
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
  SAKER_RETURN_IF_ERROR(put_int(kKeyFrontEnd, m.progress.front_end));
  SAKER_RETURN_IF_ERROR(put_int(kKeyMosaic, m.progress.mosaic));
  SAKER_RETURN_IF_ERROR(put_int(kKeyActivity, m.progress.activity));
  SAKER_RETURN_IF_ERROR(put_int(kKeyTiles, m.progress.tiles));
  SAKER_RETURN_IF_ERROR(put_int(kKeyCancelled, m.progress.cancelled));

  SAKER_RETURN_IF_ERROR(Exec("DELETE FROM source", "saving table source"));
  SAKER_ASSIGN_OR_RETURN(
      Statement source,
      Prepare("INSERT INTO source (id, path, fingerprint, size_bytes, width, height, frame_rate, "
              "frame_count, duration_s) VALUES (1, ?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8)",
              "saving table source"));
  const SourceVideo& s = m.source;
  Binder b(source.get());
  b.Text(1, s.path);
  b.Text(2, s.fingerprint);
  b.Int64(3, s.size_bytes);
  b.Int64(4, s.width);
  b.Int64(5, s.height);
  b.Double(6, s.frame_rate);
  b.Int64(7, s.frame_count);
  b.Double(8, s.duration_s);
  return Run(source.get(), b, "saving table source");
}

Status MissionStore::Impl::WriteFrames(const std::vector<FrameRecord>& frames) {
  SAKER_RETURN_IF_ERROR(Exec("DELETE FROM frames", "saving table frames"));
  SAKER_ASSIGN_OR_RETURN(
      Statement stmt,
      Prepare("INSERT INTO frames (frame_index, time_s, utc_us, map_from_frame, metadata_corners, "
              "sensor_latitude_deg, sensor_longitude_deg, sensor_height_m, pts, key_frame) "
              "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10)",
              "saving table frames"));
  uint8_t matrix[kMatrix3Values * 8];
  uint8_t corners[kCornerValues * 8];
  for (const FrameRecord& f : frames) {
    Binder b(stmt.get());
    b.Int64(1, f.index);
    b.Double(2, f.time_s);
    b.OptionalInt64(3, f.utc_us);
    if (f.map_from_frame) {
      EncodeRowMajor(*f.map_from_frame, matrix);
      b.Blob(4, matrix, sizeof(matrix));
    } else {
      b.Null(4);
    }
    if (f.metadata_corners) {
      double values[kCornerValues];
      for (int i = 0; i < 4; ++i) {
        values[2 * i] = (*f.metadata_corners)[size_t(i)].x();
        values[2 * i + 1] = (*f.metadata_corners)[size_t(i)].y();
      }
      EncodeDoubles(values, kCornerValues, corners);
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
    SAKER_RETURN_IF_ERROR(Run(stmt.get(), b, "saving table frames"));
  }
  return Status::Ok();
}

Status MissionStore::Impl::WriteGraph(const Mission& m) {
  SAKER_RETURN_IF_ERROR(Exec("DELETE FROM links", "saving table links"));
  SAKER_RETURN_IF_ERROR(Exec("DELETE FROM key_frames", "saving table key_frames"));
  uint8_t matrix[kMatrix3Values * 8];
  uint8_t covariance[kCovarianceValues * 8];
  {
    SAKER_ASSIGN_OR_RETURN(
        Statement stmt,
        Prepare("INSERT INTO key_frames (ordinal, id, frame_index, segment, map_from_frame, "
                "covariance, node) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7)",
                "saving table key_frames"));
    for (size_t i = 0; i < m.key_frames.size(); ++i) {
      const KeyFrameRecord& k = m.key_frames[i];
      EncodeRowMajor(k.map_from_frame, matrix);
      EncodeRowMajor(k.covariance, covariance);
      Binder b(stmt.get());
      b.Int64(1, int64_t(i));
      b.Int64(2, k.id);
      b.Int64(3, k.frame_index);
      b.Int64(4, k.segment);
      b.Blob(5, matrix, sizeof(matrix));
      b.Blob(6, covariance, sizeof(covariance));
      b.Int64(7, k.node ? 1 : 0);
      SAKER_RETURN_IF_ERROR(Run(stmt.get(), b, "saving table key_frames"));
    }
  }
  SAKER_ASSIGN_OR_RETURN(
      Statement stmt,
      Prepare("INSERT INTO links (ordinal, from_id, to_id, kind, to_from_from, covariance, "
              "correspondences) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7)",
              "saving table links"));
  for (size_t i = 0; i < m.links.size(); ++i) {
    const LinkRecord& l = m.links[i];
    EncodeRowMajor(l.to_from_from, matrix);
    EncodeRowMajor(l.covariance, covariance);
    Binder b(stmt.get());
    b.Int64(1, int64_t(i));
    b.Int64(2, l.from);
    b.Int64(3, l.to);
    b.Text(4, LinkKindName(l.kind));
    b.Blob(5, matrix, sizeof(matrix));
    b.Blob(6, covariance, sizeof(covariance));
    b.Int64(7, l.correspondences);
    SAKER_RETURN_IF_ERROR(Run(stmt.get(), b, "saving table links"));
  }
  return Status::Ok();
}

Status MissionStore::Impl::WriteTracks(const std::vector<ActivityTrack>& tracks) {
  // Points first: they refer to their track.
  SAKER_RETURN_IF_ERROR(Exec("DELETE FROM track_points", "saving table track_points"));
  SAKER_RETURN_IF_ERROR(Exec("DELETE FROM tracks", "saving table tracks"));
  SAKER_ASSIGN_OR_RETURN(
      Statement track_stmt,
      Prepare("INSERT INTO tracks (ordinal, id, start_s, end_s, length, speed, speed_mps, "
              "heading_deg, visit, point_count) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10)",
              "saving table tracks"));
  SAKER_ASSIGN_OR_RETURN(
      Statement point_stmt,
      Prepare("INSERT INTO track_points (track_ordinal, ordinal, frame, time_s, image_x, image_y, "
              "box_min_x, box_min_y, box_max_x, box_max_y, map_x, map_y) "
              "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12)",
              "saving table track_points"));
  for (size_t i = 0; i < tracks.size(); ++i) {
    const ActivityTrack& t = tracks[i];
    Binder b(track_stmt.get());
    b.Int64(1, int64_t(i));
    b.Int64(2, t.id);
    b.Double(3, t.start_s);
    b.Double(4, t.end_s);
    b.Double(5, t.length);
    b.Double(6, t.speed);
    b.OptionalDouble(7, t.speed_mps);
    b.Double(8, t.heading_deg);
    b.Int64(9, t.visit);
    b.Int64(10, int64_t(t.points.size()));
    SAKER_RETURN_IF_ERROR(Run(track_stmt.get(), b, "saving table tracks"));
    for (size_t j = 0; j < t.points.size(); ++j) {
      const TrackPoint& p = t.points[j];
      Binder pb(point_stmt.get());
      pb.Int64(1, int64_t(i));
      pb.Int64(2, int64_t(j));
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
      SAKER_RETURN_IF_ERROR(Run(point_stmt.get(), pb, "saving table track_points"));
    }
  }
  return Status::Ok();
}

Status MissionStore::Impl::SaveInTransaction(const Mission& mission, unsigned parts) {
  Transaction transaction(db.get(), path);
  SAKER_RETURN_IF_ERROR(transaction.Begin(/*write=*/true));
  SAKER_RETURN_IF_ERROR(WriteHeader(mission));
  if (parts & kSaveFrames) SAKER_RETURN_IF_ERROR(WriteFrames(mission.frames));
  if (parts & kSaveGraph) SAKER_RETURN_IF_ERROR(WriteGraph(mission));
  if (parts & kSaveTracks) SAKER_RETURN_IF_ERROR(WriteTracks(mission.tracks));
  return transaction.Commit();
}

// ---------------------------------------------------------------------------------------------
// Load.

Status MissionStore::Impl::LoadMeta(Mission* m) const {
  std::map<std::string, MetaValue> values;
  {
    SAKER_ASSIGN_OR_RETURN(Statement stmt,
                           Prepare("SELECT key, value FROM meta", "loading table meta"));
    RowReader row(stmt.get(), path, "meta");
    int rc;
    while ((rc = sqlite3_step(stmt.get())) == SQLITE_ROW) {
      row.NextRow();
      std::string key = row.Text(0);
      SAKER_RETURN_IF_ERROR(row.status());
      MetaValue v;
      v.type = sqlite3_column_type(stmt.get(), 1);
      if (v.type == SQLITE_INTEGER) v.integer = sqlite3_column_int64(stmt.get(), 1);
      if (v.type == SQLITE_FLOAT) v.real = sqlite3_column_double(stmt.get(), 1);
      if (v.type == SQLITE_TEXT) v.text = row.Text(1);
      SAKER_RETURN_IF_ERROR(row.status());
      if (!values.emplace(key, std::move(v)).second) {
        return InvalidDataError(path + ": table meta: key '" + key + "' appears twice");
      }
    }
    if (rc != SQLITE_DONE) return Error(rc, "loading table meta");
  }
  MetaReader meta(values, path);
  const int64_t version = meta.Int(kKeySchemaVersion, 1, std::numeric_limits<int32_t>::max());
  SAKER_RETURN_IF_ERROR(meta.status());
  if (version > kSchemaVersion) {
    return UnsupportedError(path + ": written by a newer Saker: schema " + std::to_string(version) +
                            ", this version reads up to " + std::to_string(kSchemaVersion));
  }
  m->schema_version = int(version);
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
  m->progress.front_end = meta.Bool(kKeyFrontEnd);
  m->progress.mosaic = meta.Bool(kKeyMosaic);
  m->progress.activity = meta.Bool(kKeyActivity);
  m->progress.tiles = meta.Bool(kKeyTiles);
  m->progress.cancelled = meta.Bool(kKeyCancelled);
  SAKER_RETURN_IF_ERROR(meta.status());
  const std::string problem = HeaderProblem(*m);
  if (!problem.empty()) return InvalidDataError(path + ": table meta: " + problem);
  return Status::Ok();
}

Status MissionStore::Impl::LoadSource(SourceVideo* s) const {
  SAKER_ASSIGN_OR_RETURN(
      Statement stmt,
      Prepare("SELECT id, path, fingerprint, size_bytes, width, height, frame_rate, frame_count, "
              "duration_s FROM source",
              "loading table source"));
  RowReader row(stmt.get(), path, "source");
  int rc;
  while ((rc = sqlite3_step(stmt.get())) == SQLITE_ROW) {
    row.NextRow();
    if (row.row() > 1) return InvalidDataError(path + ": table source: more than one row");
    row.Int(0, 1, 1);
    s->path = row.Text(1);
    s->fingerprint = row.Text(2);
    s->size_bytes = row.Int64(3);
    s->width = row.Int32(4);
    s->height = row.Int32(5);
    s->frame_rate = row.Real(6);
    s->frame_count = row.Int64(7);
    s->duration_s = row.Real(8);
    SAKER_RETURN_IF_ERROR(row.status());
  }
  if (rc != SQLITE_DONE) return Error(rc, "loading table source");
  if (row.row() == 0) return InvalidDataError(path + ": table source: no row");
  return Status::Ok();
}

Status MissionStore::Impl::LoadFrames(std::vector<FrameRecord>* frames) const {
  SAKER_ASSIGN_OR_RETURN(
      Statement stmt,
      Prepare(schema >= 2
                  ? "SELECT frame_index, time_s, utc_us, map_from_frame, metadata_corners, "
                    "sensor_latitude_deg, sensor_longitude_deg, sensor_height_m, pts, key_frame "
                    "FROM frames ORDER BY frame_index"
                  : "SELECT frame_index, time_s, utc_us, map_from_frame, metadata_corners, "
                    "sensor_latitude_deg, sensor_longitude_deg, sensor_height_m, NULL, NULL "
                    "FROM frames ORDER BY frame_index",
              "loading table frames"));
  RowReader row(stmt.get(), path, "frames");
  int rc;
  while ((rc = sqlite3_step(stmt.get())) == SQLITE_ROW) {
    row.NextRow();
    FrameRecord f;
    f.index = row.Int64(0);
    if (!frames->empty() && f.index <= frames->back().index) {
      row.Fail(0, "frame index " + std::to_string(f.index) + " appears twice");
    }
    f.time_s = row.Real(1);
    f.utc_us = row.OptionalInt64(2);
    if (!row.IsNull(3)) f.map_from_frame = row.Matrix3(3);
    if (!row.IsNull(4)) {
      double values[kCornerValues];
      row.Doubles(4, kCornerValues, values);
      std::array<Eigen::Vector2d, 4> corners;
      for (int i = 0; i < 4; ++i) {
        corners[size_t(i)] = Eigen::Vector2d(values[2 * i], values[2 * i + 1]);
      }
      f.metadata_corners = corners;
    }
    // The sensor is absent when all three columns are NULL; a single NULL is a NaN.
    if (!row.IsNull(5) || !row.IsNull(6) || !row.IsNull(7)) {
      f.sensor = geo::Wgs84{row.Real(5), row.Real(6), row.Real(7)};
    }
    f.pts = row.OptionalInt64(8);
    if (f.pts) f.key_frame = row.Bool(9);
    SAKER_RETURN_IF_ERROR(row.status());
    frames->push_back(std::move(f));
  }
  if (rc != SQLITE_DONE) return Error(rc, "loading table frames");
  return Status::Ok();
}

Status MissionStore::Impl::LoadKeyFrames(std::vector<KeyFrameRecord>* key_frames) const {
  SAKER_ASSIGN_OR_RETURN(
      Statement stmt,
      Prepare("SELECT ordinal, id, frame_index, segment, map_from_frame, covariance, node "
              "FROM key_frames ORDER BY ordinal",
              "loading table key_frames"));
  RowReader row(stmt.get(), path, "key_frames");
  int rc;
  while ((rc = sqlite3_step(stmt.get())) == SQLITE_ROW) {
    row.NextRow();
    const int64_t ordinal = row.Int64(0);
    if (ordinal != int64_t(key_frames->size())) {
      row.Fail(0, "ordinal " + std::to_string(ordinal) + " where " +
                      std::to_string(key_frames->size()) + " was expected (a row is missing)");
    }
    KeyFrameRecord k;
    k.id = row.Int32(1);
    k.frame_index = row.Int64(2);
    k.segment = row.Int32(3);
    k.map_from_frame = row.Matrix3(4);
    k.covariance = row.Covariance(5);
    k.node = row.Bool(6);
    SAKER_RETURN_IF_ERROR(row.status());
    key_frames->push_back(k);
  }
  if (rc != SQLITE_DONE) return Error(rc, "loading table key_frames");
  return Status::Ok();
}

Status MissionStore::Impl::LoadLinks(std::vector<LinkRecord>* links) const {
  SAKER_ASSIGN_OR_RETURN(
      Statement stmt,
      Prepare("SELECT ordinal, from_id, to_id, kind, to_from_from, covariance, correspondences "
              "FROM links ORDER BY ordinal",
              "loading table links"));
  RowReader row(stmt.get(), path, "links");
  int rc;
  while ((rc = sqlite3_step(stmt.get())) == SQLITE_ROW) {
    row.NextRow();
    const int64_t ordinal = row.Int64(0);
    if (ordinal != int64_t(links->size())) {
      row.Fail(0, "ordinal " + std::to_string(ordinal) + " where " + std::to_string(links->size()) +
                      " was expected (a row is missing)");
    }
    LinkRecord l;
    l.from = row.Int32(1);
    l.to = row.Int32(2);
    const std::string kind = row.Text(3);
    if (row.status().ok()) {
      const std::optional<LinkKind> parsed = LinkKindFromName(kind);
      if (parsed) {
        l.kind = *parsed;
      } else {
        row.Fail(3, "unknown link kind '" + kind + "'");
      }
    }
    l.to_from_from = row.Matrix3(4);
    l.covariance = row.Covariance(5);
    l.correspondences = row.Int32(6);
    SAKER_RETURN_IF_ERROR(row.status());
    links->push_back(l);
  }
  if (rc != SQLITE_DONE) return Error(rc, "loading table links");
  return Status::Ok();
}

Status MissionStore::Impl::LoadTracks(std::vector<ActivityTrack>* tracks) const {
  std::vector<int64_t> point_counts;
  {
    SAKER_ASSIGN_OR_RETURN(
        Statement stmt,
        Prepare("SELECT ordinal, id, start_s, end_s, length, speed, speed_mps, heading_deg, "
                "visit, point_count FROM tracks ORDER BY ordinal",
                "loading table tracks"));
    RowReader row(stmt.get(), path, "tracks");
    int rc;
    while ((rc = sqlite3_step(stmt.get())) == SQLITE_ROW) {
      row.NextRow();
      const int64_t ordinal = row.Int64(0);
      if (ordinal != int64_t(tracks->size())) {
        row.Fail(0, "ordinal " + std::to_string(ordinal) + " where " +
                        std::to_string(tracks->size()) + " was expected (a row is missing)");
      }
      ActivityTrack t;
      t.id = row.Int64(1);
      t.start_s = row.Real(2);
      t.end_s = row.Real(3);
      t.length = row.Real(4);
      t.speed = row.Real(5);
      t.speed_mps = row.OptionalReal(6);
      t.heading_deg = row.Real(7);
      t.visit = row.Int32(8);
      const int64_t count = row.Int(9, 0, std::numeric_limits<int64_t>::max());
      SAKER_RETURN_IF_ERROR(row.status());
      tracks->push_back(std::move(t));
      point_counts.push_back(count);
    }
    if (rc != SQLITE_DONE) return Error(rc, "loading table tracks");
  }
  SAKER_ASSIGN_OR_RETURN(
      Statement stmt,
      Prepare("SELECT track_ordinal, ordinal, frame, time_s, image_x, image_y, box_min_x, "
              "box_min_y, box_max_x, box_max_y, map_x, map_y "
              "FROM track_points ORDER BY track_ordinal, ordinal",
              "loading table track_points"));
  RowReader row(stmt.get(), path, "track_points");
  int rc;
  while ((rc = sqlite3_step(stmt.get())) == SQLITE_ROW) {
    row.NextRow();
    const int64_t track = row.Int64(0);
    const int64_t ordinal = row.Int64(1);
    SAKER_RETURN_IF_ERROR(row.status());
    if (track < 0 || track >= int64_t(tracks->size())) {
      row.Fail(0, "track_ordinal " + std::to_string(track) + " names no track");
      return row.status();
    }
    std::vector<TrackPoint>& points = (*tracks)[size_t(track)].points;
    if (ordinal != int64_t(points.size())) {
      row.Fail(1, "ordinal " + std::to_string(ordinal) + " where " + std::to_string(points.size()) +
                      " was expected (a row is missing)");
    }
    if (int64_t(points.size()) >= point_counts[size_t(track)]) {
      row.FailRow("more points than the track's point_count " +
                  std::to_string(point_counts[size_t(track)]));
    }
    TrackPoint p;
    p.frame = row.Int64(2);
    p.time_s = row.Real(3);
    p.image = Eigen::Vector2d(row.Real(4), row.Real(5));
    p.box_min = Eigen::Vector2d(row.Real(6), row.Real(7));
    p.box_max = Eigen::Vector2d(row.Real(8), row.Real(9));
    p.map = Eigen::Vector2d(row.Real(10), row.Real(11));
    SAKER_RETURN_IF_ERROR(row.status());
    points.push_back(p);
  }
  if (rc != SQLITE_DONE) return Error(rc, "loading table track_points");
  for (size_t i = 0; i < tracks->size(); ++i) {
    if (int64_t((*tracks)[i].points.size()) != point_counts[i]) {
      return InvalidDataError(path + ": table track_points: track " + std::to_string(i) + " has " +
                              std::to_string((*tracks)[i].points.size()) +
                              " points, table tracks says " + std::to_string(point_counts[i]));
    }
  }
  return Status::Ok();
}

Status MissionStore::Impl::LoadInTransaction(Mission* m) {
  // One read transaction: a concurrent Save is seen entirely or not at all.
  Transaction transaction(db.get(), path);
  SAKER_RETURN_IF_ERROR(transaction.Begin(/*write=*/false));
  SAKER_RETURN_IF_ERROR(LoadMeta(m));
  SAKER_RETURN_IF_ERROR(LoadSource(&m->source));
  SAKER_RETURN_IF_ERROR(LoadFrames(&m->frames));
  SAKER_RETURN_IF_ERROR(LoadKeyFrames(&m->key_frames));
  SAKER_RETURN_IF_ERROR(LoadLinks(&m->links));
  SAKER_RETURN_IF_ERROR(LoadTracks(&m->tracks));
  return transaction.Commit();
}

// ---------------------------------------------------------------------------------------------
// MissionStore.

MissionStore::MissionStore(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
MissionStore::~MissionStore() = default;

const std::string& MissionStore::path() const { return impl_->path; }
OpenMode MissionStore::mode() const { return impl_->mode; }

StatusOr<std::unique_ptr<MissionStore>> MissionStore::Open(const std::string& path, OpenMode mode) {
  SAKER_RETURN_IF_ERROR(CheckFileHeader(path));
  auto impl = std::make_unique<Impl>();
  impl->path = path;
  impl->mode = mode;
  // Identify the file through a read-only connection first, so a refused file is never opened
  // for writing (closing a writable connection may checkpoint into it).
  SAKER_RETURN_IF_ERROR(impl->OpenConnection(SQLITE_OPEN_READONLY));
  SAKER_RETURN_IF_ERROR(impl->CheckIdentity());
  if (mode == OpenMode::kReadWrite) {
    impl->db.reset();
    SAKER_RETURN_IF_ERROR(impl->OpenConnection(SQLITE_OPEN_READWRITE));
    SAKER_RETURN_IF_ERROR(impl->CheckIdentity());
    SAKER_RETURN_IF_ERROR(impl->SetWriteOptions());
    if (impl->schema < kSchemaVersion) SAKER_RETURN_IF_ERROR(impl->Upgrade());
  }
  return std::unique_ptr<MissionStore>(new MissionStore(std::move(impl)));
}

void MissionStore::RemoveStaleTemporaries(const std::string& path) {
  const std::filesystem::path target(path);
  std::filesystem::path directory = target.parent_path();
  if (directory.empty()) directory = ".";
  const std::string name = target.filename().string();
  // A FileReplacement's ".NAME.part-PID-N.EXT" (Create's, CopyMission's) and the one Create
  // makes for CopyMission's, "..NAME.part-PID-N.EXT.part-PID-M.EXT"; from older versions Create's
  // ".NAME.new-PID-N", CopyMission's "NAME.part-PID" and ".NAME.part-PID.new-PID-N". Each with
  // its -wal / -shm.
  const std::string prefixes[] = {"." + name + ".part-", ".." + name + ".part-",
                                  "." + name + ".new-", name + ".part-"};
  std::error_code error;
  for (std::filesystem::directory_iterator it(directory, error), end; !error && it != end;
       it.increment(error)) {
    const std::string file = it->path().filename().string();
    for (const std::string& prefix : prefixes) {
      if (file.compare(0, prefix.size(), prefix) != 0) continue;
      const std::string rest = file.substr(prefix.size());
      const size_t digits = rest.find_first_not_of("0123456789");
      if (digits == 0 || rest.empty()) continue;
      const long pid = std::strtol(rest.substr(0, digits).c_str(), nullptr, 10);
      // Only a dead job's: a live one (this process or another) may be building it now.
      if (pid <= 0 || ::kill(pid_t(pid), 0) == 0 || errno != ESRCH) continue;
      std::error_code ignored;
      std::filesystem::remove(it->path(), ignored);
    }
  }
}

Status MissionStore::FoldLog(const std::string& path) {
  struct stat st;
  if (::stat(path.c_str(), &st) != 0) {
    const int err = errno;
    if (err != ENOENT) return IoError(path + ": " + std::strerror(err));
    // A log or journal without its database (a writer was killed, then the file alone deleted)
    // would be replayed onto the next file to take the name.
    for (const char* suffix : {"-wal", "-shm", "-journal"}) ::unlink((path + suffix).c_str());
    return Status::Ok();
  }
  // Fold the mission's write-ahead log into it; the log goes when the last connection closes.
  SAKER_ASSIGN_OR_RETURN(std::unique_ptr<MissionStore> old, Open(path, OpenMode::kReadWrite));
  return old->impl_->Checkpoint();
}

StatusOr<std::unique_ptr<MissionStore>> MissionStore::Create(const std::string& path,
                                                             bool replace) {
  struct stat st;
  bool exists = true;
  if (::stat(path.c_str(), &st) != 0) {
    const int err = errno;
    if (err != ENOENT) return IoError(path + ": " + std::strerror(err));
    exists = false;
  }
  if (exists) {
    if (!replace) {
      return InvalidArgumentError(path + ": a file already exists there (not replaced)");
    }
    // Only a mission this version reads may be replaced; this probe never writes.
    {
      auto probe = Open(path, OpenMode::kReadOnly);
      if (!probe.ok()) {
        return Status(probe.status().code(), probe.status().message() + " (not replaced)");
      }
    }
  }
  if (Status folded = FoldLog(path); !folded.ok()) {
    return Status(folded.code(), folded.message() + " (not replaced)");
  }
  RemoveStaleTemporaries(path);

  // Built beside the target and renamed over it (not over a file that appeared meanwhile when
  // none was there), with the log folded in and synced, so a crash leaves the old or the new file.
  FileReplacement replacement(path, {.overwrite = exists, .side_suffixes = kDatabaseSideSuffixes});
  const std::string& temp = replacement.temporary();
  auto build = [&]() -> Status {
    Impl impl;
    impl.path = temp;
    impl.mode = OpenMode::kReadWrite;
    SAKER_RETURN_IF_ERROR(impl.OpenConnection(SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE));
    // Space freed when a finished job drops its checkpoints goes back to the file system
    // (ClearCheckpoint); only settable while the database is empty, before the switch to WAL.
    SAKER_RETURN_IF_ERROR(impl.Exec("PRAGMA auto_vacuum = INCREMENTAL", "setting auto-vacuum"));
    SAKER_RETURN_IF_ERROR(impl.SetWriteOptions());
    const std::string pragmas = "PRAGMA application_id = " + std::to_string(kMissionApplicationId) +
                                "; PRAGMA user_version = " + std::to_string(kSchemaVersion);
    {
      Transaction transaction(impl.db.get(), impl.path);
      SAKER_RETURN_IF_ERROR(transaction.Begin(/*write=*/true));
      SAKER_RETURN_IF_ERROR(impl.Exec(pragmas.c_str(), "setting the file identity"));
      SAKER_RETURN_IF_ERROR(impl.Exec(kSchemaSql, "creating the schema"));
      SAKER_RETURN_IF_ERROR(impl.Exec(kCheckpointSql, "creating the schema"));
      SAKER_RETURN_IF_ERROR(transaction.Commit());
    }
    SAKER_RETURN_IF_ERROR(impl.SaveInTransaction(Mission{}, kSaveAll));
    return impl.Checkpoint();
  };
  if (Status built = build(); !built.ok()) {
    return Status(built.code(), path + ": cannot create the mission: " + built.message());
  }
  SAKER_RETURN_IF_ERROR(replacement.Commit());
  return Open(path, OpenMode::kReadWrite);
}

Status MissionStore::Save(const Mission& mission, unsigned parts) {
  if (impl_->mode != OpenMode::kReadWrite) {
    return InvalidArgumentError(impl_->path + ": cannot save: the mission is open read-only");
  }
  if ((parts & ~unsigned(kSaveAll)) != 0) {
    return InvalidArgumentError(impl_->path + ": cannot save: unknown parts " +
                                std::to_string(parts));
  }
  std::string problem = HeaderProblem(mission);
  if (problem.empty()) problem = PartsProblem(mission, parts);
  if (!problem.empty()) return InvalidArgumentError(impl_->path + ": cannot save: " + problem);
  try {
    return impl_->SaveInTransaction(mission, parts);
  } catch (const std::bad_alloc&) {
    return IoError(impl_->path + ": out of memory while saving");
  }
}

StatusOr<Mission> MissionStore::Load() const {
  try {
    Mission mission;
    SAKER_RETURN_IF_ERROR(impl_->LoadInTransaction(&mission));
    return mission;
  } catch (const std::bad_alloc&) {
    return IoError(impl_->path + ": out of memory while loading (a corrupt file?)");
  }
}

Status MissionStore::WriteTiles(const std::vector<EncodedTile>& tiles) {
  if (impl_->mode != OpenMode::kReadWrite) {
    return InvalidArgumentError(impl_->path +
                                ": cannot write tiles: the mission is open "
                                "read-only");
  }
  for (const EncodedTile& tile : tiles) {
    if (tile.level < 0 || tile.x < 0 || tile.y < 0) {
      return InvalidArgumentError(impl_->path + ": cannot write tile (" +
                                  std::to_string(tile.level) + ", " + std::to_string(tile.x) +
                                  ", " + std::to_string(tile.y) + "): negative level or position");
    }
  }
  Transaction transaction(impl_->db.get(), impl_->path);
  SAKER_RETURN_IF_ERROR(transaction.Begin(/*write=*/true));
  SAKER_ASSIGN_OR_RETURN(
      Statement stmt,
      impl_->Prepare("INSERT OR REPLACE INTO tiles (level, x, y, data) VALUES (?1, ?2, ?3, ?4)",
                     "writing tiles"));
  for (const EncodedTile& tile : tiles) {
    Binder b(stmt.get());
    b.Int64(1, tile.level);
    b.Int64(2, tile.x);
    b.Int64(3, tile.y);
    b.Blob(4, tile.bytes.data(), tile.bytes.size());
    SAKER_RETURN_IF_ERROR(impl_->Run(stmt.get(), b, "writing tiles"));
  }
  return transaction.Commit();
}

Status MissionStore::ClearTiles() {
  if (impl_->mode != OpenMode::kReadWrite) {
    return InvalidArgumentError(impl_->path +
                                ": cannot clear tiles: the mission is open "
                                "read-only");
  }
  Transaction transaction(impl_->db.get(), impl_->path);
  SAKER_RETURN_IF_ERROR(transaction.Begin(/*write=*/true));
  SAKER_RETURN_IF_ERROR(impl_->Exec("DELETE FROM tiles", "clearing tiles"));
  return transaction.Commit();
}

Status MissionStore::WriteCheckpoint(const std::vector<CheckpointRecord>& records,
                                     const std::vector<std::string>& replace_kinds) {
  if (impl_->mode != OpenMode::kReadWrite) {
    return InvalidArgumentError(impl_->path +
                                ": cannot write a checkpoint: the mission is open read-only");
  }
  Transaction transaction(impl_->db.get(), impl_->path);
  SAKER_RETURN_IF_ERROR(transaction.Begin(/*write=*/true));
  if (!replace_kinds.empty()) {
    SAKER_ASSIGN_OR_RETURN(Statement clear, impl_->Prepare("DELETE FROM checkpoint WHERE kind = ?1",
                                                           "writing the checkpoint"));
    for (const std::string& kind : replace_kinds) {
      Binder b(clear.get());
      b.Text(1, kind);
      SAKER_RETURN_IF_ERROR(impl_->Run(clear.get(), b, "writing the checkpoint"));
    }
  }
  SAKER_ASSIGN_OR_RETURN(
      Statement stmt,
      impl_->Prepare("INSERT OR REPLACE INTO checkpoint (kind, key, data) VALUES (?1, ?2, ?3)",
                     "writing the checkpoint"));
  for (const CheckpointRecord& record : records) {
    Binder b(stmt.get());
    b.Text(1, record.kind);
    b.Int64(2, record.key);
    b.Blob(3, record.bytes.data(), record.bytes.size());
    SAKER_RETURN_IF_ERROR(impl_->Run(stmt.get(), b, "writing the checkpoint"));
  }
  return transaction.Commit();
}

StatusOr<std::vector<CheckpointRecord>> MissionStore::ReadCheckpoint() const {
  std::vector<CheckpointRecord> records;
  if (impl_->schema < 3) return records;  // older files have no checkpoints
  Transaction transaction(impl_->db.get(), impl_->path);
  SAKER_RETURN_IF_ERROR(transaction.Begin(/*write=*/false));
  SAKER_ASSIGN_OR_RETURN(Statement stmt,
                         impl_->Prepare("SELECT kind, key, data FROM checkpoint ORDER BY kind, key",
                                        "reading the checkpoint"));
  const std::string where = impl_->path + ": table checkpoint";
  int rc;
  try {
    while ((rc = sqlite3_step(stmt.get())) == SQLITE_ROW) {
      if (sqlite3_column_type(stmt.get(), 0) != SQLITE_TEXT ||
          sqlite3_column_type(stmt.get(), 1) != SQLITE_INTEGER ||
          sqlite3_column_type(stmt.get(), 2) != SQLITE_BLOB) {
        return InvalidDataError(where +
                                ": a row of the wrong types (kind text, key integer, "
                                "data blob)");
      }
      CheckpointRecord record;
      const auto* kind = reinterpret_cast<const char*>(sqlite3_column_text(stmt.get(), 0));
      record.kind.assign(kind != nullptr ? kind : "", size_t(sqlite3_column_bytes(stmt.get(), 0)));
      record.key = sqlite3_column_int64(stmt.get(), 1);
      const auto* data = static_cast<const uint8_t*>(sqlite3_column_blob(stmt.get(), 2));
      const int size = sqlite3_column_bytes(stmt.get(), 2);
      if (data == nullptr && size > 0) return IoError(where + ": out of memory");
      if (size > 0) record.bytes.assign(data, data + size);
      records.push_back(std::move(record));
    }
  } catch (const std::bad_alloc&) {
    return IoError(where + ": out of memory");
  }
  if (rc != SQLITE_DONE) return impl_->Error(rc, "reading the checkpoint");
  SAKER_RETURN_IF_ERROR(transaction.Commit());
  return records;
}

Status MissionStore::ClearCheckpoint() {
  if (impl_->mode != OpenMode::kReadWrite) {
    return InvalidArgumentError(impl_->path +
                                ": cannot clear the checkpoint: the mission is open read-only");
  }
  {
    Transaction transaction(impl_->db.get(), impl_->path);
    SAKER_RETURN_IF_ERROR(transaction.Begin(/*write=*/true));
    SAKER_RETURN_IF_ERROR(impl_->Exec("DELETE FROM checkpoint", "clearing the checkpoint"));
    SAKER_RETURN_IF_ERROR(transaction.Commit());
  }
  // Gives the freed pages back to the file system (a no-op in files made without auto-vacuum).
  return impl_->Exec("PRAGMA incremental_vacuum", "clearing the checkpoint");
}

StatusOr<std::optional<std::vector<uint8_t>>> MissionStore::ReadTile(int level, int x,
                                                                     int y) const {
  if (impl_->read_tile.get() == nullptr) {
    SAKER_ASSIGN_OR_RETURN(
        impl_->read_tile,
        impl_->Prepare("SELECT data FROM tiles WHERE level = ?1 AND x = ?2 AND y = ?3",
                       "reading a tile", SQLITE_PREPARE_PERSISTENT));
  }
  sqlite3_stmt* stmt = impl_->read_tile.get();
  ResetOnExit reset(stmt);
  Binder b(stmt);
  b.Int64(1, level);
  b.Int64(2, x);
  b.Int64(3, y);
  if (b.rc() != SQLITE_OK) return impl_->Error(b.rc(), "reading a tile");
  const int rc = sqlite3_step(stmt);
  if (rc == SQLITE_DONE) return std::optional<std::vector<uint8_t>>();
  if (rc != SQLITE_ROW) return impl_->Error(rc, "reading a tile");
  const std::string where = impl_->path + ": table tiles, tile (" + std::to_string(level) + ", " +
                            std::to_string(x) + ", " + std::to_string(y) + ")";
  if (sqlite3_column_type(stmt, 0) != SQLITE_BLOB) {
    return InvalidDataError(where + ": data is " + TypeName(sqlite3_column_type(stmt, 0)) +
                            ", not a blob");
  }
  const auto* data = static_cast<const uint8_t*>(sqlite3_column_blob(stmt, 0));
  const int size = sqlite3_column_bytes(stmt, 0);
  if (data == nullptr && size > 0) return IoError(where + ": out of memory");
  try {
    return std::optional<std::vector<uint8_t>>(std::vector<uint8_t>(data, data + size));
  } catch (const std::bad_alloc&) {
    return IoError(where + ": out of memory");
  }
}

StatusOr<int64_t> MissionStore::CountTiles() const {
  if (impl_->count_tiles.get() == nullptr) {
    SAKER_ASSIGN_OR_RETURN(
        impl_->count_tiles,
        impl_->Prepare("SELECT count(*) FROM tiles", "counting tiles", SQLITE_PREPARE_PERSISTENT));
  }
  sqlite3_stmt* stmt = impl_->count_tiles.get();
  ResetOnExit reset(stmt);
  const int rc = sqlite3_step(stmt);
  if (rc != SQLITE_ROW) return impl_->Error(rc, "counting tiles");
  return int64_t(sqlite3_column_int64(stmt, 0));
}

}  // namespace saker::mission
