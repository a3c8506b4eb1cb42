#pragma once

// MISB ST 0601 UAS Datalink Local Set decoding (tag mappings of ST 0601.17).
//
// Decoding is tolerant, as real streams demand: a bad checksum, a missing
// checksum, or an item whose length does not fit its mapping is reported in
// St0601Set::warnings and the rest of the set is still decoded. Every item is
// kept, in stream order, with its raw bytes.

#include "core/klv/klv.h"
#include "core/util/status.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <optional>
#include <string>
#include <variant>
#include <vector>

namespace saker::klv {

// MISB running 16-bit checksum (BCC-16): bytes at even offsets are added as
// the high byte of a 16-bit word, bytes at odd offsets as the low byte.
// 06 0E 2B 34 02 00 81 BB gives 0xB4FD.
uint16_t Bcc16(ByteSpan data);

// A value the encoder marked as unavailable: an error indicator such as
// 0x8000 for a signed 16-bit mapping, 0x80000000 for latitudes, an ST 1201
// special value, or an empty (zero-length) item.
struct Absent {
  bool operator==(const Absent&) const = default;
};

// A decoded ST 0601 (and EG 0104) value:
// - std::monostate: kept raw, not decoded (nested sets, packs, unknown tags,
//   items whose length is wrong for their mapping)
// - Absent: see above
// - double: fixed-point and ST 1201 mappings, in the unit of the tag
//   (degrees, metres, m/s, ...)
// - int64_t: signed integers (outside air temperature, leap seconds, ...)
// - uint64_t: unsigned integers, enumerations, flags, time stamps
//   (microseconds since 1970-01-01 UTC, leap seconds not counted)
// - std::string: text items (ISO 646 / UTF-8 bytes as sent, may hold NULs)
using St0601Value = std::variant<std::monostate, Absent, double, int64_t, uint64_t, std::string>;

// One tag of a local set.
struct St0601Item {
  uint32_t tag = 0;
  std::vector<uint8_t> raw;  // value bytes as sent
  St0601Value value;
};

// A decoded ST 0601 local set.
struct St0601Set {
  std::vector<St0601Item> items;            // stream order, every tag kept (duplicates too)
  std::optional<uint16_t> stored_checksum;  // the tag 1 value, when present and 2 bytes long
  uint16_t computed_checksum = 0;           // BCC-16 over key..checksum length byte
  bool checksum_ok = false;                 // stored == computed
  std::vector<std::string> warnings;        // one line per tolerated problem

  // The first item with `tag`, or null.
  const St0601Item* Find(uint32_t tag) const;
  // The first item with `tag` as a number: double, int64_t and uint64_t
  // values all convert. nullopt when missing, Absent, raw or text.
  std::optional<double> GetDouble(uint32_t tag) const;
  // The first item with `tag` when it decoded as text.
  std::optional<std::string> GetString(uint32_t tag) const;
  // The first item with `tag` when it decoded as an unsigned integer.
  std::optional<uint64_t> GetUnsigned(uint32_t tag) const;
};

// Decodes the local set in `packet.value`. The checksum is BCC-16 over the
// whole packet from the first key byte through the checksum item's tag and
// length bytes (the 2 checksum value bytes excluded); `packet.bytes` is used
// when it holds the packet, otherwise the packet is rebuilt from key, value
// and the shortest BER length. Errors: the key is not the ST 0601 key
// (version byte ignored), or the value is not empty and not even its first
// item could be read. Anything less is a warning.
StatusOr<St0601Set> DecodeSt0601(const KlvPacket& packet);

// Decodes one item's value bytes with the tag's ST 0601.17 mapping. On a
// length that does not fit the mapping the value is std::monostate and, when
// `warning` is not null, *warning says why.
St0601Value DecodeSt0601Value(uint32_t tag, ByteSpan raw, std::string* warning = nullptr);

// Human name of a tag ("Sensor Latitude"); "Unknown tag" outside 1-143.
const char* St0601TagName(uint32_t tag);

// The value step of one code of the tag's mapping for an item of `length`
// bytes (1 for integer tags); nullopt for text and undecoded tags. Used to
// compare decoded values with references "within one LSB".
std::optional<double> St0601Resolution(uint32_t tag, size_t length);

// JSON form of a decoded value: number, string, "absent", or null when raw.
nlohmann::json St0601ValueToJson(const St0601Value& value);

// {"items": [{"tag", "name", "value", "raw"}...], "checksum": {"stored",
// "computed", "ok"}, "warnings": [...]}; the value is a number, a string,
// "absent", or null when the item was kept raw; "raw" is lower-case hex.
nlohmann::json St0601ToJson(const St0601Set& set);

}  // namespace saker::klv
