#pragma once

// SMPTE ST 336 KLV framing: 16-byte universal keys, BER lengths, BER-OID
// tags, and splitting a demuxed data buffer into KLV packets.
//
// Everything here reads untrusted bytes from a video file: every function
// checks bounds and reports malformed input as a Status or an error string,
// never by reading past the span or crashing.

#include "core/util/status.h"

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace saker::klv {

// A read-only view of bytes; std::vector<uint8_t> converts to it implicitly.
using ByteSpan = std::span<const uint8_t>;

// A 16-byte SMPTE universal label (UL), used as the key of a KLV packet and of
// every item of an EG 0104 universal set.
struct UniversalKey {
  std::array<uint8_t, 16> bytes{};

  // Lower-case hex in four groups of four bytes: "060e2b34 020b0101 0e010301 01000000".
  std::string ToHex() const;
  // Exact byte comparison; see SameKeyIgnoringVersion() for matching against
  // the registered keys below.
  bool operator==(const UniversalKey&) const = default;
};

// The 0-based index of the version byte in a universal key (byte 8 in the
// 1-based numbering of SMPTE ST 336).
inline constexpr size_t kKeyVersionByte = 7;

// True when the keys are equal except possibly for the version byte. SMPTE
// ST 336 defines byte 8 as the version of the registry that first defined
// the label, and MISB ST 0107 tells decoders not to use it to tell labels
// apart: real encoders write both 01 and newer values (the EG 0104 "User
// Defined Time Stamp" appears as version 01 and 03). Every key comparison in
// this library uses this function.
bool SameKeyIgnoringVersion(const UniversalKey& a, const UniversalKey& b);

// MISB ST 0601 UAS Datalink Local Set: 06 0E 2B 34 02 0B 01 01 0E 01 03 01 01 00 00 00.
extern const UniversalKey kSt0601Key;
// MISB EG 0104 Predator UAV Basic Universal Set: 06 0E 2B 34 02 01 01 01 0E 01 01 02 01 01 00 00.
extern const UniversalKey kEg0104Key;
// MISB ST 0903 VMTI Local Set (standalone): 06 0E 2B 34 02 0B 01 01 0E 01 03 03 06 00 00 00.
extern const UniversalKey kSt0903Key;

// The four bytes every SMPTE universal label starts with.
inline constexpr std::array<uint8_t, 4> kUniversalKeyPrefix = {0x06, 0x0E, 0x2B, 0x34};

// Reads a BER length at the start of `data`: short form (one byte < 0x80) or
// long form (0x80 | n, then n big-endian bytes, 1 <= n <= 8). The indefinite
// form (0x80 alone) is not allowed in KLV and is an error, as are more than 8
// length bytes and a length field running past `data`. On success
// `*consumed` (which may be null) receives the number of bytes read.
StatusOr<uint64_t> ReadBerLength(ByteSpan data, size_t* consumed);

// Appends the shortest BER length encoding of `n` (short form below 128, else long form).
void AppendBerLength(uint64_t n, std::vector<uint8_t>* out);

// Reads a BER-OID encoded tag (7 bits per byte, high bit set on every byte
// but the last), as used by local-set tags >= 128. More than 4 bytes (tags
// beyond 2^28 - 1, far past any MISB tag) or running past `data` is an error.
StatusOr<uint64_t> ReadBerOid(ByteSpan data, size_t* consumed);

// One KLV packet as found in the input.
struct KlvPacket {
  UniversalKey key;
  std::vector<uint8_t> value;  // the value bytes only
  std::vector<uint8_t> bytes;  // the whole packet, key + BER length + value (for checksums)
  size_t offset = 0;           // offset of the first key byte in the split input
};

// What SplitKlvPackets() found in a buffer.
struct KlvSplitResult {
  std::vector<KlvPacket> packets;   // complete packets, in input order
  std::vector<std::string> errors;  // one line per framing problem, naming the offset
  size_t skipped_bytes = 0;         // bytes not part of any returned packet
};

// Splits a buffer (one demuxed KLV data packet may hold one or several KLV
// packets, or garbage) into KLV packets. A packet must start with the
// universal label prefix 06 0E 2B 34. Bytes before a prefix, a key cut short,
// a bad BER length or a length that overruns the buffer are reported in
// `errors` for that packet only; parsing then resyncs at the next 06 0E 2B 34
// after the failed packet's first byte.
KlvSplitResult SplitKlvPackets(ByteSpan data);

// Lower-case hex of `data` without separators ("0e2b"), for JSON dumps.
std::string BytesToHex(ByteSpan data);

// `text` with every byte that is not part of a well-formed UTF-8 sequence
// replaced by U+FFFD. KLV text items are arbitrary bytes, while JSON
// serialisation (nlohmann::json::dump) throws on invalid UTF-8.
std::string ToValidUtf8(std::string_view text);

}  // namespace saker::klv
