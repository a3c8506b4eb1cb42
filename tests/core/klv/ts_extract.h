#pragma once

// A minimal MPEG-2 transport stream reader for the KLV tests: just enough to
// pull the metadata PES payloads out of the sample files, so the KLV tests do
// not depend on the video reader. Not for production use: it assumes
// PAT/PMT sections fit in one TS packet and ignores continuity counters.

#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace saker::klv::testing {

// One elementary stream declared in the PMT.
struct TsStream {
  uint16_t pid = 0;
  uint8_t stream_type = 0;  // 0x06 private PES (asynchronous KLV), 0x15 metadata in PES
  // Access units, in file order: one PES payload each for stream_type 0x06;
  // for 0x15, each Metadata Access Unit cell of the PES payload with its
  // 5-byte header (service id, sequence, flags, cell_data_length) removed.
  std::vector<std::vector<uint8_t>> units;
};

// The program's streams in PMT order (so the index of a stream matches
// FFmpeg's stream index). PES payloads are collected for the data streams
// (stream_type 0x06 and 0x15) only; video streams are listed with no units.
// On malformed input returns what it has and sets *error.
std::vector<TsStream> ExtractTsStreams(std::span<const uint8_t> ts, std::string* error);

}  // namespace saker::klv::testing
