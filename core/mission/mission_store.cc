#include "core/mission/mission_store.h"

#include "core/mission/schema.h"
#include "core/mission/sqlite.h"
#include "core/util/durable_file.h"

#include <fcntl.h>
#include <sqlite3.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
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
// SQLite reserves room for the longest of them ("-journal") in every path it opens.
constexpr size_t kPathReserve = 8;
// What is added to a mission's name beside it: ".lock" (the writer's lock), "-wal" and "-shm"
// (a mission in WAL mode never has a -journal).
constexpr size_t kNameReserve = 5;

// The file whose lock a mission's writer holds.
std::string LockPath(const std::string& path) { return path + ".lock"; }

// The exclusive right to write a mission: an flock on "<mission>.lock" held while the writer
// lives. The lock file is beside the mission, not the mission itself, so it survives Create's
// rename of a new file over the path. The OS drops the lock when the process ends (a kill -9
// included); the file then left, naming a dead process, blocks nobody. flock locks belong to an
// open file description, so two stores of one process exclude each other too.
class WriterLock {
 public:
  WriterLock(const WriterLock&) = delete;
  WriterLock& operator=(const WriterLock&) = delete;
  // Removes the file, then lets go: a writer that opened it meanwhile finds it gone (Acquire).
  ~WriterLock() {
    ::unlink(path_.c_str());
    ::close(fd_);
  }

  // The lock of the mission at `mission`, or IoError naming the process that holds it.
  static StatusOr<std::unique_ptr<WriterLock>> Acquire(const std::string& mission);
  // Whether a writer holds the lock of the mission at `mission` now.
  static bool IsHeld(const std::string& mission);

 private:
  WriterLock(std::string path, int fd) : path_(std::move(path)), fd_(fd) {}

  std::string path_;
  int fd_;
};

// The process id recorded in a lock file, or 0.
long LockHolder(int fd) {
  char text[32] = {};
  const ssize_t n = ::pread(fd, text, sizeof(text) - 1, 0);
  return n > 0 ? std::strtol(text, nullptr, 10) : 0;
}

StatusOr<std::unique_ptr<WriterLock>> WriterLock::Acquire(const std::string& mission) {
  const std::string path = LockPath(mission);
  for (int attempt = 0; attempt < 100; ++attempt) {
    const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0666);
    if (fd < 0) {
      return IoError(mission + ": cannot create the lock file beside it: " +
                     std::string(std::strerror(errno)));
    }
    if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
      const int err = errno;
      const long holder = LockHolder(fd);
      ::close(fd);
      if (err != EWOULDBLOCK) {
        return IoError(mission + ": cannot lock " + path + ": " + std::strerror(err));
      }
      return IoError(mission + ": the mission is in use by " +
                     (holder > 0 ? "process " + std::to_string(holder) : "another process") +
                     ", which is writing it: wait for that job to end or cancel it");
    }
    // The holder before may have removed the file between our open and our lock: the lock
    // counts only on the file that is at the path.
    struct stat held, named;
    if (::fstat(fd, &held) == 0 && ::stat(path.c_str(), &named) == 0 &&
        held.st_dev == named.st_dev && held.st_ino == named.st_ino) {
      const std::string pid = std::to_string(::getpid()) + "\n";
      // The process id is for messages only: a lock file it cannot be written to still locks.
      if (::ftruncate(fd, 0) == 0 && ::pwrite(fd, pid.data(), pid.size(), 0) < 0) errno = 0;
      return std::unique_ptr<WriterLock>(new WriterLock(path, fd));
    }
    ::close(fd);
  }
  return IoError(mission + ": cannot lock " + path + ": it keeps being replaced");
}

