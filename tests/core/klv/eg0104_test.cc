// MISB EG 0104 universal sets: the real Fort A.P. Hill clip and hand-built
// packets.

#include "core/klv/eg0104.h"

#include "core/klv/decode.h"
#include "tests/core/klv/klv_test_util.h"
#include "tests/core/klv/ts_extract.h"
#include "tests/testing/test_data.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

namespace saker::klv {
namespace {

using testing::BerLength;
using testing::HexBytes;
using testing::MakePacket;

std::vector<KlvPacket> AphillPackets() {
  auto path = saker::testing::FindTestData("kwiver/aphill_short.ts");
  if (!path) return {};
  std::string error;
  const auto streams = testing::ExtractTsStreams(saker::testing::ReadFileBytes(*path), &error);
  EXPECT_TRUE(error.empty()) << error;
  std::vector<KlvPacket> packets;
  for (const auto& stream : streams) {
    for (const auto& unit : stream.units) {
      auto split = SplitKlvPackets(unit);
      EXPECT_TRUE(split.errors.empty());
      packets.insert(packets.end(), split.packets.begin(), split.packets.end());
    }
  }
  return packets;
}

TEST(Eg0104Test, AphillAllPacketsDecode) {
  SAKER_REQUIRE_TEST_DATA(path, "kwiver/aphill_short.ts");
  const auto packets = AphillPackets();
  ASSERT_EQ(packets.size(), 48u);
  uint64_t previous_time = 0;
  for (const auto& packet : packets) {
    const DecodedPacket decoded = DecodePacket(packet);
    ASSERT_EQ(decoded.kind, PacketKind::kEg0104);
    ASSERT_TRUE(decoded.status.ok()) << decoded.status.ToString();
    ASSERT_TRUE(decoded.eg0104.has_value());
    EXPECT_TRUE(decoded.eg0104->warnings.empty()) << decoded.eg0104->warnings.front();
    EXPECT_EQ(decoded.eg0104->items.size(), 23u);
    for (const auto& item : decoded.eg0104->items) {
      EXPECT_NE(item.name, "Unknown key") << item.key.ToHex();
      EXPECT_FALSE(std::holds_alternative<std::monostate>(item.value)) << item.name;
    }
    ASSERT_TRUE(decoded.metadata.has_value());
    const FrameMetadata& m = *decoded.metadata;
    EXPECT_EQ(m.standard, MetadataStandard::kEg0104);
    EXPECT_TRUE(m.HasCorners());
    ASSERT_TRUE(m.unix_time_us.has_value());
    EXPECT_GT(*m.unix_time_us, previous_time) << "time stamps increase";
    previous_time = *m.unix_time_us;
    EXPECT_FALSE(ToJson(decoded).dump().empty());
  }
}

TEST(Eg0104Test, AphillFirstPacket) {
  SAKER_REQUIRE_TEST_DATA(path, "kwiver/aphill_short.ts");
  const auto packets = AphillPackets();
  ASSERT_FALSE(packets.empty());
  auto set = DecodeEg0104(packets[0]);
  ASSERT_TRUE(set.ok()) << set.status().ToString();
  using F = Eg0104Field;
  EXPECT_NEAR(*set->GetDouble(F::kDeviceLatitude), 38.252336, 1e-6);
  EXPECT_NEAR(*set->GetDouble(F::kDeviceLongitude), -77.366859, 1e-6);
  EXPECT_NEAR(*set->GetDouble(F::kDeviceAltitude), 1054.4, 1e-3);
  EXPECT_EQ(*set->GetString(F::kDeviceDesignation), "ABCD");
  EXPECT_NEAR(*set->GetDouble(F::kPlatformHeadingAngle), -102.788, 1e-3) << "sent as -180..180";

  const FrameMetadata m = ToFrameMetadata(*set);
  EXPECT_EQ(*m.unix_time_us, 1221515219356000u) << "2008-09-15 21:46:59.356 UTC";
  EXPECT_NEAR(*m.sensor_latitude_deg, 38.252336, 1e-6);
  EXPECT_NEAR(*m.sensor_longitude_deg, -77.366859, 1e-6);
  EXPECT_NEAR(*m.sensor_altitude_m, 1054.4, 1e-3);
  ASSERT_TRUE(m.frame_center.has_value());
  EXPECT_NEAR(m.frame_center->latitude_deg, 38.2455872, 1e-7);
  EXPECT_NEAR(m.frame_center->longitude_deg, -77.3537377, 1e-7);
  ASSERT_TRUE(m.corners.has_value());
  EXPECT_NEAR((*m.corners)[0].latitude_deg, 38.2456129, 1e-7);
  EXPECT_NEAR((*m.corners)[0].longitude_deg, -77.3535250, 1e-7);
  EXPECT_NEAR(*m.platform_heading_deg, 360 - 102.788, 1e-3) << "normalised to 0..360";
  EXPECT_NEAR(*m.sensor_hfov_deg, 0.8, 1e-6);
  EXPECT_NEAR(*m.sensor_vfov_deg, 0.6, 1e-6);
  EXPECT_NEAR(*m.slant_range_m, 1729.92, 0.01);
  EXPECT_EQ(*m.platform_designation, "ABCD");
  EXPECT_FALSE(m.mission_id.has_value());
  EXPECT_FALSE(m.ls_version.has_value());
  EXPECT_TRUE(m.checksum_ok);

  // The corners are ordered around the footprint (upper-left, upper-right,
  // lower-right, lower-left): looking south-east, the upper-left corner is
  // the far-left one, east-north-east of the centre.
  const auto& c = *m.corners;
  EXPECT_GT(c[0].longitude_deg, m.frame_center->longitude_deg);
  EXPECT_LT(c[1].latitude_deg, m.frame_center->latitude_deg);
  EXPECT_LT(c[2].longitude_deg, m.frame_center->longitude_deg);
  EXPECT_GT(c[3].latitude_deg, m.frame_center->latitude_deg);

  // Relative pointing reproduces the absolute line of sight when rotated back
  // through the platform attitude (aerospace yaw-pitch-roll).
  ASSERT_TRUE(m.sensor_rel_azimuth_deg && m.sensor_rel_elevation_deg);
  const double d = std::numbers::pi / 180;
  const double az = *m.sensor_rel_azimuth_deg * d, el = *m.sensor_rel_elevation_deg * d;
  const double b[3] = {std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), -std::sin(el)};
  const double h = *m.platform_heading_deg * d, p = *m.platform_pitch_deg * d,
               r = *m.platform_roll_deg * d;
  // ned = Rz(h) Ry(p) Rx(r) body
  const double x1 = b[0], y1 = std::cos(r) * b[1] - std::sin(r) * b[2],
               z1 = std::sin(r) * b[1] + std::cos(r) * b[2];
  const double x2 = std::cos(p) * x1 + std::sin(p) * z1, y2 = y1,
               z2 = -std::sin(p) * x1 + std::cos(p) * z1;
  const double n = std::cos(h) * x2 - std::sin(h) * y2, e = std::sin(h) * x2 + std::cos(h) * y2;
  EXPECT_NEAR(std::atan2(e, n) / d, *set->GetDouble(F::kAngleToNorth), 1e-9);
  EXPECT_NEAR(std::atan2(-z2, std::hypot(n, e)) / d, *set->GetDouble(F::kObliquityAngle), 1e-9);
  EXPECT_NEAR(*set->GetDouble(F::kObliquityAngle), -37.55, 0.01) << "about 37 deg down";
}

// An item: key + BER length + value.
std::vector<uint8_t> Item(const UniversalKey& key, const std::vector<uint8_t>& value) {
  std::vector<uint8_t> out(key.bytes.begin(), key.bytes.end());
  const auto length = BerLength(value.size());
  out.insert(out.end(), length.begin(), length.end());
  out.insert(out.end(), value.begin(), value.end());
  return out;
}

std::vector<uint8_t> Concat(std::initializer_list<std::vector<uint8_t>> parts) {
  std::vector<uint8_t> out;
  for (const auto& p : parts) out.insert(out.end(), p.begin(), p.end());
  return out;
}

TEST(Eg0104Test, SyntheticSet) {
  using F = Eg0104Field;
  UniversalKey time_v1 = Eg0104FieldKey(F::kUnixTimeStamp);
  EXPECT_EQ(time_v1.ToHex(), "060e2b34 01010103 07020101 01050000");
  time_v1.bytes[kKeyVersionByte] = 0x01;  // as KWIVER's hand-made packet writes it
  UniversalKey unknown = Eg0104FieldKey(F::kEpisodeNumber);
  unknown.bytes[15] = 0x42;
  const auto value = Concat({
      Item(Eg0104FieldKey(F::kDeviceDesignation), HexBytes("426f62")),  // "Bob"
      Item(Eg0104FieldKey(F::kEpisodeNumber), HexBytes("342e32")),      // "4.2"
      Item(time_v1, HexBytes("00000000000010e1")),                      // 4321
      Item(Eg0104FieldKey(F::kFrameCenterLatitude), HexBytes("4043204c8bc9cd3e")),
      Item(Eg0104FieldKey(F::kDeviceAltitude), HexBytes("4483cccd")),
      Item(Eg0104FieldKey(F::kSlantRange), HexBytes("4483cc")),  // 3 bytes: kept raw
      Item(Eg0104FieldKey(F::kTargetWidth), {}),                 // empty: absent
      Item(unknown, HexBytes("01")),
  });
  auto set = DecodeEg0104(MakePacket(kEg0104Key, value));
  ASSERT_TRUE(set.ok()) << set.status().ToString();
  ASSERT_EQ(set->items.size(), 8u);
  EXPECT_EQ(*set->GetString(F::kDeviceDesignation), "Bob");
  EXPECT_EQ(*set->GetString(F::kEpisodeNumber), "4.2");
  EXPECT_EQ(std::get<uint64_t>(set->Find(F::kUnixTimeStamp)->value), 4321u)
      << "version byte ignored";
  EXPECT_DOUBLE_EQ(*set->GetDouble(F::kFrameCenterLatitude), 38.252336);
  EXPECT_NEAR(*set->GetDouble(F::kDeviceAltitude), 1054.4, 1e-3);
  EXPECT_TRUE(std::holds_alternative<std::monostate>(set->items[5].value));
  EXPECT_TRUE(std::holds_alternative<Absent>(set->items[6].value));
  EXPECT_EQ(set->items[7].name, "Unknown key");
  EXPECT_TRUE(std::holds_alternative<std::monostate>(set->items[7].value));
  EXPECT_EQ(set->warnings.size(), 1u) << "the 3-byte slant range";

  const FrameMetadata m = ToFrameMetadata(*set);
  EXPECT_EQ(*m.mission_id, "4.2");
  EXPECT_EQ(*m.platform_designation, "Bob");
  EXPECT_EQ(*m.unix_time_us, 4321u);
  EXPECT_FALSE(m.frame_center.has_value()) << "longitude missing";
  EXPECT_FALSE(m.slant_range_m.has_value());
  EXPECT_FALSE(m.HasCorners());

  const auto json = Eg0104ToJson(*set);
  ASSERT_EQ(json.at("items").size(), 8u);
  EXPECT_EQ(json.at("items")[0].at("name"), "Device Designation");
  EXPECT_EQ(json.at("items")[0].at("value"), "Bob");
  EXPECT_EQ(json.at("items")[0].at("key"), "060e2b34 01010101 01012001 00000000");
  EXPECT_EQ(json.at("items")[6].at("value"), "absent");
  EXPECT_TRUE(json.at("items")[5].at("value").is_null());
  EXPECT_EQ(json.at("items")[5].at("raw"), "4483cc");
}

TEST(Eg0104Test, MalformedSets) {
  using F = Eg0104Field;
  const auto good = Item(Eg0104FieldKey(F::kDeviceAltitude), HexBytes("4483cccd"));
  // Truncated second item: the first is kept.
  auto truncated = Concat({good, good});
  truncated.resize(truncated.size() - 2);
  auto set = DecodeEg0104(MakePacket(kEg0104Key, truncated));
  ASSERT_TRUE(set.ok());
  EXPECT_EQ(set->items.size(), 1u);
  EXPECT_EQ(set->warnings.size(), 1u);
  // Trailing bytes too short for an item.
  set = DecodeEg0104(MakePacket(kEg0104Key, Concat({good, HexBytes("060e2b")})));
  ASSERT_TRUE(set.ok());
  EXPECT_EQ(set->items.size(), 1u);
  EXPECT_EQ(set->warnings.size(), 1u);
  // Not a key at all.
  set = DecodeEg0104(MakePacket(kEg0104Key, Concat({good, std::vector<uint8_t>(20, 0x11)})));
  ASSERT_TRUE(set.ok());
  EXPECT_EQ(set->items.size(), 1u);
  // Errors: nothing readable, wrong packet key.
  EXPECT_EQ(DecodeEg0104(MakePacket(kEg0104Key, std::vector<uint8_t>(40, 0x11))).status().code(),
            StatusCode::kInvalidData);
  EXPECT_EQ(DecodeEg0104(MakePacket(kSt0601Key, good)).status().code(),
            StatusCode::kInvalidArgument);
  // Empty set: fine, nothing in it.
  set = DecodeEg0104(MakePacket(kEg0104Key, {}));
  ASSERT_TRUE(set.ok());
  EXPECT_TRUE(set->items.empty());
  EXPECT_EQ(Eg0104FieldOf(kSt0601Key), F::kUnknown);
  EXPECT_EQ(Eg0104FieldKey(F::kUnknown), UniversalKey{});
}

}  // namespace
}  // namespace saker::klv
