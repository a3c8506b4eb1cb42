#include "core/klv/eg0104.h"

#include <algorithm>
#include <bit>
#include <cmath>

namespace saker::klv {

namespace {

enum class ValueType { kString, kUint, kReal };

struct FieldSpec {
  Eg0104Field field;
  const char* name;
  ValueType type;
  // Key bytes 9-16 (bytes 1-4 are 06 0E 2B 34, 5-7 are 01 01 01 for
  // elements, byte 8 is the version, ignored).
  std::array<uint8_t, 8> item;
  uint8_t version;  // as registered, for documentation and encoding tests
};

// EG 0104.5 elements (SMPTE RP 210 labels).
constexpr FieldSpec kFields[] = {
    {Eg0104Field::kUnixTimeStamp,
     "User Defined Time Stamp",
     ValueType::kUint,
     {0x07, 0x02, 0x01, 0x01, 0x01, 0x05, 0x00, 0x00},
     0x03},
    {Eg0104Field::kEventStartDateTime,
     "Event Start Date Time - UTC",
     ValueType::kString,
     {0x07, 0x02, 0x01, 0x02, 0x07, 0x01, 0x00, 0x00},
     0x01},
    {Eg0104Field::kEpisodeNumber,
     "Episode Number",
     ValueType::kString,
     {0x01, 0x05, 0x05, 0x00, 0x00, 0x00, 0x00, 0x00},
     0x01},
    {Eg0104Field::kDeviceDesignation,
     "Device Designation",
     ValueType::kString,
     {0x01, 0x01, 0x20, 0x01, 0x00, 0x00, 0x00, 0x00},
     0x01},
    {Eg0104Field::kImageSourceDevice,
     "Image Source Device",
     ValueType::kString,
     {0x04, 0x20, 0x01, 0x02, 0x01, 0x01, 0x00, 0x00},
     0x01},
    {Eg0104Field::kImageCoordinateSystem,
     "Image Coordinate System",
     ValueType::kString,
     {0x07, 0x01, 0x01, 0x01, 0x00, 0x00, 0x00, 0x00},
     0x01},
    {Eg0104Field::kDeviceLatitude,
     "Device Latitude",
     ValueType::kReal,
     {0x07, 0x01, 0x02, 0x01, 0x02, 0x04, 0x02, 0x00},
     0x03},
    {Eg0104Field::kDeviceLongitude,
     "Device Longitude",
     ValueType::kReal,
     {0x07, 0x01, 0x02, 0x01, 0x02, 0x06, 0x02, 0x00},
     0x03},
    {Eg0104Field::kDeviceAltitude,
     "Device Altitude",
     ValueType::kReal,
     {0x07, 0x01, 0x02, 0x01, 0x02, 0x02, 0x00, 0x00},
     0x01},
    {Eg0104Field::kHorizontalFov,
     "Field of View (FOV-Horizontal)",
     ValueType::kReal,
     {0x04, 0x20, 0x02, 0x01, 0x01, 0x08, 0x00, 0x00},
     0x02},
    {Eg0104Field::kVerticalFov,
     "Field of View (FOV-Vertical)",
     ValueType::kReal,
     {0x04, 0x20, 0x02, 0x01, 0x01, 0x0A, 0x01, 0x00},
     0x07},
    {Eg0104Field::kSlantRange,
     "Slant Range",
     ValueType::kReal,
     {0x07, 0x01, 0x08, 0x01, 0x01, 0x00, 0x00, 0x00},
     0x01},
    {Eg0104Field::kTargetWidth,
     "Target Width",
     ValueType::kReal,
     {0x07, 0x01, 0x09, 0x02, 0x01, 0x00, 0x00, 0x00},
     0x01},
    {Eg0104Field::kFrameCenterLatitude,
     "Frame Center Latitude",
     ValueType::kReal,
     {0x07, 0x01, 0x02, 0x01, 0x03, 0x02, 0x00, 0x00},
     0x01},
    {Eg0104Field::kFrameCenterLongitude,
     "Frame Center Longitude",
     ValueType::kReal,
     {0x07, 0x01, 0x02, 0x01, 0x03, 0x04, 0x00, 0x00},
     0x01},
    {Eg0104Field::kFrameCenterElevation,
     "Frame Center Elevation",
     ValueType::kReal,
     {0x07, 0x01, 0x02, 0x01, 0x03, 0x16, 0x00, 0x00},
     0x0A},
    {Eg0104Field::kCornerLatitude1,
     "Corner Latitude Point 1",
     ValueType::kReal,
     {0x07, 0x01, 0x02, 0x01, 0x03, 0x07, 0x01, 0x00},
     0x03},
    {Eg0104Field::kCornerLatitude2,
     "Corner Latitude Point 2",
     ValueType::kReal,
     {0x07, 0x01, 0x02, 0x01, 0x03, 0x08, 0x01, 0x00},
     0x03},
    {Eg0104Field::kCornerLatitude3,
     "Corner Latitude Point 3",
     ValueType::kReal,
     {0x07, 0x01, 0x02, 0x01, 0x03, 0x09, 0x01, 0x00},
     0x03},
    {Eg0104Field::kCornerLatitude4,
     "Corner Latitude Point 4",
     ValueType::kReal,
     {0x07, 0x01, 0x02, 0x01, 0x03, 0x0A, 0x01, 0x00},
     0x03},
    {Eg0104Field::kCornerLongitude1,
     "Corner Longitude Point 1",
     ValueType::kReal,
     {0x07, 0x01, 0x02, 0x01, 0x03, 0x0B, 0x01, 0x00},
     0x03},
    {Eg0104Field::kCornerLongitude2,
     "Corner Longitude Point 2",
     ValueType::kReal,
     {0x07, 0x01, 0x02, 0x01, 0x03, 0x0C, 0x01, 0x00},
     0x03},
    {Eg0104Field::kCornerLongitude3,
     "Corner Longitude Point 3",
     ValueType::kReal,
     {0x07, 0x01, 0x02, 0x01, 0x03, 0x0D, 0x01, 0x00},
     0x03},
    {Eg0104Field::kCornerLongitude4,
     "Corner Longitude Point 4",
     ValueType::kReal,
     {0x07, 0x01, 0x02, 0x01, 0x03, 0x0E, 0x01, 0x00},
     0x03},
    {Eg0104Field::kSensorRollAngle,
     "Sensor Roll Angle",
     ValueType::kReal,
     {0x07, 0x01, 0x10, 0x01, 0x01, 0x00, 0x00, 0x00},
     0x01},
    {Eg0104Field::kAngleToNorth,
     "Angle to North",
     ValueType::kReal,
     {0x07, 0x01, 0x10, 0x01, 0x02, 0x00, 0x00, 0x00},
     0x01},
    {Eg0104Field::kObliquityAngle,
     "Obliquity Angle",
     ValueType::kReal,
     {0x07, 0x01, 0x10, 0x01, 0x03, 0x00, 0x00, 0x00},
     0x01},
    {Eg0104Field::kPlatformRollAngle,
     "Platform Roll Angle",
     ValueType::kReal,
     {0x07, 0x01, 0x10, 0x01, 0x04, 0x00, 0x00, 0x00},
     0x07},
    {Eg0104Field::kPlatformPitchAngle,
     "Platform Pitch Angle",
     ValueType::kReal,
     {0x07, 0x01, 0x10, 0x01, 0x05, 0x00, 0x00, 0x00},
     0x07},
    {Eg0104Field::kPlatformHeadingAngle,
     "Platform Heading Angle",
     ValueType::kReal,
     {0x07, 0x01, 0x10, 0x01, 0x06, 0x00, 0x00, 0x00},
     0x07},
};

// Bytes 1-7 of every element key: the UL prefix, then "element, dictionary".
constexpr std::array<uint8_t, 7> kElementKeyStart = {0x06, 0x0E, 0x2B, 0x34, 0x01, 0x01, 0x01};

const FieldSpec* FindField(const UniversalKey& key) {
  if (!std::equal(kElementKeyStart.begin(), kElementKeyStart.end(), key.bytes.begin())) {
    return nullptr;
  }
  for (const FieldSpec& spec : kFields) {
    if (std::equal(spec.item.begin(), spec.item.end(), key.bytes.begin() + 8)) return &spec;
  }
  return nullptr;
}

St0601Value DecodeValue(const FieldSpec& spec, ByteSpan raw, std::string* warning) {
  if (raw.empty()) return Absent{};
  switch (spec.type) {
    case ValueType::kString:
      return std::string(raw.begin(), raw.end());
    case ValueType::kUint: {
      if (raw.size() > 8) break;
      uint64_t v = 0;
      for (uint8_t b : raw) v = (v << 8) | b;
      return v;
    }
    case ValueType::kReal: {
      double v = 0;
      if (raw.size() == 4) {
        uint32_t bits = 0;
        for (uint8_t b : raw) bits = (bits << 8) | b;
        v = std::bit_cast<float>(bits);
      } else if (raw.size() == 8) {
        uint64_t bits = 0;
        for (uint8_t b : raw) bits = (bits << 8) | b;
        v = std::bit_cast<double>(bits);
      } else {
        break;
      }
      if (!std::isfinite(v)) return Absent{};
      return v;
    }
  }
  *warning =
      std::string(spec.name) + ": unexpected length " + std::to_string(raw.size()) + "; kept raw";
  return std::monostate{};
}

}  // namespace

Eg0104Field Eg0104FieldOf(const UniversalKey& key) {
  const FieldSpec* spec = FindField(key);
  return spec != nullptr ? spec->field : Eg0104Field::kUnknown;
}

UniversalKey Eg0104FieldKey(Eg0104Field field) {
  UniversalKey key;
  for (const FieldSpec& spec : kFields) {
    if (spec.field != field) continue;
    std::copy(kElementKeyStart.begin(), kElementKeyStart.end(), key.bytes.begin());
    key.bytes[kKeyVersionByte] = spec.version;
    std::copy(spec.item.begin(), spec.item.end(), key.bytes.begin() + 8);
  }
  return key;
}

const Eg0104Item* Eg0104Set::Find(Eg0104Field field) const {
  for (const auto& item : items) {
    if (Eg0104FieldOf(item.key) == field) return &item;
  }
  return nullptr;
}

std::optional<double> Eg0104Set::GetDouble(Eg0104Field field) const {
  const Eg0104Item* item = Find(field);
  if (item == nullptr) return std::nullopt;
  if (auto* d = std::get_if<double>(&item->value)) return *d;
  if (auto* u = std::get_if<uint64_t>(&item->value)) return static_cast<double>(*u);
  return std::nullopt;
}

std::optional<std::string> Eg0104Set::GetString(Eg0104Field field) const {
  const Eg0104Item* item = Find(field);
  if (item == nullptr) return std::nullopt;
  if (auto* s = std::get_if<std::string>(&item->value)) return *s;
  return std::nullopt;
}

StatusOr<Eg0104Set> DecodeEg0104(const KlvPacket& packet) {
  if (!SameKeyIgnoringVersion(packet.key, kEg0104Key)) {
    return InvalidArgumentError("not a MISB EG 0104 packet: key " + packet.key.ToHex());
  }
  const ByteSpan value(packet.value);
  Eg0104Set set;
  size_t pos = 0;
  while (pos < value.size()) {
    const size_t left = value.size() - pos;
    if (left < 17) {
      set.warnings.push_back("offset " + std::to_string(pos) + ": " + std::to_string(left) +
                             " trailing bytes, too short for an item; ignored");
      break;
    }
    if (!std::equal(kUniversalKeyPrefix.begin(), kUniversalKeyPrefix.end(), value.begin() + pos)) {
      set.warnings.push_back("offset " + std::to_string(pos) +
                             ": item key does not start with 06 0E 2B 34; rest of the set ignored");
      break;
    }
    Eg0104Item item;
    std::copy_n(value.begin() + pos, 16, item.key.bytes.begin());
    size_t length_size = 0;
    auto length = ReadBerLength(value.subspan(pos + 16), &length_size);
    if (!length.ok()) {
      set.warnings.push_back("item " + item.key.ToHex() + ": " + length.status().message() +
                             "; rest of the set ignored");
      break;
    }
    const size_t start = pos + 16 + length_size;
    if (*length > value.size() - start) {
      set.warnings.push_back("item " + item.key.ToHex() + ": length " + std::to_string(*length) +
                             " overruns the set (" + std::to_string(value.size() - start) +
                             " bytes left); rest of the set ignored");
      break;
    }
    const ByteSpan raw = value.subspan(start, static_cast<size_t>(*length));
    item.raw.assign(raw.begin(), raw.end());
    if (const FieldSpec* spec = FindField(item.key)) {
      item.name = spec->name;
      std::string warning;
      item.value = DecodeValue(*spec, raw, &warning);
      if (!warning.empty()) set.warnings.push_back(std::move(warning));
    } else {
      item.name = "Unknown key";
    }
    set.items.push_back(std::move(item));
    pos = start + raw.size();
  }
  if (set.items.empty() && !value.empty()) {
    return InvalidDataError("EG 0104 set of " + std::to_string(value.size()) +
                            " bytes has no readable item: " + set.warnings.front());
  }
  return set;
}

nlohmann::json Eg0104ToJson(const Eg0104Set& set) {
  using nlohmann::json;
  json items = json::array();
  for (const auto& item : set.items) {
    items.push_back({{"key", item.key.ToHex()},
                     {"name", item.name},
                     {"value", St0601ValueToJson(item.value)},
                     {"raw", BytesToHex(item.raw)}});
  }
  json warnings = json::array();
  for (const auto& w : set.warnings) warnings.push_back(ToValidUtf8(w));
  return {{"items", std::move(items)}, {"warnings", std::move(warnings)}};
}

}  // namespace saker::klv
