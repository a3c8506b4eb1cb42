#pragma once

// Replacing a file so that a crash, a kill or a full disk at any moment leaves either the old file
// or the complete new one, never a torn one (QGIS issue 39372 is what happens otherwise): the new
// content is written to a temporary beside the target, flushed to the disk (fsync), renamed over
// the target, and the folder is flushed so the rename itself survives a power loss. Any failure
// removes the temporary and leaves the target as it was.
//
// Writers that need a path (SQLite, GDAL, cv::imwrite, FFmpeg) write to temporary(); text and
// JSON go through a stream (ReplaceFileFromStream) or a string (ReplaceFileContents).

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
// writers that choose the format by it). Nothing exists there until the writer creates it; a file
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

 private:
  std::string target_;
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

// Makes sure the data of the file (or the entries of the folder) at `path` reach the disk.
// File systems that cannot sync a folder (EINVAL) count as success.
Status SyncPath(const std::string& path);

}  // namespace saker
