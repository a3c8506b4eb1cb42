#pragma once

// A small reader of MPEG-TS program map tables. FFmpeg 5.1 does not tell a synchronous KLV
// stream (stream_type 0x15, MISB ST 1402) from an asynchronous one (0x06): both come out as
// AV_CODEC_ID_SMPTE_KLV with profile FF_PROFILE_UNKNOWN. The PMT does, so VideoReader reads the
// first PMTs of a local transport stream itself. Plain bytes in, no FFmpeg.

#include "core/util/status.h"

#include <cstddef>
#include <cstdint>
#include <map>
#include <string>

namespace saker::video {

inline constexpr int kStreamTypePrivatePes = 0x06;  // asynchronous KLV (registration "KLVA")
inline constexpr int kStreamTypeMetadata = 0x15;    // synchronous KLV (metadata in PES)

// Elementary stream_type by PID, from every program map table found in `data` (the start of a
// transport stream with 188, 192 or 204 byte packets). Sections must pass their CRC-32. Returns
// an empty map when the bytes are not a transport stream or hold no complete PMT.
std::map<int, int> ScanPmtStreamTypes(const uint8_t* data, size_t size);

// The same for the first `max_bytes` of a local file; NotFound / IoError when unreadable.
StatusOr<std::map<int, int>> ScanPmtStreamTypesInFile(const std::string& path,
                                                      size_t max_bytes = 4 << 20);

}  // namespace saker::video
