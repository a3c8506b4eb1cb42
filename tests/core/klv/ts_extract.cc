#include "tests/core/klv/ts_extract.h"

#include <algorithm>
#include <map>
#include <optional>

namespace saker::klv::testing {

namespace {

constexpr size_t kTsPacketSize = 188;
constexpr uint8_t kStreamTypePrivatePes = 0x06;
constexpr uint8_t kStreamTypeMetadataPes = 0x15;

bool IsDataStream(uint8_t stream_type) {
  return stream_type == kStreamTypePrivatePes || stream_type == kStreamTypeMetadataPes;
}

// The section that starts in `payload` (after the pointer field), or empty.
std::span<const uint8_t> SectionOf(std::span<const uint8_t> payload) {
  if (payload.empty()) return {};
  const size_t pointer = payload[0];
  if (payload.size() < 1 + pointer + 3) return {};
  auto section = payload.subspan(1 + pointer);
  const size_t length = ((section[1] & 0x0F) << 8) | section[2];
  if (section.size() < 3 + length) return {};
  return section.first(3 + length);
}

// Appends the access units of one complete PES packet.
void FinishPes(const std::vector<uint8_t>& pes, TsStream* stream, std::string* error) {
  if (pes.size() < 9 || pes[0] != 0 || pes[1] != 0 || pes[2] != 1) {
    *error = "PID " + std::to_string(stream->pid) + ": PES without start code";
    return;
  }
  const size_t declared = (static_cast<size_t>(pes[4]) << 8) | pes[5];
  const size_t end = declared == 0 ? pes.size() : std::min(pes.size(), 6 + declared);
  const size_t start = 9 + pes[8];
  if (start > end) {
    *error = "PID " + std::to_string(stream->pid) + ": PES header longer than the packet";
    return;
  }
  std::span<const uint8_t> payload(pes.data() + start, end - start);
  if (stream->stream_type != kStreamTypeMetadataPes) {
    stream->units.emplace_back(payload.begin(), payload.end());
    return;
  }
  // ISO/IEC 13818-1 metadata access units: a 5-byte header, then the cell.
  while (payload.size() >= 5) {
    const size_t cell = (static_cast<size_t>(payload[3]) << 8) | payload[4];
    const size_t take = std::min(cell, payload.size() - 5);
    stream->units.emplace_back(payload.begin() + 5, payload.begin() + 5 + take);
    payload = payload.subspan(5 + take);
  }
}

}  // namespace

std::vector<TsStream> ExtractTsStreams(std::span<const uint8_t> ts, std::string* error) {
  std::vector<TsStream> streams;
  std::optional<uint16_t> pmt_pid;
  std::map<uint16_t, std::vector<uint8_t>> pending;  // PES being reassembled, by PID
  auto stream_of = [&streams](uint16_t pid) -> TsStream* {
    for (auto& s : streams) {
      if (s.pid == pid) return &s;
    }
    return nullptr;
  };

  for (size_t offset = 0; offset + kTsPacketSize <= ts.size(); offset += kTsPacketSize) {
    auto packet = ts.subspan(offset, kTsPacketSize);
    if (packet[0] != 0x47) {
      *error = "lost TS sync at offset " + std::to_string(offset);
      break;
    }
    const bool unit_start = (packet[1] & 0x40) != 0;
    const uint16_t pid = static_cast<uint16_t>(((packet[1] & 0x1F) << 8) | packet[2]);
    const int adaptation = (packet[3] >> 4) & 0x03;
    size_t header = 4;
    if (adaptation & 0x02) header += 1 + packet[4];
    if ((adaptation & 0x01) == 0 || header >= kTsPacketSize) continue;
    auto payload = packet.subspan(header);

    if (pid == 0 && unit_start && !pmt_pid) {
      auto section = SectionOf(payload);
      // Program loop: 8-byte header, 4-byte entries, 4-byte CRC.
      for (size_t i = 8; i + 4 <= section.size() && i + 4 <= section.size() - 4; i += 4) {
        const uint16_t program = static_cast<uint16_t>((section[i] << 8) | section[i + 1]);
        if (program != 0) {
          pmt_pid = static_cast<uint16_t>(((section[i + 2] & 0x1F) << 8) | section[i + 3]);
          break;
        }
      }
      continue;
    }
    if (pmt_pid && pid == *pmt_pid && unit_start && streams.empty()) {
      auto section = SectionOf(payload);
      if (section.size() < 12 + 4) continue;
      const size_t info_length = ((section[10] & 0x0F) << 8) | section[11];
      size_t i = 12 + info_length;
      while (i + 5 <= section.size() - 4) {
        TsStream stream;
        stream.stream_type = section[i];
        stream.pid = static_cast<uint16_t>(((section[i + 1] & 0x1F) << 8) | section[i + 2]);
        const size_t es_info = ((section[i + 3] & 0x0F) << 8) | section[i + 4];
        streams.push_back(stream);
        i += 5 + es_info;
      }
      continue;
    }
    TsStream* stream = stream_of(pid);
    if (stream == nullptr || !IsDataStream(stream->stream_type)) continue;
    if (unit_start) {
      if (auto it = pending.find(pid); it != pending.end()) {
        FinishPes(it->second, stream, error);
        pending.erase(it);
      }
      pending[pid].assign(payload.begin(), payload.end());
    } else if (auto it = pending.find(pid); it != pending.end()) {
      it->second.insert(it->second.end(), payload.begin(), payload.end());
    }
  }
  for (const auto& [pid, pes] : pending) FinishPes(pes, stream_of(pid), error);
  return streams;
}

}  // namespace saker::klv::testing
