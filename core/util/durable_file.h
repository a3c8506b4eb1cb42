#pragma once

// Replacing a file so that a crash, a kill or a full disk at any moment leaves either the old file
// or the complete new one, never a torn one (QGIS issue 39372 is what happens otherwise): the new
// content is written to a temporary beside the target, flushed to the disk (fsync), renamed over
// the target, and the folder is flushed so the rename itself survives a power loss. Any failure
// removes the temporary and leaves the target as it was.
//
// Writers that need a path (SQLite, GDAL, cv::imwrite, FFmpeg) write to temporary(); text and
// JSON go through a stream (ReplaceFileFromStream) or a string (ReplaceFileContents).
//
// Targets that are not files are never renamed over: "-" (standard output), "/dev/stdout",
// "/dev/stderr" and "/dev/fd/N" ("/proc/self/fd/N") name this process's open descriptor, which gets
// the bytes; a character device or a FIFO (or a link to one) is opened and written; a block device
// or a socket is refused. The content is still built in a temporary first (in the system's
// temporary folder), so a writer that needs a path or fails half-way sends nothing. A regular file
// reached through a symbolic link is replaced where the link points, and the link is kept.

#include "core/util/status.h"

#include <functional>
#include <iosfwd>
#include <string>
#include <string_view>
#include <vector>

namespace saker {

// How a FileReplacement puts its file in place.
struct ReplaceOptions {
  // Whether a file already at the target is replaced. false (for a caller that checked the target
  // was free): the commit fails with InvalidArgument if something appeared there meanwhile,
  // decided atomically where the file system can (renameat2 RENAME_NOREPLACE).
  bool overwrite = true;
  // Suffixes of side files a writer may leave beside the temporary (SQLite's "-wal", GDAL's
  // ".aux.xml"): removed with the temporary, and after a commit, since they do not move with it.
  std::vector<std::string> side_suffixes = {};
};

// One replacement of `target`. The temporary is named after the target, hidden and unique to this
// process and call: "<folder>/.<name>.part-<pid>-<n><extension>" (the target's extension last, for
// writers that choose the format by it), in the target's folder, or in the system's temporary
// folder for a target that is not a file. Nothing exists there until the writer creates it; a file
// or folder of the same name (left by a dead process with the same id) is removed first.
// The temporary may also be a folder the writer fills (its files are flushed with it).
class FileReplacement {
 public:
  explicit FileReplacement(std::string target, ReplaceOptions options = {});
  FileReplacement(const FileReplacement&) = delete;
  FileReplacement& operator=(const FileReplacement&) = delete;
  // Discards the temporary unless committed.
  ~FileReplacement();

  const std::string& target() const { return target_; }
  const std::string& temporary() const { return temporary_; }

  // Flushes the temporary to the disk, renames it over the target and flushes the folder. Errors
  // name the target; on any failure the temporary is removed and the target is left as it was.
  // Call once.
  Status Commit();
  // Removes the temporary and its side files now (best effort; also done by the destructor).
  void Discard();
  // The message of a writer's error in terms of the target: without a leading "<temporary>: ",
  // the hidden temporary's name nowhere (a person knows only the target's).
  std::string Reason(const Status& status) const;

 private:
  // Copies the temporary's bytes into the target that is no regular file (a device, a FIFO, an
  // open descriptor).
  Status CopyIntoTarget() const;

  std::string target_;
  std::string place_;        // the file renamed over: the target, or where its link points
  int descriptor_ = -1;      // ">= 0": the target names this open descriptor of the process
  bool not_a_file_ = false;  // the target is a device, FIFO or descriptor: written, not replaced
  std::string temporary_;
  ReplaceOptions options_;
  bool done_ = false;
};

// Writes the content of `target`: `write` gets the temporary path and creates the file there.
using PathWriter = std::function<Status(const std::string& temporary)>;
// Streams the content of the file; the stream's state is checked after it returns.
using StreamWriter = std::function<Status(std::ostream& out)>;

// `write(temporary)`, then FileReplacement::Commit. A failure of `write` is returned as it is
// (it should name the target), and the temporary is removed.
Status ReplaceFile(const std::string& target, const PathWriter& write,
                   const ReplaceOptions& options = {});
// ReplaceFile through a binary std::ofstream; a stream that cannot be opened or written is an
// IoError naming the target.
Status ReplaceFileFromStream(const std::string& target, const StreamWriter& write);
// ReplaceFileFromStream writing `contents`.
Status ReplaceFileContents(const std::string& target, std::string_view contents);

// Refuses `output` when it is one of the files the job reads (`inputs`): the same file by device
// and inode, whatever the names (a hard link, another path, a link to it), so a job never writes
// over its own input. Inputs that do not exist are skipped; an output that does not exist yet is
// none of them. The error (InvalidArgument) names the output and the input.
Status CheckNotAnInput(const std::string& output, const std::vector<std::string>& inputs);

// Removes the temporaries that dead processes left for `target` (a FileReplacement's
// ".<name>.part-<pid>-<n>...", of a process that no longer exists; a live one's may be in use): a
// job killed outright (SIGKILL, power cut) cannot remove its own. Best effort; every
// FileReplacement does it for its target.
void RemoveStaleTemporaries(const std::string& target);

// Makes sure the data of the file (or the entries of the folder) at `path` reach the disk.
// File systems that cannot sync a folder (EINVAL) count as success.
Status SyncPath(const std::string& path);

}  // namespace saker
