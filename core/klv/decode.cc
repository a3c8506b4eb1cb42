#include "core/klv/decode.h"

namespace saker::klv {

PacketKind PacketKindOf(const UniversalKey& key) {
  if (SameKeyIgnoringVersion(key, kSt0601Key)) return PacketKind::kSt0601;
  if (SameKeyIgnoringVersion(key, kEg0104Key)) return PacketKind::kEg0104;
  if (SameKeyIgnoringVersion(key, kSt0903Key)) return PacketKind::kSt0903;
  return PacketKind::kUnknown;
}

const char* PacketKindId(PacketKind kind) {
  switch (kind) {
    case PacketKind::kSt0601:
      return "st0601";
    case PacketKind::kEg0104:
      return "eg0104";
    case PacketKind::kSt0903:
      return "st0903";
    case PacketKind::kUnknown:
      return "unknown";
  }
  return "unknown";
}

const char* PacketKindName(PacketKind kind) {
  switch (kind) {
    case PacketKind::kSt0601:
      return "ST 0601";
    case PacketKind::kEg0104:
      return "EG 0104";
    case PacketKind::kSt0903:
      return "ST 0903";
    case PacketKind::kUnknown:
      return "unknown";
  }
  return "unknown";
}

DecodedPacket DecodePacket(const KlvPacket& packet) {
  DecodedPacket decoded;
  decoded.kind = PacketKindOf(packet.key);
  decoded.key = packet.key;
  decoded.length = packet.value.size();
  switch (decoded.kind) {
    case PacketKind::kSt0601: {
      auto set = DecodeSt0601(packet);
      if (set.ok()) {
        decoded.metadata = ToFrameMetadata(*set);
        decoded.st0601 = std::move(set).value();
      } else {
        decoded.status = set.status();
      }
      break;
    }
    case PacketKind::kEg0104: {
      auto set = DecodeEg0104(packet);
      if (set.ok()) {
        decoded.metadata = ToFrameMetadata(*set);
        decoded.eg0104 = std::move(set).value();
      } else {
        decoded.status = set.status();
      }
      break;
    }
    case PacketKind::kSt0903:
    case PacketKind::kUnknown:
      break;
  }
  if (!decoded.st0601 && !decoded.eg0104) decoded.raw = packet.value;
  return decoded;
}

nlohmann::json ToJson(const DecodedPacket& packet) {
  using nlohmann::json;
  json j;
  j["kind"] = PacketKindId(packet.kind);
  j["key"] = packet.key.ToHex();
  j["status"] = packet.status.ok() ? std::string("ok") : ToValidUtf8(packet.status.ToString());
  j["length"] = packet.length;
  if (packet.st0601) j.update(St0601ToJson(*packet.st0601));
  if (packet.eg0104) j.update(Eg0104ToJson(*packet.eg0104));
  if (packet.metadata) j["metadata"] = FrameMetadataToJson(*packet.metadata);
  if (!packet.st0601 && !packet.eg0104) j["raw"] = BytesToHex(packet.raw);
  return j;
}

}  // namespace saker::klv
