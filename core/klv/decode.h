#pragma once

// One entry point for any KLV packet: recognise the standard from the key,
// decode it, and derive the FrameMetadata.

#include "core/klv/eg0104.h"
#include "core/klv/klv.h"
#include "core/klv/metadata.h"
#include "core/klv/st0601.h"
#include "core/util/status.h"

#include <nlohmann/json.hpp>

#include <optional>
#include <vector>

namespace saker::klv {

// The standard a packet's key names (version byte ignored).
enum class PacketKind { kSt0601, kEg0104, kSt0903, kUnknown };

// A packet after DecodePacket(). It is always returned, even when decoding
// failed, so a dump lists every packet of a stream.
struct DecodedPacket {
  PacketKind kind = PacketKind::kUnknown;
  UniversalKey key;
  std::optional<St0601Set> st0601;        // when kind is kSt0601 and it decoded
  std::optional<Eg0104Set> eg0104;        // when kind is kEg0104 and it decoded
  std::optional<FrameMetadata> metadata;  // when kind is 0601 or 0104 and it decoded
  Status status;                          // decode error (packet still listed); OK for
                                          // ST 0903 and unknown keys, which are not decoded
  size_t length = 0;                      // bytes in the packet value
  // The value bytes, kept only when no set was decoded (unknown keys, ST 0903,
  // decode errors): a decoded set already holds every item's raw bytes, and a
  // long flight would otherwise keep each packet twice.
  std::vector<uint8_t> raw;
};

// The kind of packet `key` introduces.
PacketKind PacketKindOf(const UniversalKey& key);

// Short name of a kind: "st0601", "eg0104", "st0903", "unknown".
const char* PacketKindId(PacketKind kind);
// Name for people: "ST 0601", "EG 0104", "ST 0903", "unknown".
const char* PacketKindName(PacketKind kind);

DecodedPacket DecodePacket(const KlvPacket& packet);

// {"kind", "key", "status", "length"}, then for a decoded ST 0601 packet the
// members of St0601ToJson ("items", "checksum", "warnings"), for EG 0104 those
// of Eg0104ToJson ("items", "warnings"), "metadata" (FrameMetadataToJson) when
// derived, and "raw" (hex of the value) for packets that were not decoded.
nlohmann::json ToJson(const DecodedPacket& packet);

}  // namespace saker::klv
