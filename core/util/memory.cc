#include "core/util/memory.h"

#include <unistd.h>

#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>

namespace saker {
namespace {

// The value of a "Name:   1234 kB" line of a /proc file, in bytes; 0 when absent.
int64_t ProcKilobytes(const char* file, const char* name) {
  std::ifstream in(file);
  std::string line;
  const size_t length = std::strlen(name);
  while (std::getline(in, line)) {
    if (line.compare(0, length, name) != 0 || line.size() <= length || line[length] != ':')
      continue;
    long long kilobytes = 0;
    if (std::sscanf(line.c_str() + length + 1, "%lld", &kilobytes) != 1 || kilobytes < 0) return 0;
    return static_cast<int64_t>(kilobytes) * 1024;
  }
  return 0;
}

}  // namespace

int64_t ResidentMemoryBytes() {
  // statm is one short line, cheaper than status: the front end asks every few frames.
  std::FILE* file = std::fopen("/proc/self/statm", "r");
  if (file == nullptr) return 0;
  long long size = 0, resident = 0;
  const int read = std::fscanf(file, "%lld %lld", &size, &resident);
  std::fclose(file);
  const long page = sysconf(_SC_PAGESIZE);
  if (read != 2 || resident < 0 || page <= 0) return 0;
  return static_cast<int64_t>(resident) * page;
}

int64_t PeakResidentMemoryBytes() { return ProcKilobytes("/proc/self/status", "VmHWM"); }

int64_t PhysicalMemoryBytes() { return ProcKilobytes("/proc/meminfo", "MemTotal"); }

int64_t DefaultMemoryLimitMiB() { return PhysicalMemoryBytes() / 4 * 3 / (1024 * 1024); }

}  // namespace saker