bool WriterLock::IsHeld(const std::string& mission) {
  const int fd = ::open(LockPath(mission).c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return false;  // no writer has it (none can where it cannot be made)
  const bool held = ::flock(fd, LOCK_SH | LOCK_NB) != 0 && errno == EWOULDBLOCK;
  ::close(fd);  // drops the shared lock if it was taken
  return held;
}

// The folder of `path` ("." for a bare name).
std::string FolderOf(const std::string& path) {
  const std::filesystem::path parent = std::filesystem::path(path).parent_path();
  return parent.empty() ? "." : parent.string();
}

bool FileExists(const std::string& path) {
  struct stat st;
  return ::stat(path.c_str(), &st) == 0;
}

// The path as SQLite will see it: absolute, through symbolic links (its unix VFS resolves them).
std::string FullPath(const std::string& path) {
  std::error_code error;
  std::filesystem::path full = std::filesystem::weakly_canonical(path, error);
  if (error) full = std::filesystem::absolute(path, error);
  return error ? path : full.string();
}

// Refuses, naming the limit, a mission path SQLite cannot open: SQLite's unix VFS opens full
// paths of at most its mxPathname (512) bytes less room for "-journal", and the folder's file
// system limits names (NAME_MAX, 255 bytes) with ".lock", "-wal" or "-shm" added. `extra` bytes are
// what a temporary built beside the mission adds to its path and name (Create's); the limits
// named are the mission's own.
Status CheckPathLimits(const std::string& path, size_t extra) {
  const std::filesystem::path target(path);
  const std::string name = target.filename().string();
  const long name_max = ::pathconf(FolderOf(path).c_str(), _PC_NAME_MAX);
  const size_t max_name = (name_max > 0 ? static_cast<size_t>(name_max) : 255);
  // A temporary is set up with a rollback journal before it switches to WAL.
  const size_t reserve = extra > 0 ? std::max(kNameReserve, extra + kPathReserve) : kNameReserve;
  if (name.size() + reserve > max_name) {
    const std::string limit = std::to_string(max_name - reserve);
    return InvalidArgumentError(path + ": the file name is " + std::to_string(name.size()) +
                                " bytes long; a mission's name may have at most " + limit +
                                " bytes here (the file system allows " + std::to_string(max_name) +
                                ", and Saker and SQLite write files named after it with up to " +
                                std::to_string(reserve) + " bytes more)");
  }
  const sqlite3_vfs* vfs = sqlite3_vfs_find(nullptr);
  const size_t max_path =
      static_cast<size_t>(vfs != nullptr ? vfs->mxPathname : 512) - kPathReserve - extra;
  const std::string full = FullPath(path);
  if (full.size() > max_path) {
    return InvalidArgumentError(path + ": the path is " + std::to_string(full.size()) +
                                " bytes long in full; SQLite opens a mission's path of at most " +
                                std::to_string(max_path) +
                                " bytes: move it to a shorter folder or name");
  }
  return Status::Ok();
}

}  // namespace

// ---------------------------------------------------------------------------------------------

