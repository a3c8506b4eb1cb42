#include "core/util/durable_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <utility>

namespace saker {
namespace {

namespace fs = std::filesystem;

std::string ParentFolder(const std::string& path) {
  const fs::path parent = fs::path(path).parent_path();
  return parent.empty() ? "." : parent.string();
}

std::string TemporaryFor(const std::string& target) {
  static std::atomic<int64_t> counter{0};
  const fs::path path(target);
  const std::string name = "." + path.filename().string() + ".part-" + std::to_string(::getpid()) +
                           "-" + std::to_string(counter++) + path.extension().string();
  return (fs::path(ParentFolder(target)) / name).string();
}

// rename() that fails with EEXIST instead of replacing a file that appeared meanwhile.
int RenameNoReplace(const std::string& from, const std::string& to) {
#ifdef RENAME_NOREPLACE
  const int rc = ::renameat2(AT_FDCWD, from.c_str(), AT_FDCWD, to.c_str(), RENAME_NOREPLACE);
  if (rc == 0 || (errno != EINVAL && errno != ENOSYS && errno != EOPNOTSUPP)) return rc;
#endif
  // The file system cannot refuse atomically: check, then rename.
  struct stat st;
  if (::lstat(to.c_str(), &st) == 0) {
    errno = EEXIST;
    return -1;
  }
  return std::rename(from.c_str(), to.c_str());
}

Status SyncOne(const std::string& path, bool folder) {
  const int fd = ::open(path.c_str(), (folder ? O_RDONLY | O_DIRECTORY : O_RDONLY) | O_CLOEXEC);
  if (fd < 0) return IoError(path + ": cannot open to sync: " + std::strerror(errno));
  int rc;
  do {
    rc = ::fsync(fd);
  } while (rc != 0 && errno == EINTR);
  const int err = errno;
  ::close(fd);
  // Some file systems cannot sync a folder (EINVAL); the rename is then as durable as it gets.
  if (rc != 0 && !(folder && err == EINVAL)) {
    return IoError(path + ": fsync failed: " + std::strerror(err));
  }
  return Status::Ok();
}

}  // namespace

Status SyncPath(const std::string& path) {
  struct stat st;
  if (::stat(path.c_str(), &st) != 0) {
    return IoError(path + ": cannot open to sync: " + std::strerror(errno));
  }
  if (!S_ISDIR(st.st_mode)) return SyncOne(path, /*folder=*/false);
  // A folder built as a whole: its files first, then its entries.
  std::error_code error;
  for (fs::recursive_directory_iterator it(path, error), end; !error && it != end;
       it.increment(error)) {
    if (it->is_regular_file(error)) SAKER_RETURN_IF_ERROR(SyncOne(it->path().string(), false));
  }
  if (error) return IoError(path + ": cannot list to sync: " + error.message());
  return SyncOne(path, /*folder=*/true);
}

FileReplacement::FileReplacement(std::string target, ReplaceOptions options)
    : target_(std::move(target)), temporary_(TemporaryFor(target_)), options_(std::move(options)) {
  // The name is this process's and this call's alone: whatever is there is a dead process's.
  Discard();
  done_ = false;
}

FileReplacement::~FileReplacement() {
  if (!done_) Discard();
}

void FileReplacement::Discard() {
  std::error_code ignored;
  fs::remove_all(temporary_, ignored);
  for (const std::string& suffix : options_.side_suffixes) fs::remove(temporary_ + suffix, ignored);
  done_ = true;
}

Status FileReplacement::Commit() {
  SAKER_CHECK(!done_) << target_ << ": FileReplacement committed or discarded twice";
  Status status = SyncPath(temporary_);
  if (!status.ok()) {
    status = Status(status.code(), target_ + ": " + status.message());
  } else {
    const int rc = options_.overwrite ? std::rename(temporary_.c_str(), target_.c_str())
                                      : RenameNoReplace(temporary_, target_);
    if (rc != 0) {
      const int err = errno;
      status = err == EEXIST ? InvalidArgumentError(target_ + ": a file appeared there meanwhile")
                             : IoError(target_ + ": cannot move " + temporary_ +
                                       " into place: " + std::strerror(err));
    }
  }
  Discard();  // after a rename only the side files are left
  SAKER_RETURN_IF_ERROR(status);
  return SyncOne(ParentFolder(target_), /*folder=*/true);
}

Status ReplaceFile(const std::string& target, const PathWriter& write,
                   const ReplaceOptions& options) {
  FileReplacement replacement(target, options);
  SAKER_RETURN_IF_ERROR(write(replacement.temporary()));
  return replacement.Commit();
}

Status ReplaceFileFromStream(const std::string& target, const StreamWriter& write) {
  return ReplaceFile(target, [&](const std::string& temporary) -> Status {
    std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
    if (!out) return IoError(target + ": cannot create the file (" + std::strerror(errno) + ")");
    SAKER_RETURN_IF_ERROR(write(out));
    out.close();
    if (!out) return IoError(target + ": writing the file failed (" + std::strerror(errno) + ")");
    return Status::Ok();
  });
}

Status ReplaceFileContents(const std::string& target, std::string_view contents) {
  return ReplaceFileFromStream(target, [&](std::ostream& out) {
    out.write(contents.data(), static_cast<std::streamsize>(contents.size()));
    return Status::Ok();
  });
}

}  // namespace saker
