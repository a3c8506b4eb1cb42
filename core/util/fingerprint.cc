#include "core/util/fingerprint.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cinttypes>
#include <cstdio>
#include <cstring>
#include <vector>

namespace saker {
namespace {

constexpr uint64_t kFnvPrime = 0x100000001b3ull;
constexpr int64_t kFingerprintChunk = 1 << 20;

}  // namespace

uint64_t Fnv1a(const void* data, size_t size, uint64_t hash) {
  const auto* bytes = static_cast<const uint8_t*>(data);
  for (size_t i = 0; i < size; ++i) {
    hash ^= bytes[i];
    hash *= kFnvPrime;
  }
  return hash;
}

StatusOr<std::string> FingerprintFile(const std::string& path) {
  // O_NONBLOCK: opening a FIFO without a writer would wait for ever (it is refused below); a
  // regular file's reads are not affected.
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
  if (fd < 0) {
    const int err = errno;
    if (err == ENOENT || err == ENOTDIR) return NotFoundError(path + ": no such file");
    return IoError(path + ": cannot open: " + std::strerror(err));
  }
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{fd};
  struct stat st;
  if (::fstat(fd, &st) != 0) return IoError(path + ": cannot stat: " + std::strerror(errno));
  if (!S_ISREG(st.st_mode)) return IoError(path + ": not a regular file");
  const int64_t size = st.st_size;

  // The size, then the first, middle and last MiB (overlapping for files under 3 MiB).
  uint8_t size_bytes[8];
  for (int b = 0; b < 8; ++b)
    size_bytes[b] = static_cast<uint8_t>(static_cast<uint64_t>(size) >> (8 * b));
  uint64_t hash = Fnv1a(size_bytes, sizeof(size_bytes));
  const int64_t chunk = std::min(size, kFingerprintChunk);
  const int64_t offsets[3] = {0, (size - chunk) / 2, size - chunk};
  std::vector<uint8_t> buffer(static_cast<size_t>(chunk));
  for (const int64_t offset : offsets) {
    int64_t got = 0;
    while (got < chunk) {
      const ssize_t r = ::pread(fd, buffer.data() + got, static_cast<size_t>(chunk - got),
                                static_cast<off_t>(offset + got));
      if (r < 0 && errno == EINTR) continue;
      if (r < 0) return IoError(path + ": cannot read: " + std::strerror(errno));
      if (r == 0) return IoError(path + ": the file shrank while it was read");
      got += r;
    }
    hash = Fnv1a(buffer.data(), static_cast<size_t>(chunk), hash);
  }
  char digits[17];
  std::snprintf(digits, sizeof(digits), "%016" PRIx64, hash);
  return "v1:" + std::to_string(size) + ":" + digits;
}

}  // namespace saker
