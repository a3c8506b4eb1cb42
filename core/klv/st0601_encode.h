#pragma once

// MISB ST 0601 UAS Datalink Local Set encoding: the inverse of DecodeSt0601,
// with the same ST 0601.17 tag table.
//
// The decoder is tolerant because real streams are not; the encoder is
// strict because Saker's own packets must be: a value outside its mapping's
// range, a length ST 0601.17 does not allow, or a call with the wrong type
// for the tag is an error, never clamped or guessed.

#include "core/klv/klv.h"
#include "core/util/status.h"

#include <cstddef>
#include <cstdint>
#include <string_view>
#include <vector>

namespace saker::klv {

// Builds one ST 0601 local set packet: the 16-byte UAS Datalink LS key, the
// BER length, the items in the order added, then the checksum item (tag 1)
// holding Bcc16() over everything before its value. Tags are BER-OID and
// lengths BER, both in their shortest form.
//
//   St0601Encoder e;
//   e.AddUnsigned(2, time_us).AddUnsigned(65, 17).Add(13, latitude).Add(14, longitude);
//   StatusOr<std::vector<uint8_t>> packet = e.Finish();
//
// The Add* calls never fail on their own: the first bad item is remembered
// and Finish() reports it, naming the item's position, tag number and name,
// the value and why it was refused. Items after the first error are ignored.
//
// A `length` of 0 asks for the tag's standard length: the fixed length of
// fixed-length mappings, the length ST 0601.17 suggests for IMAPB tags, and
// the shortest that holds the value for variable-length integers (tags 110,
// 111, 131, 133, 136, 137). Any other length must be one the tag allows.
class St0601Encoder {
 public:
  // A value in the tag's unit (degrees, metres, m/s, ...) for the
  // fixed-point and ST 1201 IMAPB tags, rounded to the nearest code. Errors:
  // NaN or infinity, outside the mapping's range, not such a tag.
  St0601Encoder& Add(uint32_t tag, double value, size_t length = 0);
  // Unsigned integer, enumeration, flag and time stamp tags (microseconds
  // since 1970 UTC for tags 2, 72 and 131). Errors: the value does not fit
  // in the length, or the tag is not an unsigned integer tag.
  St0601Encoder& AddUnsigned(uint32_t tag, uint64_t value, size_t length = 0);
  // Signed integer tags (39 outside air temperature, 136 leap seconds, 137
  // correction offset), two's complement.
  St0601Encoder& AddSigned(uint32_t tag, int64_t value, size_t length = 0);
  // Text tags, bytes as given (UTF-8). Errors: empty text (a zero-length item
  // means "no value": use AddAbsent), text longer than the tag allows (127
  // bytes, Target ID 32).
  St0601Encoder& AddString(uint32_t tag, std::string_view text);
  // "No value" for the tag: the error indicator of the signed fixed-point
  // mappings (0x8000, 0x80000000), and a zero-length item for every other
  // tag, which MISB reads as "value unknown". Either decodes as Absent (raw
  // tags as an empty raw item).
  St0601Encoder& AddAbsent(uint32_t tag);
  // Bytes written as the item's value unchanged: nested local sets, packs,
  // lists, tags above 143, or any item kept raw. Errors: tag 0, tag 1, tags
  // beyond 2^28 - 1 (a four-byte BER-OID).
  St0601Encoder& AddRaw(uint32_t tag, ByteSpan bytes);

  // The packet bytes. Errors: the first bad item: besides the errors above,
  // a tag added twice that ST 0601.17 allows once (all but 100, 101, 102 and
  // 115) and the checksum (tag 1) added by hand; or a missing mandatory item
  // (2 Precision Time Stamp, 65 LS Version Number).
  StatusOr<std::vector<uint8_t>> Finish() const;

 private:
  struct Item {
    uint32_t tag = 0;
    std::vector<uint8_t> value;
  };

  // Appends the item, or records the first error when the tag is not
  // allowed here or `value` failed to encode (its message says why).
  St0601Encoder& Append(uint32_t tag, StatusOr<std::vector<uint8_t>> value);

  std::vector<Item> items_;
  size_t calls_ = 0;  // Add* calls so far, to number items in messages
  Status error_;      // the first error; OK while every item was accepted
};

}  // namespace saker::klv
