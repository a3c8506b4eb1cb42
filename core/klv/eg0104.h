#pragma once

// MISB EG 0104 "Predator UAV Basic Universal Metadata Set" (EG 0104.5): the
// pre-ST 0601 format still found in older airborne recordings. The set is a
// sequence of items, each a 16-byte SMPTE universal key, a BER length and a
// value; numbers are big-endian IEEE 754 floats or doubles, text is ASCII.

#include "core/klv/klv.h"
#include "core/klv/st0601.h"
#include "core/util/status.h"

#include <nlohmann/json.hpp>

#include <optional>
#include <string>
#include <vector>

namespace saker::klv {

// The EG 0104 items this library decodes. Keys are matched ignoring the
// version byte (see SameKeyIgnoringVersion).
enum class Eg0104Field {
  kUnknown,
  kUnixTimeStamp,          // "User Defined Time Stamp", microseconds since 1970 UTC (uint64)
  kEventStartDateTime,     // "Event Start Date Time - UTC" (text)
  kEpisodeNumber,          // mission id (text)
  kDeviceDesignation,      // platform designation (text)
  kImageSourceDevice,      // (text)
  kImageCoordinateSystem,  // (text)
  kDeviceLatitude,         // sensor latitude, degrees
  kDeviceLongitude,        // sensor longitude, degrees
  kDeviceAltitude,         // sensor altitude, metres above mean sea level
  kHorizontalFov,          // degrees
  kVerticalFov,            // degrees
  kSlantRange,             // metres
  kTargetWidth,            // metres
  kFrameCenterLatitude,    // degrees
  kFrameCenterLongitude,   // degrees
  kFrameCenterElevation,   // metres
  kCornerLatitude1,        // corners: 1 upper left, 2 upper right, 3 lower right, 4 lower left
  kCornerLatitude2,
  kCornerLatitude3,
  kCornerLatitude4,
  kCornerLongitude1,
  kCornerLongitude2,
  kCornerLongitude3,
  kCornerLongitude4,
  kSensorRollAngle,      // degrees
  kAngleToNorth,         // sensor line-of-sight azimuth from true north, degrees
  kObliquityAngle,       // sensor line-of-sight elevation, degrees (negative below horizon)
  kPlatformRollAngle,    // degrees
  kPlatformPitchAngle,   // degrees
  kPlatformHeadingAngle  // degrees from true north (may be sent as -180..180)
};

// One item of a universal set.
struct Eg0104Item {
  UniversalKey key;
  std::string name;          // EG 0104 element name, or "Unknown key"
  std::vector<uint8_t> raw;  // value bytes as sent
  St0601Value value;         // double, uint64_t, std::string, Absent, or monostate when raw
};

// A decoded EG 0104 set.
struct Eg0104Set {
  std::vector<Eg0104Item> items;      // stream order, every item kept
  std::vector<std::string> warnings;  // one line per tolerated problem

  // The first item for `field`, or null.
  const Eg0104Item* Find(Eg0104Field field) const;
  // The first item for `field` as a number (double or unsigned).
  std::optional<double> GetDouble(Eg0104Field field) const;
  // The first item for `field` as text.
  std::optional<std::string> GetString(Eg0104Field field) const;
};

// The field a key stands for (version byte ignored), kUnknown if none.
Eg0104Field Eg0104FieldOf(const UniversalKey& key);

// The registered key of `field` (with the version byte EG 0104.5 lists), or
// an all-zero key for kUnknown. For building test packets and encoders.
UniversalKey Eg0104FieldKey(Eg0104Field field);

// Decodes the universal set in `packet.value`. Errors: the key is not the
// EG 0104 set key (version byte ignored), or the value is not empty and not
// even its first item could be read. A truncated or malformed later item
// ends the set with a warning; an item of the wrong size is kept raw.
StatusOr<Eg0104Set> DecodeEg0104(const KlvPacket& packet);

// {"items": [{"key", "name", "value", "raw"}...], "warnings": [...]}, with
// values encoded as in St0601ToJson.
nlohmann::json Eg0104ToJson(const Eg0104Set& set);

}  // namespace saker::klv
