#include "core/util/durable_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string_view>
#include <utility>
#include <vector>

namespace saker {
namespace {

namespace fs = std::filesystem;

std::string ParentFolder(const std::string& path) {
  const fs::path parent = fs::path(path).parent_path();
  return parent.empty() ? "." : parent.string();
}

// The prefix of the names of the temporaries of `target`: ".<name>.part-".
std::string TemporaryPrefix(const std::string& target) {
  return "." + fs::path(target).filename().string() + ".part-";
}

std::string TemporaryFor(const std::string& target, const std::string& folder) {
  static std::atomic<int64_t> counter{0};
  const std::string name = TemporaryPrefix(target) + std::to_string(::getpid()) + "-" +
                           std::to_string(counter++) + fs::path(target).extension().string();
  return (fs::path(folder) / name).string();
}

// The descriptor a name stands for, as the shell reads it in a redirection: "-" and /dev/stdout
// are 1, /dev/stderr 2, /dev/fd/N and /proc/self/fd/N are N; -1 for any other name.
int DescriptorNamed(const std::string& target) {
  if (target == "-" || target == "/dev/stdout") return STDOUT_FILENO;
  if (target == "/dev/stderr") return STDERR_FILENO;
  for (const std::string_view prefix : {"/dev/fd/", "/proc/self/fd/"}) {
    if (target.size() <= prefix.size() || target.compare(0, prefix.size(), prefix) != 0) continue;
    const std::string number = target.substr(prefix.size());
    if (number.size() > 6 || number.find_first_not_of("0123456789") != std::string::npos) return -1;
    return std::stoi(number);
  }
  return -1;
}

// Writes all of `size` bytes, through short writes and interruptions.
bool WriteAll(int fd, const char* data, size_t size) {
  while (size > 0) {
    const ssize_t n = ::write(fd, data, size);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    data += n;
    size -= static_cast<size_t>(n);
  }
  return true;
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

Status CheckNotAnInput(const std::string& output, const std::vector<std::string>& inputs) {
  struct stat out;
  if (output == "-" || ::stat(output.c_str(), &out) != 0) return Status::Ok();
  for (const std::string& input : inputs) {
    struct stat in;
    if (input.empty() || ::stat(input.c_str(), &in) != 0) continue;
    if (in.st_dev != out.st_dev || in.st_ino != out.st_ino) continue;
    return InvalidArgumentError(
        output + ": is " + (input == output ? "" : "the same file as " + input + ", ") +
        "an input of this job: writing there would destroy it; choose another file");
  }
  return Status::Ok();
}

void RemoveStaleTemporaries(const std::string& target) {
  const std::string prefix = TemporaryPrefix(target);
  std::error_code error;
  for (fs::directory_iterator it(ParentFolder(target), error), end; !error && it != end;
       it.increment(error)) {
    const std::string file = it->path().filename().string();
    if (file.compare(0, prefix.size(), prefix) != 0) continue;
    const std::string rest = file.substr(prefix.size());
    const size_t digits = rest.find_first_not_of("0123456789");
    if (digits == 0 || digits == std::string::npos || rest[digits] != '-') continue;
    const long pid = std::strtol(rest.substr(0, digits).c_str(), nullptr, 10);
    // Only a dead process's: a live one (this process or another) may be writing it now.
    if (pid <= 0 || ::kill(static_cast<pid_t>(pid), 0) == 0 || errno != ESRCH) continue;
    std::error_code ignored;
    fs::remove_all(it->path(), ignored);
  }
}

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
    : target_(std::move(target)), place_(target_), options_(std::move(options)) {
  descriptor_ = DescriptorNamed(target_);
  struct stat st;
  if (descriptor_ >= 0) {
    not_a_file_ = true;
  } else if (::stat(target_.c_str(), &st) == 0) {
    not_a_file_ = !S_ISREG(st.st_mode) && !S_ISDIR(st.st_mode);
    std::error_code error;
    if (S_ISREG(st.st_mode) && fs::is_symlink(target_, error)) {
      const fs::path resolved = fs::canonical(target_, error);
      if (!error) place_ = resolved.string();  // replace the file, keep the link
    }
  }
  // The content is built beside the file it replaces, or in the temporary folder.
  std::string built_for = place_;
  if (not_a_file_) {
    std::error_code error;
    fs::path folder = fs::temp_directory_path(error);
    if (error) folder = "/tmp";
    built_for =
        (folder / (target_ == "-" ? fs::path("stdout") : fs::path(target_).filename())).string();
  }
  RemoveStaleTemporaries(built_for);
  temporary_ = TemporaryFor(built_for, ParentFolder(built_for));
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

std::string FileReplacement::Reason(const Status& status) const {
  std::string message = status.message();
  if (message.rfind(temporary_ + ": ", 0) == 0) message.erase(0, temporary_.size() + 2);
  for (size_t at = message.find(temporary_); at != std::string::npos;
       at = message.find(temporary_, at + target_.size())) {
    message.replace(at, temporary_.size(), target_);
  }
  return message;
}

Status FileReplacement::CopyIntoTarget() const {
  struct stat st;
  if (descriptor_ < 0 && ::stat(target_.c_str(), &st) == 0 && !S_ISCHR(st.st_mode) &&
      !S_ISFIFO(st.st_mode)) {
    return InvalidArgumentError(target_ + ": is " +
                                (S_ISBLK(st.st_mode)    ? "a block device"
                                 : S_ISSOCK(st.st_mode) ? "a socket"
                                                        : "not a file") +
                                "; Saker writes to files, character devices, FIFOs and \"-\" "
                                "(standard output)");
  }
  if (!options_.overwrite) return InvalidArgumentError(target_ + ": something is already there");
  std::ifstream in(temporary_, std::ios::binary);
  if (!in) return IoError(target_ + ": the content to write is missing (" + temporary_ + ")");
  const int fd = descriptor_ >= 0 ? descriptor_ : ::open(target_.c_str(), O_WRONLY | O_CLOEXEC);
  if (fd < 0) return IoError(target_ + ": cannot open to write: " + std::strerror(errno));
  std::vector<char> buffer(1 << 16);
  bool written = true;
  while (written && in) {
    in.read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
    written = WriteAll(fd, buffer.data(), static_cast<size_t>(in.gcount()));
  }
  const int err = errno;
  if (descriptor_ < 0) ::close(fd);
  if (!written) return IoError(target_ + ": writing failed: " + std::strerror(err));
  if (in.bad()) return IoError(target_ + ": reading back " + temporary_ + " failed");
  return Status::Ok();
}

Status FileReplacement::Commit() {
  SAKER_CHECK(!done_) << target_ << ": FileReplacement committed or discarded twice";
  if (not_a_file_) {
    const Status copied = CopyIntoTarget();
    Discard();
    return copied;
  }
  Status status = SyncPath(temporary_);
  if (!status.ok()) {
    status = Status(status.code(), target_ + ": " + status.message());
  } else {
    const int rc = options_.overwrite ? std::rename(temporary_.c_str(), place_.c_str())
                                      : RenameNoReplace(temporary_, place_);
    if (rc != 0) {
      const int err = errno;
      status =
          err == EEXIST
              ? InvalidArgumentError(target_ + ": a file appeared there meanwhile")
              : IoError(target_ + ": cannot move the new file into place: " + std::strerror(err));
    }
  }
  Discard();  // after a rename only the side files are left
  SAKER_RETURN_IF_ERROR(status);
  return SyncOne(ParentFolder(place_), /*folder=*/true);
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
