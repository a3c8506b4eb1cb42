#include "core/video/mpegts_pmt.h"

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <set>
#include <vector>

namespace saker::video {
namespace {

constexpr size_t kTsPacketSize = 188;
constexpr uint8_t kSyncByte = 0x47;
constexpr int kPatPid = 0x0000;
constexpr uint8_t kPatTableId = 0x00;
constexpr uint8_t kPmtTableId = 0x02;

// CRC-32/MPEG-2 (polynomial 0x04C11DB7, no reflection); a section with its CRC appended sums to 0.
uint32_t Crc32Mpeg2(const uint8_t* p, size_t n) {
  uint32_t crc = 0xFFFFFFFFu;
  for (size_t i = 0; i < n; ++i) {
    crc ^= static_cast<uint32_t>(p[i]) << 24;
    for (int bit = 0; bit < 8; ++bit) {
      crc = (crc & 0x80000000u) ? (crc << 1) ^ 0x04C11DB7u : (crc << 1);
    }
  }
  return crc;
}

// Finds the packet stride (188 plain, 192 M2TS with a 4-byte prefix, 204 with FEC) and the offset
// of the first sync byte, by requiring several sync bytes in a row. False when none fits.
bool DetectPacketLayout(const uint8_t* data, size_t size, size_t* stride, size_t* offset) {
  constexpr std::array<size_t, 3> kStrides = {188, 192, 204};
  constexpr int kRun = 5;
  for (size_t candidate : kStrides) {
    for (size_t start = 0; start < candidate && start < size; ++start) {
      int run = 0;
      for (size_t pos = start; pos < size && run < kRun; pos += candidate, ++run) {
        if (data[pos] != kSyncByte) break;
      }
      // Short inputs: accept as many packets as there are, at least two.
      const size_t available = (size - start + candidate - 1) / candidate;
      if (run == kRun || (run >= 2 && static_cast<size_t>(run) == available)) {
        *stride = candidate;
        *offset = start;
        return true;
      }
    }
  }
  return false;
}

class PmtScanner {
 public:
  void AddPacket(const uint8_t* p) {
    if (p[0] != kSyncByte || (p[1] & 0x80)) return;  // lost sync or transport error
    const int pid = ((p[1] & 0x1F) << 8) | p[2];
    if (pid != kPatPid && pmt_pids_.count(pid) == 0) return;
    const bool unit_start = (p[1] & 0x40) != 0;
    const int adaptation = (p[3] >> 4) & 0x3;
    if ((adaptation & 0x1) == 0) return;  // no payload
    size_t start = 4;
    if (adaptation & 0x2) start += 1 + p[4];
    if (start >= kTsPacketSize) return;
    const uint8_t* payload = p + start;
    size_t length = kTsPacketSize - start;
    std::vector<uint8_t>& buffer = sections_[pid];
    if (unit_start) {
      const size_t pointer = payload[0];
      if (1 + pointer > length) return;
      // Bytes before the pointer finish the section begun in earlier packets.
      if (!buffer.empty()) {
        buffer.insert(buffer.end(), payload + 1, payload + 1 + pointer);
        Drain(pid, &buffer);
      }
      buffer.assign(payload + 1 + pointer, payload + length);
      Drain(pid, &buffer);
    } else if (!buffer.empty()) {
      buffer.insert(buffer.end(), payload, payload + length);
      Drain(pid, &buffer);
    }
  }

  bool Done() const { return pat_seen_ && pmts_done_.size() == pmt_pids_.size(); }
  const std::map<int, int>& stream_types() const { return stream_types_; }

 private:
  // Consumes every complete section at the front of `buffer`.
  void Drain(int pid, std::vector<uint8_t>* buffer) {
    while (buffer->size() >= 3) {
      if ((*buffer)[0] == 0xFF) {  // stuffing: nothing more in this packet
        buffer->clear();
        return;
      }
      const size_t total = 3 + ((((*buffer)[1] & 0x0F) << 8) | (*buffer)[2]);
      if (buffer->size() < total) return;  // wait for the next packet
      HandleSection(pid, buffer->data(), total);
      buffer->erase(buffer->begin(), buffer->begin() + static_cast<std::ptrdiff_t>(total));
    }
  }

  void HandleSection(int pid, const uint8_t* s, size_t n) {
    // Long-form sections only: header 8 bytes, CRC 4 bytes, current (not next) version.
    if (n < 12 || (s[1] & 0x80) == 0 || (s[5] & 0x01) == 0) return;
    if (Crc32Mpeg2(s, n) != 0) return;
    const size_t end = n - 4;
    if (pid == kPatPid && s[0] == kPatTableId) {
      pat_seen_ = true;
      for (size_t i = 8; i + 4 <= end; i += 4) {
        const int program = (s[i] << 8) | s[i + 1];
        const int program_pid = ((s[i + 2] & 0x1F) << 8) | s[i + 3];
        if (program != 0) pmt_pids_.insert(program_pid);  // program 0 names the network PID
      }
    } else if (pid != kPatPid && s[0] == kPmtTableId) {
      const size_t program_info_length = ((s[10] & 0x0F) << 8) | s[11];
      for (size_t i = 12 + program_info_length; i + 5 <= end;) {
        const int stream_type = s[i];
        const int es_pid = ((s[i + 1] & 0x1F) << 8) | s[i + 2];
        const size_t es_info_length = ((s[i + 3] & 0x0F) << 8) | s[i + 4];
        stream_types_[es_pid] = stream_type;
        i += 5 + es_info_length;
      }
      pmts_done_.insert(pid);
    }
  }

  std::set<int> pmt_pids_;
  std::set<int> pmts_done_;
  bool pat_seen_ = false;
  std::map<int, std::vector<uint8_t>> sections_;
  std::map<int, int> stream_types_;
};

std::map<int, int> Scan(const uint8_t* data, size_t size, bool* complete) {
  *complete = false;
  size_t stride = 0;
  size_t offset = 0;
  if (data == nullptr || !DetectPacketLayout(data, size, &stride, &offset)) return {};
  PmtScanner scanner;
  for (size_t pos = offset; pos + kTsPacketSize <= size && !scanner.Done(); pos += stride) {
    scanner.AddPacket(data + pos);
  }
  *complete = scanner.Done();
  return scanner.stream_types();
}

}  // namespace

std::map<int, int> ScanPmtStreamTypes(const uint8_t* data, size_t size) {
  bool complete = false;
  return Scan(data, size, &complete);
}

StatusOr<std::map<int, int>> ScanPmtStreamTypesInFile(const std::string& path, size_t max_bytes) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    const int err = errno;
    if (err == ENOENT) return NotFoundError(path + ": no such file");
    return IoError(path + ": cannot open: " + std::strerror(err));
  }
  // Tables repeat every 100 ms or so: the first read almost always suffices.
  std::vector<uint8_t> bytes;
  std::map<int, int> types;
  for (size_t want = std::min<size_t>(max_bytes, 256 << 10);;
       want = std::min(max_bytes, want * 4)) {
    const size_t have = bytes.size();
    bytes.resize(want);
    in.read(reinterpret_cast<char*>(bytes.data() + have),
            static_cast<std::streamsize>(want - have));
    bytes.resize(have + static_cast<size_t>(in.gcount()));
    if (in.bad()) return IoError(path + ": read error");
    bool complete = false;
    types = Scan(bytes.data(), bytes.size(), &complete);
    if (complete || !in || bytes.size() >= max_bytes) break;
  }
  return types;
}

}  // namespace saker::video
