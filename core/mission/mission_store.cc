#include "core/mission/mission_store.h"

#include "core/mission/schema.h"
#include "core/mission/sqlite.h"
#include "core/util/durable_file.h"

#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <new>
#include <utility>

namespace saker::mission {
namespace {

// How long a connection waits for another one's lock (a writer's commit, a checkpoint) before it
// reports "database is locked".
constexpr int kBusyTimeoutMs = 5000;

// The files SQLite may keep beside a database.
const std::vector<std::string> kDatabaseSideSuffixes = {"-wal", "-shm", "-journal"};

}  // namespace

// ---------------------------------------------------------------------------------------------

struct MissionStore::Impl {
  OpenMode mode = OpenMode::kReadOnly;
  int schema_version = kSchemaVersion;  // of the file, as schema::CheckIdentity read it
  sqlite::Database db;                  // destroyed last: after the statements below
  sqlite::Statement read_tile;          // cached: tiles are read one by one while the map is panned
  sqlite::Statement count_tiles;

  const std::string& path() const { return db.path(); }
  // WAL, its sync level, foreign keys: the settings of a connection that writes.
  Status SetWriteOptions();
  // Folds the write-ahead log into the file and truncates it.
  Status Checkpoint();
};

Status MissionStore::Impl::SetWriteOptions() {
  SAKER_ASSIGN_OR_RETURN(const std::string journal,
                         db.QueryText("PRAGMA journal_mode = WAL", "switching to WAL"));
  if (journal != "wal") {
    return IoError(path() + ": cannot use a write-ahead log here (journal mode stays " + journal +
                   "); is the file on a network file system?");
  }
  // In WAL mode NORMAL loses at most the last commits on power loss, never consistency; a killed
  // process loses nothing that was committed.
  SAKER_RETURN_IF_ERROR(db.Exec("PRAGMA synchronous = NORMAL", "setting synchronous"));
  // The schema declares track_points -> tracks for other tools; Save writes both tables in one
  // transaction and Load checks the relation, so enforcing it per row (a third slower track
  // save) buys nothing here.
  return db.Exec("PRAGMA foreign_keys = OFF", "configuring foreign keys");
}

Status MissionStore::Impl::Checkpoint() {
  SAKER_ASSIGN_OR_RETURN(sqlite::Statement stmt,
                         db.Prepare("PRAGMA wal_checkpoint(TRUNCATE)", "checkpointing"));
  const int rc = sqlite3_step(stmt.get());
  if (rc != SQLITE_ROW) return db.Error(rc, "checkpointing");
  if (sqlite3_column_int(stmt.get(), 0) != 0) {
    return IoError(path() + ": the mission is in use by another program (checkpoint blocked)");
  }
  return Status::Ok();
}

// ---------------------------------------------------------------------------------------------
// MissionStore.

MissionStore::MissionStore(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
MissionStore::~MissionStore() = default;

const std::string& MissionStore::path() const { return impl_->path(); }
OpenMode MissionStore::mode() const { return impl_->mode; }

StatusOr<std::unique_ptr<MissionStore>> MissionStore::Open(const std::string& path, OpenMode mode) {
  SAKER_RETURN_IF_ERROR(schema::CheckFileHeader(path));
  auto impl = std::make_unique<Impl>();
  impl->mode = mode;
  // Identify the file through a read-only connection first, so a refused file is never opened
  // for writing (closing a writable connection may checkpoint into it).
  SAKER_RETURN_IF_ERROR(impl->db.Open(path, SQLITE_OPEN_READONLY, kBusyTimeoutMs));
  SAKER_ASSIGN_OR_RETURN(impl->schema_version, schema::CheckIdentity(impl->db));
  if (mode == OpenMode::kReadWrite) {
    impl->db.Close();
    SAKER_RETURN_IF_ERROR(impl->db.Open(path, SQLITE_OPEN_READWRITE, kBusyTimeoutMs));
    SAKER_ASSIGN_OR_RETURN(impl->schema_version, schema::CheckIdentity(impl->db));
    SAKER_RETURN_IF_ERROR(impl->SetWriteOptions());
    if (impl->schema_version < kSchemaVersion) {
      SAKER_RETURN_IF_ERROR(schema::Upgrade(impl->db, impl->schema_version));
      impl->schema_version = kSchemaVersion;
    }
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
      if (pid <= 0 || ::kill(static_cast<pid_t>(pid), 0) == 0 || errno != ESRCH) continue;
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
    impl.mode = OpenMode::kReadWrite;
    SAKER_RETURN_IF_ERROR(
        impl.db.Open(temp, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE, kBusyTimeoutMs));
    // Space freed when a finished job drops its checkpoints goes back to the file system
    // (ClearCheckpoint); only settable while the database is empty, before the switch to WAL.
    SAKER_RETURN_IF_ERROR(impl.db.Exec("PRAGMA auto_vacuum = INCREMENTAL", "setting auto-vacuum"));
    SAKER_RETURN_IF_ERROR(impl.SetWriteOptions());
    SAKER_RETURN_IF_ERROR(schema::Create(impl.db));
    SAKER_RETURN_IF_ERROR(schema::Save(impl.db, Mission{}, kSaveAll));
    return impl.Checkpoint();
  };
  if (Status built = build(); !built.ok()) {
    return Status(built.code(), path + ": cannot create the mission: " + replacement.Reason(built));
  }
  SAKER_RETURN_IF_ERROR(replacement.Commit());
  return Open(path, OpenMode::kReadWrite);
}

Status MissionStore::Save(const Mission& mission, unsigned parts) {
  if (impl_->mode != OpenMode::kReadWrite) {
    return InvalidArgumentError(impl_->path() + ": cannot save: the mission is open read-only");
  }
  if ((parts & ~static_cast<unsigned>(kSaveAll)) != 0) {
    return InvalidArgumentError(impl_->path() + ": cannot save: unknown parts " +
                                std::to_string(parts));
  }
  std::string problem = schema::HeaderProblem(mission);
  if (problem.empty()) problem = schema::PartsProblem(mission, parts);
  if (!problem.empty()) return InvalidArgumentError(impl_->path() + ": cannot save: " + problem);
  try {
    return schema::Save(impl_->db, mission, parts);
  } catch (const std::bad_alloc&) {
    return IoError(impl_->path() + ": out of memory while saving");
  }
}

StatusOr<Mission> MissionStore::Load() const {
  try {
    Mission mission;
    SAKER_RETURN_IF_ERROR(schema::Load(impl_->db, impl_->schema_version, &mission));
    return mission;
  } catch (const std::bad_alloc&) {
    return IoError(impl_->path() + ": out of memory while loading (a corrupt file?)");
  }
}

Status MissionStore::WriteTiles(const std::vector<EncodedTile>& tiles) {
  if (impl_->mode != OpenMode::kReadWrite) {
    return InvalidArgumentError(impl_->path() +
                                ": cannot write tiles: the mission is open "
                                "read-only");
  }
  for (const EncodedTile& tile : tiles) {
    if (tile.level < 0 || tile.x < 0 || tile.y < 0) {
      return InvalidArgumentError(impl_->path() + ": cannot write tile (" +
                                  std::to_string(tile.level) + ", " + std::to_string(tile.x) +
                                  ", " + std::to_string(tile.y) + "): negative level or position");
    }
  }
  sqlite::Transaction transaction(impl_->db);
  SAKER_RETURN_IF_ERROR(transaction.Begin(/*write=*/true));
  SAKER_ASSIGN_OR_RETURN(
      sqlite::Statement stmt,
      impl_->db.Prepare("INSERT OR REPLACE INTO tiles (level, x, y, data) VALUES (?1, ?2, ?3, ?4)",
                        "writing tiles"));
  for (const EncodedTile& tile : tiles) {
    sqlite::Binder b(stmt.get());
    b.Int64(1, tile.level);
    b.Int64(2, tile.x);
    b.Int64(3, tile.y);
    b.Blob(4, tile.bytes.data(), tile.bytes.size());
    SAKER_RETURN_IF_ERROR(impl_->db.Run(stmt.get(), b, "writing tiles"));
  }
  return transaction.Commit();
}

Status MissionStore::ClearTiles() {
  if (impl_->mode != OpenMode::kReadWrite) {
    return InvalidArgumentError(impl_->path() +
                                ": cannot clear tiles: the mission is open "
                                "read-only");
  }
  sqlite::Transaction transaction(impl_->db);
  SAKER_RETURN_IF_ERROR(transaction.Begin(/*write=*/true));
  SAKER_RETURN_IF_ERROR(impl_->db.Exec("DELETE FROM tiles", "clearing tiles"));
  return transaction.Commit();
}

Status MissionStore::WriteCheckpoint(const std::vector<CheckpointRecord>& records,
                                     const std::vector<std::string>& replace_kinds) {
  if (impl_->mode != OpenMode::kReadWrite) {
    return InvalidArgumentError(impl_->path() +
                                ": cannot write a checkpoint: the mission is open read-only");
  }
  sqlite::Transaction transaction(impl_->db);
  SAKER_RETURN_IF_ERROR(transaction.Begin(/*write=*/true));
  if (!replace_kinds.empty()) {
    SAKER_ASSIGN_OR_RETURN(
        sqlite::Statement clear,
        impl_->db.Prepare("DELETE FROM checkpoint WHERE kind = ?1", "writing the checkpoint"));
    for (const std::string& kind : replace_kinds) {
      sqlite::Binder b(clear.get());
      b.Text(1, kind);
      SAKER_RETURN_IF_ERROR(impl_->db.Run(clear.get(), b, "writing the checkpoint"));
    }
  }
  SAKER_ASSIGN_OR_RETURN(
      sqlite::Statement stmt,
      impl_->db.Prepare("INSERT OR REPLACE INTO checkpoint (kind, key, data) VALUES (?1, ?2, ?3)",
                        "writing the checkpoint"));
  for (const CheckpointRecord& record : records) {
    sqlite::Binder b(stmt.get());
    b.Text(1, record.kind);
    b.Int64(2, record.key);
    b.Blob(3, record.bytes.data(), record.bytes.size());
    SAKER_RETURN_IF_ERROR(impl_->db.Run(stmt.get(), b, "writing the checkpoint"));
  }
  return transaction.Commit();
}

StatusOr<std::vector<CheckpointRecord>> MissionStore::ReadCheckpoint() const {
  std::vector<CheckpointRecord> records;
  if (impl_->schema_version < 3) return records;  // older files have no checkpoints
  sqlite::Transaction transaction(impl_->db);
  SAKER_RETURN_IF_ERROR(transaction.Begin(/*write=*/false));
  const std::string where = impl_->path() + ": table checkpoint";
  try {
    SAKER_RETURN_IF_ERROR(impl_->db.ForEachRow(
        "SELECT kind, key, data FROM checkpoint ORDER BY kind, key", "reading the checkpoint",
        "checkpoint", [&](sqlite::RowReader& row) -> Status {
          if (row.Type(0) != SQLITE_TEXT || row.Type(1) != SQLITE_INTEGER ||
              row.Type(2) != SQLITE_BLOB) {
            return InvalidDataError(where +
                                    ": a row of the wrong types (kind text, key integer, "
                                    "data blob)");
          }
          CheckpointRecord record;
          record.kind = row.Text(0);
          record.key = row.Int64(1);
          if (!row.Bytes(2, &record.bytes)) return IoError(where + ": out of memory");
          records.push_back(std::move(record));
          return Status::Ok();
        }));
  } catch (const std::bad_alloc&) {
    return IoError(where + ": out of memory");
  }
  SAKER_RETURN_IF_ERROR(transaction.Commit());
  return records;
}

Status MissionStore::ClearCheckpoint() {
  if (impl_->mode != OpenMode::kReadWrite) {
    return InvalidArgumentError(impl_->path() +
                                ": cannot clear the checkpoint: the mission is open read-only");
  }
  {
    sqlite::Transaction transaction(impl_->db);
    SAKER_RETURN_IF_ERROR(transaction.Begin(/*write=*/true));
    SAKER_RETURN_IF_ERROR(impl_->db.Exec("DELETE FROM checkpoint", "clearing the checkpoint"));
    SAKER_RETURN_IF_ERROR(transaction.Commit());
  }
  // Gives the freed pages back to the file system (a no-op in files made without auto-vacuum).
  return impl_->db.Exec("PRAGMA incremental_vacuum", "clearing the checkpoint");
}

StatusOr<std::optional<std::vector<uint8_t>>> MissionStore::ReadTile(int level, int x,
                                                                     int y) const {
  if (impl_->read_tile.get() == nullptr) {
    SAKER_ASSIGN_OR_RETURN(
        impl_->read_tile,
        impl_->db.Prepare("SELECT data FROM tiles WHERE level = ?1 AND x = ?2 AND y = ?3",
                          "reading a tile", SQLITE_PREPARE_PERSISTENT));
  }
  sqlite3_stmt* stmt = impl_->read_tile.get();
  sqlite::ResetOnExit reset(stmt);
  sqlite::Binder b(stmt);
  b.Int64(1, level);
  b.Int64(2, x);
  b.Int64(3, y);
  if (b.rc() != SQLITE_OK) return impl_->db.Error(b.rc(), "reading a tile");
  const int rc = sqlite3_step(stmt);
  if (rc == SQLITE_DONE) return std::optional<std::vector<uint8_t>>();
  if (rc != SQLITE_ROW) return impl_->db.Error(rc, "reading a tile");
  const std::string where = impl_->path() + ": table tiles, tile (" + std::to_string(level) + ", " +
                            std::to_string(x) + ", " + std::to_string(y) + ")";
  if (sqlite3_column_type(stmt, 0) != SQLITE_BLOB) {
    return InvalidDataError(where + ": data is " + sqlite::TypeName(sqlite3_column_type(stmt, 0)) +
                            ", not a blob");
  }
  try {
    std::vector<uint8_t> bytes;
    if (!sqlite::ColumnBytes(stmt, 0, &bytes)) return IoError(where + ": out of memory");
    return std::optional<std::vector<uint8_t>>(std::move(bytes));
  } catch (const std::bad_alloc&) {
    return IoError(where + ": out of memory");
  }
}

StatusOr<int64_t> MissionStore::CountTiles() const {
  if (impl_->count_tiles.get() == nullptr) {
    SAKER_ASSIGN_OR_RETURN(impl_->count_tiles,
                           impl_->db.Prepare("SELECT count(*) FROM tiles", "counting tiles",
                                             SQLITE_PREPARE_PERSISTENT));
  }
  sqlite3_stmt* stmt = impl_->count_tiles.get();
  sqlite::ResetOnExit reset(stmt);
  const int rc = sqlite3_step(stmt);
  if (rc != SQLITE_ROW) return impl_->db.Error(rc, "counting tiles");
  return static_cast<int64_t>(sqlite3_column_int64(stmt, 0));
}

}  // namespace saker::mission
