#pragma once

// FrameMetadata: the per-packet telemetry the rest of Saker consumes, filled
// the same way from MISB ST 0601 and MISB EG 0104 packets. Every field is
// optional: a packet may carry any subset, and error indicators decode to
// "absent" rather than to a made-up number.

#include "core/klv/eg0104.h"
#include "core/klv/st0601.h"

#include <nlohmann/json.hpp>

#include <array>
#include <cstdint>
#include <optional>
#include <string>

namespace saker::klv {

// A WGS 84 geodetic position, degrees.
struct LatLon {
  double latitude_deg = 0;
  double longitude_deg = 0;
};

// Which standard a FrameMetadata came from.
enum class MetadataStandard { kSt0601, kEg0104 };

// Telemetry of one metadata packet. Angles are degrees, distances metres,
// positions WGS 84.
struct FrameMetadata {
  MetadataStandard standard = MetadataStandard::kSt0601;
  std::optional<uint64_t> unix_time_us;  // precision time stamp, UTC microseconds
  std::optional<std::string> mission_id;
  std::optional<std::string> platform_designation;
  // Platform attitude. Heading is 0..360 from true north; ST 0601 pitch and
  // roll come from the full-range tags 90/91 when present, else 6/7.
  std::optional<double> platform_heading_deg, platform_pitch_deg, platform_roll_deg;
  // Sensor position; altitude is above mean sea level (ST 0601 tag 15, EG 0104
  // Device Altitude).
  std::optional<double> sensor_latitude_deg, sensor_longitude_deg, sensor_altitude_m;
  std::optional<double> sensor_hfov_deg, sensor_vfov_deg;
  // Sensor pointing relative to the platform body, ST 0601 convention
  // (azimuth 0..360 clockwise from the nose, elevation positive up, then
  // roll). EG 0104 sends absolute pointing (Angle to North, Obliquity Angle);
  // it is converted with RelativeFromAbsolutePointing() when the platform
  // attitude is known. EG 0104 Sensor Roll Angle is passed through as is.
  std::optional<double> sensor_rel_azimuth_deg, sensor_rel_elevation_deg, sensor_rel_roll_deg;
  std::optional<double> slant_range_m;
  std::optional<LatLon> frame_center;
  std::optional<double> frame_center_elevation_m;
  // Image corners, in MISB order: 1 upper-left, 2 upper-right, 3 lower-right,
  // 4 lower-left of the image (ST 0601 tags 82-89 "Corner Point 1" is the
  // upper-left corner; EG 0104 numbers its corners the same way).
  // Full corners (82-89) when all eight are present and valid, else frame
  // centre + offset corners (26-33). EG 0104: its four corner points.
  std::optional<std::array<LatLon, 4>> corners;
  std::optional<uint32_t> ls_version;  // ST 0601 tag 65
  // False when the packet's checksum did not verify, including an ST 0601
  // packet with no checksum item. EG 0104 has no checksum: always true.
  bool checksum_ok = true;

  bool HasCorners() const { return corners.has_value(); }
};

FrameMetadata ToFrameMetadata(const St0601Set& set);
FrameMetadata ToFrameMetadata(const Eg0104Set& set);

// Sensor pointing relative to the platform body.
struct RelativePointing {
  double azimuth_deg = 0;    // 0..360, clockwise from the nose seen from above
  double elevation_deg = 0;  // -90..90, positive above the body x-y plane
};

// Converts an absolute line of sight (azimuth from true north, elevation
// above the local horizontal) into the ST 0601 platform-relative azimuth and
// elevation, given the platform attitude (aerospace yaw-pitch-roll in the
// local north-east-down frame).
RelativePointing RelativeFromAbsolutePointing(double heading_deg, double pitch_deg, double roll_deg,
                                              double azimuth_deg, double elevation_deg);

// JSON with the fields that are set, plus "standard" and "checksum_ok";
// corners as [{"latitude_deg", "longitude_deg"} x4].
nlohmann::json FrameMetadataToJson(const FrameMetadata& metadata);

}  // namespace saker::klv
