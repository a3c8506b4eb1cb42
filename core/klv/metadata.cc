#include "core/klv/metadata.h"

#include <cmath>
#include <numbers>

namespace saker::klv {

namespace {

constexpr double kDegToRad = std::numbers::pi / 180.0;
constexpr double kRadToDeg = 180.0 / std::numbers::pi;

double Wrap360(double deg) {
  double wrapped = std::fmod(deg, 360.0);
  if (wrapped < 0) wrapped += 360.0;
  return wrapped >= 360.0 ? 0.0 : wrapped;
}

// A longitude in [-180, 180]: a frame centre near the antimeridian plus an offset (tags 26-33)
// can pass it. The value is kept bit for bit when already in range.
double WrapLongitude(double deg) {
  if (deg >= -180.0 && deg <= 180.0) return deg;
  return std::remainder(deg, 360.0);
}

// A position when both coordinates are present.
std::optional<LatLon> MakeLatLon(std::optional<double> lat, std::optional<double> lon) {
  if (!lat || !lon) return std::nullopt;
  return LatLon{*lat, *lon};
}

}  // namespace

RelativePointing RelativeFromAbsolutePointing(double heading_deg, double pitch_deg, double roll_deg,
                                              double azimuth_deg, double elevation_deg) {
  // Line of sight in north-east-down.
  const double az = azimuth_deg * kDegToRad;
  const double el = elevation_deg * kDegToRad;
  const double los_ned[3] = {std::cos(el) * std::cos(az), std::cos(el) * std::sin(az),
                             -std::sin(el)};
  // body_from_ned = Rx(roll)^T * Ry(pitch)^T * Rz(heading)^T, applied in turn.
  const double h = heading_deg * kDegToRad;
  const double p = pitch_deg * kDegToRad;
  const double r = roll_deg * kDegToRad;
  // Undo heading (rotation about down).
  const double x1 = std::cos(h) * los_ned[0] + std::sin(h) * los_ned[1];
  const double y1 = -std::sin(h) * los_ned[0] + std::cos(h) * los_ned[1];
  const double z1 = los_ned[2];
  // Undo pitch (rotation about the right wing).
  const double x2 = std::cos(p) * x1 - std::sin(p) * z1;
  const double y2 = y1;
  const double z2 = std::sin(p) * x1 + std::cos(p) * z1;
  // Undo roll (rotation about the nose).
  const double x3 = x2;
  const double y3 = std::cos(r) * y2 + std::sin(r) * z2;
  const double z3 = -std::sin(r) * y2 + std::cos(r) * z2;
  RelativePointing rel;
  rel.azimuth_deg = Wrap360(std::atan2(y3, x3) * kRadToDeg);
  rel.elevation_deg = std::atan2(-z3, std::hypot(x3, y3)) * kRadToDeg;
  return rel;
}

FrameMetadata ToFrameMetadata(const St0601Set& set) {
  FrameMetadata m;
  m.standard = MetadataStandard::kSt0601;
  m.unix_time_us = set.GetUnsigned(2);
  m.mission_id = set.GetString(3);
  m.platform_designation = set.GetString(10);
  m.platform_heading_deg = set.GetDouble(5);
  m.platform_pitch_deg = set.GetDouble(90);
  if (!m.platform_pitch_deg) m.platform_pitch_deg = set.GetDouble(6);
  m.platform_roll_deg = set.GetDouble(91);
  if (!m.platform_roll_deg) m.platform_roll_deg = set.GetDouble(7);
  m.sensor_latitude_deg = set.GetDouble(13);
  m.sensor_longitude_deg = set.GetDouble(14);
  m.sensor_altitude_m = set.GetDouble(15);
  m.sensor_hfov_deg = set.GetDouble(16);
  m.sensor_vfov_deg = set.GetDouble(17);
  m.sensor_rel_azimuth_deg = set.GetDouble(18);
  m.sensor_rel_elevation_deg = set.GetDouble(19);
  m.sensor_rel_roll_deg = set.GetDouble(20);
  m.slant_range_m = set.GetDouble(21);
  m.frame_center = MakeLatLon(set.GetDouble(23), set.GetDouble(24));
  m.frame_center_elevation_m = set.GetDouble(25);

  std::array<LatLon, 4> corners;
  bool full = true;
  for (uint32_t i = 0; i < 4 && full; ++i) {
    auto corner = MakeLatLon(set.GetDouble(82 + 2 * i), set.GetDouble(83 + 2 * i));
    if (corner) {
      corners[i] = *corner;
    } else {
      full = false;
    }
  }
  if (full) {
    m.corners = corners;
  } else if (m.frame_center) {
    bool offsets = true;
    for (uint32_t i = 0; i < 4 && offsets; ++i) {
      auto offset = MakeLatLon(set.GetDouble(26 + 2 * i), set.GetDouble(27 + 2 * i));
      if (offset) {
        corners[i] = {m.frame_center->latitude_deg + offset->latitude_deg,
                      WrapLongitude(m.frame_center->longitude_deg + offset->longitude_deg)};
      } else {
        offsets = false;
      }
    }
    if (offsets) m.corners = corners;
  }
  if (auto version = set.GetUnsigned(65)) m.ls_version = static_cast<uint32_t>(*version);
  m.checksum_ok = set.checksum_ok;
  return m;
}

FrameMetadata ToFrameMetadata(const Eg0104Set& set) {
  using F = Eg0104Field;
  FrameMetadata m;
  m.standard = MetadataStandard::kEg0104;
  if (const Eg0104Item* time = set.Find(F::kUnixTimeStamp)) {
    if (auto* us = std::get_if<uint64_t>(&time->value)) m.unix_time_us = *us;
  }
  m.mission_id = set.GetString(F::kEpisodeNumber);
  m.platform_designation = set.GetString(F::kDeviceDesignation);
  if (auto heading = set.GetDouble(F::kPlatformHeadingAngle)) {
    m.platform_heading_deg = Wrap360(*heading);
  }
  m.platform_pitch_deg = set.GetDouble(F::kPlatformPitchAngle);
  m.platform_roll_deg = set.GetDouble(F::kPlatformRollAngle);
  m.sensor_latitude_deg = set.GetDouble(F::kDeviceLatitude);
  m.sensor_longitude_deg = set.GetDouble(F::kDeviceLongitude);
  m.sensor_altitude_m = set.GetDouble(F::kDeviceAltitude);
  m.sensor_hfov_deg = set.GetDouble(F::kHorizontalFov);
  m.sensor_vfov_deg = set.GetDouble(F::kVerticalFov);
  const auto azimuth = set.GetDouble(F::kAngleToNorth);
  const auto elevation = set.GetDouble(F::kObliquityAngle);
  if (azimuth && elevation && m.platform_heading_deg && m.platform_pitch_deg &&
      m.platform_roll_deg) {
    const RelativePointing rel = RelativeFromAbsolutePointing(
        *m.platform_heading_deg, *m.platform_pitch_deg, *m.platform_roll_deg, *azimuth, *elevation);
    m.sensor_rel_azimuth_deg = rel.azimuth_deg;
    m.sensor_rel_elevation_deg = rel.elevation_deg;
  }
  m.sensor_rel_roll_deg = set.GetDouble(F::kSensorRollAngle);
  m.slant_range_m = set.GetDouble(F::kSlantRange);
  m.frame_center =
      MakeLatLon(set.GetDouble(F::kFrameCenterLatitude), set.GetDouble(F::kFrameCenterLongitude));
  m.frame_center_elevation_m = set.GetDouble(F::kFrameCenterElevation);
  const F lat_fields[4] = {F::kCornerLatitude1, F::kCornerLatitude2, F::kCornerLatitude3,
                           F::kCornerLatitude4};
  const F lon_fields[4] = {F::kCornerLongitude1, F::kCornerLongitude2, F::kCornerLongitude3,
                           F::kCornerLongitude4};
  std::array<LatLon, 4> corners;
  bool all = true;
  for (int i = 0; i < 4 && all; ++i) {
    auto corner = MakeLatLon(set.GetDouble(lat_fields[i]), set.GetDouble(lon_fields[i]));
    if (corner) {
      corners[i] = *corner;
    } else {
      all = false;
    }
  }
  if (all) m.corners = corners;
  m.checksum_ok = true;
  return m;
}

nlohmann::json FrameMetadataToJson(const FrameMetadata& m) {
  using nlohmann::json;
  json j;
  j["standard"] = m.standard == MetadataStandard::kSt0601 ? "ST 0601" : "EG 0104";
  auto put = [&j](const char* name, const auto& field) {
    if (field) j[name] = *field;
  };
  put("unix_time_us", m.unix_time_us);
  if (m.mission_id) j["mission_id"] = ToValidUtf8(*m.mission_id);
  if (m.platform_designation) j["platform_designation"] = ToValidUtf8(*m.platform_designation);
  put("platform_heading_deg", m.platform_heading_deg);
  put("platform_pitch_deg", m.platform_pitch_deg);
  put("platform_roll_deg", m.platform_roll_deg);
  put("sensor_latitude_deg", m.sensor_latitude_deg);
  put("sensor_longitude_deg", m.sensor_longitude_deg);
  put("sensor_altitude_m", m.sensor_altitude_m);
  put("sensor_hfov_deg", m.sensor_hfov_deg);
  put("sensor_vfov_deg", m.sensor_vfov_deg);
  put("sensor_rel_azimuth_deg", m.sensor_rel_azimuth_deg);
  put("sensor_rel_elevation_deg", m.sensor_rel_elevation_deg);
  put("sensor_rel_roll_deg", m.sensor_rel_roll_deg);
  put("slant_range_m", m.slant_range_m);
  auto lat_lon = [](const LatLon& p) {
    return json{{"latitude_deg", p.latitude_deg}, {"longitude_deg", p.longitude_deg}};
  };
  if (m.frame_center) j["frame_center"] = lat_lon(*m.frame_center);
  put("frame_center_elevation_m", m.frame_center_elevation_m);
  if (m.corners) {
    json corners = json::array();
    for (const LatLon& c : *m.corners) corners.push_back(lat_lon(c));
    j["corners"] = std::move(corners);
  }
  put("ls_version", m.ls_version);
  j["checksum_ok"] = m.checksum_ok;
  return j;
}

}  // namespace saker::klv
