#pragma once

// Internal to core/klv: the ST 0601.17 tag table shared by the decoder
// (st0601.cc) and the encoder (st0601_encode.cc), so both read one mapping per
// tag and cannot drift apart. Not part of the library's public interface.

#include <cstddef>
#include <cstdint>

namespace saker::klv::internal {

// How a tag's value bytes turn into a St0601Value.
enum class Mapping {
  kRaw,          // kept as bytes (nested sets, packs, lists)
  kString,       // text
  kUint,         // big-endian unsigned, 1..length bytes
  kInt,          // big-endian two's complement, 1..length bytes
  kUnsignedMap,  // exactly `length` bytes, 0..2^n-1 onto [min, max]
  kSignedMap,    // exactly `length` bytes, -(2^(n-1)-1)..2^(n-1)-1 onto [-max, max];
                 // -2^(n-1) is the error indicator
  kImapb,        // MISB ST 1201 IMAPB onto [min, max], 1..8 bytes
  kChecksum,     // tag 1, exactly 2 bytes
};

struct TagSpec {
  uint32_t tag = 0;
  const char* name = nullptr;
  Mapping mapping = Mapping::kRaw;
  // Fixed length. For integers the decoder reads 1..length bytes whatever
  // the tag; for IMAPB and text it is the longest value ST 0601.17 allows
  // (the decoder reads IMAPB up to 8 bytes and text of any length).
  size_t length = 0;
  double min = 0;
  double max = 0;

  // Rules only the encoder applies: the decoder accepts what real streams
  // send, the encoder writes only what ST 0601.17 allows.
  //
  // IMAPB: the length written when the caller names none (the length
  // ST 0601.17 suggests for the tag; any 1..length is allowed).
  size_t default_length = 0;
  // Integers: any length 1..length is allowed, and the shortest that holds
  // the value is written by default. Otherwise exactly `length` bytes.
  bool variable_length = false;
  // The tag may appear more than once in a set ("multiples allowed").
  bool multiples = false;
};

inline constexpr uint32_t kMaxSt0601Tag = 143;

// The spec of `tag`, or null for tags outside 1-143.
const TagSpec* FindTagSpec(uint32_t tag);

}  // namespace saker::klv::internal
