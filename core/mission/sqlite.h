#pragma once

// The SQLite plumbing under MissionStore: a configured connection, transactions, statements,
// parameter binding and checked column reading, each turning SQLite's result codes into a Status
// that names the file. Internal to saker_mission (not part of its public API); nothing here knows
// the mission schema (core/mission/schema.h).

#include "core/util/status.h"

#include <Eigen/Core>
#include <sqlite3.h>

#include <cstdint>
#include <cstring>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace saker::mission::sqlite {

// ---------------------------------------------------------------------------------------------
// Little-endian float64 blobs.

void EncodeDoubles(const double* values, int n, uint8_t* out);
void DecodeDoubles(const uint8_t* in, int n, double* values);

// A fixed-size matrix as row-major float64 (`out`: rows * cols * 8 bytes).
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
// Errors.

// The Status for a failed SQLite call on the database at `path` (`db` may be null): content
// problems are InvalidData, the rest IoError; the message names the file and `what` was done.
Status SqliteError(sqlite3* db, int rc, const std::string& path, const std::string& what);

// "an integer", "a real", ... for messages about a value of the wrong type.
const char* TypeName(int type);

// The bytes of column `col` of the current row (a BLOB); false when SQLite ran out of memory
// reading them. Throws std::bad_alloc when `out` cannot hold them.
bool ColumnBytes(sqlite3_stmt* stmt, int col, std::vector<uint8_t>* out);

// ---------------------------------------------------------------------------------------------
// Statements.

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

// Reads the columns of one result row with type and size checks, remembering the first problem
// (InvalidData naming the file, the table, the row and the column). Values read after a problem
// are defaults; check status() once per row.
class RowReader {
 public:
  RowReader(sqlite3_stmt* stmt, const std::string& path, const char* table)
      : stmt_(stmt), path_(path), table_(table) {}

  void NextRow() { ++row_; }
  // The current row, from 1.
  int64_t row() const { return row_; }
  const Status& status() const { return status_; }

  int Type(int col) const { return sqlite3_column_type(stmt_, col); }
  bool IsNull(int col) const { return Type(col) == SQLITE_NULL; }

  int64_t Int64(int col);
  // An integer in [lo, hi].
  int64_t Int(int col, int64_t lo, int64_t hi);
  int32_t Int32(int col);
  bool Bool(int col) { return Int(col, 0, 1) == 1; }
  std::optional<int64_t> OptionalInt64(int col);
  // REAL (or an INTEGER a tool wrote); NULL is NaN, which SQLite cannot store.
  double Real(int col);
  std::optional<double> OptionalReal(int col);
  std::string Text(int col);
  // The bytes of a BLOB (ColumnBytes: no type check); false when SQLite ran out of memory.
  bool Bytes(int col, std::vector<uint8_t>* out) { return ColumnBytes(stmt_, col, out); }
  // A BLOB of exactly `n` float64.
  void Doubles(int col, int n, double* out);
  // A BLOB of a fixed-size matrix, row-major float64.
  template <typename Matrix>
  Matrix RowMajor(int col) {
    double values[Matrix::RowsAtCompileTime * Matrix::ColsAtCompileTime];
    Doubles(col, (Matrix::RowsAtCompileTime * Matrix::ColsAtCompileTime), values);
    Matrix m;
    DecodeRowMajor(values, &m);
    return m;
  }

  void Fail(int col, const std::string& problem);
  void FailRow(const std::string& problem);

 private:
  sqlite3_stmt* stmt_;
  const std::string& path_;
  const char* table_;
  int64_t row_ = 0;
  Status status_;
};

// ---------------------------------------------------------------------------------------------
// The connection.

// One open database connection and its path, which every error names. Use from one thread at a
// time.
class Database {
 public:
  Database() = default;
  Database(const Database&) = delete;
  Database& operator=(const Database&) = delete;

  // Opens `path` (sqlite3_open_v2 `flags`) and configures the connection: waits up to
  // `busy_timeout_ms` for another connection's lock, and keeps a hostile file within its own
  // content (defensive mode, untrusted schema, cell size checks). Closes any earlier connection.
  // `immutable`: read-only, promising SQLite that nothing changes the file while it is open, so
  // it takes no locks and makes no -wal / -shm files (read-only media; a one-off read of a file
  // no job writes).
  Status Open(const std::string& path, int flags, int busy_timeout_ms, bool immutable = false);
  void Close() { db_.reset(); }

  sqlite3* get() const { return db_.get(); }
  const std::string& path() const { return path_; }

  Status Error(int rc, const std::string& what) const {
    return SqliteError(db_.get(), rc, path_, what);
  }
  // Runs SQL that returns no rows.
  Status Exec(const char* sql, const std::string& what) const;
  StatusOr<Statement> Prepare(const char* sql, const std::string& what, unsigned flags = 0) const;
  // Steps a statement that returns no row, after checking its bindings, and resets it.
  Status Run(sqlite3_stmt* stmt, const Binder& binder, const std::string& what) const;
  // A one-row, one-integer query such as a pragma.
  StatusOr<int64_t> QueryInt(const char* sql, const std::string& what) const;
  // A one-row, one-text query (NULL reads as empty).
  StatusOr<std::string> QueryText(const char* sql, const std::string& what) const;
  // Prepares `sql` and calls `read` for each result row (the reader moved to it), stopping at the
  // first problem: `read`'s Status, the reader's, or SQLite's (`what` failed). `table` names
  // the rows in the reader's messages.
  Status ForEachRow(const char* sql, const std::string& what, const char* table,
                    const std::function<Status(RowReader& row)>& read) const;

 private:
  struct Closer {
    // sqlite3_close_v2 defers the close until every statement is finalized; it only fails for a
    // null or already closed handle.
    void operator()(sqlite3* db) const { sqlite3_close_v2(db); }
  };

  std::string path_;
  std::unique_ptr<sqlite3, Closer> db_;
};

// A transaction that rolls back unless committed.
class Transaction {
 public:
  explicit Transaction(const Database& db) : db_(db) {}
  Transaction(const Transaction&) = delete;
  Transaction& operator=(const Transaction&) = delete;
  ~Transaction() {
    // ROLLBACK only fails when SQLite already rolled the transaction back after an error.
    if (active_) sqlite3_exec(db_.get(), "ROLLBACK", nullptr, nullptr, nullptr);
  }

  // `write`: take the write lock now (BEGIN IMMEDIATE), waiting up to the busy timeout, so the
  // transaction never fails half-way for a lock.
  Status Begin(bool write);
  Status Commit();

 private:
  const Database& db_;
  bool active_ = false;
};

}  // namespace saker::mission::sqlite