struct MissionStore::Impl {
  std::unique_ptr<WriterLock> lock;  // a writer's; released last, after the connection closed
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
  // Opens `path` for reading and identifies it: a snapshot (immutable) or a live connection.
  Status OpenToRead(const std::string& path, bool snapshot);
  // OpenToRead as `mode` asks and as the storage allows.
  Status OpenReadOnly(const std::string& path);
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

bool MissionStore::IsWritable(const std::string& path) {
  return ::access(path.c_str(), W_OK) == 0 && ::access(FolderOf(path).c_str(), W_OK) == 0;
}

Status MissionStore::Impl::OpenToRead(const std::string& path, bool snapshot) {
  SAKER_RETURN_IF_ERROR(db.Open(path, SQLITE_OPEN_READONLY, kBusyTimeoutMs, snapshot));
  SAKER_ASSIGN_OR_RETURN(schema_version, schema::CheckIdentity(db));
  return Status::Ok();
}

Status MissionStore::Impl::OpenReadOnly(const std::string& path) {
  // A write-ahead log beside the file holds commits (of a job writing now, or of one that was
  // killed) that only a live connection reads; a live connection makes and leaves the log and
  // its shared memory (-shm) beside the file.
  const bool log_present = FileExists(path + "-wal");
  if (mode == OpenMode::kSnapshot && !log_present && !WriterLock::IsHeld(path)) {
    return OpenToRead(path, /*snapshot=*/true);
  }
  const Status live = OpenToRead(path, /*snapshot=*/false);
  if (live.ok() || live.code() != StatusCode::kIoError || IsWritable(path)) return live;
  // Read-only storage, or a file the user may not write: no job of theirs changes it, and SQLite
  // cannot make the files a live connection needs there.
  if (log_present) {
    return IoError(live.message() +
                   " (the mission is read-only here and holds the write-ahead log of an "
                   "interrupted job: copy it with its -wal file to storage you can write to)");
  }
  return OpenToRead(path, /*snapshot=*/true);
}

StatusOr<std::unique_ptr<MissionStore>> MissionStore::Open(const std::string& path, OpenMode mode) {
  SAKER_RETURN_IF_ERROR(schema::CheckFileHeader(path));
  SAKER_RETURN_IF_ERROR(CheckPathLimits(path, 0));
  auto impl = std::make_unique<Impl>();
  impl->mode = mode;
  return OpenImpl(path, std::move(impl));
}

StatusOr<std::unique_ptr<MissionStore>> MissionStore::OpenImpl(const std::string& path,
                                                               std::unique_ptr<Impl> impl) {
  // Identify the file through a read-only connection first, so a refused file is never opened
  // for writing (closing a writable connection may checkpoint into it).
  SAKER_RETURN_IF_ERROR(impl->OpenReadOnly(path));
  if (impl->mode == OpenMode::kReadWrite) {
    impl->db.Close();
    if (impl->lock == nullptr) {
      SAKER_ASSIGN_OR_RETURN(impl->lock, WriterLock::Acquire(path));
    }
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
  const std::filesystem::path directory = FolderOf(path);
  const std::string name = std::filesystem::path(path).filename().string();
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
  Impl locked;
  SAKER_ASSIGN_OR_RETURN(locked.lock, WriterLock::Acquire(path));
  return FoldLogLocked(path, &locked);
}

Status MissionStore::FoldLogLocked(const std::string& path, Impl* locked) {
  struct stat st;
  if (::stat(path.c_str(), &st) != 0) {
    const int err = errno;
    if (err != ENOENT) return IoError(path + ": " + std::strerror(err));
    // A log or journal without its database (a writer was killed, then the file alone deleted)
    // would be replayed onto the next file to take the name.
    for (const std::string& suffix : kDatabaseSideSuffixes) ::unlink((path + suffix).c_str());
    return Status::Ok();
  }
  // Fold the mission's write-ahead log into it; the log goes when the last connection closes.
  auto impl = std::make_unique<Impl>();
  impl->mode = OpenMode::kReadWrite;
  impl->lock = std::move(locked->lock);
  SAKER_ASSIGN_OR_RETURN(std::unique_ptr<MissionStore> old, OpenImpl(path, std::move(impl)));
  const Status folded = old->impl_->Checkpoint();
  old->impl_->db.Close();
  locked->lock = std::move(old->impl_->lock);  // the caller goes on holding it
  return folded;
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
  if (exists && !replace) {
    return InvalidArgumentError(path + ": a file already exists there (not replaced)");
  }
  // Built beside the target and renamed over it (not over a file that appeared meanwhile when
  // none was there), with the log folded in and synced, so a crash leaves the old or the new file.
  FileReplacement replacement(path, {.overwrite = exists, .side_suffixes = kDatabaseSideSuffixes});
  const std::string& temp = replacement.temporary();
  SAKER_RETURN_IF_ERROR(
      CheckPathLimits(path, std::filesystem::path(temp).filename().string().size() -
                                std::filesystem::path(path).filename().string().size()));
  // The writer's lock before anything is probed, folded or replaced, held by the new store: a
  // second job on this mission is refused here, not left writing a file renamed away.
  auto locked = std::make_unique<Impl>();
  locked->mode = OpenMode::kReadWrite;
  auto lock = WriterLock::Acquire(path);
  if (!lock.ok()) {
    // Named once, as the other errors of Create: "PATH: cannot create the mission: why".
    std::string why = lock.status().message();
    if (why.rfind(path + ": ", 0) == 0) why.erase(0, path.size() + 2);
    return Status(lock.status().code(), path + ": cannot create the mission: " + why);
  }
  locked->lock = std::move(*lock);
  if (exists) {
    // Only a mission this version reads may be replaced; this probe never writes.
    auto probe = Open(path, OpenMode::kReadOnly);
    if (!probe.ok()) {
      return Status(probe.status().code(), probe.status().message() + " (not replaced)");
    }
  }
  if (Status folded = FoldLogLocked(path, locked.get()); !folded.ok()) {
    return Status(folded.code(), folded.message() + " (not replaced)");
  }
  RemoveStaleTemporaries(path);

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
  return OpenImpl(path, std::move(locked));
}

Status MissionStore::Save(const Mission& mission, unsigned parts) {
  if (impl_->mode != OpenMode::kReadWrite) {
    return InvalidArgumentError(impl_->path() + ": cannot save: the mission is open read-only");
  }
  if ((parts & ~static_cast<unsigned>(kSaveAll | kSaveReviews)) != 0) {
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

Status MissionStore::SaveReviews(const Mission& mission) {
  if (impl_->mode != OpenMode::kReadWrite) {
    return InvalidArgumentError(impl_->path() +
                                ": cannot save the reviews: the mission is open read-only");
  }
  const std::string problem = schema::ReviewsProblem(mission);
  if (!problem.empty()) {
    return InvalidArgumentError(impl_->path() + ": cannot save the reviews: " + problem);
  }
  try {
    return schema::SaveReviews(impl_->db, mission);
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
