#pragma once

// The mission file (`.saker`): an SQLite database with a versioned schema of plain relational
// tables, so a viewer, the command-line tool or a Python script can read what a processing job
// wrote. Every write is one transaction and the file runs in WAL mode, so a crash or kill -9 at any
// moment leaves the last committed state, and a viewer reads while a worker writes. The schema,
// blob layouts and error behaviour are described in docs/mission-file.md.
//
// A MissionStore is one SQLite connection: use it from one thread at a time (open a second store
// for a second thread or process).

#include "core/mission/mission.h"
#include "core/util/fingerprint.h"
#include "core/util/status.h"

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace saker::mission {

// The `application_id` of every Saker mission file ('SAKR'); with the `meta` table's
// schema_version it tells a mission from any other SQLite database.
inline constexpr int32_t kMissionApplicationId = 0x53414B52;

enum class OpenMode {
  // Viewers: never writes, sees what a job writing meanwhile commits. A mission on read-only
  // storage (or one the user may not write) opens too, as a snapshot, unless it holds the
  // write-ahead log of an interrupted job.
  kReadOnly,
  // A one-off read (info, export, copy): as kReadOnly, but a mission no job is writing is opened
  // as an immutable snapshot, so no -wal / -shm files are left beside it. A job that starts
  // writing the same mission in place during the read may make the read fail.
  kSnapshot,
  // The processing job: the mission's one writer, holding its lock (`<mission>.lock`) while
  // open; a second writer is refused, naming the process that writes.
  kReadWrite,
};

// The parts of a mission that Save writes. The header (schema version, saker_version, source,
// options_json, map, pyramid info, progress) is always written; the parts not named keep what
// the file held.
enum SavePart : unsigned {
  kSaveFrames = 1u,  // Mission::frames
  kSaveGraph = 2u,   // Mission::key_frames and Mission::links
  kSaveTracks = 4u,  // Mission::tracks with their points
  kSaveAll = 7u,     // what processing writes
  // Mission::reviews and Mission::bookmarks, the analyst's: never part of kSaveAll, so that a
  // job's saves keep them (SaveReviews writes them alone; a copy names them).
  kSaveReviews = 8u,
};

// One encoded tile of the mosaic pyramid (PyramidInfo gives the geometry).
struct EncodedTile {
  int level = 0;               // 0 = full resolution, >= 0
  int x = 0;                   // column of the tile in its level, >= 0
  int y = 0;                   // row, >= 0
  std::vector<uint8_t> bytes;  // PNG or JPEG; opaque to the store
};

// One record of a processing checkpoint: opaque bytes under (kind, key), which the processing
// pipeline defines (pipeline/checkpoint.h).
struct CheckpointRecord {
  std::string kind;
  int64_t key = 0;
  std::vector<uint8_t> bytes;
};

// An open mission file. Errors are returned as Status naming the file (and, for bad content,
// the table); nothing throws across this interface.
class MissionStore {
 public:
  // Creates a new mission file at `path` holding an empty mission of schema kSchemaVersion, open
  // for reading and writing. If a file exists there, it is refused (InvalidArgument) unless
  // `replace` is true AND that file is a Saker mission this version can read: a foreign, corrupt
  // or newer-version file is never overwritten (its Open error is returned). The new file is
  // built beside the target and renamed over it, so a crash leaves either the old or the new file.
  // The writer's lock is taken before anything is replaced: a mission that another job writes
  // (kReadWrite, Create) is refused with IoError naming its process; replacing one that another
  // program holds a transaction on fails with IoError too. A path SQLite cannot open (too long,
  // or a name too long for the temporary built beside it) is refused up front (InvalidArgument
  // naming the limit).
  static StatusOr<std::unique_ptr<MissionStore>> Create(const std::string& path,
                                                        bool replace = false);
  // To be called just before a file built elsewhere is renamed over `path`: if a mission is
  // there, folds its write-ahead log into it (opening it for writing: it must be a mission this
  // version reads), so that no log is left to be replayed onto the new file; if nothing is there,
  // removes any orphaned log, shared-memory or journal file of a deleted mission. Create does this
  // itself; pipeline::CopyMission calls it. IoError when a job writes the mission.
  static Status FoldLog(const std::string& path);
  // Removes the temporary files that jobs killed while building a file for `path` left beside
  // it (Create's and CopyMission's, named after their process: only those of processes that no
  // longer exist). Best effort; Create does this itself; CopyMission calls it.
  static void RemoveStaleTemporaries(const std::string& path);

  // Opens an existing mission. NotFound when missing; InvalidData for a zero-byte, truncated,
  // corrupt or non-SQLite file or an SQLite database that is not a Saker mission; Unsupported for
  // a newer schema version. A file that is refused is never written. Read-only stores work while
  // another process writes. kReadWrite takes the writer's lock: IoError naming the process when
  // another job writes the mission. InvalidArgument naming the limit for a path SQLite cannot
  // open (too long).
  static StatusOr<std::unique_ptr<MissionStore>> Open(const std::string& path,
                                                      OpenMode mode = OpenMode::kReadOnly);

  MissionStore(const MissionStore&) = delete;
  MissionStore& operator=(const MissionStore&) = delete;
  ~MissionStore();

  // The path the store was opened with.
  const std::string& path() const;
  OpenMode mode() const;
  // Whether a job could write the file (false on read-only storage, or for a file or folder the
  // user may not write): a viewer says "read-only".
  static bool IsWritable(const std::string& path);

  // One transaction: writes the header and replaces the parts named by `parts` (SavePart bits).
  // InvalidArgument on a read-only store, for unknown part bits, or for a mission the file cannot
  // represent (duplicate frame indices, a map origin that is not set exactly when geo-referenced,
  // an unknown link kind); nothing is written then. A crash at any moment leaves the last
  // committed state readable.
  Status Save(const Mission& mission, unsigned parts = kSaveAll);
  // Replaces the analyst's reviews and bookmarks (Mission::reviews, Mission::bookmarks) and
  // nothing else, in one transaction: what the workstation writes when the analyst judges a
  // track. InvalidArgument for reviews out of order or repeated, unknown values, a note longer
  // than kMaxNoteBytes, a bookmark whose time or place is not finite.
  Status SaveReviews(const Mission& mission);
  // The whole mission except the tile images, read in one transaction (so never half of a
  // concurrent Save). Frames come back sorted by index, everything else in saved order.
  // InvalidData naming the file and the table when the content is inconsistent (a blob of the
  // wrong size, a value of the wrong type, an unknown link kind, a missing row).
  StatusOr<Mission> Load() const;

  // The checkpoint of an unfinished processing job, so that it can resume (docs/reliability.md).
  // WriteCheckpoint, in one transaction, first removes every record of the kinds in
  // `replace_kinds`, then inserts `records`, replacing those with the same (kind, key).
  // InvalidArgument on a read-only store.
  Status WriteCheckpoint(const std::vector<CheckpointRecord>& records,
                         const std::vector<std::string>& replace_kinds = {});
  // Every record, sorted by kind and key, read in one transaction (empty for a file of schema
  // version 2 or older).
  StatusOr<std::vector<CheckpointRecord>> ReadCheckpoint() const;
  // Removes every record (a job that completed) and gives the space back where the file allows.
  Status ClearCheckpoint();

  // Stores tiles of the mosaic pyramid in one transaction, replacing tiles with the same
  // (level, x, y). InvalidArgument on a read-only store or for a negative level or position.
  Status WriteTiles(const std::vector<EncodedTile>& tiles);
  // Removes every tile, in one transaction.
  Status ClearTiles();
  // The bytes of one tile, or std::nullopt when the file has no such tile.
  StatusOr<std::optional<std::vector<uint8_t>>> ReadTile(int level, int x, int y) const;
  // How many tiles the file holds.
  StatusOr<int64_t> CountTiles() const;

 private:
  struct Impl;
  explicit MissionStore(std::unique_ptr<Impl> impl);
  // Open's work, for an `impl` whose mode (and, for writing, lock) is set.
  static StatusOr<std::unique_ptr<MissionStore>> OpenImpl(const std::string& path,
                                                          std::unique_ptr<Impl> impl);
  // FoldLog's work, by the holder of the mission's lock.
  // `locked` holds the lock, and holds it again on return.
  static Status FoldLogLocked(const std::string& path, Impl* locked);

  std::unique_ptr<Impl> impl_;
};

// The video fingerprint (core/util/fingerprint.h), also under this namespace so that callers of
// mission::FingerprintFile keep compiling.
using ::saker::FingerprintFile;

}  // namespace saker::mission
