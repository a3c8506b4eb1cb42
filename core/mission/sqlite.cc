#include "core/mission/sqlite.h"

#include <algorithm>
#include <bit>
#include <cctype>
#include <limits>

namespace saker::mission::sqlite {
namespace {

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

// `path` as an SQLite URI ("file:" and the path, percent-encoded but for unreserved bytes and '/').
std::string FileUri(const std::string& path) {
  static const char kHex[] = "0123456789ABCDEF";
  std::string uri = "file:";
  for (const char c : path) {
    const auto byte = static_cast<unsigned char>(c);
    if (std::isalnum(byte) != 0 || std::strchr("/-._~", c) != nullptr) {
      uri += c;
    } else {
      uri += '%';
      uri += kHex[byte >> 4];
      uri += kHex[byte & 15];
    }
  }
  return uri;
}

std::string ColumnName(sqlite3_stmt* stmt, int col) {
  const char* name = sqlite3_column_name(stmt, col);
  return name != nullptr ? name : "column " + std::to_string(col);
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Little-endian float64 blobs.

void EncodeDoubles(const double* values, int n, uint8_t* out) {
  if constexpr (std::endian::native == std::endian::little) {
    std::memcpy(out, values, static_cast<size_t>(n) * 8);
  } else {
    for (int i = 0; i < n; ++i) {
      const uint64_t bits = std::bit_cast<uint64_t>(values[i]);
      for (int b = 0; b < 8; ++b) out[i * 8 + b] = static_cast<uint8_t>(bits >> (8 * b));
    }
  }
}

void DecodeDoubles(const uint8_t* in, int n, double* values) {
  if constexpr (std::endian::native == std::endian::little) {
    std::memcpy(values, in, static_cast<size_t>(n) * 8);
  } else {
    for (int i = 0; i < n; ++i) {
      uint64_t bits = 0;
      for (int b = 0; b < 8; ++b) bits |= static_cast<uint64_t>(in[i * 8 + b]) << (8 * b);
      values[i] = std::bit_cast<double>(bits);
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Errors.

Status SqliteError(sqlite3* db, int rc, const std::string& path, const std::string& what) {
  const char* detail = db != nullptr ? sqlite3_errmsg(db) : sqlite3_errstr(rc);
  std::string message = path + ": " + what + ": " + (detail ? detail : "unknown SQLite error");
  if ((rc & 0xff) == SQLITE_CORRUPT) message += " (the file is damaged or truncated)";
  return SqliteStatus(rc, message);
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

bool ColumnBytes(sqlite3_stmt* stmt, int col, std::vector<uint8_t>* out) {
  const auto* data = static_cast<const uint8_t*>(sqlite3_column_blob(stmt, col));
  const int size = sqlite3_column_bytes(stmt, col);
  if (data == nullptr && size > 0) return false;
  out->assign(data, data + size);
  return true;
}

// ---------------------------------------------------------------------------------------------
// RowReader.

int64_t RowReader::Int64(int col) {
  const int type = Type(col);
  if (type != SQLITE_INTEGER) {
    Fail(col, std::string("expected an integer, found ") + TypeName(type));
    return 0;
  }
  return sqlite3_column_int64(stmt_, col);
}

int64_t RowReader::Int(int col, int64_t lo, int64_t hi) {
  const int64_t v = Int64(col);
  if (v < lo || v > hi) {
    Fail(col, std::to_string(v) + " is outside [" + std::to_string(lo) + ", " + std::to_string(hi) +
                  "]");
    return 0;
  }
  return v;
}

int32_t RowReader::Int32(int col) {
  return static_cast<int32_t>(
      Int(col, std::numeric_limits<int32_t>::min(), std::numeric_limits<int32_t>::max()));
}

std::optional<int64_t> RowReader::OptionalInt64(int col) {
  if (IsNull(col)) return std::nullopt;
  return Int64(col);
}

double RowReader::Real(int col) {
  const int type = Type(col);
  if (type == SQLITE_NULL) return std::numeric_limits<double>::quiet_NaN();
  if (type != SQLITE_FLOAT && type != SQLITE_INTEGER) {
    Fail(col, std::string("expected a real number, found ") + TypeName(type));
    return 0;
  }
  return sqlite3_column_double(stmt_, col);
}

std::optional<double> RowReader::OptionalReal(int col) {
  if (IsNull(col)) return std::nullopt;
  return Real(col);
}

std::string RowReader::Text(int col) {
  const int type = Type(col);
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
  return std::string(text, static_cast<size_t>(size));
}

void RowReader::Doubles(int col, int n, double* out) {
  std::fill(out, out + n, 0.0);
  const int type = Type(col);
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

void RowReader::Fail(int col, const std::string& problem) {
  if (!status_.ok()) return;
  status_ = InvalidDataError(path_ + ": table " + table_ + ", row " + std::to_string(row_) +
                             ", column " + ColumnName(stmt_, col) + ": " + problem);
}

void RowReader::FailRow(const std::string& problem) {
  if (!status_.ok()) return;
  status_ = InvalidDataError(path_ + ": table " + table_ + ", row " + std::to_string(row_) + ": " +
                             problem);
}

// ---------------------------------------------------------------------------------------------
// Database.

Status Database::Open(const std::string& path, int flags, int busy_timeout_ms, bool immutable) {
  path_ = path;
  sqlite3* raw = nullptr;
  const int rc = immutable ? sqlite3_open_v2((FileUri(path) + "?immutable=1").c_str(), &raw,
                                             SQLITE_OPEN_READONLY | SQLITE_OPEN_URI, nullptr)
                           : sqlite3_open_v2(path.c_str(), &raw, flags, nullptr);
  db_.reset(raw);  // closed on every path, even when the open failed
  if (rc != SQLITE_OK) return SqliteError(raw, rc, path, "cannot open");
  int status = sqlite3_extended_result_codes(get(), 0);
  if (status == SQLITE_OK) status = sqlite3_busy_timeout(get(), busy_timeout_ms);
  // A hostile file must not reach beyond its own content: no writes to SQLite's internal
  // structures, and no functions with side effects in its views or triggers.
  if (status == SQLITE_OK) status = sqlite3_db_config(get(), SQLITE_DBCONFIG_DEFENSIVE, 1, nullptr);
#ifdef SQLITE_DBCONFIG_TRUSTED_SCHEMA
  if (status == SQLITE_OK) {
    status = sqlite3_db_config(get(), SQLITE_DBCONFIG_TRUSTED_SCHEMA, 0, nullptr);
  }
#endif
  if (status != SQLITE_OK) return Error(status, "configuring the connection");
  return Exec("PRAGMA cell_size_check = ON", "configuring the connection");
}

Status Database::Exec(const char* sql, const std::string& what) const {
  const int rc = sqlite3_exec(get(), sql, nullptr, nullptr, nullptr);
  if (rc != SQLITE_OK) return Error(rc, what);
  return Status::Ok();
}

StatusOr<Statement> Database::Prepare(const char* sql, const std::string& what,
                                      unsigned flags) const {
  Statement stmt;
  const int rc = sqlite3_prepare_v3(get(), sql, -1, flags, stmt.out(), nullptr);
  if (rc != SQLITE_OK) return Error(rc, what);
  if (stmt.get() == nullptr) return Error(SQLITE_ERROR, what + ": empty statement");
  return stmt;
}

Status Database::Run(sqlite3_stmt* stmt, const Binder& binder, const std::string& what) const {
  ResetOnExit reset(stmt);
  if (binder.rc() != SQLITE_OK) return Error(binder.rc(), what);
  const int rc = sqlite3_step(stmt);
  if (rc != SQLITE_DONE && rc != SQLITE_ROW) return Error(rc, what);
  return Status::Ok();
}

StatusOr<int64_t> Database::QueryInt(const char* sql, const std::string& what) const {
  SAKER_ASSIGN_OR_RETURN(Statement stmt, Prepare(sql, what));
  const int rc = sqlite3_step(stmt.get());
  if (rc != SQLITE_ROW) {
    if (rc == SQLITE_DONE) return InvalidDataError(path_ + ": " + what + ": no result");
    return Error(rc, what);
  }
  if (sqlite3_column_type(stmt.get(), 0) != SQLITE_INTEGER) {
    return InvalidDataError(path_ + ": " + what + ": not an integer");
  }
  return static_cast<int64_t>(sqlite3_column_int64(stmt.get(), 0));
}

StatusOr<std::string> Database::QueryText(const char* sql, const std::string& what) const {
  SAKER_ASSIGN_OR_RETURN(Statement stmt, Prepare(sql, what));
  const int rc = sqlite3_step(stmt.get());
  if (rc != SQLITE_ROW) {
    if (rc == SQLITE_DONE) return InvalidDataError(path_ + ": " + what + ": no result");
    return Error(rc, what);
  }
  const auto* text = reinterpret_cast<const char*>(sqlite3_column_text(stmt.get(), 0));
  return std::string(text != nullptr ? text : "");
}

Status Database::ForEachRow(const char* sql, const std::string& what, const char* table,
                            const std::function<Status(RowReader& row)>& read) const {
  SAKER_ASSIGN_OR_RETURN(Statement stmt, Prepare(sql, what));
  RowReader row(stmt.get(), path_, table);
  int rc;
  while ((rc = sqlite3_step(stmt.get())) == SQLITE_ROW) {
    row.NextRow();
    SAKER_RETURN_IF_ERROR(read(row));
    SAKER_RETURN_IF_ERROR(row.status());
  }
  if (rc != SQLITE_DONE) return Error(rc, what);
  return Status::Ok();
}

// ---------------------------------------------------------------------------------------------
// Transaction.

Status Transaction::Begin(bool write) {
  SAKER_RETURN_IF_ERROR(
      db_.Exec(write ? "BEGIN IMMEDIATE" : "BEGIN",
               write ? "starting a write transaction" : "starting a read transaction"));
  active_ = true;
  return Status::Ok();
}

Status Transaction::Commit() {
  SAKER_RETURN_IF_ERROR(db_.Exec("COMMIT", "committing"));
  active_ = false;
  return Status::Ok();
}

}  // namespace saker::mission::sqlite
